//! Tests of the environment core: determinism across seeds, batch sizes and threads, next-step
//! autoreset, refused actions, and every action mode flying a hover.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::config::Prepared;
use super::env::Env;
use super::*;
use crate::plant::rotor::lift_from_pwm_n;
use crate::plant::{Airframe, rotor::MOTOR_PWM_MAX_US, rotor::MOTOR_PWM_MIN_US};

/// One step's outputs of a batch.
#[derive(Debug, Clone, PartialEq)]
struct Out {
    obs: Vec<f32>,
    reward: Vec<f32>,
    terminated: Vec<bool>,
    truncated: Vec<bool>,
    reset_now: Vec<bool>,
}

impl Out {
    fn new(env: &VecEnv) -> Self {
        let n = env.num_envs();
        Self {
            obs: vec![0.0; n * env.config().obs_dim()],
            reward: vec![0.0; n],
            terminated: vec![false; n],
            truncated: vec![false; n],
            reset_now: vec![false; n],
        }
    }

    fn step(&mut self, env: &mut VecEnv, actions: &[f32]) -> Result<(), GymError> {
        env.step(
            actions,
            &mut self.obs,
            &mut self.reward,
            &mut self.terminated,
            &mut self.truncated,
            &mut self.reset_now,
        )
    }

    fn obs_of(&self, i: usize, d: usize) -> Vec<u32> {
        self.obs[i * d..(i + 1) * d].iter().map(|x| x.to_bits()).collect()
    }

    fn bits(&self) -> (Vec<u32>, Vec<u32>) {
        (self.obs.iter().map(|x| x.to_bits()).collect(), self.reward.iter().map(|x| x.to_bits()).collect())
    }
}

/// Env `i`'s action at step `k`: random within the bounds, from (i, k) alone.
fn action(config: &EnvConfig, i: usize, k: usize) -> [f32; 4] {
    let mut rng = ChaCha8Rng::seed_from_u64((i as u64) << 32 | k as u64);
    let (lo, hi) = (config.action_low(), config.action_high());
    // Near hover for the collective, so episodes last long enough to be compared.
    std::array::from_fn(|c| {
        let x: f32 = rng.random();
        if c == 0 && config.action == ActionMode::Ctbr { 0.4 + 0.15 * x } else { lo[c] + (hi[c] - lo[c]) * x * 0.2 }
    })
}

fn actions(config: &EnvConfig, n: usize, k: usize) -> Vec<f32> {
    (0..n).flat_map(|i| action(config, i, k)).collect()
}

fn ctbr_estimate() -> EnvConfig {
    EnvConfig { observe: Observe::Estimate, ..EnvConfig::new(Task::Hover, ActionMode::Ctbr) }
}

/// Every step's outputs of `steps` steps of `n` envs reset with `seed`.
fn run(config: &EnvConfig, n: usize, seed: u64, steps: usize) -> Vec<Out> {
    let mut env = VecEnv::new(config.clone(), n, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(seed, &mut out.obs).unwrap();
    let mut all = vec![out.clone()];
    for k in 0..steps {
        out.step(&mut env, &actions(config, n, k)).unwrap();
        all.push(out.clone());
    }
    all
}

#[test]
fn given_the_same_seed_twice_then_200_steps_of_16_envs_are_bit_identical() {
    let config = ctbr_estimate();
    let (a, b) = (run(&config, 16, 42, 200), run(&config, 16, 42, 200));
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(x.bits(), y.bits(), "step {k}");
        assert_eq!((&x.terminated, &x.truncated, &x.reset_now), (&y.terminated, &y.truncated, &y.reset_now));
    }
    let other = run(&config, 16, 43, 1);
    assert_ne!(a[1].bits(), other[1].bits(), "another seed, another batch");
    // The random actions do end episodes: the autoreset path is part of what was compared.
    assert!(a.iter().any(|o| o.reset_now.iter().any(|x| *x)), "no episode ended in 200 steps");
}

#[test]
fn given_8_or_64_envs_or_1_or_2_threads_then_env_7_sees_the_same() {
    let config = ctbr_estimate();
    let d = config.obs_dim();
    let env7 = |outs: &[Out]| outs.iter().map(|o| (o.obs_of(7, d), o.reward[7].to_bits())).collect::<Vec<_>>();
    let small = env7(&run(&config, 8, 5, 150));
    let large = env7(&run(&config, 64, 5, 150));
    assert_eq!(small, large);
    let in_pool = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| env7(&run(&config, 8, 5, 150)))
    };
    assert_eq!(in_pool(1), small);
    assert_eq!(in_pool(2), small);
}

/// The observation `reset` gives env `i`'s episode `episode` of seed `seed`.
fn reset_obs(config: &EnvConfig, seed: u64, i: u64, episode: u64) -> Vec<u32> {
    let mut obs = vec![0.0; config.obs_dim()];
    Env::reset(&Prepared::new(config).unwrap(), seed, i, episode, &mut obs).unwrap();
    obs.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn given_an_env_marked_ended_then_the_next_step_resets_it_with_its_next_episode() {
    let config = EnvConfig::new(Task::Hover, ActionMode::Ctbr);
    let d = config.obs_dim();
    let mut env = VecEnv::new(config.clone(), 3, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(9, &mut out.obs).unwrap();
    assert_eq!(out.obs_of(1, d), reset_obs(&config, 9, 1, 0), "reset is episode 0 of (seed, i)");
    let hover = [0.45, 0.0, 0.0, 0.0].repeat(3);
    out.step(&mut env, &hover).unwrap();
    env.set_ended(&[false, true, false]).unwrap();
    out.step(&mut env, &hover).unwrap();
    assert_eq!(out.reset_now, [false, true, false]);
    assert_eq!((out.reward[1], out.terminated[1], out.truncated[1]), (0.0, false, false));
    assert_ne!(out.reward[0], 0.0);
    assert_eq!(out.obs_of(1, d), reset_obs(&config, 9, 1, 1));
    assert_ne!(out.obs_of(1, d), reset_obs(&config, 9, 1, 0));
    assert_eq!(env.episode_index(), [0, 1, 0]);
    let t = env.episode_time_s();
    assert!(t[1] == 0.0 && (t[0] - 0.02).abs() < 1e-12, "{t:?}");
    // The next step flies the new episode.
    out.step(&mut env, &hover).unwrap();
    assert!(!out.reset_now[1] && (env.episode_time_s()[1] - 0.01).abs() < 1e-12);
}

#[test]
fn given_motors_at_zero_then_the_vehicle_falls_terminates_and_is_reset_at_the_next_step() {
    let config = EnvConfig::new(Task::Hover, ActionMode::Motors);
    let d = config.obs_dim();
    let mut env = VecEnv::new(config.clone(), 2, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(3, &mut out.obs).unwrap();
    let mut steps = 0;
    while !out.terminated[0] {
        out.step(&mut env, &[0.0; 8]).unwrap();
        assert!(!out.truncated[0] && !out.reset_now[0]);
        steps += 1;
        assert!(steps < 200, "no termination in 2 s of falling");
    }
    assert!(env.truth(0).pos_ned_m[2] > -0.05, "it ended at the ground: {:?}", env.truth(0));
    out.step(&mut env, &[0.0; 8]).unwrap();
    assert!(out.reset_now[0] && !out.terminated[0] && !out.truncated[0] && out.reward[0] == 0.0);
    assert_eq!(out.obs_of(0, d), reset_obs(&config, 3, 0, 1));
}

#[test]
fn given_a_short_episode_then_it_is_truncated_on_time() {
    let config = EnvConfig { episode_s: 0.05, ..EnvConfig::new(Task::Hover, ActionMode::Velocity) };
    let mut env = VecEnv::new(config, 1, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(1, &mut out.obs).unwrap();
    for k in 1..=5 {
        out.step(&mut env, &[0.0; 4]).unwrap();
        assert_eq!((out.truncated[0], out.terminated[0]), (k == 5, false), "step {k}");
    }
    out.step(&mut env, &[0.0; 4]).unwrap();
    assert!(out.reset_now[0]);
}

#[test]
fn given_a_nan_action_then_the_error_names_env_and_component_and_nothing_changed() {
    let config = ctbr_estimate();
    let (mut a, mut b) = (VecEnv::new(config.clone(), 4, true).unwrap(), VecEnv::new(config.clone(), 4, true).unwrap());
    let (mut oa, mut ob) = (Out::new(&a), Out::new(&b));
    a.reset(7, &mut oa.obs).unwrap();
    b.reset(7, &mut ob.obs).unwrap();
    for k in 0..3 {
        oa.step(&mut a, &actions(&config, 4, k)).unwrap();
        ob.step(&mut b, &actions(&config, 4, k)).unwrap();
    }
    for (bad, name) in [(f32::NAN, "NaN"), (f32::INFINITY, "inf")] {
        let mut act = actions(&config, 4, 3);
        act[3 * 4 + 1] = bad;
        let before = oa.clone();
        let e = oa.step(&mut a, &act).unwrap_err().to_string();
        assert_eq!(e, format!("action for env 3, component 1 is {name}: actions must be finite"));
        assert_eq!(oa, before, "outputs untouched");
    }
    for k in 3..20 {
        oa.step(&mut a, &actions(&config, 4, k)).unwrap();
        ob.step(&mut b, &actions(&config, 4, k)).unwrap();
        assert_eq!(oa.bits(), ob.bits(), "step {k}");
    }
    assert_eq!(a.episode_time_s(), b.episode_time_s());
}

#[test]
fn given_a_wrong_length_or_an_ended_env_without_autoreset_then_the_step_is_refused() {
    let config = EnvConfig::new(Task::Hover, ActionMode::Motors);
    let mut env = VecEnv::new(config, 2, false).unwrap();
    let mut out = Out::new(&env);
    env.reset(1, &mut out.obs).unwrap();
    let e = out.step(&mut env, &[0.5; 7]).unwrap_err().to_string();
    assert_eq!(e, "actions have 7 values, expected 4 x 2 = 8");
    let mut short = vec![0.0; 3];
    let e = env.step(&[0.5; 8], &mut short, &mut out.reward, &mut [false; 2], &mut [false; 2], &mut [false; 2]);
    assert!(e.unwrap_err().to_string().contains("observations buffer has 3 values"));
    assert_eq!(env.episode_time_s(), [0.0, 0.0], "nothing stepped");
    out.step(&mut env, &[0.5; 8]).unwrap();
    env.set_ended(&[true, false]).unwrap();
    let before = env.episode_time_s();
    let e = out.step(&mut env, &[0.5; 8]).unwrap_err().to_string();
    assert_eq!(e, "env 0 has been marked ended: reset it before stepping");
    assert_eq!(env.episode_time_s(), before, "env 1 did not step either");
    assert!(env.set_ended(&[true]).is_err());
    env.reset(1, &mut out.obs).unwrap();
    out.step(&mut env, &[0.5; 8]).unwrap();
}

#[test]
fn given_bad_configurations_then_they_are_refused_with_a_clear_message() {
    let ca = EnvConfig { controller: "ca".parse().unwrap(), ..EnvConfig::new(Task::Hover, ActionMode::Ctbr) };
    let e = ca.validate().unwrap_err().to_string();
    assert_eq!(e, "ctbr needs a controller with a rate loop; ca has none");
    assert!(VecEnv::new(ca.clone(), 1, true).is_err());
    assert!(EnvConfig { action: ActionMode::Attitude, ..ca }.validate().is_ok());
    let hz = EnvConfig { policy_hz: 7, ..EnvConfig::new(Task::Hover, ActionMode::Motors) };
    assert!(hz.validate().unwrap_err().to_string().contains("policy_hz = 7"));
    let mut grid = EnvConfig::new(Task::Hover, ActionMode::Motors);
    grid.randomize.push((Param::MotorTauS, Distribution::Values(vec![0.04])));
    assert!(grid.validate().unwrap_err().to_string().contains("use `choice`"));
    let mut gust = EnvConfig::new(Task::Track, ActionMode::Motors);
    gust.randomize.push((Param::GustAmplitudeMps, Distribution::Uniform([0.0, 1.0])));
    assert!(gust.validate().unwrap_err().to_string().contains("gust"), "{:?}", gust.validate());
    let e = "walk".parse::<ActionMode>().unwrap_err().to_string();
    assert_eq!(e, "unknown action mode `walk` (known: motors, ctbr, attitude, velocity)");
    for (task, name) in Task::ALL {
        assert_eq!(name.parse::<Task>().unwrap(), *task);
        let c = EnvConfig::new(*task, ActionMode::Motors);
        assert_eq!(c.obs_names().len(), c.obs_dim());
    }
    assert_eq!("estimate".parse::<Observe>().unwrap(), Observe::Estimate);
    assert_eq!("random".parse::<TrackPath>().unwrap(), TrackPath::Random);
}

/// The collective that holds the plant's hover, as the controllers normalise it (F_min to F_max).
fn hover_collective(airframe: &Airframe) -> f32 {
    let (lo, hi) = (lift_from_pwm_n(MOTOR_PWM_MIN_US), lift_from_pwm_n(MOTOR_PWM_MAX_US));
    ((airframe.hover_lift_n() / airframe.thrust_scale - lo) / (hi - lo)) as f32
}

#[test]
fn given_a_hover_policy_in_every_action_mode_then_the_vehicle_stays_up_for_a_second() {
    let mismatch = Airframe::mismatch();
    for mode in [ActionMode::Motors, ActionMode::Ctbr, ActionMode::Attitude, ActionMode::Velocity] {
        let config = EnvConfig { randomize: Vec::new(), ..EnvConfig::new(Task::Hover, mode) };
        let c = hover_collective(&mismatch);
        let a = match mode {
            ActionMode::Motors => [((mismatch.hover_pwm_us() - 1000.0) / 1000.0) as f32; 4],
            ActionMode::Ctbr | ActionMode::Attitude => [c, 0.0, 0.0, 0.0],
            ActionMode::Velocity => [0.0; 4],
        };
        let mut env = VecEnv::new(config, 4, false).unwrap();
        let mut out = Out::new(&env);
        env.reset(11, &mut out.obs).unwrap();
        for _ in 0..100 {
            out.step(&mut env, &a.repeat(4)).unwrap();
            assert!(!out.terminated.iter().any(|x| *x), "{mode}: terminated at {:?}", env.episode_time_s());
        }
        for i in 0..4 {
            let t = env.truth(i);
            assert!((t.pos_ned_m[2] + 1.5).abs() < 0.8, "{mode}: env {i} at {t:?}");
            // Beyond staying up: ctbr holds its zero rates, attitude levels, velocity comes to rest.
            let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let held = match mode {
                ActionMode::Motors => true,
                ActionMode::Ctbr => norm(t.rate_frd_radps) < 0.1,
                ActionMode::Attitude => t.q_ned_frd[1].hypot(t.q_ned_frd[2]) < 0.02,
                ActionMode::Velocity => norm(t.vel_ned_mps) < 0.5,
            };
            assert!(held, "{mode}: env {i} at {t:?}");
        }
    }
}

#[test]
fn given_the_random_track_then_each_reset_draws_its_own_path_and_the_observation_looks_ahead() {
    let config = EnvConfig {
        track_path: TrackPath::Random,
        randomize_start: false,
        episode_s: 40.0,
        ..EnvConfig::new(Task::Track, ActionMode::Velocity)
    };
    let d = config.obs_dim();
    assert_eq!(d, 19);
    let mut env = VecEnv::new(config, 2, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(4, &mut out.obs).unwrap();
    let starts: Vec<[f64; 3]> = (0..2).map(|i| env.truth(i).ref_pos_ned_m).collect();
    assert_ne!(starts[0], starts[1], "two envs, two paths");
    for (i, s) in starts.iter().enumerate() {
        assert!(s[0].abs() <= 1.5 && s[1].abs() <= 1.5 && s[2] == -1.5, "env {i}: {s:?}");
        assert_eq!(env.truth(i).pos_ned_m, *s, "starts on its path without a random start");
    }
    for _ in 0..200 {
        out.step(&mut env, &[0.0; 8]).unwrap();
    }
    // At 2 s the reference moves: the look-ahead is about 0.5 s of its speed (0.3-0.6 m/s).
    let ahead = f64::from(out.obs[16]).hypot(f64::from(out.obs[17]));
    let speed = f64::from(out.obs[13]).hypot(f64::from(out.obs[14]));
    assert!(speed > 0.1 && ahead > 0.05 && ahead < 0.35, "speed {speed}, ahead {ahead}");
}

#[test]
fn given_the_figure8_then_the_reference_and_look_ahead_are_the_scenario_track_s_exactly() {
    use crate::scenario::reference::{ReferenceGen, ReferenceMode};
    let config = EnvConfig::new(Task::Track, ActionMode::Velocity);
    let spec = crate::scenario::Scenario::load("figure8").unwrap().reference;
    let (mut now, mut ahead) =
        (ReferenceGen::new(&spec, ReferenceMode::FeedForward), ReferenceGen::new(&spec, ReferenceMode::FeedForward));
    let mut env = VecEnv::new(config, 2, true).unwrap();
    let mut out = Out::new(&env);
    env.reset(2, &mut out.obs).unwrap();
    for k in 0..400 {
        let t = env.truth(1);
        let (r, a) = (now.at(t.time_s), ahead.at(t.time_s + LOOKAHEAD_S));
        assert_eq!((t.ref_pos_ned_m, t.ref_vel_ned_mps), (r.pos_ned_m.into(), r.vel_ned_mps.into()), "step {k}");
        let expected: Vec<f32> = (0..3).map(|c| (a.pos_ned_m[c] - r.pos_ned_m[c]) as f32).collect();
        assert_eq!(out.obs[19 + 16..19 + 19], expected[..], "step {k}");
        out.step(&mut env, &[0.0; 8]).unwrap();
        assert!(!out.terminated[1], "step {k}: {:?}", env.truth(1));
    }
    assert!(env.truth(1).ref_vel_ned_mps[0].hypot(env.truth(1).ref_vel_ned_mps[1]) > 0.1, "it moved");
}

#[test]
fn given_estimate_or_truth_observations_then_the_flight_is_the_same_and_only_the_noise_differs() {
    let estimate = ctbr_estimate();
    let truth = EnvConfig { observe: Observe::Truth, ..estimate.clone() };
    let (mut a, mut b) = (VecEnv::new(truth.clone(), 2, true).unwrap(), VecEnv::new(estimate, 2, true).unwrap());
    let (mut oa, mut ob) = (Out::new(&a), Out::new(&b));
    a.reset(5, &mut oa.obs).unwrap();
    b.reset(5, &mut ob.obs).unwrap();
    let mut largest = [0.0_f32; 13];
    for k in 0..100 {
        let act = actions(&truth, 2, k);
        oa.step(&mut a, &act).unwrap();
        ob.step(&mut b, &act).unwrap();
        assert_eq!(a.truth(0), b.truth(0), "step {k}: the controller saw the same noisy state");
        assert_eq!(oa.reward, ob.reward, "the reward is the truth's");
        for (c, l) in largest.iter_mut().enumerate() {
            *l = l.max((oa.obs[c] - ob.obs[c]).abs());
        }
    }
    // The paper's noise: 0.02 m, 0.05 m/s, 0.005 rad, 0.01 rad/s (1 sigma); 100 samples stay within 5 sigma.
    let sigma = [0.02, 0.02, 0.02, 0.05, 0.05, 0.05, 0.005, 0.005, 0.005, 0.005, 0.01, 0.01, 0.01];
    for (c, (l, s)) in largest.iter().zip(sigma).enumerate() {
        assert!(*l > 0.0 && *l < 5.0 * s, "component {c}: {l}");
    }
}

#[test]
fn an_env_is_small() {
    for path in [TrackPath::Figure8, TrackPath::Random] {
        let config = EnvConfig { track_path: path, ..EnvConfig::new(Task::Track, ActionMode::Ctbr) };
        let env = VecEnv::new(config, 2, true).unwrap();
        let (size, heap) = env.env_bytes();
        println!("{path}: env {size} B struct, ~{heap} B heap");
        assert!(size + heap < 64 * 1024, "{path}: {size} + {heap}");
    }
}

//! Plant-level tests: signs, hover, integrator accuracy, invariants (proptest), determinism, config.

use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

use super::*;

fn hover_pwm() -> f64 {
    Airframe::nominal().hover_pwm_us()
}

fn at_altitude(d_m: f64) -> InitialState {
    InitialState { pos_ned_m: Vector3::new(0.0, 0.0, d_m), ..InitialState::default() }
}

fn nominal_plant(initial: &InitialState) -> Plant {
    Plant::new(PlantConfig::default(), initial, 0).unwrap()
}

/// Applies `pwm` for `pulse_s`, then hover PWM for `coast_s`, in 2 ms steps.
fn pulse(plant: &mut Plant, pwm: [f64; 4], pulse_s: f64, coast_s: f64) {
    for _ in 0..(pulse_s / 0.002).round() as usize {
        plant.step(pwm, 2000);
    }
    for _ in 0..(coast_s / 0.002).round() as usize {
        plant.step([hover_pwm(); 4], 2000);
    }
}

#[test]
fn given_a_positive_roll_moment_when_thrust_is_about_weight_then_the_vehicle_accelerates_toward_east() {
    let mut plant = nominal_plant(&at_altitude(-10.0));
    let h = hover_pwm();
    // Mx = l(F4 - F1) > 0: left rotor up, right rotor down.
    pulse(&mut plant, [h - 30.0, h, h, h + 30.0], 0.2, 0.5);
    let t = plant.truth();
    assert!(t.euler_rad.x > 0.02, "{t:?}");
    assert!(t.vel_ned_mps.y > 0.01, "{t:?}");
    // Eq 10 is not linear, so ±30 µs leaves a tiny yaw moment: cross-coupling stays tiny.
    assert!(t.vel_ned_mps.x.abs() < 1e-3 * t.vel_ned_mps.y, "{t:?}");
}

#[test]
fn given_a_positive_pitch_moment_when_thrust_is_about_weight_then_the_vehicle_accelerates_toward_minus_north() {
    let mut plant = nominal_plant(&at_altitude(-10.0));
    let h = hover_pwm();
    // My = l(F3 - F2) > 0: front rotor up, rear rotor down: nose up.
    pulse(&mut plant, [h, h - 30.0, h + 30.0, h], 0.2, 0.5);
    let t = plant.truth();
    assert!(t.euler_rad.y > 0.02, "{t:?}");
    assert!(t.vel_ned_mps.x < -0.01, "{t:?}");
    assert!(t.vel_ned_mps.y.abs() < 1e-3 * -t.vel_ned_mps.x, "{t:?}");
}

#[test]
fn given_a_positive_yaw_moment_when_applied_then_yaw_increases() {
    let mut plant = nominal_plant(&at_altitude(-10.0));
    let h = hover_pwm();
    // Mz = λ(F2 + F3 - F1 - F4) > 0: front and rear up, right and left down.
    pulse(&mut plant, [h - 30.0, h + 30.0, h + 30.0, h - 30.0], 0.5, 0.0);
    let t = plant.truth();
    assert!(t.rate_frd_radps.z > 0.01 && t.euler_rad.z > 0.001, "{t:?}");
    assert!(t.euler_rad.x.abs() < 1e-9 && t.euler_rad.y.abs() < 1e-9, "{t:?}");
}

#[test]
fn given_the_nominal_airframe_at_hover_pwm_when_flown_10_s_then_it_drifts_less_than_1_mm() {
    let initial = at_altitude(-5.0);
    let mut plant = nominal_plant(&initial);
    let pwm = hover_pwm();
    for _ in 0..5000 {
        plant.step([pwm; 4], 2000);
    }
    let t = plant.truth();
    assert_eq!(plant.time_us(), 10_000_000);
    let drift = (t.pos_ned_m - initial.pos_ned_m).norm();
    assert!(drift < 1e-3, "{drift}");
    assert!(t.euler_rad.norm() < 1e-9);
}

#[test]
fn given_the_golden_translation_runs_first_second_when_replayed_open_loop_then_altitude_matches_the_prototype() {
    // spec/golden/golden_ACO_paper_pos_nominal.csv: the controller holds all four rotors at
    // 1837.572949 µs from t = 0 to beyond 1.1 s, climbing from D = 0 at hover lift; D printed to 1e-6 m.
    let golden = [(0.2, -0.013480), (0.4, -0.065060), (0.6, -0.156248), (0.8, -0.286969), (1.0, -0.457101)];
    let mut plant = nominal_plant(&InitialState::default());
    let mut k = 0;
    for (t_s, d_m) in golden {
        while (k as f64) * 0.002 < t_s - 1e-9 {
            plant.step([1837.572949; 4], 2000);
            k += 1;
        }
        let d = plant.truth().pos_ned_m.z;
        assert!((d - d_m).abs() < 1e-6, "t = {t_s}: D = {d} vs golden {d_m}");
    }
}

/// Pose (position, Euler) after `seconds` of a sinusoidal differential manoeuvre.
fn manoeuvre(integrator_step_s: f64, seconds: f64) -> (Vector3<f64>, Vector3<f64>) {
    // Nominal airframe: the mismatch plant's constant disturbance torque would tumble the open-loop
    // vehicle within seconds, and a tumbling body amplifies any difference.
    let config = PlantConfig { integrator_step_s, ..PlantConfig::default() };
    let mut plant = Plant::new(config, &at_altitude(-20.0), 0).unwrap();
    let h = hover_pwm();
    let steps = (seconds / 0.002).round() as usize;
    for k in 0..steps {
        let t = k as f64 * 0.002;
        let roll = 40.0 * (2.0 * std::f64::consts::PI * 1.3 * t).sin();
        let pitch = 30.0 * (2.0 * std::f64::consts::PI * 0.7 * t).cos();
        let yaw = 60.0 * (2.0 * std::f64::consts::PI * 0.4 * t).sin();
        let collective = h + 150.0 * (2.0 * std::f64::consts::PI * 0.5 * t).sin();
        plant.step(
            [collective - roll - yaw, collective - pitch + yaw, collective + pitch + yaw, collective + roll - yaw],
            2000,
        );
    }
    let t = plant.truth();
    (t.pos_ned_m, t.euler_rad)
}

#[test]
fn given_a_manoeuvre_when_integrated_at_1_ms_and_0_25_ms_then_pose_agrees_within_1e_6() {
    let (p1, e1) = manoeuvre(0.001, 4.0);
    let (p2, e2) = manoeuvre(0.00025, 4.0);
    // The manoeuvre really moves and turns the vehicle.
    assert!((p1 - Vector3::new(0.0, 0.0, -20.0)).norm() > 0.5 && e1.norm() > 0.05, "{p1} {e1}");
    assert!((p1 - p2).norm() < 1e-6, "{}", (p1 - p2).norm());
    assert!((e1 - e2).norm() < 1e-6, "{}", (e1 - e2).norm());
}

#[test]
fn given_a_step_not_multiple_of_the_substep_when_stepping_then_the_last_substep_is_shorter() {
    let config = PlantConfig::default();
    let mut coarse = Plant::new(config.clone(), &at_altitude(-10.0), 0).unwrap();
    let mut fine = Plant::new(config, &at_altitude(-10.0), 0).unwrap();
    let pwm = [1500.0, 1450.0, 1520.0, 1480.0];
    for _ in 0..400 {
        coarse.step(pwm, 2500); // 1 + 1 + 0.5 ms
    }
    for _ in 0..2000 {
        fine.step(pwm, 500);
    }
    assert_eq!(coarse.time_us(), 1_000_000);
    assert_eq!(fine.time_us(), 1_000_000);
    let (a, b) = (coarse.truth(), fine.truth());
    assert!((a.pos_ned_m - b.pos_ned_m).norm() < 1e-8, "{a:?} {b:?}");
    assert!((a.euler_rad - b.euler_rad).norm() < 1e-8);
}

#[test]
fn given_a_pwm_step_when_the_rotors_respond_then_lift_follows_the_first_order_lag() {
    let mut plant = nominal_plant(&at_altitude(-10.0));
    let f0 = plant.truth().rotor_lift_n[0];
    let fc = rotor::lift_from_pwm_n(1900.0);
    for _ in 0..20 {
        plant.step([1900.0; 4], 2000); // 40 ms = τ_m
    }
    let expected = fc + (f0 - fc) * (-1.0_f64).exp();
    let f = plant.truth().rotor_lift_n;
    // RK4 at h/τ = 1/40 is accurate to a few nN here.
    assert!(f.iter().all(|&fi| (fi - expected).abs() < 1e-8), "{f:?} vs {expected}");
}

#[test]
fn given_initial_lifts_when_reading_truth_at_t0_then_acceleration_is_consistent_with_them() {
    let initial = InitialState { rotor_lift_n: Some([13.0; 4]), ..at_altitude(-5.0) };
    let plant = nominal_plant(&initial);
    let t = plant.truth();
    assert_eq!(t.time_us, 0);
    assert!((t.acc_ned_mps2 - Vector3::new(0.0, 0.0, 9.81 - 52.0 / 5.2)).norm() < 1e-12);
    assert!((t.specific_force_frd_mps2 - Vector3::new(0.0, 0.0, -52.0 / 5.2)).norm() < 1e-12);
    // The PWM in effect at t = 0 holds those lifts.
    let pwm = plant.last_pwm_us();
    assert!(pwm.iter().all(|&p| (rotor::lift_from_pwm_n(p) - 13.0).abs() < 1e-9), "{pwm:?}");
    // Default: hover lifts of the true (plant) mass.
    let mismatch =
        Plant::new(PlantConfig { airframe: Airframe::mismatch(), ..PlantConfig::default() }, &at_altitude(-5.0), 0)
            .unwrap();
    assert!(mismatch.truth().acc_ned_mps2.norm() < 1e-12);
    assert_eq!(mismatch.truth().rotor_lift_n, [5.4 * 9.81 / 4.0; 4]);
}

#[test]
fn given_a_rotor_failure_injected_at_run_time_when_stepping_then_that_rotor_lift_decays_to_zero() {
    let mut plant = nominal_plant(&at_altitude(-50.0));
    plant.airframe_mut().rotor_health[rotor::ROTOR_FRONT] = 0.0;
    for _ in 0..50 {
        plant.step([hover_pwm(); 4], 2000);
    }
    // Front lift lost: the nose drops.
    let t = plant.truth();
    assert!(t.rate_frd_radps.y < -0.5 && t.euler_rad.y < -0.01, "{t:?}");
    for _ in 0..450 {
        plant.step([hover_pwm(); 4], 2000);
    }
    let t = plant.truth();
    assert!(t.rotor_lift_n[rotor::ROTOR_FRONT] < 1e-3, "{t:?}");
    assert!((t.rotor_lift_n[rotor::ROTOR_REAR] - Airframe::nominal().hover_lift_n()).abs() < 1e-9);
}

#[test]
fn given_a_gust_on_demand_when_injected_then_the_wind_follows_it() {
    let mut plant = nominal_plant(&at_altitude(-5.0));
    let gust = GustConfig { onset_s: 0.1, rise_s: 0.1, release_s: 0.5, ..GustConfig::default() };
    plant.wind_mut().set_gust(Some(&gust)).unwrap();
    for _ in 0..200 {
        plant.step([hover_pwm(); 4], 2000);
    }
    let t = plant.truth();
    assert!((t.wind_ned_mps - Vector3::new(0.0, 6.7, 0.0)).norm() < 1e-12, "{t:?}");
    assert!(t.vel_ned_mps.y > 0.0);
}

#[test]
fn given_sensor_noise_switched_on_when_running_with_turbulence_then_the_wind_is_bit_identical() {
    let run = |noisy: bool, seed: u64| {
        let mut config = PlantConfig {
            wind: WindConfig::from_toml("[gust]\n[turbulence]\nmodel = \"gauss_markov\"\n"),
            ..PlantConfig::default()
        };
        if noisy {
            config.sensors.accel.white_sigma = 0.2;
            config.sensors.gyro.bias_walk_sigma_per_sqrt_s = 0.001;
            config.sensors.gps.position.white_sigma = 0.5;
        }
        let mut plant = Plant::new(config, &at_altitude(-5.0), seed).unwrap();
        let mut winds = Vec::new();
        for _ in 0..1000 {
            plant.step([hover_pwm(); 4], 2000);
            let _ = plant.sample_sensors();
            let _ = plant.sample_state(&StateNoise::paper());
            winds.push(plant.truth().wind_ned_mps);
        }
        (winds, plant.truth())
    };
    let (quiet, quiet_truth) = run(false, 3);
    let (noisy, noisy_truth) = run(true, 3);
    assert_eq!(quiet, noisy);
    assert_eq!(quiet_truth, noisy_truth);
    let (other, _) = run(false, 4);
    assert_ne!(quiet, other);
}

impl WindConfig {
    fn from_toml(text: &str) -> Self {
        toml::from_str(text).unwrap()
    }
}

#[test]
fn given_the_same_seed_when_running_twice_then_truth_and_sensors_are_identical() {
    let config = PlantConfig::from_toml_str(
        "[airframe]\npreset = \"mismatch\"\n[wind]\nbeaufort = 4\n[wind.gust]\nonset_s = 0.2\nrise_s = 0.2\nrelease_s = 1.0\n\
         [wind.turbulence]\nmodel = \"dryden\"\n[sensors.accel]\nwhite_sigma = 0.1\n[sensors.gps]\nlatency_s = 0.1\n",
    )
    .unwrap();
    let run = || {
        let mut plant = Plant::new(config.clone(), &at_altitude(-3.0), 17).unwrap();
        let mut out = Vec::new();
        for k in 0..800 {
            let pwm = 1500.0 + 100.0 * (k as f64 * 0.01).sin();
            plant.step([pwm, 1510.0, 1490.0, pwm], 2000);
            out.push((plant.truth(), plant.sample_sensors()));
        }
        out
    };
    assert_eq!(run(), run());
}

#[test]
fn given_a_full_toml_when_parsed_then_every_section_lands_and_errors_are_clear() {
    let config = PlantConfig::from_toml_str(
        r#"
        integrator_step_s = 0.0005
        [airframe]
        preset = "mismatch"
        mass_kg = 5.3
        [wind]
        steady_ned_mps = [1.0, 0.0, 0.0]
        [wind.gust]
        amplitude_mps = 4.0
        [wind.turbulence]
        model = "gauss_markov"
        scale_with_gust = true
        [sensors.home]
        lat_deg = 54.9
        lon_deg = 23.9
        alt_amsl_m = 70.0
        [sensors.gps]
        rate_hz = 5.0
        latency_s = 0.1
        [ground]
        ground_d_m = 1.0
        "#,
    )
    .unwrap();
    assert_eq!(config.integrator_step_s, 0.0005);
    assert_eq!(config.airframe.mass_kg, 5.3);
    assert_eq!(config.airframe.thrust_scale, 0.99);
    assert_eq!(config.wind.gust.as_ref().unwrap().amplitude_mps, Some(4.0));
    assert_eq!(config.sensors.home.lat_deg, 54.9);
    assert_eq!(config.sensors.gps.latency_s, 0.1);
    assert_eq!(config.ground.ground_d_m, 1.0);
    assert_eq!(PlantConfig::from_toml_str("").unwrap(), PlantConfig::default());
    Plant::new(config, &InitialState::default(), 0).unwrap();

    let unknown = PlantConfig::from_toml_str("[airframe]\npreset = \"x8\"\n").unwrap_err().to_string();
    assert!(unknown.contains("unknown airframe preset \"x8\""), "{unknown}");
    let typo = PlantConfig::from_toml_str("integrator_step = 0.001\n").unwrap_err().to_string();
    assert!(typo.contains("unknown field"), "{typo}");
    let bad_mass = PlantConfig::from_toml_str("[airframe]\nmass_kg = -1.0\n").unwrap_err().to_string();
    assert!(bad_mass.contains("airframe.mass_kg") && bad_mass.contains("> 0"), "{bad_mass}");
    let slow = PlantConfig { integrator_step_s: 0.1, ..PlantConfig::default() };
    let err = Plant::new(slow, &InitialState::default(), 0).unwrap_err().to_string();
    assert!(err.contains("integrator_step_s"), "{err}");
    let below = Plant::new(PlantConfig::default(), &at_altitude(0.5), 0).unwrap_err().to_string();
    assert!(below.contains("below the ground"), "{below}");
    let nan = InitialState { vel_ned_mps: Vector3::new(f64::NAN, 0.0, 0.0), ..InitialState::default() };
    assert!(Plant::new(PlantConfig::default(), &nan, 0).is_err());
}

fn no_thrust_config(drag: bool, inertia: Vector3<f64>) -> PlantConfig {
    PlantConfig {
        airframe: Airframe {
            rotor_health: [0.0; 4],
            drag_cda_m2: if drag { 0.1 } else { 0.0 },
            inertia_kgm2: inertia,
            ..Airframe::nominal()
        },
        ground: GroundConfig { enabled: false, ground_d_m: 0.0 },
        ..PlantConfig::default()
    }
}

fn any_pwm() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(f64::MIN),
        -1.0e12..1.0e12_f64,
        900.0..2100.0_f64,
    ]
}

proptest! {
    // 64 cases of the default 256: PROPTEST_CASES scales them with every other property test.
    #![proptest_config(ProptestConfig::with_cases(ProptestConfig::default().cases * 64 / 256))]

    #[test]
    fn given_no_thrust_and_no_drag_when_released_then_it_falls_freely_at_g(
        v0 in prop::array::uniform3(-5.0..5.0_f64),
        euler in prop::array::uniform3(-1.0..1.0_f64),
        rate in prop::array::uniform3(-3.0..3.0_f64),
        steps in 10usize..1000,
    ) {
        let initial = InitialState {
            pos_ned_m: Vector3::new(1.0, -2.0, -100.0),
            vel_ned_mps: Vector3::from(v0),
            euler_rad: Vector3::from(euler),
            rate_frd_radps: Vector3::from(rate),
            rotor_lift_n: Some([0.0; 4]),
        };
        let mut plant = Plant::new(no_thrust_config(false, Vector3::new(0.08, 0.08, 0.12)), &initial, 0).unwrap();
        for _ in 0..steps {
            plant.step([1500.0; 4], 2000);
        }
        let t_s = steps as f64 * 0.002;
        let g = Vector3::new(0.0, 0.0, 9.81);
        let truth = plant.truth();
        let expected_p = initial.pos_ned_m + initial.vel_ned_mps * t_s + g * (0.5 * t_s * t_s);
        let expected_v = initial.vel_ned_mps + g * t_s;
        prop_assert!((truth.pos_ned_m - expected_p).norm() < 1e-9, "{} vs {}", truth.pos_ned_m, expected_p);
        prop_assert!((truth.vel_ned_mps - expected_v).norm() < 1e-9);
        prop_assert!((truth.acc_ned_mps2 - g).norm() < 1e-12);
        prop_assert!(truth.specific_force_frd_mps2.norm() < 1e-12);
    }

    #[test]
    fn given_a_torque_free_spin_when_integrated_then_inertial_angular_momentum_is_conserved(
        ixy in prop::array::uniform2(0.05..0.2_f64),
        iz_frac in 0.1..1.0_f64,
        rate in prop::array::uniform3(-3.0..3.0_f64),
        euler in prop::array::uniform3(-1.0..1.0_f64),
    ) {
        // Izz within the triangle inequality.
        let (ix, iy) = (ixy[0], ixy[1]);
        let iz = (ix - iy).abs() + iz_frac * (ix + iy - (ix - iy).abs());
        let inertia = Vector3::new(ix, iy, iz);
        let initial = InitialState {
            pos_ned_m: Vector3::new(0.0, 0.0, -100.0),
            euler_rad: Vector3::from(euler),
            rate_frd_radps: Vector3::from(rate),
            rotor_lift_n: Some([0.0; 4]),
            ..InitialState::default()
        };
        let mut plant = Plant::new(no_thrust_config(true, inertia), &initial, 0).unwrap();
        let momentum = |t: &Truth| t.q_ned_frd.to_rotation_matrix().matrix() * Matrix3::from_diagonal(&inertia) * t.rate_frd_radps;
        let energy = |t: &Truth| 0.5 * t.rate_frd_radps.dot(&inertia.component_mul(&t.rate_frd_radps));
        let (l0, e0) = (momentum(&plant.truth()), energy(&plant.truth()));
        for _ in 0..1000 {
            plant.step([1000.0; 4], 2000);
            let t = plant.truth();
            prop_assert!((t.q_ned_frd.quaternion().norm() - 1.0).abs() < 1e-12);
        }
        let t = plant.truth();
        let scale = l0.norm().max(1e-3);
        prop_assert!((momentum(&t) - l0).norm() < 1e-6 * scale, "{} vs {}", momentum(&t), l0);
        prop_assert!((energy(&t) - e0).abs() < 1e-6 * e0.max(1e-6));
    }

    #[test]
    fn given_any_pwm_including_nan_and_infinities_when_stepping_then_the_state_stays_finite(
        commands in prop::collection::vec(prop::array::uniform4(any_pwm()), 1..60),
        dt_us in 1u64..40_000,
    ) {
        let config = PlantConfig {
            airframe: Airframe::mismatch(),
            ..PlantConfig::default()
        };
        let mut plant = Plant::new(config, &at_altitude(-2.0), 1).unwrap();
        for pwm in &commands {
            plant.step(*pwm, dt_us);
            let t = plant.truth();
            prop_assert!(plant.state().is_finite());
            prop_assert!(t.acc_ned_mps2.iter().chain(t.euler_rad.iter()).chain(t.specific_force_frd_mps2.iter()).all(|x| x.is_finite()));
            prop_assert!((t.q_ned_frd.quaternion().norm() - 1.0).abs() < 1e-12);
            prop_assert!(plant.last_pwm_us().iter().all(|p| (1000.0..=2000.0).contains(p)));
            let s = plant.sample_sensors();
            prop_assert!(s.accel_frd_mps2.iter().all(|x| x.is_finite()) && s.baro.is_some_and(|b| b.pressure_hpa.is_finite()));
        }
    }
}

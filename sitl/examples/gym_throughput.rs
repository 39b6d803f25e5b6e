//! Throughput of `sitl::gym::VecEnv`: env steps per second for a batch, per action mode, with a
//! constant action near the mismatch plant's hover (no policy cost). `cargo run --release -p sitl --example gym_throughput --
//! [num_envs] [steps] [modes,comma-separated] [threads] [hover|track]`.

use std::time::Instant;

use sitl::gym::{ActionMode, EnvConfig, Task, VecEnv};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(Ok(1024), |s| s.parse())?;
    let steps: usize = args.get(2).map_or(Ok(200), |s| s.parse())?;
    let modes = args.get(3).map_or("motors,ctbr", String::as_str).to_owned();
    if let Some(threads) = args.get(4) {
        rayon::ThreadPoolBuilder::new().num_threads(threads.parse()?).build_global()?;
    }
    for mode in modes.split(',') {
        let action: ActionMode = mode.parse()?;
        let task: Task = args.get(5).map_or("hover", String::as_str).parse()?;
        let config = EnvConfig::new(task, action);
        let d = config.obs_dim();
        let mut env = VecEnv::new(config, n, true)?;
        let (size, heap) = env.env_bytes();
        let act = match action {
            ActionMode::Motors => [0.6_f32; 4],
            ActionMode::Ctbr | ActionMode::Attitude => [0.65, 0.0, 0.0, 0.0],
            ActionMode::Velocity => [0.0; 4],
        };
        let actions: Vec<f32> = (0..n).flat_map(|_| act).collect();
        let (mut obs, mut rew) = (vec![0.0; n * d], vec![0.0; n]);
        let (mut term, mut trunc, mut now) = (vec![false; n], vec![false; n], vec![false; n]);
        let t0 = Instant::now();
        for seed in 0..5 {
            env.reset(seed, &mut obs)?;
        }
        let reset_us = t0.elapsed().as_secs_f64() * 1e6 / (5 * n) as f64;
        env.reset(1, &mut obs)?;
        let t0 = Instant::now();
        let mut resets = 0;
        for _ in 0..steps {
            env.step(&actions, &mut obs, &mut rew, &mut term, &mut trunc, &mut now)?;
            resets += now.iter().filter(|x| **x).count();
        }
        let wall = t0.elapsed().as_secs_f64();
        println!(
            "{task} {mode:>9}: N={n} x {steps} steps in {wall:.3} s: {:.0} env steps/s ({resets} autoresets, {reset_us:.1} µs of wall per env reset); env struct {size} B, heap ~{heap} B",
            (n * steps) as f64 / wall
        );
    }
    Ok(())
}

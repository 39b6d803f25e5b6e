//! One whole in-process run of every built-in scenario with ACO, as `sitl scenario` and `sitl sweep` fly it
//! (lockstep plant, controller, reference, metrics; the trace at 50 Hz), warm. Throughput is in simulated
//! milliseconds, so criterion's "Kelem/s" divided by 1,000 is the real-time factor on one core: 2.5 Melem/s
//! is 2,500x real time. `tick_floor` times what every tick of a run must do whatever the scenario (plant
//! step, truth, the noisy state, the ACO update) in a closed-loop hover, and so bounds the factor any
//! scenario can reach on this machine.

use std::hint::black_box;

use autopilot::core::control::{ControllerKind, LoopRates, Reference, new_controller};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use sitl::plant::sensors::StateNoise;
use sitl::plant::{InitialState, Plant};
use sitl::scenario::runner::{RunOptions, control_input, lockstep_plant_config, run};
use sitl::scenario::{BUILT_INS, Scenario};

fn scenario_run(c: &mut Criterion) {
    let mut group = c.benchmark_group("scenario_run_aco");
    // A run is 8-36 simulated seconds (tens of milliseconds): a handful of samples is enough.
    group.sample_size(20);
    for (name, _) in BUILT_INS {
        let scenario = Scenario::load(name).expect("built-in scenarios load");
        let modes = scenario.reference_modes();
        group.throughput(Throughput::Elements((scenario.duration_s * 1000.0).round() as u64));
        for &mode in &modes {
            let opts = RunOptions { mode, ..RunOptions::new(ControllerKind::ACO) };
            let id = if modes.len() > 1 { format!("{name}/{mode}") } else { (*name).to_owned() };
            group.bench_function(id, |b| b.iter(|| black_box(run(black_box(&scenario), &opts).expect("runs"))));
        }
    }
    group.finish();
}

fn tick_floor(c: &mut Criterion) {
    let mut group = c.benchmark_group("tick_floor_aco");
    let scenario = Scenario::load("gust-hover").expect("built-in scenarios load");
    let rates = LoopRates::default();
    let dt_us = u64::from(1_000_000 / rates.inner_hz);
    // One tick is 1000 / inner_hz simulated milliseconds (2 at 500 Hz).
    group.throughput(Throughput::Elements(u64::from(1000 / rates.inner_hz)));
    for (name, noise) in [("noise-free", StateNoise::none()), ("paper-noise", StateNoise::paper())] {
        let config = lockstep_plant_config(&scenario, None).expect("the gust-hover plant builds");
        let hover = Vector3::new(0.0, 0.0, -1.5);
        let initial = InitialState { pos_ned_m: hover, ..InitialState::default() };
        let mut plant = Plant::new(config, &initial, 1).expect("the plant builds");
        let mut controller = new_controller(ControllerKind::ACO, &scenario.controller);
        let reference = Reference::position(hover, 0.0);
        group.bench_function(name, |b| {
            b.iter(|| {
                let truth = plant.truth();
                let state = plant.sample_state_of(&truth, &noise);
                let pwm_us = controller.update(&control_input(&state), black_box(&reference));
                plant.step(pwm_us, dt_us);
            });
        });
        let truth = plant.truth();
        assert!((truth.pos_ned_m - hover).norm() < 0.5, "the benchmark's hover held: {:?}", truth.pos_ned_m);
    }
    group.finish();
}

criterion_group!(benches, scenario_run, tick_floor);
criterion_main!(benches);

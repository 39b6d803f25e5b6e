//! One plant step of 2 ms as the paper's loops run it: two 1 ms RK4 substeps with rotor lag, the gust with
//! Gauss-Markov turbulence, and a full noisy sensor sample (IMU, magnetometer, barometer, GPS schedule).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sitl::plant::{InitialState, Plant, PlantConfig};

fn noisy_turbulent_config() -> PlantConfig {
    PlantConfig::from_toml_str(
        r#"
        [wind.gust]
        onset_s = 0.0
        release_s = 1.0e6
        [wind.turbulence]
        model = "gauss_markov"
        scale_with_gust = true
        [sensors.accel]
        white_sigma = 0.2
        bias_walk_sigma_per_sqrt_s = 0.001
        [sensors.gyro]
        white_sigma = 0.01
        bias_walk_sigma_per_sqrt_s = 0.0001
        [sensors.mag]
        white_sigma = 0.005
        [sensors.baro]
        white_sigma_m = 0.3
        [sensors.gps]
        latency_s = 0.1
        [sensors.gps.position]
        white_sigma = 0.5
        [sensors.gps.velocity]
        white_sigma = 0.1
        "#,
    )
    .expect("benchmark config parses")
}

fn plant_step(c: &mut Criterion) {
    // Nominal airframe at hover PWM: open loop, the turbulence only pushes it around (drag acts at the
    // centre of mass), so millions of iterations stay in a physical flight regime.
    let initial = InitialState { pos_ned_m: nalgebra::Vector3::new(0.0, 0.0, -100.0), ..InitialState::default() };
    let config = noisy_turbulent_config();
    let hover_pwm_us = config.airframe.hover_pwm_us();
    let mut plant = Plant::new(config, &initial, 1).expect("benchmark plant builds");
    let pwm = [hover_pwm_us; 4];
    c.bench_function("plant_step_2ms_turbulence_noisy_sensors", |b| {
        b.iter(|| {
            plant.step(black_box(pwm), black_box(2000));
            black_box(plant.sample_sensors())
        });
    });
}

criterion_group!(benches, plant_step);
criterion_main!(benches);

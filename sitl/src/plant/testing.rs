//! Test fixtures of the plant that tests elsewhere in the crate share: a climbing, turning plant and
//! its sensor samples under a schedule of changes.

use nalgebra::Vector3;

use super::sensors::{SensorConfig, SensorSample};
use super::{InitialState, Plant, PlantConfig};

/// A climbing, turning plant (every sensor's truth changes from sample to sample), with modest sensor
/// noise, seed 7.
pub(crate) fn moving_plant() -> Plant {
    let config = PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() };
    let initial = InitialState {
        pos_ned_m: Vector3::new(0.0, 0.0, -20.0),
        vel_ned_mps: Vector3::new(2.0, 1.0, -0.5),
        rate_frd_radps: Vector3::new(0.1, -0.05, 0.2),
        ..InitialState::default()
    };
    Plant::new(config, &initial, 7).expect("plant")
}

/// PWM that keeps the plant climbing and turning.
pub(crate) const PWM_US: [f64; 4] = [1700.0, 1650.0, 1700.0, 1600.0];

/// The sensor samples of `steps` 2 ms steps of [`moving_plant`], calling `at(k, plant)` before sample k.
pub(crate) fn run(steps: usize, mut at: impl FnMut(usize, &mut Plant)) -> Vec<SensorSample> {
    let mut plant = moving_plant();
    (0..steps)
        .map(|k| {
            at(k, &mut plant);
            let s = plant.sample_sensors();
            plant.step(PWM_US, 2000);
            s
        })
        .collect()
}

//! The airframe's SIM_ parameters: per-rotor thrust multipliers (SIM_MOT1_EFF..SIM_MOT4_EFF, the rotors'
//! health), the payload (SIM_PAYLOAD_KG at SIM_CG_OFS_X/Y) and the multiplier of an injected partial
//! motor failure (SIM_MOT_WRONG_EFF, stored only). In, a set the table's range check passed; out, the
//! plant's airframe changed from its next step.

use nalgebra::Vector3;

use super::{SIM_PARAMS, idx};
use crate::plant::Plant;
use autopilot::core::mavlink::params::Applied;

/// The start values of the airframe's parameters, read from `plant` (its rotor health and payload).
pub(super) fn initial_values(plant: &Plant, values: &mut [f32; SIM_PARAMS.len()]) {
    let airframe = &plant.config().airframe;
    for (i, health) in airframe.rotor_health.iter().enumerate() {
        values[idx::MOT1_EFF + i] = *health as f32;
    }
    values[idx::PAYLOAD_KG] = airframe.payload.mass_kg as f32;
    values[idx::CG_OFS_X] = airframe.payload.offset_frd_m.x as f32;
    values[idx::CG_OFS_Y] = airframe.payload.offset_frd_m.y as f32;
}

/// Apply a set of airframe parameter `index` (one of SIM_MOT1_EFF..SIM_CG_OFS_Y) to `value`, within the
/// table's range already (a health in [0, 1], a mass >= 0, an offset within ±0.5 m: always physical).
pub(super) fn apply(index: usize, value: f32, plant: &mut Plant) -> Applied {
    let airframe = plant.airframe_mut();
    let v = f64::from(value);
    match index {
        idx::MOT1_EFF..=idx::MOT4_EFF => airframe.rotor_health[index - idx::MOT1_EFF] = v,
        idx::PAYLOAD_KG => airframe.payload.mass_kg = v,
        idx::CG_OFS_X => airframe.payload.offset_frd_m = Vector3::new(v, airframe.payload.offset_frd_m.y, 0.0),
        idx::CG_OFS_Y => airframe.payload.offset_frd_m = Vector3::new(airframe.payload.offset_frd_m.x, v, 0.0),
        // Read when a motor failure of type WRONG is injected: nothing to change now.
        idx::MOT_WRONG_EFF => {}
        _ => {}
    }
    Applied::default()
}

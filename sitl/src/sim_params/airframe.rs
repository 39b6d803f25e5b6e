//! The airframe's SIM_ parameters: per-rotor thrust multipliers (SIM_MOT1_EFF..SIM_MOT4_EFF, the rotors'
//! health), the payload (SIM_PAYLOAD_KG at SIM_CG_OFS_X/Y) and the multiplier of an injected partial
//! motor failure (SIM_MOT_WRNG_EFF, stored only, `sim_params/sensors.rs`). In, a set the table's range check passed; out, the
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
        idx::MOT_WRNG_EFF => {}
        _ => {}
    }
    Applied::default()
}

#[cfg(test)]
mod tests {
    use crate::plant::rotor::lift_from_pwm_n;
    use crate::plant::{InitialState, Plant, PlantConfig};
    use crate::sim_params::SimParamService;
    use crate::sim_params::events::param_index;

    fn set(s: &mut SimParamService, plant: &mut Plant, name: &str, value: f32) -> Result<(), String> {
        s.set_now(param_index(name).expect("a SIM_ parameter"), value, plant)
    }

    #[test]
    fn given_sim_mot3_eff_0_6_then_rotor_3_settles_at_0_6_of_its_lift_and_the_others_keep_theirs() {
        let initial = InitialState { pos_ned_m: nalgebra::Vector3::new(0.0, 0.0, -50.0), ..InitialState::default() };
        let mut plant = Plant::new(
            PlantConfig {
                ground: crate::plant::GroundConfig { enabled: false, ground_d_m: 0.0 },
                ..PlantConfig::default()
            },
            &initial,
            1,
        )
        .unwrap();
        let mut s = SimParamService::new(1, &plant);
        assert_eq!(s.get("SIM_MOT3_EFF"), Some(1.0));
        set(&mut s, &mut plant, "SIM_MOT3_EFF", 0.6).unwrap();
        assert_eq!(plant.config().airframe.rotor_health, [1.0, 1.0, f64::from(0.6_f32), 1.0]);
        // 0.5 s at 1500 µs (12.5 lag constants): each lift is its health times F10(1500).
        for _ in 0..250 {
            plant.step([1500.0; 4], 2000);
        }
        let f = lift_from_pwm_n(1500.0);
        let lift = plant.truth().rotor_lift_n;
        assert!((lift[2] - f64::from(0.6_f32) * f).abs() < 1e-4 * f, "{lift:?}");
        assert!((lift[0] - f).abs() < 1e-4 * f && (lift[3] - f).abs() < 1e-4 * f, "{lift:?}");
        // Out of range: refused with the table's reason, nothing changed.
        let e = set(&mut s, &mut plant, "SIM_MOT3_EFF", 1.2).unwrap_err();
        assert!(e.contains("SIM_MOT3_EFF") && e.contains("1.2"), "{e}");
        assert_eq!((plant.config().airframe.rotor_health[2], s.get("SIM_MOT3_EFF")), (f64::from(0.6_f32), Some(0.6)));
    }

    #[test]
    fn given_payload_sets_then_the_airframe_carries_them_and_a_new_service_reads_them_back() {
        let mut plant = Plant::new(PlantConfig::default(), &InitialState::default(), 1).unwrap();
        let mut s = SimParamService::new(1, &plant);
        set(&mut s, &mut plant, "SIM_PAYLOAD_KG", 0.5).unwrap();
        set(&mut s, &mut plant, "SIM_CG_OFS_Y", -0.04).unwrap();
        set(&mut s, &mut plant, "SIM_CG_OFS_X", 0.1).unwrap();
        let p = plant.config().airframe.payload;
        assert_eq!(
            (p.mass_kg, p.offset_frd_m.x, p.offset_frd_m.y, p.offset_frd_m.z),
            (0.5, f64::from(0.1_f32), f64::from(-0.04_f32), 0.0)
        );
        assert!((plant.config().airframe.weight_n() - 5.7 * 9.81).abs() < 1e-12);
        let fresh = SimParamService::new(1, &plant);
        assert_eq!(
            (fresh.get("SIM_PAYLOAD_KG"), fresh.get("SIM_CG_OFS_X"), fresh.get("SIM_CG_OFS_Y")),
            (Some(0.5), Some(0.1), Some(-0.04))
        );
        assert!(set(&mut s, &mut plant, "SIM_CG_OFS_X", 0.6).is_err());
        assert!(set(&mut s, &mut plant, "SIM_PAYLOAD_KG", -1.0).is_err());
        assert_eq!(plant.config().airframe.payload, p);
    }
}

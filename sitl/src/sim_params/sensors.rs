//! The SIM_ parameters of the plant's sensor, battery and link faults (SIM_GPS_FAIL .. SIM_LINK_LOSS in
//! [`super::SIM_PARAMS`]): their start values read from the plant, and what a set that passed the table's
//! range check does to the plant (or why the plant refuses it, with nothing changed).
//!
//! - SIM_GPS_FAIL, SIM_BARO_FAIL, SIM_MAG_FAIL, SIM_ACC_FAIL, SIM_GYRO_FAIL: the sensor's fault as a
//!   MAVLink `FAILURE_TYPE` number ([`crate::plant::faults`]); a number inside the range that the sensor
//!   does not have (GPS 3 garbage, accelerometer or gyro 1 off) is refused, naming the ones it has
//!   (`SIM_ACC_FAIL: only 0 ok, 2 stuck, 3 garbage`).
//! - SIM_GPS_JUMP_N, SIM_GPS_JUMP_E: the wrong GPS's offset (m), from its next fix.
//! - SIM_BAT_FAIL: 1 the battery monitor reports the pack empty ([`crate::plant::battery`]); refused on a
//!   plant that simulates no pack.
//! - SIM_MOT_WRNG_EFF: stored only; the thrust an injected motor WRONG failure leaves
//!   ([`super::failure_sets`]).
//! - SIM_LINK_DELAY, SIM_LINK_LOSS: the plant link's added delay and loss ([`crate::link`]).

use crate::plant::{Fault, Plant, Sensor};

use super::idx;

/// The sensor whose fault parameter `index` is.
fn fault_sensor(index: usize) -> Option<Sensor> {
    match index {
        idx::GPS_FAIL => Some(Sensor::Gps),
        idx::BARO_FAIL => Some(Sensor::Baro),
        idx::MAG_FAIL => Some(Sensor::Mag),
        idx::ACC_FAIL => Some(Sensor::Accel),
        idx::GYRO_FAIL => Some(Sensor::Gyro),
        _ => None,
    }
}

/// The fault parameter of `sensor`.
fn fault_index(sensor: Sensor) -> usize {
    match sensor {
        Sensor::Gps => idx::GPS_FAIL,
        Sensor::Baro => idx::BARO_FAIL,
        Sensor::Mag => idx::MAG_FAIL,
        Sensor::Accel => idx::ACC_FAIL,
        Sensor::Gyro => idx::GYRO_FAIL,
    }
}

/// The fault a set of `sensor`'s parameter to `value` (inside the table's range) asks for.
///
/// # Errors
/// The sensor does not have it: what it takes (the port's text is one STATUSTEXT, 50 bytes, after the
/// parameter's name).
fn sensor_fault(sensor: Sensor, value: f32) -> Result<Fault, String> {
    let only = || {
        let known: Vec<String> = sensor.faults().iter().map(|f| format!("{} {}", f.failure_type(), f.word())).collect();
        format!("only {}", known.join(", "))
    };
    Fault::from_failure_type(value as u32).filter(|f| value >= 0.0 && sensor.faults().contains(f)).ok_or_else(only)
}

/// Whether any plant takes a set of this module's parameter `index` to `value` (inside the table's
/// range): a sensor's fault parameter only takes the failure types the sensor has.
///
/// # Errors
/// As [`apply`] for a fault the sensor does not have.
pub(super) fn check(index: usize, value: f32) -> Result<(), String> {
    fault_sensor(index).map_or(Ok(()), |sensor| sensor_fault(sensor, value).map(|_| ()))
}

/// Whether parameter `index` is one of this module's.
pub(super) fn owns(index: usize) -> bool {
    (idx::GPS_FAIL..=idx::LINK_LOSS).contains(&index)
}

/// This module's values in `values` (indexed as [`super::SIM_PARAMS`]) as the plant has them now.
pub(super) fn initial_values(plant: &Plant, values: &mut [f32]) {
    let faults = plant.sensor_faults();
    for sensor in Sensor::ALL {
        values[fault_index(sensor)] = f32::from(faults.fault(sensor).failure_type());
    }
    let [north_m, east_m] = faults.gps_jump_ne_m();
    values[idx::GPS_JUMP_N] = north_m as f32;
    values[idx::GPS_JUMP_E] = east_m as f32;
    values[idx::BAT_FAIL] = f32::from(u8::from(plant.battery().is_some_and(crate::plant::Battery::failed)));
    values[idx::LINK_DELAY] = (plant.link_faults().delay_us() / 1000) as f32;
    values[idx::LINK_LOSS] = plant.link_faults().loss_pct() as f32;
}

/// Apply a set of this module's parameter `index` to `value` (inside the table's range) to `plant`.
///
/// # Errors
/// The plant's reason for refusing it (a fault the sensor does not have, a battery fault without a pack);
/// nothing changed then.
pub(super) fn apply(index: usize, value: f32, plant: &mut Plant) -> Result<(), String> {
    if let Some(sensor) = fault_sensor(index) {
        let fault = sensor_fault(sensor, value)?;
        return plant.sensor_faults_mut().set(sensor, fault).map_err(|e| format!("only {}", e.known));
    }
    match index {
        idx::GPS_JUMP_N | idx::GPS_JUMP_E => {
            let mut jump = plant.sensor_faults().gps_jump_ne_m();
            jump[index - idx::GPS_JUMP_N] = f64::from(value);
            plant.sensor_faults_mut().set_gps_jump_ne_m(jump);
        }
        idx::BAT_FAIL => {
            if plant.battery().is_none() {
                if value == 1.0 {
                    return Err("the plant simulates no battery".into());
                }
            } else {
                plant.battery_mut().set_failed(value == 1.0);
            }
        }
        idx::LINK_DELAY => plant.link_faults_mut().set_delay_us(value as u64 * 1000),
        idx::LINK_LOSS => plant.link_faults_mut().set_loss_pct(f64::from(value)),
        // SIM_MOT_WRNG_EFF: read by the failure injection, nothing to change now.
        _ => debug_assert_eq!(index, idx::MOT_WRNG_EFF),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use autopilot::core::mavlink::params::{decode_value, encode_value, param_name};
    use mavlink::dialects::common::{MavMessage, MavResult, PARAM_SET_DATA};
    use mavlink::types::CharArray;
    use proptest::prelude::*;

    use super::super::{PLANT_COMPONENT_ID, SIM_PARAMS, SimParamService};
    use super::*;
    use crate::plant::{BatteryConfig, InitialState, PlantConfig};
    use autopilot::core::mavlink::failure::FailureRequest;

    const SYS: u8 = 1;

    /// This module's parameters.
    const NAMES: [&str; 11] = [
        "SIM_GPS_FAIL",
        "SIM_BARO_FAIL",
        "SIM_MAG_FAIL",
        "SIM_ACC_FAIL",
        "SIM_GYRO_FAIL",
        "SIM_GPS_JUMP_N",
        "SIM_GPS_JUMP_E",
        "SIM_BAT_FAIL",
        "SIM_MOT_WRNG_EFF",
        "SIM_LINK_DELAY",
        "SIM_LINK_LOSS",
    ];

    fn plant() -> Plant {
        Plant::new(PlantConfig::default(), &InitialState::default(), 1).expect("plant")
    }

    /// A PARAM_SET of `name` to `value` in the parameter's own type, as a ground station sends it.
    fn set_msg(name: &str, value: f32) -> MavMessage {
        let kind =
            SIM_PARAMS.iter().find(|d| d.name == name).map_or(autopilot::core::params::ParamKind::Real, |d| d.kind);
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: encode_value(kind, value),
            target_system: SYS,
            target_component: PLANT_COMPONENT_ID,
            param_id: CharArray::from(name),
            param_type: kind.mav_param_type(),
        })
    }

    /// The STATUSTEXTs and the (name, value) of the PARAM_VALUEs in `replies`.
    fn split(replies: &[MavMessage]) -> (Vec<String>, Vec<(String, f32)>) {
        let mut texts = Vec::new();
        let mut values = Vec::new();
        for m in replies {
            match m {
                MavMessage::STATUSTEXT(t) => {
                    let len = t.text.iter().position(|&b| b == 0).unwrap_or(50);
                    texts.push(String::from_utf8_lossy(&t.text[..len]).into_owned());
                }
                MavMessage::PARAM_VALUE(v) => {
                    values.push((param_name(&v.param_id), decode_value(v.param_type, v.param_value).expect("decodes")))
                }
                _ => {}
            }
        }
        (texts, values)
    }

    /// Everything this module's parameters act on, as the plant has it.
    fn observed(plant: &Plant) -> (Vec<Fault>, [f64; 2], bool, u64, f64) {
        let f = plant.sensor_faults();
        (
            Sensor::ALL.iter().map(|s| f.fault(*s)).collect(),
            f.gps_jump_ne_m(),
            plant.battery().is_some_and(crate::plant::Battery::failed),
            plant.link_faults().delay_us(),
            plant.link_faults().loss_pct(),
        )
    }

    #[test]
    fn given_each_parameter_set_through_the_port_then_the_plant_changes_and_the_value_is_echoed() {
        let mut plant = plant();
        let mut s = SimParamService::new(SYS, &plant);
        for (name, value) in [
            ("SIM_GPS_FAIL", 4.0),
            ("SIM_BARO_FAIL", 1.0),
            ("SIM_MAG_FAIL", 2.0),
            ("SIM_ACC_FAIL", 3.0),
            ("SIM_GYRO_FAIL", 2.0),
            ("SIM_GPS_JUMP_N", -12.5),
            ("SIM_GPS_JUMP_E", 7.0),
            ("SIM_BAT_FAIL", 1.0),
            ("SIM_MOT_WRNG_EFF", 0.4),
            ("SIM_LINK_DELAY", 20.0),
            ("SIM_LINK_LOSS", 12.5),
        ] {
            let (texts, values) = split(&s.on_message(&set_msg(name, value), &mut plant));
            assert!(texts.is_empty(), "{name}: {texts:?}");
            assert_eq!(values, [(name.to_owned(), value)], "{name} echoed");
            assert_eq!(s.get(name), Some(value));
        }
        let want = (
            vec![Fault::Wrong, Fault::Off, Fault::Stuck, Fault::Garbage, Fault::Stuck],
            [-12.5, 7.0],
            true,
            20_000,
            12.5,
        );
        assert_eq!(observed(&plant), want);
        assert_eq!(plant.battery().expect("pack").reading().remaining, 0.0, "reports empty");
        // And a service started on that plant reads every value back from it.
        let again = SimParamService::new(SYS, &plant);
        for name in NAMES.iter().filter(|n| **n != "SIM_MOT_WRNG_EFF") {
            assert_eq!(again.get(name), s.get(name), "{name} read from the plant");
        }
    }

    #[test]
    fn given_a_failure_type_the_sensor_does_not_have_then_the_set_is_refused_with_the_reason_and_nothing_changes() {
        let mut plant = plant();
        let mut s = SimParamService::new(SYS, &plant);
        for (name, value, text) in [
            ("SIM_ACC_FAIL", 1.0, "SIM_ACC_FAIL: only 0 ok, 2 stuck, 3 garbage"),
            ("SIM_GYRO_FAIL", 1.0, "SIM_GYRO_FAIL: only 0 ok, 2 stuck, 3 garbage"),
            ("SIM_GPS_FAIL", 3.0, "SIM_GPS_FAIL: only 0 ok, 1 off, 2 stuck, 4 wrong"),
            ("SIM_BARO_FAIL", 3.0, "SIM_BARO_FAIL: 3 not in 0..2"),
            ("SIM_LINK_LOSS", 95.0, "SIM_LINK_LOSS: 95 not in 0..90"),
        ] {
            let before = observed(&plant);
            let (texts, values) = split(&s.on_message(&set_msg(name, value), &mut plant));
            assert_eq!(texts, [text.to_owned()], "{name}: one STATUSTEXT, whole");
            assert_eq!(values, [(name.to_owned(), 0.0)], "{name}: the unchanged value echoed");
            assert_eq!(observed(&plant), before, "{name}");
        }
        let direct = s.set("SIM_ACC_FAIL", 1.0, &mut plant).expect_err("refused");
        assert_eq!(direct, "SIM_ACC_FAIL: only 0 ok, 2 stuck, 3 garbage", "the same text without the port");
        // And without a plant, as a scenario file's set is checked when it loads.
        assert_eq!(super::super::check_set("SIM_ACC_FAIL", 1.0), Err(direct));
        assert_eq!(
            super::super::check_set("SIM_GPS_FAIL", 3.0).expect_err("no garbage"),
            "SIM_GPS_FAIL: only 0 ok, 1 off, 2 stuck, 4 wrong"
        );
        assert_eq!(
            super::super::check_set("SIM_LINK_LOSS", 95.0).expect_err("range"),
            "SIM_LINK_LOSS: 95 not in 0..90"
        );
        assert_eq!(super::super::check_set("SIM_NOPE", 1.0).expect_err("unknown"), "unknown parameter SIM_NOPE");
        for (name, value) in
            [("SIM_GPS_FAIL", 4.0), ("SIM_ACC_FAIL", 3.0), ("SIM_BAT_FAIL", 1.0), ("SIM_GUST_SPD", 5.0)]
        {
            assert_eq!(super::super::check_set(name, value), Ok(()), "{name} = {value}");
        }
    }

    #[test]
    fn given_a_plant_without_a_pack_then_sim_bat_fail_1_is_refused() {
        let config = PlantConfig {
            battery: BatteryConfig { enabled: false, ..BatteryConfig::default() },
            ..PlantConfig::default()
        };
        let mut plant = Plant::new(config, &InitialState::default(), 1).expect("plant");
        let mut s = SimParamService::new(SYS, &plant);
        let err = s.set("SIM_BAT_FAIL", 1.0, &mut plant).expect_err("no pack");
        assert_eq!(err, "SIM_BAT_FAIL: the plant simulates no battery");
        assert_eq!(s.get("SIM_BAT_FAIL"), Some(0.0));
        assert!(s.set("SIM_BAT_FAIL", 0.0, &mut plant).is_ok(), "clearing is always fine");
        // Injected, it is DENIED (a value the plant refuses), nothing changed.
        let battery_off = FailureRequest { unit_id: 100, type_id: 1, instance: 0 };
        let injection = s.inject_failure(&battery_off, &mut plant);
        assert_eq!(injection.result, MavResult::MAV_RESULT_DENIED);
        assert!(injection.text.contains("no battery"), "{}", injection.text);
        assert_eq!(s.get("SIM_BAT_FAIL"), Some(0.0));
    }

    #[test]
    fn given_an_injection_through_the_service_then_the_port_shows_the_state_and_a_refused_one_changes_nothing() {
        let mut plant = plant();
        let mut s = SimParamService::new(SYS, &plant);
        let gps_stuck = FailureRequest { unit_id: 4, type_id: 2, instance: 0 };
        let injection = s.inject_failure(&gps_stuck, &mut plant);
        assert_eq!(injection.result, MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(injection.text, "failure injected: SIM_GPS_FAIL = 2");
        let (texts, values) = split(&injection.messages);
        assert_eq!((texts, values), (vec![injection.text.clone()], vec![("SIM_GPS_FAIL".to_owned(), 2.0)]));
        assert_eq!(s.get("SIM_GPS_FAIL"), Some(2.0));
        assert_eq!(plant.sensor_faults().fault(Sensor::Gps), Fault::Stuck);
        let rc_off = FailureRequest { unit_id: 104, type_id: 1, instance: 0 };
        assert_eq!(s.inject_failure(&rc_off, &mut plant).result, MavResult::MAV_RESULT_ACCEPTED);
        assert!(plant.radio().failed() && s.get("SIM_RC_FAIL") == Some(1.0));

        let every = |s: &SimParamService| (0..SIM_PARAMS.len()).map(|i| s.value(i)).collect::<Vec<_>>();
        let before = (every(&s), observed(&plant));
        for (request, result) in [
            ([1.0, 1.0, 0.0], MavResult::MAV_RESULT_UNSUPPORTED),
            ([4.0, 7.0, 0.0], MavResult::MAV_RESULT_UNSUPPORTED),
            ([105.0, 1.0, 0.0], MavResult::MAV_RESULT_UNSUPPORTED),
            ([4.0, 1.0, f32::NAN], MavResult::MAV_RESULT_DENIED),
        ] {
            let injection = s.inject_forwarded(request, &mut plant);
            assert_eq!(injection.result, result, "{request:?}");
            assert!(injection.text.starts_with("failure injection refused: "), "{}", injection.text);
            assert!(split(&injection.messages).1.is_empty(), "no value changed");
            assert_eq!((every(&s), observed(&plant)), before, "{request:?} changed nothing");
        }
        let clear = FailureRequest { unit_id: 4, type_id: 0, instance: 1 };
        assert_eq!(s.inject_failure(&clear, &mut plant).result, MavResult::MAV_RESULT_ACCEPTED);
        assert_eq!(plant.sensor_faults().fault(Sensor::Gps), Fault::Ok);
    }

    #[test]
    fn given_motor_injections_through_the_service_then_they_follow_whether_the_plant_has_sim_motn_eff() {
        // NOTE for the lead: part D adds SIM_MOT1_EFF..SIM_MOT4_EFF. Before that merge this branch has none
        // and every motor row answers UNSUPPORTED (the second arm); after it the first arm runs. Once
        // merged, delete the `else` arm so that the test requires the motor rows to work.
        let mut plant = plant();
        let mut s = SimParamService::new(SYS, &plant);
        s.set("SIM_MOT_WRNG_EFF", 0.6, &mut plant).expect("in range");
        let motor2_wrong = FailureRequest { unit_id: 101, type_id: 4, instance: 2 };
        let all_off = FailureRequest { unit_id: 101, type_id: 1, instance: 0 };
        if s.get("SIM_MOT1_EFF").is_some() {
            assert_eq!(s.inject_failure(&motor2_wrong, &mut plant).result, MavResult::MAV_RESULT_ACCEPTED);
            assert_eq!(s.get("SIM_MOT2_EFF"), Some(0.6));
            assert_eq!(s.get("SIM_MOT1_EFF"), Some(1.0));
            assert_eq!(s.inject_failure(&all_off, &mut plant).result, MavResult::MAV_RESULT_ACCEPTED);
            assert!((1..=4).all(|n| s.get(&format!("SIM_MOT{n}_EFF")) == Some(0.0)));
        } else {
            for request in [motor2_wrong, all_off] {
                let injection = s.inject_failure(&request, &mut plant);
                assert_eq!(injection.result, MavResult::MAV_RESULT_UNSUPPORTED);
                assert!(injection.text.ends_with("is not a parameter of this plant"), "{}", injection.text);
            }
        }
    }

    /// A set of one of this module's parameters: a value in range, out of range, not whole, or not finite.
    fn any_set() -> impl Strategy<Value = (usize, f32)> {
        let value = prop_oneof![
            (-20.0_f32..20.0).prop_map(f32::round),
            -20_000.0_f32..20_000.0,
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(0.5_f32),
            (0.0_f32..1.0),
        ];
        (0..NAMES.len(), value)
    }

    proptest! {
        // 64 cases of the default 256: PROPTEST_CASES scales them with every other property test.
        #![proptest_config(ProptestConfig::with_cases(ProptestConfig::default().cases * 64 / 256))]

        /// Random sequences of sets never panic; a set the table or the plant refuses changes nothing
        /// (neither a value on the port nor the plant); an accepted one is shown on the port.
        #[test]
        fn given_random_sets_then_none_panics_and_a_refused_one_changes_nothing(sets in prop::collection::vec(any_set(), 1..40)) {
            let mut plant = plant();
            let mut s = SimParamService::new(SYS, &plant);
            for (k, (i, value)) in sets.into_iter().enumerate() {
                let name = NAMES[i];
                let every = |s: &SimParamService| (0..SIM_PARAMS.len()).map(|i| s.value(i).map(f32::to_bits)).collect::<Vec<_>>();
                let before = (every(&s), observed(&plant));
                let def = SIM_PARAMS.iter().find(|d| d.name == name).expect("in the table");
                let in_range = def.check(value).is_ok();
                match s.set(name, value, &mut plant) {
                    Ok(_) => {
                        prop_assert!(in_range, "{name} = {value} accepted out of range");
                        prop_assert_eq!(s.get(name), Some(value));
                    }
                    Err(reason) => {
                        prop_assert!(reason.starts_with(name), "{}", reason);
                        prop_assert_eq!((every(&s), observed(&plant)), before, "set {} {} = {} changed something", k, name, value);
                    }
                }
                // The plant keeps producing finite samples whatever the faults.
                plant.step([1500.0; 4], 2000);
                let sample = plant.sample_sensors();
                prop_assert!(sample.accel_frd_mps2.iter().all(|x| x.is_finite()));
            }
        }
    }
}

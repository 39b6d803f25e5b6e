//! The estimator's reaction to sensor faults at the vehicle level: the whole core in lockstep with the real
//! plant (modest sensor noise), a sensor of the plant failed through its SIM_ parameters (as an injected
//! failure sets them); judged on what the vehicle says (STATUSTEXT, SYS_STATUS health
//! bits), its estimate's flags and the plant's truth. Pure simulated time: no sleeps.

use autopilot::core::estimator::{EstimatorEvent, EstimatorSource, HeightSource, Source, SourceFault};
use autopilot::core::mavlink::common::{MavCmd, MavMessage, MavResult, MavSeverity, MavSysStatusSensor};
use sitl::plant::PlantConfig;
use tests::rig::Rig;

/// Takes off to `alt_m` and waits 3 s in Hold; returns the truth's hold height (m, down).
fn take_off(rig: &mut Rig, alt_m: f32) -> f64 {
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    let nan = f32::NAN;
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, alt_m]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.wait_until(20.0, "takeoff complete", |r| {
        r.vehicle.commander_output().state == autopilot::core::commander::State::Hold
    });
    rig.run_s(3.0, |_| {});
    rig.plant.truth().pos_ned_m.z
}

/// The STATUSTEXTs sent, with their time (s) and severity.
fn texts(messages: &[(u64, MavMessage)]) -> Vec<(f64, MavSeverity, String)> {
    messages
        .iter()
        .filter_map(|(t, m)| match m {
            MavMessage::STATUSTEXT(s) => {
                Some((*t as f64 * 1e-6, s.severity, s.text.to_str().unwrap_or_default().to_owned()))
            }
            _ => None,
        })
        .collect()
}

/// The health bits of the SYS_STATUS messages sent, with their time (s).
fn sys_status_health(messages: &[(u64, MavMessage)]) -> Vec<(f64, MavSysStatusSensor)> {
    messages
        .iter()
        .filter_map(|(t, m)| match m {
            MavMessage::SYS_STATUS(s) => Some((*t as f64 * 1e-6, s.onboard_control_sensors_health)),
            _ => None,
        })
        .collect()
}

/// Every text the estimator can announce.
fn estimator_texts() -> Vec<String> {
    let mut all = Vec::new();
    for source in [Source::Gps, Source::Baro, Source::Mag, Source::Imu] {
        all.push(EstimatorEvent::Regained { source }.text());
        for fault in [SourceFault::Lost, SourceFault::Stuck, SourceFault::Rejected] {
            for height_source in [HeightSource::Baro, HeightSource::Gps, HeightSource::None] {
                all.push(EstimatorEvent::Fault { source, fault, height_source }.text());
            }
        }
    }
    all
}

#[test]
fn given_gps_lost_in_hold_then_gps_lost_is_said_within_1_s_position_invalid_the_health_bit_cleared_and_regained_said() {
    let mut rig = Rig::new(EstimatorSource::Fused);
    take_off(&mut rig, 3.0);
    rig.take_messages();
    // WHEN the plant's GPS stops delivering fixes (SIM_GPS_FAIL = 1, as an injected GPS OFF) for 3 s.
    rig.sim_set("SIM_GPS_FAIL", 1.0);
    let last_fix_s = rig.now_us as f64 * 1e-6;
    let mut invalid_at_s = None;
    rig.run_s(3.0, |r| {
        if invalid_at_s.is_none() && !r.vehicle.estimate().flags.position_valid {
            invalid_at_s = Some(r.now_us as f64 * 1e-6);
        }
    });
    let outage = rig.take_messages();
    // THEN "GPS lost" is said, as a warning, within 1 s of the last fix, the position is invalid from that
    // very step, and SYS_STATUS no longer reports the GPS healthy.
    let said = texts(&outage);
    let (lost_s, severity, _) = said.iter().find(|(_, _, t)| t == "GPS lost: dead reckoning").expect("GPS lost said");
    println!("last fix {last_fix_s:.3} s, GPS lost said {lost_s:.3} s, position invalid {invalid_at_s:?} s");
    assert_eq!(*severity, MavSeverity::MAV_SEVERITY_WARNING);
    assert!(lost_s - last_fix_s <= 1.0, "said {:.3} s after the last fix", lost_s - last_fix_s);
    assert_eq!(invalid_at_s, Some(*lost_s), "position invalid at the announcement");
    let gps_bit = MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS;
    let after: Vec<_> = sys_status_health(&outage).into_iter().filter(|(t, _)| t > lost_s).collect();
    assert!(!after.is_empty() && after.iter().all(|(_, h)| !h.contains(gps_bit)), "{after:?}");
    let f = rig.vehicle.estimate().flags;
    assert_eq!(f.health.gps, Some(SourceFault::Lost));
    assert!(!f.gps_ok && !f.velocity_valid && f.baro_ok && f.mag_ok && f.attitude_valid);

    // WHEN the fixes come back (SIM_GPS_FAIL = 0), THEN "GPS regained" (info), valid again, and SYS_STATUS healthy again.
    rig.sim_set("SIM_GPS_FAIL", 0.0);
    rig.run_s(2.5, |_| {});
    let back = rig.take_messages();
    let said = texts(&back);
    assert!(said.iter().any(|(_, s, t)| t == "GPS regained" && *s == MavSeverity::MAV_SEVERITY_INFO), "{said:?}");
    assert!(rig.vehicle.estimate().flags.position_valid && rig.vehicle.estimate().flags.gps_ok);
    assert!(sys_status_health(&back).last().is_some_and(|(_, h)| h.contains(gps_bit)));
}

#[test]
fn given_the_baro_stuck_in_hold_then_it_is_said_within_1_5_s_height_comes_from_gps_and_the_truth_holds_within_0_5_m() {
    let mut rig = Rig::new(EstimatorSource::Fused);
    let hold_d_m = take_off(&mut rig, 3.0);
    rig.take_messages();
    // WHEN the plant's barometer repeats its last value for 20 s (SIM_BARO_FAIL = 2, as an injected BARO STUCK).
    rig.sim_set("SIM_BARO_FAIL", 2.0);
    let start_s = rig.now_us as f64 * 1e-6;
    let mut worst_alt_err_m: f64 = 0.0;
    rig.run_s(20.0, |r| worst_alt_err_m = worst_alt_err_m.max((r.plant.truth().pos_ned_m.z - hold_d_m).abs()));
    let messages = rig.take_messages();
    let said = texts(&messages);
    let (stuck_s, severity, _) =
        said.iter().find(|(_, _, t)| t == "Baro stuck: height from GPS").expect("baro stuck said");
    println!(
        "baro frozen at {start_s:.3} s: said at {stuck_s:.3} s; worst truth height error over 20 s {worst_alt_err_m:.3} m"
    );
    // THEN it is said as a warning within 1.5 s, the height comes from GPS, SYS_STATUS clears the baro's
    // health bit, and the vehicle holds its height on the truth within 0.5 m.
    assert_eq!(*severity, MavSeverity::MAV_SEVERITY_WARNING);
    assert!(stuck_s - start_s <= 1.5, "said {:.3} s after it froze", stuck_s - start_s);
    let f = rig.vehicle.estimate().flags;
    assert_eq!((f.health.baro, f.height_source), (Some(SourceFault::Stuck), HeightSource::Gps));
    assert!(f.position_valid && !f.baro_ok);
    let baro_bit = MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE;
    let after: Vec<_> = sys_status_health(&messages).into_iter().filter(|(t, _)| t > stuck_s).collect();
    assert!(!after.is_empty() && after.iter().all(|(_, h)| !h.contains(baro_bit)), "{after:?}");
    assert!(worst_alt_err_m < 0.5, "height error {worst_alt_err_m} m");
}

#[test]
fn given_a_noise_free_plant_when_flown_on_the_fused_estimator_then_the_estimator_never_announces_a_fault() {
    // Noise-free sensors repeat values whenever the vehicle is still: nothing may be taken for stuck.
    let mut rig = Rig::with(PlantConfig::default(), EstimatorSource::Fused, |_| {});
    take_off(&mut rig, 2.0);
    rig.run_s(10.0, |r| assert!(r.vehicle.estimate().flags.health.all_healthy(), "{:?}", r.vehicle.estimate().flags));
    assert_eq!(rig.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    rig.wait_until(20.0, "auto-disarm after landing", |r| !r.armed());
    rig.run_s(5.0, |_| {});
    let forbidden = estimator_texts();
    let said = texts(&rig.take_messages());
    assert!(said.iter().all(|(_, _, t)| !forbidden.contains(t)), "{said:?}");
    assert!(rig.vehicle.estimate().flags.health.all_healthy());
}

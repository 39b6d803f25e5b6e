//! Every injectable fault flown in-process, in lockstep with the real plant (nominal airframe, modest
//! sensor noise, the fused estimator, ACO): MAV_CMD_INJECT_FAILURE as a ground station sends it, forwarded
//! by the vehicle to the plant's SIM_ service, which fails what it simulates. The vehicle reacts from its
//! data only; each test is judged on the plant's truth against the hold point, on what the vehicle said
//! and when. Pure simulated time: no sleeps.

use autopilot::core::commander::{FlightMode, State};
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::FailureType::{
    FAILURE_TYPE_GARBAGE as GARBAGE, FAILURE_TYPE_OFF as OFF, FAILURE_TYPE_OK as OK, FAILURE_TYPE_SLOW as SLOW,
    FAILURE_TYPE_STUCK as STUCK, FAILURE_TYPE_WRONG as WRONG,
};
use autopilot::core::mavlink::common::{FailureType, FailureUnit, MavMessage, MavResult, MavSeverity};
use nalgebra::Vector3;
use tests::rig::Rig;

/// MAVLink FAILURE_UNIT values, by their short names.
mod unit {
    pub use autopilot::core::mavlink::common::FailureUnit::{
        FAILURE_UNIT_SENSOR_ACCEL as ACCEL, FAILURE_UNIT_SENSOR_BARO as BARO, FAILURE_UNIT_SENSOR_GPS as GPS,
        FAILURE_UNIT_SENSOR_GYRO as GYRO, FAILURE_UNIT_SENSOR_MAG as MAG, FAILURE_UNIT_SYSTEM_BATTERY as BATTERY,
        FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL as MAVLINK_SIGNAL, FAILURE_UNIT_SYSTEM_MOTOR as MOTOR,
    };
}

/// The rig's hover (2.5 m, Hold, 5 s), SYS_FAILURE_EN = 1.
fn hovering() -> Rig {
    let mut rig = Rig::hovering();
    rig.set_param("SYS_FAILURE_EN", 1.0);
    rig
}

fn accepted() -> MavResult {
    MavResult::MAV_RESULT_ACCEPTED
}

/// What a flight after an injection showed, from the injection on.
#[derive(Debug)]
struct Flight {
    /// STATUSTEXTs with their time after the injection (s) and severity.
    said: Vec<(f64, MavSeverity, String)>,
    /// The worst horizontal and vertical distance of the truth from the hold point (m) while airborne
    /// and not landing.
    worst_horizontal_m: f64,
    worst_vertical_m: f64,
    /// When the vehicle switched to Land (s after the injection), if it did.
    land_after_s: Option<f64>,
    /// Whether the motors were stopped by the failure detector.
    killed: bool,
    /// Truth at the end.
    on_ground: bool,
}

impl Flight {
    /// When a text starting with `prefix` was said (s after the injection).
    fn said_at(&self, prefix: &str) -> Option<f64> {
        self.said.iter().find(|(_, _, t)| t.starts_with(prefix)).map(|(t, _, _)| *t)
    }
}

/// Injects `(unit, failure_type, instance)` into a hover and flies `seconds` (or until disarmed).
fn fly_with(rig: &mut Rig, unit: FailureUnit, failure_type: FailureType, instance: u8, seconds: f64) -> Flight {
    let hold: Vector3<f64> = rig.plant.truth().pos_ned_m;
    let start_us = rig.now_us;
    assert_eq!(rig.inject(unit, failure_type, instance), accepted(), "{unit:?}/{failure_type:?}/{instance}");
    let mut flight = Flight {
        said: Vec::new(),
        worst_horizontal_m: 0.0,
        worst_vertical_m: 0.0,
        land_after_s: None,
        killed: false,
        on_ground: false,
    };
    let end_us = start_us + (seconds * 1e6) as u64;
    loop {
        let since_s = (rig.now_us - start_us) as f64 * 1e-6;
        let mode = rig.vehicle.commander_output().mode;
        if flight.land_after_s.is_none() && mode == FlightMode::Land {
            flight.land_after_s = Some(since_s);
        }
        if flight.land_after_s.is_none() && rig.vehicle.commander().state() != State::Killed {
            let e = rig.plant.truth().pos_ned_m - hold;
            flight.worst_horizontal_m = flight.worst_horizontal_m.max(e.x.hypot(e.y));
            flight.worst_vertical_m = flight.worst_vertical_m.max(e.z.abs());
        }
        if rig.now_us >= end_us || !rig.armed() {
            break;
        }
        rig.tick();
    }
    flight.killed = rig.vehicle.commander().state() == State::Killed;
    flight.on_ground = rig.plant.truth().on_ground;
    flight.said = said_since(rig, start_us);
    println!("{unit:?}/{failure_type:?}/{instance}: {flight:?}");
    flight
}

#[test]
fn given_sys_failure_en_0_then_denied_an_unimplemented_type_unsupported_and_neither_changes_the_plant() {
    let mut rig = Rig::new(EstimatorSource::Fused);
    rig.run_s(1.0, |_| {});
    assert_eq!(rig.inject(unit::GPS, OFF, 0), MavResult::MAV_RESULT_DENIED);
    rig.set_param("SYS_FAILURE_EN", 1.0);
    assert_eq!(rig.inject(unit::GPS, SLOW, 0), MavResult::MAV_RESULT_UNSUPPORTED);
    assert_eq!(rig.inject(unit::ACCEL, OFF, 0), MavResult::MAV_RESULT_UNSUPPORTED);
    assert_eq!(rig.inject(unit::MOTOR, OFF, 5), MavResult::MAV_RESULT_UNSUPPORTED, "a quadrotor has no motor 5");
    assert_eq!(rig.sim.get("SIM_GPS_FAIL"), Some(0.0));
    assert_eq!(rig.sim.get("SIM_ACC_FAIL"), Some(0.0));
    rig.run_s(1.0, |_| {});
    assert!(rig.vehicle.estimate().flags.gps_ok, "the GPS still delivers");
}

#[test]
fn given_motor_1_wrong_at_90_percent_in_hold_then_aco_holds_within_0_3_m_of_the_hold_point() {
    // 90 %: inside the envelope with every moment balanced (h >= 0.881); the 70 % is beyond any
    // controller on this airframe (docs/scenarios.md, "What the airframe can hold at all").
    let mut rig = hovering();
    rig.sim_set("SIM_MOT_WRNG_EFF", 0.9);
    let flight = fly_with(&mut rig, unit::MOTOR, WRONG, 1, 20.0);
    assert_eq!(rig.sim.get("SIM_MOT1_EFF"), Some(0.9));
    assert!(rig.armed() && flight.land_after_s.is_none() && !flight.killed, "{flight:?}");
    assert!(flight.worst_horizontal_m.hypot(flight.worst_vertical_m) <= 0.3, "{flight:?}");
    // And back to healthy with OK.
    assert_eq!(rig.inject(unit::MOTOR, OK, 1), accepted());
    assert_eq!(rig.sim.get("SIM_MOT1_EFF"), Some(1.0));
}

#[test]
fn given_motor_1_off_in_hold_then_the_failure_detector_terminates_and_says_so() {
    let mut rig = hovering();
    let flight = fly_with(&mut rig, unit::MOTOR, OFF, 1, 10.0);
    assert!(flight.killed, "{flight:?}");
    let said = flight.said_at("Failsafe: attitude").expect("the failure said");
    // Tilted past 60 deg within a few tenths of a second, then FD_FAIL_R_TTRI = 0.3 s.
    assert!(said <= 1.5, "{flight:?}");
}

#[test]
fn given_gps_stuck_in_hold_then_it_is_said_within_1_5_s_the_height_holds_within_0_3_m_and_it_lands() {
    let mut rig = hovering();
    let flight = fly_with(&mut rig, unit::GPS, STUCK, 0, 60.0);
    let said = flight.said_at("GPS stuck").expect("GPS stuck said");
    assert!(said <= 1.5, "{flight:?}");
    assert!(flight.worst_vertical_m <= 0.3, "{flight:?}");
    assert!(flight.land_after_s.is_some() && flight.on_ground && !rig.armed(), "{flight:?}");
}

#[test]
fn given_gps_wrong_by_50_m_in_hold_then_the_jump_is_rejected_and_said_and_the_vehicle_does_not_follow_it() {
    let mut rig = hovering();
    let flight = fly_with(&mut rig, unit::GPS, WRONG, 0, 60.0);
    let said = flight.said_at("GPS rejected").expect("GPS rejected said");
    assert!(said <= 1.5, "{flight:?}");
    assert!(flight.worst_horizontal_m <= 0.5 && flight.worst_vertical_m <= 0.3, "{flight:?}");
}

#[test]
fn given_baro_off_in_hold_then_it_is_said_within_1_s_and_the_height_holds_on_gps_within_0_5_m() {
    let mut rig = hovering();
    let flight = fly_with(&mut rig, unit::BARO, OFF, 0, 20.0);
    assert!(flight.said_at("Baro lost: height from GPS").is_some_and(|t| t <= 1.0), "{flight:?}");
    assert!(rig.armed() && flight.land_after_s.is_none(), "{flight:?}");
    assert!(flight.worst_vertical_m <= 0.5 && flight.worst_horizontal_m <= 0.3, "{flight:?}");
}

#[test]
fn given_mag_off_or_stuck_in_hold_then_it_is_said_and_the_position_holds_within_0_3_m_on_the_gyro() {
    for (failure_type, text) in [(OFF, "Mag lost: heading on gyro"), (STUCK, "Mag stuck: heading on gyro")] {
        let mut rig = hovering();
        let flight = fly_with(&mut rig, unit::MAG, failure_type, 0, 20.0);
        assert!(flight.said_at(text).is_some_and(|t| t <= 1.0), "{flight:?}");
        assert!(rig.armed() && flight.land_after_s.is_none(), "{flight:?}");
        assert!(flight.worst_horizontal_m.hypot(flight.worst_vertical_m) <= 0.3, "{flight:?}");
    }
}

#[test]
fn given_the_imu_stuck_or_garbage_in_hold_then_it_is_said_as_critical_within_0_5_s_and_the_vehicle_lands_or_is_terminated()
 {
    for (unit, failure_type) in
        [(unit::ACCEL, STUCK), (unit::ACCEL, GARBAGE), (unit::GYRO, STUCK), (unit::GYRO, GARBAGE)]
    {
        let mut rig = hovering();
        let flight = fly_with(&mut rig, unit, failure_type, 0, 20.0);
        let (t, severity, _) =
            flight.said.iter().find(|(_, _, t)| t.starts_with("IMU")).expect("the IMU fault said").clone();
        assert!(t <= 0.5 && severity == MavSeverity::MAV_SEVERITY_CRITICAL, "{flight:?}");
        // Position and velocity are invalid from the fault on: the position failsafe lands after
        // COM_POS_FS_DELAY (1 s), unless the attitude failure detector stops the motors first.
        assert!(flight.killed || flight.land_after_s.is_some_and(|l| l <= t + 1.1), "{flight:?}");
    }
}

#[test]
fn given_the_battery_reported_empty_in_hold_then_the_battery_failsafe_lands() {
    let mut rig = hovering();
    let flight = fly_with(&mut rig, unit::BATTERY, OFF, 0, 60.0);
    assert!(flight.land_after_s.is_some_and(|t| t <= 2.0), "{flight:?}");
    assert!(flight.worst_horizontal_m.hypot(flight.worst_vertical_m) <= 0.3, "{flight:?}");
    assert!(flight.on_ground && !rig.armed(), "{flight:?}");
}

#[test]
fn given_the_gcs_link_injected_off_in_hold_then_its_heartbeats_are_not_heard_and_nav_dll_act_returns_after_com_dl_loss_t()
 {
    let mut rig = hovering();
    rig.set_param("NAV_DLL_ACT", 2.0);
    rig.set_param("COM_DL_LOSS_T", 5.0);
    let beat = autopilot::core::mavlink::gcs_heartbeat();
    // The ground station heartbeats at 1 Hz throughout.
    let fly_beating = |rig: &mut Rig, seconds: f64, each: &mut dyn FnMut(&Rig)| {
        let end = rig.now_us + (seconds * 1e6) as u64;
        while rig.now_us < end {
            if rig.now_us % 1_000_000 < 2_000 {
                rig.send(&beat);
            }
            rig.tick();
            each(rig);
        }
    };
    fly_beating(&mut rig, 3.0, &mut |_| {});
    rig.take_messages();
    // WHEN MAVLINK_SIGNAL is injected OFF: the vehicle hears nothing but MAV_CMD_INJECT_FAILURE.
    assert_eq!(rig.inject(unit::MAVLINK_SIGNAL, OFF, 0), accepted());
    let off_us = rig.now_us;
    let mut returned_us = None;
    fly_beating(&mut rig, 7.0, &mut |r| {
        if returned_us.is_none() && r.vehicle.commander_output().mode == FlightMode::ReturnToLaunch {
            returned_us = Some(r.now_us);
        }
    });
    let after_s = (returned_us.expect("the vehicle returns") - off_us) as f64 * 1e-6;
    let said = statustexts(&mut rig);
    println!("MAVLINK_SIGNAL off: Return {after_s:.3} s after; {said:?}");
    // The last heartbeat heard came up to 1 s before the injection.
    assert!((4.0..=5.1).contains(&after_s), "{after_s}");
    assert!(said.iter().any(|t| t == "Failsafe: GCS link lost, returning"), "{said:?}");
    // MAVLINK_SIGNAL OK (heard even while deaf): the heartbeats are heard again.
    assert_eq!(rig.inject(unit::MAVLINK_SIGNAL, OK, 0), accepted());
    fly_beating(&mut rig, 2.0, &mut |_| {});
    let said = statustexts(&mut rig);
    assert!(said.iter().any(|t| t == "GCS link regained"), "{said:?}");
}

/// The STATUSTEXTs the vehicle sent since the last call: their time after `start_us` (s), severity, text.
fn said_since(rig: &mut Rig, start_us: u64) -> Vec<(f64, MavSeverity, String)> {
    rig.take_messages()
        .into_iter()
        .filter_map(|(t, m)| match m {
            MavMessage::STATUSTEXT(s) => Some((
                t.saturating_sub(start_us) as f64 * 1e-6,
                s.severity,
                s.text.to_str().unwrap_or_default().to_owned(),
            )),
            _ => None,
        })
        .collect()
}

/// The texts alone.
fn statustexts(rig: &mut Rig) -> Vec<String> {
    said_since(rig, 0).into_iter().map(|(_, _, text)| text).collect()
}

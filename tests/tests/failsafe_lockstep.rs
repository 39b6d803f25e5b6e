//! Failsafes flown in-process, in lockstep with the real plant (nominal airframe, modest sensor noise, the
//! fused estimator), on vehicle time: a ground station that heartbeats once a second and then goes
//! silent. Judged on the mode the vehicle reports, the time it changed, what it said, and where the plant's
//! truth lands.

use autopilot::core::commander::FlightMode;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::{
    HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage, MavState, MavType, PARAM_SET_DATA,
};
use autopilot::core::mavlink::params::{decode_value, encode_value};
use autopilot::core::params::PARAMS;
use nalgebra::Vector3;
use tests::rig::{Rig, mission_item};

const NAN: f32 = f32::NAN;

fn gcs_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: Default::default(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// PARAM_SET as a PX4 ground station sends it, in the parameter's own type (NAV_DLL_ACT as an INT32 in
/// PX4's bytewise encoding, as MAVSDK's `set_param_int`), and the echo, decoded by its type, checked.
fn set_param(rig: &mut Rig, name: &str, value: f32) {
    let kind = PARAMS.iter().find(|d| d.name == name).expect("a parameter").kind;
    let replies = rig.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: encode_value(kind, value),
        target_system: 1,
        target_component: 1,
        param_id: name.into(),
        param_type: kind.mav_param_type(),
    }));
    assert!(
        replies.iter().any(|m| matches!(m, MavMessage::PARAM_VALUE(p)
            if p.param_type == kind.mav_param_type() && decode_value(p.param_type, p.param_value) == Some(value))),
        "{name} = {value}: {replies:?}"
    );
}

/// Ticks for `seconds`, sending a GCS HEARTBEAT every second of vehicle time while `heartbeats`.
fn fly(rig: &mut Rig, seconds: f64, heartbeats: bool) {
    let end = rig.now_us + (seconds * 1e6) as u64;
    while rig.now_us < end {
        if heartbeats && rig.now_us % 1_000_000 < 2_000 {
            rig.send(&gcs_heartbeat());
        }
        rig.tick();
    }
}

fn said(rig: &mut Rig, text: &str) -> Vec<u64> {
    rig.take_messages()
        .into_iter()
        .filter(|(_, m)| matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == text)))
        .map(|(t, _)| t)
        .collect()
}

fn converged_rig() -> Rig {
    let mut rig = Rig::new(EstimatorSource::Fused);
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    fly(&mut rig, 1.0, true);
    rig
}

#[test]
fn given_nav_dll_act_return_when_the_gcs_goes_silent_in_a_mission_then_it_returns_after_com_dl_loss_t_and_lands_home() {
    // GIVEN NAV_DLL_ACT = 2 (return), COM_DL_LOSS_T = 5 s and a mission out to 20 m, flown while the
    // ground station heartbeats.
    let mut rig = converged_rig();
    set_param(&mut rig, "NAV_DLL_ACT", 2.0);
    set_param(&mut rig, "COM_DL_LOSS_T", 5.0);
    let home = rig.plant.truth().pos_ned_m;
    let origin = rig.vehicle.estimate().origin.expect("origin");
    let est_home = rig.vehicle.home().expect("home").pos_ned_m;
    let at = |n: f64, e: f64| origin.geodetic_from_ned(&(est_home + Vector3::new(n, e, 0.0)));
    let (lat1, lon1, _) = at(20.0, 0.0);
    let (lat2, lon2, _) = at(20.0, 20.0);
    let items = [
        mission_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN], f64::NAN, f64::NAN, 5.0),
        mission_item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], lat1, lon1, 5.0),
        mission_item(2, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], lat2, lon2, 5.0),
    ];
    rig.start_mission(&items);
    fly(&mut rig, 15.0, true);
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Mission);
    rig.take_messages();
    // WHEN it goes silent (its last HEARTBEAT was at a whole second).
    let last_heartbeat_us = rig.now_us - rig.now_us % 1_000_000;
    let mut rtl_at_us = None;
    let start = rig.now_us;
    while rig.armed() {
        assert!(rig.now_us - start < 120_000_000, "not landed within 120 s");
        rig.tick();
        if rtl_at_us.is_none() && rig.vehicle.commander_output().mode == FlightMode::ReturnToLaunch {
            rtl_at_us = Some(rig.now_us);
        }
    }
    // THEN it returns COM_DL_LOSS_T after the last HEARTBEAT (to within 0.1 s of vehicle time), says why,
    // and lands at home.
    let rtl_at_us = rtl_at_us.expect("switched to RTL");
    let after_s = (rtl_at_us - last_heartbeat_us) as f64 * 1e-6;
    let said_at = said(&mut rig, "Failsafe: GCS link lost, returning");
    let landed = rig.plant.truth().pos_ned_m;
    println!(
        "datalink loss: RTL {after_s:.3} s after the last HEARTBEAT, landed {:.3} m from home",
        (landed - home).xy().norm()
    );
    assert!((after_s - 5.0).abs() <= 0.1, "RTL {after_s} s after the last HEARTBEAT");
    assert_eq!(said_at, vec![rtl_at_us], "announced once, as it switched");
    assert!((landed - home).xy().norm() <= 0.10, "landed {landed:?}, home {home:?}");
}

#[test]
fn given_nav_dll_act_hold_when_the_link_returns_then_it_says_so_and_stays_in_hold() {
    let mut rig = converged_rig();
    set_param(&mut rig, "NAV_DLL_ACT", 1.0);
    set_param(&mut rig, "COM_DL_LOSS_T", 5.0);
    let nan = NAN;
    rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 3.0]);
    rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    fly(&mut rig, 8.0, true);
    // Holding (AUTO LOITER) when the link goes.
    rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0]);
    rig.take_messages();
    fly(&mut rig, 6.0, false);
    assert_eq!(said(&mut rig, "Failsafe: GCS link lost, holding").len(), 1);
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Hold);
    // WHEN the ground station is back THEN the vehicle says so and stays where the failsafe put it.
    fly(&mut rig, 2.0, true);
    assert_eq!(said(&mut rig, "GCS link regained").len(), 1);
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Hold);
    assert!(rig.armed());
}

#[test]
fn given_nav_dll_act_0_when_the_link_is_lost_then_it_is_only_said_and_the_mode_stays() {
    let mut rig = converged_rig();
    let nan = NAN;
    rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 3.0]);
    rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    fly(&mut rig, 8.0, true);
    rig.take_messages();
    fly(&mut rig, 12.0, false);
    assert_eq!(said(&mut rig, "Failsafe: GCS link lost").len(), 1);
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Hold, "the takeoff's hold goes on");
}

//! Failsafes flown in-process, in lockstep with the real plant (nominal airframe, modest sensor noise, the
//! fused estimator), on vehicle time: a ground station that heartbeats once a second and then goes
//! silent. Judged on the mode the vehicle reports, the time it changed, what it said, and where the plant's
//! truth lands.

use autopilot::core::commander::FlightMode;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::{MavCmd, MavMessage};
use autopilot::core::mavlink::gcs_heartbeat;
use nalgebra::Vector3;
use tests::rig::{Rig, mission_item};

const NAN: f32 = f32::NAN;

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
    rig.set_param("NAV_DLL_ACT", 2.0);
    rig.set_param("COM_DL_LOSS_T", 5.0);
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
    rig.set_param("NAV_DLL_ACT", 1.0);
    rig.set_param("COM_DL_LOSS_T", 5.0);
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

#[test]
fn given_com_low_bat_act_3_when_sim_bat_drain_empties_the_pack_in_a_mission_then_warn_return_and_land_before_empty() {
    // GIVEN a pack at 20 % drained in 1000 s of motor time (SIM_BAT_DRAIN; 5 % every 50 s), BAT_CRIT_THR
    // 10 % and BAT_EMERGEN_THR 3 % (so the return has 70 s before the emergency), COM_LOW_BAT_ACT 3, and a
    // mission out to 15 m that ends holding there.
    let mut config = sitl::plant::PlantConfig {
        sensors: sitl::plant::SensorConfig::modest_noise(),
        ..sitl::plant::PlantConfig::default()
    };
    config.battery.initial_remaining = 0.2;
    config.battery.drain_s = 1000.0;
    let mut rig = Rig::with(config, EstimatorSource::Fused, |_| {});
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    fly(&mut rig, 1.0, true);
    rig.set_param("BAT_CRIT_THR", 0.10);
    rig.set_param("BAT_EMERGEN_THR", 0.03);
    let home = rig.plant.truth().pos_ned_m;
    let origin = rig.vehicle.estimate().origin.expect("origin");
    let est_home = rig.vehicle.home().expect("home").pos_ned_m;
    let (lat, lon, _) = origin.geodetic_from_ned(&(est_home + Vector3::new(15.0, 0.0, 0.0)));
    let items = [
        mission_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN], f64::NAN, f64::NAN, 5.0),
        mission_item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], lat, lon, 5.0),
    ];
    rig.start_mission(&items);
    rig.take_messages();
    // WHEN the pack drains.
    let start = rig.now_us;
    let mut rtl_at = None;
    let mut messages = Vec::new();
    let mut remaining_at_rtl = 0.0;
    while rig.armed() || rig.now_us - start < 5_000_000 {
        assert!(rig.now_us - start < 300_000_000, "not landed within 300 s");
        fly(&mut rig, 0.1, true);
        let remaining = rig.plant.battery().expect("a pack").reading().remaining;
        if rtl_at.is_none() && rig.vehicle.commander_output().mode == FlightMode::ReturnToLaunch {
            rtl_at = Some(rig.now_us);
            remaining_at_rtl = remaining;
        }
        messages.extend(rig.take_messages());
    }
    // THEN a warning at 15 %, a return at 10 %, said once each, in that order; it lands at home with
    // charge left (the plant's truth).
    let text_at = |text: &str| -> Vec<u64> {
        messages
            .iter()
            .filter(|(_, m)| matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == text)))
            .map(|(t, _)| *t)
            .collect()
    };
    let low = text_at("Battery low: 14% remaining");
    let critical = text_at("Failsafe: battery critical (9%), returning");
    let landed = rig.plant.truth().pos_ned_m;
    let left = rig.plant.battery().expect("a pack").reading().remaining;
    println!(
        "battery: low warning at {:.1} s, return at {:.1} s ({:.3} left), landed {:.3} m from home with {:.3} left",
        (low[0] - start) as f64 * 1e-6,
        (critical[0] - start) as f64 * 1e-6,
        remaining_at_rtl,
        (landed - home).xy().norm(),
        left
    );
    assert_eq!(low.len(), 1, "one warning");
    assert_eq!(critical.len(), 1, "one return");
    assert!(low[0] < critical[0]);
    assert!(rtl_at.is_some_and(|t| t.abs_diff(critical[0]) <= 2_000), "switched as it said");
    assert!((0.095..0.101).contains(&remaining_at_rtl), "returned at {remaining_at_rtl}");
    assert!(left > 0.03, "landed before the emergency level: {left}");
    assert!((landed - home).xy().norm() <= 0.15, "landed {landed:?}, home {home:?}");
}

/// A SET_POSITION_TARGET_LOCAL_NED with a velocity only (NED m/s; position, acceleration and yaw ignored).
fn velocity_target(vn_mps: f32, ve_mps: f32) -> MavMessage {
    use autopilot::core::mavlink::common::{MavFrame, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA};
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        vx: vn_mps,
        vy: ve_mps,
        type_mask: PositionTargetTypemask::from_bits_truncate(7 | 448 | 1024 | 2048),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        ..Default::default()
    })
}

/// DO_REPOSITION (COMMAND_INT, as QGroundControl sends it) to `north_m` north of home at 3 m; the replies.
fn reposition_north(rig: &mut Rig, north_m: f64) -> Vec<MavMessage> {
    use autopilot::core::mavlink::common::{COMMAND_INT_DATA, MavFrame};
    let origin = rig.vehicle.estimate().origin.expect("origin");
    let home = rig.vehicle.home().expect("home").pos_ned_m;
    let (lat, lon, _) = origin.geodetic_from_ned(&(home + Vector3::new(north_m, 0.0, 0.0)));
    rig.send(&MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        param1: -1.0,
        param4: f32::NAN,
        x: (lat * 1e7).round() as i32,
        y: (lon * 1e7).round() as i32,
        z: 3.0,
        command: MavCmd::MAV_CMD_DO_REPOSITION,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        ..Default::default()
    }))
}

/// A converged rig that took off to 3 m and holds there.
fn airborne_rig() -> Rig {
    let mut rig = converged_rig();
    rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN, NAN, NAN, 3.0]);
    rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    fly(&mut rig, 10.0, true);
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Hold);
    rig
}

#[test]
fn given_gf_max_hor_dist_10_when_a_goto_20_m_away_is_asked_then_it_is_refused_with_the_reason() {
    use autopilot::core::mavlink::common::MavResult;
    let mut rig = airborne_rig();
    rig.set_param("GF_MAX_HOR_DIST", 10.0);
    let replies = reposition_north(&mut rig, 20.0);
    assert!(
        matches!(&replies[0], MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_DENIED),
        "{replies:?}"
    );
    assert!(
        replies.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(s)
            if s.text.to_str().is_ok_and(|t| t == "Reposition: beyond GF_MAX_HOR_DIST"))),
        "{replies:?}"
    );
    let before = rig.plant.truth().pos_ned_m;
    fly(&mut rig, 5.0, true);
    let truth = rig.plant.truth().pos_ned_m;
    assert!((truth - before).xy().norm() < 0.3, "not flown: {before:?} -> {truth:?}");
    // Within the limit it is flown.
    let replies = reposition_north(&mut rig, 8.0);
    assert!(matches!(&replies[0], MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_ACCEPTED));
}

#[test]
fn given_gf_max_hor_dist_10_when_an_offboard_velocity_pushes_outward_then_it_holds_before_10_5_m_on_the_truth() {
    // GIVEN GF_MAX_HOR_DIST 10 m and GF_ACTION 2 (hold, the default), hovering at home.
    let mut rig = airborne_rig();
    rig.set_param("GF_MAX_HOR_DIST", 10.0);
    let home = rig.plant.truth().pos_ned_m;
    // WHEN an offboard stream flies north at 1.5 m/s (20 Hz), for 30 s.
    let replies = rig.send(&velocity_target(1.5, 0.0));
    assert!(replies.is_empty(), "{replies:?}");
    let result = rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(result, autopilot::core::mavlink::common::MavResult::MAV_RESULT_ACCEPTED, "{:?}", rig.take_messages());
    assert_eq!(rig.vehicle.commander().mode(), FlightMode::Offboard);
    rig.take_messages();
    let mut farthest_m: f64 = 0.0;
    let mut held_at_m = None;
    for _ in 0..600 {
        fly(&mut rig, 0.05, true);
        rig.send(&velocity_target(1.5, 0.0));
        let d = (rig.plant.truth().pos_ned_m - home).xy().norm();
        farthest_m = farthest_m.max(d);
        if held_at_m.is_none() && rig.vehicle.commander_output().mode == FlightMode::Hold {
            held_at_m = Some(d);
        }
    }
    // THEN it switched to Hold, said why once, and never left 10.5 m from home (the plant's truth).
    let said_at = said(&mut rig, "Failsafe: fence, beyond GF_MAX_HOR_DIST, holding");
    println!("geofence: hold at {:.2} m from home, farthest {farthest_m:.2} m", held_at_m.unwrap_or(f64::NAN));
    assert_eq!(said_at.len(), 1);
    assert!(held_at_m.is_some_and(|d| d < 10.0), "predicted: held at {held_at_m:?}");
    assert!(farthest_m < 10.5, "farthest {farthest_m} m");
    assert_eq!(rig.vehicle.commander_output().mode, FlightMode::Hold);
}

#[test]
fn given_a_rally_point_closer_than_home_when_returning_then_it_lands_at_the_rally_point() {
    use autopilot::core::mavlink::common::{MISSION_COUNT_DATA, MavFrame, MavMissionResult, MavMissionType};
    let mut rig = airborne_rig();
    let home_truth = rig.plant.truth().pos_ned_m;
    let origin = rig.vehicle.estimate().origin.expect("origin");
    let home = rig.vehicle.home().expect("home").pos_ned_m;
    // GIVEN a rally point 12 m north of home, uploaded as a RALLY transfer.
    let (lat, lon, _) = origin.geodetic_from_ned(&(home + Vector3::new(12.0, 0.0, 0.0)));
    let count = MISSION_COUNT_DATA {
        count: 1,
        target_system: 1,
        target_component: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_RALLY,
        ..Default::default()
    };
    rig.send(&MavMessage::MISSION_COUNT(count));
    let mut item = mission_item(0, MavCmd::MAV_CMD_NAV_RALLY_POINT, [0.0; 4], lat, lon, 5.0);
    item.frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    item.mission_type = MavMissionType::MAV_MISSION_TYPE_RALLY;
    let replies = rig.send(&MavMessage::MISSION_ITEM_INT(item));
    assert!(
        matches!(replies.first(), Some(MavMessage::MISSION_ACK(a)) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED),
        "{replies:?}"
    );
    // WHEN the vehicle, 9 m north, is told to return.
    reposition_north(&mut rig, 9.0);
    fly(&mut rig, 20.0, true);
    rig.command(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]);
    let start = rig.now_us;
    while rig.armed() {
        assert!(rig.now_us - start < 90_000_000, "not landed within 90 s");
        fly(&mut rig, 0.1, true);
    }
    // THEN it landed at the rally point (3 m away), not at home (9 m away), on the plant's truth.
    let landed = rig.plant.truth().pos_ned_m - home_truth;
    println!("rally: landed at N {:.3} E {:.3} m from home (rally point at N 12)", landed.x, landed.y);
    assert!((landed.xy() - nalgebra::Vector2::new(12.0, 0.0)).norm() < 0.3, "landed {landed:?}");
}

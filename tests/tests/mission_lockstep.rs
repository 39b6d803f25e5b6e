//! The paper's figure-8 flown as a real mission, in-process through the whole vehicle core: the plant in
//! lockstep, the fused estimator on GPS/IMU/mag/baro, the mission uploaded with the MAVLink mission
//! protocol, started in AUTO MISSION, every item reported reached, and the track compared with the same
//! spline the in-process figure-8 scenario flies. Also RTL, a mission that lands, offboard, and MAVSDK's
//! waypoint and speed pairs, whose MISSION_CURRENT never steps back.

use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::{MavCmd, MavMessage, MavResult};
use autopilot::core::navigator::spline::{FIGURE8_NE_M, SplinePath};
use nalgebra::{Vector2, Vector3};
use sitl::plant::{PlantConfig, SensorConfig};
use tests::rig::{Rig, mission_item};

const NAN: f32 = f32::NAN;

/// The paper's sensor noise level for the full stack: GPS position within 2 cm (the paper's state noise on
/// position), the rest as `sitl run`'s modest noise.
fn plant_config() -> PlantConfig {
    let mut sensors = SensorConfig::modest_noise();
    sensors.gps.position.white_sigma = 0.02;
    sensors.gps.eph_m = 0.02;
    sensors.gps.epv_m = 0.03;
    PlantConfig { sensors, ..PlantConfig::default() }
}

/// A rig whose estimator trusts the GPS as the plant's does.
fn rig() -> Rig {
    Rig::with(plant_config(), EstimatorSource::Fused, |v| {
        v.estimator.gps_pos_noise_m = 0.02;
        v.estimator.gps_hgt_noise_m = 0.03;
    })
}

/// The geodetic point `ne_m` metres from the plant's home.
fn at(rig: &Rig, ne_m: [f64; 2]) -> (f64, f64) {
    let home = rig.plant.config().sensors.home;
    let origin = autopilot::core::estimator::GeoOrigin {
        lat_deg: home.lat_deg,
        lon_deg: home.lon_deg,
        alt_amsl_m: home.alt_amsl_m,
    };
    let (lat, lon, _) = origin.geodetic_from_ned(&Vector3::new(ne_m[0], ne_m[1], 0.0));
    (lat, lon)
}

fn reached(messages: &[(u64, MavMessage)]) -> Vec<u16> {
    messages
        .iter()
        .filter_map(|(_, m)| if let MavMessage::MISSION_ITEM_REACHED(r) = m { Some(r.seq) } else { None })
        .collect()
}

/// What a figure-8 mission flight gave: the items reached, in order, and the truth's cross-track error
/// (m) against the scenario's spline, altitude error (m) and horizontal speed (m/s) at every step on
/// the track.
struct Figure8Flight {
    reached: Vec<u16>,
    cross_m: Vec<f64>,
    alt_err_m: Vec<f64>,
    speed_mps: Vec<f64>,
}

/// A converged vehicle on the ground flies the figure-8 mission for `laps` laps: takeoff, speed 0.3 m/s,
/// nine waypoints at 1.5 m (seq 2-10), for more than one lap a DO_JUMP back to seq 2 (`laps - 1`
/// repeats), then land; armed and switched to AUTO MISSION, until landed and disarmed. The track is
/// sampled from the first figure-8 waypoint reached to the last lap's last one.
fn fly_figure8_mission(laps: u16) -> Figure8Flight {
    let mut rig = rig();
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(1.0, |_| {});
    let mut items = vec![
        mission_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN], f64::NAN, f64::NAN, 1.5),
        mission_item(1, MavCmd::MAV_CMD_DO_CHANGE_SPEED, [1.0, 0.3, -1.0, 0.0], f64::NAN, f64::NAN, 0.0),
    ];
    for (i, ne) in FIGURE8_NE_M.iter().enumerate() {
        let (lat, lon) = at(&rig, *ne);
        items.push(mission_item(
            2 + i as u16,
            MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT,
            [0.0, 0.0, 0.0, NAN],
            lat,
            lon,
            1.5,
        ));
    }
    if laps > 1 {
        let repeats = f32::from(laps - 1);
        items.push(mission_item(11, MavCmd::MAV_CMD_DO_JUMP, [2.0, repeats, 0.0, 0.0], f64::NAN, f64::NAN, 0.0));
    }
    let (lat, lon) = at(&rig, [0.0, 0.0]);
    let land_seq = items.len() as u16;
    items.push(mission_item(land_seq, MavCmd::MAV_CMD_NAV_LAND, [0.0, 0.0, 0.0, NAN], lat, lon, 0.0));
    for item in &mut items {
        if matches!(item.command, MavCmd::MAV_CMD_DO_CHANGE_SPEED | MavCmd::MAV_CMD_DO_JUMP) {
            item.frame = autopilot::core::mavlink::common::MavFrame::MAV_FRAME_MISSION;
        }
    }
    rig.start_mission(&items);
    rig.take_messages();

    let path = SplinePath::new(&FIGURE8_NE_M);
    let mut flight =
        Figure8Flight { reached: Vec::new(), cross_m: Vec::new(), alt_err_m: Vec::new(), speed_mps: Vec::new() };
    let mut nearest_s: Option<f64> = None;
    let mut on_track = false;
    let start = rig.now_us;
    let limit_us = 40_000_000 + u64::from(laps) * 30_000_000;
    while rig.armed() || rig.now_us - start < 1_000_000 {
        assert!(
            rig.now_us - start < limit_us,
            "mission not finished within {} s: reached {:?}, {:?}, truth {:?}, texts {:?}",
            limit_us / 1_000_000,
            reached(&rig.messages),
            rig.vehicle.commander_output().state,
            rig.plant.truth().pos_ned_m,
            rig.messages
                .iter()
                .filter_map(|(_, m)| if let MavMessage::STATUSTEXT(t) = m {
                    t.text.to_str().ok().map(str::to_owned)
                } else {
                    None
                })
                .collect::<Vec<_>>()
        );
        rig.tick();
        let seen = reached(&rig.messages);
        on_track = seen.contains(&2) && seen.iter().filter(|&&s| s == 10).count() < usize::from(laps);
        if on_track {
            let t = rig.plant.truth();
            let p = t.pos_ned_m;
            let (d, s) = match nearest_s {
                Some(s) => path.nearest_near(Vector2::new(p.x, p.y), s, 0.05),
                None => path.nearest_near(Vector2::new(p.x, p.y), 0.0, 0.3),
            };
            nearest_s = Some(s);
            flight.cross_m.push(d);
            flight.alt_err_m.push(p.z + 1.5);
            flight.speed_mps.push(t.vel_ned_mps.xy().norm());
        }
    }
    assert!(!on_track);
    assert!(rig.plant.truth().pos_ned_m.z.abs() < 0.05, "landed");
    flight.reached = reached(&rig.take_messages());
    flight
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn given_the_figure8_as_a_mission_when_flown_through_the_vehicle_then_every_item_is_reached_and_it_tracks_the_spline() {
    let flight = fly_figure8_mission(1);
    assert_eq!(flight.reached, (0..=11).collect::<Vec<u16>>(), "items reached");
    let (cross_rms, cross_max) = (rms(&flight.cross_m), flight.cross_m.iter().copied().fold(0.0, f64::max));
    println!(
        "figure-8 mission (vehicle core, fused estimator): cross-track rms {cross_rms:.4} m, max {cross_max:.4} m, \
         altitude rms {:.4} m over {} samples ({:.1} s)",
        rms(&flight.alt_err_m),
        flight.cross_m.len(),
        flight.cross_m.len() as f64 * 0.002
    );
    assert!(flight.cross_m.len() > 10_000, "flew the track for over 20 s");
    assert!(cross_rms < 0.05, "cross-track rms {cross_rms}");
}

#[test]
fn given_the_figure8_repeated_by_a_do_jump_when_flown_then_three_laps_without_stopping_at_the_seams() {
    let flight = fly_figure8_mission(3);
    let mut want = vec![0, 1];
    for _ in 0..3 {
        want.extend(2..=11); // the figure-8, then the jump (taken twice, then passed once used up)
    }
    want.push(12);
    assert_eq!(flight.reached, want, "items reached");
    let cross_rms = rms(&flight.cross_m);
    // Away from the start and the stop (the first and last 3 s), the vehicle keeps moving through the seams.
    let cruise = &flight.speed_mps[1500..flight.speed_mps.len() - 1500];
    let min_speed = cruise.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "figure-8 mission, 3 laps through DO_JUMP: cross-track rms {cross_rms:.4} m, altitude rms {:.4} m, \
         min speed {min_speed:.3} m/s over {:.1} s",
        rms(&flight.alt_err_m),
        flight.cross_m.len() as f64 * 0.002
    );
    assert!(flight.cross_m.len() > 3 * 12_000, "flew the track for 3 laps of 24 s: {} samples", flight.cross_m.len());
    assert!(cross_rms < 0.05, "cross-track rms {cross_rms}");
    assert!(min_speed > 0.2, "no stop at the seams: min speed {min_speed} m/s");
}

/// A SET_POSITION_TARGET_LOCAL_NED with position and yaw (MAVSDK's type_mask 2552).
fn position_target(n_m: f32, e_m: f32, d_m: f32) -> MavMessage {
    use autopilot::core::mavlink::common::{MavFrame, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA};
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        x: n_m,
        y: e_m,
        z: d_m,
        type_mask: PositionTargetTypemask::from_bits_truncate(2552),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        ..Default::default()
    })
}

/// A converged vehicle that took off to 1.5 m and is in Hold.
fn hovering_rig() -> Rig {
    let mut rig = rig();
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(1.0, |_| {});
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN, NAN, NAN, 1.5]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.wait_until(15.0, "takeoff", |r| r.vehicle.commander_output().state == autopilot::core::commander::State::Hold);
    rig
}

/// The PX4 custom_mode the vehicle reports (as its HEARTBEAT carries it).
fn custom_mode(rig: &Rig) -> u32 {
    autopilot::core::mavlink::identity::custom_mode(rig.vehicle.commander_output().mode)
}

#[test]
fn given_offboard_setpoints_when_they_stop_then_the_vehicle_holds_after_half_a_second_of_vehicle_time() {
    // GIVEN a vehicle holding at 1.5 m.
    let mut rig = hovering_rig();
    let home = rig.vehicle.estimate().pos_ned_m;
    // WHEN OFFBOARD is asked for without setpoints THEN it is refused; with them streaming at 20 Hz it flies
    // to the setpoint.
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_DENIED
    );
    let target = (home.x as f32 + 1.0, home.y as f32, home.z as f32);
    rig.send(&position_target(target.0, target.1, target.2));
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    for _ in 0..200 {
        rig.run_s(0.05, |_| {});
        rig.send(&position_target(target.0, target.1, target.2));
    }
    assert_eq!(custom_mode(&rig), 0x0006_0000, "still OFFBOARD while setpoints flow");
    let p = rig.vehicle.estimate().pos_ned_m;
    assert!((p.x - f64::from(target.0)).abs() < 0.1, "flew to the setpoint: {p:?}");
    // AND when they stop, THEN Hold (AUTO LOITER) after 0.5 s of vehicle time, not before.
    rig.run_s(0.45, |_| {});
    assert_eq!(custom_mode(&rig), 0x0006_0000, "0.45 s without setpoints: still OFFBOARD");
    rig.take_messages();
    rig.run_s(0.1, |_| {});
    assert_eq!(custom_mode(&rig), 0x0304_0000, "0.55 s without setpoints: Hold");
    // AND it says why.
    let said = rig.take_messages().into_iter().any(|(_, m)| {
        matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == "Failsafe: offboard setpoints lost, holding"))
    });
    assert!(said, "the switch to Hold is announced");
}

#[test]
fn given_a_return_to_launch_when_away_then_it_climbs_returns_lands_at_home_and_disarms() {
    let mut rig = hovering_rig();
    // Away with DO_REPOSITION (QGroundControl's "go to location"), 4 m north at the same altitude.
    let (lat, lon) = at(&rig, [4.0, 0.0]);
    let reposition = autopilot::core::mavlink::common::COMMAND_INT_DATA {
        param1: -1.0,
        param4: f32::NAN,
        x: (lat * 1e7).round() as i32,
        y: (lon * 1e7).round() as i32,
        z: f32::NAN,
        command: MavCmd::MAV_CMD_DO_REPOSITION,
        target_system: 1,
        target_component: 1,
        frame: autopilot::core::mavlink::common::MavFrame::MAV_FRAME_GLOBAL,
        ..Default::default()
    };
    let replies = rig.send(&MavMessage::COMMAND_INT(reposition));
    assert!(
        matches!(replies.first(), Some(MavMessage::COMMAND_ACK(a)) if a.result == MavResult::MAV_RESULT_ACCEPTED),
        "{replies:?}"
    );
    rig.run_s(12.0, |_| {});
    assert!((rig.plant.truth().pos_ned_m.x - 4.0).abs() < 0.15, "repositioned: {:?}", rig.plant.truth().pos_ned_m);
    // WHEN told to return.
    let mut max_alt: f64 = 0.0;
    assert_eq!(rig.command(MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    rig.tick();
    assert_eq!(custom_mode(&rig), 0x0504_0000, "AUTO RTL");
    let start = rig.now_us;
    while rig.armed() {
        assert!(rig.now_us - start < 60_000_000, "not landed and disarmed within 60 s");
        rig.tick();
        max_alt = max_alt.max(-rig.plant.truth().pos_ned_m.z);
    }
    // THEN it climbed to RTL_RETURN_ALT (10 m) without overshoot, came back above home and landed there.
    let p = rig.plant.truth().pos_ned_m;
    assert!(max_alt > 9.95 && max_alt < 10.05, "return altitude {max_alt}");
    assert!(p.xy().norm() < 0.3 && p.z.abs() < 0.05, "landed at home: {p:?}");
}

/// A SET_ATTITUDE_TARGET for a level attitude at `yaw_rad` with a normalized `thrust`; `type_mask` 7 is
/// MAVSDK's `set_attitude` (body rates ignored), 7 | 64 also ignores the thrust.
fn attitude_target(yaw_rad: f64, thrust: f32, type_mask: u8) -> MavMessage {
    use autopilot::core::mavlink::common::{AttitudeTargetTypemask, SET_ATTITUDE_TARGET_DATA};
    let q = nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad);
    MavMessage::SET_ATTITUDE_TARGET(SET_ATTITUDE_TARGET_DATA {
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        thrust,
        target_system: 1,
        target_component: 1,
        type_mask: AttitudeTargetTypemask::from_bits_truncate(type_mask),
        ..Default::default()
    })
}

/// Streams `msg` at 20 Hz for `seconds` of vehicle time.
fn stream(rig: &mut Rig, msg: &MavMessage, seconds: f64) {
    for _ in 0..(seconds * 20.0).round() as usize {
        rig.send(msg);
        rig.run_s(0.05, |_| {});
    }
}

#[test]
fn given_offboard_attitude_with_thrust_then_the_thrust_climbs_and_sinks_and_without_it_the_altitude_holds() {
    // GIVEN a vehicle holding at 1.5 m.
    let mut rig = hovering_rig();
    rig.run_s(2.0, |_| {});
    let yaw = rig.vehicle.estimate().euler_rad.z;
    let alt = |rig: &Rig| -rig.plant.truth().pos_ned_m.z;
    let start_m = alt(&rig);
    // WHEN in OFFBOARD with a level attitude and thrust 0.62 (hover is 0.46 on this airframe) for 2 s.
    rig.send(&attitude_target(yaw, 0.62, 7));
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    stream(&mut rig, &attitude_target(yaw, 0.62, 7), 2.0);
    // THEN it climbs, level.
    let climbed_m = alt(&rig) - start_m;
    let truth = rig.plant.truth();
    assert!(climbed_m > 0.3, "thrust 0.62 for 2 s climbed {climbed_m} m");
    assert!(truth.vel_ned_mps.z < -0.2, "still climbing: {:?}", truth.vel_ned_mps);
    assert!(truth.euler_rad.x.abs() < 0.05 && truth.euler_rad.y.abs() < 0.05, "level: {:?}", truth.euler_rad);
    // AND with thrust 0.30 for 3 s it sinks.
    stream(&mut rig, &attitude_target(yaw, 0.30, 7), 3.0);
    let vel_d = rig.plant.truth().vel_ned_mps.z;
    assert!(vel_d > 0.15, "thrust 0.30 for 3 s: sinking at {vel_d} m/s");
    assert_eq!(custom_mode(&rig), 0x0006_0000, "OFFBOARD throughout");
    // AND with the thrust ignored it holds the altitude it had when the thrust stopped.
    let dropped_m = alt(&rig);
    stream(&mut rig, &attitude_target(yaw, 0.30, 7 | 64), 5.0);
    let held_m = alt(&rig);
    assert!((held_m - dropped_m).abs() < 0.15, "held {held_m} m, thrust dropped at {dropped_m} m");
    assert!(rig.plant.truth().vel_ned_mps.z.abs() < 0.1, "settled: {:?}", rig.plant.truth().vel_ned_mps);
}

/// QGroundControl and MAVSDK upload a takeoff and a land "here" with latitude and longitude 0: the one
/// resolver reads (0, 0) as here for flying and for the mission check alike, so the mission is accepted,
/// started and flown (before, the check placed (0, 0) in the Gulf of Guinea and refused the start as
/// "over 10 km from home" while the navigator would have flown it here).
#[test]
fn given_takeoff_and_land_items_at_lat_lon_0_0_when_the_mission_is_flown_then_it_climbs_here_flies_and_lands_within_0_15_m_of_the_waypoint()
 {
    let mut rig = rig();
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(1.0, |_| {});
    let (lat, lon) = at(&rig, [3.0, 0.0]);
    let items = [
        mission_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, NAN], 0.0, 0.0, 2.0),
        mission_item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], lat, lon, 2.0),
        mission_item(2, MavCmd::MAV_CMD_NAV_LAND, [0.0, 0.0, 0.0, NAN], 0.0, 0.0, 0.0),
    ];
    rig.start_mission(&items);
    let start = rig.now_us;
    let mut max_alt_m: f64 = 0.0;
    while rig.armed() || rig.now_us - start < 1_000_000 {
        assert!(rig.now_us - start < 60_000_000, "not landed and disarmed within 60 s: {:?}", reached(&rig.messages));
        rig.tick();
        max_alt_m = max_alt_m.max(-rig.plant.truth().pos_ned_m.z);
    }
    let p = rig.plant.truth().pos_ned_m;
    assert_eq!(reached(&rig.take_messages()), vec![0, 1, 2], "every item reached in order");
    assert!((max_alt_m - 2.0).abs() < 0.1, "took off here to 2 m: {max_alt_m}");
    assert!((p.xy() - Vector2::new(3.0, 0.0)).norm() < 0.15 && p.z.abs() < 0.05, "landed at the waypoint: {p:?}");
}

/// MAVSDK's mission as its Mission plugin uploads it: each waypoint a NAV_WAYPOINT followed by a
/// DO_CHANGE_SPEED, and its progress is the item of MISSION_CURRENT's seq. CI once saw that progress step
/// back (4, 3, 4): when MISSION_CURRENT's stream was due in the step a waypoint was reached, the stream's
/// message (already the next waypoint) went before the navigator's own MISSION_CURRENT for the speed item
/// it passed on the way. Here the stream runs every step, so every arrival meets it.
#[test]
fn given_mavsdk_waypoint_and_speed_pairs_when_flown_then_mission_current_never_steps_back() {
    let mut rig = hovering_rig();
    // MISSION_CURRENT (id 42) every 2 ms: every step of the vehicle.
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [42.0, 2000.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let corners = [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
    let mut items = Vec::new();
    for ne in corners {
        let (lat, lon) = at(&rig, ne);
        let seq = items.len() as u16;
        items.push(mission_item(seq, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], lat, lon, 1.5));
        let mut speed =
            mission_item(seq + 1, MavCmd::MAV_CMD_DO_CHANGE_SPEED, [1.0, 0.5, -1.0, 0.0], f64::NAN, f64::NAN, 0.0);
        speed.frame = autopilot::core::mavlink::common::MavFrame::MAV_FRAME_MISSION;
        items.push(speed);
    }
    assert_eq!(rig.upload(&items), autopilot::core::mavlink::common::MavMissionResult::MAV_MISSION_ACCEPTED);
    rig.take_messages();
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let start = rig.now_us;
    while !reached(&rig.messages).contains(&7) {
        assert!(rig.now_us - start < 60_000_000, "not finished within 60 s: reached {:?}", reached(&rig.messages));
        rig.tick();
    }
    rig.run_s(1.0, |_| {});
    let messages = rig.take_messages();
    let current: Vec<u16> = messages
        .iter()
        .filter_map(|(_, m)| if let MavMessage::MISSION_CURRENT(c) = m { Some(c.seq) } else { None })
        .collect();
    assert!(current.len() > 1000, "the stream ran every step: {} messages", current.len());
    let back: Vec<_> = current.windows(2).filter(|w| w[1] < w[0]).map(|w| (w[0], w[1])).collect();
    assert!(back.is_empty(), "MISSION_CURRENT stepped back: {back:?}");
    let mut seen = current.clone();
    seen.dedup();
    assert_eq!(seen, (0..8).collect::<Vec<u16>>(), "every item became current, in order");
    assert_eq!(reached(&messages), (0..8).collect::<Vec<u16>>(), "every item reached, in order");
}

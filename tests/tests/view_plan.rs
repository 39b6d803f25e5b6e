//! What the live view draws of a vehicle's plan, in lockstep through the whole core: a mission uploaded
//! with the MAVLink mission protocol, a geofence and rally points loaded as a ground station leaves them,
//! and the autopilot's plan frame (`autopilot::runtime::view::plan_frame`) placing each where it is, in
//! the vehicle's local NED, with the item flown now marked.

use autopilot::core::estimator::{EstimatorSource, GeoOrigin};
use autopilot::core::mavlink::common::{MavCmd, MavFrame, MavResult};
use autopilot::core::mission::MissionItem;
use autopilot::core::plan::geofence::{Fence, Rally};
use autopilot::runtime::view::{plan_frame, vehicle_frame};
use nalgebra::Vector3;
use tests::rig::{Rig, mission_item};

const NAN: f32 = f32::NAN;

fn origin(rig: &Rig) -> GeoOrigin {
    let home = rig.plant.config().sensors.home;
    GeoOrigin { lat_deg: home.lat_deg, lon_deg: home.lon_deg, alt_amsl_m: home.alt_amsl_m }
}

/// Latitude and longitude `n_m`, `e_m` from the plant's home.
fn at(rig: &Rig, n_m: f64, e_m: f64) -> (f64, f64) {
    let (lat, lon, _) = origin(rig).geodetic_from_ned(&Vector3::new(n_m, e_m, 0.0));
    (lat, lon)
}

fn fence_item(rig: &Rig, seq: u16, command: MavCmd, param1: f32, n_m: f64, e_m: f64) -> MissionItem {
    let (lat, lon) = at(rig, n_m, e_m);
    MissionItem {
        seq,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        command,
        param1,
        param2: 0.0,
        param3: 0.0,
        param4: 0.0,
        x: (lat * 1e7).round() as i32,
        y: (lon * 1e7).round() as i32,
        z: 0.0,
        autocontinue: false,
    }
}

fn near(a: [f64; 3], b: [f64; 3], tol_m: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol_m)
}

#[test]
fn given_a_mission_a_fence_and_rally_points_then_the_plan_frame_places_each_where_it_is_flown() {
    let mut rig = Rig::new(EstimatorSource::Fused);
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(1.0, |_| {});
    let (a, b) = (at(&rig, 20.0, 0.0), at(&rig, 20.0, 15.0));
    let takeoff = mission_item(0, MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0; 4], f64::NAN, f64::NAN, 5.0);
    let wp1 = mission_item(1, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], a.0, a.1, 5.0);
    let wp2 = mission_item(2, MavCmd::MAV_CMD_NAV_WAYPOINT, [0.0, 0.0, 0.0, NAN], b.0, b.1, 8.0);
    assert_eq!(
        rig.upload(&[takeoff, wp1, wp2]),
        autopilot::core::mavlink::common::MavMissionResult::MAV_MISSION_ACCEPTED
    );
    let v = MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION;
    let fence = Fence::new(vec![
        fence_item(&rig, 0, v, 4.0, -40.0, -40.0),
        fence_item(&rig, 1, v, 4.0, 40.0, -40.0),
        fence_item(&rig, 2, v, 4.0, 40.0, 40.0),
        fence_item(&rig, 3, v, 4.0, -40.0, 40.0),
        fence_item(&rig, 4, MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 5.0, 10.0, -10.0),
    ])
    .expect("a valid fence");
    rig.vehicle.load_fence(fence);
    let rally = Rally::new(vec![fence_item(&rig, 0, MavCmd::MAV_CMD_NAV_RALLY_POINT, 0.0, -15.0, 5.0)]).expect("rally");
    rig.vehicle.load_rally(rally);
    rig.set_param("GF_MAX_VER_DIST", 30.0);
    rig.set_param("GF_MAX_HOR_DIST", 60.0);
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.run_s(0.1, |_| {});

    let estimate = rig.vehicle.log_snapshot().estimate;
    let latched = estimate.origin.expect("an origin");
    // Where the plant's home is in the vehicle's frame (the estimator latched its origin on a noisy fix).
    let home_in_local = latched.ned_from_geodetic(origin(&rig).lat_deg, origin(&rig).lon_deg, origin(&rig).alt_amsl_m);
    let local = |n: f64, e: f64, d: f64| [home_in_local.x + n, home_in_local.y + e, home_in_local.z + d];
    let frame = plan_frame("v0", rig.now_us, &rig.vehicle.plan_view(), estimate.origin);
    let home = frame.home_ned_m.expect("home is set at arming");
    let ground_d = home[2];

    // The mission's two waypoints (the takeoff has no point of its own), at their heights above home.
    assert_eq!(frame.mission_ned_m.len(), 2, "{:?}", frame.mission_ned_m);
    let mut wp1 = local(20.0, 0.0, 0.0);
    wp1[2] = ground_d - 5.0;
    let mut wp2 = local(20.0, 15.0, 0.0);
    wp2[2] = ground_d - 8.0;
    assert!(near(frame.mission_ned_m[0], wp1, 0.05), "{:?} vs {wp1:?}", frame.mission_ned_m[0]);
    assert!(near(frame.mission_ned_m[1], wp2, 0.05), "{:?} vs {wp2:?}", frame.mission_ned_m[1]);
    assert_eq!(frame.mission_current, Some(0), "the first item with a point is the one flown next");

    // The fence: the polygon's four corners, the exclusion circle, GF_MAX_HOR_DIST about home, the ceiling.
    assert_eq!(frame.fence_polygons_ne_m.len(), 1);
    let corner = local(40.0, 40.0, 0.0);
    assert!(
        frame.fence_polygons_ne_m[0].iter().any(|v| (v[0] - corner[0]).abs() < 0.05 && (v[1] - corner[1]).abs() < 0.05)
    );
    let circle = local(10.0, -10.0, 0.0);
    assert!(near(frame.fence_circles_ne_m[0], [circle[0], circle[1], 5.0], 0.05), "{:?}", frame.fence_circles_ne_m);
    assert!(near(frame.fence_circles_ne_m[1], [home[0], home[1], 60.0], 1e-9), "{:?}", frame.fence_circles_ne_m);
    assert!((frame.fence_max_alt_m.expect("ceiling") - (30.0 - ground_d)).abs() < 1e-9);

    // The rally point, on the ground.
    let rally = local(-15.0, 5.0, 0.0);
    assert!(near(frame.rally_ned_m[0], [rally[0], rally[1], ground_d], 0.05), "{:?}", frame.rally_ned_m);

    // And the vehicle's own frame carries the same origin, so a viewer moves both alike.
    let v = vehicle_frame("v0", rig.now_us, &rig.vehicle);
    assert_eq!(v.origin, frame.origin);
    assert!(v.armed);
}

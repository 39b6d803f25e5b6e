//! Faults flown in-process, in lockstep with the real plant (nominal airframe, modest sensor noise, the
//! fused estimator), on vehicle time: a rotor that stops, a GPS that goes silent. The vehicle never sees
//! the fault itself, only its data; judged on the plant's truth, what the vehicle said and when.

use autopilot::core::commander::{FlightMode, State};
use autopilot::core::mavlink::common::{MavCmd, MavMessage};
use tests::rig::Rig;

const NAN: f32 = f32::NAN;

/// The texts the vehicle said since the last call, with their times (µs).
fn texts(rig: &mut Rig) -> Vec<(u64, String)> {
    rig.take_messages()
        .into_iter()
        .filter_map(|(t, m)| match m {
            MavMessage::STATUSTEXT(s) => s.text.to_str().ok().map(|x| (t, x.to_owned())),
            _ => None,
        })
        .collect()
}

fn common_accepted() -> autopilot::core::mavlink::common::MavResult {
    autopilot::core::mavlink::common::MavResult::MAV_RESULT_ACCEPTED
}

#[test]
fn given_rotor_1_stops_in_hold_when_the_vehicle_rolls_past_60_deg_then_it_terminates_within_fd_fail_r_ttri_and_says_so()
{
    // GIVEN a hover in Hold with the default detector (FD_FAIL_R 60 deg for 0.3 s, FD_ACT 2 terminate).
    let mut rig = Rig::hovering();
    // WHEN rotor 1 (right) loses all thrust.
    rig.plant.airframe_mut().rotor_health[0] = 0.0;
    let mut beyond_since_us = None;
    let start = rig.now_us;
    while rig.vehicle.commander().state() != State::Killed {
        assert!(rig.now_us - start < 10_000_000, "no termination within 10 s");
        rig.tick();
        let est = rig.vehicle.estimate().euler_rad;
        if beyond_since_us.is_none() && (est.x.abs().to_degrees() > 60.0 || est.y.abs().to_degrees() > 60.0) {
            beyond_since_us = Some(rig.now_us);
        }
    }
    // THEN the motors stop FD_FAIL_R_TTRI after the estimate first passed 60 deg (to one 2 ms tick), the
    // truth had passed it too, and the vehicle said why.
    let beyond_since_us = beyond_since_us.expect("rolled past 60 deg");
    let after_s = (rig.now_us - beyond_since_us) as f64 * 1e-6;
    let truth_roll_deg = rig.plant.truth().euler_rad.x.to_degrees();
    let said = texts(&mut rig);
    println!(
        "terminated {after_s:.3} s after the estimate passed 60 deg; truth roll {truth_roll_deg:.1} deg; {said:?}"
    );
    assert!((0.3..=0.302).contains(&after_s), "{after_s}");
    assert!(truth_roll_deg.abs() > 60.0, "{truth_roll_deg}");
    assert!(!rig.armed());
    assert!(
        said.iter().any(|(_, t)| t.starts_with("Failsafe: attitude roll -") && t.ends_with(" deg, terminating")),
        "{said:?}"
    );
}

#[test]
fn given_fd_act_1_when_the_attitude_fails_then_the_vehicle_switches_to_land_and_says_so() {
    // GIVEN FD_ACT = 1 (land) and a hover.
    let mut rig = Rig::hovering();
    rig.set_param("FD_ACT", 1.0);
    rig.take_messages();
    // WHEN rotor 1 stops.
    rig.plant.airframe_mut().rotor_health[0] = 0.0;
    rig.wait_until(10.0, "land", |r| r.vehicle.commander_output().mode == FlightMode::Land);
    // THEN it lands (the detector's action) and is not killed; the text says "landing".
    let said = texts(&mut rig);
    assert_eq!(rig.vehicle.commander().state(), State::Land);
    assert!(
        said.iter().any(|(_, t)| t.starts_with("Failsafe: attitude roll") && t.ends_with(" deg, landing")),
        "{said:?}"
    );
}

#[test]
fn given_a_healthy_hover_and_a_4_m_reposition_then_the_detector_never_fires() {
    // GIVEN a hover; WHEN it flies a 1 m reposition and back (tilts of a few degrees).
    let mut rig = Rig::hovering();
    let here = rig.plant.truth().pos_ned_m;
    let origin = rig.vehicle.estimate().origin.expect("origin");
    let (lat, lon, _) =
        origin.geodetic_from_ned(&(rig.vehicle.estimate().pos_ned_m + nalgebra::Vector3::new(3.0, 3.0, 0.0)));
    let reposition = [-1.0, 0.0, 0.0, NAN, lat as f32, lon as f32, NAN];
    assert_eq!(rig.command(MavCmd::MAV_CMD_DO_REPOSITION, reposition), common_accepted());
    rig.run_s(10.0, |r| assert_ne!(r.vehicle.commander().state(), State::Killed));
    // THEN it is still flying, in Hold, and nothing was said of an attitude failure.
    let said = texts(&mut rig);
    assert!(rig.armed());
    assert!(!said.iter().any(|(_, t)| t.contains("attitude")), "{said:?}");
    assert!((rig.plant.truth().pos_ned_m - here).norm() > 2.0, "it moved");
}

#[test]
fn given_the_gps_stops_in_hold_then_its_loss_is_said_within_1_s_the_height_holds_within_0_3_m_and_it_lands_within_2_s()
{
    // GIVEN a hover in Hold with COM_POS_FS_DELAY = 1 s.
    let mut rig = Rig::hovering();
    let hold_d_m = rig.plant.truth().pos_ned_m.z;
    // WHEN the GPS stops.
    rig.sim_set("SIM_GPS_FAIL", 1.0);
    let cut_us = rig.now_us;
    let mut land_at_us = None;
    let mut worst_height_error_m: f64 = 0.0;
    while rig.armed() {
        assert!(rig.now_us - cut_us < 60_000_000, "not landed within 60 s");
        rig.tick();
        if land_at_us.is_none() {
            worst_height_error_m = worst_height_error_m.max((rig.plant.truth().pos_ned_m.z - hold_d_m).abs());
            if rig.vehicle.commander_output().mode == FlightMode::Land {
                land_at_us = Some(rig.now_us);
            }
        }
    }
    // THEN the position is flagged lost, it holds its height (truth) until the failsafe, lands level and
    // disarms on the ground; it said why.
    let said = texts(&mut rig);
    let land_after_s = (land_at_us.expect("switched to land") - cut_us) as f64 * 1e-6;
    let truth = rig.plant.truth();
    println!(
        "land {land_after_s:.3} s after the cut; worst height error before it {worst_height_error_m:.3} m; landed at D {:.3} m; {said:?}",
        truth.pos_ned_m.z
    );
    assert!(worst_height_error_m <= 0.3, "{worst_height_error_m}");
    // The estimator's GPS timeout (0.5 s) and then COM_POS_FS_DELAY (1 s).
    assert!((1.0..=2.0).contains(&land_after_s), "{land_after_s}");
    assert!(truth.on_ground);
    let lost_us = said.iter().find(|(_, t)| t.starts_with("GPS lost")).map(|(t, _)| *t).expect("GPS lost said");
    assert!(lost_us - cut_us <= 1_000_000, "said {} µs after the cut", lost_us - cut_us);
    assert!(said.iter().any(|(_, t)| t == "Failsafe: position lost, landing"), "{said:?}");
}

//! The geometric SE(3) controller (`se3`, the first guest controller, `autopilot/src/controllers/se3.rs`)
//! flown in lockstep on the plant's truth: the gust hover and the fast figure-8 with the jerk, as the
//! built-in scenarios fly them (mismatch plant, the paper's state noise, 500 Hz), and a 20 s hover through
//! the whole vehicle with the fused estimator on the plant's noisy sensors.
//!
//! `cargo test -p tests --test se3 -- --nocapture` prints the figures.

use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::{MavCmd, MavResult};
use sitl::scenario::ReferenceMode::{FeedForward, FeedForwardJerk};
use tests::rig::Rig;

fn se3() -> ControllerKind {
    "se3".parse().expect("se3 is registered")
}

#[test]
fn se3_holds_the_gust_under_30_cm_and_tracks_the_fast_figure_8_with_the_jerk_within_10_cm_rms() {
    let gust = tests::run("gust-hover", se3(), "mismatch", 1, 500, FeedForward).metrics.gust.expect("gust metrics");
    let track =
        tests::run("figure8-fast", se3(), "mismatch", 1, 500, FeedForwardJerk).metrics.track.expect("track metrics");
    eprintln!(
        "se3 gust-hover: peak {:.3} m, rms xy {:.3} m, rms z {:.4} m; figure8-fast with jerk: cross-track rms {:.3} m, \
         max {:.3} m, altitude rms {:.4} m",
        gust.peak_m, gust.rms_xy_m, gust.rms_z_m, track.cross_track_rms_m, track.cross_track_max_m, track.alt_rms_m
    );
    assert!(gust.peak_m < 0.30, "gust peak {:.3} m", gust.peak_m);
    assert!(track.cross_track_rms_m <= 0.10, "cross-track rms {:.3} m", track.cross_track_rms_m);
}

/// As `vehicle_lockstep`'s fused flight (nominal plant, modest sensor noise, seed 7), with `se3`: take
/// off to 1.5 m, settle 3 s, hold 20 s; the largest distance from home + 1.5 m on the truth.
#[test]
fn se3_with_the_fused_estimator_hovers_20_s_within_5_cm_of_the_point_on_the_truth() {
    let plant = sitl::plant::PlantConfig {
        sensors: sitl::plant::SensorConfig::modest_noise(),
        ..sitl::plant::PlantConfig::default()
    };
    let mut rig = Rig::with(plant, EstimatorSource::Fused, |vc| vc.controller = se3());
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(0.5, |_| {});
    let hover = rig.plant.truth().pos_ned_m - nalgebra::Vector3::new(0.0, 0.0, 1.5);
    let nan = f32::NAN;
    let accepted = MavResult::MAV_RESULT_ACCEPTED;
    assert_eq!(rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5]), accepted);
    assert_eq!(rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), accepted);
    rig.wait_until(15.0, "takeoff complete", |r| {
        r.vehicle.commander_output().state == autopilot::core::commander::State::Hold
    });
    rig.run_s(3.0, |_| {});
    let mut truth_err = 0.0_f64;
    rig.run_s(20.0, |r| truth_err = truth_err.max((r.plant.truth().pos_ned_m - hover).norm()));
    eprintln!("se3 fused hover: largest distance from the point over 20 s {truth_err:.3} m (truth)");
    assert!(truth_err <= 0.05, "hover error {truth_err:.3} m");
}

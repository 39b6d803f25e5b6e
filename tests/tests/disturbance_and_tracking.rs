//! Gust, turbulence and figure-8 experiments (mismatch plant, sensor noise on), in lockstep: the ACO
//! acceptance checks of spec (e), the baselines' sanity ranges, and bit-reproducibility.

use autopilot::core::control::ControllerKind;
const ACO: ControllerKind = ControllerKind::ACO;
const CA: ControllerKind = ControllerKind::CA;
const PID: ControllerKind = ControllerKind::PID;
use sitl::scenario::ReferenceMode::{FeedForward, FeedForwardJerk, PositionOnly};
use sitl::scenario::metrics::GustMetrics;
use tests::cached;

fn gust(controller: autopilot::core::control::ControllerKind) -> GustMetrics {
    cached("gust-hover", controller, "mismatch", 1, 500, FeedForward).metrics.gust.clone().expect("gust metrics")
}

fn recovery(g: &GustMetrics) -> (f64, f64) {
    (g.recovery_onset_s.unwrap_or(f64::INFINITY), g.recovery_release_s.unwrap_or(f64::INFINITY))
}

#[test]
fn aco_rejects_the_beaufort_4_gust() {
    let (aco, ca, pid) = (gust(ACO), gust(CA), gust(PID));
    let (a_on, a_off) = recovery(&aco);
    for (name, other) in [("CA", &ca), ("PID", &pid)] {
        let (o_on, o_off) = recovery(other);
        assert!(a_on <= 3.0 && a_on <= 0.5 * o_on, "recovery after onset {a_on:.2} s vs {name} {o_on:.2} s");
        assert!(a_off <= 3.0 && a_off <= 0.5 * o_off, "recovery after release {a_off:.2} s vs {name} {o_off:.2} s");
    }
    assert!(aco.peak_m <= 0.18 && aco.peak_m <= 0.6 * ca.peak_m, "peak {:.3} m vs CA {:.3} m", aco.peak_m, ca.peak_m);
    assert!(aco.steady_err_m <= 0.02, "steady error during the gust {:.3} m", aco.steady_err_m);
    assert!(aco.rms_z_m <= 0.01, "vertical rms {:.4} m", aco.rms_z_m);
}

#[test]
fn baselines_recover_from_the_gust_in_their_specified_ranges() {
    let (ca_on, ca_off) = recovery(&gust(CA));
    let (pid_on, pid_off) = recovery(&gust(PID));
    for (what, v, lo, hi) in [
        ("CA onset", ca_on, 6.0, 8.0),
        ("CA release", ca_off, 6.0, 8.0),
        ("PID onset", pid_on, 7.5, 9.5),
        ("PID release", pid_off, 7.5, 9.5),
    ] {
        assert!((lo..=hi).contains(&v), "{what} recovery {v:.2} s outside {lo}-{hi} s");
    }
}

#[test]
fn aco_halves_the_turbulence_error_of_ca_over_five_seeds() {
    let mean = |c| {
        let v: Vec<f64> = (1..=5)
            .map(|seed| {
                cached("turbulence-hover", c, "mismatch", seed, 500, FeedForward)
                    .metrics
                    .gust
                    .clone()
                    .expect("gust metrics")
                    .rms_xy_m
            })
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (aco, ca) = (mean(ACO), mean(CA));
    assert!(aco <= 0.08 && aco <= 0.5 * ca, "mean horizontal rms over 5 seeds: ACO {aco:.3} m, CA {ca:.3} m");
}

#[test]
fn aco_flies_the_figure_8() {
    let track = |c, mode| cached("figure8", c, "mismatch", 1, 500, mode).metrics.track.clone().expect("track metrics");
    let ff = track(ACO, FeedForward);
    assert!(ff.cross_track_rms_m <= 0.025, "feed-forward cross-track rms {:.3} m", ff.cross_track_rms_m);
    assert!(ff.cross_track_max_m <= 0.07, "feed-forward cross-track max {:.3} m", ff.cross_track_max_m);
    assert!(ff.alt_rms_m <= 0.01, "altitude rms {:.4} m", ff.alt_rms_m);
    let (aco, ca) = (track(ACO, PositionOnly), track(CA, PositionOnly));
    assert!(
        aco.cross_track_rms_m <= 1.05 * ca.cross_track_rms_m,
        "position-only cross-track rms {:.3} m vs CA {:.3} m",
        aco.cross_track_rms_m,
        ca.cross_track_rms_m
    );
}

/// docs/experiments.md's "at 0.9 m/s ACO needs the reference's jerk" (`figure8-fast`, mismatch plant, noise on):
/// measured ACO 0.279 m cross-track RMS with velocity and acceleration feed-forward, 0.062 m with the jerk
/// added (`cargo test -p tests --test disturbance_and_tracking fast -- --nocapture` prints all three
/// controllers). Held at 0.07 m with the jerk, and at most a quarter of the RMS without it.
#[test]
fn aco_on_the_fast_figure_8_tracks_within_7_cm_rms_with_the_jerk_and_4x_better_than_without() {
    let track =
        |c, mode| cached("figure8-fast", c, "mismatch", 1, 500, mode).metrics.track.clone().expect("track metrics");
    for (name, c) in [("ACO", ACO), ("CA", CA), ("PID", PID)] {
        let (ff, jerk) = (track(c, FeedForward), track(c, FeedForwardJerk));
        println!(
            "figure8-fast {name}: feed-forward {:.3} / {:.3} m, with jerk {:.3} / {:.3} m cross-track RMS / max",
            ff.cross_track_rms_m, ff.cross_track_max_m, jerk.cross_track_rms_m, jerk.cross_track_max_m
        );
    }
    let (ff, jerk) = (track(ACO, FeedForward).cross_track_rms_m, track(ACO, FeedForwardJerk).cross_track_rms_m);
    assert!(jerk <= 0.07, "with the jerk: cross-track rms {jerk:.3} m");
    assert!(jerk <= 0.25 * ff, "with the jerk {jerk:.3} m against {ff:.3} m without");
}

#[test]
fn noisy_runs_stay_finite_and_inside_the_weight_bounds() {
    for (scenario, mode) in [("gust-hover", FeedForward), ("figure8", FeedForward), ("turbulence-hover", FeedForward)] {
        let out = cached(scenario, ACO, "mismatch", 1, 500, mode);
        assert!(!out.metrics.non_finite, "{scenario}: non-finite value");
        assert!(!out.metrics.weights_at_bounds, "{scenario}: an LMS weight reached its bound");
    }
}

#[test]
fn the_same_seed_gives_a_bit_identical_trace_and_another_seed_does_not() {
    let a = tests::run("turbulence-hover", ACO, "mismatch", 7, 500, FeedForward);
    let b = tests::run("turbulence-hover", ACO, "mismatch", 7, 500, FeedForward);
    let c = tests::run("turbulence-hover", ACO, "mismatch", 8, 500, FeedForward);
    let bits = |t: &sitl::scenario::runner::Trace| t.rows.iter().flatten().map(|v| v.to_bits()).collect::<Vec<u64>>();
    assert_eq!(bits(&a.trace), bits(&b.trace), "same seed, different trace");
    assert_ne!(bits(&a.trace), bits(&c.trace), "different seeds, same trace");
}

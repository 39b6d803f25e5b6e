//! The paper's attitude and translation experiments, noise-free, in lockstep: equivalence with the
//! reference prototype (its table and golden traces) and the ACO acceptance checks of spec (e).

use autopilot::core::control::ControllerKind::{self, Aco, Ca, Pid};
use sitl::scenario::ReferenceMode::FeedForward;
use sitl::scenario::runner::RunOutput;
use tests::{ATTITUDE_TABLE, ReferenceRow, TRANSLATION_TABLE, cached, golden, rms, segment};

const PLANTS: [&str; 2] = ["nominal", "mismatch"];
const ATT_AXES: [&str; 3] = ["roll", "pitch", "yaw"];

fn att(controller: ControllerKind, plant: &str) -> std::sync::Arc<RunOutput> {
    cached("paper-attitude", controller, plant, 1, 500, FeedForward)
}

fn trans(controller: ControllerKind, plant: &str) -> std::sync::Arc<RunOutput> {
    cached("paper-translation", controller, plant, 1, 500, FeedForward)
}

/// The initial-step segments in table order: attitude (roll, pitch, yaw at 0 s), translation (n, e at
/// 0 s, climb at 0 s, descent at 10 s).
fn table_segments(out: &RunOutput, attitude: bool) -> Vec<&sitl::scenario::metrics::SegmentMetrics> {
    if attitude {
        ATT_AXES.iter().map(|a| segment(out, a, 0.0)).collect()
    } else {
        vec![segment(out, "n", 0.0), segment(out, "e", 0.0), segment(out, "d", 0.0), segment(out, "d", 10.0)]
    }
}

fn later_worst_overshoot(out: &RunOutput) -> f64 {
    out.metrics.segments.iter().flatten().filter(|s| s.t0_s > 0.0).map(|s| s.overshoot_pct).fold(0.0, f64::max)
}

fn check_equivalence(row: &ReferenceRow, out: &RunOutput, attitude: bool) -> Vec<String> {
    let mut bad = Vec::new();
    let who = format!("{} {} {:?}", out.metrics.scenario, row.plant, row.controller);
    for (seg, want) in table_segments(out, attitude).iter().zip(row.steps) {
        if (seg.overshoot_pct - want.overshoot_pct).abs() > 1.0 {
            bad.push(format!(
                "{who} {} t0 {}: overshoot {:.2} % vs {:.1} %",
                seg.axis, seg.t0_s, seg.overshoot_pct, want.overshoot_pct
            ));
        }
        match (seg.settling_s, want.settling_s) {
            (Some(got), Some(w)) if (got - w).abs() <= 0.3 => {}
            (got, w) => bad.push(format!("{who} {} t0 {}: settling {got:?} s vs {w:?} s", seg.axis, seg.t0_s)),
        }
    }
    if let Some(w) = row.worst_later_overshoot_pct {
        let got = later_worst_overshoot(out);
        if (got - w).abs() > 1.0 {
            bad.push(format!("{who}: worst overshoot on the 6/10 s steps {got:.2} % vs {w:.1} %"));
        }
    }
    let axes: [&str; 3] = if attitude { ATT_AXES } else { ["n", "e", "d"] };
    for (axis, want) in axes.iter().zip(row.rms) {
        let got = rms(out, axis);
        if (got - want).abs() > 0.05 * want {
            bad.push(format!("{who} {axis}: rms {got:.4} vs {want:.3}"));
        }
    }
    bad
}

#[test]
fn aco_matches_the_reference_results_on_both_plants() {
    let mut bad = Vec::new();
    for row in ATTITUDE_TABLE.iter().filter(|r| r.controller == Aco) {
        bad.extend(check_equivalence(row, &att(row.controller, row.plant), true));
    }
    for row in TRANSLATION_TABLE.iter().filter(|r| r.controller == Aco) {
        bad.extend(check_equivalence(row, &trans(row.controller, row.plant), false));
    }
    assert!(bad.is_empty(), "ACO departs from the reference results:\n{}", bad.join("\n"));
}

#[test]
fn baselines_match_the_reference_translation_results_on_both_plants() {
    let mut bad = Vec::new();
    for row in TRANSLATION_TABLE.iter().filter(|r| r.controller != Aco) {
        bad.extend(check_equivalence(row, &trans(row.controller, row.plant), false));
    }
    assert!(bad.is_empty(), "baselines depart from the reference results:\n{}", bad.join("\n"));
}

#[test]
fn baselines_match_the_reference_attitude_results_on_both_plants() {
    let mut bad = Vec::new();
    for row in ATTITUDE_TABLE.iter().filter(|r| r.controller != Aco) {
        bad.extend(check_equivalence(row, &att(row.controller, row.plant), true));
    }
    assert!(bad.is_empty(), "baselines depart from the reference results:\n{}", bad.join("\n"));
}

#[test]
fn aco_follows_the_golden_traces_within_2_cm_and_10_mrad() {
    let mut worst = Vec::new();
    for plant in PLANTS {
        for (scenario, file) in [("paper-attitude", "att"), ("paper-translation", "pos")] {
            let out = cached(scenario, Aco, plant, 1, 500, FeedForward);
            let gold = golden(&format!("golden_ACO_paper_{file}_{plant}.csv"));
            assert_eq!(out.trace.rows.len(), gold.len(), "{scenario} {plant}: trace rows");
            let (mut dp, mut da) = (0.0_f64, 0.0_f64);
            for (row, g) in out.trace.rows.iter().zip(&gold) {
                assert!((row[0] - g[0]).abs() < 1e-9, "sample times differ");
                for i in 1..4 {
                    dp = dp.max((row[i] - g[i]).abs());
                }
                for i in 4..7 {
                    da = da.max(sitl::scenario::metrics::wrap_pi(row[i] - g[i]).abs());
                }
            }
            worst.push((scenario, plant, dp, da));
        }
    }
    for (scenario, plant, dp, da) in &worst {
        assert!(
            *dp <= 0.02 && *da <= 0.01,
            "{scenario} {plant}: max |dp| {dp:.4} m, max |d angle| {da:.4} rad (all: {worst:?})"
        );
    }
}

#[test]
fn aco_attitude_meets_its_acceptance_checks() {
    for plant in PLANTS {
        let (aco, ca) = (att(Aco, plant), att(Ca, plant));
        for seg in aco.metrics.segments.iter().flatten() {
            let who = format!("{plant} {} t0 {}", seg.axis, seg.t0_s);
            assert!(seg.overshoot_pct <= 2.0, "{who}: overshoot {:.2} %", seg.overshoot_pct);
            let ts = seg.settling_s.unwrap_or(f64::INFINITY);
            let limit = match (seg.axis, seg.t0_s == 0.0) {
                ("yaw", true) => 3.5,
                ("yaw", false) => 2.7,
                _ => 1.5,
            };
            assert!(ts <= limit, "{who}: settling {ts:.2} s > {limit} s");
            assert!(seg.sse <= 1e-3, "{who}: steady-state error {:.2e} rad", seg.sse);
        }
        let (ya, yc) = (segment(&aco, "yaw", 0.0), segment(&ca, "yaw", 0.0));
        let (ya, yc) = (ya.settling_s.unwrap(), yc.settling_s.unwrap_or(f64::INFINITY));
        assert!(ya + 2.0 <= yc, "{plant}: ACO yaw settles in {ya:.2} s, CA in {yc:.2} s: not 2 s faster");
        for axis in ["roll", "pitch"] {
            let (a, c) = (segment(&aco, axis, 0.0), segment(&ca, axis, 0.0));
            assert!(a.overshoot_pct <= (0.5 * c.overshoot_pct).max(2.0), "{plant} {axis}: overshoot vs CA");
            let (ta, tc) = (a.settling_s.unwrap(), c.settling_s.unwrap_or(f64::INFINITY));
            assert!(ta <= tc + 0.3, "{plant} {axis}: settling {ta:.2} s vs CA {tc:.2} s");
        }
        for axis in ATT_AXES {
            let (a, c) = (rms(&aco, axis), rms(&ca, axis));
            assert!(a <= 1.05 * c, "{plant} {axis}: rms {a:.4} vs CA {c:.4}");
        }
    }
}

#[test]
fn aco_translation_meets_its_acceptance_checks() {
    for plant in PLANTS {
        let (aco, ca) = (trans(Aco, plant), trans(Ca, plant));
        for seg in aco.metrics.segments.iter().flatten() {
            let who = format!("{plant} {} t0 {}", seg.axis, seg.t0_s);
            assert!(seg.overshoot_pct <= 1.0, "{who}: overshoot {:.2} %", seg.overshoot_pct);
            let limit = match (seg.axis, seg.t0_s == 0.0) {
                ("d", true) => 6.0,
                ("d", false) => 4.5,
                _ => 7.5,
            };
            let ts = seg.settling_s.unwrap_or(f64::INFINITY);
            assert!(ts <= limit, "{who}: settling {ts:.2} s > {limit} s");
            assert!(seg.sse <= 5e-3, "{who}: steady-state error {:.2e} m", seg.sse);
        }
        for axis in ["n", "e"] {
            let (a, c) = (segment(&aco, axis, 0.0).overshoot_pct, segment(&ca, axis, 0.0).overshoot_pct);
            if c >= 3.0 {
                assert!(a <= c / 3.0, "{plant} {axis}: overshoot {a:.2} % vs CA {c:.2} %");
            }
        }
        for axis in ["n", "e", "d"] {
            let (a, c) = (rms(&aco, axis), rms(&ca, axis));
            assert!(a <= 1.1 * c, "{plant} {axis}: rms {a:.4} vs CA {c:.4}");
        }
    }
}

#[test]
fn aco_stays_finite_inside_its_weight_bounds_and_is_no_busier_than_pid() {
    for plant in PLANTS {
        for scenario in ["paper-attitude", "paper-translation"] {
            let aco = cached(scenario, Aco, plant, 1, 500, FeedForward);
            let pid = cached(scenario, Pid, plant, 1, 500, FeedForward);
            assert!(!aco.metrics.non_finite, "{scenario} {plant}: non-finite value");
            assert!(!aco.metrics.weights_at_bounds, "{scenario} {plant}: an LMS weight reached its bound");
            let (a, p) = (aco.metrics.pwm_activity_us, pid.metrics.pwm_activity_us);
            assert!(a <= 1.2 * p, "{scenario} {plant}: PWM activity {a:.3} vs PID {p:.3} us/tick");
        }
    }
}

#[test]
fn baselines_are_the_specified_ones_on_the_mismatch_plant() {
    for axis in ["n", "e"] {
        let os = segment(&trans(Ca, "mismatch"), axis, 0.0).overshoot_pct;
        assert!((2.0..=8.0).contains(&os), "CA {axis} overshoot {os:.2} % outside 2-8 %");
    }
    let os = segment(&att(Pid, "mismatch"), "pitch", 0.0).overshoot_pct;
    assert!((5.0..=9.0).contains(&os), "PID pitch overshoot {os:.2} % outside 5-9 %");
}

/// "Every metric within 10 % or 0.2 s of its 500 Hz value": times within max(10 %, 0.2 s), overshoot within
/// max(10 %, 0.2 points), RMS within 10 %.
#[test]
fn aco_is_loop_rate_invariant_at_250_and_1000_hz() {
    let mut bad = Vec::new();
    for scenario in ["paper-attitude", "paper-translation"] {
        for plant in PLANTS {
            let base = cached(scenario, Aco, plant, 1, 500, FeedForward);
            for hz in [250, 1000] {
                let out = cached(scenario, Aco, plant, 1, hz, FeedForward);
                for (b, o) in base.metrics.segments.iter().flatten().zip(out.metrics.segments.iter().flatten()) {
                    let who = format!("{scenario} {plant} {hz} Hz {} t0 {}", b.axis, b.t0_s);
                    match (b.settling_s, o.settling_s) {
                        (Some(tb), Some(to)) if (to - tb).abs() <= (0.1 * tb).max(0.2) => {}
                        (tb, to) => bad.push(format!("{who}: settling {to:?} vs {tb:?} s")),
                    }
                    if (o.overshoot_pct - b.overshoot_pct).abs() > (0.1 * b.overshoot_pct).max(0.2) {
                        bad.push(format!("{who}: overshoot {:.2} vs {:.2} %", o.overshoot_pct, b.overshoot_pct));
                    }
                }
                for (axis, rb) in base.metrics.rms.iter().flatten() {
                    let ro = rms(&out, axis);
                    if (ro - rb).abs() > 0.1 * rb {
                        bad.push(format!("{scenario} {plant} {hz} Hz {axis}: rms {ro:.4} vs {rb:.4}"));
                    }
                }
            }
        }
    }
    assert!(bad.is_empty(), "loop-rate dependence:\n{}", bad.join("\n"));
}

/// The competent CA's scenario file (docs/controller.md §4.3), loaded from `sitl/scenarios/competent-ca/`.
fn competent_ca(file: &str) -> sitl::scenario::Scenario {
    let path = format!("{}/../sitl/scenarios/competent-ca/{file}", env!("CARGO_MANIFEST_DIR"));
    sitl::scenario::Scenario::load(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The competent CA (feed-forward, integral of the model-following error, e-modification, hedging, attitude
/// adaptation rates of 100) settles every step of the paper's attitude experiment within 2 % in under
/// 3.5 s on both plants (the tuning guard asks 4 s; measured at most 3.03 s, yaw at 0 s on the mismatch
/// plant), overshoots under 2 % and ends each step within 1 mrad, where the paper's CA keeps up to
/// 19 mrad and its mismatch yaw never settles. The file's block is `MracConfig::competent()`.
#[test]
fn competent_ca_settles_every_paper_attitude_step_within_3_5_s_on_both_plants() {
    let scenario = competent_ca("paper-attitude.toml");
    assert_eq!(scenario.controller.mrac, autopilot::core::control::MracConfig::competent());
    let mut bad = Vec::new();
    for plant in PLANTS {
        let out = tests::run_scenario(&scenario, Ca, plant, 1, 500, FeedForward);
        assert!(!out.metrics.weights_at_bounds && !out.metrics.non_finite, "{plant}");
        let segments: Vec<_> = out.metrics.segments.iter().flatten().collect();
        assert_eq!(segments.len(), 9, "{plant}: roll, pitch and yaw at 0, 6 and 10 s");
        for s in segments {
            let who = format!("{plant} {} t0 {}", s.axis, s.t0_s);
            match s.settling_s {
                Some(t) if t <= 3.5 => {}
                t => bad.push(format!("{who}: settling {t:?} s")),
            }
            if s.overshoot_pct > 2.0 {
                bad.push(format!("{who}: overshoot {:.2} %", s.overshoot_pct));
            }
            if s.sse > 1e-3 {
                bad.push(format!("{who}: sse {:.1e} rad", s.sse));
            }
        }
    }
    let paper = att(Ca, "mismatch");
    assert_eq!(segment(&paper, "yaw", 6.0).settling_s, None, "the paper's CA: mismatch yaw at 6 s never settles");
    assert!(bad.is_empty(), "competent CA on paper-attitude:\n{}", bad.join("\n"));
}

/// With the reference's jerk, the competent CA tracks the 0.9 m/s figure-8 on the mismatch plant with
/// under half the paper's CA's cross-track RMS (measured 0.050 m against 0.132 m, seed 1), which reads
/// the reference position only and flies every mode alike.
#[test]
fn competent_ca_halves_the_papers_cross_track_on_the_fast_figure_8_with_the_jerk() {
    use sitl::scenario::ReferenceMode::FeedForwardJerk;
    let competent = tests::run_scenario(&competent_ca("figure8-fast.toml"), Ca, "mismatch", 1, 500, FeedForwardJerk);
    let paper = cached("figure8-fast", Ca, "mismatch", 1, 500, FeedForwardJerk);
    let rms = |out: &RunOutput| out.metrics.track.as_ref().expect("a track run").cross_track_rms_m;
    let (c, p) = (rms(&competent), rms(&paper));
    assert!(c < 0.5 * p, "competent CA {c:.3} m vs paper's CA {p:.3} m");
    assert!(!competent.metrics.weights_at_bounds && !competent.metrics.non_finite);
}

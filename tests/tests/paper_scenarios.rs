//! The paper's attitude and translation experiments, noise-free, in lockstep: equivalence with the
//! reference prototype (its table and golden traces) and the ACO acceptance checks of spec (e).

use autopilot::core::control::ControllerKind;
const ACO: ControllerKind = ControllerKind::ACO;
const CA: ControllerKind = ControllerKind::CA;
const PID: ControllerKind = ControllerKind::PID;
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
    let who = format!("{} {} {}", out.metrics.scenario, row.plant, row.controller.as_str().to_uppercase());
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
fn aco_matches_the_reference_results_on_both_plants_within_1_point_0_3_s_and_5_percent() {
    let mut bad = Vec::new();
    for row in ATTITUDE_TABLE.iter().filter(|r| r.controller == ACO) {
        bad.extend(check_equivalence(row, &att(row.controller, row.plant), true));
    }
    for row in TRANSLATION_TABLE.iter().filter(|r| r.controller == ACO) {
        bad.extend(check_equivalence(row, &trans(row.controller, row.plant), false));
    }
    assert!(bad.is_empty(), "ACO departs from the reference results:\n{}", bad.join("\n"));
}

#[test]
fn baselines_match_the_reference_translation_results_on_both_plants_within_1_point_0_3_s_and_5_percent() {
    let mut bad = Vec::new();
    for row in TRANSLATION_TABLE.iter().filter(|r| r.controller != ACO) {
        bad.extend(check_equivalence(row, &trans(row.controller, row.plant), false));
    }
    assert!(bad.is_empty(), "baselines depart from the reference results:\n{}", bad.join("\n"));
}

#[test]
fn baselines_match_the_reference_attitude_results_on_both_plants_within_1_point_0_3_s_and_5_percent() {
    let mut bad = Vec::new();
    for row in ATTITUDE_TABLE.iter().filter(|r| r.controller != ACO) {
        bad.extend(check_equivalence(row, &att(row.controller, row.plant), true));
    }
    assert!(bad.is_empty(), "baselines depart from the reference results:\n{}", bad.join("\n"));
}

/// Every cell of the reference tables that the tests hold (overshoot, settling, worst later overshoot,
/// RMS), as (row and cell, ours, the prototype's), each printed to the prototype's digits.
fn printed_cells() -> Vec<(String, String, String)> {
    let mut cells = Vec::new();
    for (table, attitude) in [(ATTITUDE_TABLE, true), (TRANSLATION_TABLE, false)] {
        let axes: &[&str] = if attitude { &["roll", "pitch", "yaw"] } else { &["n", "e", "d up", "d down"] };
        for row in table {
            let out = if attitude { att(row.controller, row.plant) } else { trans(row.controller, row.plant) };
            let who = format!("{} {} {}", out.metrics.scenario, row.plant, row.controller.as_str().to_uppercase());
            for ((seg, want), axis) in table_segments(&out, attitude).iter().zip(row.steps).zip(axes) {
                cells.push((
                    format!("{who} {axis} overshoot %"),
                    format!("{:.1}", seg.overshoot_pct),
                    format!("{:.1}", want.overshoot_pct),
                ));
                let print = |t: Option<f64>| t.map_or_else(|| "never".to_owned(), |t| format!("{t:.2}"));
                cells.push((format!("{who} {axis} settling s"), print(seg.settling_s), print(want.settling_s)));
            }
            if let Some(w) = row.worst_later_overshoot_pct {
                cells.push((
                    format!("{who} worst overshoot on the 6/10 s steps %"),
                    format!("{:.1}", later_worst_overshoot(&out)),
                    format!("{w:.1}"),
                ));
            }
            let rms_axes: [&str; 3] = if attitude { ATT_AXES } else { ["n", "e", "d"] };
            for (axis, want) in rms_axes.iter().zip(row.rms) {
                cells.push((format!("{who} {axis} rms"), format!("{:.3}", rms(&out, axis)), format!("{want:.3}")));
            }
        }
    }
    cells
}

/// The cells where our figure, printed to the prototype's digits, differs from its table: (row and cell,
/// ours, the prototype's). Each is one unit in the last printed digit.
const CELLS_OFF_BY_A_PRINTED_DIGIT: [(&str, &str, &str); 8] = [
    ("paper-attitude mismatch ACO roll rms", "0.065", "0.066"),
    ("paper-attitude mismatch PID pitch overshoot %", "6.9", "6.8"),
    ("paper-attitude mismatch PID pitch settling s", "1.78", "1.77"),
    ("paper-attitude mismatch PID yaw settling s", "4.68", "4.67"),
    ("paper-attitude mismatch PID worst overshoot on the 6/10 s steps %", "12.9", "12.8"),
    ("paper-attitude nominal PID roll settling s", "1.31", "1.30"),
    ("paper-attitude nominal PID worst overshoot on the 6/10 s steps %", "3.4", "3.3"),
    ("paper-translation mismatch PID e settling s", "7.65", "7.64"),
];

/// docs/experiments.md's claim, cell by cell: of the 126 overshoot, settling and RMS cells of the prototype's
/// attitude and translation tables (ACO, CA and PID, both plants), every one prints as the prototype's
/// but exactly the eight listed, whose last printed digit differs by one. A cell that starts or stops
/// matching fails this test, so the list in docs/experiments.md stays exact.
#[test]
fn the_reference_tables_match_to_the_printed_digit_in_all_but_8_of_126_cells() {
    let cells = printed_cells();
    assert_eq!(cells.len(), 126, "cells compared");
    let off: Vec<(&str, &str, &str)> = cells
        .iter()
        .filter(|(_, ours, theirs)| ours != theirs)
        .map(|(w, o, t)| (w.as_str(), o.as_str(), t.as_str()))
        .collect();
    assert_eq!(off, CELLS_OFF_BY_A_PRINTED_DIGIT, "cells whose printed digits differ from the prototype's");
}

/// ACO against the prototype's four golden traces (50 Hz samples of NED position and Euler angles): the
/// largest gap is 1.50 mm and 1.96e-5 rad, on the nominal attitude run (`cargo test -p tests --test
/// paper_scenarios golden -- --nocapture` prints each trace's). Held at 2 mm and 3e-5 rad (30 µrad), a
/// hundred times tighter than the spec's stretch goal of 0.02 m and 0.01 rad.
#[test]
fn aco_follows_the_golden_traces_within_2_mm_and_30_urad() {
    const POS_TOL_M: f64 = 0.002;
    const ANGLE_TOL_RAD: f64 = 3e-5;
    let mut worst = Vec::new();
    for plant in PLANTS {
        for (scenario, file) in [("paper-attitude", "att"), ("paper-translation", "pos")] {
            let out = cached(scenario, ACO, plant, 1, 500, FeedForward);
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
            println!("{scenario} {plant}: max |d pos| {:.3} mm, max |d angle| {da:.2e} rad", dp * 1e3);
            worst.push((scenario, plant, dp, da));
        }
    }
    for (scenario, plant, dp, da) in &worst {
        assert!(
            *dp <= POS_TOL_M && *da <= ANGLE_TOL_RAD,
            "{scenario} {plant}: max |dp| {dp:.2e} m, max |d angle| {da:.2e} rad (all: {worst:?})"
        );
    }
}

#[test]
fn aco_attitude_meets_its_acceptance_checks() {
    for plant in PLANTS {
        let (aco, ca) = (att(ACO, plant), att(CA, plant));
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
        let (aco, ca) = (trans(ACO, plant), trans(CA, plant));
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
fn aco_stays_finite_inside_its_weight_bounds_and_its_pwm_at_most_1_2x_as_busy_as_pid() {
    for plant in PLANTS {
        for scenario in ["paper-attitude", "paper-translation"] {
            let aco = cached(scenario, ACO, plant, 1, 500, FeedForward);
            let pid = cached(scenario, PID, plant, 1, 500, FeedForward);
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
        let os = segment(&trans(CA, "mismatch"), axis, 0.0).overshoot_pct;
        assert!((2.0..=8.0).contains(&os), "CA {axis} overshoot {os:.2} % outside 2-8 %");
    }
    let os = segment(&att(PID, "mismatch"), "pitch", 0.0).overshoot_pct;
    assert!((5.0..=9.0).contains(&os), "PID pitch overshoot {os:.2} % outside 5-9 %");
}

/// "Every metric within 10 % or 0.2 s of its 500 Hz value": times within max(10 %, 0.2 s), overshoot within
/// max(10 %, 0.2 points), RMS within 10 %.
#[test]
fn aco_paper_metrics_at_250_and_1000_hz_stay_within_10_percent_or_0_2_s_of_their_500_hz_values() {
    let mut bad = Vec::new();
    for scenario in ["paper-attitude", "paper-translation"] {
        for plant in PLANTS {
            let base = cached(scenario, ACO, plant, 1, 500, FeedForward);
            for hz in [250, 1000] {
                let out = cached(scenario, ACO, plant, 1, hz, FeedForward);
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
        let out = tests::run_scenario(&scenario, CA, plant, 1, 500, FeedForward);
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
    let paper = att(CA, "mismatch");
    assert_eq!(segment(&paper, "yaw", 6.0).settling_s, None, "the paper's CA: mismatch yaw at 6 s never settles");
    assert!(bad.is_empty(), "competent CA on paper-attitude:\n{}", bad.join("\n"));
}

/// With the reference's jerk, the competent CA tracks the 0.9 m/s figure-8 on the mismatch plant with
/// under half the paper's CA's cross-track RMS (measured 0.050 m against 0.132 m, seed 1), which reads
/// the reference position only and flies every mode alike.
#[test]
fn competent_ca_halves_the_papers_cross_track_on_the_fast_figure_8_with_the_jerk() {
    use sitl::scenario::ReferenceMode::FeedForwardJerk;
    let competent = tests::run_scenario(&competent_ca("figure8-fast.toml"), CA, "mismatch", 1, 500, FeedForwardJerk);
    let paper = cached("figure8-fast", CA, "mismatch", 1, 500, FeedForwardJerk);
    let rms = |out: &RunOutput| out.metrics.track.as_ref().expect("a track run").cross_track_rms_m;
    let (c, p) = (rms(&competent), rms(&paper));
    assert!(c < 0.5 * p, "competent CA {c:.3} m vs paper's CA {p:.3} m");
    assert!(!competent.metrics.weights_at_bounds && !competent.metrics.non_finite);
}

/// Why the baselines' roll/pitch saturation freezes are off by default: with them acting, as the spec's
/// text reads, every initial roll and pitch settling time of CA and PID (both plants) misses the
/// prototype's by more than 0.2 s (CA mismatch roll 4.93 s against 1.10 s), and three of the four
/// baseline attitude rows leave the spec's tolerances (CA nominal stays inside, 0.26 s off).
#[test]
fn with_the_roll_pitch_freezes_acting_every_baseline_roll_and_pitch_settling_misses_the_prototype_by_over_0_2_s() {
    let mut s = sitl::scenario::Scenario::load("paper-attitude").expect("built-in");
    s.controller.mrac.freeze_roll_pitch = true;
    s.controller.pid.freeze_roll_pitch = true;
    let mut rows_outside = Vec::new();
    for row in ATTITUDE_TABLE.iter().filter(|r| r.controller != ACO) {
        let out = tests::run_scenario(&s, row.controller, row.plant, 1, 500, FeedForward);
        for (seg, want) in table_segments(&out, true).iter().zip(row.steps).take(2) {
            let (got, want) = (seg.settling_s.unwrap_or(f64::INFINITY), want.settling_s.expect("the table's"));
            println!("frozen {} {} {}: settling {got:.3} s against {want:.2} s", row.plant, row.controller, seg.axis);
            assert!(
                (got - want).abs() > 0.2,
                "{} {:?} {}: {got:.3} s against {want} s",
                row.plant,
                row.controller,
                seg.axis
            );
        }
        if !check_equivalence(row, &out, true).is_empty() {
            rows_outside.push((row.plant, row.controller));
        }
    }
    assert_eq!(rows_outside, [("mismatch", CA), ("mismatch", PID), ("nominal", PID)], "rows outside the tolerances");
}

/// The metric definitions checked on data they did not produce: applied to the prototype's own golden
/// traces (ACO, 50 Hz samples), they give every overshoot of its ACO rows to the printed digit, and every
/// settling time within one 20 ms sample of its figure (its table came from finer samples: yaw 2.90
/// against 2.89 s, for example).
#[test]
fn metrics_of_the_golden_traces_give_the_prototypes_overshoots_to_the_printed_digit_and_settling_within_20_ms() {
    use sitl::scenario::metrics::{StepSegment, step_metrics};
    let step = |axis, t0_s, t1_s, start, target| StepSegment { axis, t0_s, t1_s, start, target, wrap: axis == "yaw" };
    let mut bad = Vec::new();
    for row in ATTITUDE_TABLE.iter().chain(TRANSLATION_TABLE).filter(|r| r.controller == ACO) {
        let attitude = row.worst_later_overshoot_pct.is_some();
        let file = if attitude { "att" } else { "pos" };
        let gold = golden(&format!("golden_ACO_paper_{file}_{}.csv", row.plant));
        let t: Vec<f64> = gold.iter().map(|g| g[0]).collect();
        // (golden column, the step) as the scenario files set them: attitude from (0.4, -0.5, -0.4) rad to
        // level until 6 s; translation from the origin to (1, -1, -3) m, then D to -2 m at 10 s.
        let segments = if attitude {
            vec![
                (4, step("roll", 0.0, 6.0, 0.4, 0.0)),
                (5, step("pitch", 0.0, 6.0, -0.5, 0.0)),
                (6, step("yaw", 0.0, 6.0, -0.4, 0.0)),
            ]
        } else {
            vec![
                (1, step("n", 0.0, 22.0, 0.0, 1.0)),
                (2, step("e", 0.0, 22.0, 0.0, -1.0)),
                (3, step("d", 0.0, 10.0, 0.0, -3.0)),
                (3, step("d", 10.0, 22.0, -3.0, -2.0)),
            ]
        };
        for ((column, seg), want) in segments.iter().zip(row.steps) {
            let y: Vec<f64> = gold.iter().map(|g| g[*column]).collect();
            let m = step_metrics(&t, &y, seg);
            let who = format!("{file} {} {} t0 {}", row.plant, seg.axis, seg.t0_s);
            let (got, want_s) = (m.settling_s.unwrap_or(f64::INFINITY), want.settling_s.expect("the table's"));
            println!(
                "{who}: overshoot {:.3} % ({:.1}), settling {got:.2} s ({want_s:.2})",
                m.overshoot_pct, want.overshoot_pct
            );
            if format!("{:.1}", m.overshoot_pct) != format!("{:.1}", want.overshoot_pct) {
                bad.push(format!("{who}: overshoot {:.3} % against {:.1} %", m.overshoot_pct, want.overshoot_pct));
            }
            if (got - want_s).abs() > 0.02 + 1e-9 {
                bad.push(format!("{who}: settling {got:.3} s against {want_s:.2} s"));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

//! Tests of sweep specs, case generation, shards, the row files and the summary.

use super::table::{self, percentile};
use super::*;
use crate::scenario::MetricKind;

/// A short gust hover (6 s, gust from 1 s to 3 s), so a sweep of a few runs takes well under a second: the
/// shared fixture, 5 m/s.
fn short_gust() -> Scenario {
    crate::scenario::fixtures::short_gust(5.0, 3.0)
}

const SPEC: &str = r#"
name = "t"
scenario = "unused: the tests pass the scenario"
controllers = ["aco", "ca", "pid"]
samples = 3
seed = 7
[vary]
mass_kg = { scale = [0.85, 1.15] }
gust_amplitude_mps = { uniform = [0.0, 10.0] }
gust_azimuth_deg = { values = [0.0, 90.0] }
[bounds]
gust_peak_m = 0.5
"#;

fn sweep(text: &str) -> Result<Sweep, SweepError> {
    Sweep::from_toml(text, short_gust())
}

fn error(text: &str) -> String {
    sweep(text).unwrap_err().to_string()
}

#[test]
fn the_cases_are_the_grid_times_the_samples_and_each_runs_every_controller() {
    let s = sweep(SPEC).unwrap();
    assert_eq!(s.cases(), 6);
    assert_eq!(s.runs(), 18);
    assert_eq!(s.param_names(), ["mass_kg", "gust_amplitude_mps", "gust_azimuth_deg"]);
    let nominal_mass = runner::plant_config(&s.scenario, None).unwrap().airframe.mass_kg;
    let mut azimuths = Vec::new();
    for c in 0..s.cases() {
        let case = s.case(c).unwrap();
        let [mass, gust, azimuth] = case.values[..] else { panic!("{:?}", case.values) };
        assert!(mass >= 0.85 * nominal_mass && mass <= 1.15 * nominal_mass, "{mass}");
        assert!((0.0..=10.0).contains(&gust), "{gust}");
        azimuths.push(azimuth);
        // The values reach the scenario the run flies.
        assert_eq!(case.scenario.airframe.mass_kg, Some(mass));
        let g = case.scenario.wind.gust.as_ref().unwrap();
        assert_eq!(g.amplitude_mps, Some(gust));
        assert!((g.direction_ned[0] - azimuth.to_radians().cos()).abs() < 1e-12);
    }
    // The grid axis: the first three cases at 0 deg, the next three at 90 deg.
    assert_eq!(azimuths, [0.0, 0.0, 0.0, 90.0, 90.0, 90.0]);
    // The sensor-noise scale reaches the run's scenario.
    let noisy = sweep(&SPEC.replace("[bounds]", "state_noise_scale = { values = [0.5, 2.0] }\n[bounds]")).unwrap();
    assert_eq!(noisy.cases(), 12);
    assert_eq!(noisy.case(11).unwrap().scenario.state_noise_scale, 2.0);
    // Random draws differ between cases and repeat for the same case.
    assert_ne!(s.case(0).unwrap().values, s.case(1).unwrap().values);
    assert_eq!(s.case(4).unwrap().values, s.case(4).unwrap().values);
    assert_ne!(s.case(0).unwrap().seed, s.case(1).unwrap().seed);
}

#[test]
fn another_sweep_seed_draws_other_values() {
    let a = sweep(SPEC).unwrap();
    let b = sweep(&SPEC.replace("seed = 7", "seed = 8")).unwrap();
    assert_ne!(a.case(0).unwrap().values, b.case(0).unwrap().values);
}

#[test]
fn bad_specs_are_refused_naming_what_is_wrong() {
    let e = error(&SPEC.replace("samples = 3", "samples = 3\nbogus = 1"));
    assert!(e.contains("bogus"), "{e}");
    let e = error(&SPEC.replace("mass_kg =", "mass_g ="));
    assert!(e.contains("mass_g") && e.contains("thrust_scale"), "{e}");
    let e = error(&SPEC.replace("[0.85, 1.15]", "[1.15, 0.85]"));
    assert!(e.contains("mass_kg") && e.contains("ascending"), "{e}");
    let e = error(&SPEC.replace("uniform = [0.0, 10.0]", "gaussian = [0.0, 10.0]"));
    assert!(e.contains("gaussian"), "{e}");
    let e = error(
        &SPEC.replace("gust_azimuth_deg = { values = [0.0, 90.0] }", "wind_azimuth_deg = { scale = [0.0, 1.0] }"),
    );
    assert!(e.contains("wind_azimuth_deg") && e.contains("uniform"), "{e}");
    let e = error(&SPEC.replace("[bounds]", "beaufort = { values = [3.0, 4.0] }\n[bounds]"));
    assert!(e.contains("beaufort") && e.contains("gust_amplitude_mps"), "{e}");
    let e = error(&SPEC.replace("gust_peak_m = 0.5", "cross_track_rms_m = 0.5"));
    assert!(e.contains("cross_track_rms_m") && e.contains("gust_peak_m"), "{e}");
    let e = error(&SPEC.replace("samples = 3", "samples = 0"));
    assert!(e.contains("samples"), "{e}");
    let e = error(&SPEC.replace("[bounds]", "seed = { values = [1.5] }\n[bounds]"));
    assert!(e.contains("seed") && e.contains("whole"), "{e}");
    // A value no plant can have fails at load, naming the case, before any run.
    let e = error(&SPEC.replace("{ scale = [0.85, 1.15] }", "{ uniform = [-1.0, -0.5] }"));
    assert!(e.contains("case 0") && e.contains("mass"), "{e}");
    let e = error(&SPEC.replace("[bounds]", "state_noise_scale = { uniform = [-1.0, 0.0] }\n[bounds]"));
    assert!(e.contains("case 0") && e.contains("state_noise_scale"), "{e}");
    // The gust parameters need a gust.
    let mut calm = short_gust();
    calm.wind.gust = None;
    calm.metrics = vec![MetricKind::Steps];
    let e = Sweep::from_toml(SPEC, calm).unwrap_err().to_string();
    assert!(e.contains("gust") && e.contains("[wind.gust]"), "{e}");
}

#[test]
fn shards_split_the_runs_without_gaps_or_overlap() {
    assert_eq!(shard_runs(10, (1, 3)), [0, 3, 6, 9]);
    assert_eq!(shard_runs(10, (3, 3)), [2, 5, 8]);
    let mut all: Vec<u64> = (1..=4).flat_map(|k| shard_runs(18, (k, 4))).collect();
    all.sort_unstable();
    assert_eq!(all, (0..18).collect::<Vec<_>>());
    assert_eq!(parse_shard("2/3"), Ok((2, 3)));
    for bad in ["0/3", "4/3", "1/0", "2", "a/3", "1/b"] {
        assert!(parse_shard(bad).is_err(), "{bad}");
    }
}

#[test]
fn merged_shards_equal_the_unsharded_run_row_for_row_and_bit_for_bit() {
    let s = sweep(SPEC).unwrap();
    let whole: Vec<Row> = (0..s.runs()).map(|r| s.run(r).unwrap()).collect();
    let csv = table::to_csv(&s, &whole);
    // Shards run separately (and in any order), written and read back as files would be.
    let shards: Vec<Vec<Row>> = [(3, 3), (1, 3), (2, 3)]
        .iter()
        .map(|&k| {
            let rows: Vec<Row> = shard_runs(s.runs(), k).iter().map(|&r| s.run(r).unwrap()).collect();
            table::from_csv(&s, "shard", &table::to_csv(&s, &rows)).unwrap()
        })
        .collect();
    let merged = table::merge(&s, shards.clone()).unwrap();
    assert_eq!(merged, whole);
    assert_eq!(table::to_csv(&s, &merged), csv);
    // The paired design: a case's controllers share its seed and values.
    assert!(whole.chunks(3).all(|c| c.iter().all(|r| r.seed == c[0].seed && r.params == c[0].params)));
    // A missing shard, a shard given twice, or another spec's shard is refused.
    let e = table::merge(&s, shards[..2].to_vec()).unwrap_err().to_string();
    assert!(e.contains("missing"), "{e}");
    let e = table::merge(&s, [shards.clone(), vec![shards[0].clone()]].concat()).unwrap_err().to_string();
    assert!(e.contains("more than one shard"), "{e}");
    let other = sweep(&SPEC.replace("seed = 7", "seed = 9")).unwrap();
    let e = table::merge(&other, shards).unwrap_err().to_string();
    assert!(e.contains("not this spec's"), "{e}");
}

#[test]
fn a_row_file_of_another_sweep_or_a_broken_row_is_refused_with_its_line() {
    let s = sweep(SPEC).unwrap();
    let rows = vec![s.run(0).unwrap()];
    let csv = table::to_csv(&s, &rows);
    assert_eq!(table::from_csv(&s, "f.csv", &csv).unwrap(), rows);
    let fewer = sweep(&SPEC.replace("mass_kg = { scale = [0.85, 1.15] }\n", "")).unwrap();
    let e = table::from_csv(&fewer, "f.csv", &csv).unwrap_err().to_string();
    assert!(e.contains("f.csv:1") && e.contains("header"), "{e}");
    let broken = csv.replace(",aco,", ",acx,");
    let e = table::from_csv(&s, "f.csv", &broken).unwrap_err().to_string();
    assert!(e.contains("f.csv:2") && e.contains("acx"), "{e}");
}

#[test]
fn the_summary_ranks_runs_that_never_recovered_last_and_counts_the_bound() {
    assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 50.0), 2.0);
    assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 99.0), 4.0);
    assert_eq!(percentile(&[5.0], 1.0), 5.0);
    assert!(percentile(&[], 50.0).is_nan());
    let s = sweep(SPEC).unwrap();
    let columns = s.metric_columns();
    let peak = columns.iter().position(|c| c == "gust_peak_m").unwrap();
    let onset = columns.iter().position(|c| c == "gust_recovery_onset_s").unwrap();
    let mut rows = Vec::new();
    for (i, (p, rec)) in [(0.2, Some(1.0)), (0.4, None), (0.6, Some(2.0)), (0.8, Some(3.0))].into_iter().enumerate() {
        let mut metrics = vec![Some(0.0); columns.len()];
        metrics[peak] = Some(p);
        metrics[onset] = rec;
        rows.push(Row {
            run: i as u64 * 3,
            case: i as u64,
            controller: ControllerKind::ACO,
            seed: 1,
            params: vec![],
            metrics,
        });
    }
    let summary = table::summarize(&s, &rows);
    let aco = &summary.controllers["aco"];
    let p = aco.iter().find(|m| m.metric == "gust_peak_m").unwrap();
    assert_eq!((p.within, p.p50, p.max), (Some(0.5), 0.4, 0.8));
    let r = aco.iter().find(|m| m.metric == "gust_recovery_onset_s").unwrap();
    assert_eq!((r.missing, r.p50, r.max), (1, 2.0, f64::INFINITY));
    assert!(summary.table().contains("never"), "{}", summary.table());
    assert!(summary.table().contains("50.0 % <= 0.500"), "{}", summary.table());
}

#[test]
fn each_row_says_whether_its_airframe_can_hover_at_all() {
    // The paper's lift curve spans 11.28-14.48 N a rotor: the mismatch plant (lift factor 0.99) cannot
    // hover above about 5.84 kg, nor descend below about 4.55 kg.
    let s = sweep(
        "name = \"t\"\nscenario = \"x\"\ncontrollers = [\"aco\"]\nseed = 1\n[vary]\nmass_kg = { values = [4.4, 5.4, 6.2] }\n",
    )
    .unwrap();
    let columns = s.metric_columns();
    let (max, min) = (0, 1);
    assert_eq!(&columns[..2], ["max_thrust_to_weight", "min_thrust_to_weight"]);
    let rows: Vec<Row> = (0..3).map(|r| s.run(r).unwrap()).collect();
    let tw = |r: &Row, i: usize| r.metrics[i].unwrap();
    assert!(tw(&rows[0], min) > 1.0, "4.4 kg cannot descend: {:?}", rows[0].metrics);
    assert!(tw(&rows[1], max) > 1.0 && tw(&rows[1], min) < 1.0, "5.4 kg hovers: {:?}", rows[1].metrics);
    assert!(tw(&rows[2], max) < 1.0, "6.2 kg cannot hover: {:?}", rows[2].metrics);
    assert!((tw(&rows[1], max) - 4.0 * 14.477 * 0.99 / (5.4 * 9.81)).abs() < 2e-3, "{:?}", rows[1].metrics);
}

/// rotor-degradation cut to 6 s with its fault at 5 s.
fn short_degradation() -> Scenario {
    let mut s = Scenario::load("rotor-degradation").unwrap();
    s.duration_s = 6.0;
    s
}

const ROTOR_SPEC: &str = r#"
name = "rotor"
scenario = "unused"
samples = 1
seed = 3
[vary]
mot1_eff = { values = [0.95, 0.6] }
[bounds]
fault_peak_position_error_m = 0.3
"#;

#[test]
fn given_mot1_eff_values_then_each_case_sets_the_events_fault_and_a_rerun_is_bit_identical() {
    let s = Sweep::from_toml(ROTOR_SPEC, short_degradation()).unwrap();
    assert_eq!((s.cases(), s.runs(), s.param_names()), (2, 6, vec!["mot1_eff"]));
    let case = s.case(1).unwrap();
    assert_eq!(case.scenario.events[0].set["SIM_MOT1_EFF"], 0.6);
    assert_eq!(case.scenario.airframe.rotor_health, None, "the fault stays an event, not a start value");
    let columns = s.metric_columns();
    let peak = columns.iter().position(|c| c == "fault_peak_position_error_m").unwrap();
    let lost = columns.iter().position(|c| c == "fault_lost_control").unwrap();
    let rows: Vec<Row> = (0..s.runs()).map(|r| s.run(r).unwrap()).collect();
    // 5 % lost is held by every controller; 40 % lost is beyond the airframe: no controller holds it.
    for row in &rows {
        let held = row.params[0] == 0.95;
        assert_eq!(row.metrics[lost], Some(if held { 0.0 } else { 1.0 }), "{row:?}");
        assert_eq!(row.metrics[peak].unwrap() < 0.3, held, "{row:?}");
    }
    let again: Vec<Row> = (0..s.runs()).map(|r| s.run(r).unwrap()).collect();
    assert_eq!(table::to_csv(&s, &rows), table::to_csv(&s, &again));
    // Without an event that sets it, mot1_eff is the rotor's health from the start.
    let mut from_start = short_degradation();
    from_start.events.clear();
    let s = Sweep::from_toml(ROTOR_SPEC, from_start).unwrap();
    assert_eq!(s.case(0).unwrap().scenario.airframe.rotor_health, Some([0.95, 1.0, 1.0, 1.0]));
    // Out of a rotor's range: refused when the sweep loads.
    let e = Sweep::from_toml(&ROTOR_SPEC.replace("0.6]", "1.2]"), short_degradation()).unwrap_err().to_string();
    assert!(e.contains("SIM_MOT1_EFF = 1.2"), "{e}");
}

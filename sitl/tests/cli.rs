//! The `sitl` command line, run as a user runs it: clear errors for bad input, and the metrics JSON and
//! files that `sitl scenario` promises.

use std::process::Command;

fn sitl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sitl")).args(args).env_remove("RUST_BACKTRACE").output().expect("sitl runs")
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("sitl-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

#[test]
fn scenario_prints_one_metrics_object_per_run_and_writes_trace_and_plot() {
    let out = temp_dir("scenario");
    let o = sitl(&["scenario", "paper-attitude", "--controller", "aco,pid", "--json", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> =
        String::from_utf8(o.stdout).unwrap().lines().map(|l| serde_json::from_str(l).expect("JSON line")).collect();
    assert_eq!(lines.len(), 2);
    for (line, ctrl) in lines.iter().zip(["aco", "pid"]) {
        assert_eq!(line["scenario"], "paper-attitude");
        assert_eq!(line["controller"], ctrl);
        assert_eq!(line["rate_hz"], 500);
        assert_eq!(line["non_finite"], false);
        assert!(line["segments"].as_array().is_some_and(|s| s.len() == 9), "{line}");
        assert!(line["realtime_factor"].as_f64().is_some_and(|x| x > 1.0));
    }
    let dir = out.join("paper-attitude");
    let csv = std::fs::read_to_string(dir.join("aco_nominal_seed1_500hz.csv")).expect("trace written");
    assert!(csv.starts_with("t,pN,pE,pD,roll,pitch,yaw,pwm1,pwm2,pwm3,pwm4,"));
    assert_eq!(csv.lines().count(), 1 + 800, "16 s at 50 Hz plus the header");
    let png = std::fs::read(dir.join("attitude_nominal_seed1_500hz.png")).expect("plot written");
    assert_eq!(&png[1..4], b"PNG");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn unknown_scenario_and_bad_options_fail_with_a_clear_message() {
    let o = sitl(&["scenario", "no-such-thing", "--no-plots"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("paper-attitude") && err.contains("figure8"), "{err}");

    let o = sitl(&[
        "scenario",
        "paper-attitude",
        "--rate-hz",
        "300",
        "--no-plots",
        "--out",
        temp_dir("rate").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("rate"), "{}", String::from_utf8_lossy(&o.stderr));

    let o = sitl(&["serve", "--plant", "nope"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("nominal, mismatch"));

    let dir = temp_dir("config");
    let bad = dir.join("plant.toml");
    std::fs::write(&bad, "[airframe]\nmass_kg = -1.0\n").unwrap();
    let o = sitl(&["serve", "--config", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("mass_kg"), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn run_and_serve_say_in_their_help_that_they_run_at_real_time_unless_told() {
    for command in ["run", "serve"] {
        let o = sitl(&[command, "--help"]);
        assert!(o.status.success());
        let help = String::from_utf8_lossy(&o.stdout);
        assert!(help.contains("--speed <X|max>") && help.contains("--lockstep"), "{help}");
        assert!(help.contains("default 1: real time"), "{help}");
    }
}

#[test]
fn a_bad_speed_is_refused_before_anything_starts() {
    for (command, bad) in [("run", "0"), ("run", "-1"), ("run", "nan"), ("run", "fast"), ("serve", "inf")] {
        let o = sitl(&[command, "-i", "97", "--speed", bad]);
        assert_eq!(o.status.code(), Some(2), "{command} --speed {bad}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("--speed") && err.contains(&format!("'{bad}'")), "{command} --speed {bad}: {err}");
        assert!(!err.contains("sitl:"), "{command} --speed {bad} started something: {err}");
    }
    let o = sitl(&["run", "--lockstep", "--speed", "4"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--lockstep") && err.contains("--speed"), "{err}");
    // A scenario runs as fast as possible by itself: a pacing is refused, not silently ignored.
    for pacing in [&["--speed", "1"][..], &["--lockstep"][..]] {
        let o = sitl(&[&["run", "--scenario", "gust-hover"][..], pacing].concat());
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("--scenario") && err.contains(pacing[0]), "{err}");
        assert!(!err.contains("flying scenario"), "{err}");
    }
}

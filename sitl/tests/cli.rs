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
    // Every file written is named on standard error.
    let err = String::from_utf8_lossy(&o.stderr);
    for file in ["aco_nominal_seed1_500hz.csv", "pid_nominal_seed1_500hz.csv", "attitude_nominal_seed1_500hz.png"] {
        assert!(err.contains(&format!("sitl: wrote {}", dir.join(file).display())), "{file}: {err}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// A short hover with every `[airframe]` field set: its label has eleven overrides, far past a file name.
const EVERY_AIRFRAME_FIELD: &str = r#"
name = "every-airframe-field"
duration_s = 3.0
plant = "mismatch"
metrics = ["steps"]
[initial]
pos_ned_m = [0.0, 0.0, -1.5]
[reference]
kind = "position"
steps = [{ t_s = 0.0, pos_ned_m = [0.2, 0.0, -1.5] }]
[airframe]
mass_kg = 5.25
inertia_kgm2 = [0.081, 0.082, 0.121]
arm_m = 0.241
yaw_moment_m = 0.0271
motor_tau_s = 0.041
thrust_scale = 1.01
rotor_health = [1.0, 0.99, 1.0, 0.98]
disturbance_torque_frd_nm = [0.001, -0.002, 0.0005]
drag_cda_m2 = 0.011
air_density_kgpm3 = 1.2
gravity_mps2 = 9.81
"#;

#[test]
fn a_scenario_with_every_airframe_field_set_runs_and_writes_files_named_within_64_bytes_of_label() {
    let out = temp_dir("every-airframe");
    let file = out.join("every.toml");
    std::fs::write(&file, EVERY_AIRFRAME_FIELD).unwrap();
    let o =
        sitl(&["scenario", file.to_str().unwrap(), "--controller", "aco", "--json", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON line");
    // The whole label stays in the JSON.
    let label = line["plant"].as_str().unwrap();
    assert!(
        label.starts_with("mismatch+mass_kg=5.25+inertia_kgm2=") && label.ends_with("+gravity_mps2=9.81"),
        "{label}"
    );
    assert_eq!(line["airframe_overrides"].as_object().map(serde_json::Map::len), Some(11), "{line}");
    let dir = out.join("every-airframe-field");
    let names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    let short = sitl::scenario::file_label(label);
    assert!(short.starts_with("mismatch+") && short.len() <= sitl::scenario::FILE_LABEL_MAX_LEN, "{short}");
    for expected in [format!("aco_{short}_seed1_500hz.csv"), format!("translation_{short}_seed1_500hz.png")] {
        assert!(names.contains(&expected), "{expected} not in {names:?}");
    }
    assert!(names.iter().all(|n| n.len() < 100 && !n.ends_with(".tmp")), "{names:?}");
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

/// `sitl` with the environment a developer might have (`RUST_BACKTRACE=1`): user errors still print one
/// line, with no backtrace.
fn sitl_with_backtrace(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sitl")).args(args).env("RUST_BACKTRACE", "1").output().expect("sitl runs")
}

/// The `autopilot` binary next to `sitl`, as `sitl run` finds it.
fn autopilot_binary() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_BIN_EXE_sitl")).with_file_name("autopilot")
}

/// Standard error's lines, and that they hold no ANSI escape (standard error is a pipe here).
fn stderr_lines(o: &std::process::Output) -> Vec<String> {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains('\u{1b}'), "colour codes in redirected output: {err:?}");
    err.lines().map(str::to_owned).collect()
}

#[test]
fn a_busy_instance_is_one_line_naming_the_instance_the_port_and_the_next_free_one() {
    // GIVEN instance 61's plant port held by another process's socket.
    let held = std::net::UdpSocket::bind(("127.0.0.1", 4560 + 61)).expect("port free to hold");
    // WHEN `sitl run -i 61` starts THEN it stops at once with one line, and starts nothing.
    let o = sitl_with_backtrace(&["run", "-i", "61", "--speed", "max", "--duration", "1", "--state-dir", "off"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr_lines(&o),
        ["sitl: error: instance 61 is in use: udp 127.0.0.1:4621 (the plant) is held by another process; try -i 62"]
    );
    // The autopilot alone says the same about its own port.
    let ap = std::net::UdpSocket::bind(("0.0.0.0", 18570 + 63)).expect("port free to hold");
    let o = Command::new(autopilot_binary())
        .args(["-i", "63", "--state-dir", "off"])
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("autopilot runs");
    assert_eq!(o.status.code(), Some(1));
    let lines = stderr_lines(&o);
    let last = lines.last().expect("a line");
    assert!(
        last.starts_with(
            "autopilot: error: instance 63 is in use (another autopilot or SITL holds its port); try -i 64:"
        ) && last.contains("18633"),
        "{lines:?}"
    );
    assert!(!lines.iter().any(|l| l.contains("backtrace") || l.contains("Stack")), "{lines:?}");
    drop((held, ap));
}

#[test]
fn every_run_argument_is_checked_before_anything_starts() {
    // A controller that does not exist: refused by the argument parser, naming the flag and the choices.
    let o = sitl(&["run", "-i", "64", "--controller", "nope"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--controller") && err.contains("nope"), "{err}");
    assert!(!err.contains("sitl: instance"), "nothing started: {err}");
    let o = sitl(&["run", "-i", "64", "--estimator", "magic"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("[possible values: fused, truth]"));

    // An autopilot configuration with an unknown key: one line naming the file and the key, before the
    // plant or the autopilot start.
    let dir = temp_dir("apconfig");
    let bad = dir.join("ap.toml");
    std::fs::write(&bad, "[vehicle]\nbogus_field = 3\n").unwrap();
    let o = sitl_with_backtrace(&["run", "-i", "64", "--autopilot-config", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let lines = stderr_lines(&o);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].starts_with("sitl: error: ") && lines[0].contains("ap.toml"), "{lines:?}");
    assert!(lines[0].contains("bogus_field"), "{lines:?}");

    // A TOML syntax error in a plant configuration: said once, on one line.
    let broken = dir.join("plant.toml");
    std::fs::write(&broken, "[airframe\nmass_kg = 1.0\n").unwrap();
    let o = sitl_with_backtrace(&["serve", "-i", "64", "--config", broken.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let lines = stderr_lines(&o);
    assert_eq!(lines.len(), 1, "{lines:?}");
    let line = &lines[0];
    assert!(line.starts_with("sitl: error: ") && line.contains("plant.toml"), "{line}");
    assert_eq!(line.matches("TOML parse error at line 1, column 10").count(), 1, "said once: {line}");
    assert!(line.contains("unclosed table") && !line.contains('|'), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_says_what_it_restored_and_wipe_starts_clean() {
    // GIVEN a state directory with a changed parameter, as an earlier run leaves it.
    let dir = temp_dir("wipe");
    std::fs::write(dir.join("params.txt"), "MPC_XY_CRUISE\t2\n").unwrap();
    let state = dir.to_str().unwrap();
    // WHEN a run starts on it THEN the start-up says what was restored.
    let o = sitl(&["run", "-i", "65", "--speed", "max", "--duration", "0.5", "--state-dir", state]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = stderr_lines(&o).join("\n");
    assert!(
        err.contains(&format!("state restored from {state}: 1 parameter differs from default (MPC_XY_CRUISE)")),
        "{err}"
    );
    // WHEN the next run has --wipe THEN the parameter is gone and the start says it is fresh.
    let o = sitl(&["run", "-i", "65", "--speed", "max", "--duration", "0.5", "--state-dir", state, "--wipe"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = stderr_lines(&o).join("\n");
    assert!(err.contains(&format!("wiped {state}: removed params.txt")), "{err}");
    assert!(err.contains(&format!("no state to restore in {state}")), "{err}");
    assert!(
        !dir.join("params.txt").exists()
            || !std::fs::read_to_string(dir.join("params.txt")).unwrap().contains("MPC_XY_CRUISE\t2\n")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A tiny tuning: two gains, 6 s scenarios, 8 evaluations.
const TUNE_SPEC: &str = r#"
name = "tiny"
controller = "pid"
budget = 8
seed = 3
[optimizer]
population = 4
[[gain]]
name = "pid.kp_pos_per_s"
bounds = [0.3, 2.0]
scale = "log"
[[gain]]
name = "pid.k_att_per_s"
axes = [0, 1]
bounds = [1.0, 8.0]
[[train]]
scenario = "hover.toml"
cost = { gust_peak_m = 1.0 }
[[heldout]]
scenario = "hover.toml"
seeds = [5]
limits = { gust_recovery_release_s = 3.0 }
"#;

const TUNE_HOVER: &str = r#"
name = "hover"
duration_s = 6.0
plant = "mismatch"
metrics = ["gust"]
[initial]
pos_ned_m = [0.0, 0.0, -1.5]
[reference]
kind = "position"
steps = [{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.5] }]
[wind.gust]
amplitude_mps = 3.0
onset_s = 1.0
rise_s = 0.5
release_s = 2.5
fall_s = 0.5
"#;

#[test]
fn tune_writes_the_same_files_on_one_thread_and_two_and_evaluate_flies_them_held_out() {
    let dir = temp_dir("tune");
    std::fs::write(dir.join("tiny.toml"), TUNE_SPEC).unwrap();
    std::fs::write(dir.join("hover.toml"), TUNE_HOVER).unwrap();
    let spec = dir.join("tiny.toml");
    let mut outputs = Vec::new();
    for jobs in ["1", "2"] {
        let out = dir.join(format!("out{jobs}"));
        let o = sitl(&["tune", spec.to_str().unwrap(), "--jobs", jobs, "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(stdout.contains("tiny (pid): 8 evaluations") && stdout.contains("held out:"), "{stdout}");
        assert!(stdout.contains("pid (start) [pid]") && stdout.contains("pid (tuned) [pid]"), "{stdout}");
        let files: Vec<Vec<u8>> = ["trace.csv", "controller.toml", "params.txt", "result.json", "heldout.json"]
            .iter()
            .map(|f| std::fs::read(out.join(f)).unwrap_or_else(|e| panic!("{f}: {e}")))
            .collect();
        outputs.push(files);
    }
    assert!(outputs[0] == outputs[1], "one thread and two wrote different files");
    // The tuned gains fly held out from the file; `pid` is the defaults.
    let gains = dir.join("out1").join("controller.toml");
    let out = dir.join("evaluate");
    let o = sitl(&[
        "tune",
        spec.to_str().unwrap(),
        "--evaluate",
        gains.to_str().unwrap(),
        "pid",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(report.as_array().map(Vec::len), Some(2), "{report}");
    assert_eq!(report[1]["gains"], "pid (defaults)");
    assert!(report[0]["sets"][0]["mean"]["gust_peak_m"].as_f64().is_some(), "{report}");
    assert!(report[0]["sets"][0]["worst"]["gust_peak_m"].as_f64().is_some(), "{report}");
    assert!(out.join("heldout.csv").exists());
    // A bad spec fails before any run, naming the key.
    std::fs::write(&spec, TUNE_SPEC.replace("pid.kp_pos_per_s", "pid.kp_position")).unwrap();
    let o = sitl(&["tune", spec.to_str().unwrap(), "--out", dir.join("bad").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("pid.kp_position"), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!dir.join("bad").exists(), "nothing written");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `sitl serve` stopped with Ctrl-C (SIGINT) closes with its radio line, as `sitl run` does.
#[test]
fn serve_stopped_by_ctrl_c_ends_with_the_radio_summary_line() {
    use std::io::{BufRead, BufReader, Read};
    let mut child = Command::new(env!("CARGO_BIN_EXE_sitl"))
        .args(["serve", "-i", "61", "--rc-in-port", "5671"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("sitl serve starts");
    let mut stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    while !line.contains("waiting for an autopilot") {
        line.clear();
        assert!(stderr.read_line(&mut line).expect("reads") > 0, "serve ended before listening");
    }
    let interrupted = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
    assert!(interrupted.success());
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).expect("reads to the end");
    assert!(child.wait().expect("serve exits").success(), "{rest}");
    assert!(rest.contains("sitl: radio: 0 RC_CHANNELS sent; RC input: 0 datagrams taken, 0 dropped"), "{rest}");
}

/// Every tool takes any registered controller name; an unknown one is one line listing the registered
/// names, and `sitl controllers` lists them with their table and whether they fly the rate level.
#[test]
fn an_unknown_controller_is_one_line_listing_the_registered_names() {
    let listed = sitl(&["controllers"]);
    assert!(listed.status.success());
    let text = String::from_utf8(listed.stdout).unwrap();
    for line in ["aco       aco       yes", "ca|mrac   mrac      no", "pid       pid       yes"] {
        assert!(text.contains(line), "{line} in\n{text}");
    }
    let names: Vec<&str> =
        text.lines().skip(1).filter_map(|l| l.split_whitespace().next()?.split('|').next()).collect();
    let expected = format!("unknown controller `lqr` (registered: {})", names.join(", "));
    for args in [
        &["scenario", "gust-hover", "--controller", "aco,lqr"][..],
        &["run", "--controller", "lqr"][..],
        &["bench", "--controller", "lqr"][..],
    ] {
        let o = sitl(args);
        assert!(!o.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        let first = err.lines().next().unwrap_or("");
        assert!(first.contains(&expected), "{args:?}: {err}");
    }
    let dir = temp_dir("unknown-controller");
    let spec = dir.join("sweep.toml");
    std::fs::write(&spec, "name = \"s\"\nscenario = \"gust-hover\"\ncontrollers = [\"lqr\"]\nseed = 1\n").unwrap();
    let o = sitl(&["sweep", spec.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains(&expected), "{err}");
}

//! `sitl line` run as a test harness runs it: bad arguments are one clear line and create nothing; good
//! ones give two symlinked pty ends and a ready line, carry bytes from one end to the other, and on SIGTERM
//! remove the links and leave the final counters in the stats file. Unix only (ptys).
#![cfg(unix)]

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Longest any wait lasts: only a failure waits this long.
const PATIENCE: Duration = Duration::from_secs(60);

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sitl-line-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn sitl_line(dir: &Path, extra: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_sitl"));
    command
        .arg("line")
        .arg("--link-a")
        .arg(dir.join("a"))
        .arg("--link-b")
        .arg(dir.join("b"))
        .args(extra)
        .env_remove("RUST_BACKTRACE");
    command
}

/// Kills the child if the test fails half-way.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn sitl_line_with_a_bad_argument_fails_with_one_line_naming_it_and_creates_nothing() {
    let dir = temp_dir("bad");
    let cases: [(&[&str], &str); 7] = [
        (&["--baud", "0"], "--baud must be at least 1 bit per second, got 0"),
        (&["--loss", "60"], "--loss must be a percentage in 0..=50 (1 = 1 %), got 60"),
        (&["--loss", "NaN"], "--loss must be a percentage in 0..=50"),
        (&["--burst", "0"], "--burst must be at least 1 byte, got 0"),
        (&["--corrupt=-1"], "--corrupt must be a percentage in 0..=50 (1 = 1 %), got -1"),
        (&["--latency-ms", "20000"], "--latency-ms must be in 0..=10000, got 20000"),
        (&["--buffer", "0"], "--buffer must be in 1..="),
    ];
    for (args, message) in cases {
        let o = sitl_line(&dir, args).output().expect("sitl runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with(&format!("sitl: error: {message}")), "{args:?}: {err}");
        assert_eq!(std::fs::read_dir(&dir).expect("dir").count(), 0, "{args:?} created something");
    }
    // A file where a link would go is never replaced.
    std::fs::write(dir.join("b"), "keep").expect("a file");
    let o = sitl_line(&dir, &[]).output().expect("sitl runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("--link-b") && err.contains("exists and is not a symlink"), "{err}");
    assert_eq!(std::fs::read_to_string(dir.join("b")).expect("still there"), "keep");
    assert!(std::fs::symlink_metadata(dir.join("a")).is_err(), "no link A");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sitl_line_links_two_ends_carries_bytes_and_on_sigterm_removes_the_links_and_writes_the_stats() {
    let dir = temp_dir("good");
    let stats_file = dir.join("stats.json");
    let mut child = sitl_line(&dir, &["--baud", "57600", "--stats", stats_file.to_str().expect("UTF-8")])
        .stderr(Stdio::piped())
        .spawn()
        .expect("sitl line starts");
    let mut stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = Running(child);
    let deadline = Instant::now() + PATIENCE;
    while !(dir.join("a").exists() && dir.join("b").exists()) {
        assert!(Instant::now() < deadline, "no links");
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut ready = String::new();
    stderr.read_line(&mut ready).expect("the ready line");
    let a_device = std::fs::read_link(dir.join("a")).expect("link A");
    let b_device = std::fs::read_link(dir.join("b")).expect("link B");
    assert_eq!(
        ready.trim_end(),
        format!(
            "sitl line: A {} ({}) <-> B {} ({}) at 57600 baud (5760 B/s), loss 0 % in bursts of 1 B, corruption \
             0 %, latency 0 ms",
            dir.join("a").display(),
            a_device.display(),
            dir.join("b").display(),
            b_device.display()
        )
    );

    let open = |end: &str| {
        serialport::new(dir.join(end).to_str().expect("UTF-8"), 57_600)
            .timeout(Duration::from_millis(10))
            .open()
            .expect("open an end")
    };
    let mut a = open("a");
    let mut b = open("b");
    a.write_all(b"over the line").expect("write A");
    let mut got = Vec::new();
    let mut buf = [0_u8; 64];
    while got.len() < 13 && Instant::now() < deadline {
        match b.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("reading B: {e}"),
        }
    }
    assert_eq!(got, b"over the line");
    drop((a, b));

    let terminated = Command::new("kill").args(["-TERM", &line.0.id().to_string()]).status().expect("kill runs");
    assert!(terminated.success());
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).expect("reads to the end");
    assert!(line.0.wait().expect("sitl line exits").success(), "{rest}");
    assert!(rest.contains("sitl line: A to B: 13 B in, 13 B out, 0 B lost"), "{rest}");
    assert!(rest.contains("sitl line: B to A: 0 B in, 0 B out, 0 B lost"), "{rest}");
    assert!(std::fs::symlink_metadata(dir.join("a")).is_err(), "link A removed");
    assert!(std::fs::symlink_metadata(dir.join("b")).is_err(), "link B removed");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats_file).expect("the stats file")).expect("JSON");
    assert_eq!(stats["a_to_b"]["bytes_in"], 13, "{stats}");
    assert_eq!(stats["a_to_b"]["bytes_out"], 13, "{stats}");
    assert_eq!(stats["a_to_b"]["lost"], 0, "{stats}");
    assert_eq!(stats["b_to_a"]["bytes_in"], 0, "{stats}");
    assert!(stats["elapsed_s"].as_f64().is_some_and(|s| s > 0.0), "{stats}");
    assert!(!dir.join("stats.json.tmp").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

//! End to end: `sitl run -i N` (plant server + the `autopilot` binary, lockstep, as fast as possible),
//! flown by this test as a ground station over UDP exactly as QGroundControl would be: listen on
//! 14550+N, command the autopilot at 18570+N. Waits on vehicle time (`time_boot_ms` of the telemetry),
//! never on wall sleeps; a wall-clock deadline fails the test instead of hanging, and a guard kills the
//! whole process group (sitl and its autopilot child) however the test ends.

use std::net::UdpSocket;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use autopilot::core::hil::{FrameDecoder, encode_frame_v2};
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::command_long;
use autopilot::core::mavlink::common::{
    MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult, MavSysStatusSensor,
};

const WALL_LIMIT: Duration = Duration::from_secs(120);
const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

/// Kills the process group of `sitl run` (the autopilot child included) on drop.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let pgid = self.0.id();
        // `--` so the negative process-group id is not read as a signal or option.
        let _ = Command::new("kill").args(["-s", "KILL", "--", &format!("-{pgid}")]).status();
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[derive(Default)]
struct Seen {
    time_ms: u32,
    heartbeats: u32,
    base_mode: Option<MavModeFlag>,
    landed_state: Option<MavLandedState>,
    converged: bool,
    pos_ned_m: Option<[f32; 3]>,
    vel_ned_mps: [f32; 3],
    acks: Vec<(MavCmd, MavResult)>,
}

struct Gcs {
    socket: UdpSocket,
    autopilot: String,
    sysid: u8,
    decoder: FrameDecoder,
    seen: Seen,
    wall_start: Instant,
    first_time_ms: Option<u32>,
}

impl Gcs {
    /// Read whatever arrives for up to 100 ms of wall time and update what we know.
    fn pump(&mut self) {
        assert!(self.wall_start.elapsed() < WALL_LIMIT, "e2e test exceeded its {WALL_LIMIT:?} wall-clock limit");
        let mut buf = [0u8; 4096];
        let Ok(len) = self.socket.recv(&mut buf) else { return };
        for frame in self.decoder.decode_datagram(&buf[..len]) {
            if frame.header.system_id != u32::from(self.sysid) {
                continue;
            }
            let s = &mut self.seen;
            let mut t = None;
            match frame.message {
                MavMessage::HEARTBEAT(h) => {
                    s.heartbeats += 1;
                    s.base_mode = Some(h.base_mode);
                }
                MavMessage::EXTENDED_SYS_STATE(e) => s.landed_state = Some(e.landed_state),
                MavMessage::SYS_STATUS(st) => {
                    s.converged =
                        st.onboard_control_sensors_health.contains(MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK);
                }
                MavMessage::LOCAL_POSITION_NED(p) => {
                    s.pos_ned_m = Some([p.x, p.y, p.z]);
                    s.vel_ned_mps = [p.vx, p.vy, p.vz];
                    t = Some(p.time_boot_ms);
                }
                MavMessage::ATTITUDE(a) => t = Some(a.time_boot_ms),
                MavMessage::SYSTEM_TIME(st) => t = Some(st.time_boot_ms),
                MavMessage::COMMAND_ACK(a) => s.acks.push((a.command, a.result)),
                _ => {}
            }
            if let Some(t) = t {
                s.time_ms = s.time_ms.max(t);
                self.first_time_ms.get_or_insert(t);
            }
        }
    }

    fn now_s(&self) -> f64 {
        f64::from(self.seen.time_ms) * 1e-3
    }

    /// Pump until `cond`, at most `timeout_s` of vehicle time; returns the vehicle time it took (s).
    fn wait_until(&mut self, timeout_s: f64, what: &str, cond: impl Fn(&Seen) -> bool) -> f64 {
        let start = self.now_s();
        while !cond(&self.seen) {
            assert!(self.now_s() - start < timeout_s, "timed out ({timeout_s} s vehicle time) waiting for {what}");
            self.pump();
        }
        self.now_s() - start
    }

    fn run_s(&mut self, seconds: f64, mut each: impl FnMut(&Seen)) {
        let end = self.now_s() + seconds;
        while self.now_s() < end {
            self.pump();
            each(&self.seen);
        }
    }

    fn command(&mut self, command: MavCmd, params: [f32; 7]) -> MavResult {
        let msg = command_long(self.sysid, 1, command, params);
        self.seen.acks.clear();
        self.socket.send_to(&encode_frame_v2(GCS, &msg), &self.autopilot).expect("send command");
        self.wait_until(5.0, &format!("ACK of {command:?}"), |s| s.acks.iter().any(|a| a.0 == command));
        self.seen.acks.iter().find(|a| a.0 == command).map(|a| a.1).expect("ack")
    }
}

fn armed(s: &Seen) -> bool {
    s.base_mode.is_some_and(|m| m.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED))
}

#[test]
fn sitl_run_flies_takeoff_hold_land_over_udp() {
    fly(&[]);
}

#[test]
fn sitl_run_with_the_truth_fed_estimator_flies_the_same_flight() {
    fly(&["--estimator", "truth"]);
}

fn fly(extra_args: &[&str]) {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).expect("clock").subsec_nanos();
    // A random instance in 20..=60, retried if its ground-station port is taken (the other test, another run).
    let mut attempt = 0;
    let (n, socket) = loop {
        let n = 20 + u16::try_from((nanos.wrapping_add(attempt * 7919) ^ std::process::id()) % 41).expect("small");
        match UdpSocket::bind(("127.0.0.1", 14550 + n)) {
            Ok(socket) => break (n, socket),
            Err(e) => assert!(attempt < 20, "no free ground-station port 14550+N: {e}"),
        }
        attempt += 1;
    };
    socket.set_read_timeout(Some(Duration::from_millis(100))).expect("timeout");
    let sitl = env!("CARGO_BIN_EXE_sitl");
    let autopilot_bin = std::path::Path::new(sitl).with_file_name("autopilot");
    if !autopilot_bin.exists() {
        // `cargo test -p sitl` alone does not build the other crate's binary; build it (same profile).
        let profile_release = std::path::Path::new(sitl).parent().is_some_and(|d| d.ends_with("release"));
        let mut build = Command::new(env!("CARGO"));
        build.args(["build", "-p", "autopilot", "--bin", "autopilot"]);
        if profile_release {
            build.arg("--release");
        }
        assert!(build.status().expect("cargo build").success(), "building the autopilot binary failed");
    }
    let child = Command::new(sitl)
        .args(["run", "-i", &n.to_string()])
        .args(extra_args)
        .process_group(0)
        .spawn()
        .expect("spawn sitl");
    let _guard = Guard(child);
    let wall_start = Instant::now();
    let mut gcs = Gcs {
        socket,
        autopilot: format!("127.0.0.1:{}", 18570 + n),
        sysid: u8::try_from(n + 1).expect("sysid"),
        decoder: FrameDecoder::new(),
        seen: Seen::default(),
        wall_start,
        first_time_ms: None,
    };

    // GIVEN the vehicle talking (HEARTBEATs) and its estimator converged (SYS_STATUS PREARM_CHECK healthy).
    while gcs.seen.heartbeats < 2 {
        gcs.pump();
    }
    let converge_s = gcs.wait_until(30.0, "estimator convergence", |s| s.converged && s.pos_ned_m.is_some());
    gcs.run_s(0.5, |_| {});
    let ground_d_m = gcs.seen.pos_ned_m.expect("position")[2];

    // WHEN the ground station sends NAV_TAKEOFF 1.5 m and arms.
    let nan = f32::NAN;
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    gcs.wait_until(2.0, "HEARTBEAT armed", armed);

    // THEN it climbs to 1.5 m above the ground and settles.
    let target_d_m = ground_d_m - 1.5;
    let climb_s = gcs.wait_until(15.0, "climb to 1.5 m", |s| {
        s.pos_ned_m.is_some_and(|p| (p[2] - target_d_m).abs() < 0.05) && s.vel_ned_mps[2].abs() < 0.1
    });
    gcs.run_s(3.0, |_| {});
    let p = gcs.seen.pos_ned_m.expect("position");
    let hover = [p[0], p[1], target_d_m];
    // AND holds within 0.10 m of the hover point (by its own LOCAL_POSITION_NED) for 20 s.
    let mut hover_err_m = 0.0_f32;
    gcs.run_s(20.0, |s| {
        if let Some(p) = s.pos_ned_m {
            let e = (0..3).map(|i| (p[i] - hover[i]).powi(2)).sum::<f32>().sqrt();
            hover_err_m = hover_err_m.max(e);
        }
    });
    assert!(armed(&gcs.seen), "still armed in the hover");

    // WHEN told to land, THEN it lands and disarms by itself.
    assert_eq!(gcs.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    let land_s = gcs.wait_until(25.0, "auto-disarm after landing", |s| !armed(s));
    gcs.wait_until(3.0, "EXTENDED_SYS_STATE ON_GROUND", |s| {
        s.landed_state == Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND)
    });

    let wall_s = wall_start.elapsed().as_secs_f64();
    let sim_s = f64::from(gcs.seen.time_ms - gcs.first_time_ms.unwrap_or(0)) * 1e-3;
    println!(
        "e2e instance {n} {extra_args:?}: converge {converge_s:.1} s, climb {climb_s:.1} s, hover error max {hover_err_m:.3} m, \
         land {land_s:.1} s; {sim_s:.1} sim s in {wall_s:.1} s wall = {:.1}x real time ({:.0} steps/s at 500 Hz)",
        sim_s / wall_s,
        sim_s * 500.0 / wall_s
    );
    assert!(hover_err_m <= 0.10, "hover error {hover_err_m:.3} m > 0.10 m");
}

//! What the two-process tests share: a ground station over UDP on the instance's API port (`Gcs`), a
//! client of the plant's SIM_ port collecting its truth (`TruthLink`), a free instance, the binaries, and
//! a guard that kills a process group. Waits are on vehicle time; a wall-clock limit stops a hung run.
#![allow(dead_code)]

use std::net::UdpSocket;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use autopilot::core::estimator::GeoOrigin;
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::command_long;
use autopilot::core::mavlink::common::{
    MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult, MavSysStatusSensor,
};
use autopilot::core::plant_link::{FrameDecoder, encode_frame_v2};
use autopilot::runtime::ports::InstancePorts;
use nalgebra::Vector3;

pub const WALL_LIMIT: Duration = Duration::from_secs(120);

pub const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

/// Kills the process group of `sitl run` (the autopilot child included) on drop.
pub struct Guard(pub Child);

impl Drop for Guard {
    fn drop(&mut self) {
        if matches!(self.0.try_wait(), Ok(Some(_))) {
            return;
        }
        let pgid = self.0.id();
        // `--` so the negative process-group id is not read as a signal or option.
        let _ = Command::new("kill").args(["-s", "KILL", "--", &format!("-{pgid}")]).status();
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[derive(Default)]
pub struct Seen {
    pub time_ms: u32,
    pub heartbeats: u32,
    pub base_mode: Option<MavModeFlag>,
    pub landed_state: Option<MavLandedState>,
    pub converged: bool,
    pub errors_comm: u16,
    pub pos_ned_m: Option<[f32; 3]>,
    pub vel_ned_mps: [f32; 3],
    pub acks: Vec<(MavCmd, MavResult)>,
    /// Whether the vehicle streams RC_CHANNELS (it has heard a radio).
    pub rc: bool,
}

/// A client of the plant's SIM_ port (UDP 19550+N): it says HEARTBEAT once per wall second, every 20 ms
/// until the truth flows (so the plant keeps it as a peer), and collects the plant's truth, SIM_STATE at 50 Hz of plant time, each after a
/// SYSTEM_TIME with its plant time (the vehicle's `time_boot_ms` clock). Positions are NED (m) about the
/// first sample's point, through the autopilot's geodetic map (the plant's GPS map).
pub struct TruthLink {
    pub socket: UdpSocket,
    pub plant: String,
    pub sysid: u8,
    pub decoder: FrameDecoder,
    pub last_hello: Option<Instant>,
    pub origin: Option<GeoOrigin>,
    pub time_ms: Option<u32>,
    /// (plant time ms, position NED m about `origin`) of each SIM_STATE, in arrival order.
    pub samples: Vec<(u32, Vector3<f64>)>,
}

impl TruthLink {
    pub fn new(n: u16) -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").expect("bind the truth client");
        socket.set_nonblocking(true).expect("non-blocking");
        let ports = InstancePorts::of(n).expect("in range");
        Self {
            socket,
            plant: format!("127.0.0.1:{}", ports.sim_params_udp),
            sysid: ports.system_id,
            decoder: FrameDecoder::new(),
            last_hello: None,
            origin: None,
            time_ms: None,
            samples: Vec::new(),
        }
    }

    /// Say HEARTBEAT if a wall second has passed (every 20 ms until the truth flows: the first may come
    /// before `sitl run` has bound the port), then read every datagram waiting.
    pub fn drain(&mut self) {
        let every = if self.samples.is_empty() { Duration::from_millis(20) } else { Duration::from_secs(1) };
        if self.last_hello.is_none_or(|at| at.elapsed() >= every) {
            let hello = encode_frame_v2(GCS, &autopilot::core::mavlink::gcs_heartbeat());
            self.socket.send_to(&hello, &self.plant).expect("hello to the SIM_ port");
            self.last_hello = Some(Instant::now());
        }
        let mut buf = [0u8; 4096];
        while let Ok(len) = self.socket.recv(&mut buf) {
            for frame in self.decoder.decode_datagram(&buf[..len]) {
                if frame.header.system_id != u32::from(self.sysid) || frame.header.component_id != 51 {
                    continue;
                }
                match frame.message {
                    MavMessage::SYSTEM_TIME(t) => self.time_ms = Some(t.time_boot_ms),
                    MavMessage::SIM_STATE(st) => {
                        let t_ms = self.time_ms.take().expect("SYSTEM_TIME before each SIM_STATE");
                        let (lat, lon) = (f64::from(st.lat_int) * 1e-7, f64::from(st.lon_int) * 1e-7);
                        let origin = *self.origin.get_or_insert(GeoOrigin {
                            lat_deg: lat,
                            lon_deg: lon,
                            alt_amsl_m: f64::from(st.alt),
                        });
                        self.samples.push((t_ms, origin.ned_from_geodetic(lat, lon, f64::from(st.alt))));
                    }
                    _ => {}
                }
            }
        }
    }

    /// The last sample at or before plant time `t_ms`, once a later one has come (the truth trails the
    /// telemetry by up to a poll of the plant); None while none has.
    pub fn at(&self, t_ms: u32) -> Option<Vector3<f64>> {
        if self.samples.last().is_none_or(|s| s.0 <= t_ms) {
            return None;
        }
        let before = self.samples.iter().rev().find(|s| s.0 <= t_ms);
        Some(before.unwrap_or_else(|| panic!("no truth sample at or before {t_ms} ms")).1)
    }
}

pub struct Gcs {
    pub socket: UdpSocket,
    pub autopilot: String,
    pub sysid: u8,
    pub decoder: FrameDecoder,
    pub seen: Seen,
    pub wall_start: Instant,
    pub first_time_ms: Option<u32>,
    pub truth: TruthLink,
}

impl Gcs {
    /// A ground station of instance `n` listening on `socket` (its API port), speaking to the autopilot on
    /// UDP 18570+N, with a client of the plant's SIM_ port for the truth; the wall-clock limit from now.
    pub fn new(n: u16, socket: UdpSocket) -> Self {
        Self {
            socket,
            autopilot: format!("127.0.0.1:{}", 18570 + n),
            sysid: u8::try_from(n + 1).expect("sysid"),
            decoder: FrameDecoder::new(),
            seen: Seen::default(),
            wall_start: Instant::now(),
            first_time_ms: None,
            truth: TruthLink::new(n),
        }
    }

    /// Read the plant's truth waiting, then whatever arrives for up to 100 ms of wall time, and update what
    /// we know.
    pub fn pump(&mut self) {
        assert!(self.wall_start.elapsed() < WALL_LIMIT, "e2e test exceeded its {WALL_LIMIT:?} wall-clock limit");
        self.truth.drain();
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
                    s.errors_comm = st.errors_comm;
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
                MavMessage::RC_CHANNELS(_) => s.rc = true,
                _ => {}
            }
            if let Some(t) = t {
                s.time_ms = s.time_ms.max(t);
                self.first_time_ms.get_or_insert(t);
            }
        }
    }

    pub fn now_s(&self) -> f64 {
        f64::from(self.seen.time_ms) * 1e-3
    }

    /// Pump until `cond`, at most `timeout_s` of vehicle time; returns the vehicle time it took (s).
    pub fn wait_until(&mut self, timeout_s: f64, what: &str, cond: impl Fn(&Seen) -> bool) -> f64 {
        let start = self.now_s();
        while !cond(&self.seen) {
            assert!(self.now_s() - start < timeout_s, "timed out ({timeout_s} s vehicle time) waiting for {what}");
            self.pump();
        }
        self.now_s() - start
    }

    pub fn run_s(&mut self, seconds: f64, mut each: impl FnMut(&Seen)) {
        let end = self.now_s() + seconds;
        while self.now_s() < end {
            self.pump();
            each(&self.seen);
        }
    }

    /// The plant's truth (NED m about its first sample) at vehicle time `t_ms`: the last sample at or
    /// before it, waiting (on the wall-clock guard) until a later one shows none is still to come.
    pub fn truth_at(&mut self, t_ms: u32) -> Vector3<f64> {
        loop {
            if let Some(p) = self.truth.at(t_ms) {
                return p;
            }
            self.pump();
        }
    }

    pub fn command(&mut self, command: MavCmd, params: [f32; 7]) -> MavResult {
        let msg = command_long(self.sysid, 1, command, params);
        self.seen.acks.clear();
        self.socket.send_to(&encode_frame_v2(GCS, &msg), &self.autopilot).expect("send command");
        self.wait_until(5.0, &format!("ACK of {command:?}"), |s| s.acks.iter().any(|a| a.0 == command));
        self.seen.acks.iter().find(|a| a.0 == command).map(|a| a.1).expect("ack")
    }
}

pub fn armed(s: &Seen) -> bool {
    s.base_mode.is_some_and(|m| m.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED))
}

/// A free instance N in 20..=60 with its API port bound (14541+N from N = 10: the port a script listens
/// on; QGroundControl's 14550 is shared by every instance, so concurrent tests cannot each hold it),
/// retried while another test or run holds it.
pub fn free_instance() -> (u16, UdpSocket) {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).expect("clock").subsec_nanos();
    for attempt in 0..40u32 {
        let n = 20 + u16::try_from((nanos.wrapping_add(attempt * 7919) ^ std::process::id()) % 41).expect("small");
        let port = InstancePorts::of(n).expect("in range").api_udp;
        if let Ok(api) = UdpSocket::bind(("127.0.0.1", port)) {
            api.set_read_timeout(Some(Duration::from_millis(100))).expect("timeout");
            return (n, api);
        }
    }
    panic!("no free API port for instances 20..=60");
}

/// The `sitl` binary, with an up-to-date `autopilot` binary built next to it.
pub fn sitl_binary() -> &'static str {
    static BUILT: std::sync::Once = std::sync::Once::new();
    let sitl = env!("CARGO_BIN_EXE_sitl");
    BUILT.call_once(|| {
        // `cargo test -p sitl` alone neither builds nor refreshes the other crate's binary: build it as
        // `cargo test --workspace` does (same profile, and the same features: the dev-dependencies' are
        // unified in, so a plain `cargo build -p autopilot` would rebuild tokio and its dependants, a
        // minute of CI), a no-op when it is current.
        let profile_release = std::path::Path::new(sitl).parent().is_some_and(|d| d.ends_with("release"));
        let mut build = Command::new(env!("CARGO"));
        build.args(["test", "--workspace", "--no-run", "--locked"]);
        if profile_release {
            build.arg("--release");
        }
        assert!(build.status().expect("cargo test --no-run").success(), "building the autopilot binary failed");
    });
    sitl
}

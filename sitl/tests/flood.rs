//! Floods against the real `autopilot` binary, with this test as its plant (HIL_SENSOR in lockstep, about
//! real time) and as its ground stations. Two checks of the bounds, on the process's resident
//! memory (`VmRSS` of `/proc/PID/status`), never on wall time:
//!
//! - 1,000 TCP connections opened and held: the server keeps [`TCP_CAP`] of them, says once that it is
//!   full, the clients it holds keep their HEARTBEATs, and a new client is served as soon as one closes;
//!   resident memory stays flat.
//! - mixed frames (valid, corrupted, random bytes) on every port (UDP from 64 senders, past the peer cap;
//!   a TCP stream; the plant's UDP socket): resident memory grows by less than 1 MB. The default run sends
//!   [`DEFAULT_FLOOD_FRAMES`] per port; `FLOOD_FRAMES=1000000 cargo test -p sitl --test flood -- --nocapture`
//!   runs the million (the figures are in docs/security.md).

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use autopilot::core::mavlink::common::{MavCmd, MavMessage, PARAM_REQUEST_READ_DATA};
use autopilot::core::mavlink::{MavHeader, command_long, gcs_heartbeat};
use autopilot::core::plant_link::{FrameDecoder, HilSensorFields, encode_frame_v2, encode_hil_sensor};
use nalgebra::Vector3;

/// The TCP client cap the autopilot runs with here (`[gcs] tcp_max_clients`).
const TCP_CAP: usize = 16;
/// Mixed frames per port in the default run.
const DEFAULT_FLOOD_FRAMES: usize = 100_000;
/// A wall-clock limit on every wait, so that a broken autopilot fails the test instead of hanging it.
const WAIT: Duration = Duration::from_secs(30);
const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

/// The `autopilot` binary, built next to `sitl` (as `cargo test --workspace` does; a no-op when current).
fn autopilot_binary() -> PathBuf {
    static BUILT: std::sync::Once = std::sync::Once::new();
    let sitl = Path::new(env!("CARGO_BIN_EXE_sitl"));
    BUILT.call_once(|| {
        let mut build = Command::new(env!("CARGO"));
        build.args(["test", "--workspace", "--no-run", "--locked"]);
        if sitl.parent().is_some_and(|d| d.ends_with("release")) {
            build.arg("--release");
        }
        assert!(build.status().expect("cargo test --no-run").success(), "building the autopilot binary failed");
    });
    sitl.with_file_name("autopilot")
}

/// A free local port for `kind` ("tcp" or "udp").
fn free_port(kind: &str) -> u16 {
    match kind {
        "tcp" => TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).expect("free port").port(),
        _ => UdpSocket::bind("127.0.0.1:0").and_then(|s| s.local_addr()).expect("free port").port(),
    }
}

/// The autopilot process, its stderr in a file; killed on drop.
struct Autopilot {
    child: Child,
    log: PathBuf,
    tcp: SocketAddr,
    udp: SocketAddr,
    _dir: TempDir,
}

struct TempDir(PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl Drop for Autopilot {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Autopilot {
    /// Resident memory now (kB).
    fn rss_kb(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).expect("status");
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .expect("VmRSS")
    }

    /// Lines of its log that contain `text`.
    fn log_count(&self, text: &str) -> usize {
        std::fs::read_to_string(&self.log).unwrap_or_default().lines().filter(|l| l.contains(text)).count()
    }
}

/// The plant: answers the autopilot's announcement, then steps it with HIL_SENSOR samples (level, at
/// rest) every 2 ms of wall time, each waiting for its actuator reply. Returns the autopilot's plant
/// address once known.
struct Plant {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    autopilot: SocketAddr,
}

impl Plant {
    fn start(socket: UdpSocket) -> Self {
        socket.set_read_timeout(Some(Duration::from_millis(100))).expect("timeout");
        let mut buf = [0u8; 2048];
        let start = Instant::now();
        let autopilot = loop {
            assert!(start.elapsed() < WAIT, "the autopilot never announced itself to the plant");
            if let Ok((_, from)) = socket.recv_from(&mut buf) {
                break from;
            }
        };
        let stop = Arc::new(AtomicBool::new(false));
        let running = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut time_us = 0u64;
            while !running.load(Ordering::Relaxed) {
                time_us += 2_000;
                let fields = HilSensorFields {
                    time_us,
                    accel_frd_mps2: Vector3::new(0.0, 0.0, -9.81),
                    gyro_frd_radps: Vector3::zeros(),
                    mag_frd_gauss: None,
                    baro: None,
                };
                let frame = encode_frame_v2(
                    MavHeader { system_id: 1, component_id: 51, sequence: 0 },
                    &MavMessage::HIL_SENSOR(encode_hil_sensor(&fields)),
                );
                let _ = socket.send_to(&frame, autopilot);
                let sent = Instant::now();
                // The reply (or anything: the flood may delay it); at most 100 ms.
                let _ = socket.recv_from(&mut buf);
                std::thread::sleep(Duration::from_millis(2).saturating_sub(sent.elapsed()));
            }
        });
        Self { stop, thread: Some(thread), autopilot }
    }
}

impl Drop for Plant {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Starts the autopilot (TCP cap [`TCP_CAP`], UDP peer cap 32, no fixed UDP targets, no state) and its
/// plant.
fn start(name: &str) -> (Autopilot, Plant) {
    let dir = std::env::temp_dir().join(format!("aco-flood-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let plant_socket = UdpSocket::bind("127.0.0.1:0").expect("plant socket");
    let (tcp_port, udp_port) = (free_port("tcp"), free_port("udp"));
    let config = dir.join("autopilot.toml");
    std::fs::write(
        &config,
        format!(
            "[plant]\nlink = \"udp://{}\"\n[gcs]\nudp_bind = \"127.0.0.1:{udp_port}\"\nudp_targets = []\n\
             tcp_bind = \"127.0.0.1:{tcp_port}\"\ntcp_max_clients = {TCP_CAP}\nudp_max_peers = 32\n\
             [state]\ndir = \"off\"\n",
            plant_socket.local_addr().expect("addr")
        ),
    )
    .expect("config");
    let log = dir.join("autopilot.log");
    let child = Command::new(autopilot_binary())
        .arg("--config")
        .arg(&config)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stderr(std::fs::File::create(&log).expect("log"))
        .process_group(0)
        .spawn()
        .expect("spawn autopilot");
    let autopilot = Autopilot {
        child,
        log,
        tcp: SocketAddr::from(([127, 0, 0, 1], tcp_port)),
        udp: SocketAddr::from(([127, 0, 0, 1], udp_port)),
        _dir: TempDir(dir),
    };
    let plant = Plant::start(plant_socket);
    (autopilot, plant)
}

/// A HEARTBEAT of the vehicle in `bytes` (decoded with `decoder`, which keeps a partial frame).
fn has_vehicle_heartbeat(decoder: &mut FrameDecoder, bytes: &[u8]) -> bool {
    decoder.push(bytes).iter().any(|f| f.header.system_id == 1 && matches!(f.message, MavMessage::HEARTBEAT(_)))
}

/// Reads `stream` (non-blocking) until a vehicle HEARTBEAT arrives (true) or it is closed (false).
fn wait_heartbeat_or_close(stream: &mut TcpStream) -> bool {
    stream.set_read_timeout(Some(Duration::from_millis(200))).expect("timeout");
    let mut decoder = FrameDecoder::new();
    let mut buf = [0u8; 4096];
    let start = Instant::now();
    while start.elapsed() < WAIT {
        match stream.read(&mut buf) {
            Ok(0) => return false,
            Ok(n) if has_vehicle_heartbeat(&mut decoder, &buf[..n]) => return true,
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return false,
        }
    }
    panic!("neither a HEARTBEAT nor the end of the stream within {WAIT:?}");
}

#[test]
fn a_thousand_tcp_connections_held_the_server_keeps_its_cap_says_so_once_and_serves_a_new_client_when_one_closes() {
    let (autopilot, _plant) = start("tcp");
    // Warm up: one client, served.
    let mut first = TcpStream::connect(autopilot.tcp).expect("connect");
    assert!(wait_heartbeat_or_close(&mut first), "a first client is served");
    drop(first);
    std::thread::sleep(Duration::from_millis(300));
    let rss_before = autopilot.rss_kb();

    // GIVEN 1,000 connections opened and held.
    let mut streams: Vec<TcpStream> =
        (0..1000).map(|i| TcpStream::connect(autopilot.tcp).unwrap_or_else(|e| panic!("connect {i}: {e}"))).collect();
    for s in &streams {
        s.set_nonblocking(true).expect("nonblocking");
    }
    // THEN each is either served (a HEARTBEAT comes) or closed at once.
    let mut served = vec![None::<bool>; streams.len()];
    let mut decoders: Vec<FrameDecoder> = (0..streams.len()).map(|_| FrameDecoder::new()).collect();
    let mut buf = [0u8; 4096];
    let start = Instant::now();
    while served.iter().any(Option::is_none) {
        assert!(start.elapsed() < WAIT, "undecided connections: {}", served.iter().filter(|s| s.is_none()).count());
        for (i, s) in streams.iter_mut().enumerate() {
            if served[i].is_some() {
                continue;
            }
            match s.read(&mut buf) {
                Ok(0) => served[i] = Some(false),
                Ok(n) if has_vehicle_heartbeat(&mut decoders[i], &buf[..n]) => served[i] = Some(true),
                Ok(_) => {}
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(_) => served[i] = Some(false),
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let held: Vec<usize> = (0..streams.len()).filter(|i| served[*i] == Some(true)).collect();
    assert_eq!(held.len(), TCP_CAP, "the server holds exactly its cap");
    assert_eq!(autopilot.log_count("TCP client cap reached"), 1, "the refusals are said once");

    // The clients it holds keep their telemetry.
    for &i in &held {
        streams[i].set_nonblocking(false).expect("blocking");
        assert!(wait_heartbeat_or_close(&mut streams[i]), "held client {i} lost its telemetry");
    }
    let rss_held = autopilot.rss_kb();

    // WHEN one held client closes THEN a new client is served.
    let gone = held[0];
    drop(streams.swap_remove(gone));
    let start = Instant::now();
    let mut newcomer = loop {
        let mut s = TcpStream::connect(autopilot.tcp).expect("connect");
        if wait_heartbeat_or_close(&mut s) {
            break s;
        }
        assert!(start.elapsed() < WAIT, "no slot freed after a held client closed");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(wait_heartbeat_or_close(&mut newcomer));
    assert_eq!(autopilot.log_count("TCP client slot free again"), 1, "the end of the burst is said once");
    let rss_after = autopilot.rss_kb();
    eprintln!("tcp: RSS {rss_before} kB before, {rss_held} kB with 1000 connections held, {rss_after} kB after");
    assert!(rss_after.saturating_sub(rss_before) < 1024, "RSS grew from {rss_before} to {rss_after} kB");
}

/// The `i`th frame of a mixed flood: a valid GCS message (heartbeat, a message request, a parameter read), the same
/// with a corrupted byte, a truncated frame, or random bytes.
fn mixed_frame(i: usize, rng: &mut u64) -> Vec<u8> {
    let mut next = || {
        *rng ^= *rng << 13;
        *rng ^= *rng >> 7;
        *rng ^= *rng << 17;
        *rng
    };
    let header = MavHeader { sequence: (i % 256) as u8, ..GCS };
    let valid = match i % 3 {
        0 => encode_frame_v2(header, &gcs_heartbeat()),
        // EXTENDED_SYS_STATE, once.
        1 => encode_frame_v2(
            header,
            &command_long(1, 1, MavCmd::MAV_CMD_REQUEST_MESSAGE, [245.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ),
        _ => encode_frame_v2(
            header,
            &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: (next() % 200) as i16,
                target_system: 1,
                target_component: 1,
                param_id: [0u8; 16].into(),
            }),
        ),
    };
    match i % 4 {
        0 => valid,
        1 => {
            let mut bad = valid;
            let at = (next() as usize) % bad.len();
            bad[at] ^= 0x5A;
            bad
        }
        2 => valid[..valid.len() / 2].to_vec(),
        _ => (0..(next() % 64 + 1)).map(|_| next() as u8).collect(),
    }
}

/// Sends `frames` mixed frames to every port: UDP from 64 sockets, one TCP stream (its replies read and
/// dropped), the plant socket.
fn flood(autopilot: &Autopilot, plant: SocketAddr, frames: usize) {
    let senders: Vec<UdpSocket> = (0..64).map(|_| UdpSocket::bind("127.0.0.1:0").expect("bind")).collect();
    let mut tcp = TcpStream::connect(autopilot.tcp).expect("connect");
    let mut reader = tcp.try_clone().expect("clone");
    let drain = std::thread::spawn(move || {
        let mut buf = [0u8; 65536];
        while matches!(reader.read(&mut buf), Ok(n) if n > 0) {}
    });
    let mut rng = 0x9E37_79B9_7F4A_7C15_u64;
    let mut tcp_batch = Vec::new();
    for i in 0..frames {
        let frame = mixed_frame(i, &mut rng);
        // Each sender sends every kind of frame, so all 64 become peers.
        let sender = &senders[(i / 4) % senders.len()];
        let _ = sender.send_to(&frame, autopilot.udp);
        let _ = sender.send_to(&frame, plant);
        tcp_batch.extend_from_slice(&frame);
        if tcp_batch.len() > 16_384 {
            tcp.write_all(&tcp_batch).expect("TCP write");
            tcp_batch.clear();
        }
        if i % 64 == 63 {
            // Let the autopilot read: a datagram dropped by a full socket buffer tests nothing.
            std::thread::sleep(Duration::from_micros(200));
        }
    }
    tcp.write_all(&tcp_batch).expect("TCP write");
    std::thread::sleep(Duration::from_millis(500));
    // Both handles share the socket: shutting it down ends the reader's blocking read.
    let _ = tcp.shutdown(std::net::Shutdown::Both);
    let _ = drain.join();
}

#[test]
fn mixed_frames_on_every_port_leave_resident_memory_flat() {
    let frames = std::env::var("FLOOD_FRAMES").ok().and_then(|v| v.parse().ok()).unwrap_or(DEFAULT_FLOOD_FRAMES);
    let (autopilot, plant) = start("frames");
    let mut client = TcpStream::connect(autopilot.tcp).expect("connect");
    assert!(wait_heartbeat_or_close(&mut client), "served before the flood");
    // Warm up every path (peer tables full, buffers at their size), then measure.
    flood(&autopilot, plant.autopilot, frames / 10);
    std::thread::sleep(Duration::from_millis(500));
    let rss_before = autopilot.rss_kb();
    let start = Instant::now();
    flood(&autopilot, plant.autopilot, frames);
    let took = start.elapsed();
    std::thread::sleep(Duration::from_millis(500));
    let rss_after = autopilot.rss_kb();
    eprintln!(
        "flood: {frames} mixed frames per port (UDP, TCP, plant) in {:.1} s: RSS {rss_before} kB before, \
         {rss_after} kB after",
        took.as_secs_f64()
    );
    assert!(rss_after.saturating_sub(rss_before) < 1024, "RSS grew from {rss_before} to {rss_after} kB");
    // Still flying and serving: a held client gets its HEARTBEAT.
    assert!(wait_heartbeat_or_close(&mut client), "the client held through the flood is still served");
    // 64 senders past a cap of 32: said once per burst (a burst ends when a peer expires, after 10 s without
    // a frame from it, which a slow machine can make happen mid-flood), not once per refused frame.
    let (reached, freed) =
        (autopilot.log_count("UDP peer cap reached"), autopilot.log_count("UDP peer slot free again"));
    eprintln!("flood: UDP peer cap said {reached} time(s), its end {freed} time(s)");
    assert!(reached >= 1 && reached <= freed + 1, "cap reached said {reached} times, its end {freed} times");
}

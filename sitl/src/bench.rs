//! `sitl bench`: what the SITL costs and how it answers. One vehicle (the default): the two-process
//! real-time factor in lockstep, and the CPU and telemetry of a real-time run. `--vehicles N`: a swarm of N
//! started as `sitl run -n N` starts it, at real time, with a ground station on UDP 14550 that measures,
//! per vehicle, the wall-clock intervals between its HEARTBEATs and the latency of a COMMAND_ACK to a
//! COMMAND_LONG addressed to its system id, and the CPU of the plant process and of every autopilot (user
//! plus system, from `/proc`, per process and per thread); then PASS or FAIL against the swarm's targets:
//! every vehicle's HEARTBEAT interval p99 <= [`HEARTBEAT_P99_LIMIT_S`], COMMAND_ACK p99 <=
//! [`ACK_P99_LIMIT_MS`].

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use autopilot::core::hil::{FrameDecoder, encode_frame_v2};
use autopilot::core::mavlink::command::command_long;
use autopilot::runtime::ports::InstancePorts;
use clap::Parser;
use mavlink::MavHeader;
use mavlink::dialects::common::{MavCmd, MavMessage};
use sitl::launch::{self, AutopilotChild, TempConfig};
use sitl::link::{LinkConfig, Pacing, PlantServer};
use sitl::plant::{InitialState, Plant};

use crate::{
    BenchArgs, Cli, Command, RunArgs, bind_sim_params, duration_us, instance_ports, realistic_plant_config, start_swarm,
};

/// The swarm target: every vehicle's HEARTBEAT interval at the ground station, p99 (s).
pub const HEARTBEAT_P99_LIMIT_S: f64 = 1.2;
/// The swarm target: COMMAND_ACK latency at the ground station, p99 over every command (ms).
pub const ACK_P99_LIMIT_MS: f64 = 20.0;
/// Each vehicle gets one COMMAND_LONG per this period, the vehicles' sends spread evenly over it.
const COMMAND_PERIOD: Duration = Duration::from_secs(1);
/// After every vehicle was heard, the swarm runs this long before the measurement starts.
const WARM_UP: Duration = Duration::from_secs(2);
/// The receive buffer the bench's ground station asks for (B).
const GROUND_STATION_RCVBUF_BYTES: usize = 4 << 20;
/// How long the ground station waits for every vehicle's first HEARTBEAT.
const HEAR_ALL_TIMEOUT: Duration = Duration::from_secs(60);
/// The message each command requests: AUTOPILOT_VERSION (harmless, and not a HEARTBEAT, whose intervals
/// are measured).
const REQUESTED_MESSAGE_ID: f32 = 148.0;

/// `sitl bench`.
pub fn run(args: &BenchArgs) -> Result<()> {
    match args.vehicles {
        Some(count) => bench_swarm(args, count),
        None => bench_one(args),
    }
}

/// p50, p99 and the largest of a sample (nearest rank: the smallest value with at least p % of the sample
/// at or below it), and its size. Units are the sample's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub count: usize,
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

impl Summary {
    /// The summary of `values` (NaN sorts last); `None` for an empty sample.
    #[must_use]
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        Some(Self {
            count: sorted.len(),
            p50: nearest_rank(&sorted, 50.0),
            p99: nearest_rank(&sorted, 99.0),
            max: sorted[sorted.len() - 1],
        })
    }
}

/// The `pct` percentile of an ascending, non-empty sample by nearest rank.
fn nearest_rank(sorted: &[f64], pct: f64) -> f64 {
    let rank = (pct / 100.0 * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// `summary` as "p50 a, p99 b, max c UNIT" with each value times `scale`.
fn describe(summary: Option<Summary>, scale: f64, unit: &str, decimals: usize) -> String {
    match summary {
        Some(s) => format!(
            "p50 {:.d$}, p99 {:.d$}, max {:.d$} {unit} ({} samples)",
            s.p50 * scale,
            s.p99 * scale,
            s.max * scale,
            s.count,
            d = decimals
        ),
        None => "no samples".to_owned(),
    }
}

// -- one vehicle -----------------------------------------------------------------------------------------

/// Counts what arrives on a UDP port (the ground-station side of a bench run) until stopped.
struct TelemetryCounter {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<(u64, u64)>,
}

impl TelemetryCounter {
    fn listen(port: u16) -> Result<Self> {
        let socket = UdpSocket::bind(("127.0.0.1", port)).with_context(|| format!("binding udp {port}"))?;
        socket.set_read_timeout(Some(Duration::from_millis(20)))?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut decoder = FrameDecoder::new();
            let (mut frames, mut bytes) = (0, 0);
            let mut buf = [0u8; 65_536];
            while !flag.load(Ordering::Relaxed) {
                if let Ok(n) = socket.recv(&mut buf) {
                    frames += decoder.decode_datagram(&buf[..n]).len() as u64;
                    bytes += n as u64;
                }
            }
            (frames, bytes)
        });
        Ok(Self { stop, thread })
    }

    /// (MAVLink messages, bytes) received.
    fn finish(self) -> (u64, u64) {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().unwrap_or((0, 0))
    }
}

/// One bench run: the default `sitl run` plant and autopilot for `duration_s` simulated seconds, with a
/// ground station listening on the QGroundControl port, or (`gcs` false) with the autopilot's
/// ground-station links off.
fn bench_once(
    n: u16,
    pacing: Pacing,
    duration_s: f64,
    gcs: bool,
    stop: &AtomicBool,
) -> Result<(launch::LaunchReport, u64, u64)> {
    let (plant_port, _, qgc_port, _) = instance_ports(n)?;
    let plant = Plant::new(realistic_plant_config(), &InitialState::default(), 1)?;
    let link = LinkConfig { pacing, connect_timeout: Some(Duration::from_secs(30)), ..LinkConfig::default() };
    let listen = format!("127.0.0.1:{plant_port}");
    // As `sitl run`: the SIM_ parameter service polled between steps.
    let (sim_params, _) = bind_sim_params(n, &plant)?;
    let mut server =
        PlantServer::bind_udp(plant, listen.as_str(), link).with_context(|| format!("binding {listen}"))?;
    server.set_hook(Box::new(sim_params));
    let counter = TelemetryCounter::listen(qgc_port)?;
    let mut args: Vec<OsString> = vec![
        "--plant".into(),
        format!("udp://{listen}").into(),
        "-i".into(),
        n.to_string().into(),
        "--state-dir".into(),
        "off".into(),
    ];
    let _config = if gcs {
        None
    } else {
        let config = TempConfig::write("bench", "[gcs]\nudp_targets = []\ntcp_bind = \"off\"\n")
            .map_err(|(path, e)| anyhow::anyhow!("writing {}: {e}", path.display()))?;
        args.extend(["--config".into(), config.path().into()]);
        Some(config)
    };
    let child = AutopilotChild::spawn_with(&launch::autopilot_binary()?, &args, Some("warn"))?;
    let report = launch::run_with_child(&mut server, child, duration_us(Some(duration_s))?, stop, |_, _| {})?;
    let (messages, bytes) = counter.finish();
    if report.stopped {
        bail!("stopped");
    }
    Ok((report, messages, bytes))
}

/// `sitl bench` without `--vehicles`: lockstep with and without ground-station links, then real time.
fn bench_one(args: &BenchArgs) -> Result<()> {
    let stop = launch::ctrl_c_flag();
    let n = args.instance;
    println!(
        "sitl bench: the default `sitl run` plant (nominal, modest sensor noise) and autopilot (fused estimator, \
         ACO, on the ground), telemetry to a ground station on udp {}",
        InstancePorts::of(n)?.qgc_udp
    );
    for gcs in [true, false] {
        let (r, messages, _) = bench_once(n, Pacing::Lockstep, args.sim_s, gcs, &stop)?;
        println!(
            "  lockstep, {}: {:.1} sim s in {:.2} s wall = {:.1}x real time, {:.0} steps/s, {:.1} us per step; CPU \
             per step: autopilot {:.1} us, plant {:.1} us (both poll while waiting); {} telemetry messages received",
            if gcs { "telemetry to the ground station" } else { "ground-station links off" },
            r.sim_s,
            r.wall_s,
            r.realtime_factor(),
            r.steps as f64 / r.wall_s,
            r.wall_s * 1e6 / r.steps as f64,
            r.autopilot_cpu_s.unwrap_or(f64::NAN) * 1e6 / r.steps as f64,
            r.plant_cpu_s.unwrap_or(f64::NAN) * 1e6 / r.steps as f64,
            messages,
        );
    }
    if args.realtime_s <= 0.0 {
        return Ok(());
    }
    let (r, messages, bytes) = bench_once(n, Pacing::RealTime { speed: 1.0 }, args.realtime_s, true, &stop)?;
    println!(
        "  real time: {:.1} s: CPU autopilot {:.2} % of a core, plant {:.2} %; telemetry {:.1} messages/s, {:.2} kB/s",
        r.wall_s,
        100.0 * r.autopilot_cpu_s.unwrap_or(f64::NAN) / r.wall_s,
        100.0 * r.plant_cpu_s.unwrap_or(f64::NAN) / r.wall_s,
        messages as f64 / r.wall_s,
        bytes as f64 / r.wall_s / 1000.0,
    );
    Ok(())
}

// -- a swarm ---------------------------------------------------------------------------------------------

/// The `sitl run` options of the bench's swarm: `sitl run -n N -i FIRST` with no kept state, parsed by
/// the same command line, so the swarm is started exactly as `sitl run -n N` starts it.
fn swarm_run_args(first: u16, count: u16) -> Result<RunArgs> {
    let (first, count) = (first.to_string(), count.to_string());
    let cli = Cli::try_parse_from(["sitl", "run", "-n", &count, "-i", &first, "--state-dir", "off", "--no-ulog"])?;
    let Command::Run(run) = cli.command else { bail!("`sitl run` parsed as another command") };
    Ok(run)
}

/// CPU seconds (user + system) of every thread of process `pid` (`self` for this one), by thread id,
/// with the thread's name.
fn thread_cpu_s(pid: &str) -> BTreeMap<u32, (String, f64)> {
    let mut threads = BTreeMap::new();
    let Ok(entries) = std::fs::read_dir(format!("/proc/{pid}/task")) else { return threads };
    for entry in entries.flatten() {
        let Some(tid) = entry.file_name().to_str().and_then(|t| t.parse::<u32>().ok()) else { continue };
        let dir = entry.path();
        let Some(cpu_s) = launch::cpu_seconds(&dir.join("stat").to_string_lossy()) else { continue };
        let name = std::fs::read_to_string(dir.join("comm")).unwrap_or_default().trim().to_owned();
        threads.insert(tid, (name, cpu_s));
    }
    threads
}

/// The CPU counters the measurement window starts and ends with.
#[derive(Debug, Clone)]
struct CpuSample {
    at: Instant,
    /// This process (the plants, the ground station, the bookkeeping), s.
    plant_process_s: f64,
    /// The ground-station thread of this process, s.
    ground_station_s: f64,
    /// Each autopilot process, in instance order, s.
    autopilots_s: Vec<f64>,
    /// Every thread of this process and of every autopilot: (pid, tid) -> (name, s).
    threads: BTreeMap<(u32, u32), (String, f64)>,
}

impl CpuSample {
    fn take(pids: &[u32]) -> Self {
        let mut threads = BTreeMap::new();
        let own = std::process::id();
        for (tid, v) in thread_cpu_s("self") {
            threads.insert((own, tid), v);
        }
        for &pid in pids {
            for (tid, v) in thread_cpu_s(&pid.to_string()) {
                threads.insert((pid, tid), v);
            }
        }
        Self {
            at: Instant::now(),
            plant_process_s: launch::own_cpu_s().unwrap_or(f64::NAN),
            ground_station_s: launch::cpu_seconds("/proc/thread-self/stat").unwrap_or(f64::NAN),
            autopilots_s: pids
                .iter()
                .map(|p| launch::cpu_seconds(&format!("/proc/{p}/stat")).unwrap_or(f64::NAN))
                .collect(),
            threads,
        }
    }
}

/// The bench ground station's socket on 127.0.0.1:`port`: bound without SO_REUSEADDR (it is the only
/// ground station on the port, or the bench does not start), with a receive buffer of
/// [`GROUND_STATION_RCVBUF_BYTES`] (as far as `net.core.rmem_max` allows): the default 208 KiB holds about
/// 0.1 s of a large swarm's telemetry (each small datagram is charged about 1 KiB), less than this thread
/// may wait for a core on a loaded machine, and the kernel drops what does not fit.
fn ground_station_socket(port: u16) -> Result<UdpSocket> {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, Some(socket2::Protocol::UDP))?;
    socket.set_recv_buffer_size(GROUND_STATION_RCVBUF_BYTES)?;
    socket.bind(&SocketAddr::from(([127, 0, 0, 1], port)).into()).with_context(|| {
        format!("binding udp {port}, where the bench listens as the ground station (is QGroundControl running?)")
    })?;
    let socket = UdpSocket::from(socket);
    socket.set_read_timeout(Some(Duration::from_millis(2)))?;
    Ok(socket)
}

/// Datagrams the kernel dropped at the UDP socket bound on 127.0.0.1:`port` for want of receive buffer
/// (the `drops` column of `/proc/net/udp`), or `None` if there is no such socket.
fn socket_drops(port: u16) -> Option<u64> {
    let table = std::fs::read_to_string("/proc/net/udp").ok()?;
    let local = format!("0100007F:{port:04X}");
    table.lines().skip(1).find_map(|line| {
        let fields: Vec<&str> = line.split_whitespace().collect();
        (fields.get(1) == Some(&local.as_str())).then(|| fields.last()?.parse().ok()).flatten()
    })
}

/// What the ground station measured over the window, per vehicle in instance order.
#[derive(Debug, Default)]
struct Measured {
    /// Wall seconds between consecutive HEARTBEATs (and the silence at the end of the window when it is
    /// longer than the limit).
    heartbeat_intervals_s: Vec<Vec<f64>>,
    /// COMMAND_ACK latencies, ms (an unanswered command: infinity).
    ack_latencies_ms: Vec<Vec<f64>>,
    unanswered: Vec<u64>,
    /// Telemetry received over the window: messages and bytes, and the autopilots' messages that never
    /// arrived (gaps in their MAVLink sequence numbers).
    messages: u64,
    bytes: u64,
    lost: u64,
    /// Of the lost, those the ground station's own socket dropped (its receive buffer was full).
    dropped_here: Option<u64>,
    cpu: Option<(CpuSample, CpuSample)>,
    /// Plant time at the window's start and end, µs.
    plant_time_us: (u64, u64),
    /// Vehicles never heard (when the ground station gave up waiting), by system id.
    never_heard: Vec<u8>,
    stopped: bool,
}

/// The ground station of a swarm bench, on this thread: waits for every vehicle's HEARTBEAT, lets the
/// swarm run [`WARM_UP`], then for `window` sends each vehicle a COMMAND_LONG (REQUEST_MESSAGE) every
/// [`COMMAND_PERIOD`] and records HEARTBEAT arrivals and COMMAND_ACK latencies, taking the CPU counters at
/// both ends. Returns early (stopped) once `stop` or `swarm_done` is set.
fn ground_station(
    socket: &UdpSocket,
    first: u16,
    pids: &[u32],
    window: Duration,
    plant_time_us: &AtomicU64,
    stop: &AtomicBool,
    swarm_done: &AtomicBool,
) -> Result<Measured> {
    let count = pids.len();
    let ports: Vec<InstancePorts> =
        (0..count).map(|k| InstancePorts::of(first + k as u16)).collect::<Result<_, _>>()?;
    let targets: Vec<SocketAddr> = ports.iter().map(|p| SocketAddr::from(([127, 0, 0, 1], p.autopilot_udp))).collect();
    let first_sysid = u32::from(ports[0].system_id);
    let index_of = |sysid: u32| sysid.checked_sub(first_sysid).map(|k| k as usize).filter(|&k| k < count);
    let mut m = Measured {
        heartbeat_intervals_s: vec![Vec::new(); count],
        ack_latencies_ms: vec![Vec::new(); count],
        unanswered: vec![0; count],
        ..Measured::default()
    };
    let mut last_heartbeat: Vec<Option<Instant>> = vec![None; count];
    let mut last_sequence: Vec<Option<u8>> = vec![None; count];
    let mut outstanding: Vec<Option<Instant>> = vec![None; count];
    let mut next_command: Vec<Instant> = Vec::new();
    let mut decoder = FrameDecoder::new();
    let mut buf = vec![0u8; 65_536];
    let mut sequence = 0u8;
    let started = Instant::now();
    // The phases: None until every vehicle was heard and the plants step; then the window's start and end.
    let mut window_at: Option<(Instant, Instant)> = None;
    let mut start_cpu: Option<CpuSample> = None;
    let mut drops_at_start: Option<u64> = None;
    loop {
        let now = Instant::now();
        if stop.load(Ordering::Relaxed) || swarm_done.load(Ordering::Relaxed) {
            m.stopped = true;
            return Ok(m);
        }
        match window_at {
            None => {
                let heard = last_heartbeat.iter().all(Option::is_some);
                if heard && plant_time_us.load(Ordering::Relaxed) > 0 {
                    let start = now + WARM_UP;
                    window_at = Some((start, start + window));
                    let spread = COMMAND_PERIOD.as_secs_f64() / count as f64;
                    next_command = (0..count).map(|k| start + Duration::from_secs_f64(spread * k as f64)).collect();
                } else if now - started > HEAR_ALL_TIMEOUT {
                    m.never_heard =
                        (0..count).filter(|&k| last_heartbeat[k].is_none()).map(|k| ports[k].system_id).collect();
                    return Ok(m);
                }
            }
            Some((start, end)) => {
                if start_cpu.is_none() && now >= start {
                    start_cpu = Some(CpuSample::take(pids));
                    drops_at_start = socket_drops(ports[0].qgc_udp);
                    m.plant_time_us.0 = plant_time_us.load(Ordering::Relaxed);
                    // Intervals count from here: a HEARTBEAT before the window starts none.
                    last_heartbeat.iter_mut().for_each(|t| *t = None);
                }
                if now >= end {
                    let end_cpu = CpuSample::take(pids);
                    m.dropped_here = drops_at_start.zip(socket_drops(ports[0].qgc_udp)).map(|(a, b)| b - a);
                    m.plant_time_us.1 = plant_time_us.load(Ordering::Relaxed);
                    for k in 0..count {
                        if outstanding[k].is_some_and(|sent| now - sent >= COMMAND_PERIOD) {
                            m.unanswered[k] += 1;
                            m.ack_latencies_ms[k].push(f64::INFINITY);
                        }
                        // A vehicle silent at the end: its silence is an interval at least this long.
                        let silence_s = last_heartbeat[k].map_or(window.as_secs_f64(), |t| (now - t).as_secs_f64());
                        if silence_s > HEARTBEAT_P99_LIMIT_S {
                            m.heartbeat_intervals_s[k].push(silence_s);
                        }
                    }
                    m.cpu = start_cpu.map(|s| (s, end_cpu));
                    return Ok(m);
                }
                for k in 0..count {
                    if now >= start && now >= next_command[k] {
                        if outstanding[k].take().is_some() {
                            m.unanswered[k] += 1;
                            m.ack_latencies_ms[k].push(f64::INFINITY);
                        }
                        let header = MavHeader { system_id: 255, component_id: 190, sequence };
                        sequence = sequence.wrapping_add(1);
                        let params = [REQUESTED_MESSAGE_ID, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
                        let msg = command_long(ports[k].system_id, 1, MavCmd::MAV_CMD_REQUEST_MESSAGE, params);
                        socket.send_to(&encode_frame_v2(header, &msg), targets[k])?;
                        outstanding[k] = Some(Instant::now());
                        next_command[k] += COMMAND_PERIOD;
                    }
                }
            }
        }
        let Ok(len) = socket.recv(&mut buf) else { continue };
        let arrived = Instant::now();
        let measuring = window_at.is_some_and(|(start, _)| arrived >= start);
        let frames = decoder.decode_datagram(&buf[..len]);
        if measuring {
            m.messages += frames.len() as u64;
            m.bytes += len as u64;
        }
        for frame in frames {
            let Some(k) = index_of(frame.header.system_id) else { continue };
            if frame.header.component_id != 1 {
                continue;
            }
            let sequence = frame.header.sequence;
            if measuring && let Some(last) = last_sequence[k] {
                m.lost += u64::from(sequence.wrapping_sub(last).wrapping_sub(1));
            }
            last_sequence[k] = Some(sequence);
            match frame.message {
                MavMessage::HEARTBEAT(_) => {
                    if measuring && let Some(previous) = last_heartbeat[k] {
                        m.heartbeat_intervals_s[k].push((arrived - previous).as_secs_f64());
                    }
                    last_heartbeat[k] = Some(arrived);
                }
                MavMessage::COMMAND_ACK(ack) if ack.command == MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                    if let Some(sent) = outstanding[k].take() {
                        m.ack_latencies_ms[k].push((arrived - sent).as_secs_f64() * 1e3);
                    }
                }
                _ => {}
            }
        }
    }
}

/// `sitl bench --vehicles N`.
fn bench_swarm(args: &BenchArgs, count: u16) -> Result<()> {
    if !(args.realtime_s.is_finite() && args.realtime_s >= 5.0) {
        bail!("--vehicles measures over --realtime-s of wall time: give at least 5 s, got {}", args.realtime_s);
    }
    let first = args.instance;
    let qgc = InstancePorts::of(first)?.qgc_udp;
    let socket = ground_station_socket(qgc)?;
    let run_args = swarm_run_args(first, count)?;
    let stop = launch::ctrl_c_flag();
    let cores = std::thread::available_parallelism().map_or(0, std::num::NonZero::get);
    println!(
        "sitl bench --vehicles {count}: a swarm as `sitl run -n {count} -i {first}` starts it (fused estimators, on \
         the ground) at real time on {cores} cores; a ground station on udp {qgc} measures {:.0} s of wall time \
         after every vehicle was heard and {:.0} s of warm-up, sending each vehicle a COMMAND_LONG \
         (REQUEST_MESSAGE) every {:.0} s",
        args.realtime_s,
        WARM_UP.as_secs_f64(),
        COMMAND_PERIOD.as_secs_f64(),
    );
    // The autopilots log warnings only: N start-up banners would bury the figures.
    let (mut servers, children) = start_swarm(&run_args, Some("warn"))?;
    let pids: Vec<u32> = children.iter().map(AutopilotChild::id).collect();
    let window = Duration::from_secs_f64(args.realtime_s);
    let halt = AtomicBool::new(false);
    let swarm_done = AtomicBool::new(false);
    let plant_time_us = AtomicU64::new(0);
    let (swarm, measured) = std::thread::scope(|scope| {
        let gcs = std::thread::Builder::new().name("bench-gcs".into()).spawn_scoped(scope, || {
            let m = ground_station(&socket, first, &pids, window, &plant_time_us, &stop, &swarm_done);
            halt.store(true, Ordering::Relaxed);
            m
        });
        let swarm = launch::run_swarm(&mut servers, children, None, &halt, |t_us| {
            plant_time_us.store(t_us, Ordering::Relaxed);
        });
        swarm_done.store(true, Ordering::Relaxed);
        let measured = match gcs {
            Ok(thread) => thread.join().unwrap_or_else(|_| Err(anyhow::anyhow!("the ground-station thread panicked"))),
            Err(e) => Err(e.into()),
        };
        (swarm, measured)
    });
    let swarm = swarm?;
    let m = measured?;
    if !m.never_heard.is_empty() {
        bail!("no HEARTBEAT within {:.0} s from systems {:?}", HEAR_ALL_TIMEOUT.as_secs_f64(), m.never_heard);
    }
    if stop.load(Ordering::Relaxed) || m.cpu.is_none() {
        bail!("stopped before the measurement ended");
    }
    let resends: u64 = swarm.vehicles.iter().map(|v| v.link.resends).sum();
    report(args, first, &m, resends)
}

/// Prints the figures and the PASS or FAIL line; FAIL is an error (exit code 1).
fn report(args: &BenchArgs, first: u16, m: &Measured, resends: u64) -> Result<()> {
    let count = m.heartbeat_intervals_s.len();
    let Some((start, end)) = &m.cpu else { bail!("no CPU figures") };
    let wall_s = (end.at - start.at).as_secs_f64();
    let sim_s = (m.plant_time_us.1.saturating_sub(m.plant_time_us.0)) as f64 * 1e-6;
    println!(
        "  plant time: {sim_s:.2} s in {wall_s:.2} s of wall time ({:.3}x real time); plant-link resends: {resends}; \
         telemetry at the ground station: {:.0} messages/s, {:.1} kB/s, {} lost (sequence gaps; {} of them dropped \
         by the ground station's full receive buffer)",
        sim_s / wall_s,
        m.messages as f64 / wall_s,
        m.bytes as f64 / wall_s / 1e3,
        m.lost,
        m.dropped_here.map_or_else(|| "?".to_owned(), |d| d.to_string()),
    );
    // HEARTBEAT intervals: every vehicle's, and the one whose p99 is worst.
    let per_vehicle: Vec<Option<Summary>> = m.heartbeat_intervals_s.iter().map(|v| Summary::of(v)).collect();
    let all_intervals: Vec<f64> = m.heartbeat_intervals_s.iter().flatten().copied().collect();
    let worst = (0..count).max_by(|&a, &b| {
        let p99 = |k: usize| per_vehicle[k].map_or(f64::INFINITY, |s| s.p99);
        p99(a).total_cmp(&p99(b))
    });
    println!("  HEARTBEAT interval, all vehicles: {}", describe(Summary::of(&all_intervals), 1.0, "s", 3));
    if let Some(k) = worst {
        println!(
            "  HEARTBEAT interval, worst vehicle (system {}): {}",
            u32::from(first) + 1 + k as u32,
            describe(per_vehicle[k], 1.0, "s", 3)
        );
    }
    let all_acks: Vec<f64> = m.ack_latencies_ms.iter().flatten().copied().collect();
    let unanswered: u64 = m.unanswered.iter().sum();
    let ack = Summary::of(&all_acks);
    println!("  COMMAND_ACK latency, all commands: {} ({unanswered} unanswered)", describe(ack, 1.0, "ms", 2));
    let worst_ack = (0..count)
        .filter_map(|k| Summary::of(&m.ack_latencies_ms[k]).map(|s| (k, s)))
        .max_by(|a, b| a.1.p99.total_cmp(&b.1.p99));
    if let Some((k, s)) = worst_ack {
        println!(
            "  COMMAND_ACK latency, worst vehicle (system {}): {}",
            u32::from(first) + 1 + k as u32,
            describe(Some(s), 1.0, "ms", 2)
        );
    }
    // CPU: the plant process (less its ground-station thread), the autopilots, per thread name.
    let pct = |s: f64| 100.0 * s / wall_s;
    let plant_process_s = end.plant_process_s - start.plant_process_s;
    let ground_station_s = end.ground_station_s - start.ground_station_s;
    let autopilot_s: Vec<f64> = end.autopilots_s.iter().zip(&start.autopilots_s).map(|(b, a)| b - a).collect();
    let autopilots_s: f64 = autopilot_s.iter().sum();
    let plants_s = plant_process_s - ground_station_s;
    let total_s = plants_s + autopilots_s;
    println!(
        "  CPU (user + system, % of one core): {:.1} % in all, {:.2} % per vehicle; plants {:.1} % ({:.2} % per \
         vehicle), autopilots {:.1} % ({:.2} % each on average, {:.2} % the most); the bench's ground station {:.1} % \
         on top",
        pct(total_s),
        pct(total_s) / count as f64,
        pct(plants_s),
        pct(plants_s) / count as f64,
        pct(autopilots_s),
        pct(autopilots_s) / count as f64,
        pct(autopilot_s.iter().copied().fold(0.0, f64::max)),
        pct(ground_station_s),
    );
    let own = std::process::id();
    let mut by_name: BTreeMap<(bool, String), f64> = BTreeMap::new();
    for (key, (name, after)) in &end.threads {
        let before = start.threads.get(key).map_or(0.0, |(_, s)| *s);
        *by_name.entry((key.0 == own, name.clone())).or_default() += after - before;
    }
    let threads = |plant: bool| {
        let mut rows: Vec<(&String, f64)> =
            by_name.iter().filter(|((p, _), _)| *p == plant).map(|((_, n), s)| (n, *s)).collect();
        rows.sort_by(|a, b| b.1.total_cmp(&a.1));
        rows.iter().map(|(n, s)| format!("{n} {:.1} %", pct(*s))).collect::<Vec<_>>().join(", ")
    };
    println!("  CPU by thread, plant process: {}", threads(true));
    println!("  CPU by thread name, all autopilots together: {}", threads(false));
    let heartbeat_ok = per_vehicle.iter().all(|s| s.is_some_and(|s| s.p99 <= HEARTBEAT_P99_LIMIT_S));
    let ack_ok = ack.is_some_and(|s| s.p99 <= ACK_P99_LIMIT_MS);
    let verdict = if heartbeat_ok && ack_ok { "PASS" } else { "FAIL" };
    println!(
        "{verdict}: {count} vehicles at real time: every vehicle's HEARTBEAT interval p99 <= {HEARTBEAT_P99_LIMIT_S} \
         s: {}; COMMAND_ACK p99 <= {ACK_P99_LIMIT_MS} ms: {} (over {:.0} s; `--realtime-s` for longer)",
        if heartbeat_ok { "held" } else { "not held" },
        if ack_ok { "held" } else { "not held" },
        args.realtime_s,
    );
    if verdict == "FAIL" {
        bail!("the swarm of {count} did not hold the targets");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_rank() {
        // GIVEN 1..=100 in any order THEN p50 is 50, p99 99, max 100.
        let values: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        assert_eq!(Summary::of(&values), Some(Summary { count: 100, p50: 50.0, p99: 99.0, max: 100.0 }));
        // A small sample: p99 is its largest value, p50 the lower middle one.
        let s = Summary::of(&[3.0, 1.0, 2.0, 4.0]).expect("a sample");
        assert_eq!((s.p50, s.p99, s.max), (2.0, 4.0, 4.0));
        assert_eq!(Summary::of(&[7.5]), Some(Summary { count: 1, p50: 7.5, p99: 7.5, max: 7.5 }));
        assert_eq!(Summary::of(&[]), None);
        // An unanswered command (infinity) counts as the slowest.
        let s = Summary::of(&[1.0, f64::INFINITY]).expect("a sample");
        assert_eq!((s.p50, s.p99), (1.0, f64::INFINITY));
    }

    #[test]
    fn a_summary_reads_with_its_unit() {
        let s = Summary::of(&[0.001, 0.002]);
        assert_eq!(describe(s, 1e3, "ms", 1), "p50 1.0, p99 2.0, max 2.0 ms (2 samples)");
        assert_eq!(describe(None, 1.0, "s", 3), "no samples");
    }

    #[test]
    fn the_bench_swarm_is_sitl_run_n() {
        let run = swarm_run_args(90, 32).expect("parses");
        assert_eq!((run.instance, run.count, run.state_dir.as_deref(), run.no_ulog), (90, 32, Some("off"), true));
        assert!(run.plant.pacing() == Pacing::RealTime { speed: 1.0 }, "real time");
    }
}

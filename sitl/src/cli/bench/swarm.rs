//! `sitl bench --vehicles N`: a swarm started as `sitl run -n N` starts it, measured at real time by a
//! ground station (HEARTBEAT intervals, COMMAND_ACK latency, CPU per process and thread) and judged PASS or
//! FAIL against the swarm's targets.

use std::collections::BTreeMap;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use autopilot::core::mavlink::command::command_long;
use autopilot::core::plant_link::{FrameDecoder, encode_frame_v2};
use autopilot::runtime::ports::InstancePorts;
use mavlink::MavHeader;
use mavlink::dialects::common::{MavCmd, MavMessage};
use sitl::launch::{self, AutopilotChild};

use super::{BenchArgs, Summary, describe};
use crate::cli::run::{RunArgs, start_swarm};

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

/// The `sitl run` options of the bench's swarm: `sitl run -n N -i FIRST` with no kept state, parsed by
/// the same command line, so the swarm is started exactly as `sitl run -n N` starts it.
fn swarm_run_args(first: u16, count: u16) -> Result<RunArgs> {
    let (first, count) = (first.to_string(), count.to_string());
    RunArgs::parse_options(["-n", &count, "-i", &first, "--state-dir", "off", "--no-ulog"])
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
pub(super) fn bench_swarm(args: &BenchArgs, count: u16) -> Result<()> {
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
        let swarm = launch::run_swarm(&mut servers, children, None, &halt, |t_us, _| {
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
    use sitl::link::Pacing;

    #[test]
    fn the_bench_swarm_is_sitl_run_n() {
        let run = swarm_run_args(90, 32).expect("parses");
        assert_eq!((run.instance, run.count, run.state_dir.as_deref(), run.no_ulog), (90, 32, Some("off"), true));
        assert!(run.plant.pacing() == Pacing::RealTime { speed: 1.0 }, "real time");
    }
}

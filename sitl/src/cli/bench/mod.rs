//! `sitl bench`: what the SITL costs and how it answers. One vehicle (the default): the two-process
//! real-time factor in lockstep, and the CPU and telemetry of a real-time run. `--vehicles N` (`swarm`): a
//! swarm of N started as `sitl run -n N` starts it, at real time, with a ground station on UDP 14550 that
//! measures, per vehicle, the wall-clock intervals between its HEARTBEATs and the latency of a COMMAND_ACK to
//! a COMMAND_LONG addressed to its system id, and the CPU of the plant process and of every autopilot (user
//! plus system, from `/proc`, per process and per thread); then PASS or FAIL against the swarm's targets:
//! every vehicle's HEARTBEAT interval p99 <= [`swarm::HEARTBEAT_P99_LIMIT_S`], COMMAND_ACK p99 <=
//! [`swarm::ACK_P99_LIMIT_MS`].

mod swarm;

use std::ffi::OsString;
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use autopilot::core::plant_link::FrameDecoder;
use autopilot::runtime::ports::InstancePorts;
use clap::Args;
use sitl::launch::{self, AutopilotChild, TempConfig};
use sitl::link::{LinkConfig, Pacing, PlantServer};
use sitl::plant::{InitialState, Plant};

use super::common::{bind_sim_params, duration_us, instance_ports, realistic_plant_config};
use swarm::bench_swarm;

#[derive(Args)]
pub(crate) struct BenchArgs {
    /// Instance N (ports as for `sitl run -i N`).
    #[arg(short = 'i', long, default_value_t = 90)]
    pub(crate) instance: u16,
    /// Simulated seconds of the lockstep run.
    #[arg(long, default_value_t = 120.0)]
    pub(crate) sim_s: f64,
    /// Wall seconds of the real-time run (0 skips it).
    #[arg(long, default_value_t = 10.0)]
    pub(crate) realtime_s: f64,
    /// Instead: a swarm of N at real time as `sitl run -n N -i <instance>` starts it, measured by a ground
    /// station on udp 14550 for --realtime-s: each vehicle's HEARTBEAT intervals and COMMAND_ACK latency,
    /// total CPU; PASS or FAIL against p99 1.2 s and 20 ms.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=255))]
    pub(crate) vehicles: Option<u16>,
    /// The autopilot's controller: any registered name (`sitl controllers`); default the autopilot's.
    #[arg(long)]
    pub(crate) controller: Option<ControllerKind>,
}

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
    controller: Option<ControllerKind>,
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
    server.set_sim_port(sim_params);
    let counter = TelemetryCounter::listen(qgc_port)?;
    let mut args: Vec<OsString> = vec![
        "--plant".into(),
        format!("udp://{listen}").into(),
        "-i".into(),
        n.to_string().into(),
        "--state-dir".into(),
        "off".into(),
    ];
    if let Some(kind) = controller {
        args.extend(["--controller".into(), kind.as_str().into()]);
    }
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
        let (r, messages, _) = bench_once(n, Pacing::Lockstep, args.sim_s, gcs, args.controller, &stop)?;
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
    let (r, messages, bytes) =
        bench_once(n, Pacing::RealTime { speed: 1.0 }, args.realtime_s, true, args.controller, &stop)?;
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
}

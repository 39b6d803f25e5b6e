//! `sitl bench`: what the two-process SITL costs. The real-time factor of the default `sitl run` plant and
//! autopilot in lockstep (with and without ground-station links), and the CPU and telemetry of a real-time
//! run.

use std::ffi::OsString;
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use autopilot::core::hil::FrameDecoder;
use autopilot::runtime::ports::InstancePorts;
use sitl::launch::{self, AutopilotChild, TempConfig};
use sitl::link::{LinkConfig, Pacing, PlantServer};
use sitl::plant::{InitialState, Plant};

use crate::{BenchArgs, bind_sim_params, duration_us, instance_ports, realistic_plant_config};

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

/// `sitl bench`: lockstep with and without ground-station links, then real time.
pub fn run(args: &BenchArgs) -> Result<()> {
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

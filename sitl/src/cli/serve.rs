//! `sitl serve`: the plant served to an autopilot over the HIL plant protocol, on UDP or a serial port.

use anyhow::{Context, Result, bail};
use autopilot::core::plant_link::budget::{LinkBudget, PlantStreams, parse_plant_rate, period_us};
use autopilot::runtime::transport::{POLL_INTERVAL, SerialTransport, parse_serial_spec};
use clap::Args;
use sitl::launch;
use sitl::link::{LinkConfig, Pacing, PlantServer, Transport, UdpTransport};
use std::time::Duration;

use super::common::{
    PlantArgs, bind_rc_in, bind_sim_params, describe_pacing, describe_rc_in, faults_summary, hawkeye_summary,
    instance_ports, radio_summary, realistic_plant_config,
};

#[derive(Args)]
pub(crate) struct ServeArgs {
    #[command(flatten)]
    pub(crate) plant: PlantArgs,
    /// Instance: the UDP port becomes 4560 + N, the SIM_ parameter port 19550 + N (system N + 1).
    #[arg(short = 'i', long, default_value_t = 0)]
    pub(crate) instance: u16,
    /// UDP address to listen on; the autopilot announces itself with any MAVLink message.
    #[arg(long)]
    pub(crate) listen: Option<String>,
    /// Serve over a serial port instead of UDP: `DEVICE:BAUD`, e.g. /dev/ttyUSB0:921600.
    #[arg(long)]
    pub(crate) serial: Option<String>,
    /// Plant step per sensor sample, µs (2000 = 500 Hz).
    #[arg(long, default_value_t = 2000, conflicts_with = "rate")]
    pub(crate) dt_us: u64,
    /// Sensor samples per second (the board's rate), one of 1000, 500, 400, 250, 200, 125, 100, 80, 50;
    /// the autopilot must run at the same rate (`autopilot --rate`). Default 500.
    #[arg(long, value_name = "HZ", value_parser = parse_plant_rate)]
    pub(crate) rate: Option<u32>,
    /// Over `--serial`, send the simulator's ground truth (HIL_STATE_QUATERNION) too, as over UDP; a real
    /// board never sends it, so by default the serial link carries none.
    #[arg(long, requires = "serial")]
    pub(crate) truth: bool,
    /// Time the link as the airframe's board does: a sample every period of wall time whether or not the
    /// autopilot has answered, each step on the newest command, motors to minimum after 100 ms without
    /// one (docs/board.md). Real time (or `--speed X`); not reproducible, unlike lockstep.
    #[arg(long, conflicts_with = "lockstep")]
    pub(crate) free_run: bool,
}

/// The pacing as the banner says it, and whether the plant runs free.
fn describe_timing(pacing: Pacing, free_run: bool) -> String {
    let paced = describe_pacing(pacing);
    if free_run { format!("{paced}, free-running as the board (sample every period, watchdog 100 ms)") } else { paced }
}

/// How long a free-running plant's receive waits at most: well below a step at the fastest rate (1 ms).
const FREE_RUN_POLL: Duration = Duration::from_millis(1);

/// Serve until stopped, free-running at `free_run_speed` or in lockstep; a free run reports how its
/// answers came.
fn serve_steps<T: Transport>(
    server: &mut PlantServer<T>,
    free_run_speed: Option<f64>,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<u64> {
    let Some(speed) = free_run_speed else { return Ok(server.run(None, stop)?) };
    let steps = server.run_free(speed, None, stop)?;
    let s = server.stats();
    eprintln!(
        "sitl: free run: {} samples sent ({} not taken by a full line), {} answers a step or more late, {} stale, \
         {} board watchdog trips",
        s.sensor_sent, s.send_timeouts, s.late_actuators, s.stale_actuators, s.watchdog_trips
    );
    Ok(steps)
}

pub(crate) fn serve(args: &ServeArgs) -> Result<()> {
    if args.listen.is_none() && args.serial.is_none() {
        launch::check_instance_free(args.instance, false)?;
    }
    args.plant.check_hawkeye(args.instance)?;
    let (plant, pacing) = args.plant.build(realistic_plant_config())?;
    let free_run_speed = match (args.free_run, pacing) {
        (false, _) => None,
        (true, Pacing::RealTime { speed }) => Some(speed),
        (true, Pacing::Lockstep) => bail!("--free-run runs on the wall clock: give it a --speed, not max"),
    };
    // A free-running plant must not sleep in a receive past its next step.
    let poll = if free_run_speed.is_some() { FREE_RUN_POLL } else { POLL_INTERVAL };
    if args.dt_us == 0 || args.dt_us > 20_000 {
        bail!("--dt-us must be in 1..=20000, got {}", args.dt_us);
    }
    let dt_us = args.rate.map_or(args.dt_us, period_us);
    let send_truth = args.serial.is_none() || args.truth;
    let link = LinkConfig { dt_us, pacing, send_truth, ..LinkConfig::default() };
    let rc_port = args.plant.rc_in_port(args.instance);
    let serial =
        args.serial.as_deref().map(parse_serial_spec).transpose().map_err(anyhow::Error::msg).context("--serial")?;
    if let Some((_, baud)) = &serial {
        // The link budget, checked before anything is opened: a stream that cannot fit the line is refused.
        let streams = PlantStreams {
            sample_rate_hz: 1e6 / dt_us as f64,
            gps_rate_hz: plant.config().sensors.gps.rate_hz,
            rc: rc_port.is_some(),
            battery: plant.battery().is_some(),
            truth: send_truth,
            odometry: false,
        };
        let budget = LinkBudget::of(&streams, *baud);
        for line in budget.lines() {
            eprintln!("sitl: {line}");
        }
        if let Some(line) = budget.refusal("--rate") {
            bail!("the plant stream does not fit the serial line: {line}");
        }
    }
    let stop = launch::ctrl_c_flag();
    let (sim_params, sim_port) = bind_sim_params(args.instance, &plant)?;
    let rc_in = bind_rc_in(rc_port)?;
    let hawkeye = args.plant.hawkeye_sender(args.instance, &plant)?;
    if let Some(h) = &hawkeye {
        eprintln!("sitl: the plant's truth to Hawkeye on udp {} (50 Hz of sim time)", h.destination());
    }
    let (steps, radio, faults, hawkeye_line) = if let Some((device, baud)) = serial {
        let transport = SerialTransport::open(&device, baud, poll).with_context(|| format!("opening {device}"))?;
        eprintln!(
            "sitl: plant on serial {device} at {baud} baud, running {}; SIM_ parameters on udp \
             127.0.0.1:{sim_port}; {}",
            describe_timing(pacing, free_run_speed.is_some()),
            describe_rc_in(rc_port)
        );
        let mut server = PlantServer::new(plant, transport, link);
        server.set_sim_port(sim_params);
        if let Some(port) = rc_in {
            server.set_rc_in(port);
        }
        if let Some(h) = hawkeye {
            server.set_hawkeye(h);
        }
        let steps = serve_steps(&mut server, free_run_speed, &stop)?;
        (steps, radio_summary(&server), faults_summary(&server.stats()), hawkeye_summary(&server))
    } else {
        let port = instance_ports(args.instance)?.0;
        let listen = args.listen.clone().unwrap_or_else(|| format!("127.0.0.1:{port}"));
        let transport = UdpTransport::bind(listen.as_str())
            .and_then(|t| t.with_poll(poll))
            .with_context(|| format!("binding {listen}"))?;
        let mut server = PlantServer::new(plant, transport, link);
        server.set_sim_port(sim_params);
        if let Some(port) = rc_in {
            server.set_rc_in(port);
        }
        if let Some(h) = hawkeye {
            server.set_hawkeye(h);
        }
        eprintln!(
            "sitl: plant listening on udp {listen}, running {}; SIM_ parameters on udp 127.0.0.1:{sim_port}; {}; \
             waiting for an autopilot",
            describe_timing(pacing, free_run_speed.is_some()),
            describe_rc_in(rc_port)
        );
        let steps = serve_steps(&mut server, free_run_speed, &stop)?;
        (steps, radio_summary(&server), faults_summary(&server.stats()), hawkeye_summary(&server))
    };
    eprintln!("sitl: {steps} steps served");
    for line in [radio, faults, hawkeye_line].into_iter().flatten() {
        eprintln!("{line}");
    }
    Ok(())
}

//! `sitl run`: the one-command SITL, the plant server plus the `autopilot` binary as a child process, or
//! a scenario flown through both (a swarm, `-n N`, is `swarm`).

use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::vehicle::Vehicle;
use autopilot::runtime::{ConfigFile, Overrides, RuntimeConfig};
use clap::Args;
use sitl::launch::{self, AutopilotChild};
use sitl::link::{LinkConfig, Pacing, PlantServer};
use sitl::progress::Progress;
use sitl::scenario::Scenario;
use sitl::scenario::two_process::{self, TwoProcessOptions};

use super::common::{
    PlantArgs, bind_rc_in, bind_sim_params, describe_pacing, describe_rc_in, duration_us, faults_summary, fmt_seconds,
    gust_track_lines, instance_ports, radio_summary, realistic_plant_config,
};
use super::swarm::run_swarm;

#[derive(Args)]
pub(crate) struct RunArgs {
    #[command(flatten)]
    pub(crate) plant: PlantArgs,
    /// Instance N (0..=254): plant on UDP 4560+N, autopilot on 18570+N and TCP 5760+N, telemetry to UDP
    /// 14550 (QGroundControl, every instance) and the API port 14540+N (14541+N from N = 10), system id
    /// N+1; the plant's SIM_ parameters (wind, gusts) on UDP 19550+N.
    #[arg(short = 'i', long, default_value_t = 0)]
    pub(crate) instance: u16,
    /// Autopilot estimator (fused, truth).
    #[arg(long, value_parser = ["fused", "truth"])]
    pub(crate) estimator: Option<String>,
    /// Autopilot controller (aco, ca, pid).
    #[arg(long)]
    pub(crate) controller: Option<ControllerKind>,
    /// Autopilot `.tlog` directory.
    #[arg(long)]
    pub(crate) log_dir: Option<PathBuf>,
    /// No onboard ULog flight log from the autopilot (by default one per armed flight, in the state
    /// directory's log/<date>/<time>.ulg).
    #[arg(long)]
    pub(crate) no_ulog: bool,
    /// Autopilot configuration file (TOML; see `autopilot --help`).
    #[arg(long, conflicts_with = "scenario")]
    pub(crate) autopilot_config: Option<PathBuf>,
    /// Where the autopilot keeps its parameters and mission across restarts, or `off` (default:
    /// ~/.local/state/aco-autopilot/iN; scenarios always run without).
    #[arg(long, conflicts_with = "scenario")]
    pub(crate) state_dir: Option<String>,
    /// Sensor samples per second, for the plant and the autopilot alike (`autopilot --rate`): one of
    /// 1000, 500, 400, 250, 200, 125, 100, 80, 50. Default 500.
    #[arg(long, value_name = "HZ", value_parser = autopilot::core::plant_link::budget::parse_plant_rate, conflicts_with = "scenario")]
    pub(crate) rate: Option<u32>,
    /// Stop after this many simulated seconds (default: run until Ctrl-C).
    #[arg(long)]
    pub(crate) duration: Option<f64>,
    /// Fly a scenario through both processes and report its metrics at the end: a hover (gust-hover,
    /// turbulence-hover) starting in the air as the in-process runner does, truth-fed; a track (figure8)
    /// as a mission from the ground, on the fused estimator. A scenario is a batch run: always as fast as
    /// possible (lockstep), whatever the default pacing.
    #[arg(long)]
    pub(crate) scenario: Option<String>,
    /// With --scenario: print the metrics as one JSON object.
    #[arg(long, requires = "scenario")]
    pub(crate) json: bool,
    /// A swarm of N vehicles in one command: instances -i .. -i+N-1 (system ids from -i+1), every one's
    /// telemetry to UDP 14550 and its own API port; the plants share this process and one clock, each
    /// autopilot is its own process.
    #[arg(short = 'n', long = "count", default_value_t = 1, value_name = "N", conflicts_with = "scenario",
          value_parser = clap::value_parser!(u16).range(1..=255))]
    pub(crate) count: u16,
    /// Swarm spawn grid spacing (m): vehicle k starts k-th on a square grid, rows north, columns east.
    #[arg(long, default_value_t = 3.0, value_name = "M")]
    pub(crate) spacing: f64,
    /// Start clean: the autopilot removes the instance's kept parameters, mission, fence and rally points
    /// before it starts (ArduPilot's `-w`; a signing key is kept).
    #[arg(long, conflicts_with = "scenario")]
    pub(crate) wipe: bool,
}

pub(crate) fn run(args: &RunArgs) -> Result<()> {
    if args.count > 1 {
        if args.plant.rc_in_port.is_some_and(|p| p != 0) {
            bail!("--rc-in-port is for one vehicle: a swarm's plants take no radio");
        }
        return run_swarm(args);
    }
    if args.scenario.is_some() && (args.plant.config.is_some() || args.plant.pacing_given() || args.duration.is_some())
    {
        bail!(
            "--scenario sets the plant, pacing (as fast as possible) and duration itself; drop --config, --speed, \
             --lockstep and --duration"
        );
    }
    let n = args.instance;
    let (plant_port, ap_port, qgc_port, api_port) = instance_ports(n)?;
    let autopilot = launch::autopilot_binary()?;
    // Everything the command line names is checked before anything starts: a busy instance, an autopilot
    // configuration the autopilot would refuse, a scenario that does not load.
    launch::check_instance_free(n, true)?;
    check_autopilot_config(args, n)?;
    let stop = launch::ctrl_c_flag();
    if let Some(name) = &args.scenario {
        // The scenario runner gives the autopilot its plant, instance and estimator itself.
        let mut ap_args: Vec<OsString> = Vec::new();
        if let Some(dir) = &args.log_dir {
            ap_args.extend(["--log-dir".into(), dir.into()]);
        }
        if args.no_ulog {
            ap_args.push("--no-ulog".into());
        }
        let scenario = Scenario::load(name)?;
        let controller =
            args.controller.unwrap_or_else(|| scenario.controllers.first().copied().unwrap_or(ControllerKind::Aco));
        let estimator = match args.estimator.as_deref() {
            None => None,
            Some("truth") => Some(EstimatorSource::Truth),
            Some("fused") => Some(EstimatorSource::Fused),
            Some(other) => bail!("--estimator must be fused or truth, got `{other}`"),
        };
        let opts = TwoProcessOptions {
            controller,
            plant: args.plant.preset.clone(),
            seed: args.plant.seed,
            instance: n,
            estimator,
            autopilot_args: ap_args,
            rc_in_port: args.plant.rc_in_port(n),
        };
        eprintln!(
            "sitl: instance {n}: flying scenario {} through plant and autopilot ({controller}), as fast as possible \
             (lockstep)",
            scenario.name
        );
        let m = two_process::run(&scenario, &opts, &autopilot, &stop)?;
        return print_two_process(&m, args.json);
    }

    let (plant, pacing) = args.plant.build(realistic_plant_config())?;
    let duration = duration_us(args.duration)?;
    let listen = format!("127.0.0.1:{plant_port}");
    let (sim_params, sim_port) = bind_sim_params(n, &plant)?;
    let rc_port = args.plant.rc_in_port(n);
    let rc_in = bind_rc_in(rc_port)?;
    let mut server = PlantServer::bind_udp(plant, listen.as_str(), run_link_config(args, pacing))
        .with_context(|| format!("binding {listen}"))?;
    server.set_hook(Box::new(sim_params));
    if let Some(port) = rc_in {
        server.set_rc_in(port);
    }
    let ap_args = autopilot_args(args, n, &listen, args.state_dir.as_ref().map(OsString::from));
    let child = AutopilotChild::spawn(&autopilot, &ap_args)?;
    eprintln!(
        "sitl: instance {n} running {}{}; plant on udp {listen}, SIM_ parameters on udp 127.0.0.1:{sim_port} \
         (system {}, component {}), {}, autopilot pid {} (system id {}) listening on udp {ap_port} and tcp {}; ground \
         stations: listen on udp {qgc_port} (QGroundControl) or {api_port} (MAVSDK/API), or send to \
         127.0.0.1:{ap_port}. Ctrl-C stops both.",
        describe_pacing(pacing),
        if args.plant.pacing_given() { "" } else { " (`--speed 4` or `--speed max` to run faster)" },
        u32::from(n) + 1,
        sitl::link::PLANT_COMPONENT_ID,
        describe_rc_in(rc_port),
        child.id(),
        u32::from(n) + 1,
        5760 + u32::from(n),
    );
    let mut progress = match duration {
        Some(us) => Progress::new(&format!("sitl: instance {n}"), us.div_ceil(1_000_000), "sim s"),
        None => Progress::hidden(0),
    };
    let report = launch::run_with_child(&mut server, child, duration, &stop, |plant, _| {
        progress.set(plant.time_us() / 1_000_000);
    });
    progress.finish();
    let report = report?;
    let l = &report.link;
    eprintln!(
        "sitl: {} steps, {:.1} sim s in {:.1} s wall ({:.1}x real time, {:.0} steps/s); plant link: {} resends, {} \
         stale replies, {} junk datagrams, {} malformed frames dropped",
        report.steps,
        report.sim_s,
        report.wall_s,
        report.realtime_factor(),
        report.steps as f64 / report.wall_s.max(1e-9),
        l.resends,
        l.stale_actuators,
        l.junk_datagrams,
        l.decoder.malformed(),
    );
    if let Some(line) = radio_summary(&server) {
        eprintln!("{line}");
    }
    if let Some(line) = faults_summary(l) {
        eprintln!("{line}");
    }
    Ok(())
}

pub(crate) fn print_two_process(m: &two_process::TwoProcessMetrics, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(m)?);
        return Ok(());
    }
    let mut line = format!(
        "{} {} {} seed {} (two processes, {} estimator)",
        m.scenario, m.controller, m.plant, m.seed, m.estimator
    );
    line += &gust_track_lines(m.gust.as_ref(), m.track.as_ref());
    if let Some((reached, total)) = m.items_reached {
        line += &format!("\n  mission: {reached} of {total} items reached");
    }
    if let Some(p) = m.pilot {
        line += &format!(
            "\n  pilot: armed at {}, disarmed at {}, climbed {:.2} m at most",
            fmt_seconds(p.armed_at_s),
            fmt_seconds(p.disarmed_at_s),
            p.max_climb_m
        );
    }
    line += &format!(
        "\n  non-finite: {}  pwm activity {:.2} us/tick  {:.1} sim s in {:.2} s wall ({:.0}x real time)",
        m.non_finite, m.pwm_activity_us, m.sim_s, m.wall_s, m.realtime_factor
    );
    println!("{line}");
    Ok(())
}

/// Checks `--autopilot-config` as the autopilot of instance `n` would (parsed, resolved and a vehicle
/// built from it) before anything starts.
pub(crate) fn check_autopilot_config(args: &RunArgs, n: u16) -> Result<()> {
    let Some(path) = &args.autopilot_config else { return Ok(()) };
    let file = ConfigFile::load(path)?;
    let config = RuntimeConfig::resolve(file, n, Overrides::default())
        .with_context(|| format!("autopilot configuration {}", path.display()))?;
    Vehicle::new(config.vehicle).with_context(|| format!("autopilot configuration {}", path.display()))?;
    Ok(())
}

/// The plant link of `sitl run` at `pacing`: the autopilot has 30 s to connect; the truth estimator gets
/// ODOMETRY too.
pub(crate) fn run_link_config(args: &RunArgs, pacing: Pacing) -> LinkConfig {
    LinkConfig {
        dt_us: args.rate.map_or(LinkConfig::default().dt_us, autopilot::core::plant_link::budget::period_us),
        pacing,
        connect_timeout: Some(Duration::from_secs(30)),
        truth_odometry: args.estimator.as_deref() == Some("truth"),
        ..LinkConfig::default()
    }
}

/// The `autopilot` command line of instance `n` with its plant on `listen`, from `sitl run`'s options, and
/// `state_dir` when one is to be passed.
pub(crate) fn autopilot_args(args: &RunArgs, n: u16, listen: &str, state_dir: Option<OsString>) -> Vec<OsString> {
    let mut ap_args: Vec<OsString> = vec!["--plant".into(), format!("udp://{listen}").into()];
    ap_args.extend(["-i".into(), n.to_string().into()]);
    if let Some(estimator) = &args.estimator {
        ap_args.extend(["--estimator".into(), estimator.into()]);
    }
    if let Some(controller) = args.controller {
        ap_args.extend(["--controller".into(), controller.to_string().into()]);
    }
    if let Some(rate_hz) = args.rate {
        ap_args.extend(["--rate".into(), rate_hz.to_string().into()]);
    }
    if let Some(path) = &args.autopilot_config {
        ap_args.extend(["--config".into(), path.into()]);
    }
    if let Some(dir) = &args.log_dir {
        ap_args.extend(["--log-dir".into(), dir.into()]);
    }
    if let Some(dir) = state_dir {
        ap_args.extend(["--state-dir".into(), dir]);
    }
    if args.no_ulog {
        ap_args.push("--no-ulog".into());
    }
    if args.wipe {
        ap_args.push("--wipe".into());
    }
    ap_args
}

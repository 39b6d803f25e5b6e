//! The options of `sitl run` ([`RunArgs`]) and what the single run and the swarm both make of them: the
//! autopilot configuration checked, the plant link's timing and the `autopilot` command line.

use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use autopilot::core::control::ControllerKind;
use autopilot::core::vehicle::Vehicle;
use autopilot::runtime::{ConfigFile, Overrides, RuntimeConfig};
use clap::{Args, Parser};
use sitl::link::{LinkConfig, Pacing};

use crate::cli::common::PlantArgs;

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
    /// Autopilot controller: any registered name (`sitl controllers` lists them).
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
    #[command(flatten)]
    pub(crate) view: crate::cli::view::ViewArgs,
}

/// `sitl run` alone, to parse its options outside the whole command line (the bench's swarm).
#[derive(Parser)]
#[command(name = "sitl run")]
struct RunCommand {
    #[command(flatten)]
    args: RunArgs,
}

impl RunArgs {
    /// The options of `sitl run OPTIONS...`, parsed as the command line parses them.
    ///
    /// # Errors
    /// clap's error for options `sitl run` refuses.
    pub(crate) fn parse_options<'a>(options: impl IntoIterator<Item = &'a str>) -> Result<Self> {
        Ok(RunCommand::try_parse_from(std::iter::once("sitl run").chain(options))?.args)
    }
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

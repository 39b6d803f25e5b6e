//! `autopilot`: the ACO quadrotor autopilot process. Attaches to a plant over the HIL plant protocol (UDP
//! to the SITL plant, or serial to the real airframe's ARM board) and serves ground stations over UDP, TCP
//! and optionally serial (instance `-i N`: default ports shifted by N, system id N+1). Configuration: a
//! TOML file (`--config`, see `runtime::config`), overridden by the options below; logs with `RUST_LOG`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::plant_link::budget;
use autopilot::runtime::{self, ConfigFile, Overrides, RuntimeConfig};
use clap::{Parser, ValueEnum};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Estimator {
    /// The sensor-fusion filter.
    Fused,
    /// The plant's ground truth (the paper's truth-fed runs).
    Truth,
}

#[derive(Parser)]
#[command(name = "autopilot", version, about = "ACO quadrotor autopilot (MAVLink, HIL plant protocol)")]
struct Cli {
    /// Configuration file (TOML: [plant], [gcs], [log], [state], [vehicle]).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Plant link: `udp://HOST:PORT` (default udp://127.0.0.1:4560+N) or `serial:DEVICE:BAUD`.
    #[arg(long)]
    plant: Option<String>,
    /// Instance N (0..=254): plant udp 4560+N, own UDP 18570+N and TCP 5760+N, telemetry to UDP 14550
    /// (shared by every instance, as PX4's) and the API port 14540+N (14541+N from N = 10); system id N+1.
    #[arg(short = 'i', long, default_value_t = 0)]
    instance: u16,
    #[arg(long, value_enum)]
    estimator: Option<Estimator>,
    /// Controller: any registered name (`sitl controllers` lists them).
    #[arg(long)]
    controller: Option<ControllerKind>,
    /// Directory for `.tlog` logs of the ground-station traffic (none if omitted).
    #[arg(long)]
    log_dir: Option<PathBuf>,
    /// No onboard ULog flight log (by default one per armed flight in <state dir>/log/<date>/<time>.ulg,
    /// or in --log-dir when the state directory is off; the SDLOG_MODE parameter = -1 also turns it off).
    #[arg(long)]
    no_ulog: bool,
    /// Directory where parameters and the mission persist across restarts, or `off` (default:
    /// ~/.local/state/aco-autopilot/iN).
    #[arg(long)]
    state_dir: Option<String>,
    /// MAVLink 2 signing on from the start, with the key in this file (64 hex digits): every frame to
    /// ground stations signed, unsigned and wrongly signed ones dropped.
    #[arg(long)]
    signing_key_file: Option<PathBuf>,
    /// Start clean: remove the instance's kept parameters, mission, fence and rally points from the state
    /// directory first (ArduPilot's `-w`). A signing key is kept.
    #[arg(long)]
    wipe: bool,
    /// The plant's sample rate (Hz): LOOP_INNER_HZ, with LOOP_POS_HZ the largest divisor of it up to
    /// 100 Hz (250 -> 50), over the kept parameters. On a serial plant link the link budget at this rate
    /// is printed at start, and a rate that does not fit the line is refused, naming one that does.
    #[arg(long, value_name = "HZ", value_parser = budget::parse_plant_rate)]
    rate: Option<u32>,
    /// Stop when standard input closes (how `sitl run` keeps its autopilot from outliving it).
    #[arg(long, hide = true)]
    stop_on_stdin_eof: bool,
    /// Send the view stream (the estimate, setpoints, motors, battery, mode, controller telemetry, plan
    /// and STATUSTEXTs, as JSON datagrams at 50 Hz of vehicle time) to this UDP address; `sitl run
    /// --view` sets it (docs/view.md).
    #[arg(long, value_name = "ADDR")]
    view_udp: Option<std::net::SocketAddr>,
}

fn main() -> ExitCode {
    autopilot::cli::init_logging();
    let cli = Cli::parse();
    let instance = cli.instance;
    let result = run(cli).map_err(|err| {
        if autopilot::cli::address_in_use(err.as_ref()) {
            let next = instance.saturating_add(1);
            err.context(format!(
                "instance {instance} is in use (another autopilot or SITL holds its port); try -i {next}"
            ))
        } else {
            err
        }
    });
    autopilot::cli::exit("autopilot", result)
}

fn run(cli: Cli) -> Result<()> {
    // A controller name registered twice is refused before anything runs.
    autopilot::core::control::registry::check()?;
    let file = match &cli.config {
        Some(path) => ConfigFile::load(path)?,
        None => ConfigFile::default(),
    };
    let overrides = Overrides {
        plant: cli.plant,
        log_dir: cli.log_dir,
        no_ulog: cli.no_ulog,
        stop_on_stdin_eof: cli.stop_on_stdin_eof,
        state_dir: cli.state_dir,
        signing_key_file: cli.signing_key_file,
    };
    let mut config = RuntimeConfig::resolve(file, cli.instance, overrides)?;
    config.view_udp = cli.view_udp;
    if let Some(e) = cli.estimator {
        config.vehicle.estimator.source = match e {
            Estimator::Fused => EstimatorSource::Fused,
            Estimator::Truth => EstimatorSource::Truth,
        };
    }
    if let Some(c) = cli.controller {
        config.vehicle.controller = c;
    }
    config.plant_rate_hz = cli.rate;
    if cli.wipe {
        let Some(dir) = &config.state_dir else {
            bail!("--wipe clears the state directory, and this start has none (--state-dir off)");
        };
        let removed = runtime::wipe_state(dir).with_context(|| format!("wiping {}", dir.display()))?;
        let names: Vec<String> =
            removed.iter().filter_map(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned()).collect();
        tracing::info!(
            "wiped {}: {} (a signing key, if any, is kept)",
            dir.display(),
            if names.is_empty() { "nothing was kept".to_owned() } else { format!("removed {}", names.join(", ")) }
        );
    }
    // One thread for the tokio links: the vehicle runs on the plant link's own thread, and the links only
    // carry telemetry.
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("starting tokio")?;
    let stats = rt.block_on(runtime::run(config))?;
    if let (Some(first), Some(last)) = (stats.first_time_us, stats.last_time_us) {
        tracing::info!(
            steps = stats.steps,
            sim_s = (last - first) as f64 * 1e-6,
            plant_losses = stats.plant_losses,
            plant_malformed = stats.plant_decoder.malformed(),
            plant_missing_samples = stats.plant_missing_samples,
            plant_late_samples = stats.plant_late_samples,
            plant_rx_bytes = stats.plant_rx_bytes,
            plant_tx_bytes = stats.plant_tx_bytes,
            gcs_dropped = stats.gcs_dropped,
            statustext_suppressed = stats.statustext_suppressed,
            ulog_flights = stats.ulog_flights,
            ulog_dropped = stats.ulog_dropped,
            "autopilot stopped"
        );
    }
    Ok(())
}

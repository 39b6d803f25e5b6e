//! `autopilot`: the ACO quadrotor autopilot process. Connects to a plant over the HIL plant protocol and
//! serves ground stations over UDP (instance `-i N`: ports shifted by N, system id N+1).

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::runtime::{self, RuntimeConfig};
use clap::{Parser, ValueEnum};

/// Default plant UDP port (instance 0).
const PLANT_PORT: u16 = 4560;

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
    /// Plant address: `udp://HOST:PORT` (default udp://127.0.0.1:4560+N). Serial is not supported yet.
    #[arg(long)]
    plant: Option<String>,
    /// Instance N: shifts the plant port 4560 (if --plant is not given), 18570, 14550 and 14540 by N;
    /// system id N+1.
    #[arg(short = 'i', long, default_value_t = 0)]
    instance: u16,
    #[arg(long, value_enum, default_value = "fused")]
    estimator: Estimator,
    /// Controller: aco, ca or pid.
    #[arg(long, default_value = "aco")]
    controller: ControllerKind,
    /// Directory for `.tlog` flight logs (none if omitted).
    #[arg(long)]
    log_dir: Option<PathBuf>,
}

fn plant_addr(spec: Option<&str>, instance: u16) -> Result<SocketAddr> {
    let Some(spec) = spec else {
        let port = PLANT_PORT.checked_add(instance).context("instance too large for the plant port")?;
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    };
    if let Some(hostport) = spec.strip_prefix("udp://") {
        return hostport
            .to_socket_addrs()
            .with_context(|| format!("resolving plant address `{hostport}`"))?
            .next()
            .with_context(|| format!("plant address `{hostport}` resolves to nothing"));
    }
    if spec.starts_with("serial:") {
        bail!("--plant serial:... is not supported yet; use udp://HOST:PORT");
    }
    bail!("--plant must be udp://HOST:PORT, got `{spec}`")
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let config = RuntimeConfig {
        plant: plant_addr(cli.plant.as_deref(), cli.instance)?,
        instance: cli.instance,
        estimator: match cli.estimator {
            Estimator::Fused => EstimatorSource::Fused,
            Estimator::Truth => EstimatorSource::Truth,
        },
        controller: cli.controller,
        log_dir: cli.log_dir,
    };
    // One thread: the lockstep plant link is latency-bound, and cross-thread wake-ups cost ~30 % of the
    // real-time factor (measured with sitl's e2e flight: ~31x vs ~24x real time).
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().context("starting tokio")?;
    let stats = rt.block_on(runtime::run(config))?;
    if let (Some(first), Some(last)) = (stats.first_time_us, stats.last_time_us) {
        tracing::info!(steps = stats.steps, sim_s = (last - first) as f64 * 1e-6, "autopilot stopped");
    }
    Ok(())
}

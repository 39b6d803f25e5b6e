//! The tokio shell around the sans-I/O core: it only moves bytes. In: datagrams and streams from ground
//! stations; out to the core: [`link::Incoming`] messages on an mpsc channel; back from the core:
//! [`link::Outgoing`] messages fanned out to every ground station or addressed to one. Also the `.tlog`
//! writer and the shutdown signal every task selects on.
//!
//! Nothing here decides anything about the vehicle; see `DESIGN.md`, "The one idea".

pub mod frame;
pub mod link;
pub mod plant_link;
pub mod shutdown;
pub mod tcp;
pub mod tlog;
pub mod udp;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc;

use crate::core::control::ControllerKind;
use crate::core::estimator::EstimatorSource;
use crate::core::vehicle::VehicleConfig;
use link::{CHANNEL_CAPACITY, LinkError};
use plant_link::{PlantLinkConfig, PlantLinkError, PlantLinkStats, TlogFrame};
use tlog::{TlogError, TlogWriter};
use udp::{UdpConfig, UdpLink};

/// Frames the tlog task may lag behind before frames are dropped (and counted).
const TLOG_CHANNEL_CAPACITY: usize = 8192;

/// Everything the autopilot process is started with.
#[derive(Debug, Clone)]
pub struct RuntimeConfig {
    /// The plant's UDP address (127.0.0.1:4560+N).
    pub plant: SocketAddr,
    /// Instance N: ground-station ports shift by N, system id N+1.
    pub instance: u16,
    pub estimator: EstimatorSource,
    pub controller: ControllerKind,
    /// Where `.tlog` files go; `None`: no log.
    pub log_dir: Option<PathBuf>,
}

/// Why the runtime stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    #[error("instance {instance} is too large: the system id N+1 must fit 1..=255")]
    Instance { instance: u16 },
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Plant(#[from] PlantLinkError),
    #[error(transparent)]
    Tlog(#[from] TlogError),
    #[error("cannot create log directory {path}: {source}")]
    LogDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot listen for Ctrl-C: {0}")]
    Signal(#[source] std::io::Error),
    #[error("a runtime task panicked or was cancelled: {0}")]
    Join(#[from] tokio::task::JoinError),
}

/// The vehicle configuration of `config`.
///
/// # Errors
/// [`RuntimeError::Instance`] if the system id N+1 does not fit a byte.
pub fn vehicle_config(config: &RuntimeConfig) -> Result<VehicleConfig, RuntimeError> {
    let sysid = u8::try_from(config.instance + 1)
        .ok()
        .filter(|_| config.instance < 255)
        .ok_or(RuntimeError::Instance { instance: config.instance })?;
    let mut vehicle = VehicleConfig { sysid, controller: config.controller, ..VehicleConfig::default() };
    vehicle.estimator.source = config.estimator;
    Ok(vehicle)
}

fn wall_us() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// Write every frame that arrives until the channel closes, then close the log (`.tlog.tmp` -> `.tlog`).
async fn tlog_task(mut writer: TlogWriter, mut frames: mpsc::Receiver<TlogFrame>) -> Result<PathBuf, TlogError> {
    while let Some(frame) = frames.recv().await {
        writer.write_frame(wall_us(), &frame)?;
    }
    let records = writer.records();
    let path = tokio::task::spawn_blocking(move || writer.close())
        .await
        .unwrap_or_else(|e| Err(TlogError::Write { path: PathBuf::new(), source: std::io::Error::other(e) }))?;
    tracing::info!(path = %path.display(), records, "tlog closed");
    Ok(path)
}

/// Run the autopilot until Ctrl-C (or a task fails): the ground-station UDP link on the instance's ports,
/// the plant link driving the vehicle, and the `.tlog` writer; every task is stopped and awaited.
///
/// # Errors
/// The first task error ([`RuntimeError`]); the other tasks are still shut down.
pub async fn run(config: RuntimeConfig) -> Result<PlantLinkStats, RuntimeError> {
    let vehicle = vehicle_config(&config)?;
    let (trigger, shutdown) = shutdown::channel();
    let udp = UdpLink::bind(UdpConfig::for_instance(config.instance)).await?;
    tracing::info!(
        local = %udp.local_addr(),
        plant = %config.plant,
        sysid = vehicle.sysid,
        "autopilot up"
    );
    let (tlog_tx, tlog_task) = match &config.log_dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|source| RuntimeError::LogDir { path: dir.clone(), source })?;
            let name = format!("{}_i{}", wall_us() / 1_000_000, config.instance);
            let writer = TlogWriter::create(dir, &name)?;
            tracing::info!(path = %writer.temp_path().display(), "tlog open");
            let (tx, rx) = mpsc::channel(TLOG_CHANNEL_CAPACITY);
            (Some(tx), Some(tokio::spawn(tlog_task(writer, rx))))
        }
        None => (None, None),
    };
    let (in_tx, in_rx) = mpsc::channel(CHANNEL_CAPACITY);
    let (out_tx, out_rx) = mpsc::channel(CHANNEL_CAPACITY);
    let mut udp_task = tokio::spawn(udp.run(in_tx, out_rx, shutdown.clone()));
    let plant_config = PlantLinkConfig { plant: config.plant, vehicle };
    let mut plant_task = tokio::spawn(plant_link::run(plant_config, in_rx, out_tx, tlog_tx, shutdown.clone()));

    let mut first_error: Option<RuntimeError> = None;
    let mut udp_done = None;
    let mut plant_done = None;
    tokio::select! {
        signal = tokio::signal::ctrl_c() => {
            if let Err(e) = signal {
                first_error = Some(RuntimeError::Signal(e));
            }
            tracing::info!("shutting down");
        }
        r = &mut udp_task => udp_done = Some(r),
        r = &mut plant_task => plant_done = Some(r),
    }
    trigger.fire();
    let udp_result = match udp_done {
        Some(r) => r,
        None => udp_task.await,
    };
    let plant_result = match plant_done {
        Some(r) => r,
        None => plant_task.await,
    };
    let mut stats = PlantLinkStats::default();
    match plant_result {
        Ok(Ok(s)) => stats = s,
        Ok(Err(e)) => {
            first_error.get_or_insert(e.into());
        }
        Err(e) => {
            first_error.get_or_insert(e.into());
        }
    }
    match udp_result {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            first_error.get_or_insert(e.into());
        }
        Err(e) => {
            first_error.get_or_insert(e.into());
        }
    }
    // The plant task has dropped its tlog sender: the tlog task drains and closes.
    if let Some(task) = tlog_task {
        match task.await {
            Ok(Ok(_)) => {}
            Ok(Err(e)) => {
                first_error.get_or_insert(e.into());
            }
            Err(e) => {
                first_error.get_or_insert(e.into());
            }
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(stats),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(instance: u16) -> RuntimeConfig {
        RuntimeConfig {
            plant: SocketAddr::from(([127, 0, 0, 1], 4560 + instance)),
            instance,
            estimator: EstimatorSource::Truth,
            controller: ControllerKind::Pid,
            log_dir: None,
        }
    }

    #[test]
    fn instance_n_is_system_id_n_plus_one_and_too_large_is_refused() {
        let v = vehicle_config(&config(3)).expect("valid");
        assert_eq!((v.sysid, v.controller, v.estimator.source), (4, ControllerKind::Pid, EstimatorSource::Truth));
        assert_eq!(vehicle_config(&config(254)).expect("valid").sysid, 255);
        assert!(matches!(vehicle_config(&config(255)), Err(RuntimeError::Instance { instance: 255 })));
    }
}

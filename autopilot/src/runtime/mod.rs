//! The tokio shell around the sans-I/O core: it only moves bytes. In: datagrams and streams from ground
//! stations (UDP, TCP, serial links, each a tokio task); out to the core: [`link::Incoming`] messages on
//! one mpsc channel; back from the core: [`link::Outgoing`] messages to every link, or to the peer of one
//! link that a reply answers. The core itself runs on the plant link's own thread
//! ([`plant_link`], blocking I/O: the lockstep round trip is latency-bound). Also the configuration
//! ([`config`]), the state directory ([`state`], written through [`persist`]), the `.tlog` writer, the
//! onboard ULog flight log ([`flight_log`], encoded by [`ulog`]) and the shutdown signal every task
//! selects on ([`shutdown`]). This module starts them all and stops them all ([`run`]).
//!
//! Nothing here decides anything about the vehicle; see `docs/design.md`, the sans-I/O core.

pub mod config;
pub mod flight_log;
pub mod frame;
pub mod gcs_fanout;
pub mod link;
pub mod persist;
pub mod plant_link;
pub mod ports;
pub mod serial;
pub mod shutdown;
pub mod signing;
pub mod state;
pub mod tcp;
pub mod tlog;
pub mod transport;
pub mod udp;
pub mod ulog;
pub mod utc;
pub mod vehicle_host;
pub mod view;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc;
use tokio::task::JoinSet;

pub use config::{ConfigError, ConfigFile, Overrides, PlantEndpoint, RuntimeConfig};
use link::{CHANNEL_CAPACITY, LinkError};
use persist::PersistError;
use plant_link::{GcsOutputs, PlantLinkError, PlantLinkStats, TlogFrame};
use state::{Persisted, load_state};
pub use state::{STATE_FILES, wipe_state};

use serial::{SerialConfig, SerialLink};
use tcp::TcpLink;
use tlog::{TlogError, TlogWriter};
use transport::{SerialTransport, Transport, UdpPeerTransport};
use udp::UdpLink;

use crate::core::plant_link::budget;
use crate::core::vehicle::Vehicle;

/// Frames the tlog task may lag behind before frames are dropped (and counted).
const TLOG_CHANNEL_CAPACITY: usize = 8192;

/// Why the runtime stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Plant(#[from] PlantLinkError),
    #[error(transparent)]
    Tlog(#[from] TlogError),
    #[error(transparent)]
    Persist(#[from] PersistError),
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
    #[error("MAVLink signing key file {0}")]
    Signing(String),
    /// The plant stream does not fit the serial line (the one line of `LinkBudget::refusal`).
    #[error("the plant link does not fit its line: {0}")]
    LinkBudget(String),
    #[error("cannot open the view stream to {to}: {source}")]
    View {
        to: std::net::SocketAddr,
        #[source]
        source: std::io::Error,
    },
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

/// The plant link's transport.
fn open_plant(endpoint: &PlantEndpoint) -> Result<Box<dyn Transport + Send>, PlantLinkError> {
    let open = |source| PlantLinkError::Open { link: endpoint.to_string(), source };
    Ok(match endpoint {
        PlantEndpoint::Udp(addr) => Box::new(UdpPeerTransport::connect(*addr, transport::POLL_INTERVAL).map_err(open)?),
        PlantEndpoint::Serial { path, baud } => {
            Box::new(SerialTransport::open(path, *baud, transport::POLL_INTERVAL).map_err(open)?)
        }
    })
}

/// `--rate`: the plant's sample rate over the kept parameters too, as a PARAM_SET of LOOP_INNER_HZ and
/// LOOP_POS_HZ would set them (`run` has set them in the vehicle config).
fn set_plant_rate(persisted: &mut Persisted, config: &RuntimeConfig) {
    let rates = config.vehicle.control.rates;
    if let Some(store) = &mut persisted.params {
        for (name, value) in [("LOOP_INNER_HZ", rates.inner_hz), ("LOOP_POS_HZ", rates.position_hz)] {
            if let Err(e) = store.set(name, value as f32) {
                tracing::warn!("--rate: {name} = {value}: {e}");
            }
        }
    }
}

/// On a serial plant link, print the link budget at the vehicle's sample rate (LOOP_INNER_HZ, after the
/// kept parameters) and refuse a stream that does not fit, naming the rate that does.
fn check_link_budget(config: &RuntimeConfig, persisted: &Persisted) -> Result<(), RuntimeError> {
    let PlantEndpoint::Serial { baud, .. } = &config.plant else { return Ok(()) };
    let mut vehicle = config.vehicle.clone();
    if let Some(store) = &persisted.params {
        store.apply(&mut vehicle);
    }
    let truth = vehicle.estimator.source == crate::core::estimator::EstimatorSource::Truth;
    let streams =
        budget::PlantStreams { truth, ..budget::PlantStreams::board(f64::from(vehicle.control.rates.inner_hz)) };
    let budget = budget::LinkBudget::of(&streams, *baud);
    for line in budget.lines() {
        tracing::info!("{line}");
    }
    match budget.refusal("--rate") {
        Some(line) => Err(RuntimeError::LinkBudget(line)),
        None => Ok(()),
    }
}

/// The signing state at start: on with the key of `--signing-key-file` (an unreadable or malformed file
/// stops the start: the user asked for signing), else with the key kept in the state directory (a
/// malformed one is moved aside), else off.
fn start_signing(config: &RuntimeConfig) -> Result<signing::LinkSigning, RuntimeError> {
    let link_signing = signing::LinkSigning::new(config.state_dir.clone());
    if let Some(path) = &config.signing_key_file {
        let text =
            std::fs::read_to_string(path).map_err(|e| RuntimeError::Signing(format!("{}: {e}", path.display())))?;
        let (key, ts) =
            signing::parse_key_file(&text).map_err(|e| RuntimeError::Signing(format!("{}: {e}", path.display())))?;
        link_signing.enable(key, ts);
        tracing::info!(file = %path.display(), "MAVLink signing on (key file)");
        return Ok(link_signing);
    }
    let Some(dir) = &config.state_dir else { return Ok(link_signing) };
    match persist::load(dir, signing::KEY_FILE) {
        Ok(Some(text)) => match signing::parse_key_file(&text) {
            Ok((key, ts)) => {
                link_signing.enable(key, ts);
                tracing::info!(file = %dir.join(signing::KEY_FILE).display(), "MAVLink signing on (kept key)");
            }
            Err(e) => {
                let _ = persist::move_aside(dir, signing::KEY_FILE);
                tracing::warn!(file = %dir.join(signing::KEY_FILE).display(), "{e}: moved aside, signing off");
            }
        },
        Ok(None) => {}
        Err(e) => tracing::warn!("{e}: signing off"),
    }
    Ok(link_signing)
}

/// Run the autopilot until Ctrl-C (or, with `stop_on_stdin_eof`, until standard input closes, or until a
/// task fails): the ground-station links (UDP, TCP, serial), the plant link driving the vehicle on a
/// thread of its own, and the `.tlog` writer; every task is stopped and awaited.
///
/// # Errors
/// The first error ([`RuntimeError`]); the other tasks are still shut down.
pub async fn run(mut config: RuntimeConfig) -> Result<PlantLinkStats, RuntimeError> {
    if let Some(rate_hz) = config.plant_rate_hz {
        config.vehicle.control.rates.inner_hz = rate_hz;
        config.vehicle.control.rates.position_hz = budget::position_rate_hz(rate_hz);
    }
    // Refuse a bad vehicle configuration before opening anything.
    Vehicle::new(config.vehicle.clone()).map_err(PlantLinkError::from)?;
    let (trigger, shutdown) = shutdown::channel();
    let (in_tx, in_rx) = mpsc::channel(CHANNEL_CAPACITY);
    let mut links = JoinSet::new();
    let mut out_links = Vec::new();
    let mut counters = Vec::new();

    let signing = Arc::new(start_signing(&config)?);
    // Which links may carry SETUP_SIGNING: TCP and serial (a cable or a connection the user made), not UDP
    // unless the configuration marks it secure (`[gcs] udp_secure`, for a network the user trusts).
    let mut secure = vec![config.udp.secure];
    if config.udp.secure {
        tracing::warn!("UDP link marked secure: a SETUP_SIGNING over UDP will be accepted");
    }
    let udp = UdpLink::bind(config.udp.clone()).await?.with_signing(signing.clone());
    counters.push(udp.counters());
    let (tx, rx) = mpsc::channel(CHANNEL_CAPACITY);
    out_links.push(tx);
    tracing::info!(local = %udp.local_addr(), sysid = config.vehicle.sysid, "autopilot up");
    links.spawn(udp.run(in_tx.clone(), rx, shutdown.clone()));
    if let Some(tcp) = &config.tcp {
        let tcp = TcpLink::bind(tcp.clone()).await?.with_signing(signing.clone());
        secure.push(true);
        counters.push(tcp.counters());
        let (tx, rx) = mpsc::channel(CHANNEL_CAPACITY);
        out_links.push(tx);
        links.spawn(tcp.run(in_tx.clone(), rx, shutdown.clone()));
    }
    if let Some((path, baud)) = &config.serial {
        let serial = SerialLink::open(&SerialConfig {
            link: out_links.len(),
            path: path.clone(),
            baud: *baud,
            data_rate: config.serial_data_rate,
        })?
        .with_signing(signing.clone());
        secure.push(true);
        counters.push(serial.counters());
        let (tx, rx) = mpsc::channel(CHANNEL_CAPACITY);
        out_links.push(tx);
        links.spawn(serial.run(in_tx.clone(), rx, shutdown.clone()));
    }
    drop(in_tx);

    let (tlog_tx, tlog_task) = match &config.log_dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|source| RuntimeError::LogDir { path: dir.clone(), source })?;
            // UTC date and time, so that the names sort in the order of the runs.
            let started = utc::UtcTime::from_unix_us(wall_us());
            let name = format!("{}_{}_i{}", started.date(), started.time('-'), config.instance);
            let writer = TlogWriter::create(dir, &name)?;
            tracing::info!(path = %writer.temp_path().display(), "tlog open");
            let (tx, rx) = mpsc::channel(TLOG_CHANNEL_CAPACITY);
            (Some(tx), Some(tokio::spawn(tlog_task(writer, rx))))
        }
        None => (None, None),
    };

    let mut persisted = match &config.state_dir {
        Some(dir) => load_state(dir, &config.vehicle)?,
        None => Persisted::default(),
    };
    if config.plant_rate_hz.is_some() {
        set_plant_rate(&mut persisted, &config);
    }
    check_link_budget(&config, &persisted)?;
    let mut plant = open_plant(&config.plant)?;
    tracing::info!(plant = %config.plant, "plant link open");
    let stop = Arc::new(AtomicBool::new(false));
    let plant_stop = stop.clone();
    let vehicle = config.vehicle.clone();
    let (flight_log, ulog_task) = match &config.ulog_dir {
        Some(dir) => {
            let (tx, rx) = mpsc::channel(flight_log::ULOG_CHANNEL_CAPACITY);
            tracing::info!(dir = %dir.display(), "a ULog flight log for every armed flight");
            let logger = flight_log::FlightLogger::new(Some(tx), dir.clone(), config.vehicle.sysid);
            (logger, Some(flight_log::spawn_writer(rx)))
        }
        None => (flight_log::FlightLogger::off(), None),
    };
    let view = match config.view_udp {
        Some(to) => {
            tracing::info!(%to, "the view stream goes to udp {to}");
            view::ViewTap::to(to, config.instance).map_err(|source| RuntimeError::View { to, source })?
        }
        None => view::ViewTap::off(),
    };
    let outputs =
        GcsOutputs { links: out_links, tlog: tlog_tx, counters, signing: signing.clone(), secure, flight_log, view };
    let mut plant_task = tokio::task::spawn_blocking(move || {
        plant_link::run(plant.as_mut(), vehicle, persisted, in_rx, outputs, &plant_stop)
    });

    let mut first_error: Option<RuntimeError> = None;
    let mut plant_done = None;
    let stdin_eof = config.stop_on_stdin_eof;
    tokio::select! {
        signal = tokio::signal::ctrl_c() => {
            if let Err(e) = signal {
                first_error = Some(RuntimeError::Signal(e));
            }
            tracing::info!("shutting down (Ctrl-C)");
        }
        () = shutdown::stdin_closed(), if stdin_eof => tracing::info!("shutting down (standard input closed)"),
        () = shutdown::terminated() => tracing::info!("shutting down (SIGTERM)"),
        Some(done) = links.join_next() => {
            match done {
                Ok(Ok(())) => tracing::info!("a ground-station link stopped; shutting down"),
                Ok(Err(e)) => first_error = Some(e.into()),
                Err(e) => first_error = Some(e.into()),
            }
        }
        r = &mut plant_task => plant_done = Some(r),
    }
    trigger.fire();
    stop.store(true, Ordering::Relaxed);
    // The next start's signing timestamps continue from the last one used.
    signing.save_timestamp();
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
    while let Some(done) = links.join_next().await {
        match done {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                first_error.get_or_insert(e.into());
            }
            Err(e) => {
                first_error.get_or_insert(e.into());
            }
        }
    }
    // The plant thread has closed the flight and dropped its sender: the writer finalizes the file.
    if let Some(task) = ulog_task
        && let Err(e) = task.await
    {
        first_error.get_or_insert(e.into());
    }
    // The plant thread has dropped its tlog sender: the tlog task drains and closes.
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

//! The tokio shell around the sans-I/O core: it only moves bytes. In: datagrams and streams from ground
//! stations (UDP, TCP, serial links, each a tokio task); out to the core: [`link::Incoming`] messages on
//! one mpsc channel; back from the core: [`link::Outgoing`] messages to every link, or to the peer of one
//! link that a reply answers. The core itself runs on the plant link's own thread
//! ([`plant_link`], blocking I/O: the lockstep round trip is latency-bound). Also the configuration
//! ([`config`]), the `.tlog` writer, the onboard ULog flight log ([`flight_log`], encoded by [`ulog`])
//! and the shutdown signal every task selects on.
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
pub mod tcp;
pub mod tlog;
pub mod transport;
pub mod udp;
pub mod ulog;
pub mod utc;
pub mod vehicle_host;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc;
use tokio::task::JoinSet;

pub use config::{ConfigError, ConfigFile, Overrides, PlantEndpoint, RuntimeConfig};
use link::{CHANNEL_CAPACITY, LinkError};
use persist::{PersistError, Persister};
use plant_link::{
    FENCE_FILE, GcsOutputs, MISSION_FILE, PARAMS_FILE, Persisted, PlantLinkError, PlantLinkStats, RALLY_FILE, TlogFrame,
};

use crate::core::geofence::{FENCE_COMMANDS, Fence, Rally};
use crate::core::mavlink::common::MavCmd;
use serial::{SerialConfig, SerialLink};
use tcp::TcpLink;
use tlog::{TlogError, TlogWriter};
use transport::{SerialTransport, Transport, UdpPeerTransport};
use udp::UdpLink;

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

/// What an earlier run left in `dir` (parameters over `vehicle`'s, the mission), and the saver. A state
/// file never stops the autopilot from starting (as PX4 starts on defaults): a parameter line that cannot
/// be read, or a value out of range or that makes the configuration unusable with the values before it
/// (loop rates that do not divide), falls back to its default with a warning naming the file, the line
/// and the parameter; a file that cannot be read or parsed at all is moved aside (`NAME.corrupt-<time>`)
/// with a warning, and the vehicle starts without it.
///
/// # Errors
/// The state directory's own I/O error (it cannot be created).
fn load_state(dir: &std::path::Path, vehicle: &crate::core::config::VehicleConfig) -> Result<Persisted, RuntimeError> {
    use crate::core::params::ParamStore;
    let persister = Persister::start(dir)?;
    let aside = |name: &str, why: &dyn std::fmt::Display| match persist::move_aside(dir, name) {
        Ok(to) => {
            tracing::warn!(file = %dir.join(name).display(), moved_to = %to.display(), "{why}: moved aside, starting without it")
        }
        Err(e) => tracing::warn!(file = %dir.join(name).display(), "{why}; {e}: starting without it"),
    };
    let params = match persist::load(dir, PARAMS_FILE) {
        Ok(Some(text)) => {
            let file = dir.join(PARAMS_FILE);
            let base = ParamStore::from_config(vehicle);
            let loaded = ParamStore::from_text_lenient(&text, base.clone());
            for w in &loaded.warnings {
                tracing::warn!(file = %file.display(), "{w}");
            }
            // Replayed in file order over the defaults: a value that makes the configuration unusable with
            // the ones before it keeps its default.
            let mut store = base.clone();
            for &(line, index) in &loaded.taken {
                let (Some(value), Some(default)) = (loaded.store.get_index(index), base.get_index(index)) else {
                    continue;
                };
                if store.set_index(index, value).is_err() {
                    continue;
                }
                let mut config = vehicle.clone();
                store.apply(&mut config);
                if let Err(e) = config.validate() {
                    let _ = store.set_index(index, default);
                    let name = store.def(index).map_or("?", |d| d.name);
                    tracing::warn!(file = %file.display(), "line {line}: {name} = {value}: {e}: the default {default} is used");
                }
            }
            Some(store)
        }
        Ok(None) => None,
        Err(e) => {
            aside(PARAMS_FILE, &e);
            None
        }
    };
    let items = |text: &str, command_of: fn(u32) -> Option<MavCmd>| {
        crate::core::mission::items_from_wpl(text, command_of).map_err(|e| e.to_string())
    };
    let mission = load_plan(dir, MISSION_FILE, &aside, |text| {
        crate::core::mission::Mission::from_wpl(text).map_err(|e| e.to_string())
    });
    let fence = load_plan(dir, FENCE_FILE, &aside, |text| {
        Fence::new(items(text, |n| FENCE_COMMANDS.into_iter().find(|c| *c as u32 == n))?).map_err(|e| e.to_string())
    });
    let rally = load_plan(dir, RALLY_FILE, &aside, |text| {
        let rally_point = |n| {
            let point = MavCmd::MAV_CMD_NAV_RALLY_POINT;
            (n == point as u32).then_some(point)
        };
        Rally::new(items(text, rally_point)?).map_err(|e| e.to_string())
    });
    let persisted = Persisted { params, mission, fence, rally, persister: Some(persister) };
    tracing::info!("{}", RestoredState::of(&persisted, vehicle).describe(dir));
    Ok(persisted)
}

/// The files of the state directory that `--wipe` removes: everything the vehicle restores at start but
/// the signing key (a wipe must not quietly turn signing off; delete `signing.key` for that).
pub const STATE_FILES: [&str; 4] = [PARAMS_FILE, MISSION_FILE, FENCE_FILE, RALLY_FILE];

/// Removes the state files of `dir` ([`STATE_FILES`]) so the vehicle starts on defaults, as ArduPilot's
/// `-w` does; returns the files that were there.
///
/// # Errors
/// [`PersistError::Write`] naming a file that could not be removed.
pub fn wipe_state(dir: &std::path::Path) -> Result<Vec<std::path::PathBuf>, PersistError> {
    persist::wipe(dir, &STATE_FILES)
}

/// What a start restored from the state directory, for the start-up line that says so.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
struct RestoredState {
    /// Parameters whose restored value differs from the configuration's default.
    changed_params: Vec<&'static str>,
    mission_items: usize,
    fence_items: usize,
    rally_points: usize,
}

impl RestoredState {
    /// What `persisted` holds, parameters compared with `vehicle`'s defaults.
    fn of(persisted: &Persisted, vehicle: &crate::core::config::VehicleConfig) -> Self {
        let defaults = crate::core::params::ParamStore::from_config(vehicle);
        let changed_params = persisted.params.as_ref().map_or_else(Vec::new, |store| {
            store
                .iter()
                .zip(defaults.iter())
                .filter(|((_, value), (_, default))| value.to_bits() != default.to_bits())
                .map(|((def, _), _)| def.name)
                .collect()
        });
        Self {
            changed_params,
            mission_items: persisted.mission.as_ref().map_or(0, crate::core::mission::Mission::len),
            fence_items: persisted.fence.as_ref().map_or(0, |f| f.items().len()),
            rally_points: persisted.rally.as_ref().map_or(0, |r| r.items().len()),
        }
    }

    /// "state restored from DIR: 2 parameters differ from default (A, B), mission of 5 items, ... (`--wipe`
    /// starts clean)", or "no state to restore in DIR (a fresh start)".
    fn describe(&self, dir: &std::path::Path) -> String {
        let mut parts = Vec::new();
        match self.changed_params.as_slice() {
            [] => {}
            names => {
                let shown: Vec<&str> = names.iter().take(8).copied().collect();
                let more = if names.len() > shown.len() {
                    format!(", and {} more", names.len() - shown.len())
                } else {
                    String::new()
                };
                let noun = if names.len() == 1 { "parameter differs" } else { "parameters differ" };
                parts.push(format!("{} {noun} from default ({}{more})", names.len(), shown.join(", ")));
            }
        }
        let plural = |n: usize, one: &str, many: &str| if n == 1 { one.to_owned() } else { format!("{n} {many}") };
        if self.mission_items > 0 {
            parts.push(format!("a mission of {}", plural(self.mission_items, "1 item", "items")));
        }
        if self.fence_items > 0 {
            parts.push(format!("a fence of {}", plural(self.fence_items, "1 item", "items")));
        }
        if self.rally_points > 0 {
            parts.push(plural(self.rally_points, "1 rally point", "rally points"));
        }
        if parts.is_empty() {
            format!("no state to restore in {} (a fresh start: defaults, no mission)", dir.display())
        } else {
            format!("state restored from {}: {} (`--wipe` starts clean)", dir.display(), parts.join(", "))
        }
    }
}

/// A plan file (mission, fence, rally) of the state directory parsed by `parse`: None when absent; when
/// unreadable or unparsable, moved aside by `aside` (and None).
fn load_plan<T>(
    dir: &std::path::Path,
    file: &str,
    aside: &dyn Fn(&str, &dyn std::fmt::Display),
    parse: impl Fn(&str) -> Result<T, String>,
) -> Option<T> {
    match persist::load(dir, file) {
        Ok(Some(text)) => parse(&text).map_err(|e| aside(file, &e)).ok(),
        Ok(None) => None,
        Err(e) => {
            aside(file, &e);
            None
        }
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

/// Resolves on SIGTERM (how service managers and `kill` stop a process), never elsewhere than on Unix.
async fn terminated() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            term.recv().await;
            return;
        }
    }
    std::future::pending::<()>().await;
}

/// Resolves when standard input reaches its end (a detached thread reads it, so a pending read never
/// holds up the process exit).
async fn stdin_closed() {
    let (tx, rx) = tokio::sync::oneshot::channel();
    std::thread::spawn(move || {
        let mut sink = [0u8; 256];
        let mut stdin = std::io::stdin();
        while std::io::Read::read(&mut stdin, &mut sink).is_ok_and(|n| n > 0) {}
        let _ = tx.send(());
    });
    let _ = rx.await;
}

/// Run the autopilot until Ctrl-C (or, with `stop_on_stdin_eof`, until standard input closes, or until a
/// task fails): the ground-station links (UDP, TCP, serial), the plant link driving the vehicle on a
/// thread of its own, and the `.tlog` writer; every task is stopped and awaited.
///
/// # Errors
/// The first error ([`RuntimeError`]); the other tasks are still shut down.
pub async fn run(config: RuntimeConfig) -> Result<PlantLinkStats, RuntimeError> {
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
        let serial = SerialLink::open(&SerialConfig { link: out_links.len(), path: path.clone(), baud: *baud })?
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

    let persisted = match &config.state_dir {
        Some(dir) => load_state(dir, &config.vehicle)?,
        None => Persisted::default(),
    };
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
    let outputs =
        GcsOutputs { links: out_links, tlog: tlog_tx, counters, signing: signing.clone(), secure, flight_log };
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
        () = stdin_closed(), if stdin_eof => tracing::info!("shutting down (standard input closed)"),
        () = terminated() => tracing::info!("shutting down (SIGTERM)"),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::VehicleConfig;
    use crate::core::vehicle::Vehicle;

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("aco-state-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        dir
    }

    #[test]
    fn a_hand_edited_params_file_with_a_bricking_rate_and_garbage_starts_the_vehicle_on_those_defaults() {
        // GIVEN a params.txt with a loop rate that does not divide the inner rate, a garbage line, a value
        // that is not a number, an out-of-range value, and one good value.
        let dir = temp_dir("params");
        let text = "LOOP_POS_HZ\t300\nthis is not a parameter line\nMPC_XY_CRUISE\tfast\nMPC_TKO_SPEED\t99\nMPC_XY_CRUISE\t2\n";
        std::fs::write(dir.join(PARAMS_FILE), text).expect("write");
        let vehicle = VehicleConfig::default();
        // WHEN the autopilot loads its state THEN it starts, on the good value and the defaults of the rest.
        let persisted = load_state(&dir, &vehicle).expect("a state file never stops the start");
        let store = persisted.params.expect("the parameters");
        assert_eq!(store.get("MPC_XY_CRUISE"), Some(2.0));
        assert_eq!(store.get("LOOP_POS_HZ"), Some(100.0), "the default: 300 does not divide 500");
        assert_eq!(store.get("MPC_TKO_SPEED"), Some(1.0), "the default: 99 is out of range");
        Vehicle::with_params(vehicle, store).expect("the vehicle starts");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_start_says_what_was_restored_and_wipe_starts_clean() {
        // GIVEN a state directory with two changed parameters, a mission and a signing key.
        let dir = temp_dir("restored");
        let vehicle = VehicleConfig::default();
        let mut store = crate::core::params::ParamStore::from_config(&vehicle);
        store.set("MPC_XY_CRUISE", 2.0).expect("in range");
        store.set("NAV_DLL_ACT", 2.0).expect("in range");
        std::fs::write(dir.join(PARAMS_FILE), store.to_text()).expect("write");
        let wpl = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.0\t1\n\
                   1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t5\t1\n2\t0\t3\t21\t0\t0\t0\t0\t0\t0\t0\t1\n";
        std::fs::write(dir.join(MISSION_FILE), wpl).expect("write");
        std::fs::write(dir.join(signing::KEY_FILE), "00").expect("write");
        // WHEN it is loaded THEN the start-up line names the changed parameters and counts the mission.
        let persisted = load_state(&dir, &vehicle).expect("starts");
        let restored = RestoredState::of(&persisted, &vehicle);
        let mut changed = restored.changed_params.clone();
        changed.sort_unstable();
        assert_eq!(changed, ["MPC_XY_CRUISE", "NAV_DLL_ACT"]);
        let line = restored.describe(&dir);
        assert!(
            line.starts_with(&format!("state restored from {}: 2 parameters differ from default (", dir.display())),
            "{line}"
        );
        assert!(line.contains("MPC_XY_CRUISE, NAV_DLL_ACT), a mission of 3 items ("), "{line}");
        assert!(line.ends_with("(`--wipe` starts clean)"), "{line}");
        drop(persisted);
        // WHEN the state is wiped THEN the next start restores nothing, and the signing key is kept.
        let removed = wipe_state(&dir).expect("wipe");
        assert_eq!(removed.len(), 2, "{removed:?}");
        let persisted = load_state(&dir, &vehicle).expect("starts");
        let line = RestoredState::of(&persisted, &vehicle).describe(&dir);
        assert_eq!(line, format!("no state to restore in {} (a fresh start: defaults, no mission)", dir.display()));
        assert!(dir.join(signing::KEY_FILE).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_mission_file_that_cannot_be_parsed_is_moved_aside_and_the_vehicle_starts_without_it() {
        let dir = temp_dir("mission");
        std::fs::write(dir.join(MISSION_FILE), "not a QGC WPL file\n").expect("write");
        let persisted = load_state(&dir, &VehicleConfig::default()).expect("starts");
        assert!(persisted.mission.is_none());
        assert!(!dir.join(MISSION_FILE).exists(), "moved away");
        let aside: Vec<_> = std::fs::read_dir(&dir)
            .expect("dir")
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&format!("{MISSION_FILE}.corrupt-")))
            .collect();
        assert_eq!(aside.len(), 1, "kept for a person to look at");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_polygon_fence_uploaded_is_saved_and_after_a_restart_downloads_identical() {
        use crate::core::mavlink::MavHeader;
        use crate::core::mavlink::common::{
            MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, MavFrame,
            MavMessage, MavMissionType,
        };
        use crate::core::vehicle::ShellEffect;
        const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
        let vertex = |seq: u16, lat: i32, lon: i32| MISSION_ITEM_INT_DATA {
            param1: 4.0,
            x: lat,
            y: lon,
            seq,
            command: MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            target_system: 1,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            mission_type: FENCE,
            ..Default::default()
        };
        let polygon = [
            vertex(0, 473_970_000, 85_450_000),
            vertex(1, 473_980_000, 85_450_000),
            vertex(2, 473_980_000, 85_465_000),
            vertex(3, 473_970_000, 85_465_000),
        ];
        // GIVEN a fence uploaded as QGroundControl uploads it, and saved where the autopilot saves it.
        let dir = temp_dir("fence");
        let mut vehicle = Vehicle::new(VehicleConfig::default()).expect("vehicle");
        let count = MISSION_COUNT_DATA {
            count: 4,
            target_system: 1,
            target_component: 1,
            mission_type: FENCE,
            ..Default::default()
        };
        vehicle.handle_message(0, &GCS, &MavMessage::MISSION_COUNT(count));
        for item in &polygon {
            vehicle.handle_message(0, &GCS, &MavMessage::MISSION_ITEM_INT(item.clone()));
        }
        let saved: Vec<String> = vehicle
            .take_effects()
            .into_iter()
            .filter_map(|e| if let ShellEffect::SaveFence(text) = e { Some(text) } else { None })
            .collect();
        assert_eq!(saved.len(), 1, "saved once, when the upload completed");
        std::fs::write(dir.join(FENCE_FILE), &saved[0]).expect("write");
        // WHEN the autopilot restarts from its state directory.
        let persisted = load_state(&dir, &VehicleConfig::default()).expect("starts");
        let mut restarted = Vehicle::new(VehicleConfig::default()).expect("vehicle");
        restarted.load_fence(persisted.fence.expect("the fence is loaded"));
        // THEN a download gives back the items uploaded.
        let list = MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, mission_type: FENCE };
        let reply = restarted.handle_message(0, &GCS, &MavMessage::MISSION_REQUEST_LIST(list));
        assert!(matches!(reply.as_slice(), [MavMessage::MISSION_COUNT(c)] if c.count == 4 && c.mission_type == FENCE));
        for (seq, sent) in (0..4).zip(&polygon) {
            let request = MISSION_REQUEST_INT_DATA { seq, target_system: 1, target_component: 1, mission_type: FENCE };
            let reply = restarted.handle_message(0, &GCS, &MavMessage::MISSION_REQUEST_INT(request));
            let [MavMessage::MISSION_ITEM_INT(got)] = reply.as_slice() else { panic!("{reply:?}") };
            let expect = MISSION_ITEM_INT_DATA { target_system: 255, target_component: 190, ..sent.clone() };
            assert_eq!(*got, expect);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

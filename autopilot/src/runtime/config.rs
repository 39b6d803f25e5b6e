//! The autopilot's configuration: a TOML file (`autopilot --config FILE`), resolved against the instance
//! number and the command line into a [`RuntimeConfig`]. Every section and key is optional; unknown keys
//! are refused (a typo is an error, not a silently ignored setting).
//!
//! ```toml
//! [plant]
//! link = "udp://127.0.0.1:4560"        # or "serial:/dev/ttyACM0:921600" (the real airframe's ARM board)
//!
//! [gcs]
//! udp_bind = "0.0.0.0:18570"           # the UDP ground-station link: bound here ...
//! udp_targets = ["127.0.0.1:14550", "127.0.0.1:14540"]   # ... always sending here, and to every peer
//! tcp_bind = "0.0.0.0:5760"            # TCP server; "off" disables it
//! tcp_max_clients = 16                 # TCP clients served at once (1-1024); more are refused
//! udp_max_peers = 32                   # UDP peers broadcast to at once (1-1024); more are only answered
//! udp_secure = false                   # true: SETUP_SIGNING accepted over UDP; only on a network you trust
//! serial = "/dev/ttyUSB0:57600"        # a telemetry radio (none by default)
//! serial_data_rate = 2000              # bytes/s the serial link's output is fitted to (default baud / 10;
//!                                      # 0: unlimited); e.g. a SiK radio's air rate
//! udp_data_rate = 0                    # bytes/s for everything the UDP socket sends (default 0: unlimited)
//!
//! [log]
//! dir = "logs"                         # .tlog of all ground-station traffic per run (none by default)
//! ulog = true                          # a ULog per armed flight in <state dir>/log/ (false: none)
//!
//! [state]
//! dir = "state"                        # parameters and mission kept across restarts; "off": none
//!                                      # (default: $XDG_STATE_HOME or ~/.local/state, aco-autopilot/iN)
//!
//! [vehicle]                            # autopilot::core::config::VehicleConfig, every field optional
//! controller = "aco"
//! [vehicle.estimator]
//! source = "fused"
//! ```
//!
//! Defaults (instance N, [`super::ports`]): plant `udp://127.0.0.1:4560+N`, UDP bound on `0.0.0.0:18570+N`
//! sending to `127.0.0.1:14550` (QGroundControl, shared by every instance, as PX4's) and to the instance's
//! API port `127.0.0.1:14540+N` (14541+N from N = 10, skipping 14550), TCP on `0.0.0.0:5760+N`, system id
//! N+1. Addresses given in the file are taken as written (not shifted by N).
//!
//! A serial link's output is fitted to its data rate (PX4's stream rate multiplier and a byte pacer,
//! `core::mavlink::link_rate`): baud / 10 bytes/s unless `serial_data_rate` says otherwise. The UDP link
//! is unlimited unless `udp_data_rate` is set (one governor for all the socket sends, a broadcast counted
//! once per destination); TCP is always unlimited.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, ToSocketAddrs};
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::ports::InstancePorts;
use super::tcp::{MAX_TCP_CLIENTS, TcpConfig};
use super::transport::parse_serial_spec;
use super::udp::{MAX_UDP_PEERS, PEER_EXPIRY, UdpConfig};
use crate::core::config::VehicleConfig;
use crate::core::plant_link::budget::bytes_per_s_of_baud;

/// A configuration that cannot be used; the message names the file and the key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Parse { path: String, message: String },
    #[error("{key}: {message}")]
    Invalid { key: &'static str, message: String },
}

/// `[plant]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlantSection {
    /// `udp://HOST:PORT` or `serial:DEVICE:BAUD`.
    pub link: Option<String>,
}

/// `[gcs]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GcsSection {
    pub udp_bind: Option<SocketAddr>,
    pub udp_targets: Option<Vec<SocketAddr>>,
    /// An address, or `off`.
    pub tcp_bind: Option<String>,
    /// `DEVICE:BAUD`.
    pub serial: Option<String>,
    /// The MAVLink signing key (a file of 64 hex digits; see `runtime::signing`).
    pub signing_key_file: Option<PathBuf>,
    /// The most TCP clients served at once (default 16, at most [`MAX_PEER_CAP`]).
    pub tcp_max_clients: Option<usize>,
    /// The most UDP peers broadcast to at once (default 32, at most [`MAX_PEER_CAP`]).
    pub udp_max_peers: Option<usize>,
    /// Whether the UDP link may carry a SETUP_SIGNING (default false). Only on a network you trust:
    /// anyone who reaches the port could set the key.
    pub udp_secure: Option<bool>,
    /// Bytes/s the serial link's output is fitted to (default: baud / 10; 0: unlimited).
    pub serial_data_rate: Option<u64>,
    /// Bytes/s the UDP link's output is fitted to (default 0: unlimited).
    pub udp_data_rate: Option<u64>,
}

/// The largest `tcp_max_clients` and `udp_max_peers` a configuration may ask for: each TCP client holds a
/// task, a socket and a 256-frame queue, and every UDP broadcast goes to every peer.
pub const MAX_PEER_CAP: usize = 1024;

fn peer_cap(value: Option<usize>, default: usize, key: &'static str) -> Result<usize, ConfigError> {
    match value {
        None => Ok(default),
        Some(n) if (1..=MAX_PEER_CAP).contains(&n) => Ok(n),
        Some(n) => Err(ConfigError::Invalid { key, message: format!("{n} is outside 1-{MAX_PEER_CAP}") }),
    }
}

/// `[log]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LogSection {
    pub dir: Option<PathBuf>,
    /// The onboard ULog flight log (default on).
    pub ulog: Option<bool>,
}

/// `[state]`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StateSection {
    /// A directory, or `off`.
    pub dir: Option<String>,
}

/// The configuration file as written.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConfigFile {
    pub plant: PlantSection,
    pub gcs: GcsSection,
    pub log: LogSection,
    pub state: StateSection,
    pub vehicle: VehicleConfig,
}

impl ConfigFile {
    /// Parse TOML text; `origin` names it in errors.
    ///
    /// # Errors
    /// [`ConfigError::Parse`] with the parser's message (line, column, key).
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Parse { path: origin.to_owned(), message: e.to_string() })
    }

    /// Read and parse a file.
    ///
    /// # Errors
    /// [`ConfigError::Read`] or [`ConfigError::Parse`].
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| ConfigError::Read { path: path.to_owned(), source })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }
}

/// Where the plant is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PlantEndpoint {
    Udp(SocketAddr),
    Serial { path: String, baud: u32 },
}

impl PlantEndpoint {
    /// `udp://HOST:PORT` or `serial:DEVICE:BAUD`.
    ///
    /// # Errors
    /// A message saying what is wrong.
    pub fn parse(spec: &str) -> Result<Self, String> {
        if let Some(hostport) = spec.strip_prefix("udp://") {
            let addr = hostport
                .to_socket_addrs()
                .map_err(|e| format!("cannot resolve `{hostport}`: {e}"))?
                .next()
                .ok_or_else(|| format!("`{hostport}` resolves to nothing"))?;
            return Ok(Self::Udp(addr));
        }
        if let Some(serial) = spec.strip_prefix("serial:") {
            let (path, baud) = parse_serial_spec(serial)?;
            return Ok(Self::Serial { path, baud });
        }
        Err(format!("`{spec}` is neither udp://HOST:PORT nor serial:DEVICE:BAUD"))
    }
}

impl std::fmt::Display for PlantEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Udp(addr) => write!(f, "udp://{addr}"),
            Self::Serial { path, baud } => write!(f, "serial:{path}:{baud}"),
        }
    }
}

/// Everything the autopilot process runs with.
#[derive(Debug, Clone, PartialEq)]
pub struct RuntimeConfig {
    pub plant: PlantEndpoint,
    /// Instance N: system id N+1, default ports shifted by N.
    pub instance: u16,
    /// The vehicle (its `sysid` is N+1).
    pub vehicle: VehicleConfig,
    /// The UDP ground-station link (always on).
    pub udp: UdpConfig,
    /// The TCP server, unless off.
    pub tcp: Option<TcpConfig>,
    /// A serial ground-station link, if any: (device, baud).
    pub serial: Option<(String, u32)>,
    /// The serial link's data rate, bytes/s (baud / 10 unless `[gcs] serial_data_rate`; 0: unlimited).
    pub serial_data_rate: u64,
    /// Where `.tlog` files go; `None`: no log.
    pub log_dir: Option<PathBuf>,
    /// Where the ULog flight logs go (`<this>/<date>/<time>.ulg`): the state directory's `log/`, or with
    /// the state directory off the `.tlog` directory; `None`: no flight log (`--no-ulog`,
    /// `[log] ulog = false`, or neither directory).
    pub ulog_dir: Option<PathBuf>,
    /// Stop when standard input closes (set by `sitl run`, so that the autopilot never outlives it).
    pub stop_on_stdin_eof: bool,
    /// Where parameters and the mission persist across restarts; `None`: nowhere.
    pub state_dir: Option<PathBuf>,
    /// The MAVLink signing key file, if signing is to start on (see `runtime::signing`).
    pub signing_key_file: Option<PathBuf>,
    /// `--rate HZ`: the plant's sample rate, which `runtime::run` sets as LOOP_INNER_HZ (and LOOP_POS_HZ,
    /// `plant_link::budget::position_rate_hz`) in the vehicle and over the kept parameters; `None`: their own.
    pub plant_rate_hz: Option<u32>,
    /// Where the view stream goes (`--view-udp`, see [`crate::runtime::view`]); `None`: nowhere.
    pub view_udp: Option<SocketAddr>,
}

/// What the command line adds to (and overrides in) the file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    pub plant: Option<String>,
    pub log_dir: Option<PathBuf>,
    /// `--no-ulog`: no onboard flight log.
    pub no_ulog: bool,
    pub stop_on_stdin_eof: bool,
    /// A state directory, or `off`.
    pub state_dir: Option<String>,
    pub signing_key_file: Option<PathBuf>,
}

/// The default state directory of instance `instance`: `$XDG_STATE_HOME/aco-autopilot/iN`, else
/// `$HOME/.local/state/aco-autopilot/iN`; `None` without either.
#[must_use]
pub fn default_state_dir(instance: u16) -> Option<PathBuf> {
    let base = std::env::var_os("XDG_STATE_HOME").filter(|v| !v.is_empty()).map(PathBuf::from).or_else(|| {
        std::env::var_os("HOME").filter(|v| !v.is_empty()).map(|h| PathBuf::from(h).join(".local/state"))
    })?;
    Some(base.join("aco-autopilot").join(format!("i{instance}")))
}

fn local(port: u16) -> SocketAddr {
    SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port))
}

impl RuntimeConfig {
    /// Resolve `file` for instance `instance` with the command line's `overrides`.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming the key: an instance whose system id or ports do not fit, a plant
    /// or serial spec that does not parse, a TCP address that is neither an address nor `off`.
    pub fn resolve(file: ConfigFile, instance: u16, overrides: Overrides) -> Result<Self, ConfigError> {
        let ports = InstancePorts::of(instance)
            .map_err(|e| ConfigError::Invalid { key: "instance", message: e.to_string() })?;
        let sysid = ports.system_id;
        let plant = match overrides.plant.or(file.plant.link) {
            Some(spec) => {
                PlantEndpoint::parse(&spec).map_err(|message| ConfigError::Invalid { key: "plant.link", message })?
            }
            None => PlantEndpoint::Udp(local(ports.plant_udp)),
        };
        let default_udp = UdpConfig::for_ports(&ports);
        let udp = UdpConfig {
            link: 0,
            bind: file.gcs.udp_bind.unwrap_or(default_udp.bind),
            targets: file.gcs.udp_targets.unwrap_or(default_udp.targets),
            peer_expiry: PEER_EXPIRY,
            max_peers: peer_cap(file.gcs.udp_max_peers, MAX_UDP_PEERS, "gcs.udp_max_peers")?,
            secure: file.gcs.udp_secure.unwrap_or(false),
            data_rate: file.gcs.udp_data_rate.unwrap_or(0),
        };
        let max_clients = peer_cap(file.gcs.tcp_max_clients, MAX_TCP_CLIENTS, "gcs.tcp_max_clients")?;
        let tcp = match file.gcs.tcp_bind.as_deref().map(str::trim) {
            Some("off") => None,
            Some(addr) => Some(TcpConfig {
                link: 1,
                bind: addr.parse().map_err(|e| ConfigError::Invalid {
                    key: "gcs.tcp_bind",
                    message: format!("`{addr}` is not an address (or `off`): {e}"),
                })?,
                max_clients,
            }),
            None => Some(TcpConfig { max_clients, ..TcpConfig::for_ports(&ports) }),
        };
        let serial = file
            .gcs
            .serial
            .map(|spec| parse_serial_spec(&spec).map_err(|message| ConfigError::Invalid { key: "gcs.serial", message }))
            .transpose()?;
        let serial_data_rate = match (&serial, file.gcs.serial_data_rate) {
            (_, Some(rate)) => rate,
            (Some((_, baud)), None) => bytes_per_s_of_baud(*baud),
            (None, None) => 0,
        };
        let vehicle = VehicleConfig { sysid, ..file.vehicle };
        let state_dir = match overrides.state_dir.or(file.state.dir).as_deref().map(str::trim) {
            Some("off") => None,
            Some(dir) => Some(PathBuf::from(dir)),
            None => default_state_dir(instance),
        };
        let log_dir = overrides.log_dir.or(file.log.dir);
        let ulog = !overrides.no_ulog && file.log.ulog.unwrap_or(true);
        let ulog_dir = match (&state_dir, &log_dir) {
            _ if !ulog => None,
            (Some(state), _) => Some(state.join("log")),
            (None, Some(logs)) => Some(logs.clone()),
            (None, None) => None,
        };
        Ok(Self {
            plant,
            instance,
            vehicle,
            udp,
            tcp,
            serial,
            serial_data_rate,
            log_dir,
            ulog_dir,
            stop_on_stdin_eof: overrides.stop_on_stdin_eof,
            state_dir,
            signing_key_file: overrides.signing_key_file.or(file.gcs.signing_key_file),
            plant_rate_hz: None,
            view_udp: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::ControllerKind;
    use crate::core::estimator::EstimatorSource;

    #[test]
    fn defaults_follow_the_instance() {
        let c = RuntimeConfig::resolve(ConfigFile::default(), 3, Overrides::default()).expect("defaults");
        assert!(c.state_dir.as_ref().is_none_or(|d| d.ends_with("aco-autopilot/i3")), "{:?}", c.state_dir);
        assert_eq!(c.plant, PlantEndpoint::Udp("127.0.0.1:4563".parse().expect("addr")));
        assert_eq!(c.vehicle.sysid, 4);
        assert_eq!(c.udp.bind, "0.0.0.0:18573".parse().expect("addr"));
        assert_eq!(c.udp.targets, vec![local(14550), local(14543)], "QGroundControl's port is shared");
        assert_eq!(c.tcp.as_ref().map(|t| t.bind), Some("0.0.0.0:5763".parse().expect("addr")));
        assert_eq!((c.serial, c.log_dir), (None, None));
        assert_eq!(c.udp.data_rate, 0, "UDP unlimited by default");
        assert_eq!((c.udp.max_peers, c.udp.secure), (MAX_UDP_PEERS, false));
        assert_eq!(c.tcp.map(|t| t.max_clients), Some(MAX_TCP_CLIENTS));
        assert_eq!(c.ulog_dir, c.state_dir.map(|d| d.join("log")), "flight logs under the state directory");
    }

    #[test]
    fn the_flight_log_follows_the_state_directory_and_turns_off_by_flag_or_file() {
        let resolve = |text: &str, o: Overrides| {
            let file = ConfigFile::from_toml_str(text, "t.toml").expect("parses");
            RuntimeConfig::resolve(file, 0, o).expect("valid").ulog_dir
        };
        let state = || Overrides { state_dir: Some("st".into()), ..Overrides::default() };
        assert_eq!(resolve("", state()), Some(PathBuf::from("st/log")));
        assert_eq!(resolve("", Overrides { no_ulog: true, ..state() }), None);
        assert_eq!(resolve("[log]\nulog = false\n", state()), None);
        assert_eq!(resolve("[log]\nulog = true\n", state()), Some(PathBuf::from("st/log")));
        // With the state directory off, into the .tlog directory if there is one, else nowhere.
        let off = Overrides { state_dir: Some("off".into()), ..Overrides::default() };
        assert_eq!(resolve("", off.clone()), None);
        assert_eq!(resolve("", Overrides { log_dir: Some("logs".into()), ..off }), Some(PathBuf::from("logs")));
        assert!(ConfigFile::from_toml_str("[log]\nulog = \"yes\"\n", "t.toml").is_err());
    }

    #[test]
    fn the_peer_caps_and_udp_secure_are_set_and_checked() {
        let file = ConfigFile::from_toml_str(
            "[gcs]\ntcp_max_clients = 4\nudp_max_peers = 1024\nudp_secure = true\n",
            "caps.toml",
        )
        .expect("parses");
        let c = RuntimeConfig::resolve(file, 0, Overrides::default()).expect("valid");
        assert_eq!((c.tcp.map(|t| t.max_clients), c.udp.max_peers, c.udp.secure), (Some(4), 1024, true));
        let bad = |text: &str| {
            let file = ConfigFile::from_toml_str(text, "c.toml").expect("parses");
            RuntimeConfig::resolve(file, 0, Overrides::default()).unwrap_err().to_string()
        };
        assert_eq!(bad("[gcs]\ntcp_max_clients = 0\n"), "gcs.tcp_max_clients: 0 is outside 1-1024");
        assert_eq!(bad("[gcs]\nudp_max_peers = 1025\n"), "gcs.udp_max_peers: 1025 is outside 1-1024");
        let negative = ConfigFile::from_toml_str("[gcs]\ntcp_max_clients = -1\n", "n.toml").unwrap_err();
        assert!(negative.to_string().contains("tcp_max_clients"), "{negative}");
    }

    #[test]
    fn a_file_sets_links_and_vehicle_and_the_command_line_wins() {
        let text = r#"
            [plant]
            link = "serial:/dev/ttyACM0:921600"
            [gcs]
            udp_bind = "127.0.0.1:20000"
            udp_targets = ["127.0.0.1:20001"]
            tcp_bind = "off"
            serial = "/dev/ttyUSB0:57600"
            [log]
            dir = "flights"
            [state]
            dir = "off"
            [vehicle]
            controller = "pid"
            [vehicle.estimator]
            source = "truth"
        "#;
        let file = ConfigFile::from_toml_str(text, "test.toml").expect("parses");
        let c = RuntimeConfig::resolve(file.clone(), 0, Overrides::default()).expect("valid");
        assert_eq!(c.plant, PlantEndpoint::Serial { path: "/dev/ttyACM0".into(), baud: 921_600 });
        assert_eq!((c.udp.bind, c.udp.targets.clone()), (local(20000), vec![local(20001)]));
        assert_eq!(c.tcp, None);
        assert_eq!(c.serial, Some(("/dev/ttyUSB0".into(), 57_600)));
        assert_eq!(c.serial_data_rate, 5760, "baud / 10 by default");
        assert_eq!(c.log_dir, Some(PathBuf::from("flights")));
        assert_eq!(c.state_dir, None);
        assert_eq!((c.vehicle.controller, c.vehicle.estimator.source), (ControllerKind::PID, EstimatorSource::Truth));
        let o =
            Overrides { plant: Some("udp://127.0.0.1:5000".into()), log_dir: Some("x".into()), ..Overrides::default() };
        let c = RuntimeConfig::resolve(file, 0, o).expect("valid");
        assert_eq!(c.plant, PlantEndpoint::Udp(local(5000)));
        assert_eq!(c.log_dir, Some(PathBuf::from("x")));
    }

    #[test]
    fn the_data_rates_of_the_serial_and_udp_links_are_set() {
        let resolve = |text: &str| {
            let file = ConfigFile::from_toml_str(text, "rates.toml").expect("parses");
            let c = RuntimeConfig::resolve(file, 0, Overrides::default()).expect("valid");
            (c.serial_data_rate, c.udp.data_rate)
        };
        assert_eq!(resolve("[gcs]\nserial = \"/dev/ttyUSB0:115200\"\n"), (11_520, 0));
        assert_eq!(resolve("[gcs]\nserial = \"/dev/ttyUSB0:57600\"\nserial_data_rate = 2000\n"), (2000, 0));
        assert_eq!(resolve("[gcs]\nserial = \"/dev/ttyUSB0:57600\"\nserial_data_rate = 0\n"), (0, 0));
        assert_eq!(resolve("[gcs]\nudp_data_rate = 12000\n"), (0, 12_000));
        let typo = ConfigFile::from_toml_str("[gcs]\nserial_datarate = 1\n", "t.toml").unwrap_err();
        assert!(typo.to_string().contains("serial_datarate"), "{typo}");
        assert!(ConfigFile::from_toml_str("[gcs]\nudp_data_rate = -1\n", "t.toml").is_err());
    }

    #[test]
    fn bad_files_are_refused_with_the_key_named() {
        let typo = ConfigFile::from_toml_str("[gcs]\nudp_bnd = \"0.0.0.0:1\"\n", "a.toml").unwrap_err();
        assert!(typo.to_string().contains("udp_bnd") && typo.to_string().starts_with("a.toml"), "{typo}");
        let vehicle_typo = ConfigFile::from_toml_str("[vehicle]\ncontroler = \"aco\"\n", "b.toml").unwrap_err();
        assert!(vehicle_typo.to_string().contains("controler"), "{vehicle_typo}");
        let bad = |text: &str| {
            let file = ConfigFile::from_toml_str(text, "c.toml").expect("parses");
            RuntimeConfig::resolve(file, 0, Overrides::default()).unwrap_err().to_string()
        };
        assert!(bad("[plant]\nlink = \"tcp://x:1\"\n").starts_with("plant.link"));
        assert!(bad("[plant]\nlink = \"serial:/dev/x\"\n").contains("DEVICE:BAUD"));
        assert!(bad("[gcs]\ntcp_bind = \"everywhere\"\n").starts_with("gcs.tcp_bind"));
        assert!(bad("[gcs]\nserial = \"/dev/ttyUSB0:fast\"\n").starts_with("gcs.serial"));
        let too_big = RuntimeConfig::resolve(ConfigFile::default(), 255, Overrides::default()).unwrap_err();
        assert!(too_big.to_string().contains("at most 255"), "{too_big}");
        assert!(
            ConfigFile::load(Path::new("/nonexistent/autopilot.toml")).unwrap_err().to_string().contains("cannot read")
        );
    }
}

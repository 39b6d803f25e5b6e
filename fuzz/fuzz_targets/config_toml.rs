//! The autopilot's TOML configuration (`autopilot --config FILE`) on any text: parsed, resolved for an
//! instance, and the vehicle built from it, as `autopilot` starts. Every step either refuses with an
//! error or succeeds; nothing panics. A plant address that is a host name is dropped before resolving,
//! so the fuzzer never waits on name lookups.
#![no_main]

use autopilot::core::vehicle::Vehicle;
use autopilot::runtime::config::{ConfigFile, Overrides, RuntimeConfig};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&instance, bytes)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let Ok(mut file) = ConfigFile::from_toml_str(text, "fuzz.toml") else { return };
    if let Some(link) = &file.plant.link
        && let Some(hostport) = link.strip_prefix("udp://")
        && hostport.parse::<std::net::SocketAddr>().is_err()
    {
        file.plant.link = None;
    }
    let Ok(config) = RuntimeConfig::resolve(file, u16::from(instance), Overrides::default()) else { return };
    assert_eq!(u16::from(config.vehicle.sysid), u16::from(instance) + 1, "the system id is the instance + 1");
    if let Some(tcp) = &config.tcp {
        assert!((1..=autopilot::runtime::config::MAX_PEER_CAP).contains(&tcp.max_clients));
    }
    assert!((1..=autopilot::runtime::config::MAX_PEER_CAP).contains(&config.udp.max_peers));
    let _ = Vehicle::new(config.vehicle);
});

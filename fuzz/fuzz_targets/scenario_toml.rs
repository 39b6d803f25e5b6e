//! The scenario loader (`sitl scenario FILE`, TOML) on any text: a parse error or a scenario, never a
//! panic; a scenario that loads can say its reference modes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sitl::scenario::Scenario;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(scenario) = Scenario::from_toml("fuzz", text) {
        let _ = scenario.reference_modes();
    }
});

//! The pure vehicle core: no clocks, sockets, files or async runtime; time and randomness come in as inputs.

pub mod battery;
pub mod commander;
pub mod config;
pub mod control;
pub mod estimator;
pub mod intent;
pub mod manual;
pub mod mavlink;
pub mod mission;
pub mod navigator;
pub mod params;
pub mod plan;
pub mod plant_link;
pub mod vehicle;

/// Seconds to whole microseconds of vehicle time: negative and NaN to 0, beyond `u64` (a hold of 1e30 s)
/// saturated, so a time from a message field can never wrap or panic.
#[must_use]
pub fn seconds_to_us(s: f64) -> u64 {
    if s > 0.0 { (s * 1e6).round() as u64 } else { 0 }
}

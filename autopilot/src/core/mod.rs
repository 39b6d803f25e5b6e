//! The pure vehicle core: no clocks, sockets, files or async runtime; time and randomness come in as inputs.

pub mod commander;
pub mod config;
pub mod control;
pub mod estimator;
pub mod hil;
pub mod mavlink;
pub mod mission;
pub mod navigator;
pub mod params;
pub mod vehicle;

//! ACO quadrotor autopilot: the deterministic vehicle core (`core`) that the tokio shell, the in-process
//! scenario runner and the real airframe all drive identically.

pub mod cli;
pub mod core;
pub mod runtime;

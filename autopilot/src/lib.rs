//! ACO quadrotor autopilot: the deterministic vehicle core (`core`) that the tokio shell, the in-process
//! scenario runner and the real airframe all drive identically, and the guest controllers
//! (`controllers`) registered into it.

pub mod cli;
pub mod controllers;
pub mod core;
pub mod runtime;

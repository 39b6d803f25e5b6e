//! The subcommands of `sitl` (`main.rs` parses the command line and dispatches): one module each, and
//! `common` for what they share.

pub(crate) mod bench;
pub(crate) mod common;
#[cfg(unix)]
pub(crate) mod line;
pub(crate) mod plots;
pub(crate) mod run;
pub(crate) mod scenario;
pub(crate) mod serve;
pub(crate) mod sweep;
pub(crate) mod tune;
pub(crate) mod view;

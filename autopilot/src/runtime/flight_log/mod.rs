//! The onboard flight log: one ULog file per armed flight, from arming to disarming, as PX4's logger
//! writes with `SDLOG_MODE` 0, at `<root>/<YYYY-MM-DD>/<HH_MM_SS>.ulg` (the wall clock's UTC date and
//! time at arming; the root is the state directory's `log/`).
//!
//! Two halves, so that the lockstep loop never waits on a disk:
//! - [`FlightLogger`] lives on the plant-link thread beside the vehicle. After each step it samples the
//!   vehicle's [`LogSnapshot`](crate::core::vehicle::LogSnapshot) and its controller's telemetry on VEHICLE time at the rates of
//!   [`TOPICS`], encodes the records with the pure encoder of [`super::ulog`] and hands them, one batch
//!   per step at most, to a bounded channel with `try_send`. When the writer is behind, a batch is
//!   dropped and counted, and a dropout marker ('O') with the vehicle time lost goes in its place.
//!   Every STATUSTEXT the vehicle sends (mode changes, failsafes, refusals) becomes a logged string
//!   ('L') at its severity.
//! - [`UlogWriter`], on a blocking thread of its own ([`spawn_writer`]), writes `<name>.ulg.tmp` and,
//!   when the flight ends (disarm, or the autopilot stopping: Ctrl-C, SIGTERM, standard input closed),
//!   flushes, syncs and renames it to `<name>.ulg`: a file under its final name is complete.
//!
//! The header's timestamp and every record's are vehicle time (µs since the plant started), as PX4's
//! are time since boot. The definitions carry every parameter ('P', `int32_t` or `float` as PX4 types
//! them) and the default of each one that differs from it ('Q'); a parameter changed in flight is
//! logged again in the data section.
//!
//! The parts: [`topics`] says what is logged and encodes one record of each topic and the definitions
//! of a flight; [`sampler`] is the [`FlightLogger`]; [`writer`] is the [`UlogWriter`].

use std::path::PathBuf;

pub mod sampler;
pub mod topics;
pub mod writer;

pub use sampler::{FlightLogStats, FlightLogger, PARAM_CHECK_INTERVAL_US, SYNC_INTERVAL_US};
pub use topics::{TOPICS, px4_nav_state};
pub use writer::{FlightLogError, UlogWriter, spawn_writer};

/// Batches the writer may lag behind before one is dropped (a batch is one vehicle step's records).
pub const ULOG_CHANNEL_CAPACITY: usize = 4096;

/// What the sampler hands to the writer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogItem {
    /// A flight starts: `<dir>/<name>.ulg.tmp`, beginning with `bytes` (header and definitions).
    Open { dir: PathBuf, name: String, bytes: Vec<u8> },
    /// More of the flight's messages.
    Append(Vec<u8>),
    /// The flight ended: finalize the file under its `.ulg` name.
    Close,
}

//! The tokio shell around the sans-I/O core: it only moves bytes. In: datagrams and streams from ground
//! stations; out to the core: [`link::Incoming`] messages on an mpsc channel; back from the core:
//! [`link::Outgoing`] messages fanned out to every ground station or addressed to one. Also the `.tlog`
//! writer and the shutdown signal every task selects on.
//!
//! Nothing here decides anything about the vehicle; see `DESIGN.md`, "The one idea".

pub mod frame;
pub mod link;
pub mod shutdown;
pub mod tcp;
pub mod tlog;
pub mod udp;

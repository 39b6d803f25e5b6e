//! What every ground-station link (UDP, TCP, later serial) exchanges with the core: [`Incoming`] messages
//! in, tagged with the peer that sent them, and [`Outgoing`] messages back, to every peer or to one; and
//! the links' typed error, [`LinkError`].

use std::net::SocketAddr;

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

/// Capacity of the channels between a link and the core, in messages. At the 20 Hz offboard stream of one
/// MAVSDK client plus 1 Hz heartbeats this is seconds of slack; beyond it frames are dropped and counted
/// (`LinkStats::dropped_in`), never queued without bound.
pub const CHANNEL_CAPACITY: usize = 1024;

/// A valid message from a ground station, on its way to the core.
#[derive(Debug, Clone, PartialEq)]
pub struct Incoming {
    /// Who sent it: the address a reply goes to.
    pub peer: SocketAddr,
    pub header: MavHeader,
    pub message: MavMessage,
    /// The protocol version it arrived in (v1 is accepted on input).
    pub version: MavlinkVersion,
}

/// Where an [`Outgoing`] message goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Destination {
    /// Every fixed target and every live peer (telemetry, heartbeats, STATUSTEXT).
    All,
    /// Only this peer (e.g. a COMMAND_ACK, a PARAM_VALUE answering one client's read). Sent even if the
    /// peer is not (or no longer) in the peer table.
    Peer(SocketAddr),
}

/// A message from the core, on its way out; always sent as MAVLink 2.
#[derive(Debug, Clone, PartialEq)]
pub struct Outgoing {
    pub to: Destination,
    pub header: MavHeader,
    pub message: MavMessage,
}

/// Why a link task stopped. Per-peer send failures and malformed input are not errors: they are counted
/// in `LinkStats` and the link keeps running.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// Binding the local socket or listener failed (port in use, no permission).
    #[error("cannot bind {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    /// Receiving (or accepting) failed with an error that is not about one peer.
    #[error("receive on {local} failed: {source}")]
    Receive {
        local: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    /// Any other socket operation (reading the bound address, ...).
    #[error("link I/O: {0}")]
    Io(#[from] std::io::Error),
}

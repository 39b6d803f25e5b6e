//! What every ground-station link (UDP, TCP, serial) exchanges with the core: [`Incoming`] messages
//! in, tagged with the peer that sent them, and [`Outgoing`] messages back, to every peer or to one; the
//! links' typed error, [`LinkError`]; and what the links that fit their output to a data rate (serial,
//! UDP with `udp_data_rate`) share: their [`GovernedOutput`] (the governor on the link's clock, the frames'
//! sizes, the link's sequence, the multiplier's log).

use std::net::SocketAddr;

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;

use super::frame::{DecodedFrame, LinkCounters, encode_v2};
use crate::core::mavlink::link_rate::{LinkGovernor, MultReport, classify};

/// Capacity of the channels between a link and the core, in messages. At the 20 Hz offboard stream of one
/// MAVSDK client plus 1 Hz heartbeats this is seconds of slack; beyond it frames are dropped and counted
/// (`LinkStats::dropped_in`), never queued without bound.
pub const CHANNEL_CAPACITY: usize = 1024;

/// Which ground-station link a message came in on (its index in the runtime's link list), so that a
/// reply goes back out on the same link.
pub type LinkId = usize;

/// A valid message from a ground station, on its way to the core.
#[derive(Debug, Clone, PartialEq)]
pub struct Incoming {
    /// The link it came in on.
    pub link: LinkId,
    /// Who sent it: the address a reply goes to (UDP, TCP); unspecified (`0.0.0.0:0`) on a serial link,
    /// which has one peer.
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
    /// Opening a device (a serial port) failed.
    #[error("cannot open {what}: {source}")]
    Open {
        what: String,
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

/// Hands the frames of one read from `peer` on link `link` to the core, counting each in `counters`; a
/// full channel drops (and counts) the frame rather than blocking the link. `false` once the core has
/// gone (the link should stop).
pub fn deliver(
    incoming: &mpsc::Sender<Incoming>,
    counters: &LinkCounters,
    link: LinkId,
    peer: SocketAddr,
    frames: Vec<DecodedFrame>,
) -> bool {
    for f in frames {
        counters.add_frame_in();
        let msg = Incoming { link, peer, header: f.header, message: f.message, version: f.version };
        match incoming.try_send(msg) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                counters.add_dropped_in();
                tracing::warn!(%peer, "core is not keeping up; incoming frame dropped");
            }
            Err(TrySendError::Closed(_)) => return false,
        }
    }
    true
}

/// The bytes a MAVLink 2 signature adds to a frame.
pub const SIGNATURE_BYTES: usize = 13;

/// The size of `out`'s frame on the wire, `signed` or not: what a governed link's pacer counts.
#[must_use]
fn frame_bytes(out: &Outgoing, signed: bool) -> usize {
    encode_v2(out.header, &out.message).len() + if signed { SIGNATURE_BYTES } else { 0 }
}

/// A link's output fitted to a data rate: its [`LinkGovernor`] on the link's own clock (µs since the link
/// opened; tokio's, which is the monotonic clock outside a paused test runtime), and the link's frame
/// sequence. What the serial link and a UDP link with a data rate share.
#[derive(Debug)]
pub struct GovernedOutput {
    governor: LinkGovernor<Outgoing>,
    start: tokio::time::Instant,
    sequence: u8,
}

impl GovernedOutput {
    /// An output fitted to `data_rate` bytes/s (0: unlimited).
    #[must_use]
    pub fn new(data_rate: u64) -> Self {
        Self { governor: LinkGovernor::new(data_rate), start: tokio::time::Instant::now(), sequence: 0 }
    }

    fn now_us(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_micros()).unwrap_or(u64::MAX)
    }

    /// How long until the pacer next has a frame to hand out; `None` while nothing waits.
    pub fn next_ready_in(&mut self) -> Option<std::time::Duration> {
        let now = self.now_us();
        self.governor.next_ready_in_us(now).map(std::time::Duration::from_micros)
    }

    /// Feeds the governor the radio's RADIO_STATUS among `frames` (any sender: a radio has its own ids).
    pub fn take_radio_status(&mut self, frames: &[DecodedFrame]) {
        for f in frames {
            if let MavMessage::RADIO_STATUS(radio) = &f.message {
                let now = self.now_us();
                self.governor.on_radio_status(now, radio.txbuf);
            }
        }
    }

    /// Hands `out` to the governor, its frame (signed or not) counted `copies` times (a UDP broadcast goes
    /// once per destination).
    pub fn offer(&mut self, out: Outgoing, signed: bool, copies: usize) {
        let reply = matches!(out.to, Destination::Peer(_));
        let bytes = frame_bytes(&out, signed) * copies;
        let now = self.now_us();
        self.governor.offer(now, classify(&out.message, reply), bytes, out);
    }

    /// What the pacer allows now, in order, numbered by the link (MAVLink's sequence per link); a change
    /// of the multiplier is logged for `link`.
    pub fn ready(&mut self, link: &str) -> Vec<Outgoing> {
        let now = self.now_us();
        let mut ready = Vec::new();
        while let Some(mut out) = self.governor.pop(now) {
            out.header.sequence = self.sequence;
            self.sequence = self.sequence.wrapping_add(1);
            ready.push(out);
        }
        if let Some(report) = self.governor.take_mult_report() {
            log_mult(link, &report);
        }
        ready
    }
}

/// Logs a change of link `link`'s stream rate multiplier (`core::mavlink::link_rate`): at info when it
/// moved by more than a factor 2 since the last such, else at debug.
fn log_mult(link: &str, r: &MultReport) {
    let (mult, previous, bandwidth, radio) = (r.mult, r.previous, r.bandwidth_mult, r.radio_mult);
    if r.loud {
        tracing::info!(%link, mult, previous, bandwidth, radio, "ground-station stream rate multiplier changed");
    } else {
        tracing::debug!(%link, mult, previous, bandwidth, radio, "ground-station stream rate multiplier changed");
    }
}

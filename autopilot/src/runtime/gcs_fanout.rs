//! The vehicle's telemetry and replies to every ground-station link: the messages the vehicle host
//! queues, stamped with the vehicle's header and its own sequence, copied to the `.tlog` and handed to
//! each link's queue in bursts ([`GCS_FLUSH_INTERVAL`]) or at once for a reply to one peer. A link whose
//! queue is full loses the message (counted); broadcast STATUSTEXTs are held to a rate ([`TextLimiter`]).

use std::sync::Arc;
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;

use crate::core::mavlink::own_header;
use crate::runtime::flight_log::FlightLogger;
use crate::runtime::frame::{self, LinkCounters};
use crate::runtime::link::{Destination, Incoming, LinkId, Outgoing};
use crate::runtime::signing::LinkSigning;
use crate::runtime::view::ViewTap;

/// Wall time the step's telemetry may wait before it is handed to the ground-station links. Handing each
/// message over on its own wakes the tokio thread every time, which in lockstep (about 5000 messages per
/// wall second at 70x) cost 8 µs per step, a quarter of the round trip; in bursts it costs one wake-up.
/// Replies to a ground station are handed over at once.
pub const GCS_FLUSH_INTERVAL: Duration = Duration::from_millis(2);

/// A raw frame for the `.tlog`, in or out.
pub type TlogFrame = Vec<u8>;

/// The senders towards each ground-station link (index = [`LinkId`]) and the `.tlog`, and the links'
/// counters (their malformed frames are reported in SYS_STATUS).
#[derive(Debug, Default)]
pub struct GcsOutputs {
    pub links: Vec<mpsc::Sender<Outgoing>>,
    pub tlog: Option<mpsc::Sender<TlogFrame>>,
    pub counters: Vec<Arc<LinkCounters>>,
    /// The links' shared MAVLink signing (SETUP_SIGNING is applied here).
    pub signing: Arc<LinkSigning>,
    /// Per link (index = [`LinkId`]): whether it may carry SETUP_SIGNING (TCP, serial).
    pub secure: Vec<bool>,
    /// The onboard ULog's sampler (off by default).
    pub flight_log: FlightLogger,
    /// The view stream's tap (off unless `--view-udp`).
    pub view: ViewTap,
}

/// Broadcast STATUSTEXTs allowed per second of vehicle time, on average.
pub const STATUSTEXT_PER_S: f64 = 10.0;
/// How many may come at once above that rate.
pub const STATUSTEXT_BURST: f64 = 20.0;

/// A token bucket on vehicle time for the STATUSTEXTs the vehicle broadcasts, so that something that
/// repeats itself (a bad stream, a flapping condition) cannot flood the ground stations. Replies to one
/// peer (a refusal's reason) are not limited; the chunks of a long text follow their first.
#[derive(Debug, Clone, PartialEq)]
pub struct TextLimiter {
    tokens: f64,
    last_us: Option<u64>,
    last_allowed: bool,
}

impl Default for TextLimiter {
    fn default() -> Self {
        Self { tokens: STATUSTEXT_BURST, last_us: None, last_allowed: true }
    }
}

impl TextLimiter {
    /// Whether a STATUSTEXT at `now_us` may go out (`continuation`: a later chunk of a chunked text).
    pub fn allow(&mut self, now_us: u64, continuation: bool) -> bool {
        let elapsed_s = match self.last_us {
            Some(t) if now_us >= t => (now_us - t) as f64 * 1e-6,
            // A new timeline (the plant restarted): start full.
            Some(_) => STATUSTEXT_BURST,
            None => 0.0,
        };
        self.last_us = Some(now_us);
        self.tokens = (self.tokens + elapsed_s * STATUSTEXT_PER_S).min(STATUSTEXT_BURST);
        if continuation {
            return self.last_allowed;
        }
        self.last_allowed = self.tokens >= 1.0;
        if self.last_allowed {
            self.tokens -= 1.0;
        }
        self.last_allowed
    }
}

/// What the fan-out has lost, for [`super::plant_link::PlantLinkStats`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FanoutStats {
    /// Messages to a ground-station link dropped because its queue was full.
    pub gcs_dropped: u64,
    /// Frames not logged because the tlog writer was behind.
    pub tlog_dropped: u64,
    /// Broadcast STATUSTEXTs not sent: over [`STATUSTEXT_PER_S`] (see [`TextLimiter`]).
    pub statustext_suppressed: u64,
}

/// The fan-out to every ground-station link; see the module docs.
#[derive(Debug)]
pub struct GcsFanout {
    /// The links' queues, the `.tlog`'s, the links' counters, signing and the flight log.
    pub out: GcsOutputs,
    sysid: u8,
    sequence: u8,
    /// Messages waiting for the next flush: (only this link, message).
    pending: Vec<(Option<LinkId>, Outgoing)>,
    /// A reply is pending: flush at once.
    urgent: bool,
    last_flush: Instant,
    texts: TextLimiter,
    pub stats: FanoutStats,
}

impl GcsFanout {
    /// The fan-out of vehicle `sysid` to `out`.
    #[must_use]
    pub fn new(sysid: u8, out: GcsOutputs) -> Self {
        Self {
            out,
            sysid,
            sequence: 0,
            pending: Vec::new(),
            urgent: false,
            last_flush: Instant::now(),
            texts: TextLimiter::default(),
            stats: FanoutStats::default(),
        }
    }

    fn header(&mut self) -> MavHeader {
        let mut header = own_header(self.sysid);
        header.sequence = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        header
    }

    fn log(&mut self, frame: TlogFrame) {
        if let Some(tlog) = &self.out.tlog
            && tlog.try_send(frame).is_err()
        {
            self.stats.tlog_dropped += 1;
        }
    }

    /// A message a ground station sent, to the `.tlog` (in the MAVLink version it came in).
    pub fn log_received(&mut self, incoming: &Incoming) {
        if self.out.tlog.is_some() {
            self.log(frame::encode(incoming.header, &incoming.message, incoming.version));
        }
    }

    /// Queues a message made at vehicle time `now_us` to every link (`to == All`) or to one peer of link
    /// `link`; it goes out at the next [`GcsFanout::flush`] that is due (at once for a reply to one peer).
    pub fn send(&mut self, now_us: u64, link: Option<LinkId>, to: Destination, message: MavMessage) {
        // The flight log keeps every text, those the limiter holds back from the ground stations too.
        if let MavMessage::STATUSTEXT(text) = &message {
            self.out.flight_log.text(now_us, text.severity, text.text.to_str().unwrap_or(""));
            self.out.view.text(now_us, text.severity, text.text.to_str().unwrap_or(""));
        }
        if let (Destination::All, MavMessage::STATUSTEXT(text)) = (to, &message)
            && !self.texts.allow(now_us, text.id != 0 && text.chunk_seq > 0)
        {
            self.stats.statustext_suppressed += 1;
            return;
        }
        let header = self.header();
        if self.out.tlog.is_some() {
            self.log(frame::encode_v2(header, &message));
        }
        self.urgent |= matches!(to, Destination::Peer(_));
        self.pending.push((link, Outgoing { to, header, message }));
    }

    /// Hands the pending messages to the links if a reply waits or [`GCS_FLUSH_INTERVAL`] has passed
    /// (always with `force`).
    pub fn flush(&mut self, now: Instant, force: bool) {
        if self.pending.is_empty() || !(force || self.urgent || now - self.last_flush >= GCS_FLUSH_INTERVAL) {
            return;
        }
        let mut dropped = 0;
        for (link, out) in self.pending.drain(..) {
            for (id, tx) in self.out.links.iter().enumerate() {
                if link.is_some_and(|l| l != id) {
                    continue;
                }
                match tx.try_send(out.clone()) {
                    Ok(()) | Err(TrySendError::Closed(_)) => {}
                    Err(TrySendError::Full(_)) => dropped += 1,
                }
            }
        }
        self.stats.gcs_dropped += dropped;
        self.urgent = false;
        self.last_flush = now;
    }

    /// Whether every link's queue has closed (the ground-station side has gone).
    #[must_use]
    pub fn links_closed(&self) -> bool {
        self.out.links.iter().all(mpsc::Sender::is_closed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_repeating_statustext_is_held_to_10_per_vehicle_second_after_a_burst_of_20() {
        let mut limiter = TextLimiter::default();
        // 60 texts a second for 3 s of vehicle time (a bad stream refused at 60 Hz).
        let allowed = (0..180_u64).filter(|k| limiter.allow(k * 16_667, false)).count();
        assert_eq!(allowed, 20 + 30 - 1, "the burst, then 10 a second");
        // A chunked text's continuation follows its first chunk.
        let mut limiter = TextLimiter { tokens: 1.0, ..TextLimiter::default() };
        assert!(limiter.allow(0, false) && limiter.allow(0, true));
        assert!(!limiter.allow(0, false) && !limiter.allow(0, true));
        // A plant restart (time goes back) starts full again.
        let mut limiter = TextLimiter { tokens: 0.0, last_us: Some(5_000_000), last_allowed: false };
        assert!(!limiter.allow(5_000_000, false));
        assert!(limiter.allow(0, false), "a new timeline");
    }
}

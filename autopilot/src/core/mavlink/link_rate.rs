//! Fits one ground-station link's output to its data rate, as PX4's stream rate multiplier does: classes
//! the outgoing messages, thins the telemetry streams by a multiplier and paces the bytes written.
//!
//! Sans-I/O: the caller's clock comes in as `now_us` (µs, any monotonic origin), the caller's items
//! (whatever it writes: a message, a frame) go in with their size in bytes and come back out when the
//! link may carry them. One [`LinkGovernor`] per link.
//!
//! **Classes** ([`classify`]):
//! - *priority* ([`PRIORITY_IDS`]: HEARTBEAT, COMMAND_ACK, STATUSTEXT): never thinned, written before
//!   anything else queued;
//! - *transfer*: PARAM_VALUE, the MISSION_* protocol, any reply to one peer, and anything that is neither
//!   priority nor a stream: never thinned, written in order (FIFO) at the pace the link allows;
//! - *stream*: the periodic telemetry of `telemetry.rs` broadcast to every peer (SYS_STATUS, ATTITUDE,
//!   ATTITUDE_QUATERNION, LOCAL_POSITION_NED, GLOBAL_POSITION_INT, GPS_RAW_INT, EXTENDED_SYS_STATE,
//!   HOME_POSITION, VFR_HUD, BATTERY_STATUS, MISSION_CURRENT, DEBUG_VECT, RC_CHANNELS: ids 1, 30, 31, 32,
//!   33, 24, 245, 242, 74, 147, 42, 250, 65, [`Stream::of_message`]), thinned. A stream is keyed by its
//!   message id, and a DEBUG_VECT also by its name (the weight vectors are five streams of one id).
//!
//! **Multiplier** ([`LinkGovernor::mult`]): `min(bandwidth_mult, radio_mult)` clamped to
//! [[`MULT_MIN`], 1], PX4's `Mavlink::update_rate_mult` (`src/modules/mavlink/mavlink_main.cpp`) with
//! measured rather than nominal rates. `bandwidth_mult = (data_rate - non_stream) / stream`: the offered
//! stream bytes/s (before thinning) and the priority and transfer bytes/s, each an exponentially decaying
//! average over [`RATE_TAU_US`]; 1 on an unlimited link (data rate 0). `radio_mult` follows the radio's
//! RADIO_STATUS `txbuf` (% of its transmit buffer free), on each report: below 25 halved, 25 to 35 × 0.8,
//! 35 to 50 held, above 50 × 1.25 (at most 1); no report for [`RADIO_TIMEOUT_US`] resets it to 1. (PX4
//! takes 0.8, 0.975 and 1.025 per report; the steps here are coarser, so a radio at 1 Hz is followed
//! within seconds.)
//!
//! **Thinning** by credit per stream: each offered message adds `mult` to its stream's credit and is kept
//! when the credit reaches 1 (which then loses 1), so a 20 Hz stream at 0.5 goes out at 10 Hz exactly on
//! average, at a steady spacing. A kept stream message waits as its stream's *pending* message: a newer
//! one of the same stream replaces it in place (counted as superseded), so a stream never queues.
//!
//! **Pacing**: a token bucket at the data rate, holding at most one frame's worth ([`MAX_FRAME_BYTES`]),
//! so that the bytes handed out over any window never exceed `data_rate × window + MAX_FRAME_BYTES` (an
//! item larger than a frame, a datagram counted for several destinations, may overdraw by its excess).
//! [`LinkGovernor::pop`] hands out the priority queue first, then the transfer queue, then the pending
//! stream messages in the order their streams became pending.

use std::collections::{BTreeMap, VecDeque};

use ::mavlink::Message;
use ::mavlink::dialects::common::MavMessage;

use super::telemetry::Stream;

/// The largest MAVLink 2 frame (280 bytes, signed): the pacer's bucket.
pub const MAX_FRAME_BYTES: usize = 280;
/// The lowest multiplier (PX4's 5 %: something of every stream always goes).
pub const MULT_MIN: f64 = 0.05;
/// RADIO_STATUS silence after which the radio's multiplier returns to 1 (µs).
pub const RADIO_TIMEOUT_US: u64 = 5_000_000;
/// Time constant of the measured offered rates (µs).
pub const RATE_TAU_US: u64 = 1_000_000;
/// The message ids that are never thinned and go first: HEARTBEAT, COMMAND_ACK, STATUSTEXT.
pub const PRIORITY_IDS: [u32; 3] = [0, 77, 253];
/// Items the priority queue holds; beyond, the oldest is dropped (and counted). Only a link whose data
/// rate is below its own heartbeats and acknowledgements could get there.
pub const PRIORITY_QUEUE_CAP: usize = 1024;
/// Items the transfer queue holds; beyond, the new one is dropped (and counted): 18 whole parameter
/// lists of the vehicle's table.
pub const TRANSFER_QUEUE_CAP: usize = 4096;
/// The multiplier's relative change that is reported at all ([`LinkGovernor::take_mult_report`]).
pub const MULT_REPORT_STEP: f64 = 0.1;

/// One stream: its message id and, for DEBUG_VECT, its name (zeros otherwise).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct StreamKey {
    pub message_id: u32,
    pub name: [u8; 10],
}

impl StreamKey {
    /// The stream of message id `message_id` (not a DEBUG_VECT).
    #[must_use]
    pub const fn of_id(message_id: u32) -> Self {
        Self { message_id, name: [0; 10] }
    }
}

/// How a message is treated on a governed link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// Never thinned, sent first.
    Priority,
    /// Never thinned, paced, in order.
    Transfer,
    /// Thinned by the multiplier; only the newest waits.
    Stream(StreamKey),
}

/// The class of `message`, going to one peer (`to_one_peer`: a reply) or to every one.
#[must_use]
pub fn classify(message: &MavMessage, to_one_peer: bool) -> Class {
    let id = message.message_id();
    if PRIORITY_IDS.contains(&id) {
        return Class::Priority;
    }
    if to_one_peer || Stream::of_message(id).is_none() {
        return Class::Transfer;
    }
    let name = match message {
        MavMessage::DEBUG_VECT(d) => *d.name,
        _ => [0; 10],
    };
    Class::Stream(StreamKey { message_id: id, name })
}

/// The counts of one class; every field only grows.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClassCounters {
    /// Messages offered.
    pub offered: u64,
    /// Messages handed out by [`LinkGovernor::pop`].
    pub sent: u64,
    /// Bytes handed out.
    pub sent_bytes: u64,
    /// Stream messages not kept by the multiplier's credit.
    pub thinned: u64,
    /// Pending stream messages replaced by a newer one of their stream before they went.
    pub superseded: u64,
    /// Messages dropped because their queue was full.
    pub dropped: u64,
}

/// What a governor has done, per class.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GovernorCounters {
    pub priority: ClassCounters,
    pub transfer: ClassCounters,
    pub stream: ClassCounters,
    /// RADIO_STATUS reports taken.
    pub radio_status: u64,
}

/// What became of an offered item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offered {
    /// Queued (a stream message: pending, possibly replacing an older one).
    Queued,
    /// A stream message the multiplier thinned out.
    Thinned,
    /// Dropped: its queue was full.
    Dropped,
}

/// A change of the multiplier worth telling ([`LinkGovernor::take_mult_report`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultReport {
    /// The multiplier now.
    pub mult: f64,
    /// The last one reported.
    pub previous: f64,
    /// More than a factor 2 from the last loud report (a log at info rather than debug).
    pub loud: bool,
    pub bandwidth_mult: f64,
    pub radio_mult: f64,
}

#[derive(Debug, Clone)]
struct Queued<T> {
    bytes: usize,
    item: T,
}

/// An offered rate in bytes/s, decaying with [`RATE_TAU_US`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct DecayingRate {
    bytes_per_s: f64,
}

impl DecayingRate {
    fn add(&mut self, bytes: usize) {
        self.bytes_per_s += bytes as f64 * 1e6 / RATE_TAU_US as f64;
    }

    fn decay(&mut self, dt_us: u64) {
        self.bytes_per_s *= (-(dt_us as f64) / RATE_TAU_US as f64).exp();
    }
}

/// The governor of one link; see the module docs.
#[derive(Debug, Clone)]
pub struct LinkGovernor<T> {
    /// Bytes per second; 0: unlimited.
    data_rate: u64,
    /// Byte-microseconds in the bucket (bytes × 10⁶); below zero only after an oversized item.
    tokens: i64,
    last_us: Option<u64>,
    priority: VecDeque<Queued<T>>,
    transfer: VecDeque<Queued<T>>,
    /// The pending message of each stream, in the order the streams became pending.
    pending: VecDeque<(StreamKey, Queued<T>)>,
    credit: BTreeMap<StreamKey, f64>,
    stream_rate: DecayingRate,
    other_rate: DecayingRate,
    bandwidth_mult: f64,
    radio_mult: f64,
    last_radio_us: Option<u64>,
    mult: f64,
    reported: f64,
    announced: f64,
    counters: GovernorCounters,
}

impl<T> LinkGovernor<T> {
    /// A governor for a link of `data_rate` bytes/s (0: unlimited, nothing is paced and only a radio's
    /// reports thin the streams).
    #[must_use]
    pub fn new(data_rate: u64) -> Self {
        Self {
            data_rate,
            tokens: Self::bucket(),
            last_us: None,
            priority: VecDeque::new(),
            transfer: VecDeque::new(),
            pending: VecDeque::new(),
            credit: BTreeMap::new(),
            stream_rate: DecayingRate::default(),
            other_rate: DecayingRate::default(),
            bandwidth_mult: 1.0,
            radio_mult: 1.0,
            last_radio_us: None,
            mult: 1.0,
            reported: 1.0,
            announced: 1.0,
            counters: GovernorCounters::default(),
        }
    }

    const fn bucket() -> i64 {
        MAX_FRAME_BYTES as i64 * 1_000_000
    }

    /// The data rate (bytes/s; 0: unlimited).
    #[must_use]
    pub fn data_rate(&self) -> u64 {
        self.data_rate
    }

    /// The stream multiplier now, in [[`MULT_MIN`], 1].
    #[must_use]
    pub fn mult(&self) -> f64 {
        self.mult
    }

    /// The bandwidth's part of the multiplier (unclamped, at most 1 is not enforced).
    #[must_use]
    pub fn bandwidth_mult(&self) -> f64 {
        self.bandwidth_mult
    }

    /// The radio's part of the multiplier.
    #[must_use]
    pub fn radio_mult(&self) -> f64 {
        self.radio_mult
    }

    /// The measured offered rates (bytes/s): streams (before thinning), and everything else.
    #[must_use]
    pub fn offered_rates(&self) -> (f64, f64) {
        (self.stream_rate.bytes_per_s, self.other_rate.bytes_per_s)
    }

    #[must_use]
    pub fn counters(&self) -> &GovernorCounters {
        &self.counters
    }

    /// Items waiting: (priority, transfer, pending streams).
    #[must_use]
    pub fn queued(&self) -> (usize, usize, usize) {
        (self.priority.len(), self.transfer.len(), self.pending.len())
    }

    /// Nothing waits.
    #[must_use]
    pub fn is_idle(&self) -> bool {
        self.priority.is_empty() && self.transfer.is_empty() && self.pending.is_empty()
    }

    /// Advances the clock to `now_us`: refills the bucket, decays the measured rates, times the radio out
    /// and recomputes the multiplier. Every other call does this first; a clock that goes back is held.
    pub fn update(&mut self, now_us: u64) {
        let dt_us = self.last_us.map_or(0, |last| now_us.saturating_sub(last));
        self.last_us = Some(self.last_us.map_or(now_us, |last| last.max(now_us)));
        if dt_us > 0 {
            let gained = i64::try_from(u128::from(self.data_rate) * u128::from(dt_us)).unwrap_or(i64::MAX);
            self.tokens = self.tokens.saturating_add(gained).min(Self::bucket());
            self.stream_rate.decay(dt_us);
            self.other_rate.decay(dt_us);
        }
        if self.last_radio_us.is_some_and(|t| now_us.saturating_sub(t) > RADIO_TIMEOUT_US) {
            self.last_radio_us = None;
            self.radio_mult = 1.0;
        }
        self.bandwidth_mult = if self.data_rate == 0 || self.stream_rate.bytes_per_s <= 0.0 {
            1.0
        } else {
            (self.data_rate as f64 - self.other_rate.bytes_per_s) / self.stream_rate.bytes_per_s
        };
        let mult = self.bandwidth_mult.min(self.radio_mult);
        self.mult = if mult.is_nan() { MULT_MIN } else { mult.clamp(MULT_MIN, 1.0) };
    }

    /// A RADIO_STATUS from the link's radio at `now_us`, with `txbuf` % of its transmit buffer free.
    pub fn on_radio_status(&mut self, now_us: u64, txbuf: u8) {
        self.counters.radio_status += 1;
        self.radio_mult = match txbuf {
            0..25 => self.radio_mult * 0.5,
            25..35 => self.radio_mult * 0.8,
            35..=50 => self.radio_mult,
            _ => self.radio_mult * 1.25,
        }
        .clamp(MULT_MIN, 1.0);
        self.last_radio_us = Some(now_us);
        self.update(now_us);
    }

    /// Offers `message` (to one peer or to all) as `item` of `bytes` at `now_us`, classed by [`classify`].
    pub fn offer_message(
        &mut self,
        now_us: u64,
        message: &MavMessage,
        to_one_peer: bool,
        bytes: usize,
        item: T,
    ) -> Offered {
        self.offer(now_us, classify(message, to_one_peer), bytes, item)
    }

    /// Offers `item` of class `class`, `bytes` long, at `now_us`.
    pub fn offer(&mut self, now_us: u64, class: Class, bytes: usize, item: T) -> Offered {
        self.update(now_us);
        let queued = Queued { bytes, item };
        match class {
            Class::Priority => {
                self.counters.priority.offered += 1;
                self.other_rate.add(bytes);
                if self.priority.len() >= PRIORITY_QUEUE_CAP {
                    self.priority.pop_front();
                    self.counters.priority.dropped += 1;
                }
                self.priority.push_back(queued);
                Offered::Queued
            }
            Class::Transfer => {
                self.counters.transfer.offered += 1;
                self.other_rate.add(bytes);
                if self.transfer.len() >= TRANSFER_QUEUE_CAP {
                    self.counters.transfer.dropped += 1;
                    return Offered::Dropped;
                }
                self.transfer.push_back(queued);
                Offered::Queued
            }
            Class::Stream(key) => {
                self.counters.stream.offered += 1;
                self.stream_rate.add(bytes);
                // A stream seen for the first time goes at once.
                let credit = self.credit.entry(key).or_insert(1.0 - self.mult);
                *credit += self.mult;
                if *credit < 1.0 {
                    self.counters.stream.thinned += 1;
                    return Offered::Thinned;
                }
                *credit = (*credit - 1.0).min(1.0);
                match self.pending.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, old)) => {
                        *old = queued;
                        self.counters.stream.superseded += 1;
                    }
                    None => self.pending.push_back((key, queued)),
                }
                Offered::Queued
            }
        }
    }

    /// The size of the next item [`Self::pop`] would hand out, if any.
    fn next_bytes(&self) -> Option<usize> {
        self.priority
            .front()
            .or_else(|| self.transfer.front())
            .or_else(|| self.pending.front().map(|(_, q)| q))
            .map(|q| q.bytes)
    }

    fn need(bytes: usize) -> i64 {
        bytes.min(MAX_FRAME_BYTES) as i64 * 1_000_000
    }

    /// The next item the link may write at `now_us`, if any: the priority queue first, then the transfer
    /// queue, then the pending streams; `None` when nothing waits or the bucket does not hold its bytes.
    pub fn pop(&mut self, now_us: u64) -> Option<T> {
        self.update(now_us);
        let bytes = self.next_bytes()?;
        if self.data_rate > 0 {
            if self.tokens < Self::need(bytes) {
                return None;
            }
            self.tokens -= bytes as i64 * 1_000_000;
        }
        let (queued, counters) = if let Some(q) = self.priority.pop_front() {
            (q, &mut self.counters.priority)
        } else if let Some(q) = self.transfer.pop_front() {
            (q, &mut self.counters.transfer)
        } else {
            (self.pending.pop_front()?.1, &mut self.counters.stream)
        };
        counters.sent += 1;
        counters.sent_bytes += queued.bytes as u64;
        Some(queued.item)
    }

    /// µs from `now_us` until [`Self::pop`] will hand out the next item (0: now); `None` when nothing
    /// waits.
    pub fn next_ready_in_us(&mut self, now_us: u64) -> Option<u64> {
        self.update(now_us);
        let bytes = self.next_bytes()?;
        if self.data_rate == 0 {
            return Some(0);
        }
        let missing = u64::try_from(Self::need(bytes) - self.tokens).unwrap_or(0);
        Some(missing.div_ceil(self.data_rate))
    }

    /// The multiplier when it has moved by [`MULT_REPORT_STEP`] or more (relative) since the last report,
    /// `loud` when by more than a factor 2 since the last loud one.
    pub fn take_mult_report(&mut self) -> Option<MultReport> {
        let moved = (self.mult / self.reported - 1.0).abs();
        if moved < MULT_REPORT_STEP && !(self.mult == 1.0 && self.reported != 1.0) {
            return None;
        }
        let ratio = self.mult / self.announced;
        let loud = !(0.5..=2.0).contains(&ratio);
        if loud {
            self.announced = self.mult;
        }
        let report = MultReport {
            mult: self.mult,
            previous: self.reported,
            loud,
            bandwidth_mult: self.bandwidth_mult,
            radio_mult: self.radio_mult,
        };
        self.reported = self.mult;
        Some(report)
    }
}

#[cfg(test)]
mod tests;

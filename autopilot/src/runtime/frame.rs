//! MAVLink framing for the ground-station links: (header, message) -> MAVLink 2 bytes out; TCP/serial
//! byte streams and UDP datagrams -> `(header, message, version)` in, counting what was dropped in
//! [`LinkStats`] instead of failing.
//!
//! The parsing itself is the core's [`FrameDecoder`] (`core::mavlink::frame`, shared with the plant link): it reads
//! v2 and v1, decodes signed v2 frames (incompat flag 0x01) keeping their bytes for the links' signing
//! check (`runtime::signing`), checks CRC_EXTRA, never panics on garbage and resynchronises on the next
//! start byte. This
//! module reuses it rather than keeping a second decoder; it adds per-link counters shared between a
//! link's tasks.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

pub use crate::core::mavlink::frame::{DecodedFrame, DecoderStats, FrameDecoder};

/// One message as a MAVLink 2 frame (unsigned, payload zero-truncated).
#[must_use]
pub fn encode_v2(header: MavHeader, message: &MavMessage) -> Vec<u8> {
    crate::core::mavlink::frame::encode_frame_v2(header, message)
}

/// One message as a frame of `version`: used to log received frames in the version they arrived in.
/// A v1 request for a message id above 255 or a system id above 255 falls back to v2.
#[must_use]
pub fn encode(header: MavHeader, message: &MavMessage, version: MavlinkVersion) -> Vec<u8> {
    match version {
        MavlinkVersion::V1 => {
            crate::core::mavlink::frame::encode_frame_v1(header, message).unwrap_or_else(|| encode_v2(header, message))
        }
        MavlinkVersion::V2 => encode_v2(header, message),
    }
}

/// A snapshot of one link's counters; every field only grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Valid frames received and passed on to the core.
    pub frames_in: u64,
    /// Datagrams (UDP: several frames may be packed in one) or frames (TCP, serial) sent; a broadcast to
    /// three peers counts three.
    pub frames_out: u64,
    /// Frames dropped by the decoder: bad CRC, truncated, unknown message id, unknown incompat flags,
    /// unparsable payload.
    pub malformed: u64,
    /// Bytes outside any frame (line noise, a garbage datagram with no start byte).
    pub garbage_bytes: u64,
    /// Bytes received.
    pub bytes_in: u64,
    /// Bytes sent.
    pub bytes_out: u64,
    /// Valid frames dropped because the core's channel was full.
    pub dropped_in: u64,
    /// Sends that failed (a ground station not listening, a full socket buffer); the link keeps going.
    pub send_errors: u64,
    /// Valid frames dropped by MAVLink signing: unsigned, wrongly signed, replayed or stale
    /// (`runtime::signing`).
    pub signature_rejected: u64,
}

/// The live counters of one link, shared by its tasks; [`LinkCounters::snapshot`] reads them.
#[derive(Debug, Default)]
pub struct LinkCounters {
    frames_in: AtomicU64,
    frames_out: AtomicU64,
    malformed: AtomicU64,
    garbage_bytes: AtomicU64,
    bytes_in: AtomicU64,
    bytes_out: AtomicU64,
    dropped_in: AtomicU64,
    send_errors: AtomicU64,
    signature_rejected: AtomicU64,
}

impl LinkCounters {
    /// Fresh counters, shareable.
    #[must_use]
    pub fn new_shared() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// The counters now.
    #[must_use]
    pub fn snapshot(&self) -> LinkStats {
        LinkStats {
            frames_in: self.frames_in.load(Ordering::Relaxed),
            frames_out: self.frames_out.load(Ordering::Relaxed),
            malformed: self.malformed.load(Ordering::Relaxed),
            garbage_bytes: self.garbage_bytes.load(Ordering::Relaxed),
            bytes_in: self.bytes_in.load(Ordering::Relaxed),
            bytes_out: self.bytes_out.load(Ordering::Relaxed),
            dropped_in: self.dropped_in.load(Ordering::Relaxed),
            send_errors: self.send_errors.load(Ordering::Relaxed),
            signature_rejected: self.signature_rejected.load(Ordering::Relaxed),
        }
    }

    pub(crate) fn add_frame_in(&self) {
        self.frames_in.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn add_sent(&self, len_bytes: usize) {
        self.frames_out.fetch_add(1, Ordering::Relaxed);
        self.bytes_out.fetch_add(len_bytes as u64, Ordering::Relaxed);
    }

    pub(crate) fn add_dropped_in(&self) {
        self.dropped_in.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn add_signature_rejected(&self) {
        self.signature_rejected.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn add_send_error(&self) {
        self.send_errors.fetch_add(1, Ordering::Relaxed);
    }
}

/// A [`FrameDecoder`] that reports into a link's [`LinkCounters`]. One per TCP client / serial port, one
/// per UDP socket (datagrams are decoded whole, so peers cannot mix).
#[derive(Debug)]
pub struct CountingDecoder {
    inner: FrameDecoder,
    counters: Arc<LinkCounters>,
}

impl CountingDecoder {
    #[must_use]
    pub fn new(counters: Arc<LinkCounters>) -> Self {
        Self { inner: FrameDecoder::new(), counters }
    }

    /// Stream bytes (TCP, serial): frames completed by them; an incomplete tail waits for more.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<DecodedFrame> {
        let before = self.inner.stats();
        let frames = self.inner.push(bytes);
        self.account(before, bytes.len());
        frames
    }

    /// One whole UDP datagram: an incomplete frame at its end is counted as truncated.
    pub fn decode_datagram(&mut self, datagram: &[u8]) -> Vec<DecodedFrame> {
        let before = self.inner.stats();
        let frames = self.inner.decode_datagram(datagram);
        self.account(before, datagram.len());
        frames
    }

    /// End of a stream: an incomplete frame left over is counted as truncated.
    pub fn finish(&mut self) -> Vec<DecodedFrame> {
        let before = self.inner.stats();
        let frames = self.inner.finish();
        self.account(before, 0);
        frames
    }

    fn account(&self, before: DecoderStats, len_bytes: usize) {
        let after = self.inner.stats();
        let c = &self.counters;
        c.bytes_in.fetch_add(len_bytes as u64, Ordering::Relaxed);
        c.malformed.fetch_add(after.malformed() - before.malformed(), Ordering::Relaxed);
        c.garbage_bytes.fetch_add(after.garbage_bytes - before.garbage_bytes, Ordering::Relaxed);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use mavlink::Message as _;
    use mavlink::dialects::common::SYSTEM_TIME_DATA;

    pub(crate) fn heartbeat(system_id: u32, sequence: u8) -> (MavHeader, MavMessage) {
        let header = MavHeader { system_id, component_id: 1, sequence };
        (header, crate::core::mavlink::gcs_heartbeat())
    }

    /// `frame` (v2, unsigned) re-made as a signed frame with a dummy 13-byte signature.
    pub(crate) fn signed(frame: &[u8], msg_id: u32) -> Vec<u8> {
        let mut out = frame.to_vec();
        out[2] |= 0x01;
        let crc_at = out.len() - 2;
        let crc = mavlink::calculate_crc(&out[1..crc_at], MavMessage::extra_crc(msg_id));
        out[crc_at..].copy_from_slice(&crc.to_le_bytes());
        out.extend_from_slice(&[7u8; 13]);
        out
    }

    #[test]
    fn v2_round_trip_and_counters() {
        let counters = LinkCounters::new_shared();
        let mut dec = CountingDecoder::new(counters.clone());
        let (h, m) = heartbeat(255, 9);
        let bytes = encode_v2(h, &m);
        let frames = dec.decode_datagram(&bytes);
        assert_eq!(frames, vec![DecodedFrame { version: MavlinkVersion::V2, header: h, message: m, signed_raw: None }]);
        let s = counters.snapshot();
        assert_eq!((s.bytes_in, s.malformed, s.garbage_bytes), (bytes.len() as u64, 0, 0));
    }

    #[test]
    fn v1_and_signed_v2_are_read() {
        let counters = LinkCounters::new_shared();
        let mut dec = CountingDecoder::new(counters.clone());
        let (h, m) = heartbeat(200, 3);
        let v1 = encode(h, &m, MavlinkVersion::V1);
        assert_eq!(v1[0], 0xFE);
        let ping = MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA { time_unix_usec: 42, time_boot_ms: 7 });
        let signed_ping = signed(&encode_v2(h, &ping), 2);
        let mut stream = v1.clone();
        stream.extend_from_slice(&signed_ping);
        stream.extend_from_slice(&encode_v2(h, &m));
        // Byte by byte, as a slow serial line delivers it.
        let mut got = Vec::new();
        for b in &stream {
            got.extend(dec.push(std::slice::from_ref(b)));
        }
        let versions: Vec<_> = got.iter().map(|f| f.version).collect();
        assert_eq!(versions, vec![MavlinkVersion::V1, MavlinkVersion::V2, MavlinkVersion::V2]);
        assert_eq!(got[1].message, ping);
        assert_eq!(counters.snapshot().malformed, 0);
    }

    #[test]
    fn garbage_bad_crc_truncated_and_unknown_id_are_counted_then_resynchronised() {
        let counters = LinkCounters::new_shared();
        let mut dec = CountingDecoder::new(counters.clone());
        let (h, m) = heartbeat(1, 0);
        let good = encode_v2(h, &m);
        let mut bad_crc = good.clone();
        let last = bad_crc.len() - 1;
        bad_crc[last] ^= 0xFF;
        let mut unknown = good.clone();
        unknown[7..10].copy_from_slice(&[0x77, 0x77, 0x00]); // message id 30583: not in common
        let mut stream = vec![0x00, 0x11, 0x22];
        stream.extend_from_slice(&bad_crc);
        stream.extend_from_slice(&unknown);
        stream.extend_from_slice(&good[..good.len() - 3]); // truncated by the next frame's start
        stream.extend_from_slice(&good);
        let frames = dec.push(&stream);
        assert_eq!(frames.len(), 1, "only the last good frame survives");
        assert_eq!(frames[0].message, m);
        let s = counters.snapshot();
        assert!(s.malformed >= 3, "{s:?}");
        assert!(s.garbage_bytes >= 3, "{s:?}");
    }

    #[test]
    fn random_garbage_never_panics() {
        let counters = LinkCounters::new_shared();
        let mut dec = CountingDecoder::new(counters);
        let mut x: u32 = 0x1234_5678;
        let mut bytes = Vec::new();
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            bytes.push((x & 0xFF) as u8);
        }
        for chunk in bytes.chunks(97) {
            let _ = dec.push(chunk);
            let _ = dec.decode_datagram(chunk);
        }
        let _ = dec.finish();
    }
}

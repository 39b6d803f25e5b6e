//! MAVLink framing, pure (no sockets): one message as a v2 or v1 frame out, and frames found in a byte
//! stream or a datagram in, for the plant link and the ground-station links alike.
//!
//! [`FrameDecoder`] finds MAVLink v2 (0xFD) and v1 (0xFE) frames in a byte stream, checks the CRC (with the
//! message's CRC_EXTRA), drops and counts bad frames ([`DecoderStats`]) and resynchronises on the next
//! start byte after a bad one, so a corrupted frame never costs the good frame after it. Signed v2 frames
//! are decoded with their bytes kept (`DecodedFrame::signed_raw`); verifying them is the ground-station
//! links' job (`core::mavlink::signing`), the plant link does not sign.

use ::mavlink::dialects::common::MavMessage;
use ::mavlink::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavHeader, MavlinkVersion, Message};

/// One message as a MAVLink 2 frame (unsigned; payload zero-truncated as the protocol requires).
#[must_use]
pub fn encode_frame_v2(header: MavHeader, msg: &MavMessage) -> Vec<u8> {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(header, msg);
    raw.raw_bytes().to_vec()
}

/// One message as a MAVLink 1 frame, or `None` for a message id above 255 (v1 cannot carry it).
#[must_use]
pub fn encode_frame_v1(header: MavHeader, msg: &MavMessage) -> Option<Vec<u8>> {
    if msg.message_id() > 255 || header.system_id > 255 {
        return None;
    }
    let mut raw = MAVLinkV1MessageRaw::new();
    raw.serialize_message(header, msg);
    Some(raw.raw_bytes().to_vec())
}

/// A complete, CRC-checked message out of [`FrameDecoder`].
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedFrame {
    pub version: MavlinkVersion,
    pub header: MavHeader,
    pub message: MavMessage,
    /// A signed frame's bytes, start byte through signature, for the link to verify
    /// (`core::mavlink::signing`); None for an unsigned frame.
    pub signed_raw: Option<Vec<u8>>,
}

/// What [`FrameDecoder`] found and dropped; every field only grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecoderStats {
    /// Frames decoded and returned.
    pub frames_ok: u64,
    /// Bytes skipped while looking for a start byte (0xFD/0xFE).
    pub garbage_bytes: u64,
    /// Frames whose checksum did not match.
    pub bad_crc: u64,
    /// Frames cut short by the end of a datagram or of the input ([`FrameDecoder::finish`]).
    pub truncated: u64,
    /// v2 frames with incompatibility flags this decoder does not know.
    pub bad_flags: u64,
    /// Frames with a message id outside the common dialect (their CRC cannot be checked).
    pub unknown_id: u64,
    /// Frames with a good checksum whose payload did not parse (bad enum value, oversized payload).
    pub parse_errors: u64,
}

impl DecoderStats {
    /// Frames dropped for any reason (garbage bytes not counted).
    #[must_use]
    pub fn malformed(&self) -> u64 {
        self.bad_crc + self.truncated + self.bad_flags + self.unknown_id + self.parse_errors
    }
}

const STX_V1: u8 = mavlink::MAV_STX;
const STX_V2: u8 = mavlink::MAV_STX_V2;
const V1_HEADER_LEN: usize = 6; // STX + len, seq, sysid, compid, msgid
const V2_HEADER_LEN: usize = 10; // STX + len, incompat, compat, seq, sysid, compid, msgid (3)
const SYSID32_EXTRA_LEN: usize = 3;
const IFLAG_SIGNED: u8 = 0x01;
const IFLAG_SYSID32: u8 = 0x02;
const SIGNATURE_LEN: usize = 13;
const CRC_LEN: usize = 2;

/// What the buffer's start holds.
enum Scan {
    /// A frame was taken or dropped; continue.
    Progress,
    /// The frame at the start is incomplete.
    NeedMore,
}

/// Incremental MAVLink v2/v1 frame decoder: [`FrameDecoder::push`] a serial stream's bytes as they come,
/// or [`FrameDecoder::decode_datagram`] one UDP datagram (a datagram holds whole frames: what is left
/// incomplete at its end is counted as truncated). Bad frames are counted in [`DecoderStats`] and dropped
/// by skipping their start byte only, so a good frame inside or after them is still found. Memory is
/// bounded by one maximum frame (283 bytes with a 32-bit system id; less is kept between reads) plus the
/// latest input.
#[derive(Debug, Clone, Default)]
pub struct FrameDecoder {
    buf: Vec<u8>,
    stats: DecoderStats,
}

impl FrameDecoder {
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The counters so far.
    #[must_use]
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes held back waiting for the rest of a frame.
    #[must_use]
    pub fn pending_len(&self) -> usize {
        self.buf.len()
    }

    /// Feed stream bytes; returns the frames completed by them, in order. An incomplete frame at the end
    /// waits for the next call.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<DecodedFrame> {
        self.buf.extend_from_slice(bytes);
        let mut out = Vec::new();
        self.drain(&mut out, false);
        out
    }

    /// End of input: an incomplete frame left over is counted as truncated and the bytes after its
    /// start byte are searched again; returns any frames found in them.
    pub fn finish(&mut self) -> Vec<DecodedFrame> {
        let mut out = Vec::new();
        self.drain(&mut out, true);
        out
    }

    /// One whole datagram: [`FrameDecoder::push`] then [`FrameDecoder::finish`].
    pub fn decode_datagram(&mut self, datagram: &[u8]) -> Vec<DecodedFrame> {
        let mut out = self.push(datagram);
        out.extend(self.finish());
        out
    }

    fn drain(&mut self, out: &mut Vec<DecodedFrame>, at_end: bool) {
        let mut start = 0;
        while start < self.buf.len() {
            let Some(offset) = self.buf[start..].iter().position(|&b| b == STX_V1 || b == STX_V2) else {
                self.stats.garbage_bytes += (self.buf.len() - start) as u64;
                start = self.buf.len();
                break;
            };
            self.stats.garbage_bytes += offset as u64;
            start += offset;
            match self.scan_frame(start, out) {
                Ok(len) => start += len,
                Err(Scan::Progress) => start += 1,
                Err(Scan::NeedMore) if at_end => {
                    self.stats.truncated += 1;
                    start += 1;
                }
                Err(Scan::NeedMore) => break,
            }
        }
        self.buf.drain(..start);
    }

    /// Look at the frame starting at `self.buf[start]` (a start byte): `Ok(frame length)` when it was
    /// decoded, `Err(Progress)` when it was dropped (skip its start byte), `Err(NeedMore)` when incomplete.
    fn scan_frame(&mut self, start: usize, out: &mut Vec<DecodedFrame>) -> Result<usize, Scan> {
        let frame = &self.buf[start..];
        let version = if frame[0] == STX_V2 { MavlinkVersion::V2 } else { MavlinkVersion::V1 };
        let header_len = match version {
            MavlinkVersion::V1 => V1_HEADER_LEN,
            MavlinkVersion::V2 => V2_HEADER_LEN,
        };
        if frame.len() < 3 {
            return Err(Scan::NeedMore);
        }
        let payload_len = usize::from(frame[1]);
        let (header_len, trailer_len, sysid32) = match version {
            MavlinkVersion::V1 => (header_len, 0, false),
            MavlinkVersion::V2 => {
                let incompat = frame[2];
                if incompat & !(IFLAG_SIGNED | IFLAG_SYSID32) != 0 {
                    self.stats.bad_flags += 1;
                    return Err(Scan::Progress);
                }
                let sysid32 = incompat & IFLAG_SYSID32 != 0;
                let extra = if sysid32 { SYSID32_EXTRA_LEN } else { 0 };
                let trailer = if incompat & IFLAG_SIGNED != 0 { SIGNATURE_LEN } else { 0 };
                (header_len + extra, trailer, sysid32)
            }
        };
        let frame_len = header_len + payload_len + CRC_LEN + trailer_len;
        if frame.len() < frame_len {
            return Err(Scan::NeedMore);
        }
        let frame = &frame[..frame_len];
        let (header, msg_id) = match version {
            MavlinkVersion::V1 => (
                MavHeader { sequence: frame[2], system_id: u32::from(frame[3]), component_id: frame[4] },
                u32::from(frame[5]),
            ),
            MavlinkVersion::V2 => {
                let (system_id, rest) = if sysid32 {
                    (u32::from_le_bytes([frame[5], frame[6], frame[7], frame[8]]), &frame[9..])
                } else {
                    (u32::from(frame[5]), &frame[6..])
                };
                (
                    MavHeader { sequence: frame[4], system_id, component_id: rest[0] },
                    u32::from_le_bytes([rest[1], rest[2], rest[3], 0]),
                )
            }
        };
        if MavMessage::default_message_from_id(msg_id).is_none() {
            self.stats.unknown_id += 1;
            return Err(Scan::Progress);
        }
        let crc_at = header_len + payload_len;
        let crc = u16::from_le_bytes([frame[crc_at], frame[crc_at + 1]]);
        if crc != mavlink::calculate_crc(&frame[1..crc_at], MavMessage::extra_crc(msg_id)) {
            self.stats.bad_crc += 1;
            return Err(Scan::Progress);
        }
        match MavMessage::parse(version, msg_id, &frame[header_len..crc_at]) {
            Ok(message) => {
                self.stats.frames_ok += 1;
                let signed_raw = (trailer_len > 0).then(|| frame.to_vec());
                out.push(DecodedFrame { version, header, message, signed_raw });
                Ok(frame_len)
            }
            Err(_) => {
                self.stats.parse_errors += 1;
                Ok(frame_len)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimator::GeoOrigin;
    use crate::core::plant_link::{ActuatorCommand, HilInput, decode_hil_message, encode_actuator_controls};
    use proptest::prelude::*;

    const HOME: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };

    fn header() -> MavHeader {
        MavHeader { system_id: 1, component_id: 1, sequence: 7 }
    }

    fn actuator_frame(t: u64, pwm: [f64; 4]) -> Vec<u8> {
        let cmd = ActuatorCommand { time_us: t, pwm_us: pwm, armed: true, motor_test: false };
        encode_frame_v2(header(), &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)))
    }

    proptest! {
        #[test]
        fn decoder_survives_garbage_and_decodes_the_frame_after_it(
            garbage in prop::collection::vec(any::<u8>(), 0..600), split in 0usize..700,
        ) {
            let good = actuator_frame(42, [1500.0; 4]);
            let mut stream = garbage.clone();
            stream.extend_from_slice(&good);
            // As a datagram: the good frame at the end is always found.
            let mut dec = FrameDecoder::new();
            let frames = dec.decode_datagram(&stream);
            prop_assert!(frames.iter().any(|f| matches!(&f.message, MavMessage::HIL_ACTUATOR_CONTROLS(m) if m.time_usec == 42)));
            prop_assert_eq!(dec.pending_len(), 0);
            // As a stream cut anywhere, then the end of input.
            let split = split.min(stream.len());
            let mut dec = FrameDecoder::new();
            let mut frames = dec.push(&stream[..split]);
            frames.extend(dec.push(&stream[split..]));
            frames.extend(dec.finish());
            prop_assert!(frames.iter().any(|f| matches!(&f.message, MavMessage::HIL_ACTUATOR_CONTROLS(m) if m.time_usec == 42)));
        }

        #[test]
        fn decoder_never_panics_on_random_bytes(bytes in prop::collection::vec(any::<u8>(), 0..2000)) {
            let mut dec = FrameDecoder::new();
            let _ = dec.push(&bytes);
            let _ = dec.finish();
            prop_assert_eq!(dec.pending_len(), 0);
        }
    }

    #[test]
    fn decoder_counts_bad_crc_truncation_and_unknown_ids_and_keeps_sync() {
        let good = actuator_frame(1, [1100.0; 4]);
        let mut bad_crc = actuator_frame(2, [1200.0; 4]);
        let n = bad_crc.len();
        bad_crc[n - 1] ^= 0xFF;
        let mut bad_payload = actuator_frame(3, [1300.0; 4]);
        bad_payload[12] ^= 0x01;
        let truncated = &actuator_frame(4, [1400.0; 4])[..20];
        // v2 frame with an unused msg id 0xABCDEF, a plausible length and junk.
        let unknown = [0xFD, 4, 0, 0, 0, 1, 1, 0xEF, 0xCD, 0xAB, 1, 2, 3, 4, 0, 0];
        let bad_flags = [0xFD, 4, 0x80, 0, 0, 1, 1, 93, 0, 0];

        let mut stream = Vec::new();
        for part in [&bad_crc[..], truncated, &unknown, &bad_flags, &bad_payload, &good] {
            stream.extend_from_slice(part);
        }
        let mut dec = FrameDecoder::new();
        let frames = dec.decode_datagram(&stream);
        assert_eq!(frames.len(), 1, "{frames:?}");
        assert!(matches!(&frames[0].message, MavMessage::HIL_ACTUATOR_CONTROLS(m) if m.time_usec == 1));
        let s = dec.stats();
        assert_eq!(s.frames_ok, 1);
        assert!(s.bad_crc >= 2, "{s:?}"); // the flipped CRC and payload (and the truncated one read on)
        assert!(s.unknown_id >= 1 && s.bad_flags >= 1, "{s:?}");
        assert!(s.malformed() >= 5, "{s:?}");

        // A truncated frame at the end of a datagram is counted, and the next datagram decodes.
        let mut dec = FrameDecoder::new();
        assert!(dec.decode_datagram(truncated).is_empty());
        assert_eq!(dec.stats().truncated, 1);
        assert_eq!(dec.decode_datagram(&good).len(), 1);

        // On a stream, a truncated frame waits; the bytes after it fail its CRC and are rescanned.
        let mut dec = FrameDecoder::new();
        assert!(dec.push(truncated).is_empty());
        assert_eq!(dec.pending_len(), truncated.len());
        let mut frames = dec.push(&good);
        frames.extend(dec.push(&good));
        frames.extend(dec.finish());
        assert_eq!(frames.len(), 2, "{:?}", dec.stats());
        assert!(dec.stats().malformed() >= 1);
    }

    #[test]
    fn decoder_reads_v1_frames_several_per_datagram_and_byte_by_byte() {
        let cmd =
            ActuatorCommand { time_us: 9, pwm_us: [1000.0, 1250.0, 1500.0, 2000.0], armed: true, motor_test: false };
        let msg = MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd));
        let v1 = encode_frame_v1(header(), &msg).expect("id 93 fits v1");
        let v2 = encode_frame_v2(header(), &msg);
        let stream: Vec<u8> = [v1.clone(), v2.clone(), v1].concat();
        let mut dec = FrameDecoder::new();
        let mut frames = Vec::new();
        for b in &stream {
            frames.extend(dec.push(std::slice::from_ref(b)));
        }
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[0].version, MavlinkVersion::V1);
        assert_eq!(frames[1].version, MavlinkVersion::V2);
        assert_eq!(frames[1].header, header());
        for f in &frames {
            assert_eq!(decode_hil_message(&f.message, &HOME), Some(HilInput::Actuators(cmd)));
        }
        assert_eq!(dec.stats(), DecoderStats { frames_ok: 3, ..DecoderStats::default() });
    }
}

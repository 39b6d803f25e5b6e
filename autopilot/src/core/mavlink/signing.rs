//! MAVLink 2 message signing, as the MAVLink specification defines it, pure: no clocks, sockets or files.
//! In: the 32-byte secret key, this side's link id, frames as bytes with the time as a signing
//! timestamp (units of 10 µs since 2015-01-01 00:00 UTC, which the shell reads from the wall clock). Out:
//! signed frames, and for each received frame a [`Verdict`]: accepted, or why it is dropped.
//!
//! - Signing an outgoing frame sets the SIGNED incompatibility flag, recomputes the CRC over the changed
//!   header, and appends the 13-byte signature: link id, 48-bit timestamp, and the first 6 bytes of
//!   SHA-256(key ‖ the frame from its start byte through the CRC ‖ link id ‖ timestamp). Timestamps only
//!   grow: each is at least one more than the last, whatever the clock says.
//! - A received signed frame is accepted when its signature is the key's and its timestamp is newer
//!   than the last accepted one of its stream (its link id, system and component), or, for a stream not
//!   seen yet, no more than a minute older than this side's own timestamp; an accepted timestamp moves
//!   this side's timestamp forward.
//! - A received unsigned frame is accepted only for the messages the specification lets an
//!   implementation take unsigned; this one takes RADIO_STATUS (a radio's own report) and nothing else.

use std::collections::HashMap;
use std::fmt;

use sha2::{Digest, Sha256};

/// The SIGNED incompatibility flag of a MAVLink 2 frame.
pub const IFLAG_SIGNED: u8 = 0x01;
/// Bytes of the signature block: link id (1), timestamp (6), signature (6).
pub const SIGNATURE_LEN: usize = 13;
/// A minute in signing-timestamp units (10 µs).
pub const ONE_MINUTE_TS: u64 = 60 * 100_000;
/// The messages accepted unsigned while signing is on: RADIO_STATUS (109).
pub const UNSIGNED_ALLOWED: [u32; 1] = [109];

/// Signing time of a Unix time (µs): units of 10 µs since 2015-01-01 00:00:00 UTC (0 before then).
#[must_use]
pub fn timestamp_of_unix_us(unix_us: u128) -> u64 {
    const EPOCH_2015_US: u128 = 1_420_070_400 * 1_000_000;
    u64::try_from(unix_us.saturating_sub(EPOCH_2015_US) / 10).unwrap_or(u64::MAX) & 0xFFFF_FFFF_FFFF
}

/// A secret key: 32 bytes. Its `Debug` never shows them.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct SecretKey(pub [u8; 32]);

impl fmt::Debug for SecretKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("SecretKey(..)")
    }
}

impl SecretKey {
    /// The all-zero key, which SETUP_SIGNING sends to turn signing off.
    #[must_use]
    pub fn is_zero(&self) -> bool {
        self.0.iter().all(|&b| b == 0)
    }

    /// The key of a key file: 64 hexadecimal digits (surrounding whitespace ignored).
    ///
    /// # Errors
    /// A text that is not exactly 64 hexadecimal digits, or the all-zero key.
    pub fn from_hex(text: &str) -> Result<Self, String> {
        let text = text.trim();
        if text.len() != 64 || !text.is_ascii() {
            return Err(format!("a signing key is 64 hexadecimal digits, found {} characters", text.len()));
        }
        let mut key = [0u8; 32];
        for (i, byte) in key.iter_mut().enumerate() {
            *byte = u8::from_str_radix(&text[2 * i..2 * i + 2], 16)
                .map_err(|_| format!("a signing key is 64 hexadecimal digits; {:?} is not", &text[2 * i..2 * i + 2]))?;
        }
        let key = Self(key);
        if key.is_zero() {
            return Err("the all-zero key means \"no signing\"; it cannot be a key".into());
        }
        Ok(key)
    }

    /// The key as 64 lowercase hexadecimal digits (for the key file).
    #[must_use]
    pub fn to_hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// What happened to a received frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Accepted,
    /// Unsigned, and not a message allowed unsigned.
    Unsigned,
    /// Signed, but not with our key (or altered).
    BadSignature,
    /// Its timestamp is not newer than the last of its stream.
    Replayed,
    /// The first of its stream, and more than a minute older than our timestamp.
    TooOld,
}

/// The signing state of a system: the key, this side's link id and timestamp, and the last timestamp of
/// every stream heard.
#[derive(Debug, Clone, PartialEq)]
pub struct Signing {
    key: SecretKey,
    link_id: u8,
    timestamp: u64,
    streams: HashMap<(u8, u32, u8), u64>,
}

/// The first 6 bytes of SHA-256(key ‖ data).
fn signature_of(key: &SecretKey, data: &[u8]) -> [u8; 6] {
    let mut hasher = Sha256::new();
    hasher.update(key.0);
    hasher.update(data);
    let digest = hasher.finalize();
    let mut out = [0u8; 6];
    out.copy_from_slice(&digest[..6]);
    out
}

impl Signing {
    /// Signing with `key` as link `link_id`, timestamps from `initial_timestamp` on (the larger of the
    /// clock's and the last one used before a restart, so they never go back).
    #[must_use]
    pub fn new(key: SecretKey, link_id: u8, initial_timestamp: u64) -> Self {
        Self { key, link_id, timestamp: initial_timestamp, streams: HashMap::new() }
    }

    #[must_use]
    pub fn key(&self) -> &SecretKey {
        &self.key
    }

    /// The last timestamp used or accepted (to persist across a restart).
    #[must_use]
    pub fn timestamp(&self) -> u64 {
        self.timestamp
    }

    /// `frame` (an unsigned MAVLink 2 frame, as encoded) signed at `now_ts`; a v1 frame or a frame that
    /// is already signed is returned as it is.
    #[must_use]
    pub fn sign(&mut self, frame: &[u8], now_ts: u64) -> Vec<u8> {
        let mut out = frame.to_vec();
        if out.len() < 12 || out[0] != 0xFD || out[2] & IFLAG_SIGNED != 0 {
            return out;
        }
        out[2] |= IFLAG_SIGNED;
        let crc_at = out.len() - 2;
        let msg_id = u32::from_le_bytes([out[7], out[8], out[9], 0]);
        let extra = <::mavlink::dialects::common::MavMessage as ::mavlink::Message>::extra_crc(msg_id);
        let crc = ::mavlink::calculate_crc(&out[1..crc_at], extra);
        out[crc_at..].copy_from_slice(&crc.to_le_bytes());
        self.timestamp = now_ts.max(self.timestamp + 1) & 0xFFFF_FFFF_FFFF;
        out.push(self.link_id);
        out.extend_from_slice(&self.timestamp.to_le_bytes()[..6]);
        let value = signature_of(&self.key, &out);
        out.extend_from_slice(&value);
        out
    }

    /// The verdict on a received frame (its bytes from the start byte through the signature, if any;
    /// `msg_id` its message id), at `now_ts`; an accepted signed frame moves its stream's timestamp.
    pub fn check(&mut self, frame: &[u8], msg_id: u32, now_ts: u64) -> Verdict {
        let signed = frame.len() > SIGNATURE_LEN + 12 && frame[0] == 0xFD && frame[2] & IFLAG_SIGNED != 0;
        if !signed {
            return if UNSIGNED_ALLOWED.contains(&msg_id) { Verdict::Accepted } else { Verdict::Unsigned };
        }
        let block = frame.len() - SIGNATURE_LEN;
        let link_id = frame[block];
        let mut ts_bytes = [0u8; 8];
        ts_bytes[..6].copy_from_slice(&frame[block + 1..block + 7]);
        let ts = u64::from_le_bytes(ts_bytes);
        if signature_of(&self.key, &frame[..frame.len() - 6]) != frame[frame.len() - 6..] {
            return Verdict::BadSignature;
        }
        let stream = (link_id, u32::from(frame[5]), frame[6]);
        self.timestamp = self.timestamp.max(now_ts);
        match self.streams.get(&stream) {
            Some(&last) if ts <= last => return Verdict::Replayed,
            None if ts + ONE_MINUTE_TS < self.timestamp => return Verdict::TooOld,
            _ => {}
        }
        self.streams.insert(stream, ts);
        self.timestamp = self.timestamp.max(ts);
        Verdict::Accepted
    }
}

#[cfg(test)]
mod tests {
    use ::mavlink::MavHeader;
    use ::mavlink::dialects::common::{COMMAND_LONG_DATA, MavCmd, MavMessage, RADIO_STATUS_DATA};

    use super::*;
    use crate::core::mavlink::frame::{FrameDecoder, encode_frame_v2};

    const KEY: SecretKey = SecretKey([7u8; 32]);
    const T0: u64 = 30_000_000_000_000; // about 9.5 years after 2015

    fn disarm() -> Vec<u8> {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param2: 21196.0,
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        });
        encode_frame_v2(MavHeader { system_id: 255, component_id: 190, sequence: 3 }, &msg)
    }

    #[test]
    fn given_a_signed_frame_then_it_decodes_verifies_and_a_replay_an_old_stream_or_another_key_is_dropped() {
        let mut gcs = Signing::new(KEY, 5, T0);
        let mut vehicle = Signing::new(KEY, 0, T0);
        let frame = gcs.sign(&disarm(), T0);
        assert_eq!(frame.len(), disarm().len() + SIGNATURE_LEN);
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        assert_eq!(decoded.len(), 1, "a valid MAVLink 2 frame (CRC over the new flags)");
        assert_eq!(vehicle.check(&frame, 76, T0), Verdict::Accepted);
        assert_eq!(vehicle.check(&frame, 76, T0), Verdict::Replayed, "the same timestamp again");
        let next = gcs.sign(&disarm(), T0);
        assert_eq!(vehicle.check(&next, 76, T0), Verdict::Accepted, "the next timestamp");
        let mut intruder = Signing::new(SecretKey([8u8; 32]), 5, T0 + 10);
        assert_eq!(vehicle.check(&intruder.sign(&disarm(), T0 + 10), 76, T0), Verdict::BadSignature);
        let mut tampered = gcs.sign(&disarm(), T0);
        let at = tampered.len() - SIGNATURE_LEN - 3;
        tampered[at] ^= 1;
        assert_eq!(vehicle.check(&tampered, 76, T0), Verdict::BadSignature);
        let mut stale = Signing::new(KEY, 9, T0 - 2 * ONE_MINUTE_TS);
        assert_eq!(vehicle.check(&stale.sign(&disarm(), 0), 76, T0), Verdict::TooOld, "a new stream a minute old");
    }

    #[test]
    fn given_signing_on_then_unsigned_frames_are_dropped_except_radio_status() {
        let mut vehicle = Signing::new(KEY, 0, T0);
        assert_eq!(vehicle.check(&disarm(), 76, T0), Verdict::Unsigned);
        let radio = encode_frame_v2(
            MavHeader { system_id: 51, component_id: 68, sequence: 0 },
            &MavMessage::RADIO_STATUS(RADIO_STATUS_DATA::default()),
        );
        assert_eq!(vehicle.check(&radio, 109, T0), Verdict::Accepted);
        // A frame with a random 13-byte "signature" is not signed by the key.
        let mut forged = disarm();
        forged[2] |= IFLAG_SIGNED;
        forged.extend_from_slice(&[0x5A; SIGNATURE_LEN]);
        assert_eq!(vehicle.check(&forged, 76, T0), Verdict::BadSignature);
    }

    #[test]
    fn given_a_clock_that_goes_back_then_outgoing_timestamps_still_grow() {
        let mut s = Signing::new(KEY, 0, T0);
        let a = s.sign(&disarm(), T0);
        let b = s.sign(&disarm(), T0 - 1_000_000);
        let ts = |f: &[u8]| {
            let mut t = [0u8; 8];
            t[..6].copy_from_slice(&f[f.len() - 12..f.len() - 6]);
            u64::from_le_bytes(t)
        };
        assert!(ts(&b) > ts(&a));
        assert_eq!(s.timestamp(), ts(&b));
    }

    #[test]
    fn given_key_texts_then_64_hex_digits_are_a_key_and_anything_else_is_refused() {
        let hex = "0102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f20";
        let key = SecretKey::from_hex(&format!("  {hex}\n")).unwrap();
        assert_eq!(key.to_hex(), hex);
        assert_eq!(format!("{key:?}"), "SecretKey(..)", "never shown");
        assert!(SecretKey::from_hex("abc").is_err());
        assert!(SecretKey::from_hex(&"zz".repeat(32)).is_err());
        assert!(SecretKey::from_hex(&"00".repeat(32)).is_err());
        assert_eq!(timestamp_of_unix_us(1_420_070_400 * 1_000_000 + 100), 10);
    }
}

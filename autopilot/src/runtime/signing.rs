//! MAVLink 2 signing on the ground-station links: one state shared by every link (UDP, TCP, serial) of
//! the process, the wall clock for the signing timestamps, and the key's persistence. The plant link is
//! not signed. The rules are the core's (`core::mavlink::signing`).
//!
//! - Off (no key): frames pass unverified and go out unsigned.
//! - On: every outgoing frame is signed; a received frame that is unsigned (except RADIO_STATUS), wrongly
//!   signed, replayed or a minute stale is dropped and counted in the link's `LinkStats::signature_rejected`.
//! - The key comes from `--signing-key-file` (64 hex digits; also the `signing_key_file` config key), or
//!   from a SETUP_SIGNING received on a secure link (TCP or serial; not UDP, which anyone on the network
//!   reaches, unless the configuration marks it secure with `[gcs] udp_secure`, for a trusted network). A key set by SETUP_SIGNING is kept in the state directory as [`KEY_FILE`] (key and last
//!   timestamp, owner-only permissions, written atomically) and used again at the next start, with
//!   timestamps that continue from the saved one. It is never logged.
//! - Turning signing off: SETUP_SIGNING with the all-zero key (while signing is on it must itself be signed,
//!   as every frame must), or removing the key file.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, MavSeverity, SETUP_SIGNING_DATA};

use super::frame::{DecodedFrame, LinkCounters, encode_v2};
use super::persist::write_private_file_atomically;
use crate::core::mavlink::signing::{SecretKey, Signing, Verdict, timestamp_of_unix_us};
use crate::core::mavlink::statustext;

/// The key file in the state directory: the key's 64 hex digits, then the last timestamp used.
pub const KEY_FILE: &str = "signing.key";

/// The signing timestamp now, from the wall clock.
#[must_use]
pub fn now_timestamp() -> u64 {
    let unix_us = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_micros());
    timestamp_of_unix_us(unix_us)
}

/// The state every ground-station link shares.
#[derive(Debug, Default)]
pub struct LinkSigning {
    state: Mutex<Option<Signing>>,
    /// Where a key set by SETUP_SIGNING is kept (None: not kept).
    dir: Option<PathBuf>,
}

impl LinkSigning {
    /// Signing off; a key set later is kept in `dir`.
    #[must_use]
    pub fn new(dir: Option<PathBuf>) -> Self {
        Self { state: Mutex::new(None), dir }
    }

    /// Signing on with `key`, timestamps from `after` on (or the clock's, if later).
    pub fn enable(&self, key: SecretKey, after: u64) {
        let ts = now_timestamp().max(after);
        *self.lock() = Some(Signing::new(key, 0, ts));
    }

    pub fn disable(&self) {
        *self.lock() = None;
    }

    #[must_use]
    pub fn enabled(&self) -> bool {
        self.lock().is_some()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Signing>> {
        // A panic while holding it cannot leave the state half-changed (every change is one assignment).
        self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The frames of one read that pass, the others counted in `counters`.
    pub fn verify(&self, frames: Vec<DecodedFrame>, counters: &LinkCounters) -> Vec<DecodedFrame> {
        let mut state = self.lock();
        let Some(signing) = state.as_mut() else { return frames };
        let now = now_timestamp();
        frames
            .into_iter()
            .filter(|f| {
                let id = mavlink::Message::message_id(&f.message);
                let verdict = match &f.signed_raw {
                    Some(raw) => signing.check(raw, id, now),
                    None => signing.check(&[], id, now),
                };
                if verdict != Verdict::Accepted {
                    counters.add_signature_rejected();
                    tracing::debug!(?verdict, msg_id = id, "frame dropped by signing");
                }
                verdict == Verdict::Accepted
            })
            .collect()
    }

    /// One outgoing message as a MAVLink 2 frame, signed when signing is on.
    #[must_use]
    pub fn encode(&self, header: MavHeader, message: &MavMessage) -> Vec<u8> {
        let frame = encode_v2(header, message);
        match self.lock().as_mut() {
            Some(signing) => signing.sign(&frame, now_timestamp()),
            None => frame,
        }
    }

    /// Applies a SETUP_SIGNING from a link that is `secure` or not; returns what to tell the ground
    /// station. Keeps (or removes) the key file.
    pub fn setup(&self, key: [u8; 32], initial_timestamp: u64, secure: bool) -> String {
        if !secure {
            return "Signing: refused on UDP (use TCP or udp_secure)".into();
        }
        let key = SecretKey(key);
        if key.is_zero() {
            self.disable();
            if let Some(dir) = &self.dir {
                let _ = std::fs::remove_file(dir.join(KEY_FILE));
            }
            tracing::info!("MAVLink signing off (SETUP_SIGNING with the zero key)");
            return "Signing disabled".into();
        }
        self.enable(key, initial_timestamp);
        let ts = self.lock().as_ref().map_or(0, Signing::timestamp);
        if let Some(dir) = &self.dir
            && let Err(e) = save_key(dir, &key, ts)
        {
            tracing::warn!(error = %e, "the signing key could not be kept; it lasts until the autopilot stops");
        }
        tracing::info!("MAVLink signing on (SETUP_SIGNING)");
        "Signing enabled".into()
    }

    /// A SETUP_SIGNING received by vehicle `sysid` on a link that is `secure` or not: applied when it is
    /// for this vehicle (or every one), and the STATUSTEXT that answers the peer (WARNING when refused,
    /// NOTICE when applied); `None` when it is for another vehicle.
    #[must_use]
    pub fn on_setup_signing(&self, m: &SETUP_SIGNING_DATA, sysid: u8, secure: bool) -> Option<MavMessage> {
        let ours = m.target_system == 0 || m.target_system == sysid;
        if !ours {
            return None;
        }
        let said = self.setup(m.secret_key, m.initial_timestamp, secure);
        let severity = if said.starts_with("Signing:") {
            MavSeverity::MAV_SEVERITY_WARNING
        } else {
            MavSeverity::MAV_SEVERITY_NOTICE
        };
        Some(statustext(severity, &said))
    }

    /// Saves the last timestamp with the key (at shutdown), so the next start's timestamps continue.
    pub fn save_timestamp(&self) {
        let Some(dir) = &self.dir else { return };
        let state = self.lock();
        if let Some(s) = state.as_ref()
            && dir.join(KEY_FILE).exists()
        {
            let _ = save_key(dir, s.key(), s.timestamp());
        }
    }
}

/// Writes the key file with owner-only permissions, atomically (`persist::write_private_file_atomically`).
///
/// # Errors
/// The I/O error; the previous file is then unchanged.
pub fn save_key(dir: &Path, key: &SecretKey, timestamp: u64) -> std::io::Result<()> {
    let text = format!("{}\n{timestamp}\n", key.to_hex());
    write_private_file_atomically(&dir.join(KEY_FILE), text.as_bytes())
}

/// A key file: the key on its first line (64 hex digits), and optionally the last timestamp on the
/// second.
///
/// # Errors
/// Why the text is not a key file (never showing the key).
pub fn parse_key_file(text: &str) -> Result<(SecretKey, u64), String> {
    let mut lines = text.lines();
    let key = SecretKey::from_hex(lines.next().unwrap_or(""))?;
    let ts = match lines.next().map(str::trim).filter(|l| !l.is_empty()) {
        Some(t) => t.parse().map_err(|_| format!("the timestamp line {t:?} is not a number"))?,
        None => 0,
    };
    Ok((key, ts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_set_up_is_kept_owner_only_and_read_back_with_its_timestamp() {
        let dir = std::env::temp_dir().join(format!("aco-signing-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let s = LinkSigning::new(Some(dir.clone()));
        assert_eq!(s.setup([3; 32], 0, false), "Signing: refused on UDP (use TCP or udp_secure)");
        assert!(!s.enabled());
        assert_eq!(s.setup([3; 32], 0, true), "Signing enabled");
        let text = std::fs::read_to_string(dir.join(KEY_FILE)).unwrap();
        let (key, ts) = parse_key_file(&text).unwrap();
        assert_eq!(key, SecretKey([3; 32]));
        assert!(ts >= now_timestamp() - 100_000, "the timestamp kept is the clock's");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(dir.join(KEY_FILE)).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        assert_eq!(s.setup([0; 32], 0, true), "Signing disabled");
        assert!(!dir.join(KEY_FILE).exists() && !s.enabled());
        assert!(parse_key_file("not a key").is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}

//! `.tlog` writer for all ground-station traffic, both directions, in pymavlink's format (what
//! MAVExplorer and `mavlogdump.py` read): per message an 8-byte big-endian u64 timestamp in microseconds
//! since the Unix epoch, then the MAVLink frame's bytes, nothing else.
//!
//! The timestamp is the caller's `now_us` (the shell picks wall clock, or plant time offset onto a start
//! epoch), so the writer reads no clock. It writes to `<dir>/<name>.tlog.tmp` and renames to
//! `<dir>/<name>.tlog` only in [`TlogWriter::close`] (a `persist::AtomicFile` log): a log under its final name is always complete; one
//! left as `.tlog.tmp` (crash, error, dropped without close) is readable up to its last flush. It flushes
//! whenever [`TLOG_FLUSH_INTERVAL_US`] of `now_us` has passed since the last flush. This is blocking
//! std I/O into a buffer: cheap per call, flushes are a few kB once a second.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkVersion};

use super::frame::encode;
use super::persist::{AtomicFile, CommitError};

/// How often buffered records reach the file, in µs of the caller's clock.
pub const TLOG_FLUSH_INTERVAL_US: u64 = 1_000_000;
/// Length of the timestamp before each frame, in bytes.
pub const TLOG_TIMESTAMP_BYTES: usize = 8;

/// Why the log could not be written or read. The shell decides whether to fly on without a log; the
/// writer never hides a failure.
#[derive(Debug, thiserror::Error)]
pub enum TlogError {
    #[error("cannot create tlog {path}: {source}")]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write tlog {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot rename tlog {from} to {to}: {source}")]
    Rename {
        from: PathBuf,
        to: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("tlog {path} already exists; refusing to overwrite it")]
    Exists { path: PathBuf },
    #[error("tlog record at byte {offset_bytes} is truncated or not a MAVLink frame")]
    BadRecord { offset_bytes: usize },
}

/// One record read back from a tlog.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlogRecord {
    pub time_us: u64,
    pub frame: Vec<u8>,
}

/// An open `.tlog.tmp`; becomes `.tlog` on [`TlogWriter::close`].
#[derive(Debug)]
pub struct TlogWriter {
    file: BufWriter<AtomicFile>,
    last_flush_us: Option<u64>,
    records: u64,
}

impl TlogWriter {
    /// Start `<dir>/<name>.tlog.tmp`.
    ///
    /// # Errors
    /// [`TlogError::Exists`] if `<name>.tlog` or `<name>.tlog.tmp` already exists (a log is never
    /// overwritten), [`TlogError::Create`] if the file cannot be created.
    pub fn create(dir: &Path, name: &str) -> Result<Self, TlogError> {
        let final_path = dir.join(format!("{name}.tlog"));
        if final_path.exists() {
            return Err(TlogError::Exists { path: final_path });
        }
        let file = AtomicFile::create_log(&final_path).map_err(|source| {
            let temp_path = super::persist::temp_path(&final_path);
            if source.kind() == std::io::ErrorKind::AlreadyExists {
                TlogError::Exists { path: temp_path }
            } else {
                TlogError::Create { path: temp_path, source }
            }
        })?;
        Ok(Self { file: BufWriter::new(file), last_flush_us: None, records: 0 })
    }

    /// Where the log is being written now.
    #[must_use]
    pub fn temp_path(&self) -> &Path {
        self.file.get_ref().temp_path()
    }

    /// Where the log will be after [`TlogWriter::close`].
    #[must_use]
    pub fn final_path(&self) -> &Path {
        self.file.get_ref().path()
    }

    /// Records written so far.
    #[must_use]
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Append one raw frame stamped `now_us` (µs since the Unix epoch).
    ///
    /// # Errors
    /// [`TlogError::Write`] if the file cannot be written or flushed.
    pub fn write_frame(&mut self, now_us: u64, frame: &[u8]) -> Result<(), TlogError> {
        let res = self.file.write_all(&now_us.to_be_bytes()).and_then(|()| self.file.write_all(frame));
        res.map_err(|source| TlogError::Write { path: self.temp_path().to_owned(), source })?;
        self.records += 1;
        match self.last_flush_us {
            None => self.last_flush_us = Some(now_us),
            Some(last) if now_us.saturating_sub(last) >= TLOG_FLUSH_INTERVAL_US => {
                self.flush()?;
                self.last_flush_us = Some(now_us);
            }
            Some(_) => {}
        }
        Ok(())
    }

    /// Append one message, encoded in `version` (received frames are logged in the version they came in;
    /// see `frame::encode`: a signature on a received frame is not reproduced).
    ///
    /// # Errors
    /// [`TlogError::Write`] as [`TlogWriter::write_frame`].
    pub fn write_message(
        &mut self,
        now_us: u64,
        header: MavHeader,
        message: &MavMessage,
        version: MavlinkVersion,
    ) -> Result<(), TlogError> {
        self.write_frame(now_us, &encode(header, message, version))
    }

    /// Push buffered records to the file.
    ///
    /// # Errors
    /// [`TlogError::Write`] if the flush fails.
    pub fn flush(&mut self) -> Result<(), TlogError> {
        self.file.flush().map_err(|source| TlogError::Write { path: self.temp_path().to_owned(), source })
    }

    /// Flush, sync and rename to the final name; returns that path.
    ///
    /// # Errors
    /// [`TlogError::Write`] if flushing or syncing fails (the `.tlog.tmp` stays), [`TlogError::Rename`]
    /// if the rename fails.
    pub fn close(self) -> Result<PathBuf, TlogError> {
        let temp_path = self.temp_path().to_owned();
        let file = self.file.into_inner().map_err(|e| TlogError::Write { path: temp_path, source: e.into_error() })?;
        file.commit().map_err(|e| match e {
            CommitError::Sync { path, source } => TlogError::Write { path, source },
            CommitError::Rename { from, to, source } => TlogError::Rename { from, to, source },
        })
    }
}

/// Split a tlog's bytes into records, using each frame's header for its length (v2: 12 + payload, + 13
/// if signed; v1: 8 + payload).
///
/// # Errors
/// [`TlogError::BadRecord`] at the first record that is cut short or does not start with a MAVLink start
/// byte.
pub fn read_records(bytes: &[u8]) -> Result<Vec<TlogRecord>, TlogError> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let bad = TlogError::BadRecord { offset_bytes: at };
        let rest = &bytes[at..];
        let (Some(stamp), Some(frame)) = (rest.get(..TLOG_TIMESTAMP_BYTES), rest.get(TLOG_TIMESTAMP_BYTES..)) else {
            return Err(bad);
        };
        let mut time = [0u8; TLOG_TIMESTAMP_BYTES];
        time.copy_from_slice(stamp);
        let frame_len = match (frame.first(), frame.get(1), frame.get(2)) {
            (Some(&mavlink::MAV_STX_V2), Some(&len), Some(&incompat)) => {
                12 + usize::from(len) + if incompat & 0x01 != 0 { 13 } else { 0 }
            }
            (Some(&mavlink::MAV_STX), Some(&len), _) => 8 + usize::from(len),
            _ => return Err(bad),
        };
        let Some(frame) = frame.get(..frame_len) else { return Err(bad) };
        out.push(TlogRecord { time_us: u64::from_be_bytes(time), frame: frame.to_vec() });
        at += TLOG_TIMESTAMP_BYTES + frame_len;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::frame::tests::{heartbeat, signed};
    use crate::runtime::frame::{FrameDecoder, encode_v2};

    /// A fresh directory under the target's temp dir, unique per test.
    fn scratch_dir(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("autopilot-tlog-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn frames_read_back_with_their_timestamps_and_bytes() {
        let dir = scratch_dir("readback");
        let mut log = TlogWriter::create(&dir, "flight").expect("create");
        let (h, m) = heartbeat(1, 5);
        let v2 = encode_v2(h, &m);
        let v1 = encode(h, &m, MavlinkVersion::V1);
        let signed_v2 = signed(&v2, 0);
        let epoch_us = 1_700_000_000_000_000;
        let written = vec![
            TlogRecord { time_us: epoch_us, frame: v2.clone() },
            TlogRecord { time_us: epoch_us + 1, frame: v1 },
            TlogRecord { time_us: epoch_us + 2_500_000, frame: signed_v2 },
            TlogRecord { time_us: epoch_us + 2_500_001, frame: v2 },
        ];
        for r in &written {
            log.write_frame(r.time_us, &r.frame).expect("write");
        }
        log.write_message(epoch_us + 3_000_000, h, &m, MavlinkVersion::V2).expect("write");
        assert_eq!(log.records(), 5);
        let path = log.close().expect("close");
        let bytes = std::fs::read(&path).expect("read");
        let read = read_records(&bytes).expect("parse");
        assert_eq!(&read[..4], &written[..]);
        assert_eq!(read[4].time_us, epoch_us + 3_000_000);
        // Every frame is a valid MAVLink frame (as pymavlink will see it).
        let mut dec = FrameDecoder::new();
        for r in &read {
            assert_eq!(dec.decode_datagram(&r.frame).len(), 1);
        }
        assert_eq!(&bytes[..8], &epoch_us.to_be_bytes(), "big-endian µs timestamp first");
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn the_final_name_appears_only_on_close() {
        let dir = scratch_dir("final-name");
        let mut log = TlogWriter::create(&dir, "run").expect("create");
        let (h, m) = heartbeat(1, 0);
        log.write_message(0, h, &m, MavlinkVersion::V2).expect("write");
        assert!(log.temp_path().exists());
        assert!(!dir.join("run.tlog").exists(), "no final name while writing");
        let path = log.close().expect("close");
        assert_eq!(path, dir.join("run.tlog"));
        assert!(path.exists());
        assert!(!dir.join("run.tlog.tmp").exists());
        // A second log of the same name is refused, not overwritten.
        assert!(matches!(TlogWriter::create(&dir, "run"), Err(TlogError::Exists { .. })));
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn a_log_dropped_without_close_stays_marked_incomplete() {
        let dir = scratch_dir("dropped");
        let mut log = TlogWriter::create(&dir, "crash").expect("create");
        let (h, m) = heartbeat(1, 0);
        log.write_message(1, h, &m, MavlinkVersion::V2).expect("write");
        drop(log);
        assert!(dir.join("crash.tlog.tmp").exists());
        assert!(!dir.join("crash.tlog").exists());
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn it_flushes_once_the_interval_has_passed() {
        let dir = scratch_dir("flush");
        let mut log = TlogWriter::create(&dir, "f").expect("create");
        let (h, m) = heartbeat(1, 0);
        log.write_message(0, h, &m, MavlinkVersion::V2).expect("write");
        log.write_message(TLOG_FLUSH_INTERVAL_US - 1, h, &m, MavlinkVersion::V2).expect("write");
        assert_eq!(std::fs::metadata(log.temp_path()).expect("meta").len(), 0, "still buffered");
        log.write_message(TLOG_FLUSH_INTERVAL_US, h, &m, MavlinkVersion::V2).expect("write");
        let on_disk = std::fs::read(log.temp_path()).expect("read");
        assert_eq!(read_records(&on_disk).expect("parse").len(), 3);
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn an_unwritable_directory_is_a_typed_error() {
        let dir = scratch_dir("missing").join("does-not-exist");
        assert!(matches!(TlogWriter::create(&dir, "x"), Err(TlogError::Create { .. })));
    }

    #[test]
    fn a_truncated_log_is_reported_not_misread() {
        let (h, m) = heartbeat(1, 0);
        let mut bytes = 7u64.to_be_bytes().to_vec();
        bytes.extend_from_slice(&encode_v2(h, &m));
        let whole = bytes.len();
        bytes.extend_from_slice(&8u64.to_be_bytes());
        bytes.extend_from_slice(&encode_v2(h, &m)[..5]);
        assert!(matches!(read_records(&bytes), Err(TlogError::BadRecord { offset_bytes }) if offset_bytes == whole));
    }
}

//! The flight log's writer: on a blocking thread of its own, each flight's bytes into
//! `<dir>/<name>.ulg.tmp` (a `persist::AtomicFile` log), flushed once a second, synced and renamed to
//! `<name>.ulg` when the flight ends.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use tokio::sync::mpsc;

use super::LogItem;
use crate::runtime::persist::{AtomicFile, CommitError, temp_path};

/// Wall time between flushes of the file.
const FLUSH_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// Why a flight log could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FlightLogError {
    #[error("cannot create ULog {path}: {source}")]
    Create {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write ULog {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot rename ULog {from} to {to}: {source}")]
    Rename {
        from: PathBuf,
        to: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// An open `.ulg.tmp`.
#[derive(Debug)]
struct OpenLog {
    file: BufWriter<AtomicFile>,
    last_flush: Instant,
}

impl OpenLog {
    fn temp_path(&self) -> &Path {
        self.file.get_ref().temp_path()
    }
}

/// The writer: see the module docs. Synchronous; [`spawn_writer`] runs it on a thread.
#[derive(Debug, Default)]
pub struct UlogWriter {
    current: Option<OpenLog>,
}

impl UlogWriter {
    /// Carries out one item; returns the path of a file it finalized.
    ///
    /// # Errors
    /// [`FlightLogError`] when a file cannot be created, written or renamed; the flight is then given up
    /// (what was written stays as `.ulg.tmp`) and the next `Open` starts afresh.
    pub fn handle(&mut self, item: LogItem) -> Result<Option<PathBuf>, FlightLogError> {
        match item {
            LogItem::Open { dir, name, bytes } => {
                let closed = self.close()?;
                let mut log = create(&dir, &name)?;
                write(&mut log, &bytes)?;
                self.current = Some(log);
                Ok(closed)
            }
            LogItem::Append(bytes) => {
                let Some(log) = self.current.as_mut() else { return Ok(None) };
                if let Err(e) = write(log, &bytes) {
                    self.current = None;
                    return Err(e);
                }
                if log.last_flush.elapsed() >= FLUSH_INTERVAL {
                    log.last_flush = Instant::now();
                    if let Err(source) = log.file.flush() {
                        let path = log.temp_path().to_owned();
                        self.current = None;
                        return Err(FlightLogError::Write { path, source });
                    }
                }
                Ok(None)
            }
            LogItem::Close => self.close(),
        }
    }

    /// Flush, sync and rename the open file, if any; returns its final path.
    ///
    /// # Errors
    /// [`FlightLogError::Write`] or [`FlightLogError::Rename`] (the `.ulg.tmp` stays).
    pub fn close(&mut self) -> Result<Option<PathBuf>, FlightLogError> {
        let Some(log) = self.current.take() else { return Ok(None) };
        let path = log.temp_path().to_owned();
        let file = log.file.into_inner().map_err(|e| FlightLogError::Write { path, source: e.into_error() })?;
        let final_path = file.commit().map_err(|e| match e {
            CommitError::Sync { path, source } => FlightLogError::Write { path, source },
            CommitError::Rename { from, to, source } => FlightLogError::Rename { from, to, source },
        })?;
        Ok(Some(final_path))
    }
}

/// `<dir>/<name>.ulg.tmp`, or `<name>_1`, `<name>_2`... when a flight of that second exists already.
fn create(dir: &Path, name: &str) -> Result<OpenLog, FlightLogError> {
    std::fs::create_dir_all(dir).map_err(|source| FlightLogError::Create { path: dir.to_owned(), source })?;
    let mut last_err = None;
    for n in 0..100 {
        let stem = if n == 0 { name.to_owned() } else { format!("{name}_{n}") };
        let final_path = dir.join(format!("{stem}.ulg"));
        if final_path.exists() {
            continue;
        }
        match AtomicFile::create_log(&final_path) {
            Ok(file) => {
                let file = BufWriter::with_capacity(64 * 1024, file);
                return Ok(OpenLog { file, last_flush: Instant::now() });
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(source) => {
                last_err = Some(FlightLogError::Create { path: temp_path(&final_path), source });
                break;
            }
        }
    }
    Err(last_err.unwrap_or_else(|| FlightLogError::Create {
        path: dir.join(format!("{name}.ulg")),
        source: std::io::Error::new(std::io::ErrorKind::AlreadyExists, "100 logs of the same second"),
    }))
}

fn write(log: &mut OpenLog, bytes: &[u8]) -> Result<(), FlightLogError> {
    log.file.write_all(bytes).map_err(|source| FlightLogError::Write { path: log.temp_path().to_owned(), source })
}

/// The writer on a blocking thread: handles items until the channel closes (every sender dropped: the
/// autopilot is stopping), then finalizes the open file. Failures are logged, never fatal: the vehicle
/// flies on without its log.
pub fn spawn_writer(mut rx: mpsc::Receiver<LogItem>) -> tokio::task::JoinHandle<()> {
    tokio::task::spawn_blocking(move || {
        let mut writer = UlogWriter::default();
        let report = |r: Result<Option<PathBuf>, FlightLogError>| match r {
            Ok(Some(path)) => tracing::info!(path = %path.display(), "flight log (ULog) closed"),
            Ok(None) => {}
            Err(e) => tracing::error!("{e}"),
        };
        while let Some(item) = rx.blocking_recv() {
            let opening = matches!(item, LogItem::Open { .. });
            report(writer.handle(item));
            if opening && let Some(log) = &writer.current {
                tracing::info!(path = %log.temp_path().display(), "flight log (ULog) open");
            }
        }
        report(writer.close());
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::flight_log::sampler::tests::scratch;
    use crate::runtime::ulog;

    #[test]
    fn two_flights_in_the_same_second_get_two_names() {
        let root = scratch("same-second");
        let mut writer = UlogWriter::default();
        let open =
            || LogItem::Open { dir: root.join("2026-12-02"), name: "14_31_05".into(), bytes: ulog::header(0).to_vec() };
        writer.handle(open()).expect("open");
        let a = writer.handle(LogItem::Close).expect("close").expect("path");
        writer.handle(open()).expect("open");
        let b = writer.handle(LogItem::Close).expect("close").expect("path");
        assert_eq!(a.file_name().and_then(|n| n.to_str()), Some("14_31_05.ulg"));
        assert_eq!(b.file_name().and_then(|n| n.to_str()), Some("14_31_05_1.ulg"));
        // Appending with no file open is ignored; a root that cannot be created is an error.
        assert!(writer.handle(LogItem::Append(vec![1, 2, 3])).expect("ignored").is_none());
        std::fs::write(root.join("file"), b"").expect("write");
        let bad = LogItem::Open { dir: root.join("file").join("x"), name: "n".into(), bytes: Vec::new() };
        assert!(matches!(writer.handle(bad), Err(FlightLogError::Create { .. })));
        let _ = std::fs::remove_dir_all(&root);
    }
}

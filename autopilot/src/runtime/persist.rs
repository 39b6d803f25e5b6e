//! Persistence of what the vehicle keeps across restarts (parameters, the mission) in a state directory,
//! off the plant link's thread. In: `(file name, contents)` to save, from the vehicle's thread; at start,
//! [`load`] of a file. Out: files written atomically: the contents go to `NAME.tmp`, are synced to disk,
//! and the temporary file is renamed over `NAME`, so a reader (or a crash) never sees half a file. This
//! module owns that rule for every file of the workspace that must never be half-written: one-shot
//! ([`write_file_atomically`]) or streamed (an [`AtomicFile`]: the `.tlog` and the flight log's `.ulg`).
//!
//! Saves are done by a thread of their own, so a burst of PARAM_SETs (MAVProxy loading a parameter file)
//! never stalls the lockstep loop; a save that arrives while an older one of the same file is still
//! waiting replaces it (only the newest contents are written). Dropping the [`Persister`] writes what is
//! pending and waits for it.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc;

/// Why a file could not be saved or loaded.
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    #[error("cannot create the state directory {path}: {source}")]
    Dir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Write `contents` to `dir/name` atomically (see [`write_file_atomically`]).
///
/// # Errors
/// [`PersistError::Write`] naming the file; the previous file, if any, is then unchanged.
pub fn save_atomically(dir: &Path, name: &str, contents: &str) -> Result<(), PersistError> {
    let path = dir.join(name);
    write_file_atomically(&path, contents.as_bytes()).map_err(|source| PersistError::Write { path, source })
}

/// The temporary file that `path` is written as until it is complete: the whole name plus `.tmp`
/// (`params.txt.tmp`, `run.tlog.tmp`), so every target has its own (`x.csv` and `x.json` never share
/// one) and a file left under it by a crash says by its name that it is incomplete. The one rule for
/// every file written through [`write_file_atomically`] or an [`AtomicFile`].
#[must_use]
pub fn temp_path(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    PathBuf::from(tmp)
}

/// Why an [`AtomicFile`] could not be committed; its temporary file is then still there (a log) or
/// removed (any other file), and the file under the final name, if any, is unchanged.
#[derive(Debug, thiserror::Error)]
pub enum CommitError {
    #[error("cannot sync {path}: {source}")]
    Sync {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot rename {from} to {to}: {source}")]
    Rename {
        from: PathBuf,
        to: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl From<CommitError> for std::io::Error {
    fn from(e: CommitError) -> Self {
        match e {
            CommitError::Sync { source, .. } | CommitError::Rename { source, .. } => source,
        }
    }
}

/// A file written under [`temp_path`] and given its final name only by [`AtomicFile::commit`] (synced to
/// disk, then renamed over it), so a reader or a crash never sees half of it under that name. Unbuffered:
/// wrap it in a `BufWriter` to stream into it. Dropped without a commit, its temporary file is removed,
/// except for a log ([`AtomicFile::create_log`]), which stays readable up to its last write.
#[derive(Debug)]
pub struct AtomicFile {
    file: std::fs::File,
    temp_path: PathBuf,
    path: PathBuf,
    /// Dropped without a commit, the temporary file stays (a log) rather than being removed.
    keep_unfinished: bool,
    committed: bool,
}

impl AtomicFile {
    /// Start writing `path`, into its [`temp_path`] (what an earlier failed write left there is
    /// overwritten).
    ///
    /// # Errors
    /// The file system's, creating the temporary file.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create(true).truncate(true);
        Self::open(path, &options, false)
    }

    /// As [`AtomicFile::create`], readable and writable by its owner only (mode 0600 on Unix): for a
    /// secret such as the signing key.
    ///
    /// # Errors
    /// The file system's, creating the temporary file or setting its permissions.
    pub fn create_private(path: &Path) -> std::io::Result<Self> {
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create(true).truncate(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let file = Self::open(path, &options, false)?;
        // A temporary file an earlier failed write left keeps its mode through `open`: set it.
        #[cfg(unix)]
        file.file.set_permissions(std::os::unix::fs::PermissionsExt::from_mode(0o600))?;
        Ok(file)
    }

    /// Start a log streamed to `path`: its [`temp_path`] must not exist (a log being written, or one a
    /// crash left, is never overwritten), and dropped without a commit it stays, readable up to its
    /// last write.
    ///
    /// # Errors
    /// [`std::io::ErrorKind::AlreadyExists`] when the temporary file exists; the file system's otherwise.
    pub fn create_log(path: &Path) -> std::io::Result<Self> {
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create_new(true);
        Self::open(path, &options, true)
    }

    fn open(path: &Path, options: &std::fs::OpenOptions, keep_unfinished: bool) -> std::io::Result<Self> {
        let temp_path = temp_path(path);
        let file = options.open(&temp_path)?;
        Ok(Self { file, temp_path, path: path.to_owned(), keep_unfinished, committed: false })
    }

    /// Where the file is being written now.
    #[must_use]
    pub fn temp_path(&self) -> &Path {
        &self.temp_path
    }

    /// Where the file will be after [`AtomicFile::commit`].
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sync the file to disk and rename it over its final name; returns that path.
    ///
    /// # Errors
    /// [`CommitError`]; the file under the final name, if any, is then unchanged.
    pub fn commit(mut self) -> Result<PathBuf, CommitError> {
        self.file.sync_all().map_err(|source| CommitError::Sync { path: self.temp_path.clone(), source })?;
        std::fs::rename(&self.temp_path, &self.path).map_err(|source| CommitError::Rename {
            from: self.temp_path.clone(),
            to: self.path.clone(),
            source,
        })?;
        self.committed = true;
        sync_parent_dir(&self.path);
        Ok(self.path.clone())
    }
}

/// Makes a rename in the directory of `path` durable (the new name survives a power loss), where the
/// platform allows opening a directory to sync it (Unix); elsewhere, and on failure, the rename stands as
/// the file system keeps it: the file is whole either way, only which version a power loss leaves may vary.
fn sync_parent_dir(path: &Path) {
    #[cfg(unix)]
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed && !self.keep_unfinished {
            let _ = std::fs::remove_file(&self.temp_path);
        }
    }
}

/// The workspace's one atomic file writer: `bytes` go to the [`temp_path`] of `path`, are synced to
/// disk, and the temporary file is renamed over `path` (an [`AtomicFile`]), so a reader (or a crash)
/// never sees half a file. The autopilot's state and the simulator's outputs (traces, figures, sweep
/// rows, tuning results) are all written through it.
///
/// # Errors
/// The file system's; the temporary file is then removed and the previous file, if any, is unchanged.
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_all_and_commit(AtomicFile::create(path)?, bytes)
}

/// [`write_file_atomically`] for a secret: the file is readable and writable by its owner only (mode
/// 0600 on Unix), from its first byte on.
///
/// # Errors
/// As [`write_file_atomically`].
pub fn write_private_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_all_and_commit(AtomicFile::create_private(path)?, bytes)
}

fn write_all_and_commit(mut file: AtomicFile, bytes: &[u8]) -> std::io::Result<()> {
    file.write_all(bytes)?;
    file.commit()?;
    Ok(())
}

/// The contents of `dir/name`, or `None` if there is no such file.
///
/// # Errors
/// [`PersistError::Read`] for any other failure (permissions, not UTF-8).
pub fn load(dir: &Path, name: &str) -> Result<Option<String>, PersistError> {
    let path = dir.join(name);
    match std::fs::read_to_string(&path) {
        Ok(text) => Ok(Some(text)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(PersistError::Read { path, source }),
    }
}

/// Moves `dir/name` aside to `dir/name.corrupt-<unix seconds>`: a state file that cannot be read is kept
/// for a person to look at, neither loaded nor overwritten by the next save. Returns the new path.
///
/// # Errors
/// [`PersistError::Write`] when the rename fails.
pub fn move_aside(dir: &Path, name: &str) -> Result<PathBuf, PersistError> {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let to = dir.join(format!("{name}.corrupt-{secs}"));
    std::fs::rename(dir.join(name), &to).map_err(|source| PersistError::Write { path: to.clone(), source })?;
    Ok(to)
}

/// Removes the files named in `names` from `dir` (ArduPilot's `-w`: the next start is on defaults, with
/// no mission, fence or rally points). Returns the files that were there; files that were not are not
/// an error, nor is a missing directory.
///
/// # Errors
/// [`PersistError::Write`] naming the first file that could not be removed; the ones before it are gone.
pub fn wipe(dir: &Path, names: &[&str]) -> Result<Vec<PathBuf>, PersistError> {
    let mut removed = Vec::new();
    for name in names {
        let path = dir.join(name);
        match std::fs::remove_file(&path) {
            Ok(()) => removed.push(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => return Err(PersistError::Write { path, source }),
        }
    }
    Ok(removed)
}

/// The saving thread; see the module docs.
#[derive(Debug)]
pub struct Persister {
    tx: Option<mpsc::Sender<(String, String)>>,
    thread: Option<std::thread::JoinHandle<()>>,
    dir: PathBuf,
}

impl Persister {
    /// Start saving into `dir` (created if missing).
    ///
    /// # Errors
    /// [`PersistError::Dir`] if the directory cannot be created.
    pub fn start(dir: &Path) -> Result<Self, PersistError> {
        std::fs::create_dir_all(dir).map_err(|source| PersistError::Dir { path: dir.to_owned(), source })?;
        let (tx, rx) = mpsc::channel::<(String, String)>();
        let thread_dir = dir.to_owned();
        let thread = std::thread::Builder::new()
            .name("persist".into())
            .spawn(move || {
                while let Ok(first) = rx.recv() {
                    // Everything queued meanwhile: only the newest contents of each file.
                    let mut pending: BTreeMap<String, String> = BTreeMap::new();
                    pending.insert(first.0, first.1);
                    while let Ok((name, contents)) = rx.try_recv() {
                        pending.insert(name, contents);
                    }
                    for (name, contents) in pending {
                        match save_atomically(&thread_dir, &name, &contents) {
                            Ok(()) => tracing::debug!(file = %name, "saved"),
                            Err(e) => tracing::error!(error = %e, "not saved"),
                        }
                    }
                }
            })
            .map_err(|source| PersistError::Dir { path: dir.to_owned(), source })?;
        Ok(Self { tx: Some(tx), thread: Some(thread), dir: dir.to_owned() })
    }

    /// The state directory.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Queue `contents` to be saved as `name`.
    pub fn save(&self, name: &str, contents: String) {
        if let Some(tx) = &self.tx
            && tx.send((name.to_owned(), contents)).is_err()
        {
            tracing::error!(file = name, "the saving thread has stopped; not saved");
        }
    }
}

impl Drop for Persister {
    fn drop(&mut self) {
        drop(self.tx.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("autopilot-persist-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn saves_are_atomic_the_newest_wins_and_drop_writes_what_is_pending() {
        let dir = temp_dir("save");
        {
            let p = Persister::start(&dir).expect("start");
            for k in 0..50 {
                p.save("params.txt", format!("X\t{k}\n"));
            }
            p.save("mission.waypoints", "QGC WPL 110\n".into());
        }
        assert_eq!(load(&dir, "params.txt").expect("read"), Some("X\t49\n".into()));
        assert_eq!(load(&dir, "mission.waypoints").expect("read"), Some("QGC WPL 110\n".into()));
        assert!(!dir.join("params.txt.tmp").exists(), "no temporary file left behind");
        assert_eq!(load(&dir, "nothing.txt").expect("absent is not an error"), None);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn wipe_removes_the_named_files_and_only_those() {
        let dir = temp_dir("wipe");
        std::fs::create_dir_all(&dir).expect("dir");
        for name in ["params.txt", "mission.waypoints", "signing.key"] {
            save_atomically(&dir, name, "x\n").expect("save");
        }
        let removed = wipe(&dir, &["params.txt", "mission.waypoints", "fence.waypoints"]).expect("wipe");
        assert_eq!(removed, vec![dir.join("params.txt"), dir.join("mission.waypoints")]);
        assert!(!dir.join("params.txt").exists() && !dir.join("mission.waypoints").exists());
        assert!(dir.join("signing.key").exists(), "a file not named is kept");
        assert_eq!(
            wipe(&dir.join("absent"), &["params.txt"]).expect("no directory is not an error"),
            Vec::<PathBuf>::new()
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_save_leaves_the_old_file_intact() {
        let dir = temp_dir("fail");
        std::fs::create_dir_all(&dir).expect("dir");
        save_atomically(&dir, "params.txt", "OLD\t1\n").expect("first save");
        // A directory where the temporary file would go makes the write fail.
        std::fs::create_dir_all(dir.join("params.txt.tmp")).expect("blocker");
        assert!(save_atomically(&dir, "params.txt", "NEW\t2\n").is_err());
        assert_eq!(load(&dir, "params.txt").expect("read"), Some("OLD\t1\n".into()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn given_x_csv_and_x_json_then_each_has_its_own_temporary_file_and_none_is_left() {
        let dir = temp_dir("names");
        std::fs::create_dir_all(&dir).expect("dir");
        // A blocker where x.json's temporary file goes fails x.json alone: x.csv's is another file.
        std::fs::create_dir_all(dir.join("x.json.tmp")).expect("blocker");
        write_file_atomically(&dir.join("x.csv"), b"a,b\n").expect("x.csv");
        assert!(write_file_atomically(&dir.join("x.json"), b"{}").is_err());
        assert_eq!(std::fs::read(dir.join("x.csv")).expect("read"), b"a,b\n");
        assert!(!dir.join("x.csv.tmp").exists() && !dir.join("x.json").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn given_an_atomic_file_when_streamed_then_its_name_appears_only_on_commit_and_an_uncommitted_one_is_removed() {
        let dir = temp_dir("stream");
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("run.bin");
        let mut file = AtomicFile::create(&path).expect("create");
        assert_eq!(file.temp_path(), dir.join("run.bin.tmp"));
        file.write_all(b"abc").expect("write");
        file.write_all(b"def").expect("write");
        assert!(!path.exists(), "no final name while writing");
        assert_eq!(file.commit().expect("commit"), path);
        assert_eq!(std::fs::read(&path).expect("read"), b"abcdef");
        assert!(!dir.join("run.bin.tmp").exists());
        // Dropped without a commit: the temporary file goes, the committed file stays as it was.
        let mut file = AtomicFile::create(&path).expect("create");
        file.write_all(b"half").expect("write");
        drop(file);
        assert!(!dir.join("run.bin.tmp").exists(), "no temporary file left behind");
        assert_eq!(std::fs::read(&path).expect("read"), b"abcdef");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn given_a_log_when_dropped_without_commit_then_it_stays_incomplete_and_is_never_overwritten() {
        let dir = temp_dir("log");
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("crash.tlog");
        let mut log = AtomicFile::create_log(&path).expect("create");
        log.write_all(b"record").expect("write");
        drop(log);
        assert_eq!(std::fs::read(dir.join("crash.tlog.tmp")).expect("kept"), b"record");
        assert!(!path.exists());
        let again = AtomicFile::create_log(&path).map(|_| ()).expect_err("the crashed log is not overwritten");
        assert_eq!(again.kind(), std::io::ErrorKind::AlreadyExists);
        assert_eq!(std::fs::read(dir.join("crash.tlog.tmp")).expect("kept"), b"record");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[cfg(unix)]
    #[test]
    fn given_a_secret_when_written_atomically_then_it_is_owner_only_even_over_a_stale_temporary_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = temp_dir("private");
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("signing.key");
        // A temporary file an earlier failed write left, readable by everyone.
        std::fs::write(dir.join("signing.key.tmp"), b"old").expect("stale");
        std::fs::set_permissions(dir.join("signing.key.tmp"), std::fs::Permissions::from_mode(0o644)).expect("mode");
        write_private_file_atomically(&path, b"secret\n").expect("write");
        assert_eq!(std::fs::read(&path).expect("read"), b"secret\n");
        assert_eq!(std::fs::metadata(&path).expect("meta").permissions().mode() & 0o777, 0o600);
        assert!(!dir.join("signing.key.tmp").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}

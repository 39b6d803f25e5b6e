//! Persistence of what the vehicle keeps across restarts (parameters, the mission) in a state directory,
//! off the plant link's thread. In: `(file name, contents)` to save, from the vehicle's thread; at start,
//! [`load`] of a file. Out: files written atomically: the contents go to `NAME.tmp`, are synced to disk,
//! and the temporary file is renamed over `NAME`, so a reader (or a crash) never sees half a file.
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

/// The workspace's one atomic file writer: `bytes` go to the whole name plus `.tmp` (so `x.csv` and
/// `x.json` never share a temporary file), are synced to disk, and the temporary file is renamed over
/// `path`, so a reader (or a crash) never sees half a file. The autopilot's state and the simulator's
/// outputs (traces, figures, sweep rows, tuning results) are all written through it.
///
/// # Errors
/// The file system's; the temporary file is then removed and the previous file, if any, is unchanged.
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let write = || -> std::io::Result<()> {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    };
    write().inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
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
}

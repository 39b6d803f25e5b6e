//! The repository's files, for the tests that hold the tree and its documents to the house rules.

use std::path::{Path, PathBuf};

/// The repository's root (this crate sits one level below it).
#[must_use]
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the tests crate is inside the repository").to_path_buf()
}

/// Every file below `dir` but build outputs, virtual environments and git's own.
pub fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if path.is_dir() {
            if !matches!(name.as_ref(), "target" | ".git" | ".venv" | "node_modules" | "__pycache__")
                && !name.ends_with(".egg-info")
            {
                files(&path, out);
            }
        } else {
            out.push(path);
        }
    }
}

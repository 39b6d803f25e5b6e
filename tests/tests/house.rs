//! The house rules a new contributor relies on, checked against the tree: no non-test source file over
//! [`MAX_LINES`] lines, and docs/design.md's Layout names every top-level module and nothing that is gone.

use std::collections::BTreeSet;
use std::path::Path;

use tests::repo::{files, root};

/// The most non-test lines a source file may hold (the parameter table is exempt: it is one declaration).
const MAX_LINES: usize = 650;

/// Every `.rs` file below `dir`, relative to `root` (with `/`).
fn rust_files(root: &Path, dir: &Path) -> Vec<String> {
    let mut all = Vec::new();
    files(dir, &mut all);
    all.into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| {
            let rel = p.strip_prefix(root).expect("below the root");
            rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/")
        })
        .collect()
}

/// Whether `rel` is held to the limit: not a test (a `tests`/`test` folder or a `tests.rs`), a bench, a
/// fuzz target or the parameter table.
fn is_limited(rel: &str) -> bool {
    let parts: Vec<&str> = rel.split('/').collect();
    let (file, dirs) = parts.split_last().expect("a path has a file name");
    let test_dir = dirs.iter().any(|d| matches!(*d, "tests" | "test" | "benches"));
    !(test_dir || matches!(*file, "tests.rs" | "test.rs") || rel.starts_with("fuzz/") || rel.contains("params/table"))
}

/// The file's non-test lines: those before an inline `mod tests {` (less its `#[cfg(test)]` line and the
/// blank line above it), or all of them.
fn non_test_lines(text: &str) -> usize {
    let lines: Vec<&str> = text.lines().collect();
    match lines.iter().position(|l| l.starts_with("mod tests {") || l.starts_with("mod tests{")) {
        Some(i) => (i + 1).saturating_sub(2),
        None => lines.len(),
    }
}

#[test]
fn no_non_test_source_file_is_over_650_lines() {
    let root = root();
    let mut files = rust_files(&root, &root);
    files.sort();
    let limited: Vec<&String> = files.iter().filter(|f| is_limited(f)).collect();
    assert!(limited.len() > 100, "found only {} source files: is the walk right?", limited.len());
    let over: Vec<String> = limited
        .iter()
        .filter_map(|f| {
            let n = non_test_lines(&std::fs::read_to_string(root.join(f)).expect("a readable source file"));
            (n > MAX_LINES).then(|| format!("  {f}: {n} lines"))
        })
        .collect();
    assert!(
        over.is_empty(),
        "source files over {MAX_LINES} non-test lines (split them by job; tests may move to a tests.rs):\n{}",
        over.join("\n")
    );
}

#[test]
fn the_line_count_stops_at_the_inline_tests_and_skips_tests_benches_fuzz_and_the_table() {
    assert_eq!(non_test_lines("a\nb\nc\n"), 3);
    assert_eq!(non_test_lines("a\nb\n\n#[cfg(test)]\nmod tests {\n  x\n}\n"), 3);
    assert!(is_limited("sitl/src/link/mod.rs"));
    for exempt in [
        "sitl/tests/cli.rs",
        "autopilot/src/core/mavlink/link_rate/tests.rs",
        "tests/tests/house.rs",
        "autopilot/benches/control_tick.rs",
        "fuzz/fuzz_targets/frame_decode.rs",
        "autopilot/src/core/params/table/aco.rs",
    ] {
        assert!(!is_limited(exempt), "{exempt}");
    }
}

/// The paths named in docs/design.md's `## Layout` block: each line's first word, when it is a path.
fn layout_paths(design: &str) -> Vec<String> {
    let section = design.split("\n## Layout").nth(1).expect("docs/design.md has a `## Layout` section");
    let block = section.split("```text\n").nth(1).expect("the Layout section has a ```text block");
    let block = block.split("\n```").next().expect("the block is closed");
    block
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|w| w.contains('/') || w.ends_with(".rs") || w.ends_with(".toml"))
        .map(str::to_owned)
        .collect()
}

#[test]
fn the_layout_in_design_md_names_every_top_level_module_and_nothing_that_is_gone() {
    let root = root();
    let design = std::fs::read_to_string(root.join("docs/design.md")).expect("docs/design.md");
    let named = layout_paths(&design);
    assert!(named.len() > 30, "the Layout names only {} paths", named.len());
    let missing_on_disk: Vec<&String> = named.iter().filter(|p| !root.join(p).exists()).collect();
    assert!(missing_on_disk.is_empty(), "docs/design.md's Layout names paths that do not exist: {missing_on_disk:?}");
    let named: BTreeSet<String> = named.into_iter().collect();
    let mut unnamed = Vec::new();
    for dir in ["autopilot/src", "autopilot/src/core", "autopilot/src/runtime", "sitl/src"] {
        for entry in std::fs::read_dir(root.join(dir)).expect("a source folder").flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = if entry.path().is_dir() {
                format!("{dir}/{name}/")
            } else if name.ends_with(".rs") {
                format!("{dir}/{name}")
            } else {
                continue;
            };
            if !named.contains(&path) {
                unnamed.push(path);
            }
        }
    }
    unnamed.sort();
    assert!(unnamed.is_empty(), "modules docs/design.md's Layout does not name (add a line each): {unnamed:?}");
}

#[test]
fn the_physics_imports_nothing_above_it() {
    // sitl's layers: plant (physics) < sim_params (SIM_ service, faults) < link < scenario, sweep, tune < cli.
    // The plant names no module of the crate but its own (`scripts/import_cycles.py` checks the rest).
    let root = root();
    let files = rust_files(&root, &root.join("sitl/src/plant"));
    assert!(files.len() > 5, "found only {} plant files", files.len());
    let mut upward = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(root.join(f)).expect("a readable source file");
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if code.match_indices("crate::").any(|(at, _)| !code[at..].starts_with("crate::plant")) {
                upward.push(format!("  {f}:{}: {}", i + 1, line.trim()));
            }
        }
    }
    assert!(upward.is_empty(), "the plant imports from above it:\n{}", upward.join("\n"));
}

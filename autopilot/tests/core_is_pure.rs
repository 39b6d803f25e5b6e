//! The vehicle core must stay pure (`docs/design.md`): nothing under `src/core/` may use an async runtime,
//! sockets, files or clocks, so that it runs identically in lockstep, in SITL and on the airframe.

use std::path::Path;

const FORBIDDEN: [&str; 5] = ["tokio", "std::net", "std::fs", "Instant", "SystemTime"];

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("core directory is readable") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// `line` without the text inside double quotes (a test may name a forbidden word in a string).
fn code_outside_strings(line: &str) -> String {
    line.split('"').step_by(2).collect::<Vec<_>>().join(" ")
}

/// The offending lines of `text`, skipping comments (the doc comments may name what is forbidden) and
/// string literals.
fn offences(text: &str) -> Vec<(usize, String)> {
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.trim_start().starts_with("//"))
        .filter(|(_, line)| {
            let code = code_outside_strings(line);
            FORBIDDEN.iter().any(|word| code.contains(word))
        })
        .map(|(i, line)| (i + 1, line.trim().to_owned()))
        .collect()
}

#[test]
fn nothing_under_core_uses_io_clocks_or_an_async_runtime() {
    let core = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/core");
    let mut files = Vec::new();
    rust_files(&core, &mut files);
    assert!(files.len() > 5, "found only {} files under {}", files.len(), core.display());
    let mut bad = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).expect("source is readable");
        for (line, code) in offences(&text) {
            bad.push(format!("{}:{line}: {code}", file.display()));
        }
    }
    assert!(bad.is_empty(), "the core must stay pure:\n{}", bad.join("\n"));
}

#[test]
fn the_purity_check_catches_each_forbidden_use_and_ignores_comments() {
    for word in FORBIDDEN {
        assert_eq!(offences(&format!("let x = {word}::now();")).len(), 1, "{word}");
        assert!(offences(&format!("    // no {word} here")).is_empty(), "{word} in a comment");
        assert!(offences(&format!("let banned = [\"{word}\"];")).is_empty(), "{word} in a string");
        assert_eq!(offences(&format!("let s = \"a\"; use {word};")).len(), 1, "{word} after a string");
    }
}

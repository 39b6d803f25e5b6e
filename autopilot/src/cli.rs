//! What the `autopilot` and `sitl` command lines share: logging (INFO unless `RUST_LOG` says otherwise,
//! colour only on a terminal) and user errors printed as one line, each cause once, without a backtrace.

use std::error::Error;
use std::io::IsTerminal;
use std::process::ExitCode;

/// Log to standard error at INFO (or as `RUST_LOG` says), with ANSI colour only when standard error is a
/// terminal, so a redirected log holds no escape codes.
pub fn init_logging() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

/// The error and its causes in one line (`outer: cause: root`). A cause whose text is already part of
/// what precedes it is left out: many errors quote their source in their own message, and printing the
/// chain naively says the same TOML or I/O error twice.
#[must_use]
pub fn one_line(err: &(dyn Error + 'static)) -> String {
    let mut line = err.to_string();
    let mut cause = err.source();
    while let Some(e) = cause {
        let text = e.to_string();
        if !text.is_empty() && !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = e.source();
    }
    // A multi-line cause stays readable on one line: a TOML error's source excerpt (the `  |`, `3 | text`
    // and caret lines) goes, its position and its message stay.
    line.lines().map(str::trim).filter(|l| !l.is_empty() && !is_source_excerpt(l)).collect::<Vec<_>>().join(": ")
}

/// A line of a source excerpt as TOML (and rustc-style) errors print them: `|`, `| ^^^`, `12 | key = 1`.
fn is_source_excerpt(line: &str) -> bool {
    let rest = line.trim_start_matches(|c: char| c.is_ascii_digit()).trim_start();
    rest.starts_with('|')
}

/// The process's exit: success, or `program: error: <one line>` on standard error and exit code 1. The
/// backtrace `anyhow` captures under `RUST_BACKTRACE` is a developer's tool, not a user's message, so it
/// is not printed.
pub fn exit(program: &str, result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("{program}: error: {}", one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// The I/O error "address in use" somewhere in `err`'s chain: a port another process holds.
#[must_use]
pub fn address_in_use(err: &(dyn Error + 'static)) -> bool {
    let mut cause: Option<&(dyn Error + 'static)> = Some(err);
    while let Some(e) = cause {
        if e.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::AddrInUse) {
            return true;
        }
        cause = e.source();
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("plant configuration cfg.toml: {source}")]
    struct Quoting {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("reading the state")]
    struct Terse {
        source: std::io::Error,
    }

    #[test]
    fn a_cause_the_message_already_quotes_is_said_once() {
        let err = Quoting { source: std::io::Error::other("unknown field `bogus`") };
        assert_eq!(one_line(&err), "plant configuration cfg.toml: unknown field `bogus`");
    }

    #[test]
    fn a_cause_the_message_does_not_quote_is_appended() {
        let err = Terse { source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file") };
        assert_eq!(one_line(&err), "reading the state: no such file");
    }

    #[test]
    fn an_anyhow_context_chain_is_one_line_without_duplicates() {
        let inner = anyhow::Error::new(Quoting { source: std::io::Error::other("expected `=`\n  |\n1 | x\n") });
        let err = inner.context("loading cfg.toml");
        let line = one_line(err.as_ref());
        assert_eq!(line.matches("expected `=`").count(), 1, "{line}");
        assert!(!line.contains('\n'), "{line}");
        assert!(line.starts_with("loading cfg.toml: plant configuration"), "{line}");
    }

    #[test]
    fn a_toml_error_keeps_its_position_and_message_and_drops_the_excerpt() {
        let toml_error = toml::from_str::<toml::Table>("[airframe\nmass_kg = 1.0\n").expect_err("broken");
        let err = anyhow::Error::new(toml_error).context("plant configuration p.toml");
        let line = one_line(err.as_ref());
        assert!(line.starts_with("plant configuration p.toml: TOML parse error at line 1, column 10: "), "{line}");
        assert!(!line.contains('|') && !line.contains('^'), "{line}");
    }

    #[test]
    fn address_in_use_is_found_anywhere_in_the_chain() {
        let taken = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
        let io = std::net::UdpSocket::bind(taken.local_addr().expect("addr")).expect_err("taken");
        let err = anyhow::Error::new(io).context("binding the plant port");
        assert!(address_in_use(err.as_ref()));
        assert!(!address_in_use(anyhow::anyhow!("something else").as_ref()));
    }
}

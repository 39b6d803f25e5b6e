//! Progress of the runs that take more than a few seconds of wall time (`sitl run --duration`, `sitl
//! scenario` over many runs): an indicatif bar on a terminal, and where standard error is a file or a pipe,
//! one plain line every [`LINE_INTERVAL`] of wall time, so a CI log shows the run is alive without escape
//! codes or carriage returns.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How often the plain (not a terminal) progress line is written.
pub const LINE_INTERVAL: Duration = Duration::from_secs(10);

/// Where progress goes.
#[derive(Debug)]
enum Sink {
    Bar(ProgressBar),
    Lines { last: Instant },
    Off,
}

/// The progress of one long job of `total` units (simulated seconds, runs).
#[derive(Debug)]
pub struct Progress {
    sink: Sink,
    label: String,
    unit: &'static str,
    total: u64,
    done: u64,
}

impl Progress {
    /// A bar when standard error is a terminal, else periodic lines.
    #[must_use]
    pub fn new(label: &str, total: u64, unit: &'static str) -> Self {
        let sink = if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr_with_hz(4));
            let template = format!("{{prefix}} [{{bar:30}}] {{pos}}/{{len}} {unit} ({{percent}} %, {{eta}} left)");
            if let Ok(style) = ProgressStyle::with_template(&template) {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_prefix(label.to_owned());
            Sink::Bar(bar)
        } else {
            Sink::Lines { last: Instant::now() }
        };
        Self { sink, label: label.to_owned(), unit, total, done: 0 }
    }

    /// No output at all (for runs short enough not to need it, and for tests).
    #[must_use]
    pub fn hidden(total: u64) -> Self {
        Self { sink: Sink::Off, label: String::new(), unit: "", total, done: 0 }
    }

    /// `done` units of the total are finished.
    pub fn set(&mut self, done: u64) {
        self.done = done.min(self.total);
        match &mut self.sink {
            Sink::Bar(bar) => bar.set_position(self.done),
            Sink::Lines { last } => {
                if last.elapsed() >= LINE_INTERVAL {
                    *last = Instant::now();
                    eprintln!("{}", self.line());
                }
            }
            Sink::Off => {}
        }
    }

    /// What a plain progress line says: "label: 120 of 3000 s (4 %)".
    #[must_use]
    pub fn line(&self) -> String {
        let pct = (self.done * 100).checked_div(self.total).unwrap_or(100);
        format!("{}: {} of {} {} ({pct} %)", self.label, self.done, self.total, self.unit)
    }

    /// Runs `f` (which writes to the terminal) with the bar out of the way.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        match &self.sink {
            Sink::Bar(bar) => bar.suspend(f),
            _ => f(),
        }
    }

    /// The job is over: the bar is cleared (what follows says how it went).
    pub fn finish(self) {
        if let Sink::Bar(bar) = self.sink {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plain_line_counts_units_and_percent_and_never_exceeds_the_total() {
        let mut p = Progress::hidden(3000);
        p.label = "sitl run".into();
        p.unit = "s";
        p.set(120);
        assert_eq!(p.line(), "sitl run: 120 of 3000 s (4 %)");
        p.set(5000);
        assert_eq!(p.line(), "sitl run: 3000 of 3000 s (100 %)");
        let empty = Progress::hidden(0);
        assert!(empty.line().ends_with("(100 %)"), "{}", empty.line());
    }
}

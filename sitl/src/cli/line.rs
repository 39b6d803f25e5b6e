//! `sitl line`: an emulated serial line ([`sitl::serial_line`]) between two pty devices that symlinks name,
//! as `socat pty,link=A pty,link=B` does, but at a baud rate (10 bits a byte), with loss in bursts,
//! corruption and latency. Two processes open the two links as serial ports. It runs until SIGINT or
//! SIGTERM (or the end of standard input, with `--stop-on-stdin-eof`), writes the counters as JSON every
//! 0.5 s with `--stats`, and removes its links on the way out.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use autopilot::runtime::persist::write_file_atomically;
use clap::Args;
use sitl::serial_line::{DirectionStats, LineConfig, MAX_BUFFER_BYTES, MAX_LATENCY, SerialLine};

/// How often the stats file is written.
const STATS_PERIOD: Duration = Duration::from_millis(500);
/// How often the main thread looks at the stop flag.
const TICK: Duration = Duration::from_millis(50);

#[derive(Args)]
pub(crate) struct LineArgs {
    /// Symlink to end A's pty device (replaced if it is a stale symlink; a file there is refused).
    #[arg(long, value_name = "PATH")]
    pub(crate) link_a: PathBuf,
    /// Symlink to end B's pty device.
    #[arg(long, value_name = "PATH")]
    pub(crate) link_b: PathBuf,
    /// Bits per second; the line carries baud / 10 bytes per second (8N1).
    #[arg(long, default_value_t = 115_200)]
    pub(crate) baud: u32,
    /// Bytes lost, percent (1 = 1 %), 0..=50.
    #[arg(long, value_name = "PCT", default_value_t = 0.0)]
    pub(crate) loss: f64,
    /// Lost bytes come in runs of this many: 1 for a UART's single bytes, a packet's size for a radio.
    #[arg(long, value_name = "BYTES", default_value_t = 1)]
    pub(crate) burst: u32,
    /// Delivered bytes with one bit flipped, percent, 0..=50.
    #[arg(long, value_name = "PCT", default_value_t = 0.0)]
    pub(crate) corrupt: f64,
    /// Added to every byte's delivery, ms.
    #[arg(long, value_name = "MS", default_value_t = 0.0)]
    pub(crate) latency_ms: f64,
    /// Seed of the loss and corruption draws (one stream per direction).
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Bytes the line holds per direction before it stops reading the sender (back-pressure).
    #[arg(long, value_name = "BYTES", default_value_t = 4096)]
    pub(crate) buffer: usize,
    /// Write the counters as JSON to FILE every 0.5 s and at exit (atomically).
    #[arg(long, value_name = "FILE")]
    pub(crate) stats: Option<PathBuf>,
    /// Stop when standard input reaches its end, too.
    #[arg(long)]
    pub(crate) stop_on_stdin_eof: bool,
}

impl LineArgs {
    /// The line's configuration, every flag checked and named if bad.
    fn config(&self) -> Result<LineConfig> {
        if self.baud == 0 {
            bail!("--baud must be at least 1 bit per second, got 0");
        }
        for (flag, pct) in [("--loss", self.loss), ("--corrupt", self.corrupt)] {
            if !(0.0..=50.0).contains(&pct) {
                bail!("{flag} must be a percentage in 0..=50 (1 = 1 %), got {pct}");
            }
        }
        if self.burst == 0 {
            bail!("--burst must be at least 1 byte, got 0");
        }
        let max_latency_ms = MAX_LATENCY.as_secs_f64() * 1000.0;
        if !(0.0..=max_latency_ms).contains(&self.latency_ms) {
            bail!("--latency-ms must be in 0..={max_latency_ms}, got {}", self.latency_ms);
        }
        if !(1..=MAX_BUFFER_BYTES).contains(&self.buffer) {
            bail!("--buffer must be in 1..={MAX_BUFFER_BYTES} bytes, got {}", self.buffer);
        }
        let config = LineConfig {
            baud: self.baud,
            loss: self.loss / 100.0,
            burst_bytes: self.burst,
            corrupt: self.corrupt / 100.0,
            latency: Duration::from_secs_f64(self.latency_ms / 1000.0),
            seed: self.seed,
            buffer_bytes: self.buffer,
        };
        config.validate().map_err(anyhow::Error::msg)?;
        Ok(config)
    }
}

pub(crate) fn line(args: &LineArgs) -> Result<()> {
    let config = args.config()?;
    if args.link_a == args.link_b {
        bail!("--link-a and --link-b are both {}: each end needs its own link", args.link_a.display());
    }
    check_link_free("--link-a", &args.link_a)?;
    check_link_free("--link-b", &args.link_b)?;
    let stop = stop_flag(args.stop_on_stdin_eof)?;
    let line = SerialLine::open(config.clone()).context("opening the line's ptys")?;
    let _link_a = Link::create(&args.link_a, line.a_path())?;
    let _link_b = Link::create(&args.link_b, line.b_path())?;
    let start = Instant::now();
    if let Some(file) = &args.stats {
        write_stats(file, start, &line)?;
    }
    eprintln!(
        "sitl line: A {} ({}) <-> B {} ({}) at {} baud ({} B/s), loss {} % in bursts of {} B, corruption {} %, \
         latency {} ms",
        args.link_a.display(),
        line.a_path(),
        args.link_b.display(),
        line.b_path(),
        config.baud,
        config.bytes_per_s(),
        args.loss,
        config.burst_bytes,
        args.corrupt,
        args.latency_ms
    );
    let mut stats_due = start + STATS_PERIOD;
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(TICK);
        if let Some(file) = &args.stats
            && Instant::now() >= stats_due
        {
            write_stats(file, start, &line)?;
            stats_due += STATS_PERIOD;
        }
    }
    if let Some(file) = &args.stats {
        write_stats(file, start, &line)?;
    }
    let stats = line.stats();
    let overrun = line.overrun_bytes();
    for (name, d, overrun_bytes) in [("A to B", stats.a_to_b, overrun.a_to_b), ("B to A", stats.b_to_a, overrun.b_to_a)]
    {
        eprintln!(
            "sitl line: {name}: {} B in, {} B out, {} B lost ({overrun_bytes} B of them overrun: nobody reading), \
             {} B corrupted",
            d.bytes_in, d.bytes_out, d.lost, d.corrupted
        );
    }
    Ok(())
}

/// Refuse a link path that holds anything but a symlink (a stale one is replaced).
fn check_link_free(flag: &str, path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) if !meta.file_type().is_symlink() => {
            bail!("{flag} {} exists and is not a symlink: refusing to replace it", path.display())
        }
        _ => Ok(()),
    }
}

/// A symlink to an end's device, removed when dropped if it still points there.
struct Link {
    path: PathBuf,
    device: PathBuf,
}

impl Link {
    fn create(path: &Path, device: &str) -> Result<Link> {
        if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
            std::fs::remove_file(path).with_context(|| format!("removing the stale link {}", path.display()))?;
        }
        std::os::unix::fs::symlink(device, path).with_context(|| format!("linking {} to {device}", path.display()))?;
        Ok(Link { path: path.to_owned(), device: PathBuf::from(device) })
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        if std::fs::read_link(&self.path).is_ok_and(|target| target == self.device) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// A flag set on SIGINT or SIGTERM (and at the end of standard input if `stdin_eof`). The handlers are in
/// place when this returns, so a signal sent as soon as the line says it is ready stops it cleanly.
fn stop_flag(stdin_eof: bool) -> Result<Arc<AtomicBool>> {
    use tokio::signal::unix::{SignalKind, signal};
    let rt = tokio::runtime::Builder::new_current_thread().enable_io().build().context("the signal runtime")?;
    let (mut interrupt, mut terminate) = {
        let _context = rt.enter();
        (
            signal(SignalKind::interrupt()).context("handling SIGINT")?,
            signal(SignalKind::terminate()).context("handling SIGTERM")?,
        )
    };
    let flag = Arc::new(AtomicBool::new(false));
    let set = flag.clone();
    std::thread::spawn(move || {
        rt.block_on(async {
            let stdin_closed = async {
                if stdin_eof {
                    autopilot::runtime::shutdown::stdin_closed().await;
                } else {
                    std::future::pending::<()>().await;
                }
            };
            tokio::select! {
                _ = interrupt.recv() => {}
                _ = terminate.recv() => {}
                () = stdin_closed => {}
            }
        });
        set.store(true, Ordering::Relaxed);
    });
    Ok(flag)
}

fn direction_json(d: DirectionStats, overrun_bytes: u64) -> serde_json::Value {
    serde_json::json!({
        "bytes_in": d.bytes_in,
        "bytes_out": d.bytes_out,
        "lost": d.lost,
        "corrupted": d.corrupted,
        "overrun": overrun_bytes,
    })
}

fn write_stats(file: &Path, start: Instant, line: &SerialLine) -> Result<()> {
    let stats = line.stats();
    let overrun = line.overrun_bytes();
    let json = serde_json::json!({
        "elapsed_s": start.elapsed().as_secs_f64(),
        "a_to_b": direction_json(stats.a_to_b, overrun.a_to_b),
        "b_to_a": direction_json(stats.b_to_a, overrun.b_to_a),
    });
    write_file_atomically(file, format!("{json}\n").as_bytes())
        .with_context(|| format!("writing the stats file {}", file.display()))
}

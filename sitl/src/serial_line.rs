//! An emulated serial line between two pseudo-terminals (Unix): a UART or a telemetry radio for tests that
//! put the plant, the autopilot or a ground station on its two ends.
//!
//! In: the bytes a client writes into one end's device ([`SerialLine::a_path`], [`SerialLine::b_path`]: pty
//! slaves, opened as serial ports). Out: the same bytes at the other end, each one `10 / baud` s after the
//! one before at best (8N1: a start bit, 8 data bits and a stop bit a byte), plus `latency`; some lost in
//! runs of `burst_bytes`, some with one bit flipped, both drawn from a ChaCha8 stream per direction, so
//! what is lost or corrupted depends only on the seed and each byte's place in the stream, never on timing.
//!
//! One relay thread per direction moves the bytes from one pty master to the other: it reads what the
//! sender wrote, gives every byte the time it leaves the wire, and writes the bytes that are due in small
//! batches, sleeping in `poll` until a byte comes in or one is due (about 1 ms granularity). It stops
//! reading a sender that is `buffer_bytes` ahead of the wire, so the sender's writes block once the pty's
//! own buffer fills too (back-pressure, as a UART driver's full transmit buffer). What the receiving pty
//! has no room for is dropped and counted as lost (an overrun: nobody reads that end). The line keeps both
//! slaves open itself, so a client may close and reopen its end at any time, and it clears the
//! exclusive-open flag (`TIOCEXCL`) a client killed without closing its port leaves behind.

use std::collections::VecDeque;
use std::io;
use std::os::fd::OwnedFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rustix::event::{PollFd, PollFlags, Timespec};
use rustix::fs::{Mode, OFlags};
use rustix::io::Errno;
use rustix::pty::OpenptFlags;
use rustix::termios::OptionalActions;

/// Bits on the wire per byte (8N1), as the link budget counts them.
pub use autopilot::core::plant_link::budget::BITS_PER_BYTE;
/// The longest latency [`LineConfig::validate`] accepts.
pub const MAX_LATENCY: Duration = Duration::from_secs(10);
/// The largest `buffer_bytes` [`LineConfig::validate`] accepts.
pub const MAX_BUFFER_BYTES: usize = 1 << 24;
/// The longest a relay thread sleeps: how long [`SerialLine`]'s drop waits for it, at most.
const IDLE_S: f64 = 0.05;
/// The shortest sleep while bytes are in flight: the granularity of delivery.
const MIN_WAIT_S: f64 = 0.001;
/// How often a relay clears its sender end's exclusive-open flag.
const CLEAR_EXCLUSIVE_S: f64 = 0.1;
/// Bytes read from a sender at most at a time.
const READ_CHUNK_BYTES: usize = 4096;

/// How the line behaves, the same in both directions.
#[derive(Debug, Clone, PartialEq)]
pub struct LineConfig {
    /// Bits per second; bytes per second are `baud / 10` (8N1).
    pub baud: u32,
    /// Fraction of the bytes lost, 0..=0.5 (0.01 = 1 %).
    pub loss: f64,
    /// Lost bytes come in runs of this many (1 = independent bytes); at least 1.
    pub burst_bytes: u32,
    /// Fraction of the delivered bytes with one random bit flipped, 0..=0.5.
    pub corrupt: f64,
    /// Added to every byte's delivery, on top of its time on the wire.
    pub latency: Duration,
    /// Seed of the ChaCha8 streams that draw loss and corruption (stream 0 for A to B, 1 for B to A).
    pub seed: u64,
    /// Bytes the line holds per direction before it stops reading the sender (back-pressure).
    pub buffer_bytes: usize,
}

impl Default for LineConfig {
    /// 115200 baud, no loss (bursts of 1), no corruption, no latency, seed 1, a 4096-byte buffer.
    fn default() -> Self {
        Self {
            baud: 115_200,
            loss: 0.0,
            burst_bytes: 1,
            corrupt: 0.0,
            latency: Duration::ZERO,
            seed: 1,
            buffer_bytes: 4096,
        }
    }
}

impl LineConfig {
    /// Bytes per second on the wire: `baud / 10`.
    #[must_use]
    pub fn bytes_per_s(&self) -> f64 {
        f64::from(self.baud) / f64::from(BITS_PER_BYTE)
    }

    /// Whether every field is in range.
    ///
    /// # Errors
    /// One message naming every bad field and its range, `; `-separated.
    pub fn validate(&self) -> Result<(), String> {
        let mut bad = Vec::new();
        if self.baud == 0 {
            bad.push("baud must be at least 1 bit per second, got 0".to_owned());
        }
        for (name, value) in [("loss", self.loss), ("corrupt", self.corrupt)] {
            if !(0.0..=0.5).contains(&value) {
                bad.push(format!("{name} must be a fraction in 0..=0.5 (0.01 = 1 %), got {value}"));
            }
        }
        if self.burst_bytes == 0 {
            bad.push("burst_bytes must be at least 1 (1 = bytes lost one by one), got 0".to_owned());
        }
        if self.latency > MAX_LATENCY {
            bad.push(format!(
                "latency must be at most {} s, got {} s",
                MAX_LATENCY.as_secs(),
                self.latency.as_secs_f64()
            ));
        }
        if !(1..=MAX_BUFFER_BYTES).contains(&self.buffer_bytes) {
            bad.push(format!("buffer_bytes must be in 1..={MAX_BUFFER_BYTES}, got {}", self.buffer_bytes));
        }
        if bad.is_empty() { Ok(()) } else { Err(bad.join("; ")) }
    }
}

/// One direction's counters, in bytes; they only grow.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DirectionStats {
    /// Read from the sender.
    pub bytes_in: u64,
    /// Written to the receiver.
    pub bytes_out: u64,
    /// Read and never written: the configured loss, and the receiver's overruns (its pty full because
    /// nobody reads that end; see [`SerialLine::overrun_bytes`]). Once nothing is in flight,
    /// `bytes_in == bytes_out + lost`.
    pub lost: u64,
    /// Written with one bit flipped.
    pub corrupted: u64,
}

/// Both directions' counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LineStats {
    pub a_to_b: DirectionStats,
    pub b_to_a: DirectionStats,
}

/// The bytes each direction dropped because the receiver's pty was full (part of `lost`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OverrunBytes {
    pub a_to_b: u64,
    pub b_to_a: u64,
}

/// A running line: two pty pairs and a relay thread per direction. Dropping it stops and joins the threads
/// and closes the ptys (clients then see a hang-up).
#[derive(Debug)]
pub struct SerialLine {
    ends: [Arc<End>; 2],
    counters: [Arc<Counters>; 2],
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl SerialLine {
    /// Make the two pty pairs and start the relays.
    ///
    /// # Errors
    /// `InvalidInput` with [`LineConfig::validate`]'s message for a bad configuration; the system's error
    /// making a pty or a thread.
    pub fn open(config: LineConfig) -> io::Result<SerialLine> {
        config.validate().map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        let ends = [Arc::new(End::open()?), Arc::new(End::open()?)];
        let counters = [Arc::new(Counters::default()), Arc::new(Counters::default())];
        let stop = Arc::new(AtomicBool::new(false));
        let epoch = Instant::now();
        let mut line = SerialLine { ends, counters, stop, threads: Vec::with_capacity(2) };
        for (from, to, name) in [(0, 1, "serial-line-a-to-b"), (1, 0, "serial-line-b-to-a")] {
            let relay = Relay {
                wire: Wire::new(&config, from as u64),
                from: line.ends[from].clone(),
                to: line.ends[to].clone(),
                counters: line.counters[from].clone(),
                stop: line.stop.clone(),
                epoch,
                buffer_bytes: config.buffer_bytes,
                in_flight: VecDeque::new(),
                batch: Vec::new(),
            };
            // On an error `line` is dropped, which stops and joins the thread already started.
            line.threads.push(std::thread::Builder::new().name(name.to_owned()).spawn(move || relay.run())?);
        }
        Ok(line)
    }

    /// The device of end A (a pty slave: open it as a serial port).
    #[must_use]
    pub fn a_path(&self) -> &str {
        &self.ends[0].path
    }

    /// The device of end B.
    #[must_use]
    pub fn b_path(&self) -> &str {
        &self.ends[1].path
    }

    /// A snapshot of the counters.
    #[must_use]
    pub fn stats(&self) -> LineStats {
        LineStats { a_to_b: self.counters[0].snapshot(), b_to_a: self.counters[1].snapshot() }
    }

    /// A snapshot of the overruns: bytes dropped because the receiving end's pty was full.
    #[must_use]
    pub fn overrun_bytes(&self) -> OverrunBytes {
        OverrunBytes {
            a_to_b: self.counters[0].overrun.load(Ordering::Relaxed),
            b_to_a: self.counters[1].overrun.load(Ordering::Relaxed),
        }
    }
}

impl Drop for SerialLine {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
    }
}

/// One end of the line: a pty master the relays read and write, and its slave, held open so that the
/// master never hangs up when a client closes the slave.
#[derive(Debug)]
struct End {
    master: OwnedFd,
    slave: OwnedFd,
    path: String,
}

impl End {
    fn open() -> io::Result<End> {
        let master = rustix::pty::openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY | OpenptFlags::CLOEXEC)?;
        rustix::pty::grantpt(&master)?;
        rustix::pty::unlockpt(&master)?;
        let path = rustix::pty::ptsname(&master, Vec::new())?
            .into_string()
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "the pty's name is not UTF-8"))?;
        let slave = rustix::fs::open(path.as_str(), OFlags::RDWR | OFlags::NOCTTY | OFlags::CLOEXEC, Mode::empty())?;
        // Raw: no echo, no CR/LF translation, no flow-control characters, 8 bits, before any client opens.
        let mut termios = rustix::termios::tcgetattr(&slave)?;
        termios.make_raw();
        rustix::termios::tcsetattr(&slave, OptionalActions::Now, &termios)?;
        // A receiver that does not read must never block the relay.
        let flags = rustix::fs::fcntl_getfl(&master)?;
        rustix::fs::fcntl_setfl(&master, flags | OFlags::NONBLOCK)?;
        Ok(End { master, slave, path })
    }
}

#[derive(Debug, Default)]
struct Counters {
    bytes_in: AtomicU64,
    bytes_out: AtomicU64,
    lost: AtomicU64,
    corrupted: AtomicU64,
    overrun: AtomicU64,
}

impl Counters {
    fn snapshot(&self) -> DirectionStats {
        DirectionStats {
            bytes_in: self.bytes_in.load(Ordering::Relaxed),
            bytes_out: self.bytes_out.load(Ordering::Relaxed),
            lost: self.lost.load(Ordering::Relaxed),
            corrupted: self.corrupted.load(Ordering::Relaxed),
        }
    }
}

/// What the wire does to one byte.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fate {
    Lost,
    Delivered { byte: u8, due_s: f64, corrupted: bool },
}

/// One direction's wire: its timing, loss and corruption. Pure: times are given, nothing is read or written.
#[derive(Debug)]
struct Wire {
    byte_s: f64,
    latency_s: f64,
    /// When the wire has sent every byte given so far.
    free_at_s: f64,
    /// The chance that a byte out of a lost run starts one.
    run_start_p: f64,
    burst_bytes: u32,
    corrupt: f64,
    /// Bytes still to lose in the current run.
    run_left_bytes: u32,
    rng: ChaCha8Rng,
}

impl Wire {
    fn new(config: &LineConfig, stream: u64) -> Wire {
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        rng.set_stream(stream);
        // A run starts with chance p out of a run and lasts b bytes, so the fraction lost is
        // b p / (b p + 1 - p); this p makes it exactly `loss` (p = loss for b = 1, about loss / b otherwise).
        let b = f64::from(config.burst_bytes);
        let run_start_p = config.loss / (b * (1.0 - config.loss) + config.loss);
        Wire {
            byte_s: 1.0 / config.bytes_per_s(),
            latency_s: config.latency.as_secs_f64(),
            free_at_s: 0.0,
            run_start_p,
            burst_bytes: config.burst_bytes,
            corrupt: config.corrupt,
            run_left_bytes: 0,
            rng,
        }
    }

    /// Put `byte`, read from the sender at `read_at_s`, on the wire: it leaves the wire one byte time after
    /// the wire is free (or after it was read, if later), and is due at the receiver `latency` after that.
    /// A lost byte takes the wire's time too.
    fn send(&mut self, byte: u8, read_at_s: f64) -> Fate {
        let sent_s = self.free_at_s.max(read_at_s) + self.byte_s;
        self.free_at_s = sent_s;
        if self.run_left_bytes > 0 {
            self.run_left_bytes -= 1;
            return Fate::Lost;
        }
        if self.run_start_p > 0.0 && self.rng.random::<f64>() < self.run_start_p {
            self.run_left_bytes = self.burst_bytes - 1;
            return Fate::Lost;
        }
        let corrupted = self.corrupt > 0.0 && self.rng.random::<f64>() < self.corrupt;
        let byte = if corrupted { byte ^ (1 << self.rng.random_range(0..8_u32)) } else { byte };
        Fate::Delivered { byte, due_s: sent_s + self.latency_s, corrupted }
    }

    /// Bytes given but not yet sent at `now_s` (the wire is busy without a gap from `now_s` to `free_at_s`).
    fn unsent_bytes(&self, now_s: f64) -> usize {
        // Less a billionth of a byte, so that rounding never counts a byte just sent.
        let bytes = (self.free_at_s - now_s) / self.byte_s - 1e-9;
        if bytes > 0.0 { bytes.ceil() as usize } else { 0 }
    }

    /// When fewer than `bytes` will be unsent.
    fn unsent_below_at_s(&self, bytes: usize) -> f64 {
        self.free_at_s - bytes.saturating_sub(1) as f64 * self.byte_s
    }
}

/// One direction: reads the sender's master, writes the receiver's.
struct Relay {
    wire: Wire,
    from: Arc<End>,
    to: Arc<End>,
    counters: Arc<Counters>,
    stop: Arc<AtomicBool>,
    epoch: Instant,
    buffer_bytes: usize,
    /// Delivered bytes not yet due: (due time, byte, corrupted).
    in_flight: VecDeque<(f64, u8, bool)>,
    batch: Vec<u8>,
}

impl Relay {
    fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    fn run(mut self) {
        let mut read_buf = vec![0_u8; READ_CHUNK_BYTES];
        let mut cleared_at_s = f64::NEG_INFINITY;
        while !self.stop.load(Ordering::Relaxed) {
            let now_s = self.now_s();
            if now_s - cleared_at_s >= CLEAR_EXCLUSIVE_S {
                // A client killed without closing its port leaves the tty exclusive, and since the line holds
                // the slave open the flag would outlive it: no one but root could open the end again.
                let _ = rustix::termios::ioctl_tiocnxcl(&self.from.slave);
                cleared_at_s = now_s;
            }
            self.deliver_due(now_s);
            let now_s = self.now_s();
            let room_bytes = self.buffer_bytes.saturating_sub(self.wire.unsent_bytes(now_s));
            let mut wake_s = now_s + IDLE_S;
            if let Some(&(due_s, _, _)) = self.in_flight.front() {
                wake_s = wake_s.min(due_s);
            }
            if room_bytes == 0 {
                wake_s = wake_s.min(self.wire.unsent_below_at_s(self.buffer_bytes));
            }
            let wait = Duration::from_secs_f64((wake_s - now_s).clamp(MIN_WAIT_S, IDLE_S));
            if room_bytes == 0 {
                std::thread::sleep(wait);
            } else if self.readable(wait) {
                let want = room_bytes.min(read_buf.len());
                self.read(&mut read_buf[..want]);
            }
        }
    }

    /// Whether the sender's master has bytes, waiting up to `wait`.
    fn readable(&self, wait: Duration) -> bool {
        let timeout = Timespec::try_from(wait).unwrap_or(Timespec { tv_sec: 0, tv_nsec: 1_000_000 });
        let mut fds = [PollFd::new(&self.from.master, PollFlags::IN)];
        match rustix::event::poll(&mut fds, Some(&timeout)) {
            Ok(0) | Err(Errno::INTR) => false,
            Ok(_) => true,
            Err(e) => {
                tracing::warn!("serial line: poll on {}: {e}", self.from.path);
                std::thread::sleep(Duration::from_secs_f64(IDLE_S));
                false
            }
        }
    }

    /// Read what the sender wrote (up to `buf`'s length) and put it on the wire.
    fn read(&mut self, buf: &mut [u8]) {
        let n = match rustix::io::read(&self.from.master, &mut *buf) {
            Ok(n) if n > 0 => n,
            Err(Errno::AGAIN | Errno::INTR) => return,
            // End of file or a hang-up (no slave open, which the line's own slave rules out): do not spin.
            _ => {
                std::thread::sleep(Duration::from_secs_f64(IDLE_S));
                return;
            }
        };
        let read_at_s = self.now_s();
        let mut lost = 0;
        for &byte in &buf[..n] {
            match self.wire.send(byte, read_at_s) {
                Fate::Lost => lost += 1,
                Fate::Delivered { byte, due_s, corrupted } => self.in_flight.push_back((due_s, byte, corrupted)),
            }
        }
        self.counters.bytes_in.fetch_add(n as u64, Ordering::Relaxed);
        self.counters.lost.fetch_add(lost, Ordering::Relaxed);
    }

    /// Write the bytes due by `now_s` to the receiver; what its pty has no room for is an overrun.
    fn deliver_due(&mut self, now_s: f64) {
        self.batch.clear();
        let mut corrupted = Vec::new();
        while let Some(&(due_s, byte, bad)) = self.in_flight.front() {
            if due_s > now_s {
                break;
            }
            if bad {
                corrupted.push(self.batch.len());
            }
            self.batch.push(byte);
            self.in_flight.pop_front();
        }
        if self.batch.is_empty() {
            return;
        }
        let mut written = 0;
        while written < self.batch.len() {
            match rustix::io::write(&self.to.master, &self.batch[written..]) {
                Ok(0) => break,
                Ok(n) => written += n,
                Err(Errno::INTR) => {}
                // AGAIN: the receiver's pty is full.
                Err(_) => break,
            }
        }
        let overrun = (self.batch.len() - written) as u64;
        self.counters.bytes_out.fetch_add(written as u64, Ordering::Relaxed);
        let corrupted_out = corrupted.iter().filter(|&&i| i < written).count();
        self.counters.corrupted.fetch_add(corrupted_out as u64, Ordering::Relaxed);
        if overrun > 0 {
            self.counters.lost.fetch_add(overrun, Ordering::Relaxed);
            self.counters.overrun.fetch_add(overrun, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use serialport::SerialPort;

    use super::*;

    /// Longest any test waits for bytes: only a failure waits this long.
    const PATIENCE: Duration = Duration::from_secs(60);

    fn open_end(path: &str) -> Box<dyn SerialPort> {
        serialport::new(path, 115_200).timeout(Duration::from_millis(10)).open().expect("open an end")
    }

    fn line(config: LineConfig) -> SerialLine {
        SerialLine::open(config).expect("the line opens")
    }

    /// Write all of `bytes`, waiting out the line's back-pressure (a full pty is a timed-out write).
    fn write_patiently(port: &mut dyn SerialPort, bytes: &[u8]) {
        let deadline = Instant::now() + PATIENCE;
        let mut written = 0;
        while written < bytes.len() {
            assert!(Instant::now() < deadline, "the line stopped taking bytes after {written}");
            match port.write(&bytes[written..]) {
                Ok(n) => written += n,
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) => panic!("writing an end: {e}"),
            }
        }
    }

    /// Read until `n` bytes came, or nothing came for `quiet` (then fewer).
    fn read_bytes(port: &mut dyn SerialPort, n: usize, quiet: Duration) -> Vec<u8> {
        let mut got = Vec::with_capacity(n);
        let mut buf = [0_u8; 4096];
        let mut last = Instant::now();
        while got.len() < n && last.elapsed() < quiet {
            match port.read(&mut buf) {
                Ok(k) => {
                    got.extend_from_slice(&buf[..k]);
                    last = Instant::now();
                }
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) => panic!("reading an end: {e}"),
            }
        }
        got
    }

    /// Wait until `done(stats)`, or fail after [`PATIENCE`].
    fn stats_when(line: &SerialLine, done: impl Fn(&LineStats) -> bool) -> LineStats {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let stats = line.stats();
            if done(&stats) {
                return stats;
            }
            assert!(Instant::now() < deadline, "stats never got there: {stats:?}");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    #[test]
    fn every_byte_value_passes_a_to_b_and_b_to_a_unchanged_without_loss() {
        let line = line(LineConfig::default());
        let mut a = open_end(line.a_path());
        let mut b = open_end(line.b_path());
        let all: Vec<u8> = (0..=255).collect();
        write_patiently(a.as_mut(), &all);
        assert_eq!(read_bytes(b.as_mut(), 256, PATIENCE), all, "A to B");
        let reversed: Vec<u8> = (0..=255).rev().collect();
        write_patiently(b.as_mut(), &reversed);
        assert_eq!(read_bytes(a.as_mut(), 256, PATIENCE), reversed, "B to A");
        let whole = DirectionStats { bytes_in: 256, bytes_out: 256, lost: 0, corrupted: 0 };
        let stats = stats_when(&line, |s| s.b_to_a.bytes_out == 256);
        assert_eq!(stats, LineStats { a_to_b: whole, b_to_a: whole });
        // Nothing more comes: no echo, no translation added bytes.
        assert!(read_bytes(a.as_mut(), 1, Duration::from_millis(100)).is_empty());
        assert!(read_bytes(b.as_mut(), 1, Duration::from_millis(100)).is_empty());
    }

    #[test]
    fn at_57600_baud_5760_bytes_take_at_least_0_98_s_and_all_arrive() {
        let line = line(LineConfig { baud: 57_600, ..LineConfig::default() });
        let mut a = open_end(line.a_path());
        let mut b = open_end(line.b_path());
        let sent: Vec<u8> = (0..5760_u32).map(|i| (i % 256) as u8).collect();
        let start = Instant::now();
        let writer = {
            let sent = sent.clone();
            std::thread::spawn(move || {
                write_patiently(a.as_mut(), &sent);
                a
            })
        };
        let got = read_bytes(b.as_mut(), sent.len(), PATIENCE);
        let elapsed = start.elapsed();
        let _a = writer.join().expect("the writer");
        assert_eq!(got, sent);
        assert!(elapsed >= Duration::from_secs_f64(0.98), "5760 bytes at 5760 B/s in {elapsed:?}");
    }

    /// The bytes `i % 251` for `i` in `0..n`: a lost run shorter than 251 bytes shows as a jump.
    fn counting(n: usize) -> Vec<u8> {
        (0..n).map(|i| (i % 251) as u8).collect()
    }

    /// The lost runs in `got`, a subsequence of `counting(sent_bytes)`: (start index, length), the last one
    /// possibly cut by the end of the stream.
    fn lost_runs(got: &[u8], sent_bytes: usize) -> Vec<(usize, usize)> {
        let mut runs = Vec::new();
        let mut at = 0;
        for &byte in got {
            let gap = (usize::from(byte) + 251 - at % 251) % 251;
            if gap > 0 {
                runs.push((at, gap));
            }
            at += gap + 1;
        }
        if at < sent_bytes {
            runs.push((at, sent_bytes - at));
        }
        runs
    }

    /// Times a transfer at 1 Mbaud is tried before a test gives up on a reader too slow for the line.
    const ATTEMPTS: usize = 3;

    /// `attempt()` until its line had no overrun (`Some`), at most [`ATTEMPTS`] times. At 1 Mbaud the test's
    /// reader must empty B's pty every few tens of ms; a machine busy elsewhere (a parallel build, the
    /// other tests) can stall it longer, and the line then drops what B's full pty has no room for, as a
    /// UART does. The line counts those bytes exactly, so such an attempt is known to say nothing about the
    /// wire and is flown again; what the wire does is asserted, unchanged, on one without.
    fn without_overrun<T>(mut attempt: impl FnMut() -> Option<T>) -> T {
        for k in 1..=ATTEMPTS {
            if let Some(result) = attempt() {
                return result;
            }
            eprintln!("attempt {k} of {ATTEMPTS}: the reader fell behind the line (B's pty overran); again");
        }
        panic!("the reader fell behind the line in all {ATTEMPTS} attempts (a machine too busy for this test)");
    }

    #[test]
    fn an_attempt_with_an_overrun_is_flown_again_and_three_are_a_failure() {
        let mut tries = 0;
        assert_eq!(
            without_overrun(|| {
                tries += 1;
                (tries == 3).then_some(tries)
            }),
            3
        );
        let gave_up = std::panic::catch_unwind(|| without_overrun(|| None::<()>));
        assert!(gave_up.is_err(), "three overruns fail the test");
    }

    /// `sent_bytes` from A to B at 1 Mbaud with 1 % loss in bursts of `burst_bytes`: the lost runs in what
    /// B got, which must be those the wire draws for the seed, and the counters.
    fn lossy_transfer(sent_bytes: usize, burst_bytes: u32) -> (Vec<(usize, usize)>, DirectionStats) {
        without_overrun(|| lossy_transfer_once(sent_bytes, burst_bytes))
    }

    /// One attempt of [`lossy_transfer`]; `None` when B's pty overran.
    fn lossy_transfer_once(sent_bytes: usize, burst_bytes: u32) -> Option<(Vec<(usize, usize)>, DirectionStats)> {
        let config = LineConfig { baud: 1_000_000, loss: 0.01, burst_bytes, ..LineConfig::default() };
        let line = line(config.clone());
        let mut a = open_end(line.a_path());
        let mut b = open_end(line.b_path());
        let writer = std::thread::spawn(move || {
            write_patiently(a.as_mut(), &counting(sent_bytes));
            a
        });
        // Read until the line has taken every byte, none is in flight, and B got all it wrote.
        let mut got = Vec::with_capacity(sent_bytes);
        let deadline = Instant::now() + PATIENCE;
        let stats = loop {
            let stats = line.stats();
            let s = stats.a_to_b;
            if s.bytes_in == sent_bytes as u64 && s.bytes_out + s.lost == s.bytes_in && got.len() as u64 == s.bytes_out
            {
                break stats;
            }
            assert!(Instant::now() < deadline, "{stats:?} and B got {}", got.len());
            got.extend(read_bytes(b.as_mut(), sent_bytes - got.len(), Duration::from_millis(20)));
        };
        let _a = writer.join().expect("the writer");
        if line.overrun_bytes().a_to_b > 0 {
            return None;
        }
        assert_eq!(got.len() as u64, stats.a_to_b.bytes_out);
        let runs = lost_runs(&got, sent_bytes);
        // What is lost depends on the seed and the bytes sent only, never on timing.
        let mut wire = Wire::new(&config, 0);
        let lost: Vec<bool> = (0..sent_bytes).map(|_| wire.send(0, 0.0) == Fate::Lost).collect();
        let mut model_runs = Vec::new();
        for (i, l) in lost.iter().enumerate() {
            match model_runs.last_mut() {
                Some((start, len)) if *l && *start + *len == i => *len += 1,
                _ if *l => model_runs.push((i, 1)),
                _ => {}
            }
        }
        assert_eq!(runs, model_runs, "the lost runs the seed draws");
        Some((runs, stats.a_to_b))
    }

    #[test]
    fn with_1_percent_loss_in_single_bytes_the_lost_fraction_is_1_percent_and_every_byte_is_accounted_for() {
        let (runs, stats) = lossy_transfer(200_000, 1);
        assert_eq!(stats.bytes_in, stats.bytes_out + stats.lost);
        let fraction = stats.lost as f64 / stats.bytes_in as f64;
        assert!((0.008..=0.012).contains(&fraction), "lost {fraction}");
        assert_eq!(runs.iter().map(|r| r.1 as u64).sum::<u64>(), stats.lost);
        assert!(runs.iter().filter(|r| r.1 == 1).count() * 10 > runs.len() * 9, "mostly single bytes");
        assert_eq!(stats.corrupted, 0);
    }

    #[test]
    fn with_1_percent_loss_in_bursts_of_16_the_lost_fraction_is_1_percent_in_runs_of_16() {
        // Twice the bytes of single-byte loss: 1 % in runs of 16 is a quarter of the runs, 250 or so.
        let (runs, stats) = lossy_transfer(400_000, 16);
        assert_eq!(stats.bytes_in, stats.bytes_out + stats.lost);
        let fraction = stats.lost as f64 / stats.bytes_in as f64;
        assert!((0.008..=0.012).contains(&fraction), "lost {fraction}");
        assert_eq!(runs.iter().map(|r| r.1 as u64).sum::<u64>(), stats.lost);
        assert!(runs.len() >= 100, "{} runs", runs.len());
        // Two runs back to back make one of 32; the last may be cut by the end of the stream.
        let (last, whole) = runs.split_last().expect("runs");
        assert!(whole.iter().all(|r| r.1 % 16 == 0), "{whole:?}");
        assert!(last.1 % 16 == 0 || last.0 + last.1 == 400_000, "{last:?}");
    }

    #[test]
    fn corrupted_bytes_differ_in_exactly_one_bit_and_are_the_ones_counted() {
        const SENT_BYTES: usize = 100_000;
        let config = LineConfig { baud: 1_000_000, corrupt: 0.01, seed: 3, ..LineConfig::default() };
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let sent: Vec<u8> = (0..SENT_BYTES).map(|_| rng.random()).collect();
        let (got, stats) = without_overrun(|| {
            let line = line(config.clone());
            let mut a = open_end(line.a_path());
            let mut b = open_end(line.b_path());
            let writer = {
                let sent = sent.clone();
                std::thread::spawn(move || {
                    write_patiently(a.as_mut(), &sent);
                    a
                })
            };
            // Read until B got every byte the line took, or the line says B's pty overran.
            let mut got = Vec::with_capacity(SENT_BYTES);
            let deadline = Instant::now() + PATIENCE;
            while line.overrun_bytes().a_to_b == 0 {
                let s = line.stats().a_to_b;
                if s.bytes_in == SENT_BYTES as u64
                    && s.bytes_out + s.lost == s.bytes_in
                    && got.len() as u64 == s.bytes_out
                {
                    break;
                }
                assert!(Instant::now() < deadline, "{s:?} and B got {}", got.len());
                got.extend(read_bytes(b.as_mut(), SENT_BYTES - got.len(), Duration::from_millis(20)));
            }
            let _a = writer.join().expect("the writer");
            (line.overrun_bytes().a_to_b == 0).then(|| (got, line.stats()))
        });
        assert_eq!(got.len(), SENT_BYTES, "no loss configured");
        let differing: Vec<u8> = got.iter().zip(&sent).map(|(g, s)| g ^ s).filter(|x| *x != 0).collect();
        assert!(differing.iter().all(|x| x.count_ones() == 1), "one bit each");
        assert_eq!(stats.a_to_b.corrupted, differing.len() as u64);
        assert_eq!(stats.a_to_b.lost, 0);
        let fraction = differing.len() as f64 / SENT_BYTES as f64;
        assert!((0.008..=0.012).contains(&fraction), "corrupted {fraction}");
    }

    #[test]
    fn a_single_byte_arrives_no_sooner_than_the_latency() {
        let latency = Duration::from_millis(200);
        let line = line(LineConfig { baud: 4_000_000, latency, ..LineConfig::default() });
        let mut a = open_end(line.a_path());
        let mut b = open_end(line.b_path());
        let start = Instant::now();
        write_patiently(a.as_mut(), b"x");
        let got = read_bytes(b.as_mut(), 1, PATIENCE);
        let elapsed = start.elapsed();
        assert_eq!(got, b"x");
        assert!(elapsed >= latency, "arrived after {elapsed:?}");
    }

    /// Write 64-byte chunks into a non-blocking `fd` until it takes no more; the bytes taken.
    fn fill(fd: &OwnedFd) -> usize {
        let chunk = [0x55_u8; 64];
        let mut taken = 0;
        loop {
            match rustix::io::write(fd, &chunk) {
                Ok(n) if n > 0 => taken += n,
                Err(Errno::INTR) => {}
                Ok(_) | Err(Errno::AGAIN) => return taken,
                Err(e) => panic!("writing: {e}"),
            }
        }
    }

    fn open_non_blocking(path: &str) -> OwnedFd {
        let flags = OFlags::RDWR | OFlags::NOCTTY | OFlags::NONBLOCK | OFlags::CLOEXEC;
        rustix::fs::open(path, flags, Mode::empty()).expect("open non-blocking")
    }

    #[test]
    fn a_non_blocking_writer_gets_only_the_buffer_and_the_ptys_own_buffer_ahead_of_the_wire() {
        // The pty's own buffer, with no line behind it.
        let bare = End::open().expect("a pty");
        let bare_slave = open_non_blocking(&bare.path);
        // The kernel moves written bytes on to the reading side's buffer after the write: fill until that
        // leaves no more room.
        let mut pty_bytes = fill(&bare_slave);
        for _ in 0..10 {
            std::thread::sleep(Duration::from_millis(20));
            match fill(&bare_slave) {
                0 => break,
                more => pty_bytes += more,
            }
        }
        let config = LineConfig { baud: 9600, buffer_bytes: 256, ..LineConfig::default() };
        let bytes_per_s = config.bytes_per_s();
        let line = line(config);
        let a = open_non_blocking(line.a_path());
        let start = Instant::now();
        let mut taken = fill(&a);
        // The line takes its buffer's worth from the pty, then the pty takes that much more.
        stats_when(&line, |s| s.a_to_b.bytes_in >= 256);
        for pause in [Duration::from_millis(100), Duration::from_secs(1)] {
            std::thread::sleep(pause);
            taken += fill(&a);
            let elapsed_s = start.elapsed().as_secs_f64();
            let on_the_wire = bytes_per_s * elapsed_s;
            let bytes_in = line.stats().a_to_b.bytes_in;
            assert!(bytes_in as f64 <= 256.0 + on_the_wire + 1.0, "the line read {bytes_in} B in {elapsed_s} s");
            // The pty's own buffer varies by a few hundred bytes with how it was filled and drained.
            assert!(
                taken as f64 <= pty_bytes as f64 + 256.0 + on_the_wire + 1024.0,
                "{taken} B taken in {elapsed_s} s; the pty holds {pty_bytes} B"
            );
        }
        assert!(taken > 256, "{taken}");
    }

    #[test]
    fn a_client_that_closes_and_reopens_its_end_still_gets_bytes() {
        let line = line(LineConfig::default());
        let mut a = open_end(line.a_path());
        {
            let mut b = open_end(line.b_path());
            write_patiently(a.as_mut(), b"first");
            assert_eq!(read_bytes(b.as_mut(), 5, PATIENCE), b"first");
        }
        let mut b = open_end(line.b_path());
        write_patiently(a.as_mut(), b"second");
        assert_eq!(read_bytes(b.as_mut(), 6, PATIENCE), b"second");
        // The sender's side too, and a client that leaves its end exclusive without clearing it.
        drop(a);
        let killed = rustix::fs::open(line.a_path(), OFlags::RDWR | OFlags::NOCTTY, Mode::empty()).expect("open A");
        rustix::termios::ioctl_tiocexcl(&killed).expect("TIOCEXCL");
        drop(killed);
        std::thread::sleep(Duration::from_secs_f64(2.0 * CLEAR_EXCLUSIVE_S));
        let mut a = open_end(line.a_path());
        write_patiently(a.as_mut(), b"third");
        assert_eq!(read_bytes(b.as_mut(), 5, PATIENCE), b"third");
    }

    #[test]
    fn validate_refuses_each_bad_field_naming_it() {
        assert_eq!(LineConfig::default().validate(), Ok(()));
        let good = LineConfig::default();
        let cases = [
            ("baud", LineConfig { baud: 0, ..good.clone() }),
            ("loss", LineConfig { loss: -0.01, ..good.clone() }),
            ("loss", LineConfig { loss: 0.51, ..good.clone() }),
            ("loss", LineConfig { loss: f64::NAN, ..good.clone() }),
            ("burst_bytes", LineConfig { burst_bytes: 0, ..good.clone() }),
            ("corrupt", LineConfig { corrupt: 0.6, ..good.clone() }),
            ("latency", LineConfig { latency: Duration::from_secs(11), ..good.clone() }),
            ("buffer_bytes", LineConfig { buffer_bytes: 0, ..good.clone() }),
        ];
        for (field, config) in cases {
            let message = config.validate().expect_err(field);
            assert!(message.starts_with(field), "{field}: {message}");
            let err = SerialLine::open(config).expect_err(field);
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        }
        let all_bad = LineConfig { baud: 0, burst_bytes: 0, ..good };
        let message = all_bad.validate().expect_err("two bad fields");
        assert!(message.contains("baud") && message.contains("burst_bytes"), "{message}");
    }

    #[test]
    fn the_wire_sends_a_byte_every_10_bits_and_adds_the_latency() {
        let config = LineConfig { baud: 1000, latency: Duration::from_millis(50), ..LineConfig::default() };
        let mut wire = Wire::new(&config, 0);
        let due: Vec<f64> = [(1, 0.0), (2, 0.0), (3, 0.005), (4, 1.0)]
            .into_iter()
            .map(|(byte, at_s)| match wire.send(byte, at_s) {
                Fate::Delivered { byte: b, due_s, corrupted: false } if b == byte => due_s,
                other => panic!("{other:?}"),
            })
            .collect();
        // Back to back while busy; after a gap, from the time the byte came.
        for (got, want) in due.iter().zip([0.06, 0.07, 0.08, 1.06]) {
            assert!((got - want).abs() < 1e-9, "{due:?}");
        }
        assert_eq!(wire.unsent_bytes(1.0), 1);
        assert_eq!(wire.unsent_bytes(1.02), 0);
    }

    #[test]
    fn the_wire_loses_exactly_the_configured_fraction_in_runs_of_burst_bytes() {
        for burst_bytes in [1, 16] {
            let config = LineConfig { loss: 0.01, burst_bytes, ..LineConfig::default() };
            let mut wire = Wire::new(&config, 0);
            let lost: Vec<bool> = (0..2_000_000).map(|_| wire.send(0, 0.0) == Fate::Lost).collect();
            let fraction = lost.iter().filter(|l| **l).count() as f64 / lost.len() as f64;
            assert!((0.0095..=0.0105).contains(&fraction), "bursts of {burst_bytes}: {fraction}");
            let mut run = 0;
            for &l in lost.iter().chain([false].iter()) {
                if l {
                    run += 1;
                } else {
                    assert_eq!(run % burst_bytes, 0, "a run of {run}");
                    run = 0;
                }
            }
        }
    }

    #[test]
    fn the_wire_draws_the_same_fates_from_the_same_seed_and_another_stream_each_direction() {
        let config = LineConfig { loss: 0.1, corrupt: 0.1, seed: 5, ..LineConfig::default() };
        let fates = |stream| {
            let mut wire = Wire::new(&config, stream);
            (0..1000_u32).map(|i| wire.send((i % 256) as u8, 0.0)).collect::<Vec<_>>()
        };
        assert_eq!(fates(0), fates(0));
        assert_ne!(fates(0), fates(1));
    }
}

//! The live view: the viewer bridge (`python -m aco_gcs.view`, which logs to Rerun) started as a child
//! and fed the view stream on its standard input, one JSON [`ViewFrame`] per line ([`Viewer`]); the
//! plant's truth as frames ([`truth_frame`]); and the forwarder that takes the autopilots' frames off UDP
//! and moves them into the plant's frame ([`Forwarder`]). docs/view.md describes the stream and the view.
//!
//! A live run never waits on the viewer: frames go through a bounded queue to a writer thread, and a
//! frame that finds the queue full is dropped and counted ([`Delivery::Live`]). A recorded run (a
//! scenario, which runs faster than real time) waits instead, so its recording holds every sample
//! ([`Delivery::Complete`]).

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use autopilot::core::estimator::GeoOrigin;
pub use autopilot::runtime::view::{
    AheadFrame, EventFrame, MetaFrame, PlanFrame, TruthFrame, VIEW_PERIOD_US, VehicleFrame, ViewFrame, ViewSampler,
    arr3, meta_frame, quat, telemetry_of,
};
use nalgebra::Vector3;

use crate::plant::{Plant, Truth};

pub mod scenario;

/// Frames the queue to the bridge holds before a live run drops one (about 20 s of one vehicle).
pub const QUEUE_FRAMES: usize = 2048;
/// How long the bridge may take to start (Python, Rerun's servers) before the run gives up on it.
pub const READY_TIMEOUT: Duration = Duration::from_secs(60);

/// Where the view is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ViewerKind {
    /// The native viewer when there is a display ($DISPLAY or $WAYLAND_DISPLAY), else the web viewer.
    Auto,
    /// Rerun's web viewer, served on this machine (open the printed address in a browser).
    Web,
    /// Rerun's native viewer, spawned.
    Native,
    /// No viewer: only the recording (`--record`).
    None,
}

/// How the view is started.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ViewerOptions {
    pub kind: ViewerKind,
    /// The web viewer's HTTP port.
    pub web_port: u16,
    /// Rerun's gRPC port, which the viewers connect to.
    pub grpc_port: u16,
    /// Also save everything shown to this `.rrd` file.
    pub record: Option<PathBuf>,
    /// Stop serving when the stream ends (else a web view stays up until Ctrl-C).
    pub exit_at_eof: bool,
    /// The bridge reads this ULog file instead of the stream.
    pub ulog: Option<PathBuf>,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        Self { kind: ViewerKind::Auto, web_port: 9090, grpc_port: 9876, record: None, exit_at_eof: false, ulog: None }
    }
}

/// Whether a full queue drops frames (a live run) or waits for the bridge (a recorded run).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    Live,
    Complete,
}

/// Why the view did not start or end cleanly.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(
        "cannot start the viewer bridge `{python} -m aco_gcs.view`: {source}; the view needs Python with \
         rerun-sdk and aco_gcs (scripts/test's .venv has both, or: pip install 'rerun-sdk[catalog]==0.41.0' \
         -e gcs-scripts); SITL_VIEW_PYTHON names the interpreter"
    )]
    Spawn {
        python: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "the viewer bridge `{python} -m aco_gcs.view` stopped before it was ready ({status}); its error is above. \
         SITL_VIEW_PYTHON names the interpreter to use"
    )]
    NotReady { python: PathBuf, status: String },
    #[error("the viewer bridge did not start within {0:?}")]
    Timeout(Duration),
    #[error("writing the view stream: {0}")]
    Write(#[source] std::io::Error),
    #[error("the viewer bridge exited with {0}")]
    Exited(ExitStatus),
    #[error("cannot open the view stream's UDP port: {0}")]
    Bind(#[source] std::io::Error),
}

/// The Python that runs the bridge: `$SITL_VIEW_PYTHON`, else the repository's `.venv` (beside the
/// working directory, or above the `target/` this binary runs from), else `python3`.
#[must_use]
pub fn bridge_python() -> PathBuf {
    if let Some(p) = std::env::var_os("SITL_VIEW_PYTHON").filter(|p| !p.is_empty()) {
        return PathBuf::from(p);
    }
    let venv = |root: &Path| root.join(".venv/bin/python");
    let mut roots: Vec<PathBuf> = std::env::current_dir().into_iter().collect();
    if let Ok(exe) = std::env::current_exe() {
        // <repo>/target/<profile>/sitl
        roots.extend(exe.ancestors().nth(3).map(Path::to_path_buf));
    }
    roots.into_iter().map(|r| venv(&r)).find(|p| p.is_file()).unwrap_or_else(|| PathBuf::from("python3"))
}

/// The bridge's command-line options for `opts`.
#[must_use]
pub fn bridge_args(opts: &ViewerOptions) -> Vec<String> {
    let mut args: Vec<String> = vec!["-m".into(), "aco_gcs.view".into()];
    args.push(
        match opts.kind {
            ViewerKind::Auto => "--auto",
            ViewerKind::Web => "--web",
            ViewerKind::Native => "--native",
            ViewerKind::None => "--no-viewer",
        }
        .into(),
    );
    args.extend(["--web-port".into(), opts.web_port.to_string(), "--grpc-port".into(), opts.grpc_port.to_string()]);
    if let Some(path) = &opts.record {
        args.extend(["--record".into(), path.display().to_string()]);
    }
    if let Some(path) = &opts.ulog {
        args.extend(["--ulog".into(), path.display().to_string()]);
    }
    if opts.exit_at_eof {
        args.push("--exit-at-eof".into());
    }
    args
}

/// The bridge, running: a queue into its standard input and the thread that writes it.
pub struct Viewer {
    child: Child,
    tx: Option<SyncSender<String>>,
    writer: Option<JoinHandle<std::io::Result<u64>>>,
    dropped: Arc<AtomicU64>,
    delivery: Delivery,
    /// Where the view is: the web viewer's address, the recording's path, or "native viewer".
    pub url: String,
}

/// A handle that sends frames to the [`Viewer`] (from any thread).
#[derive(Clone)]
pub struct ViewSender {
    tx: SyncSender<String>,
    dropped: Arc<AtomicU64>,
    delivery: Delivery,
}

impl ViewSender {
    /// Queues `frame`: dropped (and counted) if the queue is full in a live run, waited for in a recorded
    /// one; false once the bridge is gone.
    pub fn send(&self, frame: &ViewFrame) -> bool {
        let line = frame.to_json();
        match self.delivery {
            Delivery::Complete => self.tx.send(line).is_ok(),
            Delivery::Live => match self.tx.try_send(line) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            },
        }
    }
}

/// What the view was sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ViewReport {
    pub written: u64,
    pub dropped: u64,
}

fn write_lines(mut stdin: ChildStdin, rx: &Receiver<String>) -> std::io::Result<u64> {
    let mut written = 0;
    let mut out = std::io::BufWriter::new(&mut stdin);
    while let Ok(line) = rx.recv() {
        out.write_all(line.as_bytes())?;
        out.write_all(b"\n")?;
        written += 1;
        // Flush when the queue is empty, so a live view is never a buffer behind.
        if let Ok(next) = rx.try_recv() {
            out.write_all(next.as_bytes())?;
            out.write_all(b"\n")?;
            written += 1;
        } else {
            out.flush()?;
        }
    }
    out.flush()?;
    Ok(written)
}

impl Viewer {
    /// Starts the bridge with `opts` and waits until it is ready (its servers up, its recording open).
    ///
    /// # Errors
    /// [`ViewError`]: no Python or no bridge, the bridge stopping or not ready in [`READY_TIMEOUT`].
    pub fn start(opts: &ViewerOptions, delivery: Delivery) -> Result<Self, ViewError> {
        Self::start_with(&bridge_python(), opts, delivery)
    }

    /// [`Viewer::start`] with the bridge run by `python`.
    ///
    /// # Errors
    /// As [`Viewer::start`].
    pub fn start_with(python: &Path, opts: &ViewerOptions, delivery: Delivery) -> Result<Self, ViewError> {
        let python = python.to_path_buf();
        let mut child = Command::new(&python)
            .args(bridge_args(opts))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|source| ViewError::Spawn { python: python.clone(), source })?;
        let stdout = child.stdout.take().ok_or_else(|| ViewError::Spawn {
            python: python.clone(),
            source: std::io::Error::other("no standard output"),
        })?;
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut lines = BufReader::new(stdout).lines();
            let first = lines.next().and_then(Result::ok);
            let _ = ready_tx.send(first);
            // The bridge's later lines (none expected) are read and dropped so it never blocks on them.
            for _ in lines {}
        });
        let url = match ready_rx.recv_timeout(READY_TIMEOUT) {
            Ok(Some(line)) if line.starts_with("ready") => line.trim_start_matches("ready").trim().to_string(),
            Ok(_) => {
                // Its output closed (or it said something else): it is stopping, or is told to.
                let deadline = std::time::Instant::now() + Duration::from_secs(5);
                let status = loop {
                    match child.try_wait() {
                        Ok(Some(status)) => break status.to_string(),
                        Ok(None) if std::time::Instant::now() < deadline => {
                            std::thread::sleep(Duration::from_millis(20))
                        }
                        _ => {
                            let _ = child.kill();
                            let _ = child.wait();
                            break "it did not say it was ready".to_string();
                        }
                    }
                };
                return Err(ViewError::NotReady { python, status });
            }
            Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(ViewError::Timeout(READY_TIMEOUT));
            }
        };
        let stdin = child.stdin.take().ok_or(ViewError::Write(std::io::Error::other("no standard input")))?;
        let (tx, rx) = sync_channel::<String>(QUEUE_FRAMES);
        let writer = std::thread::spawn(move || write_lines(stdin, &rx));
        Ok(Self { child, tx: Some(tx), writer: Some(writer), dropped: Arc::default(), delivery, url })
    }

    /// A sender of frames to this view.
    ///
    /// # Panics
    /// After [`Viewer::finish`] (which consumes the viewer, so never).
    #[must_use]
    pub fn sender(&self) -> ViewSender {
        ViewSender {
            tx: self.tx.clone().expect("the queue lives until finish"),
            dropped: self.dropped.clone(),
            delivery: self.delivery,
        }
    }

    /// Ends the stream (every [`ViewSender`] and [`Forwarder`] must be dropped first) and waits for the bridge: at once when it records
    /// or was told to exit at the end, else until the user closes the view (Ctrl-C).
    ///
    /// # Errors
    /// [`ViewError::Write`] when the stream could not be written, [`ViewError::Exited`] when the bridge
    /// failed.
    pub fn finish(mut self) -> Result<ViewReport, ViewError> {
        drop(self.tx.take());
        let written = match self.writer.take().map(JoinHandle::join) {
            Some(Ok(Ok(n))) => n,
            Some(Ok(Err(e))) if e.kind() != std::io::ErrorKind::BrokenPipe => return Err(ViewError::Write(e)),
            _ => 0,
        };
        let status = self.child.wait().map_err(ViewError::Write)?;
        // SIGINT (Ctrl-C) ends a served view: that is how it is meant to end.
        if !status.success() && status.code().is_some() {
            return Err(ViewError::Exited(status));
        }
        Ok(ViewReport { written, dropped: self.dropped.load(Ordering::Relaxed) })
    }
}

impl Drop for Viewer {
    /// A viewer dropped without [`Viewer::finish`] (the run failed) stops its bridge.
    fn drop(&mut self) {
        drop(self.tx.take());
        if let Some(writer) = self.writer.take() {
            let _ = self.child.kill();
            let _ = writer.join();
            let _ = self.child.wait();
        }
    }
}

/// The plant's truth as a frame of source `src`.
#[must_use]
pub fn truth_frame(src: &str, truth: &Truth) -> ViewFrame {
    ViewFrame::Truth(TruthFrame {
        src: src.into(),
        t_us: truth.time_us,
        pos_ned_m: arr3(&truth.pos_ned_m),
        q_ned_frd: quat(&truth.q_ned_frd),
        vel_ned_mps: arr3(&truth.vel_ned_mps),
        euler_rad: arr3(&truth.euler_rad),
        wind_ned_mps: arr3(&truth.wind_ned_mps),
    })
}

/// Where one vehicle's local frame sits in the plant's: the plant's geodetic map, and where the vehicle
/// started (its local origin until the estimator latches one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehiclePlacement {
    pub map: GeoOrigin,
    pub start_ned_m: Vector3<f64>,
}

impl VehiclePlacement {
    /// Where `plant`'s vehicle sits: the plant's map (its home) and the vehicle's position now.
    #[must_use]
    pub fn of(plant: &Plant) -> Self {
        Self { map: plant.config().sensors.home.origin(), start_ned_m: plant.truth().pos_ned_m }
    }

    /// The plant-frame position of the local origin `origin` (lat, lon, alt), or the start without one.
    #[must_use]
    pub fn offset_ned_m(&self, origin: Option<[f64; 3]>) -> Vector3<f64> {
        origin.map_or(self.start_ned_m, |[lat, lon, alt]| self.map.ned_from_geodetic(lat, lon, alt))
    }
}

/// The autopilots' frames, taken off a UDP port (each autopilot's `--view-udp`), moved into the plant's
/// frame and queued to the view, on a thread of its own until dropped.
pub struct Forwarder {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<u64>>,
}

impl Forwarder {
    /// Binds a port on loopback and forwards what arrives from source `v<N>` placed by `placements[N]`.
    ///
    /// # Errors
    /// [`ViewError::Bind`].
    pub fn start(sender: ViewSender, placements: Vec<(String, VehiclePlacement)>) -> Result<Self, ViewError> {
        let socket = UdpSocket::bind("127.0.0.1:0").map_err(ViewError::Bind)?;
        socket.set_read_timeout(Some(Duration::from_millis(100))).map_err(ViewError::Bind)?;
        let addr = socket.local_addr().map_err(ViewError::Bind)?;
        let stop = Arc::new(AtomicBool::new(false));
        let halt = stop.clone();
        let offsets = Mutex::new(placements.iter().map(|(_, p)| p.start_ned_m).collect::<Vec<_>>());
        let thread = std::thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            let mut bad = 0u64;
            while !halt.load(Ordering::Relaxed) {
                let Ok(n) = socket.recv(&mut buf) else { continue };
                let Ok(mut frame) = serde_json::from_slice::<ViewFrame>(&buf[..n]) else {
                    bad += 1;
                    continue;
                };
                let Some(k) = placements.iter().position(|(src, _)| src == frame.src()) else {
                    bad += 1;
                    continue;
                };
                let origin = match &frame {
                    ViewFrame::Vehicle(v) => v.origin,
                    ViewFrame::Plan(p) => p.origin,
                    _ => None,
                };
                let mut offsets = offsets.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                if origin.is_some() {
                    offsets[k] = placements[k].1.offset_ned_m(origin);
                }
                frame.shift_ned(&offsets[k]);
                drop(offsets);
                if !sender.send(&frame) {
                    break;
                }
            }
            bad
        });
        Ok(Self { addr, stop, thread: Some(thread) })
    }

    /// The UDP address the autopilots send to.
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for Forwarder {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests;

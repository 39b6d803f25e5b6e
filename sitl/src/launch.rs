//! The two-process SITL: the plant server on this process's thread plus the `autopilot` binary as a
//! child, as `sitl run` and `sitl bench` start them. In: a [`PlantServer`] bound on UDP, the autopilot's
//! path and arguments, an optional duration in simulated seconds, and an observer called after every
//! plant step (for a scenario's metrics). Out: a [`LaunchReport`] (steps, simulated and wall seconds, the
//! link's counters, both processes' CPU seconds).
//!
//! The child's standard input is a pipe that only this process holds and the child is started with
//! `--stop-on-stdin-eof`: however this process ends (Ctrl-C, an error, SIGKILL), the pipe closes and the
//! autopilot shuts itself down, so it never outlives the plant. Ctrl-C (SIGINT to the terminal's process
//! group) stops both: the autopilot on its own handler, the plant here through [`ctrl_c_flag`].

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use autopilot::core::plant_link::ActuatorCommand;
use autopilot::runtime::ports::{InstanceOutOfRange, InstancePorts};

use crate::link::{LinkError, LinkStats, Pacing, PlantServer, UdpTransport};
use crate::pacer::Pacer;
use crate::plant::Plant;

/// Why a launch failed.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    #[error(
        "autopilot binary not found at {0}: build it next to sitl with `cargo build --release` (or `cargo build` \
         for a debug sitl)"
    )]
    NoAutopilot(PathBuf),
    #[error("cannot start {path}: {source}")]
    Spawn {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("the autopilot exited ({0}) while the plant was running")]
    AutopilotExited(ExitStatus),
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error("the plant server thread panicked")]
    Panicked,
    #[error("instance {instance} is in use: {port} is held by another process; {hint}")]
    InstanceInUse { instance: u16, port: InstancePort, hint: String },
    #[error(transparent)]
    InstanceOutOfRange(#[from] InstanceOutOfRange),
}

/// A port an instance binds on this machine, and what it is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InstancePort {
    pub what: &'static str,
    pub tcp: bool,
    pub addr: std::net::SocketAddr,
}

impl std::fmt::Display for InstancePort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {} ({})", if self.tcp { "tcp" } else { "udp" }, self.addr, self.what)
    }
}

/// The ports instance `n` binds ([`InstancePorts`]): the plant's (UDP 4560+N) and its SIM_ parameters'
/// (UDP 19550+N), and with `autopilot` the autopilot's own UDP (18570+N) and TCP (5760+N) ports, as `sitl
/// run` starts it. The ports it sends to (14550, the API port 14540+N, and with `--hawkeye` Hawkeye's
/// 19410+N) are the ground stations' and viewers' and not among them.
///
/// # Errors
/// [`LaunchError::InstanceOutOfRange`] above the largest instance.
pub fn instance_ports(n: u16, autopilot: bool) -> Result<Vec<InstancePort>, LaunchError> {
    let p = InstancePorts::of(n)?;
    let at = |ip: [u8; 4], port: u16| std::net::SocketAddr::from((ip, port));
    let mut ports = vec![
        InstancePort { what: "the plant", tcp: false, addr: at([127, 0, 0, 1], p.plant_udp) },
        InstancePort { what: "the plant's SIM_ parameters", tcp: false, addr: at([127, 0, 0, 1], p.sim_params_udp) },
    ];
    if autopilot {
        ports.push(InstancePort { what: "the autopilot", tcp: false, addr: at([0, 0, 0, 0], p.autopilot_udp) });
        ports.push(InstancePort { what: "the autopilot's TCP server", tcp: true, addr: at([0, 0, 0, 0], p.tcp) });
    }
    Ok(ports)
}

/// The first of `ports` that cannot be bound here now (another process holds it).
#[must_use]
pub fn first_taken(ports: &[InstancePort]) -> Option<InstancePort> {
    ports.iter().copied().find(|p| {
        if p.tcp { std::net::TcpListener::bind(p.addr).is_err() } else { std::net::UdpSocket::bind(p.addr).is_err() }
    })
}

/// Checks that every port of instance `n` ([`instance_ports`]) is free before anything starts, so a busy
/// instance is one clear error that names the port and the next free instance, not a bind failure halfway
/// through a start.
///
/// # Errors
/// [`LaunchError::InstanceInUse`], or [`LaunchError::InstanceOutOfRange`].
pub fn check_instance_free(n: u16, autopilot: bool) -> Result<(), LaunchError> {
    let Some(port) = first_taken(&instance_ports(n, autopilot)?) else { return Ok(()) };
    let next = (n.saturating_add(1)..=n.saturating_add(64))
        .find(|&m| m > n && instance_ports(m, autopilot).is_ok_and(|ports| first_taken(&ports).is_none()));
    let hint = next
        .map_or_else(|| "stop the other SITL or choose another instance with -i".to_owned(), |m| format!("try -i {m}"));
    Err(LaunchError::InstanceInUse { instance: n, port, hint })
}

/// The `autopilot` binary next to the running `sitl`.
///
/// # Errors
/// [`LaunchError::NoAutopilot`] if it is not there.
pub fn autopilot_binary() -> Result<PathBuf, LaunchError> {
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("sitl"));
    let path = exe.with_file_name("autopilot");
    if path.exists() { Ok(path) } else { Err(LaunchError::NoAutopilot(path)) }
}

/// A flag set by the first Ctrl-C (SIGINT) this process receives. The handler is in place when this
/// returns: a Ctrl-C from then on sets the flag and no longer ends the process.
#[must_use]
pub fn ctrl_c_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    let set = flag.clone();
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let Ok(rt) = tokio::runtime::Builder::new_current_thread().enable_io().build() else {
            let _ = ready_tx.send(());
            return;
        };
        rt.block_on(async {
            // `ctrl_c()` registers its handler when first polled: poll it once before saying it is ready.
            let mut ctrl_c = std::pin::pin!(tokio::signal::ctrl_c());
            let first = futures_poll_once(ctrl_c.as_mut()).await;
            let _ = ready_tx.send(());
            let result = match first {
                Some(r) => r,
                None => ctrl_c.await,
            };
            if result.is_ok() {
                set.store(true, Ordering::Relaxed);
            }
        });
    });
    let _ = ready_rx.recv_timeout(Duration::from_secs(5));
    flag
}

/// Polls `fut` once: its output if it was ready, else None (it stays pinned for the caller to await).
async fn futures_poll_once<F: std::future::Future + Unpin>(fut: F) -> Option<F::Output> {
    let mut fut = fut;
    std::future::poll_fn(|cx| match std::pin::Pin::new(&mut fut).poll(cx) {
        std::task::Poll::Ready(out) => std::task::Poll::Ready(Some(out)),
        std::task::Poll::Pending => std::task::Poll::Ready(None),
    })
    .await
}

/// An autopilot configuration file in the temporary directory for a run `sitl` launches with a
/// configuration of its own, removed when dropped (also when the launch fails half-way).
#[derive(Debug)]
pub struct TempConfig {
    path: PathBuf,
}

impl TempConfig {
    /// Writes `text` to `<temp>/sitl-<pid>-<name>.toml`; on failure, the path it could not write.
    pub fn write(name: &str, text: &str) -> Result<Self, (PathBuf, std::io::Error)> {
        let config = Self { path: std::env::temp_dir().join(format!("sitl-{}-{name}.toml", std::process::id())) };
        match std::fs::write(&config.path, text) {
            Ok(()) => Ok(config),
            Err(e) => Err((config.path.clone(), e)),
        }
    }

    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for TempConfig {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The autopilot child and the pipe that keeps it alive.
#[derive(Debug)]
pub struct AutopilotChild {
    child: Child,
    stdin: Option<ChildStdin>,
}

impl AutopilotChild {
    /// Start `path` with `args` (plus `--stop-on-stdin-eof`).
    ///
    /// # Errors
    /// [`LaunchError::Spawn`].
    pub fn spawn(path: &Path, args: &[OsString]) -> Result<Self, LaunchError> {
        Self::spawn_with(path, args, None)
    }

    /// As [`AutopilotChild::spawn`], with `RUST_LOG` set to `log_filter` unless the environment sets it.
    ///
    /// # Errors
    /// [`LaunchError::Spawn`].
    pub fn spawn_with(path: &Path, args: &[OsString], log_filter: Option<&str>) -> Result<Self, LaunchError> {
        let mut command = Command::new(path);
        if let Some(filter) = log_filter
            && std::env::var_os("RUST_LOG").is_none()
        {
            command.env("RUST_LOG", filter);
        }
        let mut child = command
            .args(args)
            .arg("--stop-on-stdin-eof")
            .stdin(Stdio::piped())
            .spawn()
            .map_err(|source| LaunchError::Spawn { path: path.to_owned(), source })?;
        let stdin = child.stdin.take();
        Ok(Self { child, stdin })
    }

    #[must_use]
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// User plus system CPU seconds the child has used so far (Linux `/proc`; `None` elsewhere).
    #[must_use]
    pub fn cpu_s(&self) -> Option<f64> {
        cpu_seconds(&format!("/proc/{}/stat", self.child.id()))
    }

    /// Whether it has exited, and how.
    pub fn exited(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// Close its standard input (it shuts down cleanly and closes its log), wait up to 5 s, then kill it.
    pub fn stop(mut self) -> Option<ExitStatus> {
        drop(self.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Some(status) = self.exited() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        tracing::warn!(pid = self.child.id(), "the autopilot did not stop within 5 s; killing it");
        let _ = self.child.kill();
        self.child.wait().ok()
    }
}

/// User plus system CPU seconds from a `/proc/<pid>/stat` file (fields 14 and 15, in USER_HZ = 100
/// ticks per second, fixed by the Linux ABI).
#[must_use]
pub fn cpu_seconds(stat_path: &str) -> Option<f64> {
    let text = std::fs::read_to_string(stat_path).ok()?;
    // The command name (field 2) is in parentheses and may hold spaces: count fields after it.
    let rest = &text[text.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// CPU seconds this process has used so far.
#[must_use]
pub fn own_cpu_s() -> Option<f64> {
    cpu_seconds("/proc/self/stat")
}

/// What a launch measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaunchReport {
    pub steps: u64,
    /// Plant time at the end (s).
    pub sim_s: f64,
    /// Wall time from the first step to the last (s).
    pub wall_s: f64,
    pub link: LinkStats,
    /// CPU seconds over the run: the autopilot child, and this process (the plant).
    pub autopilot_cpu_s: Option<f64>,
    pub plant_cpu_s: Option<f64>,
    /// Set when the run ended on `stop` (Ctrl-C) rather than its duration.
    pub stopped: bool,
}

impl LaunchReport {
    #[must_use]
    pub fn realtime_factor(&self) -> f64 {
        if self.wall_s > 0.0 { self.sim_s / self.wall_s } else { 0.0 }
    }
}

/// Step `server` in lockstep with `child` until `duration_us` of plant time (`None`: no limit) or until
/// `stop` is set, calling `observe` after every step; then stop the child. Wall and CPU time are counted
/// from the end of the first step (the autopilot's start-up is not in them).
///
/// # Errors
/// The link's error, or [`LaunchError::AutopilotExited`] if the child died first.
pub fn run_with_child(
    server: &mut PlantServer<UdpTransport>,
    mut child: AutopilotChild,
    duration_us: Option<u64>,
    stop: &AtomicBool,
    mut observe: impl FnMut(&Plant, &ActuatorCommand) + Send,
) -> Result<LaunchReport, LaunchError> {
    let halt = AtomicBool::new(false);
    let started = AtomicBool::new(false);
    let (plant_result, child_exit, child_cpu) = std::thread::scope(|scope| {
        let plant = scope.spawn(|| -> Result<Measured, LinkError> {
            let mut first: Option<(Instant, Option<f64>)> = None;
            let stopped = loop {
                if duration_us.is_some_and(|d| server.plant().time_us() >= d) {
                    break false;
                }
                match server.step(&halt) {
                    Ok(cmd) => observe(server.plant(), &cmd),
                    Err(LinkError::Stopped) => break true,
                    Err(e) => return Err(e),
                }
                if first.is_none() {
                    first = Some((Instant::now(), own_cpu_s()));
                    started.store(true, Ordering::Relaxed);
                }
            };
            let (t0, cpu0) = first.unwrap_or((Instant::now(), None));
            let plant_cpu_s = cpu0.zip(own_cpu_s()).map(|(a, b)| b - a);
            Ok(Measured { wall_s: t0.elapsed().as_secs_f64(), plant_cpu_s, stopped })
        });
        let mut child_cpu0 = None;
        let mut child_exit = None;
        while !plant.is_finished() {
            if child_cpu0.is_none() && started.load(Ordering::Relaxed) {
                child_cpu0 = child.cpu_s();
            }
            if child_exit.is_none() {
                child_exit = child.exited();
            }
            if stop.load(Ordering::Relaxed) || child_exit.is_some() {
                halt.store(true, Ordering::Relaxed);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let child_cpu = child_cpu0.zip(child.cpu_s()).map(|(a, b)| b - a);
        (plant.join(), child_exit, child_cpu)
    });
    let measured = match plant_result {
        Ok(Ok(m)) => m,
        Ok(Err(e)) => {
            child.stop();
            return Err(e.into());
        }
        Err(_) => {
            child.stop();
            return Err(LaunchError::Panicked);
        }
    };
    // The autopilot failing ends the run as an error; a clean exit (its own Ctrl-C) ends it as stopped.
    if let Some(status) = child_exit
        && !status.success()
    {
        return Err(LaunchError::AutopilotExited(status));
    }
    child.stop();
    let stats = server.stats();
    Ok(LaunchReport {
        steps: stats.steps,
        sim_s: server.plant().time_us() as f64 * 1e-6,
        wall_s: measured.wall_s,
        link: stats,
        autopilot_cpu_s: child_cpu,
        plant_cpu_s: measured.plant_cpu_s,
        stopped: measured.stopped,
    })
}

/// What a swarm run measured: one [`LaunchReport`] per vehicle (CPU seconds are the whole plant process's
/// and each autopilot's), and whether the run ended on `stop`.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmReport {
    pub vehicles: Vec<LaunchReport>,
    pub wall_s: f64,
    pub stopped: bool,
}

/// Step every plant of a swarm in lockstep with its autopilot, on one thread and one clock: each tick sends
/// every plant's sensors first, then collects every reply and steps that plant, so the autopilots compute
/// at the same time. Runs until `duration_us` of plant time (`None`: no limit) or until `stop` is set, or
/// until an autopilot exits; then stops every child. `on_tick` is called with the plant time and the
/// servers (their plants) after each tick.
///
/// # Errors
/// The first link error, or [`LaunchError::AutopilotExited`] naming no vehicle (the message carries the
/// status) if a child died first.
pub fn run_swarm(
    servers: &mut [PlantServer<UdpTransport>],
    children: Vec<AutopilotChild>,
    duration_us: Option<u64>,
    stop: &AtomicBool,
    mut on_tick: impl FnMut(u64, &[PlantServer<UdpTransport>]) + Send,
) -> Result<SwarmReport, LaunchError> {
    let halt = AtomicBool::new(false);
    let mut children = children;
    // One pacer for every plant (each server then runs in lockstep): paced one by one, each would take its
    // own origin a batch after the one before it and sleep in turn.
    let mut pacer = match servers.first().map(PlantServer::pacing) {
        Some(Pacing::RealTime { speed }) => Some(Pacer::new(speed)),
        _ => None,
    };
    for server in servers.iter_mut() {
        server.set_pacing(Pacing::Lockstep);
    }
    let dt_us = servers.first().map_or(2_000, PlantServer::dt_us);
    let (result, exit) = std::thread::scope(|scope| {
        let plants = scope.spawn(|| -> Result<(f64, bool), LinkError> {
            let mut first: Option<Instant> = None;
            loop {
                let t = servers.first().map_or(0, |s| s.plant().time_us());
                if duration_us.is_some_and(|d| t >= d) {
                    break Ok((first.map_or(0.0, |t0| t0.elapsed().as_secs_f64()), false));
                }
                // The tick from t to t + dt, when it is due (after the first: its origin is the first
                // replies, when every autopilot is up).
                if let Some(pacer) = pacer.as_mut().filter(|_| first.is_some()) {
                    while let Some(wake) = pacer.wait(t, t + dt_us, Instant::now()) {
                        if halt.load(Ordering::Relaxed) {
                            return Ok((first.map_or(0.0, |t0| t0.elapsed().as_secs_f64()), true));
                        }
                        std::thread::sleep(wake.saturating_duration_since(Instant::now()));
                    }
                }
                for server in servers.iter_mut() {
                    server.begin_step()?;
                }
                for server in servers.iter_mut() {
                    match server.end_step(&halt) {
                        Ok(_) => {}
                        Err(LinkError::Stopped) => {
                            return Ok((first.map_or(0.0, |t0| t0.elapsed().as_secs_f64()), true));
                        }
                        Err(e) => return Err(e),
                    }
                }
                if first.is_none() {
                    first = Some(Instant::now());
                }
                on_tick(servers.first().map_or(0, |s| s.plant().time_us()), servers);
            }
        });
        let mut exit = None;
        while !plants.is_finished() {
            if exit.is_none() {
                exit = children.iter_mut().find_map(AutopilotChild::exited);
            }
            if stop.load(Ordering::Relaxed) || exit.is_some() {
                halt.store(true, Ordering::Relaxed);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        (plants.join(), exit)
    });
    let stop_all = |children: Vec<AutopilotChild>| {
        for child in children {
            child.stop();
        }
    };
    let (wall_s, stopped) = match result {
        Ok(Ok(measured)) => measured,
        Ok(Err(e)) => {
            stop_all(children);
            return Err(e.into());
        }
        Err(_) => {
            stop_all(children);
            return Err(LaunchError::Panicked);
        }
    };
    if let Some(status) = exit
        && !status.success()
    {
        stop_all(children);
        return Err(LaunchError::AutopilotExited(status));
    }
    let autopilot_cpu: Vec<Option<f64>> = children.iter().map(AutopilotChild::cpu_s).collect();
    stop_all(children);
    let plant_cpu_s = own_cpu_s();
    let vehicles = servers
        .iter()
        .zip(autopilot_cpu)
        .map(|(server, autopilot_cpu_s)| {
            let stats = server.stats();
            LaunchReport {
                steps: stats.steps,
                sim_s: server.plant().time_us() as f64 * 1e-6,
                wall_s,
                link: stats,
                autopilot_cpu_s,
                plant_cpu_s,
                stopped,
            }
        })
        .collect();
    Ok(SwarmReport { vehicles, wall_s, stopped })
}

/// What the plant thread measured.
struct Measured {
    wall_s: f64,
    plant_cpu_s: Option<f64>,
    stopped: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_busy_instance_names_the_port_and_the_next_free_instance() {
        // GIVEN instance 47's SIM_ parameter port held by another socket (its plant port left free).
        let held = std::net::UdpSocket::bind(("127.0.0.1", 19550 + 47)).expect("the port is free to hold");
        // WHEN instance 47 is checked THEN the error names the instance, the port and its role, and a free -i.
        let err = check_instance_free(47, false).expect_err("in use");
        let text = err.to_string();
        assert!(
            text.starts_with("instance 47 is in use: udp 127.0.0.1:19597 (the plant's SIM_ parameters) is held by another process; try -i 4"),
            "{text}"
        );
        drop(held);
        assert!(check_instance_free(47, false).is_ok(), "free again once released");
        assert!(matches!(check_instance_free(255, false), Err(LaunchError::InstanceOutOfRange(_))));
    }

    #[test]
    fn cpu_seconds_reads_utime_and_stime_after_a_name_with_spaces() {
        let dir = std::env::temp_dir().join(format!("sitl-stat-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("stat");
        std::fs::write(&path, "42 (my prog) S 1 42 42 0 -1 4194560 100 0 0 0 250 75 0 0 20 0 1 0").expect("write");
        assert_eq!(cpu_seconds(path.to_str().expect("utf-8")), Some(3.25));
        assert_eq!(cpu_seconds("/nonexistent/stat"), None);
        assert!(own_cpu_s().is_some_and(|s| s >= 0.0), "this process's own /proc entry reads");
        let _ = std::fs::remove_dir_all(dir);
    }
}

//! What the subcommands share: the plant options of `run` and `serve` and their pacing, the default
//! plant, instance ports and the SIM_ parameter service, the worker pool, output writing and the summary
//! lines of the gust and track metrics.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use autopilot::runtime::ports::{HAWKEYE_MAX_INSTANCE, InstancePorts};
use clap::Args;
use sitl::link::Pacing;
use sitl::link::hawkeye::HawkeyeSender;
use sitl::link::rc::{RC_IN_PORT, RcInPort};
use sitl::plant::{Airframe, InitialState, Plant, PlantConfig, SensorConfig};
use sitl::scenario::metrics::{GustMetrics, TrackMetrics};
use sitl::sim_params::SimParamLink;

/// The plant options `sitl run` and `sitl serve` share.
#[derive(Args)]
pub(crate) struct PlantArgs {
    /// Plant configuration file (TOML: [airframe], [wind], [sensors], [ground], [battery], integrator_step_s);
    /// default: the nominal plant with modest sensor noise.
    #[arg(long)]
    pub(crate) config: Option<PathBuf>,
    /// Airframe preset (nominal, mismatch), applied over the configuration's.
    #[arg(long = "plant")]
    pub(crate) preset: Option<String>,
    /// Pace the plant at X times real time (default 1: real time, as a ground station expects; 4 runs four
    /// times faster, 0.5 half as fast), or `max`: as fast as the autopilot answers (lockstep, about
    /// 100-150x on two cores). The plant and the autopilot step in lockstep either way.
    #[arg(long, value_name = "X|max", value_parser = parse_speed, allow_negative_numbers = true)]
    pub(crate) speed: Option<Pacing>,
    /// As fast as possible: the same as `--speed max`.
    #[arg(long, conflicts_with = "speed")]
    pub(crate) lockstep: bool,
    /// Seed of every noise and turbulence stream.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// The pilot's radio in, as ArduPilot SITL's RC input: UDP port on 127.0.0.1 taking datagrams of 8 to
    /// 16 little-endian u16 PWM values (µs, 800..2200) = channels 1..N; the last good one is held and
    /// sent to the autopilot as RC_CHANNELS at 50 Hz. Default 5501 + instance; 0 = off.
    #[arg(long, value_name = "PORT")]
    pub(crate) rc_in_port: Option<u16>,
    /// Send the plant's true state to PX4's Hawkeye 3D viewer: MAVLink 2 HIL_STATE_QUATERNION (system N+1,
    /// component 51) to UDP 127.0.0.1:19410+N, instance N (each vehicle of a swarm to its own port), at
    /// 50 Hz of simulated time. Nobody listening is fine: the sends are dropped, the plant never waits.
    #[arg(long)]
    pub(crate) hawkeye: bool,
}

impl PlantArgs {
    /// The plant and its pacing; `default` is the configuration used without `--config`.
    pub(crate) fn build(&self, default: PlantConfig) -> Result<(Plant, Pacing)> {
        let config = self.config(default)?;
        Ok((Plant::new(config, &InitialState::default(), self.seed)?, self.pacing()))
    }

    /// The plant configuration: `--config` (else `default`) with `--plant`'s airframe over it.
    pub(crate) fn config(&self, default: PlantConfig) -> Result<PlantConfig> {
        let mut config = match &self.config {
            Some(path) => {
                let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
                PlantConfig::from_toml_str(&text).with_context(|| format!("plant configuration {}", path.display()))?
            }
            None => default,
        };
        if let Some(preset) = &self.preset {
            config.airframe = Airframe::preset(preset)?;
        }
        Ok(config)
    }

    /// `--speed` or `--lockstep`; without either, real time.
    pub(crate) fn pacing(&self) -> Pacing {
        if self.lockstep { Pacing::Lockstep } else { self.speed.unwrap_or(REAL_TIME) }
    }

    /// With `--hawkeye`, that instance `n` (the last of a swarm) has a Hawkeye port clear of every other
    /// port: checked before anything starts.
    ///
    /// # Errors
    /// An instance past [`HAWKEYE_MAX_INSTANCE`] (its Hawkeye port is another instance's SIM_ port).
    pub(crate) fn check_hawkeye(&self, n: u16) -> Result<()> {
        if self.hawkeye && n > HAWKEYE_MAX_INSTANCE {
            bail!(
                "--hawkeye: instance {n}'s Hawkeye port 19410+{n} would be instance {}'s SIM_ parameter port; \
                 Hawkeye ports are clear for instances 0..={HAWKEYE_MAX_INSTANCE}",
                n - HAWKEYE_MAX_INSTANCE - 1
            );
        }
        Ok(())
    }

    /// With `--hawkeye`, the sender of instance `n`'s truth to 127.0.0.1:19410+n, from `plant`'s time.
    ///
    /// # Errors
    /// As [`PlantArgs::check_hawkeye`], or the socket's error.
    pub(crate) fn hawkeye_sender(&self, n: u16, plant: &Plant) -> Result<Option<HawkeyeSender>> {
        if !self.hawkeye {
            return Ok(None);
        }
        self.check_hawkeye(n)?;
        let ports = InstancePorts::of(n)?;
        let to = std::net::SocketAddr::from(([127, 0, 0, 1], ports.hawkeye_udp));
        Ok(Some(HawkeyeSender::new(to, ports.system_id, plant.time_us()).with_context(|| format!("--hawkeye: {to}"))?))
    }

    /// The RC input port of instance `n`: `--rc-in-port`, else [`RC_IN_PORT`] + n; `None` when 0 (off).
    pub(crate) fn rc_in_port(&self, n: u16) -> Option<u16> {
        match self.rc_in_port {
            Some(0) => None,
            Some(port) => Some(port),
            None => RC_IN_PORT.checked_add(n),
        }
    }

    /// Whether the command line chose the pacing (`--speed` or `--lockstep`).
    pub(crate) fn pacing_given(&self) -> bool {
        self.lockstep || self.speed.is_some()
    }
}

/// The pacing of `sitl run` and `sitl serve` without `--speed`: what a ground station (and a person
/// watching it) expects, as PX4's and ArduPilot's SITLs do.
pub(crate) const REAL_TIME: Pacing = Pacing::RealTime { speed: 1.0 };

/// `--speed`: `max` (lockstep, as fast as possible) or a positive, finite multiple of real time.
pub(crate) fn parse_speed(text: &str) -> Result<Pacing, String> {
    if text.trim().eq_ignore_ascii_case("max") {
        return Ok(Pacing::Lockstep);
    }
    match text.trim().parse::<f64>() {
        Ok(speed) if speed.is_finite() && speed > 0.0 => Ok(Pacing::RealTime { speed }),
        _ => Err("expected a positive multiple of real time (1 = real time, 4, 0.5) or `max` (as fast as \
                  possible, lockstep)"
            .to_owned()),
    }
}

/// How a pacing reads after "running" in the startup lines: "at real time (1x)", "at 4x real time", "as
/// fast as possible (lockstep)".
pub(crate) fn describe_pacing(pacing: Pacing) -> String {
    match pacing {
        Pacing::Lockstep => "as fast as possible (lockstep)".to_owned(),
        Pacing::RealTime { speed: 1.0 } => "at real time (1x)".to_owned(),
        Pacing::RealTime { speed } => format!("at {speed}x real time"),
    }
}

/// A rayon pool of `--jobs` threads (default one per core).
pub(crate) fn pool(jobs: Option<u16>) -> Result<(rayon::ThreadPool, usize)> {
    let threads =
        jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get), usize::from);
    Ok((rayon::ThreadPoolBuilder::new().num_threads(threads).build()?, threads))
}

/// Prints to standard output; a closed pipe (`| head`) is not an error.
pub(crate) fn print_stdout(text: &str) -> Result<()> {
    match writeln!(std::io::stdout().lock(), "{}", text.trim_end()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => Ok(result?),
    }
}

/// Writes via a temporary file and a rename, so a reader never sees a half-written file. The temporary
/// file is the whole name plus `.tmp`, so `x.csv` and `x.json` never share one.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    autopilot::runtime::persist::write_file_atomically(path, bytes)
        .with_context(|| format!("writing {}", path.display()))
}

/// The gust and track metric lines of a summary (each starting with a newline), for the runs that have them.
pub(crate) fn gust_track_lines(gust: Option<&GustMetrics>, track: Option<&TrackMetrics>) -> String {
    let mut s = String::new();
    if let Some(g) = gust {
        s += &format!(
            "\n  gust: recovery {} / {}  peak {:.3} m  steady {:.3} m  rms xy {:.3} m  rms z {:.4} m\
             \n  gust: iae {:.3} / {:.3} m s  itae {:.3} / {:.3} m s^2  within 5 / 10 / 20 cm {:.2} / {:.2} / {:.2} s",
            fmt_seconds(g.recovery_onset_s),
            fmt_seconds(g.recovery_release_s),
            g.peak_m,
            g.steady_err_m,
            g.rms_xy_m,
            g.rms_z_m,
            g.iae_onset_m_s,
            g.iae_release_m_s,
            g.itae_onset_m_s2,
            g.itae_release_m_s2,
            g.within_5cm_s,
            g.within_10cm_s,
            g.within_20cm_s
        );
    }
    if let Some(t) = track {
        s += &format!(
            "\n  track: cross-track rms {:.3} m  max {:.3} m  iae {:.3} m s  alt rms {:.4} m",
            t.cross_track_rms_m, t.cross_track_max_m, t.cross_track_iae_m_s, t.alt_rms_m
        );
    }
    s
}

/// A time that may not have come: `1.23 s` or `never`.
pub(crate) fn fmt_seconds(v: Option<f64>) -> String {
    v.map_or_else(|| "never".to_owned(), |x| format!("{x:.2} s"))
}

/// The plant `sitl run` uses without `--config`: nominal, with [`SensorConfig::modest_noise`], so the fused
/// estimator has work to do.
pub(crate) fn realistic_plant_config() -> PlantConfig {
    PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() }
}

/// The plant's SIM_ parameter service for instance `n` (system n+1) on 127.0.0.1:19550+n, and its port.
pub(crate) fn bind_sim_params(n: u16, plant: &Plant) -> Result<(SimParamLink, u16)> {
    let ports = InstancePorts::of(n)?;
    let (port, system_id) = (ports.sim_params_udp, ports.system_id);
    let link = SimParamLink::bind(("127.0.0.1", port), system_id, plant)
        .with_context(|| format!("binding the SIM_ parameter port udp 127.0.0.1:{port}"))?;
    Ok((link, port))
}

/// The RC input port on 127.0.0.1:`port` (see [`PlantArgs::rc_in_port`]), or `None` when off.
pub(crate) fn bind_rc_in(port: Option<u16>) -> Result<Option<RcInPort>> {
    port.map(|port| {
        RcInPort::bind(("127.0.0.1", port)).with_context(|| {
            format!("binding the RC input port udp 127.0.0.1:{port} (--rc-in-port PORT, or 0 for none)")
        })
    })
    .transpose()
}

/// How the startup line names the RC input port.
pub(crate) fn describe_rc_in(port: Option<u16>) -> String {
    port.map_or_else(|| "no RC input port".to_owned(), |p| format!("RC input on udp 127.0.0.1:{p}"))
}

/// The instance's ports: plant, autopilot, QGroundControl (14550, shared by every instance), API.
pub(crate) fn instance_ports(n: u16) -> Result<(u16, u16, u16, u16)> {
    let p = InstancePorts::of(n)?;
    Ok((p.plant_udp, p.autopilot_udp, p.qgc_udp, p.api_udp))
}

pub(crate) fn duration_us(seconds: Option<f64>) -> Result<Option<u64>> {
    match seconds {
        Some(s) if s.is_finite() && s > 0.0 => Ok(Some((s * 1e6).round() as u64)),
        Some(s) => bail!("--duration must be a positive number of seconds, got {s}"),
        None => Ok(None),
    }
}

/// The radio's closing line of a run or a serve (`sitl: radio: N RC_CHANNELS sent; RC input: a datagrams
/// taken, d dropped`), when the RC input port was open.
pub(crate) fn radio_summary<T: sitl::link::Transport>(server: &sitl::link::PlantServer<T>) -> Option<String> {
    server.rc_in().map(|port| {
        let rc = port.stats();
        format!(
            "sitl: radio: {} RC_CHANNELS sent; RC input: {} datagrams taken, {} dropped",
            server.stats().rc_sent,
            rc.accepted,
            rc.dropped
        )
    })
}

/// The Hawkeye closing line of a run or a serve (`sitl: hawkeye: N HIL_STATE_QUATERNION sent to ADDR, F
/// refused`), when `--hawkeye` sent.
pub(crate) fn hawkeye_summary<T: sitl::link::Transport>(server: &sitl::link::PlantServer<T>) -> Option<String> {
    server.hawkeye().map(|h| {
        let s = server.stats();
        format!(
            "sitl: hawkeye: {} HIL_STATE_QUATERNION sent to udp {}, {} refused (no viewer listening, or a full \
             buffer)",
            s.hawkeye_sent,
            h.destination(),
            s.hawkeye_failed
        )
    })
}

/// The faults' closing line of a run or a serve (`sitl: faults: N failure injections answered; plant
/// link: L sensor datagrams lost, H steps on a held command`), when the autopilot forwarded an injection
/// or the link's delay or loss (SIM_LINK_DELAY, SIM_LINK_LOSS) acted.
pub(crate) fn faults_summary(stats: &sitl::link::LinkStats) -> Option<String> {
    (stats.injections > 0 || stats.lost > 0 || stats.held_steps > 0).then(|| {
        format!(
            "sitl: faults: {} failure injections answered; plant link: {} sensor datagrams lost, {} steps on a \
             held command",
            stats.injections, stats.lost, stats.held_steps
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Cli, Command};
    use clap::Parser;
    use clap::error::ErrorKind;

    /// The pacing `sitl <command> <args>` would run at, or clap's refusal.
    fn pacing_of(command: &str, args: &[&str]) -> Result<Pacing, clap::Error> {
        let cli = Cli::try_parse_from(["sitl", command].iter().chain(args))?;
        match cli.command {
            Command::Run(run) => Ok(run.plant.pacing()),
            Command::Serve(serve) => Ok(serve.plant.pacing()),
            _ => panic!("{command} has no pacing"),
        }
    }

    #[test]
    fn given_no_injection_and_no_link_fault_then_there_is_no_faults_line_else_it_counts_them() {
        let mut stats = sitl::link::LinkStats::default();
        assert_eq!(faults_summary(&stats), None);
        stats.injections = 2;
        stats.lost = 5;
        stats.held_steps = 7;
        assert_eq!(
            faults_summary(&stats).as_deref(),
            Some(
                "sitl: faults: 2 failure injections answered; plant link: 5 sensor datagrams lost, 7 steps on a held command"
            )
        );
    }

    #[test]
    fn run_and_serve_pace_at_real_time_unless_told_otherwise() {
        for command in ["run", "serve"] {
            assert_eq!(pacing_of(command, &[]).unwrap(), Pacing::RealTime { speed: 1.0 }, "{command}");
            assert_eq!(pacing_of(command, &["-i", "3"]).unwrap(), Pacing::RealTime { speed: 1.0 }, "{command}");
            assert_eq!(pacing_of(command, &["--speed", "4"]).unwrap(), Pacing::RealTime { speed: 4.0 }, "{command}");
            assert_eq!(pacing_of(command, &["--speed=0.5"]).unwrap(), Pacing::RealTime { speed: 0.5 }, "{command}");
            assert_eq!(pacing_of(command, &["--speed", "max"]).unwrap(), Pacing::Lockstep, "{command}");
            assert_eq!(pacing_of(command, &["--speed", "MAX"]).unwrap(), Pacing::Lockstep, "{command}");
            assert_eq!(pacing_of(command, &["--lockstep"]).unwrap(), Pacing::Lockstep, "{command}");
        }
    }

    #[test]
    fn a_bad_speed_is_refused_naming_the_flag_and_the_value() {
        for bad in ["0", "-1", "-0.5", "nan", "NaN", "inf", "fast", "", "4x"] {
            let err = pacing_of("run", &["--speed", bad]).expect_err(bad);
            assert_eq!(err.kind(), ErrorKind::ValueValidation, "{bad}: {err}");
            let text = err.to_string();
            assert!(text.contains("--speed") && text.contains(&format!("'{bad}'")), "{bad}: {text}");
            assert!(text.contains("max"), "the message says what is allowed: {text}");
        }
        let err = pacing_of("serve", &["--speed", "0"]).expect_err("0");
        assert_eq!(err.kind(), ErrorKind::ValueValidation, "{err}");
    }

    /// The RC input port `sitl <command> <args>` would bind.
    fn rc_in_of(command: &str, args: &[&str]) -> Option<u16> {
        let cli = Cli::try_parse_from(["sitl", command].iter().chain(args)).expect("parses");
        match cli.command {
            Command::Run(run) => run.plant.rc_in_port(run.instance),
            Command::Serve(serve) => serve.plant.rc_in_port(serve.instance),
            _ => panic!("{command} has no RC input"),
        }
    }

    #[test]
    fn run_and_serve_take_rc_in_on_5501_plus_the_instance_unless_told_a_port_or_0_for_none() {
        for command in ["run", "serve"] {
            assert_eq!(rc_in_of(command, &[]), Some(5501), "{command}");
            assert_eq!(rc_in_of(command, &["-i", "3"]), Some(5504), "{command}");
            assert_eq!(rc_in_of(command, &["--rc-in-port", "6000"]), Some(6000), "{command}");
            assert_eq!(rc_in_of(command, &["-i", "3", "--rc-in-port", "0"]), None, "{command}");
        }
    }

    #[test]
    fn lockstep_and_speed_conflict() {
        let err = pacing_of("run", &["--lockstep", "--speed", "4"]).expect_err("conflict");
        assert_eq!(err.kind(), ErrorKind::ArgumentConflict, "{err}");
        let text = err.to_string();
        assert!(text.contains("--lockstep") && text.contains("--speed"), "{text}");
    }

    #[test]
    fn the_startup_line_says_the_pacing() {
        assert_eq!(describe_pacing(Pacing::RealTime { speed: 1.0 }), "at real time (1x)");
        assert_eq!(describe_pacing(Pacing::RealTime { speed: 4.0 }), "at 4x real time");
        assert_eq!(describe_pacing(Pacing::RealTime { speed: 0.5 }), "at 0.5x real time");
        assert_eq!(describe_pacing(Pacing::Lockstep), "as fast as possible (lockstep)");
    }
}

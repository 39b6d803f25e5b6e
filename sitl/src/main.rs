//! `sitl`: the simulator's command line. `sitl scenario` runs the paper's experiments in-process in
//! lockstep (headless, faster than real time) and writes metrics JSON, CSV traces and PNG plots;
//! `sitl serve` serves the plant to an autopilot over the MAVLink HIL plant protocol (UDP or serial);
//! `sitl run` is the one-command SITL: the plant server plus the `autopilot` binary as a child process.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use autopilot::core::control::{ControllerKind, LoopRates};
use clap::{Args, Parser, Subcommand};
use sitl::link::{LinkConfig, Pacing, PlantServer, SerialTransport};
use sitl::plant::{Airframe, InitialState, Plant, PlantConfig, SensorConfig};
use sitl::scenario::plot::{self, Panel, Run};
use sitl::scenario::reference::{ReferenceMode, ReferenceSpec, SplinePath};
use sitl::scenario::runner::{self, RunOptions, RunOutput};
use sitl::scenario::{BUILT_INS, MetricKind, Scenario};
use std::sync::atomic::AtomicBool;

#[derive(Parser)]
#[command(name = "sitl", version, about = "SITL plant of the paper's quadrotor and its experiments")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run scenarios in-process (plant + controller in lockstep on simulated time) and report metrics.
    Scenario(ScenarioArgs),
    /// Serve the plant to an autopilot over the HIL plant protocol (lockstep by default).
    Serve(ServeArgs),
    /// One-command SITL: serve the plant on UDP 4560+N and run the `autopilot` binary against it.
    Run(RunArgs),
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    plant: PlantArgs,
    /// Instance N: plant on UDP 4560+N, autopilot on 18570+N, ground stations on 14550+N / 14540+N,
    /// system id N+1.
    #[arg(short = 'i', long, default_value_t = 0)]
    instance: u16,
    /// Autopilot estimator (fused, truth).
    #[arg(long)]
    estimator: Option<String>,
    /// Autopilot controller (aco, ca, pid).
    #[arg(long)]
    controller: Option<String>,
    /// Autopilot `.tlog` directory.
    #[arg(long)]
    log_dir: Option<PathBuf>,
}

/// The plant options `sitl run` and `sitl serve` share.
#[derive(Args)]
struct PlantArgs {
    /// Plant configuration file (TOML: [airframe], [wind], [sensors], [ground], integrator_step_s);
    /// default: the nominal plant (`sitl run`: with modest sensor noise).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Airframe preset (nominal, mismatch), applied over the configuration's.
    #[arg(long = "plant")]
    preset: Option<String>,
    /// Pace the plant at this multiple of real time (lockstep with the autopilot either way); omit it to
    /// run as fast as the autopilot answers.
    #[arg(long)]
    speed: Option<f64>,
    /// Seed of every noise and turbulence stream.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl PlantArgs {
    /// The plant and its pacing; `default` is the configuration used without `--config`.
    fn build(&self, default: PlantConfig) -> Result<(Plant, Pacing)> {
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
        let pacing = match self.speed {
            Some(speed) if speed.is_finite() && speed > 0.0 => Pacing::RealTime { speed },
            Some(speed) => bail!("--speed must be a positive number, got {speed}"),
            None => Pacing::Lockstep,
        };
        Ok((Plant::new(config, &InitialState::default(), self.seed)?, pacing))
    }
}

#[derive(Args)]
struct ServeArgs {
    #[command(flatten)]
    plant: PlantArgs,
    /// Instance: the UDP port becomes 4560 + N.
    #[arg(short = 'i', long, default_value_t = 0)]
    instance: u16,
    /// UDP address to listen on; the autopilot announces itself with any MAVLink message.
    #[arg(long)]
    listen: Option<String>,
    /// Serve over a serial port instead of UDP: `DEVICE:BAUD`, e.g. /dev/ttyUSB0:921600.
    #[arg(long)]
    serial: Option<String>,
    /// Plant step per sensor sample, µs (2000 = 500 Hz).
    #[arg(long, default_value_t = 2000)]
    dt_us: u64,
}

#[derive(Args)]
struct ScenarioArgs {
    /// Built-in scenario names or scenario TOML files; `all` runs every built-in.
    #[arg(required_unless_present = "list")]
    scenarios: Vec<String>,
    /// List the built-in scenarios and exit.
    #[arg(long)]
    list: bool,
    /// Controllers, comma-separated (aco, ca, pid); default: the scenario's own list.
    #[arg(long, value_delimiter = ',')]
    controller: Vec<ControllerKind>,
    /// Airframe preset (nominal, mismatch); default: the scenario's.
    #[arg(long)]
    plant: Option<String>,
    /// Seeds: `7`, `1,2,3` or `1-5`.
    #[arg(long, default_value = "1")]
    seed: String,
    /// Inner loop rate (rate, attitude, LMS), Hz; must divide 1 MHz.
    #[arg(long, default_value_t = 500)]
    rate_hz: u32,
    /// Position loop rate, Hz; default inner rate / 5 (100 Hz at 500 Hz).
    #[arg(long)]
    position_hz: Option<u32>,
    /// Output directory for CSV traces and PNG plots.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Print one metrics JSON object per run (one per line) instead of a summary.
    #[arg(long)]
    json: bool,
    /// Trace rows per simulated second in the CSV.
    #[arg(long, default_value_t = 50)]
    trace_hz: u32,
    /// Skip the PNG plots.
    #[arg(long)]
    no_plots: bool,
}

fn parse_seeds(text: &str) -> Result<Vec<u64>> {
    let mut seeds = Vec::new();
    for part in text.split(',') {
        if let Some((a, b)) = part.split_once('-') {
            let (a, b): (u64, u64) = (a.trim().parse()?, b.trim().parse()?);
            if b < a || b - a > 10_000 {
                bail!("seed range {part} must be ascending and at most 10000 long");
            }
            seeds.extend(a..=b);
        } else {
            seeds.push(part.trim().parse().with_context(|| format!("seed `{part}` is not a whole number"))?);
        }
    }
    Ok(seeds)
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Scenario(args) => scenario(&args),
        Command::Serve(args) => serve(&args),
        Command::Run(args) => run(&args),
    }
}

fn scenario(args: &ScenarioArgs) -> Result<()> {
    if args.list {
        for (name, _) in BUILT_INS {
            let s = Scenario::load(name)?;
            println!("{name:20} {}", s.description.split_whitespace().collect::<Vec<_>>().join(" "));
        }
        return Ok(());
    }
    let names: Vec<String> = if args.scenarios.iter().any(|s| s == "all") {
        BUILT_INS.iter().map(|b| b.0.to_owned()).collect()
    } else {
        args.scenarios.clone()
    };
    let seeds = parse_seeds(&args.seed)?;
    let position_hz = args.position_hz.unwrap_or(args.rate_hz / 5);
    let rates = LoopRates { inner_hz: args.rate_hz, position_hz };
    rates.validate().context("loop rates")?;
    let stdout = std::io::stdout();
    for name in &names {
        let scenario = Scenario::load(name)?;
        let controllers =
            if args.controller.is_empty() { scenario.controllers.clone() } else { args.controller.clone() };
        let dir = args.out.join(&scenario.name);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        for &seed in &seeds {
            for mode in scenario.reference_modes() {
                let mut outputs = Vec::new();
                for &controller in &controllers {
                    let opts = RunOptions {
                        controller,
                        plant: args.plant.clone(),
                        seed,
                        rates,
                        mode,
                        trace_hz: args.trace_hz,
                    };
                    let out = runner::run(&scenario, &opts)?;
                    let stem = run_stem(&out, mode, &scenario);
                    write_atomically(&dir.join(format!("{stem}.csv")), out.trace.to_csv().as_bytes())?;
                    let line = if args.json { serde_json::to_string(&out.metrics)? } else { summary(&out) };
                    match writeln!(stdout.lock(), "{line}") {
                        // A reader that has seen enough (`| head`) is not an error.
                        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
                        result => result?,
                    }
                    outputs.push(out);
                }
                if !args.no_plots {
                    plots(&scenario, &dir, &outputs, mode)?;
                }
            }
        }
    }
    Ok(())
}

fn run_stem(out: &RunOutput, mode: ReferenceMode, scenario: &Scenario) -> String {
    let m = &out.metrics;
    let mode = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    format!("{}_{}{}_seed{}_{}hz", m.controller, m.plant, mode, m.seed, m.rate_hz)
}

/// Writes via a temporary file and a rename, so a reader never sees a half-written file.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("renaming to {}", path.display()))?;
    Ok(())
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "never".to_owned(), |x| format!("{x:.2}"))
}

fn summary(out: &RunOutput) -> String {
    let m = &out.metrics;
    let mut s = format!("{} {} {} seed {} {} Hz", m.scenario, m.controller, m.plant, m.seed, m.rate_hz);
    if let Some(mode) = &m.reference_mode {
        s += &format!(" ({mode})");
    }
    for seg in m.segments.iter().flatten() {
        s += &format!(
            "\n  {:5} t0 {:5.1} s: overshoot {:5.2} %  settling {:>5} s  sse {:.1e}",
            seg.axis,
            seg.t0_s,
            seg.overshoot_pct,
            fmt_opt(seg.settling_s),
            seg.sse
        );
    }
    if let Some(rms) = &m.rms {
        s += "\n  rms:";
        for (axis, v) in rms {
            s += &format!(" {axis} {v:.4}");
        }
    }
    if let Some(g) = &m.gust {
        s += &format!(
            "\n  gust: recovery {} / {} s  peak {:.3} m  steady {:.3} m  rms xy {:.3} m  rms z {:.4} m",
            fmt_opt(g.recovery_onset_s),
            fmt_opt(g.recovery_release_s),
            g.peak_m,
            g.steady_err_m,
            g.rms_xy_m,
            g.rms_z_m
        );
    }
    if let Some(t) = &m.track {
        s += &format!(
            "\n  track: cross-track rms {:.3} m  max {:.3} m  alt rms {:.4} m",
            t.cross_track_rms_m, t.cross_track_max_m, t.alt_rms_m
        );
    }
    s += &format!(
        "\n  weights at bounds: {}  non-finite: {}  pwm activity {:.2} us/tick  {:.1} sim s in {:.3} s wall ({:.0}x real time)",
        m.weights_at_bounds, m.non_finite, m.pwm_activity_us, m.sim_s, m.wall_s, m.realtime_factor
    );
    s
}

fn plots(scenario: &Scenario, dir: &Path, outputs: &[RunOutput], mode: ReferenceMode) -> Result<()> {
    let Some(first) = outputs.first() else { return Ok(()) };
    let labels: Vec<String> = outputs.iter().map(|o| o.metrics.controller.to_uppercase()).collect();
    let m = &first.metrics;
    let suffix = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    let file = |kind: &str| dir.join(format!("{kind}_{}{suffix}_seed{}_{}hz.png", m.plant, m.seed, m.rate_hz));
    let title = |what: &str| format!("{what}: {} plant, {}", m.plant, labels.join(" vs "));
    match &scenario.reference {
        ReferenceSpec::Attitude { .. } => {
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("roll (rad)", "roll", Some("ref_roll"), 1.0),
                Panel::new("pitch (rad)", "pitch", Some("ref_pitch"), 1.0),
                Panel::new("yaw (rad)", "yaw", Some("ref_yaw"), 1.0),
            ];
            plot::time_panels(&file("attitude"), &title("Attitude (paper Fig. 5)"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } if scenario.metrics.contains(&MetricKind::Gust) => {
            let traces: Vec<_> = outputs.iter().map(|o| with_horizontal_error(&o.trace)).collect();
            let runs: Vec<Run<'_>> = traces.iter().zip(&labels).map(|(t, l)| Run { label: l, trace: t }).collect();
            let panels = [
                Panel::new("horizontal error (m)", "err_xy", None, 1.0),
                Panel::new("altitude error (m)", "err_alt", None, 1.0),
                Panel::new("wind east (m/s)", "windE", None, 1.0),
            ];
            plot::time_panels(&file("gust"), &title("Hover under a Beaufort-4 gust"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } => {
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("north (m)", "pN", Some("refN"), 1.0),
                Panel::new("east (m)", "pE", Some("refE"), 1.0),
                Panel::new("altitude (m)", "pD", Some("refD"), -1.0),
            ];
            plot::time_panels(&file("translation"), &title("Translation (paper Fig. 6)"), &panels, &runs)?;
        }
        ReferenceSpec::Track(track) => {
            let path = SplinePath::new(&track.waypoints_ne_m);
            let samples = 600;
            let pts: Vec<(f64, f64)> = (0..=samples)
                .map(|k| path.eval(path.length_m() * f64::from(k) / f64::from(samples)).0)
                .map(|p| (p.x, p.y))
                .collect();
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            plot::track(
                &file("figure8"),
                &title(&format!("Figure-8 at {} m/s, {mode}", track.speed_mps)),
                &pts,
                &runs,
            )?;
        }
    }
    Ok(())
}

/// The trace with `err_xy` (horizontal distance to the reference) and `err_alt` (altitude error) added.
fn with_horizontal_error(trace: &runner::Trace) -> runner::Trace {
    let mut t = trace.clone();
    let idx = |name: &str| t.columns.iter().position(|c| c == name).expect("core column");
    let (n, e, d, rn, re, rd) = (idx("pN"), idx("pE"), idx("pD"), idx("refN"), idx("refE"), idx("refD"));
    t.columns.push("err_xy".into());
    t.columns.push("err_alt".into());
    for row in &mut t.rows {
        let exy = (row[n] - row[rn]).hypot(row[e] - row[re]);
        let ealt = row[rd] - row[d];
        row.push(exy);
        row.push(ealt);
    }
    t
}

fn serve(args: &ServeArgs) -> Result<()> {
    let (plant, pacing) = args.plant.build(PlantConfig::default())?;
    if args.dt_us == 0 || args.dt_us > 20_000 {
        bail!("--dt-us must be in 1..=20000, got {}", args.dt_us);
    }
    let link = LinkConfig { dt_us: args.dt_us, pacing, ..LinkConfig::default() };
    let stop = AtomicBool::new(false);
    let steps = if let Some(spec) = &args.serial {
        let (device, baud) = spec.rsplit_once(':').context("--serial takes DEVICE:BAUD")?;
        let baud: u32 = baud.parse().with_context(|| format!("baud rate `{baud}`"))?;
        let transport = SerialTransport::open(device, baud).with_context(|| format!("opening {device}"))?;
        eprintln!("sitl: plant on serial {device} at {baud} baud");
        PlantServer::new(plant, transport, link).run(None, &stop)?
    } else {
        let port = 4560 + args.instance;
        let listen = args.listen.clone().unwrap_or_else(|| format!("127.0.0.1:{port}"));
        let mut server =
            PlantServer::bind_udp(plant, listen.as_str(), link).with_context(|| format!("binding {listen}"))?;
        eprintln!("sitl: plant listening on udp {listen}; waiting for an autopilot");
        server.run(None, &stop)?
    };
    eprintln!("sitl: {steps} steps served");
    Ok(())
}

/// The plant `sitl run` uses without `--config`: nominal, with [`SensorConfig::modest_noise`], so the fused
/// estimator has work to do.
fn realistic_plant_config() -> PlantConfig {
    PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() }
}

/// Ask the child to stop (SIGINT, so it closes its log), then make sure it does.
fn stop_child(child: &mut std::process::Child) {
    if matches!(child.try_wait(), Ok(Some(_))) {
        return;
    }
    let _ = std::process::Command::new("kill").args(["-s", "INT", "--", &child.id().to_string()]).status();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(3);
    while std::time::Instant::now() < deadline {
        if matches!(child.try_wait(), Ok(Some(_))) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
}

fn run(args: &RunArgs) -> Result<()> {
    let (plant, pacing) = args.plant.build(realistic_plant_config())?;
    let n = args.instance;
    let port = |base: u16| base.checked_add(n).context("instance too large: a port would exceed 65535");
    let (plant_port, ap_port, qgc_port, api_port) = (port(4560)?, port(18570)?, port(14550)?, port(14540)?);
    let autopilot = std::env::current_exe()?.with_file_name("autopilot");
    if !autopilot.exists() {
        bail!(
            "autopilot binary not found at {}: build it next to sitl with `cargo build --release` \
             (or `cargo build` for a debug sitl)",
            autopilot.display()
        );
    }
    let link =
        LinkConfig { pacing, connect_timeout: Some(std::time::Duration::from_secs(30)), ..LinkConfig::default() };
    let listen = format!("127.0.0.1:{plant_port}");
    let mut server =
        PlantServer::bind_udp(plant, listen.as_str(), link).with_context(|| format!("binding {listen}"))?;

    let mut cmd = std::process::Command::new(&autopilot);
    cmd.args(["--plant", &format!("udp://127.0.0.1:{plant_port}"), "-i", &n.to_string()]);
    if let Some(e) = &args.estimator {
        cmd.args(["--estimator", e]);
    }
    if let Some(c) = &args.controller {
        cmd.args(["--controller", c]);
    }
    if let Some(dir) = &args.log_dir {
        cmd.arg("--log-dir").arg(dir);
    }
    let mut child = cmd.spawn().with_context(|| format!("starting {}", autopilot.display()))?;
    eprintln!(
        "sitl: instance {n}: plant on udp 127.0.0.1:{plant_port} ({}), autopilot pid {} (system id {}) \
         listening on udp {ap_port}; ground stations: listen on udp 14550+N = {qgc_port} (QGroundControl) \
         or {api_port} (MAVSDK/API), or send to 127.0.0.1:{ap_port}",
        match pacing {
            Pacing::Lockstep => "lockstep, as fast as possible".to_owned(),
            Pacing::RealTime { speed } => format!("lockstep at {speed}x real time"),
        },
        child.id(),
        u32::from(n) + 1,
    );

    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let server_stop = stop.clone();
    let wall = std::time::Instant::now();
    let server_thread = std::thread::spawn(move || {
        let result = server.run(None, &server_stop);
        (result, server.stats(), server.plant().time_us())
    });
    let child_status = loop {
        if server_thread.is_finished() {
            break None;
        }
        match child.try_wait() {
            Ok(Some(status)) => break Some(status),
            Ok(None) => {}
            Err(e) => {
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                stop_child(&mut child);
                return Err(e).context("waiting for the autopilot");
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    if let Some(status) = child_status {
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if status.success() {
            eprintln!("sitl: the autopilot stopped; plant stopped");
            return Ok(());
        }
        bail!("the autopilot exited ({status}); plant stopped");
    }
    stop_child(&mut child);
    let (result, stats, time_us) =
        server_thread.join().map_err(|_| anyhow::anyhow!("the plant server thread panicked"))?;
    let wall_s = wall.elapsed().as_secs_f64();
    let sim_s = time_us as f64 * 1e-6;
    eprintln!(
        "sitl: {} steps, {sim_s:.1} sim s in {wall_s:.1} s wall ({:.1}x real time, {:.0} steps/s)",
        stats.steps,
        sim_s / wall_s,
        stats.steps as f64 / wall_s
    );
    result?;
    Ok(())
}

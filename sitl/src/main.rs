//! `sitl`: the simulator's command line. `sitl scenario` runs the paper's experiments in-process in
//! lockstep (headless, faster than real time) and writes metrics JSON, CSV traces and PNG plots;
//! `sitl serve` serves the plant to an autopilot over the MAVLink HIL plant protocol (UDP or serial);
//! `sitl run` is the one-command SITL: the plant server plus the `autopilot` binary as a child process
//! (optionally flying a hover scenario through both, with its metrics). Both `serve` and `run` answer the
//! plant's SIM_ parameters (wind and gusts at run time, `sitl::sim_params`) on UDP 19550+N, and pace the
//! plant at real time unless told otherwise (`--speed X` for X times real time, `--speed max` or
//! `--lockstep` for as fast as the autopilot answers), as a ground station and the person watching it
//! expect; scenarios (`sitl scenario`, `sitl run --scenario`) are batch runs, always as fast as possible.
//! `sitl bench` (`bench`) measures the two-process real-time factor in lockstep and the CPU cost of the SITL
//! and its telemetry in real time, or with `--vehicles N` how a swarm of N answers a ground station.

mod bench;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use autopilot::core::control::{ControllerKind, LoopRates};
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::vehicle::Vehicle;
use autopilot::runtime::ports::InstancePorts;
use autopilot::runtime::transport::{POLL_INTERVAL, SerialTransport, parse_serial_spec};
use autopilot::runtime::{ConfigFile, Overrides, RuntimeConfig};
use clap::{Args, Parser, Subcommand};
use sitl::launch::{self, AutopilotChild};
use sitl::link::{LinkConfig, Pacing, PlantServer, UdpTransport};
use sitl::plant::{Airframe, InitialState, Plant, PlantConfig, SensorConfig};
use sitl::progress::Progress;
use sitl::scenario::metrics::{GustMetrics, TrackMetrics};
use sitl::scenario::plot::{self, Panel, Run};
use sitl::scenario::reference::{ReferenceMode, ReferenceSpec, SplinePath};
use sitl::scenario::runner::{self, RunOptions, RunOutput};
use sitl::scenario::two_process::{self, TwoProcessOptions};
use sitl::scenario::{BUILT_INS, MetricKind, Scenario, file_label};
use sitl::sim_params::SimParamLink;
use sitl::sweep::Sweep;
use std::ffi::OsString;
use std::time::Duration;

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
    /// Serve the plant to an autopilot over the HIL plant protocol, at real time unless `--speed` says
    /// otherwise.
    Serve(ServeArgs),
    /// One-command SITL: serve the plant on UDP 4560+N and run the `autopilot` binary against it, at real
    /// time unless `--speed` says otherwise (`--speed 4`, `--speed max`).
    Run(RunArgs),
    /// Measure the two-process SITL: lockstep real-time factor, and CPU and telemetry at real time.
    Bench(BenchArgs),
    /// Sweep a scenario over airframes, winds, seeds and controllers (a Monte Carlo or grid study):
    /// every run in-process in lockstep across all cores; one row per run, a robustness table, plots.
    Sweep(SweepArgs),
    /// Tune one controller's gains (CMA-ES, a budget of evaluations per seed, one or more seeds) on a
    /// training cost with guards, every evaluation's runs in parallel; write the best safe gains as a
    /// [controller] block and a parameter file (or say "no safe gains"), the trace, the convergence curves
    /// and a held-out report. With --evaluate: fly gain files on the spec's held-out set.
    Tune(TuneArgs),
}

#[derive(Args)]
struct TuneArgs {
    /// The tuning spec (TOML; docs/tuning.md).
    spec: PathBuf,
    /// Instead of tuning, fly these gain sets on the spec's held-out set: gain files (a `[controller]`
    /// block, e.g. a tuning's controller.toml) or `aco`, `ca`, `pid` for a controller's defaults.
    #[arg(long, value_name = "GAINS", num_args = 1..)]
    evaluate: Vec<String>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    jobs: Option<u16>,
    /// Output directory (default: out/tune-<name>, or out/tune-<name>-evaluate with --evaluate).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print the held-out report as JSON instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SweepArgs {
    /// The sweep spec (TOML; docs/sweeps.md).
    spec: PathBuf,
    /// Run shard K of N only: every N-th run from run K-1 (`--shard 2/3`); `--merge` joins the shards.
    #[arg(long, value_name = "K/N", value_parser = sitl::sweep::parse_shard, conflicts_with = "merge")]
    shard: Option<(u64, u64)>,
    /// Instead of running, merge the row files of shards (from `--shard`) into the whole sweep's, checked
    /// against the spec: every run once, each with the values the spec gives it.
    #[arg(long, value_name = "CSV", num_args = 1..)]
    merge: Vec<PathBuf>,
    /// A scenario file in place of the spec's `scenario`.
    #[arg(long, value_name = "FILE")]
    scenario: Option<PathBuf>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    jobs: Option<u16>,
    /// Output directory (default: out/sweep-<name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Skip the plots.
    #[arg(long)]
    no_plots: bool,
    /// Print the summary as JSON instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    plant: PlantArgs,
    /// Instance N (0..=254): plant on UDP 4560+N, autopilot on 18570+N and TCP 5760+N, telemetry to UDP
    /// 14550 (QGroundControl, every instance) and the API port 14540+N (14541+N from N = 10), system id
    /// N+1; the plant's SIM_ parameters (wind, gusts) on UDP 19550+N.
    #[arg(short = 'i', long, default_value_t = 0)]
    instance: u16,
    /// Autopilot estimator (fused, truth).
    #[arg(long, value_parser = ["fused", "truth"])]
    estimator: Option<String>,
    /// Autopilot controller (aco, ca, pid).
    #[arg(long)]
    controller: Option<ControllerKind>,
    /// Autopilot `.tlog` directory.
    #[arg(long)]
    log_dir: Option<PathBuf>,
    /// No onboard ULog flight log from the autopilot (by default one per armed flight, in the state
    /// directory's log/<date>/<time>.ulg).
    #[arg(long)]
    no_ulog: bool,
    /// Autopilot configuration file (TOML; see `autopilot --help`).
    #[arg(long, conflicts_with = "scenario")]
    autopilot_config: Option<PathBuf>,
    /// Where the autopilot keeps its parameters and mission across restarts, or `off` (default:
    /// ~/.local/state/aco-autopilot/iN; scenarios always run without).
    #[arg(long, conflicts_with = "scenario")]
    state_dir: Option<String>,
    /// Stop after this many simulated seconds (default: run until Ctrl-C).
    #[arg(long)]
    duration: Option<f64>,
    /// Fly a scenario through both processes and report its metrics at the end: a hover (gust-hover,
    /// turbulence-hover) starting in the air as the in-process runner does, truth-fed; a track (figure8)
    /// as a mission from the ground, on the fused estimator. A scenario is a batch run: always as fast as
    /// possible (lockstep), whatever the default pacing.
    #[arg(long)]
    scenario: Option<String>,
    /// With --scenario: print the metrics as one JSON object.
    #[arg(long, requires = "scenario")]
    json: bool,
    /// A swarm of N vehicles in one command: instances -i .. -i+N-1 (system ids from -i+1), every one's
    /// telemetry to UDP 14550 and its own API port; the plants share this process and one clock, each
    /// autopilot is its own process.
    #[arg(short = 'n', long = "count", default_value_t = 1, value_name = "N", conflicts_with = "scenario",
          value_parser = clap::value_parser!(u16).range(1..=255))]
    count: u16,
    /// Swarm spawn grid spacing (m): vehicle k starts k-th on a square grid, rows north, columns east.
    #[arg(long, default_value_t = 3.0, value_name = "M")]
    spacing: f64,
    /// Start clean: the autopilot removes the instance's kept parameters, mission, fence and rally points
    /// before it starts (ArduPilot's `-w`; a signing key is kept).
    #[arg(long, conflicts_with = "scenario")]
    wipe: bool,
}

#[derive(Args)]
struct BenchArgs {
    /// Instance N (ports as for `sitl run -i N`).
    #[arg(short = 'i', long, default_value_t = 90)]
    instance: u16,
    /// Simulated seconds of the lockstep run.
    #[arg(long, default_value_t = 120.0)]
    sim_s: f64,
    /// Wall seconds of the real-time run (0 skips it).
    #[arg(long, default_value_t = 10.0)]
    realtime_s: f64,
    /// Instead: a swarm of N at real time as `sitl run -n N -i <instance>` starts it, measured by a ground
    /// station on udp 14550 for --realtime-s: each vehicle's HEARTBEAT intervals and COMMAND_ACK latency,
    /// total CPU; PASS or FAIL against p99 1.2 s and 20 ms.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=255))]
    vehicles: Option<u16>,
}

/// The plant options `sitl run` and `sitl serve` share.
#[derive(Args)]
struct PlantArgs {
    /// Plant configuration file (TOML: [airframe], [wind], [sensors], [ground], [battery], integrator_step_s);
    /// default: the nominal plant with modest sensor noise.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Airframe preset (nominal, mismatch), applied over the configuration's.
    #[arg(long = "plant")]
    preset: Option<String>,
    /// Pace the plant at X times real time (default 1: real time, as a ground station expects; 4 runs four
    /// times faster, 0.5 half as fast), or `max`: as fast as the autopilot answers (lockstep, about
    /// 100-150x on two cores). The plant and the autopilot step in lockstep either way.
    #[arg(long, value_name = "X|max", value_parser = parse_speed, allow_negative_numbers = true)]
    speed: Option<Pacing>,
    /// As fast as possible: the same as `--speed max`.
    #[arg(long, conflicts_with = "speed")]
    lockstep: bool,
    /// Seed of every noise and turbulence stream.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl PlantArgs {
    /// The plant and its pacing; `default` is the configuration used without `--config`.
    fn build(&self, default: PlantConfig) -> Result<(Plant, Pacing)> {
        let config = self.config(default)?;
        Ok((Plant::new(config, &InitialState::default(), self.seed)?, self.pacing()))
    }

    /// The plant configuration: `--config` (else `default`) with `--plant`'s airframe over it.
    fn config(&self, default: PlantConfig) -> Result<PlantConfig> {
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
    fn pacing(&self) -> Pacing {
        if self.lockstep { Pacing::Lockstep } else { self.speed.unwrap_or(REAL_TIME) }
    }

    /// Whether the command line chose the pacing (`--speed` or `--lockstep`).
    fn pacing_given(&self) -> bool {
        self.lockstep || self.speed.is_some()
    }
}

/// The pacing of `sitl run` and `sitl serve` without `--speed`: what a ground station (and a person
/// watching it) expects, as PX4's and ArduPilot's SITLs do.
const REAL_TIME: Pacing = Pacing::RealTime { speed: 1.0 };

/// `--speed`: `max` (lockstep, as fast as possible) or a positive, finite multiple of real time.
fn parse_speed(text: &str) -> Result<Pacing, String> {
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
fn describe_pacing(pacing: Pacing) -> String {
    match pacing {
        Pacing::Lockstep => "as fast as possible (lockstep)".to_owned(),
        Pacing::RealTime { speed: 1.0 } => "at real time (1x)".to_owned(),
        Pacing::RealTime { speed } => format!("at {speed}x real time"),
    }
}

#[derive(Args)]
struct ServeArgs {
    #[command(flatten)]
    plant: PlantArgs,
    /// Instance: the UDP port becomes 4560 + N, the SIM_ parameter port 19550 + N (system N + 1).
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

fn main() -> ExitCode {
    autopilot::cli::init_logging();
    let result = match Cli::parse().command {
        Command::Scenario(args) => scenario(&args),
        Command::Serve(args) => serve(&args),
        Command::Run(args) => run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Sweep(args) => sweep(&args),
        Command::Tune(args) => tune(&args),
    };
    autopilot::cli::exit("sitl", result)
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
    // Every scenario loads before the first run starts: a bad name fails at once.
    let scenarios = names.iter().map(|name| Scenario::load(name)).collect::<Result<Vec<_>, _>>()?;
    let controllers_of = |scenario: &Scenario| {
        if args.controller.is_empty() { scenario.controllers.clone() } else { args.controller.clone() }
    };
    let total: usize =
        scenarios.iter().map(|s| seeds.len() * s.reference_modes().len() * controllers_of(s).len()).sum();
    let mut progress = Progress::new("sitl scenario", total as u64, "runs");
    let mut done = 0;
    let stdout = std::io::stdout();
    for scenario in &scenarios {
        let controllers = controllers_of(scenario);
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
                    let out = runner::run(scenario, &opts)?;
                    let stem = run_stem(&out, mode, scenario);
                    let csv = dir.join(format!("{stem}.csv"));
                    write_atomically(&csv, out.trace.to_csv().as_bytes())?;
                    let line = if args.json { serde_json::to_string(&out.metrics)? } else { summary(&out) };
                    let written = progress.suspend(|| {
                        eprintln!("sitl: wrote {}", csv.display());
                        writeln!(stdout.lock(), "{line}")
                    });
                    match written {
                        // A reader that has seen enough (`| head`) is not an error.
                        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => return Ok(()),
                        result => result?,
                    }
                    outputs.push(out);
                    done += 1;
                    progress.set(done);
                }
                if !args.no_plots {
                    let written = plots(scenario, &dir, &outputs, mode)?;
                    progress.suspend(|| {
                        for path in &written {
                            eprintln!("sitl: wrote {}", path.display());
                        }
                    });
                }
            }
        }
    }
    progress.finish();
    Ok(())
}

fn sweep(args: &SweepArgs) -> Result<()> {
    let spec = Sweep::load(&args.spec, args.scenario.as_deref())?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("sweep-{}", spec.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let (rows, file) = if args.merge.is_empty() {
        let runs = match args.shard {
            Some(shard) => sitl::sweep::shard_runs(spec.runs(), shard),
            None => (0..spec.runs()).collect(),
        };
        let threads = args
            .jobs
            .map_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get), usize::from);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
        let progress = std::sync::Mutex::new(Progress::new("sitl sweep", runs.len() as u64, "runs"));
        let done = std::sync::atomic::AtomicU64::new(0);
        let start = std::time::Instant::now();
        let rows = pool.install(|| {
            use rayon::prelude::*;
            runs.par_iter()
                .map(|&r| {
                    let row = spec.run(r);
                    let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                    if let Ok(mut p) = progress.lock() {
                        p.set(n);
                    }
                    row
                })
                .collect::<Result<Vec<_>, _>>()
        })?;
        if let Ok(p) = progress.into_inner() {
            p.finish();
        }
        let wall_s = start.elapsed().as_secs_f64();
        let sim_s = spec.scenario.duration_s * rows.len() as f64;
        eprintln!(
            "sitl: {} runs in {wall_s:.1} s on {threads} thread{}: {:.1} runs/s, {:.0}x real time per thread",
            rows.len(),
            if threads == 1 { "" } else { "s" },
            rows.len() as f64 / wall_s,
            sim_s / wall_s / threads as f64
        );
        let file = match args.shard {
            Some((k, n)) => format!("runs-shard-{k}-of-{n}.csv"),
            None => "runs.csv".to_owned(),
        };
        (rows, file)
    } else {
        let mut shards = Vec::new();
        for path in &args.merge {
            let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            shards.push(sitl::sweep::table::from_csv(&spec, &path.display().to_string(), &text)?);
        }
        (sitl::sweep::table::merge(&spec, shards)?, "runs.csv".to_owned())
    };
    let csv = out.join(file);
    write_atomically(&csv, sitl::sweep::table::to_csv(&spec, &rows).as_bytes())?;
    eprintln!("sitl: wrote {}", csv.display());
    let summary = sitl::sweep::table::summarize(&spec, &rows);
    let json = serde_json::to_string_pretty(&summary)?;
    let summary_path = if args.shard.is_some() { csv.with_extension("summary.json") } else { out.join("summary.json") };
    write_atomically(&summary_path, json.as_bytes())?;
    eprintln!("sitl: wrote {}", summary_path.display());
    if !args.no_plots {
        for path in sweep_plots(&spec, &rows, &out)? {
            eprintln!("sitl: wrote {}", path.display());
        }
    }
    let text = if args.json { json } else { summary.table() };
    match writeln!(std::io::stdout().lock(), "{text}") {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => Ok(result?),
    }
}

/// A rayon pool of `--jobs` threads (default one per core).
fn pool(jobs: Option<u16>) -> Result<(rayon::ThreadPool, usize)> {
    let threads =
        jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get), usize::from);
    Ok((rayon::ThreadPoolBuilder::new().num_threads(threads).build()?, threads))
}

fn tune(args: &TuneArgs) -> Result<()> {
    use sitl::tune::{GainSet, Tune, output};
    let spec = Tune::load(&args.spec)?;
    let (pool, threads) = pool(args.jobs)?;
    let suffix = if args.evaluate.is_empty() { "" } else { "-evaluate" };
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("tune-{}{suffix}", spec.name)));
    let mut gain_sets = Vec::new();
    if args.evaluate.is_empty() {
        let total = spec.budget * spec.seeds.len();
        let mut progress = Progress::new("sitl tune", total as u64, "evaluations");
        let start = std::time::Instant::now();
        let tuning = spec.run(&pool, |n| progress.set(n as u64));
        progress.finish();
        let wall_s = start.elapsed().as_secs_f64();
        let n = tuning.evaluations();
        eprintln!(
            "sitl: {n} evaluations in {wall_s:.1} s on {threads} thread{}: {:.1} evaluations/s",
            if threads == 1 { "" } else { "s" },
            n as f64 / wall_s
        );
        for path in output::write_tuning(&out, &spec, &tuning)? {
            eprintln!("sitl: wrote {}", path.display());
        }
        print_stdout(&output::Summary::of(&spec, &tuning).text())?;
        // The start point (the autopilot's defaults with the spec's [base] block, if any): what the search
        // started from, so a controller switched to another variant by its base is not judged by the
        // plain defaults'.
        let start = spec.controller_block(&spec.start()).map_err(|e| anyhow::anyhow!(e))?;
        gain_sets.push(GainSet::from_toml(&start, &format!("{} (start)", spec.controller))?);
        // The held-out set flies the file just written, so the report is of what a user takes away; with
        // no safe gains there is no tuned file, and only the defaults fly.
        if tuning.result().is_some() {
            let file = out.join("controller.toml");
            let text = std::fs::read_to_string(&file).with_context(|| format!("reading {}", file.display()))?;
            gain_sets.push(GainSet::from_toml(&text, &format!("{} (tuned)", spec.controller))?);
        }
    } else {
        for item in &args.evaluate {
            match item.parse::<ControllerKind>() {
                Ok(kind) if !Path::new(item).exists() => gain_sets.push(GainSet::defaults(kind)),
                _ => {
                    let text = std::fs::read_to_string(item).with_context(|| format!("reading gain file {item}"))?;
                    gain_sets.push(GainSet::from_toml(&text, item)?);
                }
            }
        }
    }
    if spec.heldout.is_empty() {
        if !args.evaluate.is_empty() {
            bail!("{}: no [[heldout]] set to evaluate on", args.spec.display());
        }
        return Ok(());
    }
    let results = spec.evaluate_heldout(&gain_sets, &pool);
    for path in output::write_heldout(&out, &spec, &results)? {
        eprintln!("sitl: wrote {}", path.display());
    }
    let text = if args.json {
        serde_json::to_string_pretty(&results)?
    } else {
        format!("held out:\n{}", output::heldout_table(&results))
    };
    print_stdout(&text)
}

/// Prints to standard output; a closed pipe (`| head`) is not an error.
fn print_stdout(text: &str) -> Result<()> {
    match writeln!(std::io::stdout().lock(), "{}", text.trim_end()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        result => Ok(result?),
    }
}

/// One figure per metric (flags and the airframe's thrust-to-weight excepted): its CDF and box plot per
/// controller.
fn sweep_plots(spec: &Sweep, rows: &[sitl::sweep::Row], out: &Path) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for (i, metric) in spec.metric_columns().iter().enumerate() {
        if ["weights_at_bounds", "non_finite"].iter().chain(&sitl::sweep::table::THRUST_TO_WEIGHT).any(|c| c == metric)
        {
            continue;
        }
        let per_controller: Vec<(String, Vec<f64>)> = spec
            .controllers
            .iter()
            .map(|c| {
                let values =
                    rows.iter().filter(|r| r.controller == *c).map(|r| r.metrics[i].unwrap_or(f64::INFINITY)).collect();
                (c.to_string(), values)
            })
            .collect();
        let samples: Vec<plot::Sample<'_>> =
            per_controller.iter().map(|(label, values)| plot::Sample { label, values }).collect();
        let path = out.join(format!("{metric}.png"));
        let title =
            format!("{}: {metric} over {} runs per controller", spec.name, rows.len() / spec.controllers.len().max(1));
        plot::distribution(&path, &title, &metric_axis_label(metric), &samples)?;
        written.push(path);
    }
    Ok(written)
}

/// `gust_peak_m` -> `gust peak (m)`.
fn metric_axis_label(metric: &str) -> String {
    for (suffix, unit) in [("_m", "m"), ("_s", "s"), ("_pct", "%"), ("_rad", "rad"), ("_us", "µs")] {
        if let Some(stem) = metric.strip_suffix(suffix) {
            return format!("{} ({unit})", stem.replace('_', " "));
        }
    }
    metric.replace('_', " ")
}

fn run_stem(out: &RunOutput, mode: ReferenceMode, scenario: &Scenario) -> String {
    let m = &out.metrics;
    let mode = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    format!("{}_{}{}_seed{}_{}hz", m.controller, file_label(&m.plant), mode, m.seed, m.rate_hz)
}

/// Writes via a temporary file and a rename, so a reader never sees a half-written file. The temporary
/// file is the whole name plus `.tmp`, so `x.csv` and `x.json` never share one.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    autopilot::runtime::persist::write_file_atomically(path, bytes)
        .with_context(|| format!("writing {}", path.display()))
}

/// The gust and track metric lines of a summary (each starting with a newline), for the runs that have them.
fn gust_track_lines(gust: Option<&GustMetrics>, track: Option<&TrackMetrics>) -> String {
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
fn fmt_seconds(v: Option<f64>) -> String {
    v.map_or_else(|| "never".to_owned(), |x| format!("{x:.2} s"))
}

/// The unit of a step metric's axis: attitude axes in rad, position axes (n, e, d) in m.
fn axis_unit(axis: &str) -> &'static str {
    if matches!(axis, "roll" | "pitch" | "yaw") { "rad" } else { "m" }
}

fn summary(out: &RunOutput) -> String {
    let m = &out.metrics;
    let mut s = format!("{} {} {} seed {} {} Hz", m.scenario, m.controller, m.plant, m.seed, m.rate_hz);
    if let Some(mode) = &m.reference_mode {
        s += &format!(" ({mode})");
    }
    for seg in m.segments.iter().flatten() {
        s += &format!(
            "\n  {:5} t0 {:5.1} s: overshoot {:5.2} %  settling {:>7}  sse {:.1e} {unit}  iae {:.4} {unit} s",
            seg.axis,
            seg.t0_s,
            seg.overshoot_pct,
            fmt_seconds(seg.settling_s),
            seg.sse,
            seg.iae,
            unit = axis_unit(seg.axis),
        );
    }
    if let Some(rms) = &m.rms {
        s += "\n  rms:";
        for (axis, v) in rms {
            s += &format!(" {axis} {v:.4} {}", axis_unit(axis));
        }
    }
    s += &gust_track_lines(m.gust.as_ref(), m.track.as_ref());
    s += &format!(
        "\n  weights at bounds: {}  non-finite: {}  pwm activity {:.2} us/tick  {:.1} sim s in {:.3} s wall ({:.0}x real time)",
        m.weights_at_bounds, m.non_finite, m.pwm_activity_us, m.sim_s, m.wall_s, m.realtime_factor
    );
    s += &format!(
        "\n  effort: pwm deviation from hover {:.4e} us^2 s  pwm rate {:.1} us/s  saturated {:.2} s",
        m.effort.pwm_dev_sq_us2_s, m.effort.pwm_rate_mean_us_per_s, m.effort.saturation_s
    );
    s
}

/// The figures of one scenario's runs; returns the files written.
fn plots(scenario: &Scenario, dir: &Path, outputs: &[RunOutput], mode: ReferenceMode) -> Result<Vec<PathBuf>> {
    let Some(first) = outputs.first() else { return Ok(Vec::new()) };
    let labels: Vec<String> = outputs.iter().map(|o| o.metrics.controller.to_uppercase()).collect();
    let m = &first.metrics;
    let suffix = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    let plant = file_label(&m.plant);
    let file = |kind: &str| dir.join(format!("{kind}_{plant}{suffix}_seed{}_{}hz.png", m.seed, m.rate_hz));
    let mut written = Vec::new();
    // Each figure is a PNG and an SVG of the same name.
    let mut written_file = |kind: &str| {
        let path = file(kind);
        written.extend([path.clone(), path.with_extension("svg")]);
        path
    };
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
            plot::time_panels(&written_file("attitude"), &title("Attitude (paper Fig. 5)"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } if scenario.metrics.contains(&MetricKind::Gust) => {
            let traces: Vec<_> = outputs.iter().map(|o| with_horizontal_error(&o.trace)).collect();
            let runs: Vec<Run<'_>> = traces.iter().zip(&labels).map(|(t, l)| Run { label: l, trace: t }).collect();
            let panels = [
                Panel::new("horizontal error (m)", "err_xy", None, 1.0),
                Panel::new("altitude error (m)", "err_alt", None, 1.0),
                Panel::new("wind east (m/s)", "windE", None, 1.0).common_to_all_runs(),
            ];
            // The gust is what the figure is about: the start-up transient before its onset does not set
            // the scale (it is drawn clipped over a shaded band).
            let panels = match &scenario.wind.gust {
                Some(g) => panels.map(|p| p.settled_from(g.onset_s)),
                None => panels,
            };
            plot::time_panels(&written_file("gust"), &title("Hover under a Beaufort-4 gust"), &panels, &runs)?;
        }
        ReferenceSpec::Position { .. } => {
            let runs: Vec<Run<'_>> =
                outputs.iter().zip(&labels).map(|(o, l)| Run { label: l, trace: &o.trace }).collect();
            let panels = [
                Panel::new("north (m)", "pN", Some("refN"), 1.0),
                Panel::new("east (m)", "pE", Some("refE"), 1.0),
                Panel::new("altitude (m)", "pD", Some("refD"), -1.0),
            ];
            plot::time_panels(&written_file("translation"), &title("Translation (paper Fig. 6)"), &panels, &runs)?;
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
                &written_file("figure8"),
                &title(&format!("Figure-8 at {} m/s, {mode}", track.speed_mps)),
                &pts,
                &runs,
            )?;
        }
    }
    Ok(written)
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
    if args.listen.is_none() && args.serial.is_none() {
        launch::check_instance_free(args.instance, false)?;
    }
    let (plant, pacing) = args.plant.build(realistic_plant_config())?;
    if args.dt_us == 0 || args.dt_us > 20_000 {
        bail!("--dt-us must be in 1..=20000, got {}", args.dt_us);
    }
    let link = LinkConfig { dt_us: args.dt_us, pacing, ..LinkConfig::default() };
    let stop = launch::ctrl_c_flag();
    let (sim_params, sim_port) = bind_sim_params(args.instance, &plant)?;
    let steps = if let Some(spec) = &args.serial {
        let (device, baud) = parse_serial_spec(spec).map_err(anyhow::Error::msg).context("--serial")?;
        let transport =
            SerialTransport::open(&device, baud, POLL_INTERVAL).with_context(|| format!("opening {device}"))?;
        eprintln!(
            "sitl: plant on serial {device} at {baud} baud, running {}; SIM_ parameters on udp \
             127.0.0.1:{sim_port}",
            describe_pacing(pacing)
        );
        let mut server = PlantServer::new(plant, transport, link);
        server.set_hook(Box::new(sim_params));
        server.run(None, &stop)?
    } else {
        let port = instance_ports(args.instance)?.0;
        let listen = args.listen.clone().unwrap_or_else(|| format!("127.0.0.1:{port}"));
        let mut server =
            PlantServer::bind_udp(plant, listen.as_str(), link).with_context(|| format!("binding {listen}"))?;
        server.set_hook(Box::new(sim_params));
        eprintln!(
            "sitl: plant listening on udp {listen}, running {}; SIM_ parameters on udp 127.0.0.1:{sim_port}; \
             waiting for an autopilot",
            describe_pacing(pacing)
        );
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

/// The plant's SIM_ parameter service for instance `n` (system n+1) on 127.0.0.1:19550+n, and its port.
fn bind_sim_params(n: u16, plant: &Plant) -> Result<(SimParamLink, u16)> {
    let ports = InstancePorts::of(n)?;
    let (port, system_id) = (ports.sim_params_udp, ports.system_id);
    let link = SimParamLink::bind(("127.0.0.1", port), system_id, plant)
        .with_context(|| format!("binding the SIM_ parameter port udp 127.0.0.1:{port}"))?;
    Ok((link, port))
}

/// The instance's ports: plant, autopilot, QGroundControl (14550, shared by every instance), API.
fn instance_ports(n: u16) -> Result<(u16, u16, u16, u16)> {
    let p = InstancePorts::of(n)?;
    Ok((p.plant_udp, p.autopilot_udp, p.qgc_udp, p.api_udp))
}

fn duration_us(seconds: Option<f64>) -> Result<Option<u64>> {
    match seconds {
        Some(s) if s.is_finite() && s > 0.0 => Ok(Some((s * 1e6).round() as u64)),
        Some(s) => bail!("--duration must be a positive number of seconds, got {s}"),
        None => Ok(None),
    }
}

fn print_two_process(m: &two_process::TwoProcessMetrics, json: bool) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string(m)?);
        return Ok(());
    }
    let mut line = format!(
        "{} {} {} seed {} (two processes, {} estimator)",
        m.scenario, m.controller, m.plant, m.seed, m.estimator
    );
    line += &gust_track_lines(m.gust.as_ref(), m.track.as_ref());
    if let Some((reached, total)) = m.items_reached {
        line += &format!("\n  mission: {reached} of {total} items reached");
    }
    line += &format!(
        "\n  non-finite: {}  pwm activity {:.2} us/tick  {:.1} sim s in {:.2} s wall ({:.0}x real time)",
        m.non_finite, m.pwm_activity_us, m.sim_s, m.wall_s, m.realtime_factor
    );
    println!("{line}");
    Ok(())
}

fn run(args: &RunArgs) -> Result<()> {
    if args.count > 1 {
        return run_swarm(args);
    }
    if args.scenario.is_some() && (args.plant.config.is_some() || args.plant.pacing_given() || args.duration.is_some())
    {
        bail!(
            "--scenario sets the plant, pacing (as fast as possible) and duration itself; drop --config, --speed, \
             --lockstep and --duration"
        );
    }
    let n = args.instance;
    let (plant_port, ap_port, qgc_port, api_port) = instance_ports(n)?;
    let autopilot = launch::autopilot_binary()?;
    // Everything the command line names is checked before anything starts: a busy instance, an autopilot
    // configuration the autopilot would refuse, a scenario that does not load.
    launch::check_instance_free(n, true)?;
    check_autopilot_config(args, n)?;
    let stop = launch::ctrl_c_flag();
    if let Some(name) = &args.scenario {
        // The scenario runner gives the autopilot its plant, instance and estimator itself.
        let mut ap_args: Vec<OsString> = Vec::new();
        if let Some(dir) = &args.log_dir {
            ap_args.extend(["--log-dir".into(), dir.into()]);
        }
        if args.no_ulog {
            ap_args.push("--no-ulog".into());
        }
        let scenario = Scenario::load(name)?;
        let controller =
            args.controller.unwrap_or_else(|| scenario.controllers.first().copied().unwrap_or(ControllerKind::Aco));
        let estimator = match args.estimator.as_deref() {
            None => None,
            Some("truth") => Some(EstimatorSource::Truth),
            Some("fused") => Some(EstimatorSource::Fused),
            Some(other) => bail!("--estimator must be fused or truth, got `{other}`"),
        };
        let opts = TwoProcessOptions {
            controller,
            plant: args.plant.preset.clone(),
            seed: args.plant.seed,
            instance: n,
            estimator,
            autopilot_args: ap_args,
        };
        eprintln!(
            "sitl: instance {n}: flying scenario {} through plant and autopilot ({controller}), as fast as possible \
             (lockstep)",
            scenario.name
        );
        let m = two_process::run(&scenario, &opts, &autopilot, &stop)?;
        return print_two_process(&m, args.json);
    }

    let (plant, pacing) = args.plant.build(realistic_plant_config())?;
    let duration = duration_us(args.duration)?;
    let listen = format!("127.0.0.1:{plant_port}");
    let (sim_params, sim_port) = bind_sim_params(n, &plant)?;
    let mut server = PlantServer::bind_udp(plant, listen.as_str(), run_link_config(args, pacing))
        .with_context(|| format!("binding {listen}"))?;
    server.set_hook(Box::new(sim_params));
    let ap_args = autopilot_args(args, n, &listen, args.state_dir.as_ref().map(OsString::from));
    let child = AutopilotChild::spawn(&autopilot, &ap_args)?;
    eprintln!(
        "sitl: instance {n} running {}{}; plant on udp {listen}, SIM_ parameters on udp 127.0.0.1:{sim_port} \
         (system {}, component {}), autopilot pid {} (system id {}) listening on udp {ap_port} and tcp {}; ground \
         stations: listen on udp {qgc_port} (QGroundControl) or {api_port} (MAVSDK/API), or send to \
         127.0.0.1:{ap_port}. Ctrl-C stops both.",
        describe_pacing(pacing),
        if args.plant.pacing_given() { "" } else { " (`--speed 4` or `--speed max` to run faster)" },
        u32::from(n) + 1,
        sitl::link::PLANT_COMPONENT_ID,
        child.id(),
        u32::from(n) + 1,
        5760 + u32::from(n),
    );
    let mut progress = match duration {
        Some(us) => Progress::new(&format!("sitl: instance {n}"), us.div_ceil(1_000_000), "sim s"),
        None => Progress::hidden(0),
    };
    let report = launch::run_with_child(&mut server, child, duration, &stop, |plant, _| {
        progress.set(plant.time_us() / 1_000_000);
    });
    progress.finish();
    let report = report?;
    let l = &report.link;
    eprintln!(
        "sitl: {} steps, {:.1} sim s in {:.1} s wall ({:.1}x real time, {:.0} steps/s); plant link: {} resends, {} \
         stale replies, {} junk datagrams, {} malformed frames dropped",
        report.steps,
        report.sim_s,
        report.wall_s,
        report.realtime_factor(),
        report.steps as f64 / report.wall_s.max(1e-9),
        l.resends,
        l.stale_actuators,
        l.junk_datagrams,
        l.decoder.malformed(),
    );
    Ok(())
}

/// Checks `--autopilot-config` as the autopilot of instance `n` would (parsed, resolved and a vehicle
/// built from it) before anything starts.
fn check_autopilot_config(args: &RunArgs, n: u16) -> Result<()> {
    let Some(path) = &args.autopilot_config else { return Ok(()) };
    let file = ConfigFile::load(path)?;
    let config = RuntimeConfig::resolve(file, n, Overrides::default())
        .with_context(|| format!("autopilot configuration {}", path.display()))?;
    Vehicle::new(config.vehicle).with_context(|| format!("autopilot configuration {}", path.display()))?;
    Ok(())
}

/// The plant link of `sitl run` at `pacing`: the autopilot has 30 s to connect; the truth estimator gets
/// ODOMETRY too.
fn run_link_config(args: &RunArgs, pacing: Pacing) -> LinkConfig {
    LinkConfig {
        pacing,
        connect_timeout: Some(Duration::from_secs(30)),
        truth_odometry: args.estimator.as_deref() == Some("truth"),
        ..LinkConfig::default()
    }
}

/// The `autopilot` command line of instance `n` with its plant on `listen`, from `sitl run`'s options, and
/// `state_dir` when one is to be passed.
fn autopilot_args(args: &RunArgs, n: u16, listen: &str, state_dir: Option<OsString>) -> Vec<OsString> {
    let mut ap_args: Vec<OsString> = vec!["--plant".into(), format!("udp://{listen}").into()];
    ap_args.extend(["-i".into(), n.to_string().into()]);
    if let Some(estimator) = &args.estimator {
        ap_args.extend(["--estimator".into(), estimator.into()]);
    }
    if let Some(controller) = args.controller {
        ap_args.extend(["--controller".into(), controller.to_string().into()]);
    }
    if let Some(path) = &args.autopilot_config {
        ap_args.extend(["--config".into(), path.into()]);
    }
    if let Some(dir) = &args.log_dir {
        ap_args.extend(["--log-dir".into(), dir.into()]);
    }
    if let Some(dir) = state_dir {
        ap_args.extend(["--state-dir".into(), dir]);
    }
    if args.no_ulog {
        ap_args.push("--no-ulog".into());
    }
    if args.wipe {
        ap_args.push("--wipe".into());
    }
    ap_args
}

/// Where swarm vehicle `k` of `count` starts: on a square grid `spacing_m` apart, rows north, columns east
/// (NED, metres from the plant origin).
fn grid_position_ned_m(k: u16, count: u16, spacing_m: f64) -> nalgebra::Vector3<f64> {
    let columns = (f64::from(count).sqrt().ceil() as u16).max(1);
    nalgebra::Vector3::new(f64::from(k / columns) * spacing_m, f64::from(k % columns) * spacing_m, 0.0)
}

/// The swarm of `sitl run -n N` started, once the instances, `--spacing` and the autopilot configuration
/// have been checked: N plant servers bound (not yet stepping) and N autopilot processes spawned (with
/// `RUST_LOG` set to `log_filter` unless the environment sets it), in instance order.
fn start_swarm(
    args: &RunArgs,
    log_filter: Option<&str>,
) -> Result<(Vec<PlantServer<UdpTransport>>, Vec<AutopilotChild>)> {
    let (first, count) = (args.instance, args.count);
    let last = first
        .checked_add(count - 1)
        .filter(|&last| last <= autopilot::runtime::ports::MAX_INSTANCE)
        .with_context(|| format!("-i {first} -n {count}: instances are 0..=254"))?;
    if !(args.spacing.is_finite() && args.spacing > 0.0) {
        bail!("--spacing must be a positive number of metres, got {}", args.spacing);
    }
    let autopilot = launch::autopilot_binary()?;
    for n in first..=last {
        launch::check_instance_free(n, true)?;
    }
    check_autopilot_config(args, first)?;
    let config = args.plant.config(realistic_plant_config())?;
    let pacing = args.plant.pacing();
    let mut servers = Vec::new();
    let mut children = Vec::new();
    for (k, n) in (first..=last).enumerate() {
        let k = u16::try_from(k).context("swarm index")?;
        let ports = InstancePorts::of(n)?;
        let start = InitialState { pos_ned_m: grid_position_ned_m(k, count, args.spacing), ..InitialState::default() };
        let plant = Plant::new(config.clone(), &start, args.plant.seed.wrapping_add(u64::from(k)))?;
        let listen = format!("127.0.0.1:{}", ports.plant_udp);
        let (sim_params, _) = bind_sim_params(n, &plant)?;
        let mut server = PlantServer::bind_udp(plant, listen.as_str(), run_link_config(args, pacing))
            .with_context(|| format!("binding {listen}"))?;
        server.set_hook(Box::new(sim_params));
        servers.push(server);
        // Each vehicle keeps its own state: a directory given for the swarm holds one per instance.
        let state_dir = match args.state_dir.as_deref().map(str::trim) {
            Some("off") => Some(OsString::from("off")),
            Some(dir) => Some(Path::new(dir).join(format!("i{n}")).into_os_string()),
            None => None,
        };
        let ap_args = autopilot_args(args, n, &listen, state_dir);
        children.push(AutopilotChild::spawn_with(&autopilot, &ap_args, log_filter)?);
    }
    Ok((servers, children))
}

/// `sitl run -n N`: N plants in this process on one clock, N autopilot processes.
fn run_swarm(args: &RunArgs) -> Result<()> {
    let duration = duration_us(args.duration)?;
    let stop = launch::ctrl_c_flag();
    let (mut servers, children) = start_swarm(args, None)?;
    let (first, count, pacing) = (args.instance, args.count, args.plant.pacing());
    let last = first + (count - 1);
    let api: Vec<String> =
        (first..=last).map(|n| InstancePorts::of(n).map(|p| p.api_udp.to_string())).collect::<Result<_, _>>()?;
    eprintln!(
        "sitl: swarm of {count} vehicles running {}: instances {first}..={last} (system ids {}..={}), spawned {} m \
         apart; every vehicle sends to udp 14550 (QGroundControl shows them all) and to its API port ({}); \
         plants on udp {}..={}, SIM_ parameters on udp {}..={}. Ctrl-C stops them all.",
        describe_pacing(pacing),
        u32::from(first) + 1,
        u32::from(last) + 1,
        args.spacing,
        api.join(", "),
        InstancePorts::of(first)?.plant_udp,
        InstancePorts::of(last)?.plant_udp,
        InstancePorts::of(first)?.sim_params_udp,
        InstancePorts::of(last)?.sim_params_udp,
    );
    let mut progress = match duration {
        Some(us) => Progress::new("sitl: swarm", us.div_ceil(1_000_000), "sim s"),
        None => Progress::hidden(0),
    };
    let report = launch::run_swarm(&mut servers, children, duration, &stop, |t_us| progress.set(t_us / 1_000_000));
    progress.finish();
    let report = report?;
    let steps: u64 = report.vehicles.iter().map(|v| v.steps).sum();
    let sim_s = report.vehicles.first().map_or(0.0, |v| v.sim_s);
    let resends: u64 = report.vehicles.iter().map(|v| v.link.resends).sum();
    let malformed: u64 = report.vehicles.iter().map(|v| v.link.decoder.malformed()).sum();
    let autopilot_cpu_s: f64 = report.vehicles.iter().filter_map(|v| v.autopilot_cpu_s).sum();
    eprintln!(
        "sitl: swarm of {count}: {sim_s:.1} sim s in {:.1} s wall ({:.1}x real time), {steps} plant steps in all; \
         CPU: plants {:.2} s in this process, autopilots {autopilot_cpu_s:.2} s together; plant links: {resends} \
         resends, {malformed} malformed frames dropped",
        report.wall_s,
        if report.wall_s > 0.0 { sim_s / report.wall_s } else { 0.0 },
        report.vehicles.first().and_then(|v| v.plant_cpu_s).unwrap_or(f64::NAN),
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
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

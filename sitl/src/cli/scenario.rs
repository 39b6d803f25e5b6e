//! `sitl scenario`: the paper's experiments in-process in lockstep, their CSV traces, metrics (JSON or a
//! summary) and figures.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use autopilot::core::control::{ControllerKind, LoopRates};
use clap::Args;
use sitl::progress::Progress;
use sitl::scenario::reference::ReferenceMode;
use sitl::scenario::runner::{self, RunOptions, RunOutput};
use sitl::scenario::{BUILT_INS, Scenario, file_label};

use sitl::view::scenario::{run_viewed, scenario_meta_frame};
use sitl::view::{Delivery, Viewer};

use super::common::{fmt_seconds, gust_track_lines, write_atomically};
use super::plots::plots;
use super::view::{ViewArgs, finish_viewer, start_viewer};

#[derive(Args)]
pub(crate) struct ScenarioArgs {
    /// Built-in scenario names or scenario TOML files; `all` runs every built-in.
    #[arg(required_unless_present = "list")]
    pub(crate) scenarios: Vec<String>,
    /// List the built-in scenarios and exit.
    #[arg(long)]
    pub(crate) list: bool,
    /// Controllers, comma-separated, any registered name (`sitl controllers` lists them); default: the
    /// scenario's own list.
    #[arg(long, value_delimiter = ',')]
    pub(crate) controller: Vec<ControllerKind>,
    /// Airframe preset (nominal, mismatch); default: the scenario's.
    #[arg(long)]
    pub(crate) plant: Option<String>,
    /// Seeds: `7`, `1,2,3` or `1-5`.
    #[arg(long, default_value = "1")]
    pub(crate) seed: String,
    /// Inner loop rate (rate, attitude, LMS), Hz; must divide 1 MHz.
    #[arg(long, default_value_t = 500)]
    pub(crate) rate_hz: u32,
    /// Position loop rate, Hz; default inner rate / 5 (100 Hz at 500 Hz).
    #[arg(long)]
    pub(crate) position_hz: Option<u32>,
    /// Output directory for CSV traces and PNG plots.
    #[arg(long, default_value = "out")]
    pub(crate) out: PathBuf,
    /// Print one metrics JSON object per run (one per line) instead of a summary.
    #[arg(long)]
    pub(crate) json: bool,
    /// Trace rows per simulated second in the CSV.
    #[arg(long, default_value_t = 50)]
    pub(crate) trace_hz: u32,
    /// Skip the PNG plots.
    #[arg(long)]
    pub(crate) no_plots: bool,
    /// The runs in the view (every controller overlaid on one time axis) or recorded (`--record`).
    #[command(flatten)]
    pub(crate) view: ViewArgs,
}

/// The view's name of a run of `scenario` flown with `seeds`: the controller's, with the seed and the
/// reference mode when there are several.
fn source(scenario: &Scenario, seeds: &[u64], controller: ControllerKind, seed: u64, mode: ReferenceMode) -> String {
    let mut src = controller.to_string();
    if seeds.len() > 1 {
        src += &format!("-seed{seed}");
    }
    if scenario.reference_modes().len() > 1 {
        src += &format!("-{mode}");
    }
    src
}

pub(crate) fn parse_seeds(text: &str) -> Result<Vec<u64>> {
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

pub(crate) fn scenario(args: &ScenarioArgs) -> Result<()> {
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
    let view_opts = args.view.options()?;
    let viewer = match &view_opts {
        Some(opts) => {
            if scenarios.len() > 1 {
                bail!("--view and --record show one scenario at a time; name one");
            }
            Some(start_viewer(opts, Delivery::Complete, &format!("scenario {}", names.join(" ")))?)
        }
        None => None,
    };
    let sender = viewer.as_ref().map(Viewer::sender);
    if let (Some(sender), Some(scenario)) = (&sender, scenarios.first()) {
        let mut sources = Vec::new();
        for &seed in &seeds {
            for mode in scenario.reference_modes() {
                sources.extend(controllers_of(scenario).into_iter().map(|c| source(scenario, &seeds, c, seed, mode)));
            }
        }
        sender.send(&scenario_meta_frame(scenario, &sources));
    }
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
                    let out = match &sender {
                        Some(sender) => {
                            run_viewed(scenario, &opts, &source(scenario, &seeds, controller, seed, mode), sender)?
                        }
                        None => runner::run(scenario, &opts)?,
                    };
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
    drop(sender);
    if let (Some(viewer), Some(opts)) = (viewer, &view_opts) {
        finish_viewer(viewer, opts)?;
    }
    Ok(())
}

pub(crate) fn run_stem(out: &RunOutput, mode: ReferenceMode, scenario: &Scenario) -> String {
    let m = &out.metrics;
    let mode = if scenario.reference_modes().len() > 1 { format!("_{mode}") } else { String::new() };
    format!("{}_{}{}_seed{}_{}hz", m.controller, file_label(&m.plant), mode, m.seed, m.rate_hz)
}

/// The unit of a step metric's axis: attitude axes in rad, body rates (p, q, r) in rad/s, position axes
/// (n, e, d) in m.
pub(crate) fn axis_unit(axis: &str) -> &'static str {
    match axis {
        "roll" | "pitch" | "yaw" => "rad",
        "p" | "q" | "r" => "rad/s",
        _ => "m",
    }
}

pub(crate) fn summary(out: &RunOutput) -> String {
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

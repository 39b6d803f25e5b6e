//! `sitl tune`: a controller's gains tuned on a spec's training cost (or gain files flown on its held-out
//! set with `--evaluate`), and the tuning's outputs and held-out report.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use clap::Args;
use sitl::progress::Progress;

use super::common::{pool, print_stdout};

#[derive(Args)]
pub(crate) struct TuneArgs {
    /// The tuning spec (TOML; docs/tuning.md).
    pub(crate) spec: PathBuf,
    /// Instead of tuning, fly these gain sets on the spec's held-out set: gain files (a `[controller]`
    /// block, e.g. a tuning's controller.toml) or `aco`, `ca`, `pid` for a controller's defaults.
    #[arg(long, value_name = "GAINS", num_args = 1..)]
    pub(crate) evaluate: Vec<String>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub(crate) jobs: Option<u16>,
    /// Output directory (default: out/tune-<name>, or out/tune-<name>-evaluate with --evaluate).
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Print the held-out report as JSON instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn tune(args: &TuneArgs) -> Result<()> {
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

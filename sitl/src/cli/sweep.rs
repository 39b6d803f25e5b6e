//! `sitl sweep`: a scenario swept over airframes, winds, seeds and controllers (or shards of it, or the
//! shards merged): the rows, the robustness summary and its figures.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use sitl::progress::Progress;
use sitl::sweep::Sweep;

use super::common::write_atomically;
use super::plots::sweep_plots;

#[derive(Args)]
pub(crate) struct SweepArgs {
    /// The sweep spec (TOML; docs/sweeps.md).
    pub(crate) spec: PathBuf,
    /// Run shard K of N only: every N-th run from run K-1 (`--shard 2/3`); `--merge` joins the shards.
    #[arg(long, value_name = "K/N", value_parser = sitl::sweep::parse_shard, conflicts_with = "merge")]
    pub(crate) shard: Option<(u64, u64)>,
    /// Instead of running, merge the row files of shards (from `--shard`) into the whole sweep's, checked
    /// against the spec: every run once, each with the values the spec gives it.
    #[arg(long, value_name = "CSV", num_args = 1..)]
    pub(crate) merge: Vec<PathBuf>,
    /// A scenario file in place of the spec's `scenario`.
    #[arg(long, value_name = "FILE")]
    pub(crate) scenario: Option<PathBuf>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub(crate) jobs: Option<u16>,
    /// Output directory (default: out/sweep-<name>).
    #[arg(long)]
    pub(crate) out: Option<PathBuf>,
    /// Skip the plots.
    #[arg(long)]
    pub(crate) no_plots: bool,
    /// Print the summary as JSON instead of the table.
    #[arg(long)]
    pub(crate) json: bool,
}

pub(crate) fn sweep(args: &SweepArgs) -> Result<()> {
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

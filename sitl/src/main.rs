//! `sitl`: the simulator's command line. `sitl scenario` runs the paper's experiments in-process in
//! lockstep (headless, faster than real time) and writes metrics JSON, CSV traces and PNG plots;
//! `sitl serve` serves the plant to an autopilot over the MAVLink HIL plant protocol (UDP or serial);
//! `sitl run` is the one-command SITL: the plant server plus the `autopilot` binary as a child process
//! (optionally flying a hover scenario through both, with its metrics). Both `serve` and `run` answer the
//! plant's SIM_ parameters (wind and gusts at run time, `sitl::sim_params`) on UDP 19550+N, and pace the
//! plant at real time unless told otherwise (`--speed X` for X times real time, `--speed max` or
//! `--lockstep` for as fast as the autopilot answers), as a ground station and the person watching it
//! expect; scenarios (`sitl scenario`, `sitl run --scenario`) are batch runs, always as fast as possible.
//! `sitl line` is an emulated serial line (a UART or a telemetry radio: baud rate, loss, corruption, latency)
//! between two pty devices, for tests that put two processes on its two ends.
//! `sitl bench` (`bench`) measures the two-process real-time factor in lockstep and the CPU cost of the SITL
//! and its telemetry in real time, or with `--vehicles N` how a swarm of N answers a ground station.
//!
//! This file is the command line only (clap) and the dispatch; each subcommand's work is in `cli/`.

mod cli;

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use cli::bench::BenchArgs;
#[cfg(unix)]
use cli::line::LineArgs;
use cli::run::RunArgs;
use cli::scenario::ScenarioArgs;
use cli::serve::ServeArgs;
use cli::sweep::SweepArgs;
use cli::tune::TuneArgs;

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
    /// An emulated serial line between two pty devices (symlinks --link-a and --link-b): a UART or a
    /// telemetry radio at a baud rate (10 bits a byte), with loss in bursts, corruption and latency, until
    /// SIGINT or SIGTERM.
    #[cfg(unix)]
    Line(LineArgs),
    /// List the registered controllers: the names every command takes, their `[controller]` table,
    /// whether they fly the rate level (Acro, offboard body rates, `rates` scenarios), and what they are.
    Controllers,
    /// Open an autopilot's ULog flight log in the live view's viewer (Rerun): the estimate, setpoints,
    /// motors, battery, ACO weights, modes and messages (docs/view.md).
    View(cli::view::ViewFileArgs),
}

fn main() -> ExitCode {
    autopilot::cli::init_logging();
    let command = Cli::parse().command;
    // A controller name registered twice is refused before anything runs.
    if let Err(e) = autopilot::core::control::registry::check() {
        return autopilot::cli::exit("sitl", Err(e.into()));
    }
    let result = match command {
        Command::Scenario(args) => cli::scenario::scenario(&args),
        Command::Serve(args) => cli::serve::serve(&args),
        Command::Run(args) => cli::run::run(&args),
        Command::Bench(args) => cli::bench::run(&args),
        Command::Sweep(args) => cli::sweep::sweep(&args),
        Command::Tune(args) => cli::tune::tune(&args),
        Command::View(args) => cli::view::view(&args),
        #[cfg(unix)]
        Command::Line(args) => cli::line::line(&args),
        Command::Controllers => {
            print!("{}", controllers_table());
            Ok(())
        }
    };
    autopilot::cli::exit("sitl", result)
}

/// The registered controllers, one line each: name (aliases), table, rate level, summary.
fn controllers_table() -> String {
    use autopilot::core::control::registry;
    let mut out = String::from("name      table     rates  summary\n");
    for kind in registry::all() {
        let ty = kind.ty();
        let name = std::iter::once(ty.name()).chain(ty.aliases().iter().copied()).collect::<Vec<_>>().join("|");
        let rates = if kind.flies_rates() { "yes" } else { "no" };
        out.push_str(&format!("{name:<9} {:<9} {rates:<6} {}\n", kind.table(), ty.summary()));
    }
    out
}

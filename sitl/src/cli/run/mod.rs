//! `sitl run`: the one-command SITL, the plant server plus the `autopilot` binary as a child process, or
//! a scenario flown through both (a swarm, `-n N`, is `swarm`; the options both read are `args`).

use std::ffi::OsString;

use anyhow::{Context, Result, bail};
use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use sitl::launch::{self, AutopilotChild};
use sitl::link::PlantServer;
use sitl::progress::Progress;
use sitl::scenario::Scenario;
use sitl::scenario::two_process::{self, TwoProcessOptions};
use sitl::view::{VehiclePlacement, ViewSampler, truth_frame};

use crate::cli::common::{
    bind_rc_in, bind_sim_params, describe_pacing, describe_rc_in, duration_us, faults_summary, fmt_seconds,
    gust_track_lines, hawkeye_summary, instance_ports, radio_summary, realistic_plant_config,
};

mod args;
mod swarm;
mod view;

pub(crate) use args::RunArgs;
pub(crate) use swarm::start_swarm;

use args::{autopilot_args, check_autopilot_config, run_link_config};
use swarm::run_swarm;
use view::start_view;

pub(crate) fn run(args: &RunArgs) -> Result<()> {
    if args.count > 1 {
        if args.plant.rc_in_port.is_some_and(|p| p != 0) {
            bail!("--rc-in-port is for one vehicle: a swarm's plants take no radio");
        }
        return run_swarm(args);
    }
    if args.scenario.is_some() && args.view.options()?.is_some() {
        bail!(
            "--view and --record draw a live run; a scenario is drawn by `sitl scenario NAME --view` (every \
             controller overlaid)"
        );
    }
    if args.scenario.is_some() && args.plant.hawkeye {
        bail!("--hawkeye is for `sitl run` and `sitl serve` plants; a --scenario runs its own plant without it");
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
    args.plant.check_hawkeye(n)?;
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
            args.controller.unwrap_or_else(|| scenario.controllers.first().copied().unwrap_or(ControllerKind::ACO));
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
            rc_in_port: args.plant.rc_in_port(n),
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
    let view_opts = args.view.options()?;
    let src = format!("v{n}");
    let placements = vec![(src.clone(), VehiclePlacement::of(&plant))];
    let view = start_view(view_opts.as_ref(), &format!("instance {n}"), placements)?;
    let listen = format!("127.0.0.1:{plant_port}");
    let (sim_params, sim_port) = bind_sim_params(n, &plant)?;
    let rc_port = args.plant.rc_in_port(n);
    let rc_in = bind_rc_in(rc_port)?;
    let mut server = PlantServer::bind_udp(plant, listen.as_str(), run_link_config(args, pacing))
        .with_context(|| format!("binding {listen}"))?;
    server.set_sim_port(sim_params);
    if let Some(port) = rc_in {
        server.set_rc_in(port);
    }
    if let Some(hawkeye) = args.plant.hawkeye_sender(n, server.plant())? {
        eprintln!(
            "sitl: instance {n}: the plant's truth to Hawkeye on udp {} (50 Hz of sim time)",
            hawkeye.destination()
        );
        server.set_hawkeye(hawkeye);
    }
    let mut ap_args = autopilot_args(args, n, &listen, args.state_dir.as_ref().map(OsString::from));
    if let Some(v) = &view {
        ap_args.extend(["--view-udp".into(), v.forwarder.addr().to_string().into()]);
    }
    let child = AutopilotChild::spawn(&autopilot, &ap_args)?;
    eprintln!(
        "sitl: instance {n} running {}{}; plant on udp {listen}, SIM_ parameters on udp 127.0.0.1:{sim_port} \
         (system {}, component {}), {}, autopilot pid {} (system id {}) listening on udp {ap_port} and tcp {}; ground \
         stations: listen on udp {qgc_port} (QGroundControl) or {api_port} (MAVSDK/API), or send to \
         127.0.0.1:{ap_port}. Ctrl-C stops both.",
        describe_pacing(pacing),
        if args.plant.pacing_given() { "" } else { " (`--speed 4` or `--speed max` to run faster)" },
        u32::from(n) + 1,
        sitl::link::PLANT_COMPONENT_ID,
        describe_rc_in(rc_port),
        child.id(),
        u32::from(n) + 1,
        5760 + u32::from(n),
    );
    let mut progress = match duration {
        Some(us) => Progress::new(&format!("sitl: instance {n}"), us.div_ceil(1_000_000), "sim s"),
        None => Progress::hidden(0),
    };
    let truth_to = view.as_ref().map(|v| v.sender.clone());
    let mut sampler = ViewSampler::default();
    let report = launch::run_with_child(&mut server, child, duration, &stop, |plant, _| {
        progress.set(plant.time_us() / 1_000_000);
        if let Some(to) = &truth_to
            && sampler.due(plant.time_us())
        {
            to.send(&truth_frame(&src, &plant.truth()));
        }
    });
    progress.finish();
    drop(truth_to);
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
    for line in [radio_summary(&server), faults_summary(l), hawkeye_summary(&server)].into_iter().flatten() {
        eprintln!("{line}");
    }
    if let (Some(v), Some(opts)) = (view, &view_opts) {
        v.finish(opts)?;
    }
    Ok(())
}

pub(crate) fn print_two_process(m: &two_process::TwoProcessMetrics, json: bool) -> Result<()> {
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
    if let Some(p) = m.pilot {
        line += &format!(
            "\n  pilot: armed at {}, disarmed at {}, climbed {:.2} m at most",
            fmt_seconds(p.armed_at_s),
            fmt_seconds(p.disarmed_at_s),
            p.max_climb_m
        );
    }
    line += &format!(
        "\n  non-finite: {}  pwm activity {:.2} us/tick  {:.1} sim s in {:.2} s wall ({:.0}x real time)",
        m.non_finite, m.pwm_activity_us, m.sim_s, m.wall_s, m.realtime_factor
    );
    println!("{line}");
    Ok(())
}

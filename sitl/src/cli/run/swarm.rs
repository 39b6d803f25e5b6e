//! `sitl run -n N`: a swarm of N plants in this process on one clock and N autopilot processes, placed on
//! a grid.

use std::ffi::OsString;
use std::path::Path;

use anyhow::{Context, Result, bail};
use autopilot::runtime::ports::InstancePorts;
use sitl::launch::{self, AutopilotChild};
use sitl::link::{PlantServer, UdpTransport};
use sitl::plant::{InitialState, Plant};
use sitl::progress::Progress;
use sitl::view::{VehiclePlacement, ViewSampler, truth_frame};

use super::args::{RunArgs, autopilot_args, check_autopilot_config, run_link_config};
use super::view::start_view;
use crate::cli::common::{bind_sim_params, describe_pacing, duration_us, realistic_plant_config};

/// Where swarm vehicle `k` of `count` starts: on a square grid `spacing_m` apart, rows north, columns east
/// (NED, metres from the plant origin).
pub(crate) fn grid_position_ned_m(k: u16, count: u16, spacing_m: f64) -> nalgebra::Vector3<f64> {
    let columns = (f64::from(count).sqrt().ceil() as u16).max(1);
    nalgebra::Vector3::new(f64::from(k / columns) * spacing_m, f64::from(k % columns) * spacing_m, 0.0)
}

/// The swarm of `sitl run -n N` started, once the instances, `--spacing` and the autopilot configuration
/// have been checked: N plant servers bound (not yet stepping) and N autopilot processes spawned (with
/// `RUST_LOG` set to `log_filter` unless the environment sets it), in instance order.
pub(crate) fn start_swarm(
    args: &RunArgs,
    log_filter: Option<&str>,
) -> Result<(Vec<PlantServer<UdpTransport>>, Vec<AutopilotChild>)> {
    start_swarm_viewed(args, log_filter, |_| Ok(None))
}

/// [`start_swarm`], with `view` given every vehicle's source and placement before the autopilots start
/// and answering the address they send their view stream to, if any.
fn start_swarm_viewed(
    args: &RunArgs,
    log_filter: Option<&str>,
    view: impl FnOnce(Vec<(String, VehiclePlacement)>) -> Result<Option<std::net::SocketAddr>>,
) -> Result<(Vec<PlantServer<UdpTransport>>, Vec<AutopilotChild>)> {
    let (first, count) = (args.instance, args.count);
    let last = first
        .checked_add(count - 1)
        .filter(|&last| last <= autopilot::runtime::ports::MAX_INSTANCE)
        .with_context(|| format!("-i {first} -n {count}: instances are 0..=254"))?;
    if !(args.spacing.is_finite() && args.spacing > 0.0) {
        bail!("--spacing must be a positive number of metres, got {}", args.spacing);
    }
    args.plant.check_hawkeye(last)?;
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
        server.set_sim_port(sim_params);
        if let Some(hawkeye) = args.plant.hawkeye_sender(n, server.plant())? {
            server.set_hawkeye(hawkeye);
        }
        servers.push(server);
    }
    let placements = servers
        .iter()
        .zip(first..=last)
        .map(|(server, n)| (format!("v{n}"), VehiclePlacement::of(server.plant())))
        .collect();
    let view_udp = view(placements)?;
    for n in first..=last {
        let ports = InstancePorts::of(n)?;
        let listen = format!("127.0.0.1:{}", ports.plant_udp);
        // Each vehicle keeps its own state: a directory given for the swarm holds one per instance.
        let state_dir = match args.state_dir.as_deref().map(str::trim) {
            Some("off") => Some(OsString::from("off")),
            Some(dir) => Some(Path::new(dir).join(format!("i{n}")).into_os_string()),
            None => None,
        };
        let mut ap_args = autopilot_args(args, n, &listen, state_dir);
        if let Some(addr) = view_udp {
            ap_args.extend(["--view-udp".into(), addr.to_string().into()]);
        }
        children.push(AutopilotChild::spawn_with(&autopilot, &ap_args, log_filter)?);
    }
    Ok((servers, children))
}

/// `sitl run -n N`: N plants in this process on one clock, N autopilot processes.
pub(crate) fn run_swarm(args: &RunArgs) -> Result<()> {
    let duration = duration_us(args.duration)?;
    let stop = launch::ctrl_c_flag();
    let view_opts = args.view.options()?;
    let mut live = None;
    let (mut servers, children) = start_swarm_viewed(args, None, |placements| {
        live = start_view(view_opts.as_ref(), &format!("a swarm of {}", args.count), placements)?;
        Ok(live.as_ref().map(|v| v.forwarder.addr()))
    })?;
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
    if args.plant.hawkeye {
        eprintln!(
            "sitl: swarm: the plants' truth to Hawkeye on udp {}..={} (50 Hz of sim time)",
            InstancePorts::of(first)?.hawkeye_udp,
            InstancePorts::of(last)?.hawkeye_udp
        );
    }
    let mut progress = match duration {
        Some(us) => Progress::new("sitl: swarm", us.div_ceil(1_000_000), "sim s"),
        None => Progress::hidden(0),
    };
    let truth_to = live.as_ref().map(|v| v.sender.clone());
    let sources: Vec<String> = (first..=last).map(|n| format!("v{n}")).collect();
    let mut sampler = ViewSampler::default();
    let report = launch::run_swarm(&mut servers, children, duration, &stop, |t_us, servers| {
        progress.set(t_us / 1_000_000);
        if let Some(to) = &truth_to
            && sampler.due(t_us)
        {
            for (server, src) in servers.iter().zip(&sources) {
                to.send(&truth_frame(src, &server.plant().truth()));
            }
        }
    });
    progress.finish();
    drop(truth_to);
    let report = report?;
    let steps: u64 = report.vehicles.iter().map(|v| v.steps).sum();
    let sim_s = report.vehicles.first().map_or(0.0, |v| v.sim_s);
    let resends: u64 = report.vehicles.iter().map(|v| v.link.resends).sum();
    let malformed: u64 = report.vehicles.iter().map(|v| v.link.decoder.malformed()).sum();
    let autopilot_cpu_s: f64 = report.vehicles.iter().filter_map(|v| v.autopilot_cpu_s).sum();
    if args.plant.hawkeye {
        let sent: u64 = report.vehicles.iter().map(|v| v.link.hawkeye_sent).sum();
        let refused: u64 = report.vehicles.iter().map(|v| v.link.hawkeye_failed).sum();
        eprintln!("sitl: swarm: hawkeye: {sent} HIL_STATE_QUATERNION sent, {refused} refused (no viewer listening?)");
    }
    eprintln!(
        "sitl: swarm of {count}: {sim_s:.1} sim s in {:.1} s wall ({:.1}x real time), {steps} plant steps in all; \
         CPU: plants {:.2} s in this process, autopilots {autopilot_cpu_s:.2} s together; plant links: {resends} \
         resends, {malformed} malformed frames dropped",
        report.wall_s,
        if report.wall_s > 0.0 { sim_s / report.wall_s } else { 0.0 },
        report.vehicles.first().and_then(|v| v.plant_cpu_s).unwrap_or(f64::NAN),
    );
    if let (Some(v), Some(opts)) = (live, &view_opts) {
        v.finish(opts)?;
    }
    Ok(())
}

//! `sitl serve`: the plant served to an autopilot over the HIL plant protocol, on UDP or a serial port.

use anyhow::{Context, Result, bail};
use autopilot::runtime::transport::{POLL_INTERVAL, SerialTransport, parse_serial_spec};
use clap::Args;
use sitl::launch;
use sitl::link::{LinkConfig, PlantServer};

use super::common::{
    PlantArgs, bind_rc_in, bind_sim_params, describe_pacing, describe_rc_in, faults_summary, instance_ports,
    radio_summary, realistic_plant_config,
};

#[derive(Args)]
pub(crate) struct ServeArgs {
    #[command(flatten)]
    pub(crate) plant: PlantArgs,
    /// Instance: the UDP port becomes 4560 + N, the SIM_ parameter port 19550 + N (system N + 1).
    #[arg(short = 'i', long, default_value_t = 0)]
    pub(crate) instance: u16,
    /// UDP address to listen on; the autopilot announces itself with any MAVLink message.
    #[arg(long)]
    pub(crate) listen: Option<String>,
    /// Serve over a serial port instead of UDP: `DEVICE:BAUD`, e.g. /dev/ttyUSB0:921600.
    #[arg(long)]
    pub(crate) serial: Option<String>,
    /// Plant step per sensor sample, µs (2000 = 500 Hz).
    #[arg(long, default_value_t = 2000)]
    pub(crate) dt_us: u64,
}

pub(crate) fn serve(args: &ServeArgs) -> Result<()> {
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
    let rc_port = args.plant.rc_in_port(args.instance);
    let rc_in = bind_rc_in(rc_port)?;
    let (steps, radio, faults) = if let Some(spec) = &args.serial {
        let (device, baud) = parse_serial_spec(spec).map_err(anyhow::Error::msg).context("--serial")?;
        let transport =
            SerialTransport::open(&device, baud, POLL_INTERVAL).with_context(|| format!("opening {device}"))?;
        eprintln!(
            "sitl: plant on serial {device} at {baud} baud, running {}; SIM_ parameters on udp \
             127.0.0.1:{sim_port}; {}",
            describe_pacing(pacing),
            describe_rc_in(rc_port)
        );
        let mut server = PlantServer::new(plant, transport, link);
        server.set_hook(Box::new(sim_params));
        if let Some(port) = rc_in {
            server.set_rc_in(port);
        }
        let steps = server.run(None, &stop)?;
        (steps, radio_summary(&server), faults_summary(&server.stats()))
    } else {
        let port = instance_ports(args.instance)?.0;
        let listen = args.listen.clone().unwrap_or_else(|| format!("127.0.0.1:{port}"));
        let mut server =
            PlantServer::bind_udp(plant, listen.as_str(), link).with_context(|| format!("binding {listen}"))?;
        server.set_hook(Box::new(sim_params));
        if let Some(port) = rc_in {
            server.set_rc_in(port);
        }
        eprintln!(
            "sitl: plant listening on udp {listen}, running {}; SIM_ parameters on udp 127.0.0.1:{sim_port}; {}; \
             waiting for an autopilot",
            describe_pacing(pacing),
            describe_rc_in(rc_port)
        );
        let steps = server.run(None, &stop)?;
        (steps, radio_summary(&server), faults_summary(&server.stats()))
    };
    eprintln!("sitl: {steps} steps served");
    for line in [radio, faults].into_iter().flatten() {
        eprintln!("{line}");
    }
    Ok(())
}

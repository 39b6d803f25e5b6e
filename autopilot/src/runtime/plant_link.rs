//! The autopilot side of the plant protocol over UDP, and the one task that owns the [`Vehicle`]: plant
//! datagrams (`HIL_GPS`, `HIL_STATE_QUATERNION`, `HIL_SENSOR`) become [`VehicleInputs`]; each `HIL_SENSOR`
//! is a tick (its `time_usec` is the vehicle clock): `Vehicle::step`, then `HIL_ACTUATOR_CONTROLS` echoing
//! that time, and the step's telemetry to every ground station. Ground-station messages are fed to
//! `Vehicle::handle_message` at the current vehicle time, and the replies go back to their sender.
//!
//! No locks: the vehicle lives in this task only. Without sensor datagrams for [`PLANT_SILENCE`] of wall
//! time it warns once and keeps waiting (no plant, no ticks: the motors stay at their minimum).

use std::net::SocketAddr;
use std::time::Duration;

use mavlink::MavHeader;
use mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};
use tokio::net::UdpSocket;
use tokio::sync::mpsc;

use crate::core::estimator::{EstimatorSource, GeoOrigin};
use crate::core::hil::{
    ActuatorCommand, FrameDecoder, HilInput, SensorSamples, decode_hil_message, dege7_to_deg, encode_actuator_controls,
    encode_frame_v2, mm_to_m,
};
use crate::core::mavlink::own_header;
use crate::core::vehicle::{Vehicle, VehicleConfig, VehicleError, VehicleInputs};
use crate::runtime::frame;
use crate::runtime::link::{Destination, Incoming, Outgoing};
use crate::runtime::shutdown::Shutdown;

/// Wall time without a sensor datagram after which the link is reported lost (once).
pub const PLANT_SILENCE: Duration = Duration::from_secs(1);

/// Component id of the autopilot's messages to the plant.
const PLANT_LINK_COMPONENT_ID: u8 = 1;

/// Largest datagram read from the plant.
const MAX_DATAGRAM_BYTES: usize = 65_536;

/// Why the plant link task stopped.
#[derive(Debug, thiserror::Error)]
pub enum PlantLinkError {
    #[error("cannot open the plant link to {addr}: {source}")]
    Connect {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("plant link to {addr}: {source}")]
    Io {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Vehicle(#[from] VehicleError),
}

/// A raw frame for the `.tlog`, in or out.
pub type TlogFrame = Vec<u8>;

/// What the plant link task needs.
#[derive(Debug)]
pub struct PlantLinkConfig {
    /// The plant's UDP address (127.0.0.1:4560+N).
    pub plant: SocketAddr,
    /// The vehicle; with the `Truth` source its `truth_origin` is set from the first truth sample.
    pub vehicle: VehicleConfig,
}

/// Counts of one run, returned when the task stops.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlantLinkStats {
    /// Vehicle steps (HIL_SENSOR ticks).
    pub steps: u64,
    /// Ground-station messages handled.
    pub gcs_messages: u64,
    /// Frames not logged because the tlog task was behind.
    pub tlog_dropped: u64,
    /// First and last vehicle time seen (µs).
    pub first_time_us: Option<u64>,
    pub last_time_us: Option<u64>,
}

/// The plant link and the vehicle it drives.
struct Driver {
    config: VehicleConfig,
    vehicle: Option<Vehicle>,
    home: Option<GeoOrigin>,
    inputs: VehicleInputs,
    now_us: u64,
    sequence: u8,
    plant_sequence: u8,
    outgoing: mpsc::Sender<Outgoing>,
    tlog: Option<mpsc::Sender<TlogFrame>>,
    stats: PlantLinkStats,
}

impl Driver {
    fn header(&mut self) -> MavHeader {
        let mut header = own_header(self.config.sysid);
        header.sequence = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        header
    }

    fn plant_header(&mut self) -> MavHeader {
        let header = MavHeader {
            system_id: self.config.sysid.into(),
            component_id: PLANT_LINK_COMPONENT_ID,
            sequence: self.plant_sequence,
        };
        self.plant_sequence = self.plant_sequence.wrapping_add(1);
        header
    }

    fn log(&mut self, frame: TlogFrame) {
        if let Some(tlog) = &self.tlog
            && tlog.try_send(frame).is_err()
        {
            self.stats.tlog_dropped += 1;
        }
    }

    /// Queue a message to the ground stations; `false` once the ground-station link is gone.
    async fn send_gcs(&mut self, to: Destination, message: MavMessage) -> bool {
        let header = self.header();
        if self.tlog.is_some() {
            self.log(frame::encode_v2(header, &message));
        }
        self.outgoing.send(Outgoing { to, header, message }).await.is_ok()
    }

    /// The vehicle, built on first use (with the `Truth` source only once the truth origin is known).
    fn vehicle(&mut self) -> Result<Option<&mut Vehicle>, VehicleError> {
        if self.vehicle.is_none() {
            let mut config = self.config.clone();
            if config.estimator.source == EstimatorSource::Truth {
                let Some(home) = self.home else { return Ok(None) };
                config.estimator.truth_origin.get_or_insert(home);
            }
            self.vehicle = Some(Vehicle::new(config)?);
        }
        Ok(self.vehicle.as_mut())
    }

    /// One plant datagram; returns the actuator reply to send if it carried a `HIL_SENSOR`.
    async fn on_plant_frame(&mut self, message: &MavMessage) -> Result<Option<ActuatorCommand>, PlantLinkError> {
        if self.home.is_none()
            && let MavMessage::HIL_STATE_QUATERNION(m) = message
        {
            self.home = Some(GeoOrigin {
                lat_deg: dege7_to_deg(m.lat),
                lon_deg: dege7_to_deg(m.lon),
                alt_amsl_m: mm_to_m(m.alt),
            });
        }
        let home = self.home.unwrap_or(GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 });
        match decode_hil_message(message, &home) {
            Some(HilInput::Gps(gps)) => self.inputs.gps = Some(gps),
            Some(HilInput::Truth(truth)) if self.home.is_some() => self.inputs.truth = Some(truth),
            Some(HilInput::Sensor(fields)) => {
                let samples = SensorSamples::from(&fields);
                self.inputs.imu = Some(samples.imu);
                self.inputs.mag = samples.mag;
                self.inputs.baro = samples.baro;
                let now_us = fields.time_us;
                self.now_us = now_us;
                self.stats.first_time_us.get_or_insert(now_us);
                self.stats.last_time_us = Some(now_us);
                let inputs = std::mem::take(&mut self.inputs);
                let Some(vehicle) = self.vehicle()? else {
                    return Ok(Some(ActuatorCommand { time_us: now_us, pwm_us: [1000.0; 4], armed: false }));
                };
                let outputs = vehicle.step(now_us, &inputs);
                self.stats.steps += 1;
                for message in outputs.messages {
                    if !self.send_gcs(Destination::All, message).await {
                        break;
                    }
                }
                return Ok(Some(ActuatorCommand { time_us: now_us, pwm_us: outputs.pwm_us, armed: outputs.armed }));
            }
            _ => {}
        }
        Ok(None)
    }

    async fn on_gcs(&mut self, incoming: Incoming) -> Result<(), PlantLinkError> {
        self.stats.gcs_messages += 1;
        if self.tlog.is_some() {
            self.log(frame::encode(incoming.header, &incoming.message, incoming.version));
        }
        let now_us = self.now_us;
        let Some(vehicle) = self.vehicle()? else { return Ok(()) };
        let replies = vehicle.handle_message(now_us, &incoming.header, &incoming.message);
        for reply in replies {
            self.send_gcs(Destination::Peer(incoming.peer), reply).await;
        }
        Ok(())
    }
}

/// Run the plant link until shutdown (or until the ground-station link goes away).
///
/// # Errors
/// [`PlantLinkError::Connect`] if the socket cannot be opened, [`PlantLinkError::Io`] if sending to or
/// receiving from the plant fails other than by the plant being absent, [`PlantLinkError::Vehicle`] on an
/// unusable vehicle configuration.
pub async fn run(
    config: PlantLinkConfig,
    mut incoming: mpsc::Receiver<Incoming>,
    outgoing: mpsc::Sender<Outgoing>,
    tlog: Option<mpsc::Sender<TlogFrame>>,
    mut shutdown: Shutdown,
) -> Result<PlantLinkStats, PlantLinkError> {
    let addr = config.plant;
    // Validate the configuration before touching the network.
    Vehicle::new(config.vehicle.clone())?;
    let bind: SocketAddr = if addr.is_ipv4() { ([0, 0, 0, 0], 0).into() } else { ([0u16; 8], 0).into() };
    let socket = UdpSocket::bind(bind).await.map_err(|source| PlantLinkError::Connect { addr, source })?;
    socket.connect(addr).await.map_err(|source| PlantLinkError::Connect { addr, source })?;
    let mut driver = Driver {
        config: config.vehicle,
        vehicle: None,
        home: None,
        inputs: VehicleInputs::default(),
        now_us: 0,
        sequence: 0,
        plant_sequence: 0,
        outgoing,
        tlog,
        stats: PlantLinkStats::default(),
    };
    let announce = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_GENERIC,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_BOOT,
        mavlink_version: 3,
    });
    let mut decoder = FrameDecoder::new();
    let mut buf = vec![0u8; MAX_DATAGRAM_BYTES];
    let mut gcs_open = true;
    let mut warned_silent = false;
    let mut announced = false;
    let mut last_data = tokio::time::Instant::now();
    loop {
        if !warned_silent && last_data.elapsed() >= PLANT_SILENCE {
            tracing::warn!(plant = %addr, "no sensor data from the plant for 1 s; waiting");
            warned_silent = true;
        }
        if !announced {
            let header = driver.plant_header();
            match socket.send(&encode_frame_v2(header, &announce)).await {
                Ok(_) => announced = true,
                Err(e) if is_absent_peer(&e) => {}
                Err(source) => return Err(PlantLinkError::Io { addr, source }),
            }
        }
        tokio::select! {
            biased;
            () = shutdown.recv() => break,
            received = tokio::time::timeout(PLANT_SILENCE, socket.recv(&mut buf)) => {
                let len = match received {
                    Err(_elapsed) => {
                        // Re-announce, in case the plant started after us.
                        announced = false;
                        continue;
                    }
                    Ok(Err(e)) if is_absent_peer(&e) => {
                        // Nobody listening yet (ICMP port unreachable): wait and re-announce.
                        tokio::select! {
                            () = shutdown.recv() => break,
                            () = tokio::time::sleep(Duration::from_millis(100)) => {}
                        }
                        announced = false;
                        continue;
                    }
                    Ok(Err(source)) => return Err(PlantLinkError::Io { addr, source }),
                    Ok(Ok(len)) => len,
                };
                let mut reply = None;
                for decoded in decoder.decode_datagram(&buf[..len]) {
                    if let Some(cmd) = driver.on_plant_frame(&decoded.message).await? {
                        reply = Some(cmd);
                    }
                }
                if let Some(cmd) = reply {
                    last_data = tokio::time::Instant::now();
                    if warned_silent {
                        tracing::info!(plant = %addr, "plant data again");
                        warned_silent = false;
                    }
                    let header = driver.plant_header();
                    let msg = MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd));
                    match socket.send(&encode_frame_v2(header, &msg)).await {
                        Ok(_) => {}
                        Err(e) if is_absent_peer(&e) => {}
                        Err(source) => return Err(PlantLinkError::Io { addr, source }),
                    }
                }
                // Between ticks: everything the ground stations said meanwhile.
                while gcs_open {
                    match incoming.try_recv() {
                        Ok(msg) => driver.on_gcs(msg).await?,
                        Err(mpsc::error::TryRecvError::Empty) => break,
                        Err(mpsc::error::TryRecvError::Disconnected) => gcs_open = false,
                    }
                }
            }
            msg = incoming.recv(), if gcs_open => match msg {
                Some(msg) => driver.on_gcs(msg).await?,
                None => gcs_open = false,
            },
        }
    }
    Ok(driver.stats)
}

/// Whether a socket error only means nobody is listening at the plant address (yet).
fn is_absent_peer(e: &std::io::Error) -> bool {
    matches!(e.kind(), std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::ConnectionReset)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::core::hil::{HilSensorFields, decode_actuator_controls, encode_hil_sensor};
    use crate::runtime::shutdown;

    fn sensor_datagram(time_us: u64) -> Vec<u8> {
        let fields = HilSensorFields {
            time_us,
            accel_frd_mps2: Vector3::new(0.0, 0.0, -9.806_65),
            gyro_frd_radps: Vector3::zeros(),
            mag_frd_gauss: None,
            baro: None,
        };
        let header = MavHeader { system_id: 1, component_id: 51, sequence: 0 };
        encode_frame_v2(header, &MavMessage::HIL_SENSOR(encode_hil_sensor(&fields)))
    }

    #[tokio::test]
    async fn each_hil_sensor_is_answered_with_actuators_for_its_time_and_telemetry_goes_to_the_gcs() {
        let plant = UdpSocket::bind("127.0.0.1:0").await.expect("bind fake plant");
        let plant_addr = plant.local_addr().expect("addr");
        let (trigger, shutdown) = shutdown::channel();
        let (_in_tx, in_rx) = mpsc::channel(16);
        let (out_tx, mut out_rx) = mpsc::channel(1024);
        let config = PlantLinkConfig { plant: plant_addr, vehicle: VehicleConfig { sysid: 7, ..Default::default() } };
        let task = tokio::spawn(run(config, in_rx, out_tx, None, shutdown));
        let mut buf = vec![0u8; 2048];
        // The announcement.
        let (_, autopilot) = plant.recv_from(&mut buf).await.expect("announce");
        let mut decoder = FrameDecoder::new();
        for time_us in [0_u64, 2_000, 4_000] {
            plant.send_to(&sensor_datagram(time_us), autopilot).await.expect("send");
            let len = plant.recv(&mut buf).await.expect("reply");
            let frames = decoder.decode_datagram(&buf[..len]);
            let Some(MavMessage::HIL_ACTUATOR_CONTROLS(m)) = frames.first().map(|f| &f.message) else {
                panic!("expected HIL_ACTUATOR_CONTROLS, got {frames:?}");
            };
            let cmd = decode_actuator_controls(m);
            assert_eq!(cmd.time_us, time_us);
            assert!(!cmd.armed && cmd.pwm_us.iter().all(|&p| (p - 1000.0).abs() < 1e-9), "{cmd:?}");
        }
        let mut heartbeat = false;
        while let Ok(out) = out_rx.try_recv() {
            assert_eq!(out.to, Destination::All);
            assert_eq!(out.header.system_id, 7);
            heartbeat |= matches!(out.message, MavMessage::HEARTBEAT(_));
        }
        assert!(heartbeat, "the first step's HEARTBEAT reaches the ground-station link");
        trigger.fire();
        let stats = task.await.expect("join").expect("clean stop");
        assert_eq!(stats.steps, 3);
        assert_eq!((stats.first_time_us, stats.last_time_us), (Some(0), Some(4_000)));
    }
}

//! The autopilot's end of the plant protocol, and the one thread that owns the [`Vehicle`] (in its
//! [`VehicleHost`], which speaks to the ground stations through a [`GcsFanout`]). In: plant
//! frames (`HIL_GPS`, `HIL_STATE_QUATERNION`, `HIL_SENSOR`) over a blocking [`Transport`] (UDP to the SITL
//! plant, or serial to the real airframe's ARM board), and ground-station messages from the tokio links
//! on a channel. Each `HIL_SENSOR` is a tick (its `time_usec` is the vehicle clock): `Vehicle::step`, then
//! `HIL_ACTUATOR_CONTROLS` echoing that time, and the step's telemetry to every ground-station link.
//! Ground-station messages are handled between ticks at the current vehicle time; replies go back to
//! the link and peer they came from.
//!
//! Why a thread of its own rather than a tokio task: the lockstep round trip (plant sends, autopilot
//! answers, plant steps) is latency-bound, and a blocking `recv` on one socket is the shortest path from
//! the plant's datagram to the vehicle (one system call in, one out). The tokio links only see the
//! telemetry, which is 60-odd messages per simulated second.
//!
//! No locks: the vehicle lives in this thread only. Plant silence for [`PLANT_SILENCE`] of wall time is a
//! lost link: it is reported once (log and the critical STATUSTEXT [`PLANT_LOST_TEXT`] to every ground
//! station) and the motors are commanded to their minimum (1000 µs, disarmed) on the link, so a board that
//! still listens stops them; the vehicle clock stops with the plant's. As no step makes telemetry then,
//! the vehicle's fallback (`Vehicle::plant_lost_telemetry`: HEARTBEAT with `system_status` CRITICAL, or
//! EMERGENCY when armed, and SYS_STATUS with the sensors unhealthy) goes to every ground station at once
//! and every [`PLANT_LOST_TELEMETRY_INTERVAL`] of wall time while the loss lasts, so a ground station
//! keeps its link and sees why the vehicle is unusable; its messages are still handled at the last
//! vehicle time. When the plant speaks again on the same clock (it had paused) the vehicle carries on
//! where it was ([`PLANT_REGAINED_TEXT`]); when its clock went back (a new simulation) the vehicle is
//! rebuilt disarmed, its telemetry on the new timeline from the first step ([`PLANT_RESTARTED_TEXT`]).
//! Until the plant first speaks, and after each silence, the autopilot announces itself to the plant with
//! a HEARTBEAT every second, as the plant only answers peers that spoke (`docs/design.md`, the plant
//! protocol).
//!
//! The link counts the bytes it reads and writes (UDP or serial alike) and hands them, with its decoder's
//! malformed frames, to every step (`VehicleInputs::plant_link`): the vehicle judges the link's health
//! from them and from the sample times (`core::plant_link::health`: samples missing and late, the drop rate in
//! SYS_STATUS, the texts, the ULog's `plant_link_status`). The run's totals end in [`PlantLinkStats`].

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavSeverity, MavState, MavType,
};
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TryRecvError;

use crate::core::mavlink::frame::{DecoderStats, FrameDecoder, encode_frame_v2};
use crate::core::mavlink::statustext;
use crate::core::params::ParamStore;
use crate::core::plant_link::health::PlantLinkCounters;
use crate::core::plant_link::{ActuatorCommand, encode_actuator_controls};
use crate::core::vehicle::{MOTOR_PWM_MIN_US, Vehicle, VehicleConfig, VehicleError};
use crate::runtime::link::{Destination, Incoming};
use crate::runtime::transport::Transport;

// The vehicle's host and the ground-station fan-out were parts of this module; their names stay here.
pub use crate::runtime::gcs_fanout::{
    GCS_FLUSH_INTERVAL, GcsFanout, GcsOutputs, STATUSTEXT_BURST, STATUSTEXT_PER_S, TextLimiter, TlogFrame,
};
pub use crate::runtime::state::{FENCE_FILE, MISSION_FILE, PARAMS_FILE, Persisted, RALLY_FILE};
pub use crate::runtime::vehicle_host::VehicleHost;

/// Wall time without a sensor sample after which the plant link counts as lost.
pub const PLANT_SILENCE: Duration = Duration::from_secs(1);

/// Wall-clock interval of the fallback HEARTBEAT and SYS_STATUS while the plant link is lost (the 1 Hz
/// that the vehicle keeps on vehicle time when the plant steps it).
pub const PLANT_LOST_TELEMETRY_INTERVAL: Duration = Duration::from_secs(1);

/// Said once (severity CRITICAL) to every ground station when the plant link is lost.
pub const PLANT_LOST_TEXT: &str = "Plant link lost: motors stopped";
/// Said (severity NOTICE) when the plant speaks again on the same clock (it had paused).
pub const PLANT_REGAINED_TEXT: &str = "Plant link regained";
/// Said (severity CRITICAL) when the plant's clock goes back (a new simulation).
pub const PLANT_RESTARTED_TEXT: &str = "Plant restarted: vehicle restarted, disarmed";

/// Component id of the autopilot's messages to the plant.
const PLANT_LINK_COMPONENT_ID: u8 = 1;

/// Why the plant link stopped.
#[derive(Debug, thiserror::Error)]
pub enum PlantLinkError {
    #[error("cannot open the plant link {link}: {source}")]
    Open {
        link: String,
        #[source]
        source: std::io::Error,
    },
    #[error("plant link {link}: {source}")]
    Io {
        link: String,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Vehicle(#[from] VehicleError),
}

/// Counts of one run, returned when the link stops.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlantLinkStats {
    /// Vehicle steps (HIL_SENSOR ticks).
    pub steps: u64,
    /// Ground-station messages handled.
    pub gcs_messages: u64,
    /// Messages to a ground-station link dropped because its queue was full.
    pub gcs_dropped: u64,
    /// Frames not logged because the tlog writer was behind.
    pub tlog_dropped: u64,
    /// Times the plant went silent for [`PLANT_SILENCE`].
    pub plant_losses: u64,
    /// Times the plant's clock went back (a new simulation): the vehicle was rebuilt.
    pub plant_restarts: u64,
    /// The plant link's frame decoder: malformed frames and garbage bytes dropped.
    pub plant_decoder: DecoderStats,
    /// Bytes read from and written to the plant link (UDP datagrams or serial bytes).
    pub plant_rx_bytes: u64,
    pub plant_tx_bytes: u64,
    /// Plant samples missing (gaps in the sample times) and late (a time not after the last one), as
    /// the vehicles counted them (`core::plant_link::health`), over the whole run.
    pub plant_missing_samples: u64,
    pub plant_late_samples: u64,
    /// Broadcast STATUSTEXTs not sent: over [`STATUSTEXT_PER_S`] (see [`TextLimiter`]).
    pub statustext_suppressed: u64,
    /// Flights written to the onboard ULog.
    pub ulog_flights: u64,
    /// Batches of ULog records dropped because its writer was behind.
    pub ulog_dropped: u64,
    /// First and last vehicle time seen (µs).
    pub first_time_us: Option<u64>,
    pub last_time_us: Option<u64>,
}

/// The plant transport with the bytes it carries counted each way (UDP or serial alike).
struct CountedTransport<'a> {
    inner: &'a mut dyn Transport,
    rx_bytes: u64,
    tx_bytes: u64,
}

impl CountedTransport<'_> {
    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.inner.send(bytes)?;
        self.tx_bytes += bytes.len() as u64;
        Ok(())
    }

    fn recv(&mut self) -> std::io::Result<Option<&[u8]>> {
        let got = self.inner.recv()?;
        if let Some(bytes) = &got {
            self.rx_bytes += bytes.len() as u64;
        }
        Ok(got)
    }
}

/// The autopilot's frames to the plant: its own component and sequence.
struct PlantSender {
    sysid: u8,
    sequence: u8,
}

impl PlantSender {
    fn frame(&mut self, message: &MavMessage) -> Vec<u8> {
        let header =
            MavHeader { system_id: self.sysid.into(), component_id: PLANT_LINK_COMPONENT_ID, sequence: self.sequence };
        self.sequence = self.sequence.wrapping_add(1);
        encode_frame_v2(header, message)
    }
}

/// The HEARTBEAT the autopilot announces itself to the plant with.
fn announcement() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_BOOT,
        mavlink_version: 3,
    })
}

/// Runs the plant link on `transport` until `stop` is set or the ground-station side has gone (every
/// link's queue closed and the incoming channel closed). Blocking: run it on a thread of its own.
///
/// # Errors
/// [`PlantLinkError::Vehicle`] on an unusable vehicle configuration (checked before any I/O),
/// [`PlantLinkError::Io`] if the transport fails other than by the plant being absent.
pub fn run(
    transport: &mut dyn Transport,
    vehicle: VehicleConfig,
    persisted: Persisted,
    mut incoming: mpsc::Receiver<Incoming>,
    out: GcsOutputs,
    stop: &AtomicBool,
) -> Result<PlantLinkStats, PlantLinkError> {
    let params = persisted.params.clone().unwrap_or_else(|| ParamStore::from_config(&vehicle));
    Vehicle::with_params(vehicle.clone(), params)?;
    let link = transport.describe();
    let io = |source| PlantLinkError::Io { link: link.clone(), source };
    let mut plant = PlantSender { sysid: vehicle.sysid, sequence: 0 };
    let mut host = VehicleHost::new(vehicle.clone(), persisted, GcsFanout::new(vehicle.sysid, out));
    let mut decoder = FrameDecoder::new();
    let datagrams = transport.is_datagram();
    let mut transport = CountedTransport { inner: transport, rx_bytes: 0, tx_bytes: 0 };
    let mut last_sensor: Option<Instant> = None;
    let mut last_announce: Option<Instant> = None;
    let mut last_fallback: Option<Instant> = None;
    let mut lost = false;
    let mut gcs_open = true;
    let started = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        let silent_for = now - last_sensor.unwrap_or(started);
        if silent_for >= PLANT_SILENCE && !lost {
            lost = true;
            if last_sensor.is_some() {
                host.stats.plant_losses += 1;
                tracing::warn!(
                    plant = %link,
                    "plant link lost: no sensor data for 1 s; motors to minimum, HEARTBEAT on the wall clock"
                );
                let text = statustext(MavSeverity::MAV_SEVERITY_CRITICAL, PLANT_LOST_TEXT);
                host.send_gcs(None, Destination::All, text);
                let stopped = ActuatorCommand {
                    time_us: host.now_us,
                    pwm_us: [MOTOR_PWM_MIN_US; 4],
                    armed: false,
                    motor_test: false,
                };
                let frame = plant.frame(&MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&stopped)));
                transport.send(&frame).map_err(io)?;
            } else {
                tracing::warn!(plant = %link, "no sensor data from the plant yet; waiting");
            }
        }
        // While the plant is lost no step makes telemetry: the vehicle's fallback, on the wall clock.
        if lost && last_sensor.is_some() && last_fallback.is_none_or(|t| now - t >= PLANT_LOST_TELEMETRY_INTERVAL) {
            host.plant_lost_telemetry(decoder.stats().malformed())?;
            last_fallback = Some(now);
        }
        if last_sensor.is_none_or(|_| lost) && last_announce.is_none_or(|t| now - t >= PLANT_SILENCE) {
            let frame = plant.frame(&announcement());
            transport.send(&frame).map_err(io)?;
            last_announce = Some(now);
        }
        if let Some(bytes) = transport.recv().map_err(io)? {
            let frames = if datagrams { decoder.decode_datagram(bytes) } else { decoder.push(bytes) };
            let mut reply = None;
            let counters = PlantLinkCounters {
                rx_bytes: transport.rx_bytes,
                tx_bytes: transport.tx_bytes,
                bad_frames: decoder.stats().malformed(),
            };
            let restarts = host.stats.plant_restarts;
            for decoded in frames {
                if let Some(cmd) = host.on_plant_frame(&decoded.message, counters)? {
                    reply = Some(cmd);
                }
            }
            if let Some(reply) = reply {
                let mut frame = Vec::new();
                for message in &reply.before {
                    frame.extend(plant.frame(message));
                }
                frame.extend(
                    plant.frame(&MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&reply.actuators))),
                );
                transport.send(&frame).map_err(io)?;
                last_sensor = Some(Instant::now());
                if lost {
                    lost = false;
                    last_fallback = None;
                    tracing::info!(plant = %link, "plant data again");
                    // A plant that restarted has been announced as such; one that paused is regained.
                    if host.stats.plant_losses > 0 && host.stats.plant_restarts == restarts {
                        let text = statustext(MavSeverity::MAV_SEVERITY_NOTICE, PLANT_REGAINED_TEXT);
                        host.send_gcs(None, Destination::All, text);
                    }
                }
            }
        }
        // Between ticks: everything the ground stations said meanwhile.
        while gcs_open {
            match incoming.try_recv() {
                Ok(msg) => host.on_gcs(msg)?,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => gcs_open = false,
            }
        }
        host.gcs.flush(Instant::now(), lost);
        if !gcs_open && host.gcs.links_closed() {
            tracing::info!("every ground-station link has stopped; plant link stopping");
            break;
        }
    }
    host.gcs.flush(Instant::now(), true);
    host.gcs.out.flight_log.close();
    let ulog = host.gcs.out.flight_log.stats();
    host.stats.ulog_flights = ulog.flights;
    host.stats.ulog_dropped = ulog.dropped;
    host.stats.plant_decoder = decoder.stats();
    host.stats.plant_rx_bytes = transport.rx_bytes;
    host.stats.plant_tx_bytes = transport.tx_bytes;
    let lost = host.gcs.stats;
    host.stats.gcs_dropped = lost.gcs_dropped;
    host.stats.tlog_dropped = lost.tlog_dropped;
    host.stats.statustext_suppressed = lost.statustext_suppressed;
    Ok(host.stats)
}

#[cfg(test)]
mod tests {
    use std::net::UdpSocket;
    use std::sync::Arc;

    use nalgebra::Vector3;

    use super::*;
    use crate::core::plant_link::{HilSensorFields, decode_actuator_controls, encode_hil_sensor};
    use crate::runtime::link::Outgoing;
    use crate::runtime::transport::UdpPeerTransport;

    fn sensor_frame(time_us: u64) -> Vec<u8> {
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

    struct Harness {
        plant: UdpSocket,
        out_rx: mpsc::Receiver<Outgoing>,
        in_tx: mpsc::Sender<Incoming>,
        stop: Arc<AtomicBool>,
        thread: std::thread::JoinHandle<Result<PlantLinkStats, PlantLinkError>>,
    }

    fn start(sysid: u8) -> Harness {
        let plant = UdpSocket::bind("127.0.0.1:0").expect("bind fake plant");
        plant.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
        let plant_addr = plant.local_addr().expect("addr");
        let stop = Arc::new(AtomicBool::new(false));
        let (in_tx, in_rx) = mpsc::channel(16);
        let (out_tx, out_rx) = mpsc::channel(4096);
        let thread_stop = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut transport = UdpPeerTransport::connect(plant_addr, Duration::from_millis(5)).expect("connect");
            let config = VehicleConfig { sysid, ..VehicleConfig::default() };
            let out = GcsOutputs { links: vec![out_tx], ..GcsOutputs::default() };
            run(&mut transport, config, Persisted::default(), in_rx, out, &thread_stop)
        });
        Harness { plant, out_rx, in_tx, stop, thread }
    }

    #[test]
    fn each_hil_sensor_is_answered_for_its_time_garbage_is_counted_and_telemetry_goes_out() {
        let mut h = start(7);
        let mut buf = vec![0u8; 2048];
        // The announcement.
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        for time_us in [0_u64, 2_000, 4_000] {
            if time_us == 2_000 {
                // A truncated frame and line noise ahead of a good one, in one datagram.
                let mut datagram = b"\xfd\x09\x00\x00junk".to_vec();
                datagram.extend(sensor_frame(time_us));
                h.plant.send_to(&datagram, autopilot).expect("send");
            } else {
                h.plant.send_to(&sensor_frame(time_us), autopilot).expect("send");
            }
            let cmd = loop {
                let len = h.plant.recv(&mut buf).expect("reply");
                let frames = decoder.decode_datagram(&buf[..len]);
                if let Some(MavMessage::HIL_ACTUATOR_CONTROLS(m)) = frames.first().map(|f| &f.message) {
                    break decode_actuator_controls(m);
                }
            };
            assert_eq!(cmd.time_us, time_us);
            assert!(!cmd.armed && cmd.pwm_us.iter().all(|&p| (p - 1000.0).abs() < 1e-9), "{cmd:?}");
        }
        h.stop.store(true, Ordering::Relaxed);
        let stats = h.thread.join().expect("join").expect("clean stop");
        let mut heartbeat = false;
        while let Ok(out) = h.out_rx.try_recv() {
            assert_eq!(out.to, Destination::All);
            assert_eq!(out.header.system_id, 7);
            heartbeat |= matches!(out.message, MavMessage::HEARTBEAT(_));
        }
        assert!(heartbeat, "the first step's HEARTBEAT reaches the ground-station link");
        assert_eq!(stats.steps, 3);
        assert_eq!((stats.first_time_us, stats.last_time_us), (Some(0), Some(4_000)));
        assert!(stats.plant_decoder.malformed() >= 1, "{stats:?}");
    }

    #[test]
    fn the_link_counts_its_bytes_each_way_and_the_vehicle_its_samples_missing_and_late_and_says_so() {
        let mut h = start(5);
        let mut buf = vec![0u8; 2048];
        let (len, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut received = len as u64;
        let mut sent = 0_u64;
        let mut decoder = FrameDecoder::new();
        // GIVEN samples at 0, 2, 4 ms, then 10 ms (two missing), then 10 ms again (a resend: late).
        for time_us in [0_u64, 2_000, 4_000, 10_000, 10_000] {
            let frame = sensor_frame(time_us);
            sent += frame.len() as u64;
            h.plant.send_to(&frame, autopilot).expect("send");
            loop {
                let len = h.plant.recv(&mut buf).expect("reply");
                received += len as u64;
                let answered = decoder
                    .decode_datagram(&buf[..len])
                    .into_iter()
                    .any(|f| matches!(f.message, MavMessage::HIL_ACTUATOR_CONTROLS(m) if m.time_usec == time_us));
                if answered {
                    break;
                }
            }
        }
        h.stop.store(true, Ordering::Relaxed);
        let stats = h.thread.join().expect("join").expect("clean stop");
        // Whatever else the autopilot wrote meanwhile (a repeated announcement) counts too.
        h.plant.set_read_timeout(Some(Duration::from_millis(50))).expect("timeout");
        while let Ok(len) = h.plant.recv(&mut buf) {
            received += len as u64;
        }
        // THEN the link counted every byte each way, and the vehicle two samples missing and one late,
        // and warned of the missing ones with the counts of its window (6 sample slots so far).
        assert_eq!((stats.plant_rx_bytes, stats.plant_tx_bytes), (sent, received), "{stats:?}");
        assert_eq!((stats.plant_missing_samples, stats.plant_late_samples), (2, 1), "{stats:?}");
        let said = texts(&drain(&mut h.out_rx));
        assert!(
            said.contains(&(MavSeverity::MAV_SEVERITY_WARNING, "Plant link: 2 of 6 samples missing".to_owned())),
            "{said:?}"
        );
    }

    #[test]
    fn a_plant_whose_clock_restarts_gets_a_restarted_disarmed_vehicle_whose_heartbeat_resumes_at_once() {
        let mut h = start(3);
        let mut buf = vec![0u8; 2048];
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        let mut step = |h: &mut Harness, time_us: u64| loop {
            h.plant.send_to(&sensor_frame(time_us), autopilot).expect("send");
            let len = h.plant.recv(&mut buf).expect("reply");
            let frames = decoder.decode_datagram(&buf[..len]);
            if let Some(MavMessage::HIL_ACTUATOR_CONTROLS(m)) = frames.first().map(|f| &f.message) {
                break decode_actuator_controls(m);
            }
        };
        // GIVEN a simulation 3 s in.
        for k in 0..1500_u64 {
            step(&mut h, k * 2_000);
        }
        while h.out_rx.try_recv().is_ok() {}
        // WHEN the plant starts a new simulation (its clock back at 0).
        let cmd = step(&mut h, 0);
        // THEN the step is answered, the vehicle says it restarted and its HEARTBEAT comes at once.
        assert_eq!(cmd.time_us, 0);
        assert!(!cmd.armed);
        // (Telemetry is batched: stopping the link flushes it.)
        h.stop.store(true, Ordering::Relaxed);
        h.thread.join().expect("join").expect("clean stop");
        let messages: Vec<MavMessage> = std::iter::from_fn(|| h.out_rx.try_recv().ok()).map(|o| o.message).collect();
        let restart = messages.iter().position(|m| {
            matches!(m, MavMessage::STATUSTEXT(s)
                if s.text.to_str().is_ok_and(|t| t == PLANT_RESTARTED_TEXT))
        });
        let restart = restart.expect("the restart is announced");
        let heartbeat = messages[restart..]
            .iter()
            .any(|m| matches!(m, MavMessage::HEARTBEAT(hb) if !hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)));
        assert!(heartbeat, "a HEARTBEAT on the new timeline's first step");
    }

    /// Sends the plant's HIL_SENSOR at `time_us` and returns the autopilot's answer to it, skipping what
    /// else the plant hears (announcements, a stop command).
    fn step(h: &Harness, autopilot: std::net::SocketAddr, decoder: &mut FrameDecoder, time_us: u64) -> ActuatorCommand {
        h.plant.send_to(&sensor_frame(time_us), autopilot).expect("send");
        let mut buf = vec![0u8; 2048];
        loop {
            let len = h.plant.recv(&mut buf).expect("reply");
            for f in decoder.decode_datagram(&buf[..len]) {
                if let MavMessage::HIL_ACTUATOR_CONTROLS(m) = f.message {
                    let cmd = decode_actuator_controls(&m);
                    if cmd.time_us == time_us {
                        return cmd;
                    }
                }
            }
        }
    }

    /// The ground-station messages handed over so far.
    fn drain(out_rx: &mut mpsc::Receiver<Outgoing>) -> Vec<MavMessage> {
        std::iter::from_fn(|| out_rx.try_recv().ok()).map(|o| o.message).collect()
    }

    /// The ground-station messages until `done` holds of them; `None` after `wall_limit` (a hung test
    /// fails, no speed is asserted).
    fn collect_until(
        h: &mut Harness,
        wall_limit: Duration,
        done: impl Fn(&[MavMessage]) -> bool,
    ) -> Option<Vec<MavMessage>> {
        let deadline = Instant::now() + wall_limit;
        let mut seen = Vec::new();
        while Instant::now() < deadline {
            seen.extend(drain(&mut h.out_rx));
            if done(&seen) {
                return Some(seen);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }

    fn texts(messages: &[MavMessage]) -> Vec<(MavSeverity, String)> {
        messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::STATUSTEXT(s) => Some((s.severity, s.text.to_str().unwrap_or("").to_owned())),
                _ => None,
            })
            .collect()
    }

    fn position_of_text(messages: &[MavMessage], text: &str) -> Option<usize> {
        messages.iter().position(|m| matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str() == Ok(text)))
    }

    fn system_statuses(messages: &[MavMessage]) -> Vec<MavState> {
        messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::HEARTBEAT(hb) => Some(hb.system_status),
                _ => None,
            })
            .collect()
    }

    /// The fallback HEARTBEATs (CRITICAL: the vehicle is disarmed) among `messages`.
    fn fallback_heartbeats(messages: &[MavMessage]) -> usize {
        system_statuses(messages).into_iter().filter(|s| *s == MavState::MAV_STATE_CRITICAL).count()
    }

    #[test]
    fn a_silent_plant_is_reported_motors_stopped_and_the_heartbeat_kept_on_the_wall_clock_until_it_resumes() {
        use mavlink::dialects::common::{MavCmd, MavResult, MavSysStatusSensor as S};
        let mut h = start(1);
        let mut buf = vec![0u8; 2048];
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        assert_eq!(step(&h, autopilot, &mut decoder, 0).time_us, 0);
        let started = Instant::now();
        // WHEN the plant falls silent THEN (after a second of it) the motors are commanded to minimum.
        let stop_cmd = loop {
            let len = h.plant.recv(&mut buf).expect("the stop command");
            let stop = decoder.decode_datagram(&buf[..len]).into_iter().find_map(|f| match f.message {
                MavMessage::HIL_ACTUATOR_CONTROLS(m) => Some(decode_actuator_controls(&m)),
                _ => None,
            });
            if let Some(stop) = stop {
                break stop;
            }
        };
        let after = started.elapsed();
        assert!(after >= PLANT_SILENCE, "reported after {after:?}");
        assert!(!stop_cmd.armed && stop_cmd.pwm_us == [MOTOR_PWM_MIN_US; 4], "{stop_cmd:?}");
        // THEN the ground stations are told once, and keep getting the vehicle's HEARTBEAT, CRITICAL, with
        // a SYS_STATUS whose sensors are unhealthy, every second of wall time.
        let lost = collect_until(&mut h, Duration::from_secs(10), |m| fallback_heartbeats(m) >= 3)
            .expect("three fallback HEARTBEATs");
        let from = position_of_text(&lost, PLANT_LOST_TEXT).expect("the loss is said");
        let said: Vec<_> = texts(&lost).into_iter().filter(|(_, t)| t.starts_with("Plant")).collect();
        assert_eq!(said, [(MavSeverity::MAV_SEVERITY_CRITICAL, PLANT_LOST_TEXT.to_owned())]);
        let statuses = system_statuses(&lost[from..]);
        assert!(statuses.len() >= 3 && statuses.iter().all(|s| *s == MavState::MAV_STATE_CRITICAL), "{statuses:?}");
        let sys_status: Vec<_> = lost[from..]
            .iter()
            .filter_map(|m| match m {
                MavMessage::SYS_STATUS(s) => Some(s),
                _ => None,
            })
            .collect();
        assert!(sys_status.len() >= 2, "{sys_status:?}");
        let imu = S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL;
        assert!(sys_status.iter().all(|s| s.onboard_control_sensors_present.contains(imu)
            && !s.onboard_control_sensors_health.intersects(imu | S::MAV_SYS_STATUS_PREARM_CHECK)));
        // THEN a ground-station command is still answered meanwhile (at the last vehicle time).
        let request = crate::core::mavlink::command_long(
            1,
            1,
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let peer = "127.0.0.1:14550".parse().expect("addr");
        let incoming = Incoming { link: 0, peer, header, message: request, version: mavlink::MavlinkVersion::V2 };
        h.in_tx.try_send(incoming).expect("queued");
        let answered = collect_until(&mut h, Duration::from_secs(10), |m| {
            m.iter().any(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)))
        });
        let answered = answered.expect("the command is answered while the plant is lost");
        let accepted =
            |m: &MavMessage| matches!(m, MavMessage::COMMAND_ACK(a) if a.result == MavResult::MAV_RESULT_ACCEPTED);
        assert!(answered.iter().any(accepted), "{answered:?}");
        // WHEN the plant resumes on its clock (it had paused) for a second of vehicle time THEN regained,
        // no restart, and the vehicle's own HEARTBEAT (STANDBY) again.
        for k in 1..=500_u64 {
            step(&h, autopilot, &mut decoder, k * 2_000);
        }
        h.stop.store(true, Ordering::Relaxed);
        let stats = h.thread.join().expect("join").expect("clean stop");
        let resumed = drain(&mut h.out_rx);
        let regained = position_of_text(&resumed, PLANT_REGAINED_TEXT).expect("regained");
        assert_eq!(position_of_text(&resumed, PLANT_RESTARTED_TEXT), None);
        assert_eq!(system_statuses(&resumed[regained..]).first(), Some(&MavState::MAV_STATE_STANDBY));
        assert_eq!((stats.plant_losses, stats.plant_restarts), (1, 0));
        assert_eq!(stats.last_time_us, Some(1_000_000));
    }

    #[test]
    fn a_motor_test_reaches_the_plant_as_test_enabled_not_armed_with_only_its_motor_moved_until_its_timeout() {
        let h = start(2);
        let mut buf = vec![0u8; 2048];
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        for k in 0..10_u64 {
            step(&h, autopilot, &mut decoder, k * 2_000);
        }
        // WHEN a ground station tests motor 3 at 20 % for 0.2 s.
        let test = crate::core::mavlink::command_long(
            2,
            1,
            crate::core::mavlink::common::MavCmd::MAV_CMD_DO_MOTOR_TEST,
            [3.0, 0.0, 20.0, 0.2, 0.0, 0.0, 0.0],
        );
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let peer = "127.0.0.1:14550".parse().expect("addr");
        let incoming = Incoming { link: 0, peer, header, message: test, version: mavlink::MavlinkVersion::V2 };
        h.in_tx.try_send(incoming).expect("queued");
        // THEN the plant is sent output 3 at 1200 µs flagged TEST_ENABLED (not armed), for 0.2 s of its
        // time (100 steps, one more at most for when the command landed), then 1000 µs unflagged again.
        let commands: Vec<ActuatorCommand> =
            (10..400_u64).map(|k| step(&h, autopilot, &mut decoder, k * 2_000)).collect();
        h.stop.store(true, Ordering::Relaxed);
        h.thread.join().expect("join").expect("clean stop");
        let tested: Vec<&ActuatorCommand> = commands.iter().filter(|c| c.motor_test).collect();
        assert!((100..=101).contains(&tested.len()), "{} steps tested", tested.len());
        for c in &tested {
            assert!(!c.armed && c.motors_running(), "{c:?}");
            assert!((c.pwm_us[2] - 1200.0).abs() < 0.1 && [0, 1, 3].iter().all(|&i| c.pwm_us[i] == 1000.0), "{c:?}");
        }
        let last = commands.last().expect("stepped");
        assert!(!last.motors_running() && last.effective_pwm_us() == [MOTOR_PWM_MIN_US; 4], "{last:?}");
    }

    #[test]
    fn an_injected_failure_goes_to_the_plant_ahead_of_the_actuators_and_the_plants_ack_reaches_the_ground_station() {
        use crate::core::mavlink::common::{COMMAND_ACK_DATA, MavCmd, MavParamType, MavResult, PARAM_SET_DATA};
        let mut h = start(4);
        let mut buf = vec![0u8; 2048];
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        for k in 0..5_u64 {
            step(&h, autopilot, &mut decoder, k * 2_000);
        }
        // GIVEN SYS_FAILURE_EN = 1; WHEN a ground station injects "GPS off".
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let peer = "127.0.0.1:14550".parse().expect("addr");
        let send = |message: MavMessage| {
            let incoming = Incoming { link: 0, peer, header, message, version: mavlink::MavlinkVersion::V2 };
            h.in_tx.try_send(incoming).expect("queued");
        };
        send(MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: f32::from_bits(1),
            target_system: 4,
            target_component: 1,
            param_id: "SYS_FAILURE_EN".into(),
            param_type: MavParamType::MAV_PARAM_TYPE_INT32,
        }));
        send(crate::core::mavlink::command_long(
            4,
            1,
            MavCmd::MAV_CMD_INJECT_FAILURE,
            [4.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ));
        // THEN a following reply carries the COMMAND_LONG first and the actuators last, in one datagram.
        let mut forwarded = None;
        for k in 5..100_u64 {
            h.plant.send_to(&sensor_frame(k * 2_000), autopilot).expect("send");
            let len = h.plant.recv(&mut buf).expect("reply");
            let frames: Vec<MavMessage> = decoder.decode_datagram(&buf[..len]).into_iter().map(|f| f.message).collect();
            assert!(matches!(frames.last(), Some(MavMessage::HIL_ACTUATOR_CONTROLS(_))), "{frames:?}");
            if let [MavMessage::COMMAND_LONG(c), MavMessage::HIL_ACTUATOR_CONTROLS(_)] = frames.as_slice() {
                forwarded = Some((k, c.command, c.param1, c.param2, c.param3));
                break;
            }
        }
        let (k, command, unit, kind, instance) = forwarded.expect("forwarded within 95 steps");
        assert_eq!((command, unit, kind, instance), (MavCmd::MAV_CMD_INJECT_FAILURE, 4.0, 1.0, 0.0));
        // WHEN the plant answers ACCEPTED ahead of its next sensor sample; THEN the ground station gets it.
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_INJECT_FAILURE,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..Default::default()
        });
        let mut datagram = encode_frame_v2(MavHeader { system_id: 1, component_id: 51, sequence: 0 }, &ack);
        datagram.extend(sensor_frame((k + 1) * 2_000));
        h.plant.send_to(&datagram, autopilot).expect("send");
        h.plant.recv(&mut buf).expect("reply");
        h.stop.store(true, Ordering::Relaxed);
        h.thread.join().expect("join").expect("clean stop");
        let acks: Vec<(MavResult, u8, u8)> = std::iter::from_fn(|| h.out_rx.try_recv().ok())
            .filter_map(|out| match out.message {
                MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_INJECT_FAILURE => {
                    Some((a.result, a.target_system, a.target_component))
                }
                _ => None,
            })
            .collect();
        assert_eq!(acks, [(MavResult::MAV_RESULT_ACCEPTED, 255, 190)]);
    }

    #[test]
    fn a_plant_killed_and_restarted_gets_the_fallback_meanwhile_and_a_heartbeat_within_1_s_of_its_new_clock() {
        let mut h = start(4);
        let mut buf = vec![0u8; 2048];
        let (_, autopilot) = h.plant.recv_from(&mut buf).expect("announce");
        let mut decoder = FrameDecoder::new();
        // GIVEN a simulation 3 s in.
        for k in 0..1500_u64 {
            step(&h, autopilot, &mut decoder, k * 2_000);
        }
        // WHEN the plant is killed THEN the fallback HEARTBEAT (CRITICAL) keeps coming.
        let lost = collect_until(&mut h, Duration::from_secs(10), |m| fallback_heartbeats(m) >= 2)
            .expect("two fallback HEARTBEATs");
        assert!(position_of_text(&lost, PLANT_LOST_TEXT).is_some());
        // WHEN a new simulation starts (its clock at 0) and runs 1.2 s.
        for k in 0..600_u64 {
            let cmd = step(&h, autopilot, &mut decoder, k * 2_000);
            assert!(!cmd.armed);
        }
        h.stop.store(true, Ordering::Relaxed);
        let stats = h.thread.join().expect("join").expect("clean stop");
        let messages = drain(&mut h.out_rx);
        // THEN the restart is said (not "regained"), the telemetry is on the new clock from its first step,
        // and the first HEARTBEAT comes within 1 s of it: disarmed, STANDBY, no more fallback.
        let restart = position_of_text(&messages, PLANT_RESTARTED_TEXT).expect("the restart is said");
        assert_eq!(position_of_text(&messages, PLANT_REGAINED_TEXT), None);
        let after = &messages[restart..];
        let attitude_ms = |m: &MavMessage| match m {
            MavMessage::ATTITUDE(a) => Some(a.time_boot_ms),
            _ => None,
        };
        assert_eq!(after.iter().find_map(attitude_ms), Some(0), "telemetry on the new clock from its first step");
        let heartbeat = after.iter().position(|m| matches!(m, MavMessage::HEARTBEAT(_))).expect("a HEARTBEAT");
        // Sent no later than the next time-stamped message.
        let heartbeat_by_ms = after[heartbeat..].iter().find_map(attitude_ms).expect("ATTITUDE after it");
        assert!(heartbeat_by_ms < 1_000, "first HEARTBEAT by {heartbeat_by_ms} ms of the new clock");
        let MavMessage::HEARTBEAT(hb) = &after[heartbeat] else { unreachable!() };
        assert!(!hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        assert_eq!(hb.system_status, MavState::MAV_STATE_STANDBY);
        assert!(system_statuses(after).iter().all(|s| *s == MavState::MAV_STATE_STANDBY), "no fallback after it");
        assert_eq!((stats.plant_losses, stats.plant_restarts), (1, 1));
    }
}

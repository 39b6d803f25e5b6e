//! The autopilot's end of the plant protocol, and the one thread that owns the [`Vehicle`]. In: plant
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

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavSeverity, MavState, MavType,
};
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::{TryRecvError, TrySendError};

use crate::core::estimator::{EstimatorSource, GeoOrigin};
use crate::core::geofence::{Fence, Rally};
use crate::core::hil::{
    ActuatorCommand, DecoderStats, FrameDecoder, HilInput, SensorSamples, decode_hil_message, dege7_to_deg,
    encode_actuator_controls, encode_frame_v2, mm_to_m,
};
use crate::core::mavlink::{LinkErrors, own_header, statustext};
use crate::core::mission::Mission;
use crate::core::params::ParamStore;
use crate::core::vehicle::{PWM_MIN_US, ShellEffect, Vehicle, VehicleConfig, VehicleError, VehicleInputs};
use crate::runtime::flight_log::FlightLogger;
use crate::runtime::frame::{self, LinkCounters};
use crate::runtime::link::{Destination, Incoming, LinkId, Outgoing};
use crate::runtime::persist::Persister;
use crate::runtime::signing::LinkSigning;
use crate::runtime::transport::Transport;

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

/// Wall time the step's telemetry may wait before it is handed to the ground-station links. Handing each
/// message over on its own wakes the tokio thread every time, which in lockstep (about 5000 messages per
/// wall second at 70x) cost 8 µs per step, a quarter of the round trip; in bursts it costs one wake-up.
/// Replies to a ground station are handed over at once.
pub const GCS_FLUSH_INTERVAL: Duration = Duration::from_millis(2);

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

/// A raw frame for the `.tlog`, in or out.
pub type TlogFrame = Vec<u8>;

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

/// What an earlier run left in the state directory, and where to save: the parameters (applied over the
/// configuration when the vehicle is built) and the mission.
#[derive(Debug, Default)]
pub struct Persisted {
    pub params: Option<ParamStore>,
    pub mission: Option<Mission>,
    pub fence: Option<Fence>,
    pub rally: Option<Rally>,
    /// Where parameter and mission changes are saved; `None`: not saved.
    pub persister: Option<Persister>,
}

/// The parameter file in the state directory.
pub const PARAMS_FILE: &str = "params.txt";
/// The mission file in the state directory (QGC WPL 110).
pub const MISSION_FILE: &str = "mission.waypoints";
/// The geofence file in the state directory (QGC WPL 110, fence commands).
pub const FENCE_FILE: &str = "fence.waypoints";
/// The rally-point file in the state directory (QGC WPL 110, NAV_RALLY_POINT).
pub const RALLY_FILE: &str = "rally.waypoints";

/// The senders towards each ground-station link (index = [`LinkId`]) and the `.tlog`, and the links'
/// counters (their malformed frames are reported in SYS_STATUS).
#[derive(Debug, Default)]
pub struct GcsOutputs {
    pub links: Vec<mpsc::Sender<Outgoing>>,
    pub tlog: Option<mpsc::Sender<TlogFrame>>,
    pub counters: Vec<Arc<LinkCounters>>,
    /// The links' shared MAVLink signing (SETUP_SIGNING is applied here).
    pub signing: Arc<LinkSigning>,
    /// Per link (index = [`LinkId`]): whether it may carry SETUP_SIGNING (TCP, serial).
    pub secure: Vec<bool>,
    /// The onboard ULog's sampler (off by default).
    pub flight_log: FlightLogger,
}

/// The plant link and the vehicle it drives.
struct Driver {
    config: VehicleConfig,
    vehicle: Option<Vehicle>,
    home: Option<GeoOrigin>,
    /// Whether `home` is the plant's origin (from the configuration, or moved there by the first
    /// ODOMETRY) rather than the vehicle's first position.
    home_is_plant_origin: bool,
    inputs: VehicleInputs,
    now_us: u64,
    sequence: u8,
    plant_sequence: u8,
    out: GcsOutputs,
    /// Messages waiting for the next flush: (only this link, message).
    pending: Vec<(Option<LinkId>, Outgoing)>,
    /// A reply is pending: flush at once.
    urgent: bool,
    last_flush: Instant,
    persisted: Persisted,
    stats: PlantLinkStats,
    texts: TextLimiter,
}

/// Broadcast STATUSTEXTs allowed per second of vehicle time, on average.
pub const STATUSTEXT_PER_S: f64 = 10.0;
/// How many may come at once above that rate.
pub const STATUSTEXT_BURST: f64 = 20.0;

/// A token bucket on vehicle time for the STATUSTEXTs the vehicle broadcasts, so that something that
/// repeats itself (a bad stream, a flapping condition) cannot flood the ground stations. Replies to one
/// peer (a refusal's reason) are not limited; the chunks of a long text follow their first.
#[derive(Debug, Clone, PartialEq)]
pub struct TextLimiter {
    tokens: f64,
    last_us: Option<u64>,
    last_allowed: bool,
}

impl Default for TextLimiter {
    fn default() -> Self {
        Self { tokens: STATUSTEXT_BURST, last_us: None, last_allowed: true }
    }
}

impl TextLimiter {
    /// Whether a STATUSTEXT at `now_us` may go out (`continuation`: a later chunk of a chunked text).
    pub fn allow(&mut self, now_us: u64, continuation: bool) -> bool {
        let elapsed_s = match self.last_us {
            Some(t) if now_us >= t => (now_us - t) as f64 * 1e-6,
            // A new timeline (the plant restarted): start full.
            Some(_) => STATUSTEXT_BURST,
            None => 0.0,
        };
        self.last_us = Some(now_us);
        self.tokens = (self.tokens + elapsed_s * STATUSTEXT_PER_S).min(STATUSTEXT_BURST);
        if continuation {
            return self.last_allowed;
        }
        self.last_allowed = self.tokens >= 1.0;
        if self.last_allowed {
            self.tokens -= 1.0;
        }
        self.last_allowed
    }
}

impl Driver {
    fn header(&mut self) -> MavHeader {
        let mut header = own_header(self.config.sysid);
        header.sequence = self.sequence;
        self.sequence = self.sequence.wrapping_add(1);
        header
    }

    fn plant_frame(&mut self, message: &MavMessage) -> Vec<u8> {
        let header = MavHeader {
            system_id: self.config.sysid.into(),
            component_id: PLANT_LINK_COMPONENT_ID,
            sequence: self.plant_sequence,
        };
        self.plant_sequence = self.plant_sequence.wrapping_add(1);
        encode_frame_v2(header, message)
    }

    fn log(&mut self, frame: TlogFrame) {
        if let Some(tlog) = &self.out.tlog
            && tlog.try_send(frame).is_err()
        {
            self.stats.tlog_dropped += 1;
        }
    }

    /// Queues a message to every link (`to == All`) or to one peer of link `link`; it goes out at the next
    /// [`Driver::flush`] that is due (at once for a reply to one peer).
    fn send_gcs(&mut self, link: Option<LinkId>, to: Destination, message: MavMessage) {
        // The flight log keeps every text, those the limiter holds back from the ground stations too.
        if let MavMessage::STATUSTEXT(text) = &message {
            self.out.flight_log.text(self.now_us, text.severity, text.text.to_str().unwrap_or(""));
        }
        if let (Destination::All, MavMessage::STATUSTEXT(text)) = (to, &message)
            && !self.texts.allow(self.now_us, text.id != 0 && text.chunk_seq > 0)
        {
            self.stats.statustext_suppressed += 1;
            return;
        }
        let header = self.header();
        if self.out.tlog.is_some() {
            self.log(frame::encode_v2(header, &message));
        }
        self.urgent |= matches!(to, Destination::Peer(_));
        self.pending.push((link, Outgoing { to, header, message }));
    }

    /// Hands the pending messages to the links if a reply waits or [`GCS_FLUSH_INTERVAL`] has passed
    /// (always with `force`).
    fn flush(&mut self, now: Instant, force: bool) {
        if self.pending.is_empty() || !(force || self.urgent || now - self.last_flush >= GCS_FLUSH_INTERVAL) {
            return;
        }
        let mut dropped = 0;
        for (link, out) in self.pending.drain(..) {
            for (id, tx) in self.out.links.iter().enumerate() {
                if link.is_some_and(|l| l != id) {
                    continue;
                }
                match tx.try_send(out.clone()) {
                    Ok(()) | Err(TrySendError::Closed(_)) => {}
                    Err(TrySendError::Full(_)) => dropped += 1,
                }
            }
        }
        self.stats.gcs_dropped += dropped;
        self.urgent = false;
        self.last_flush = now;
    }

    /// The vehicle, built on first use (with the `Truth` source only once a truth origin is known: from
    /// the configuration, or else the first truth sample's position).
    fn vehicle(&mut self) -> Result<Option<&mut Vehicle>, VehicleError> {
        if self.vehicle.is_none() {
            let mut config = self.config.clone();
            if config.estimator.source == EstimatorSource::Truth && config.estimator.truth_origin.is_none() {
                let Some(home) = self.home else { return Ok(None) };
                config.estimator.truth_origin = Some(home);
            }
            let params = self.persisted.params.clone().unwrap_or_else(|| ParamStore::from_config(&config));
            let mut vehicle = Vehicle::with_params(config, params)?;
            if let Some(mission) = self.persisted.mission.clone()
                && let Err(e) = vehicle.load_mission(mission)
            {
                tracing::error!(error = %e, "the saved mission is not valid any more; starting without one");
            }
            if let Some(fence) = self.persisted.fence.clone() {
                vehicle.load_fence(fence);
            }
            if let Some(rally) = self.persisted.rally.clone() {
                vehicle.load_rally(rally);
            }
            self.vehicle = Some(vehicle);
        }
        Ok(self.vehicle.as_mut())
    }

    /// Carries out what the vehicle asked of the shell: save its parameters or mission, restart it.
    fn apply_effects(&mut self) {
        let Some(vehicle) = self.vehicle.as_mut() else { return };
        for effect in vehicle.take_effects() {
            match effect {
                ShellEffect::SaveParams(text) => {
                    self.persisted.params = Some(vehicle.params().clone());
                    if let Some(p) = &self.persisted.persister {
                        p.save(PARAMS_FILE, text);
                    }
                }
                ShellEffect::SaveMission(text) => {
                    self.persisted.mission = Some(vehicle.mission().clone());
                    if let Some(p) = &self.persisted.persister {
                        p.save(MISSION_FILE, text);
                    }
                }
                ShellEffect::SaveFence(text) => {
                    self.persisted.fence = Some(vehicle.fence_and_rally().0.clone());
                    if let Some(p) = &self.persisted.persister {
                        p.save(FENCE_FILE, text);
                    }
                }
                ShellEffect::SaveRally(text) => {
                    self.persisted.rally = Some(vehicle.fence_and_rally().1.clone());
                    if let Some(p) = &self.persisted.persister {
                        p.save(RALLY_FILE, text);
                    }
                }
                ShellEffect::Reboot => {
                    tracing::info!("reboot requested: the vehicle restarts from its stored parameters and mission");
                    self.vehicle = None;
                    return;
                }
            }
        }
    }

    /// One plant frame; returns the actuator reply to send if it carried a `HIL_SENSOR`. `plant_malformed`
    /// is what the plant link's decoder has dropped so far.
    fn on_plant_frame(
        &mut self,
        message: &MavMessage,
        plant_malformed: u64,
    ) -> Result<Option<ActuatorCommand>, VehicleError> {
        if self.home.is_none()
            && let MavMessage::HIL_STATE_QUATERNION(m) = message
        {
            self.home = Some(self.config.estimator.truth_origin.unwrap_or(GeoOrigin {
                lat_deg: dege7_to_deg(m.lat),
                lon_deg: dege7_to_deg(m.lon),
                alt_amsl_m: mm_to_m(m.alt),
            }));
        }
        let home = self.home.unwrap_or(GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 });
        match decode_hil_message(message, &home) {
            Some(HilInput::Gps(gps)) => self.inputs.gps = Some(gps),
            Some(HilInput::Battery(battery)) => self.inputs.battery = Some(battery),
            Some(HilInput::Truth(truth)) if self.home.is_some() => self.inputs.truth = Some(truth),
            Some(HilInput::LocalTruth(local)) => {
                // ODOMETRY positions are about the plant's origin, but a home latched from the first
                // HIL_STATE_QUATERNION is the vehicle's first position: a vehicle that starts away from
                // the origin (a swarm's) would count its offset twice. Before the vehicle is built, home
                // moves to the plant's origin, the first position less the odometry's.
                if !self.home_is_plant_origin
                    && self.vehicle.is_none()
                    && self.config.estimator.truth_origin.is_none()
                    && let Some(first) = self.home
                {
                    let (lat_deg, lon_deg, alt_amsl_m) = first.geodetic_from_ned(&-local.pos_ned_m);
                    self.home = Some(GeoOrigin { lat_deg, lon_deg, alt_amsl_m });
                    self.home_is_plant_origin = true;
                }
                if let Some(truth) = self.inputs.truth.as_mut().filter(|t| t.time_us == local.time_us) {
                    *truth = local.refine(truth);
                }
            }
            Some(HilInput::Sensor(fields)) => {
                let samples = SensorSamples::from(&fields);
                self.inputs.imu = Some(samples.imu);
                self.inputs.mag = samples.mag;
                self.inputs.baro = samples.baro;
                let now_us = fields.time_us;
                if self.stats.last_time_us.is_some_and(|last| now_us < last) {
                    // The plant's clock went back: a new simulation, not a pause. The vehicle restarts
                    // (disarmed, its telemetry on the new timeline from this step on) from its stored
                    // parameters and mission, and says so.
                    tracing::warn!(now_us, "the plant restarted (its clock went back): the vehicle restarts, disarmed");
                    let text = statustext(MavSeverity::MAV_SEVERITY_CRITICAL, PLANT_RESTARTED_TEXT);
                    self.send_gcs(None, Destination::All, text);
                    self.stats.plant_restarts += 1;
                    self.vehicle = None;
                }
                self.now_us = now_us;
                self.stats.first_time_us.get_or_insert(now_us);
                self.stats.last_time_us = Some(now_us);
                let inputs = std::mem::take(&mut self.inputs);
                let link_errors = self.link_errors(plant_malformed);
                let Some(vehicle) = self.vehicle()? else {
                    return Ok(Some(ActuatorCommand { time_us: now_us, pwm_us: [PWM_MIN_US; 4], armed: false }));
                };
                vehicle.set_link_errors(link_errors);
                let outputs = vehicle.step(now_us, &inputs);
                self.stats.steps += 1;
                // The flight log opens before the step's texts ("Armed" is its first) and samples after.
                if let Some(vehicle) = self.vehicle.as_ref() {
                    self.out.flight_log.begin_step(now_us, vehicle);
                }
                for message in outputs.messages {
                    self.send_gcs(None, Destination::All, message);
                }
                if let Some(vehicle) = self.vehicle.as_ref() {
                    self.out.flight_log.end_step(now_us, vehicle);
                }
                self.apply_effects();
                return Ok(Some(ActuatorCommand { time_us: now_us, pwm_us: outputs.pwm_us, armed: outputs.armed }));
            }
            _ => {}
        }
        Ok(None)
    }

    /// What every link has dropped so far: malformed frames, the plant link's (`plant_malformed`) and
    /// the ground-station links', and the frames signing refused.
    fn link_errors(&self, plant_malformed: u64) -> LinkErrors {
        self.out.counters.iter().map(|c| c.snapshot()).fold(
            LinkErrors { malformed: plant_malformed, signing_rejected: 0 },
            |acc, s| LinkErrors {
                malformed: acc.malformed + s.malformed,
                signing_rejected: acc.signing_rejected + s.signature_rejected,
            },
        )
    }

    /// The vehicle's fallback telemetry while the plant is lost (HEARTBEAT CRITICAL or EMERGENCY,
    /// SYS_STATUS with the sensors unhealthy), queued to every ground-station link. Nothing when no
    /// vehicle can be built yet (the `Truth` source before any truth sample): it has not spoken either.
    fn plant_lost_telemetry(&mut self, plant_malformed: u64) -> Result<(), VehicleError> {
        let link_errors = self.link_errors(plant_malformed);
        let Some(vehicle) = self.vehicle()? else { return Ok(()) };
        vehicle.set_link_errors(link_errors);
        for message in vehicle.plant_lost_telemetry() {
            self.send_gcs(None, Destination::All, message);
        }
        Ok(())
    }

    fn on_gcs(&mut self, incoming: Incoming) -> Result<(), VehicleError> {
        self.stats.gcs_messages += 1;
        if self.out.tlog.is_some() {
            self.log(frame::encode(incoming.header, &incoming.message, incoming.version));
        }
        if let MavMessage::SETUP_SIGNING(m) = &incoming.message {
            let ours = m.target_system == 0 || m.target_system == self.config.sysid;
            if ours {
                let secure = self.out.secure.get(incoming.link).copied().unwrap_or(false);
                let said = self.out.signing.setup(m.secret_key, m.initial_timestamp, secure);
                let severity = if said.starts_with("Signing:") {
                    MavSeverity::MAV_SEVERITY_WARNING
                } else {
                    MavSeverity::MAV_SEVERITY_NOTICE
                };
                self.send_gcs(Some(incoming.link), Destination::Peer(incoming.peer), statustext(severity, &said));
            }
            return Ok(());
        }
        let now_us = self.now_us;
        let Some(vehicle) = self.vehicle()? else { return Ok(()) };
        let replies = vehicle.handle_message(now_us, &incoming.header, &incoming.message);
        for reply in replies {
            self.send_gcs(Some(incoming.link), Destination::Peer(incoming.peer), reply);
        }
        self.apply_effects();
        Ok(())
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
    let mut driver = Driver {
        config: vehicle,
        vehicle: None,
        home: None,
        home_is_plant_origin: false,
        inputs: VehicleInputs::default(),
        now_us: 0,
        sequence: 0,
        plant_sequence: 0,
        out,
        pending: Vec::new(),
        urgent: false,
        last_flush: Instant::now(),
        persisted,
        stats: PlantLinkStats::default(),
        texts: TextLimiter::default(),
    };
    let mut decoder = FrameDecoder::new();
    let datagrams = transport.is_datagram();
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
                driver.stats.plant_losses += 1;
                tracing::warn!(
                    plant = %link,
                    "plant link lost: no sensor data for 1 s; motors to minimum, HEARTBEAT on the wall clock"
                );
                let text = statustext(MavSeverity::MAV_SEVERITY_CRITICAL, PLANT_LOST_TEXT);
                driver.send_gcs(None, Destination::All, text);
                let stopped = ActuatorCommand { time_us: driver.now_us, pwm_us: [PWM_MIN_US; 4], armed: false };
                let frame = driver.plant_frame(&MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&stopped)));
                transport.send(&frame).map_err(io)?;
            } else {
                tracing::warn!(plant = %link, "no sensor data from the plant yet; waiting");
            }
        }
        // While the plant is lost no step makes telemetry: the vehicle's fallback, on the wall clock.
        if lost && last_sensor.is_some() && last_fallback.is_none_or(|t| now - t >= PLANT_LOST_TELEMETRY_INTERVAL) {
            driver.plant_lost_telemetry(decoder.stats().malformed())?;
            last_fallback = Some(now);
        }
        if last_sensor.is_none_or(|_| lost) && last_announce.is_none_or(|t| now - t >= PLANT_SILENCE) {
            let frame = driver.plant_frame(&announcement());
            transport.send(&frame).map_err(io)?;
            last_announce = Some(now);
        }
        if let Some(bytes) = transport.recv().map_err(io)? {
            let frames = if datagrams { decoder.decode_datagram(bytes) } else { decoder.push(bytes) };
            let mut reply = None;
            let malformed = decoder.stats().malformed();
            let restarts = driver.stats.plant_restarts;
            for decoded in frames {
                if let Some(cmd) = driver.on_plant_frame(&decoded.message, malformed)? {
                    reply = Some(cmd);
                }
            }
            if let Some(cmd) = reply {
                let frame = driver.plant_frame(&MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)));
                transport.send(&frame).map_err(io)?;
                last_sensor = Some(Instant::now());
                if lost {
                    lost = false;
                    last_fallback = None;
                    tracing::info!(plant = %link, "plant data again");
                    // A plant that restarted has been announced as such; one that paused is regained.
                    if driver.stats.plant_losses > 0 && driver.stats.plant_restarts == restarts {
                        let text = statustext(MavSeverity::MAV_SEVERITY_NOTICE, PLANT_REGAINED_TEXT);
                        driver.send_gcs(None, Destination::All, text);
                    }
                }
            }
        }
        // Between ticks: everything the ground stations said meanwhile.
        while gcs_open {
            match incoming.try_recv() {
                Ok(msg) => driver.on_gcs(msg)?,
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => gcs_open = false,
            }
        }
        driver.flush(Instant::now(), lost);
        if !gcs_open && driver.out.links.iter().all(mpsc::Sender::is_closed) {
            tracing::info!("every ground-station link has stopped; plant link stopping");
            break;
        }
    }
    driver.flush(Instant::now(), true);
    driver.out.flight_log.close();
    let ulog = driver.out.flight_log.stats();
    driver.stats.ulog_flights = ulog.flights;
    driver.stats.ulog_dropped = ulog.dropped;
    driver.stats.plant_decoder = decoder.stats();
    Ok(driver.stats)
}

#[cfg(test)]
mod tests {
    use std::net::UdpSocket;
    use std::sync::Arc;

    use nalgebra::Vector3;

    use super::*;
    use crate::core::hil::{HilSensorFields, decode_actuator_controls, encode_hil_sensor};
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
        assert!(!stop_cmd.armed && stop_cmd.pwm_us == [PWM_MIN_US; 4], "{stop_cmd:?}");
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

    #[test]
    fn a_repeating_statustext_is_held_to_10_per_vehicle_second_after_a_burst_of_20() {
        let mut limiter = TextLimiter::default();
        // 60 texts a second for 3 s of vehicle time (a bad stream refused at 60 Hz).
        let allowed = (0..180_u64).filter(|k| limiter.allow(k * 16_667, false)).count();
        assert_eq!(allowed, 20 + 30 - 1, "the burst, then 10 a second");
        // A chunked text's continuation follows its first chunk.
        let mut limiter = TextLimiter { tokens: 1.0, ..TextLimiter::default() };
        assert!(limiter.allow(0, false) && limiter.allow(0, true));
        assert!(!limiter.allow(0, false) && !limiter.allow(0, true));
        // A plant restart (time goes back) starts full again.
        let mut limiter = TextLimiter { tokens: 0.0, last_us: Some(5_000_000), last_allowed: false };
        assert!(!limiter.allow(5_000_000, false));
        assert!(limiter.allow(0, false), "a new timeline");
    }
}

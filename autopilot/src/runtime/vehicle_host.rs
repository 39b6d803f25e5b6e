//! The one owner of the [`Vehicle`], on the plant-link thread: it builds the vehicle (from the stored
//! parameters, mission, fence and rally points), steps it on each plant `HIL_SENSOR` with the inputs the
//! plant's frames carried, hands it the ground-station messages between steps, carries out what it asks
//! of the shell ([`ShellEffect`]: save, reboot) and sends what it says through the [`GcsFanout`].

use mavlink::dialects::common::{MavMessage, MavSeverity};

use crate::core::estimator::{EstimatorSource, GeoOrigin};
use crate::core::mavlink::units::{dege7_to_deg, mm_to_m};
use crate::core::mavlink::{LinkErrors, statustext};
use crate::core::params::ParamStore;
use crate::core::plant_link::health::PlantLinkCounters;
use crate::core::plant_link::{ActuatorCommand, HilInput, SensorSamples, decode_hil_message};
use crate::core::vehicle::{MOTOR_PWM_MIN_US, ShellEffect, Vehicle, VehicleConfig, VehicleError, VehicleInputs};
use crate::runtime::gcs_fanout::GcsFanout;
use crate::runtime::link::{Destination, Incoming, LinkId};
use crate::runtime::plant_link::{PLANT_RESTARTED_TEXT, PlantLinkStats};
use crate::runtime::state::{FENCE_FILE, MISSION_FILE, PARAMS_FILE, Persisted, RALLY_FILE};

/// What the plant link writes back after a sensor sample: the messages for the plant first (a forwarded
/// failure injection), then the actuator command, in one datagram or serial write.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantReply {
    pub actuators: ActuatorCommand,
    pub before: Vec<MavMessage>,
}

/// The vehicle, what it was built from, and where its messages go.
#[derive(Debug)]
pub struct VehicleHost {
    config: VehicleConfig,
    vehicle: Option<Vehicle>,
    home: Option<GeoOrigin>,
    /// Whether `home` is the plant's origin (from the configuration, or moved there by the first
    /// ODOMETRY) rather than the vehicle's first position.
    home_is_plant_origin: bool,
    inputs: VehicleInputs,
    /// The vehicle time of the last step (ground-station messages are handled at it).
    pub now_us: u64,
    persisted: Persisted,
    /// Where the vehicle's messages go.
    pub gcs: GcsFanout,
    pub stats: PlantLinkStats,
    /// Samples missing and late that vehicles dropped before this one counted (each vehicle counts
    /// afresh; the run's totals go on across a restart or reboot).
    retired_samples: (u64, u64),
}

impl VehicleHost {
    /// A host that builds the vehicle from `config` and `persisted` at the first plant frame that allows
    /// it, and sends through `gcs`.
    #[must_use]
    pub fn new(config: VehicleConfig, persisted: Persisted, gcs: GcsFanout) -> Self {
        Self {
            config,
            vehicle: None,
            home: None,
            home_is_plant_origin: false,
            inputs: VehicleInputs::default(),
            now_us: 0,
            persisted,
            gcs,
            stats: PlantLinkStats::default(),
            retired_samples: (0, 0),
        }
    }

    /// Queues a message, made now, to every link (`to == All`) or to one peer of link `link`.
    pub fn send_gcs(&mut self, link: Option<LinkId>, to: Destination, message: MavMessage) {
        self.gcs.send(self.now_us, link, to, message);
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
                    self.drop_vehicle();
                    return;
                }
            }
        }
    }

    /// Drops the vehicle (it is rebuilt at the next sample), keeping the run's sample totals.
    fn drop_vehicle(&mut self) {
        self.retired_samples = (self.stats.plant_missing_samples, self.stats.plant_late_samples);
        self.vehicle = None;
    }

    /// One plant frame; returns the reply to send if it carried a `HIL_SENSOR`: the actuator command, and
    /// the messages to write before it (a forwarded failure injection). `link` is what the plant link has
    /// counted so far (bytes each way, the decoder's malformed frames), handed to the step for the link's
    /// health.
    pub fn on_plant_frame(
        &mut self,
        message: &MavMessage,
        link: PlantLinkCounters,
    ) -> Result<Option<PlantReply>, VehicleError> {
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
            Some(HilInput::Rc(frame)) => self.inputs.rc = Some(frame),
            Some(HilInput::CommandAck(ack)) => self.inputs.plant_ack = Some(ack),
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
                    self.drop_vehicle();
                }
                self.now_us = now_us;
                self.stats.first_time_us.get_or_insert(now_us);
                self.stats.last_time_us = Some(now_us);
                let inputs = VehicleInputs { plant_link: Some(link), ..std::mem::take(&mut self.inputs) };
                let link_errors = self.link_errors(link.bad_frames);
                let Some(vehicle) = self.vehicle()? else {
                    return Ok(Some(PlantReply {
                        actuators: ActuatorCommand {
                            time_us: now_us,
                            pwm_us: [MOTOR_PWM_MIN_US; 4],
                            armed: false,
                            motor_test: false,
                        },
                        before: Vec::new(),
                    }));
                };
                vehicle.set_link_errors(link_errors);
                let outputs = vehicle.step(now_us, &inputs);
                let health = vehicle.plant_link_status();
                self.stats.steps += 1;
                self.stats.plant_missing_samples = self.retired_samples.0 + health.missing_samples;
                self.stats.plant_late_samples = self.retired_samples.1 + health.late_samples;
                // The flight log opens before the step's texts ("Armed" is its first) and samples after.
                if let Some(vehicle) = self.vehicle.as_ref() {
                    self.gcs.out.flight_log.begin_step(now_us, vehicle);
                }
                for message in outputs.messages {
                    self.send_gcs(None, Destination::All, message);
                }
                if let Some(vehicle) = self.vehicle.as_ref() {
                    self.gcs.out.flight_log.end_step(now_us, vehicle);
                    self.gcs.out.view.end_step(now_us, vehicle);
                }
                self.apply_effects();
                return Ok(Some(PlantReply {
                    actuators: ActuatorCommand {
                        time_us: now_us,
                        pwm_us: outputs.pwm_us,
                        armed: outputs.armed,
                        motor_test: outputs.motor_test,
                    },
                    before: outputs.plant_messages,
                }));
            }
            _ => {}
        }
        Ok(None)
    }

    /// What every link has dropped so far: malformed frames, the plant link's (`plant_malformed`) and
    /// the ground-station links', and the frames signing refused.
    fn link_errors(&self, plant_malformed: u64) -> LinkErrors {
        self.gcs.out.counters.iter().map(|c| c.snapshot()).fold(
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
    pub fn plant_lost_telemetry(&mut self, plant_malformed: u64) -> Result<(), VehicleError> {
        let link_errors = self.link_errors(plant_malformed);
        let Some(vehicle) = self.vehicle()? else { return Ok(()) };
        vehicle.set_link_errors(link_errors);
        for message in vehicle.plant_lost_telemetry() {
            self.send_gcs(None, Destination::All, message);
        }
        Ok(())
    }

    pub fn on_gcs(&mut self, incoming: Incoming) -> Result<(), VehicleError> {
        self.stats.gcs_messages += 1;
        self.gcs.log_received(&incoming);
        if let MavMessage::SETUP_SIGNING(m) = &incoming.message {
            let secure = self.gcs.out.secure.get(incoming.link).copied().unwrap_or(false);
            if let Some(said) = self.gcs.out.signing.on_setup_signing(m, self.config.sysid, secure) {
                self.send_gcs(Some(incoming.link), Destination::Peer(incoming.peer), said);
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

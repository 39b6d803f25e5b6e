//! The vehicle: estimator, controller, commander and MAVLink services in one deterministic object. In,
//! once per plant sample: the vehicle time `now_us` (µs, the plant's sensor clock) and [`VehicleInputs`]
//! (IMU at the control rate, 500 Hz by default; mag, baro with it; GPS when a fix arrives; truth for the
//! truth-fed runs). In, whenever a ground station speaks: a MAVLink message with its header. Out, per step:
//! [`VehicleOutputs`] (four PWM commands in µs, 1000-2000, the paper's rotor order; the armed flag; the
//! telemetry due this step); per message: the replies to its sender (COMMAND_ACK, STATUSTEXT). When no
//! step comes (the plant link lost), [`Vehicle::plant_lost_telemetry`]: the HEARTBEAT and SYS_STATUS
//! that say so, for the shell to send on its wall-clock fallback.
//!
//! The step: estimator update -> commander step on the estimate (the mode and its task) -> the
//! navigator turns the task into the one [`Reference`] the controller tracks (position with velocity and
//! acceleration feed-forward from jerk-limited trajectories, or an attitude; `None` for idle) ->
//! controller update -> PWM. One control tick per IMU sample (per truth sample with the `Truth` source).
//! Idle -> 1000 µs on every rotor and the controller rebuilt, so nothing adapts or integrates on the
//! ground. PWM is 1000 whenever disarmed, killed or idle, and when the estimate is invalid while armed on
//! the ground; it is clamped to [1000, 2000] and never NaN.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{MISSION_CURRENT_DATA, MISSION_ITEM_REACHED_DATA, MavMessage, MavSeverity};
use nalgebra::Vector3;

use crate::core::battery::{BatterySample, BatteryStatus};
use crate::core::commander::{Commander, CommanderInputs, CommanderOutput, Estimate, FlightMode, LandedState, Request};
pub use crate::core::config::{AirborneStart, VehicleConfig, VehicleError};
use crate::core::control::{ControlInput, Controller, ControllerKind, Reference, distributor, try_new_controller};
use crate::core::estimator::{
    BaroSample, Estimator, EstimatorSource, EstimatorState, GpsSample, ImuSample, Innovations, MagSample, TruthSample,
};
use crate::core::geofence::{Fence, Rally, Violation};
use crate::core::mavlink::command::AUTOPILOT_VERSION_ID;
use crate::core::mavlink::command::InboundCommand;
use crate::core::mavlink::mission::{MissionEvent, MissionService};
use crate::core::mavlink::offboard::OffboardContext;
use crate::core::mavlink::params::{ParamChange, ParamService, param_value};
use crate::core::mavlink::router::{
    self, Commands, GcsHeartbeats, Housekeeping, MessageContext, Microservice, OffboardReceiver, Service,
};
use crate::core::mavlink::{
    CommandContext, CommandEffect, CommandPoint, Home, LinkErrors, MavlinkService, Stream, TelemetrySnapshot,
    VehicleCommand, command_replies, housekeeping, plant_lost_heartbeat, statustext, statustext_chunks,
    sys_status_plant_lost,
};
use crate::core::mission::{Mission, MissionError, NavTarget, items_to_wpl};
use crate::core::navigator::{AutoMode, NavEvent, NavInput, Navigator, Task, nav_items};
use crate::core::params::ParamStore;
use crate::core::plan::{self, Frame, SetpointGuard, Unresolved};

/// The motor command range (µs): one definition, the distributor's.
pub use crate::core::control::distributor::{PWM_MAX_US, PWM_MIN_US};

/// One step's sensor inputs (any may be absent).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleInputs {
    pub imu: Option<ImuSample>,
    pub mag: Option<MagSample>,
    pub baro: Option<BaroSample>,
    pub gps: Option<GpsSample>,
    pub truth: Option<TruthSample>,
    /// A reading of the pack (BATTERY_STATUS from the plant or the ARM board).
    pub battery: Option<BatterySample>,
}

#[cfg(test)]
impl VehicleInputs {
    /// A truth-fed vehicle at rest, level, at the origin: the truth and the IMU reading gravity (tests).
    pub(crate) fn at_rest_truth(time_us: u64) -> Self {
        use nalgebra::UnitQuaternion;
        let truth = TruthSample {
            time_us,
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -crate::core::estimator::eskf::GRAVITY_MPS2),
        };
        let imu =
            ImuSample { time_us, accel_frd_mps2: truth.specific_force_frd_mps2, gyro_frd_radps: Vector3::zeros() };
        Self { imu: Some(imu), truth: Some(truth), ..Self::default() }
    }
}

/// One step's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleOutputs {
    /// Motor commands (µs), rotors 1..4 as in the paper; 1000 when the motors are off.
    pub pwm_us: [f64; 4],
    pub armed: bool,
    /// Telemetry due this step (HEARTBEAT, STATUSTEXT of events, streams), for every ground station.
    pub messages: Vec<MavMessage>,
}

/// What the onboard log records of the vehicle after a step, copied out so that the shell encodes it
/// without reaching into the vehicle: the estimate and the fused filter's innovations, the reference
/// flown and the controller's attitude setpoint, the motor commands and the commander's state. The
/// controller's own values (adaptive weights and the rest) are [`Controller::telemetry`].
#[derive(Debug, Clone, PartialEq)]
pub struct LogSnapshot {
    pub estimate: EstimatorState,
    pub innovations: Innovations,
    /// The reference of the last step (None: motors idle).
    pub reference: Option<Reference>,
    /// The attitude (roll, pitch, yaw) the controller's position loop last asked for (rad).
    pub attitude_setpoint_rad: Vector3<f64>,
    /// Motor commands (µs), rotors 1..4 as in the paper.
    pub pwm_us: [f64; 4],
    pub armed: bool,
    pub mode: FlightMode,
    pub landed: LandedState,
    pub battery: BatteryStatus,
    pub controller: ControllerKind,
}

/// What the vehicle asks of the shell around it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShellEffect {
    /// Restart the autopilot (PREFLIGHT_REBOOT_SHUTDOWN): rebuild the vehicle from its configuration and
    /// what is persisted.
    Reboot,
    /// Persist the mission: its QGC WPL 110 text (empty mission: only the header).
    SaveMission(String),
    /// Persist the parameters: their text (`NAME<TAB>VALUE` lines, those that differ from the defaults).
    SaveParams(String),
    /// Persist the geofence: its items as QGC WPL 110 text (empty: only the header).
    SaveFence(String),
    /// Persist the rally points: their items as QGC WPL 110 text (empty: only the header).
    SaveRally(String),
}

/// The interval (µs) of the adaptive-weight stream at `hz` (0 or less: off).
fn weights_interval_us(hz: f32) -> u64 {
    if hz > 0.0 { (1e6 / f64::from(hz)).round() as u64 } else { 0 }
}

/// The vehicle. See the module docs.
pub struct Vehicle {
    config: VehicleConfig,
    estimator: Estimator,
    controller: Box<dyn Controller>,
    /// The controller has run since it was last (re)built.
    controller_dirty: bool,
    commander: Commander,
    mavlink: MavlinkService,
    output: CommanderOutput,
    last_gps: Option<GpsSample>,
    home: Option<Home>,
    pwm_us: [f64; 4],
    /// The reference the controller tracked at the last step (None: idle).
    reference: Option<Reference>,
    throttle_low_pwm_us: f64,
    link_errors: LinkErrors,
    /// The id of the last chunked STATUSTEXT.
    text_id: u16,
    /// When a ground station last sent a HEARTBEAT (µs of vehicle time).
    gcs_heartbeat_us: Option<u64>,
    navigator: Navigator,
    /// Where the return under way goes (home or a rally point), chosen as it started.
    return_ned_m: Option<Vector3<f64>>,
    last_nav_us: Option<u64>,
    home_changed: bool,
    offboard: OffboardReceiver,
    effects: Vec<ShellEffect>,
    missions: MissionService,
    params: ParamStore,
    param_service: ParamService,
}

impl std::fmt::Debug for Vehicle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Vehicle")
            .field("sysid", &self.config.sysid)
            .field("controller", &self.controller.kind())
            .field("state", &self.output.state)
            .field("pwm_us", &self.pwm_us)
            .finish_non_exhaustive()
    }
}

impl Vehicle {
    /// A disarmed vehicle on the ground, its parameters those of `config`.
    ///
    /// # Errors
    /// [`VehicleError`] naming the first unusable part of `config`.
    pub fn new(config: VehicleConfig) -> Result<Self, VehicleError> {
        let params = ParamStore::from_config(&config);
        Self::with_params(config, params)
    }

    /// A disarmed vehicle on the ground with the parameters `params` applied over `config` (parameters
    /// persisted by an earlier run, restart-only ones included).
    ///
    /// # Errors
    /// [`VehicleError`] naming the first unusable part of the resulting configuration.
    pub fn with_params(mut config: VehicleConfig, params: ParamStore) -> Result<Self, VehicleError> {
        params.apply(&mut config);
        config.validate()?;
        let controller = try_new_controller(config.controller, &config.control)?;
        let mut commander = Commander::new(config.commander)?;
        let output = commander.step(&CommanderInputs::default());
        if let Some(start) = config.start_airborne {
            commander.start_airborne(Vector3::from(start.hold_ned_m), start.yaw_rad);
        }
        let home = commander.home_ned_m().map(|pos_ned_m| Home { pos_ned_m, geodetic: None });
        let airframe = &config.control.aco.airframe;
        let throttle_low_pwm_us = distributor::pwm_from_lift_us(0.3 * airframe.hover_rotor_lift_n());
        let mut mavlink = MavlinkService::new(config.sysid);
        mavlink.streams_mut().set_interval_us(Stream::AdaptiveWeights, weights_interval_us(params.aco_weights_hz()));
        Ok(Self {
            estimator: Estimator::new(config.estimator.clone()),
            controller,
            controller_dirty: false,
            commander,
            mavlink,
            output,
            last_gps: None,
            home,
            pwm_us: [PWM_MIN_US; 4],
            reference: None,
            throttle_low_pwm_us,
            link_errors: LinkErrors::default(),
            text_id: 0,
            gcs_heartbeat_us: None,
            navigator: {
                let mut navigator = Navigator::new(config.navigator);
                if let Some(start) = config.start_airborne {
                    // The hold starts exactly at its point (not from a first, noisy estimate).
                    navigator.start_airborne(Vector3::from(start.hold_ned_m));
                }
                navigator
            },
            last_nav_us: None,
            return_ned_m: None,
            home_changed: false,
            offboard: OffboardReceiver::default(),
            effects: Vec::new(),
            missions: MissionService::default(),
            params,
            param_service: ParamService::new(),
            config,
        })
    }

    #[must_use]
    pub fn config(&self) -> &VehicleConfig {
        &self.config
    }

    #[must_use]
    pub fn estimate(&self) -> &EstimatorState {
        self.estimator.state()
    }

    #[must_use]
    pub fn commander(&self) -> &Commander {
        &self.commander
    }

    /// The commander's output of the last step.
    #[must_use]
    pub fn commander_output(&self) -> &CommanderOutput {
        &self.output
    }

    #[must_use]
    pub fn home(&self) -> Option<&Home> {
        self.home.as_ref()
    }

    /// The reference the controller tracked at the last step (None: motors idle).
    #[must_use]
    pub fn reference(&self) -> Option<&Reference> {
        self.reference.as_ref()
    }

    /// What the onboard log records of the last step (see [`LogSnapshot`]).
    #[must_use]
    pub fn log_snapshot(&self) -> LogSnapshot {
        LogSnapshot {
            estimate: *self.estimator.state(),
            innovations: self.estimator.innovations(),
            reference: self.reference,
            attitude_setpoint_rad: self.controller.attitude_setpoint_rad(),
            pwm_us: self.pwm_us,
            armed: self.output.armed,
            mode: self.output.mode,
            landed: self.output.landed,
            battery: self.output.battery,
            controller: self.controller.kind(),
        }
    }

    /// What the shell's links have dropped so far (reported in SYS_STATUS, see [`LinkErrors`]).
    pub fn set_link_errors(&mut self, errors: LinkErrors) {
        self.link_errors = errors;
    }

    /// The MAVLink services (stream rates).
    pub fn mavlink_mut(&mut self) -> &mut MavlinkService {
        &mut self.mavlink
    }

    /// The controller (telemetry, weights).
    #[must_use]
    pub fn controller(&self) -> &dyn Controller {
        self.controller.as_ref()
    }

    /// Home as the commander keeps it, with its geodetic position once the estimator has an origin; a
    /// change is sent as HOME_POSITION at the next step.
    fn sync_home(&mut self) {
        let origin = self.estimator.state().origin;
        let geodetic = |p: &Vector3<f64>| origin.map(|o| o.geodetic_from_ned(p));
        match (self.commander.home_ned_m(), &mut self.home) {
            (Some(p), Some(home)) if home.pos_ned_m == p => {
                if home.geodetic.is_none() {
                    home.geodetic = geodetic(&p);
                }
            }
            (Some(p), _) => {
                self.home = Some(Home { pos_ned_m: p, geodetic: geodetic(&p) });
                self.home_changed = true;
            }
            (None, _) => {}
        }
    }

    /// Home altitude (m AMSL): home once set, else the ground under the vehicle; None without an origin.
    fn home_alt_amsl_m(&self) -> Option<f64> {
        if let Some((_, _, alt)) = self.home.and_then(|h| h.geodetic) {
            return Some(alt);
        }
        let est = self.estimator.state();
        est.origin.map(|o| o.alt_amsl_m - est.pos_ned_m.z).filter(|a| a.is_finite())
    }

    /// A message from a ground station at `now_us`: commands are applied at once and answered (ACK, and
    /// STATUSTEXT on refusal, then any message the command asked for) to the sender; PING and FTP get
    /// their replies; offboard setpoints are taken; anything else, or anything for another system, gets
    /// nothing.
    pub fn handle_message(&mut self, now_us: u64, header: &MavHeader, msg: &MavMessage) -> Vec<MavMessage> {
        let Some(service) = router::route(msg) else {
            return Vec::new();
        };
        let est = *self.estimator.state();
        let home_alt_amsl_m = self.home_alt_amsl_m();
        let ctx = MessageContext {
            now_us,
            sysid: self.config.sysid,
            header,
            command: CommandContext { home_alt_amsl_m },
            offboard: OffboardContext { origin: est.origin, home_alt_amsl_m, yaw_rad: est.euler_rad.z },
        };
        match service {
            Service::Housekeeping => Housekeeping.handle(&ctx, msg, &mut ()).messages,
            Service::Offboard => {
                let mut reply = self.offboard.handle(&ctx, msg, &mut ());
                if let Some(sp) = reply.effect {
                    match sp.pos_ned_m.map(|p| self.check_setpoint(&p)) {
                        Some(Err(why)) => {
                            reply.messages.extend(self.offboard.refuse(format!("Offboard: setpoint {why}")))
                        }
                        _ => {
                            self.offboard.taken();
                            self.navigator.set_offboard(now_us, sp);
                        }
                    }
                }
                reply.messages
            }
            Service::Params => {
                let before = self.params.clone();
                let reply = self.param_service.handle(&ctx, msg, &mut self.params);
                let Some(change) = reply.effect else { return reply.messages };
                match self.on_param_change(&change) {
                    Ok(extra) => reply.messages.into_iter().chain(extra).collect(),
                    Err(text) => {
                        // In range, but the configuration it makes is not flyable: undo it, in words (in
                        // chunks when it is longer than one STATUSTEXT).
                        self.params = before;
                        self.text_id = self.text_id.wrapping_add(1).max(1);
                        let mut messages = statustext_chunks(MavSeverity::MAV_SEVERITY_WARNING, &text, self.text_id);
                        messages.extend(param_value(&self.params, change.index));
                        messages
                    }
                }
            }
            Service::Mission => {
                let reply = self.missions.handle(&ctx, msg, &mut ());
                let mut messages = reply.messages;
                if let Some(event) = reply.effect {
                    messages.extend(self.on_mission_event(event));
                }
                messages
            }
            Service::Heartbeat => {
                if let Some(t) = GcsHeartbeats.handle(&ctx, msg, &mut ()).effect {
                    self.gcs_heartbeat_us = Some(t);
                }
                Vec::new()
            }
            Service::Command => match Commands.handle(&ctx, msg, &mut ()).effect {
                Some(cmd) => self.apply_command(now_us, &cmd),
                None => Vec::new(),
            },
        }
    }

    /// Applies a command and answers it: its ACK (and STATUSTEXT on refusal), then any message it asked
    /// for.
    fn apply_command(&mut self, now_us: u64, cmd: &InboundCommand) -> Vec<MavMessage> {
        let mut extra = Vec::new();
        self.navigator.refresh(now_us, self.estimator.state().origin);
        self.commander.set_nav_status(self.navigator.status());
        let outcome = match cmd.effect.clone() {
            CommandEffect::Request(req @ (Request::Mission | Request::SetMode(FlightMode::Mission))) => self
                .check_mission()
                .map_err(Some)
                .and_then(|()| self.commander.request(now_us, req).map_err(|r| Some(r.to_string()))),
            CommandEffect::Request(req) => self.commander.request(now_us, req).map_err(|r| Some(r.to_string())),
            CommandEffect::Vehicle(command) => self.vehicle_command(now_us, command, &mut extra),
            CommandEffect::Deny(text) => Err(Some(text)),
            CommandEffect::Unsupported => Err(None),
        };
        let accepted = outcome.is_ok();
        let mut replies = command_replies(cmd, outcome);
        if accepted {
            replies.extend(extra);
        }
        replies
    }

    /// The snapshot the streams and requested messages are built from, as of the last step.
    fn snapshot(&self, now_us: u64) -> TelemetrySnapshot<'_> {
        TelemetrySnapshot {
            now_us,
            estimate: self.estimator.state(),
            gps: self.last_gps.as_ref(),
            home: self.home.as_ref(),
            commander: &self.output,
            pwm_us: self.pwm_us,
            link_errors: self.link_errors,
            mission_seq: (self.navigator.mission_len() > 0).then(|| self.navigator.current_seq()),
            controller: Some(self.controller.as_ref()),
        }
    }

    /// A geodetic point of a command in local NED (altitude NaN: the vehicle's), by the one resolver.
    fn local_point(&self, point: &CommandPoint) -> Result<Vector3<f64>, Option<String>> {
        let target = NavTarget::Global {
            lat_deg: point.lat_deg,
            lon_deg: point.lon_deg,
            alt_m: point.alt_m,
            relative: point.relative_alt,
        };
        plan::resolve(&target, &self.frame(), self.estimator.state().pos_ned_m).map_err(|why| {
            Some(
                match why {
                    Unresolved::NoOrigin => "No global position yet",
                    Unresolved::NoHomeAltitude => "No home altitude yet",
                    Unresolved::Invalid => "Invalid position",
                }
                .to_owned(),
            )
        })
    }

    /// The frame targets are read in: the origin, home's altitude (or the ground under the vehicle's), the
    /// ground.
    fn frame(&self) -> Frame {
        Frame {
            origin: self.estimator.state().origin,
            home_alt_amsl_m: self.home_alt_amsl_m(),
            ground_d_m: self.home.map_or(0.0, |h| h.pos_ned_m.z),
        }
    }

    /// The checks of targets against home and the geofence, as of now.
    fn guard(&self) -> SetpointGuard<'_> {
        SetpointGuard {
            fence: self.missions.fence(),
            config: &self.config.commander.geofence,
            origin: self.estimator.state().origin.as_ref(),
            home_ned_m: self.home.map(|h| h.pos_ned_m),
        }
    }

    /// A command the vehicle answers itself; `extra` gets the messages it asked for (sent after the ACK).
    fn vehicle_command(
        &mut self,
        now_us: u64,
        command: VehicleCommand,
        extra: &mut Vec<MavMessage>,
    ) -> Result<(), Option<String>> {
        match command {
            VehicleCommand::RequestMessage { message_id } => {
                if message_id == AUTOPILOT_VERSION_ID {
                    extra.push(housekeeping::autopilot_version(self.config.sysid));
                    return Ok(());
                }
                let stream = Stream::of_message(message_id).ok_or(None)?;
                let messages = stream.messages(&self.snapshot(now_us));
                if messages.is_empty() {
                    // Not yet (no home, no fix): DENIED, quietly (MAVSDK asks three times a second).
                    return Err(Some(String::new()));
                }
                extra.extend(messages);
                Ok(())
            }
            VehicleCommand::SetMessageInterval { message_id, interval_us } => {
                let stream = Stream::of_message(message_id).ok_or(None)?;
                let us = if interval_us < 0.0 {
                    0
                } else if interval_us == 0.0 {
                    stream.default_interval_us()
                } else {
                    interval_us.round() as u64
                };
                self.mavlink.streams_mut().set_interval_us(stream, us);
                Ok(())
            }
            VehicleCommand::GetMessageInterval { message_id } => {
                let stream = Stream::of_message(message_id).ok_or(None)?;
                extra
                    .push(housekeeping::message_interval(message_id, Some(self.mavlink.streams().interval_us(stream))));
                Ok(())
            }
            VehicleCommand::ChangeSpeed { speed_mps } => {
                self.navigator.set_speed(speed_mps);
                Ok(())
            }
            VehicleCommand::SetHome { point } => {
                let pos_ned_m = point.map(|p| self.local_point(&p)).transpose()?;
                self.commander.request(now_us, Request::SetHome { pos_ned_m }).map_err(|r| Some(r.to_string()))?;
                self.sync_home();
                Ok(())
            }
            VehicleCommand::Reposition { point, yaw_rad } => {
                let pos_ned_m = point.map(|p| self.local_point(&p)).transpose()?;
                if let Some(p) = pos_ned_m {
                    self.check_setpoint(&p).map_err(|why| Some(format!("Reposition: {why}")))?;
                }
                self.commander.request(now_us, Request::Goto { pos_ned_m, yaw_rad }).map_err(|r| Some(r.to_string()))
            }
            VehicleCommand::MissionStart { first } => {
                if self.navigator.mission_len() == 0 {
                    return Err(Some("Mission start: no mission".to_owned()));
                }
                self.check_mission().map_err(Some)?;
                self.navigator.set_current(first);
                self.commander.request(now_us, Request::Mission).map_err(|r| Some(r.to_string()))
            }
            VehicleCommand::Reboot => {
                if self.commander.armed() {
                    return Err(Some("Reboot denied: armed".to_owned()));
                }
                self.effects.push(ShellEffect::Reboot);
                Ok(())
            }
            VehicleCommand::NoOp => Ok(()),
        }
    }

    /// Applies a changed parameter from the next step (gains, rates, limits, timers, speeds; the loop
    /// rates only after a restart), and asks for the parameters to be persisted. Returns the messages to
    /// send (a STATUSTEXT when the change needs a restart).
    ///
    /// # Errors
    /// The reason, when the configuration the parameter makes is not flyable; nothing changed then.
    fn on_param_change(&mut self, change: &ParamChange) -> Result<Vec<MavMessage>, String> {
        let mut next = self.config.clone();
        self.params.apply(&mut next);
        // Everything is checked now, the values that apply only after a restart (the loop rates) too:
        // a value that would stop the next start is refused when it is set.
        next.validate().map_err(|e| format!("{}: {e}", change.name))?;
        // The loop rates apply only when the vehicle is rebuilt with the stored parameters (a restart).
        next.control.rates = self.config.control.rates;
        self.commander.set_config(next.commander).map_err(|e| format!("{}: {e}", change.name))?;
        self.controller.reconfigure(&next.control);
        self.navigator.set_config(next.navigator);
        self.mavlink
            .streams_mut()
            .set_interval_us(Stream::AdaptiveWeights, weights_interval_us(self.params.aco_weights_hz()));
        self.config = next;
        self.effects.push(ShellEffect::SaveParams(self.params.to_text()));
        Ok(if change.restart_required {
            vec![statustext(MavSeverity::MAV_SEVERITY_NOTICE, &format!("{} applies after a restart", change.name))]
        } else {
            Vec::new()
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &ParamStore {
        &self.params
    }

    /// Applies a mission upload, clear or set-current; returns the messages to send (MISSION_CURRENT).
    fn on_mission_event(&mut self, event: MissionEvent) -> Vec<MavMessage> {
        match event {
            MissionEvent::Replaced(mission) => {
                self.navigator.set_mission(nav_items(&mission));
                self.missions.set_current_seq(0);
                self.effects.push(ShellEffect::SaveMission(mission.to_wpl()));
                // Accepted (it is a valid mission), but said now: it will not start while it leaves the fence.
                self.check_mission()
                    .err()
                    .map(|why| statustext(MavSeverity::MAV_SEVERITY_WARNING, &why))
                    .into_iter()
                    .collect()
            }
            MissionEvent::Cleared => {
                self.navigator.set_mission(Vec::new());
                self.missions.set_current_seq(0);
                self.effects.push(ShellEffect::SaveMission(self.missions.mission().to_wpl()));
                Vec::new()
            }
            MissionEvent::FenceReplaced(fence) => {
                self.effects.push(ShellEffect::SaveFence(items_to_wpl(fence.items())));
                let mut out = Vec::new();
                if let Err(why) = self.check_mission() {
                    out.push(statustext(MavSeverity::MAV_SEVERITY_WARNING, &why));
                }
                out
            }
            MissionEvent::RallyReplaced(rally) => {
                self.effects.push(ShellEffect::SaveRally(items_to_wpl(rally.items())));
                Vec::new()
            }
            MissionEvent::ClearedAll => {
                self.navigator.set_mission(Vec::new());
                self.missions.set_current_seq(0);
                self.effects.push(ShellEffect::SaveMission(self.missions.mission().to_wpl()));
                self.effects.push(ShellEffect::SaveFence(items_to_wpl(&[])));
                self.effects.push(ShellEffect::SaveRally(items_to_wpl(&[])));
                Vec::new()
            }
            MissionEvent::SetCurrent(seq) => {
                self.navigator.set_current(seq);
                self.missions.set_current_seq(seq);
                vec![MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA { seq, ..Default::default() })]
            }
        }
    }

    /// A mission loaded at start (persisted by an earlier run).
    ///
    /// # Errors
    /// The mission's first invalid item; the vehicle then has no mission.
    pub fn load_mission(&mut self, mission: Mission) -> Result<(), MissionError> {
        let items = nav_items(&mission);
        self.missions.set_mission(mission)?;
        self.navigator.set_mission(items);
        Ok(())
    }

    /// A geofence loaded at start (persisted by an earlier run).
    pub fn load_fence(&mut self, fence: Fence) {
        self.missions.set_fence(fence);
    }

    /// Rally points loaded at start (persisted by an earlier run).
    pub fn load_rally(&mut self, rally: Rally) {
        self.missions.set_rally(rally);
    }

    /// The geofence and the rally points as uploaded.
    #[must_use]
    pub fn fence_and_rally(&self) -> (&Fence, &Rally) {
        (self.missions.fence(), self.missions.rally())
    }

    /// Why the vehicle will not fly to `pos_ned_m` (NED m): see [`SetpointGuard::check`].
    fn check_setpoint(&self, pos_ned_m: &Vector3<f64>) -> Result<(), String> {
        self.guard().check(pos_ned_m)
    }

    /// The geofence breach predicted from the estimate, braking as the navigator brakes (MPC_ACC_HOR,
    /// MPC_JERK_AUTO).
    fn fence_breach(&self, state: &EstimatorState) -> Option<Violation> {
        if !state.flags.position_valid {
            return None;
        }
        let nav = &self.config.navigator;
        self.guard().predicted_breach(&state.pos_ned_m, &state.vel_ned_mps, nav.acc_hor_mps2, nav.jerk_mps3)
    }

    /// Why the mission cannot be flown: an item, resolved as the navigator flies it, outside the geofence
    /// or too far.
    fn check_mission(&self) -> Result<(), String> {
        if self.estimator.state().origin.is_none() {
            return Ok(());
        }
        self.guard().check_mission(&nav_items(self.missions.mission()), &self.frame())
    }

    /// The mission as uploaded.
    #[must_use]
    pub fn mission(&self) -> &Mission {
        self.missions.mission()
    }

    /// What the vehicle asks of the shell (restart, save parameters or the mission), since the last call.
    pub fn take_effects(&mut self) -> Vec<ShellEffect> {
        std::mem::take(&mut self.effects)
    }

    /// The navigator (mission, offboard).
    #[must_use]
    pub fn navigator(&self) -> &Navigator {
        &self.navigator
    }

    /// What the vehicle reports when no step is coming because the plant link is lost (no sensor sample
    /// for a while): a HEARTBEAT with its last mode and armed flag and `system_status` EMERGENCY if armed
    /// (it may be in the air with no sensors and its motors stopped), else CRITICAL; and a SYS_STATUS with
    /// every sensor unhealthy and the battery unknown. Pure: no clock, no state changes (the vehicle's own
    /// cadences stay on vehicle time and resume with the plant). The shell calls it on a wall-clock
    /// cadence, once a second, while the plant is lost.
    #[must_use]
    pub fn plant_lost_telemetry(&self) -> Vec<MavMessage> {
        vec![plant_lost_heartbeat(&self.output), sys_status_plant_lost(self.link_errors)]
    }

    /// One step at `now_us`. See the module docs.
    pub fn step(&mut self, now_us: u64, inputs: &VehicleInputs) -> VehicleOutputs {
        let truth_source = self.config.estimator.source == EstimatorSource::Truth;
        let mut tick = false;
        if let Some(imu) = &inputs.imu {
            self.estimator.update_imu(imu);
            tick = !truth_source;
        } else {
            self.estimator.update_clock(now_us);
        }
        if let Some(mag) = &inputs.mag {
            self.estimator.update_mag(mag);
        }
        if let Some(baro) = &inputs.baro {
            self.estimator.update_baro(baro);
        }
        if let Some(gps) = &inputs.gps {
            self.estimator.update_gps(gps);
            self.last_gps = Some(*gps);
        }
        if let Some(truth) = &inputs.truth {
            self.estimator.update_truth(truth);
            tick |= truth_source;
        }
        let state = *self.estimator.state();
        self.navigator.refresh(now_us, state.origin);
        let mean_pwm_us = self.pwm_us.iter().sum::<f64>() / 4.0;
        let estimate = Estimate {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            yaw_rad: state.euler_rad.z,
            position_valid: state.flags.position_valid,
            converged: state.flags.converged,
            has_origin: state.origin.is_some(),
        };
        let out = self.commander.step(&CommanderInputs {
            now_us,
            estimate,
            throttle_low: mean_pwm_us.is_nan() || mean_pwm_us <= self.throttle_low_pwm_us,
            nav: self.navigator.status(),
            gcs_heartbeat_us: self.gcs_heartbeat_us,
            battery: inputs.battery,
            fence_breach: self.fence_breach(&state),
        });
        self.sync_home();
        let reference = self.plan(now_us, &state, &out);
        self.reference = reference;
        if tick {
            self.pwm_us = self.control(&state, &out, reference);
        }
        if !out.motors_enabled {
            self.pwm_us = [PWM_MIN_US; 4];
        }
        self.output = out;
        let events = std::mem::take(&mut self.output.events);
        let due = self.mavlink.due(now_us, &events);
        let snapshot = self.snapshot(now_us);
        let mut messages = due.messages(&snapshot, &events);
        if self.home_changed {
            messages.extend(Stream::HomePosition.message(&snapshot));
        }
        self.home_changed = false;
        messages.extend(self.missions.poll(now_us).messages);
        messages.extend(self.param_service.due(&self.params));
        for event in self.navigator.take_events() {
            messages.push(match event {
                NavEvent::Current(seq) => {
                    self.missions.set_current_seq(seq);
                    MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA { seq, ..Default::default() })
                }
                NavEvent::Reached(seq) => MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA { seq }),
                NavEvent::Text(text) => statustext(MavSeverity::MAV_SEVERITY_INFO, &text),
            });
        }
        self.output.events = events;
        VehicleOutputs { pwm_us: self.pwm_us, armed: self.output.armed, messages }
    }

    /// What the controller flies this step: the navigator's reference for the commander's task.
    fn plan(&mut self, now_us: u64, state: &EstimatorState, out: &CommanderOutput) -> Option<Reference> {
        // Where a return goes, chosen as it starts and kept until it ends: the nearest rally point when one
        // is closer than home.
        let returning = out.task == Task::Auto(AutoMode::ReturnToLaunch);
        if !returning {
            self.return_ned_m = None;
        } else if self.return_ned_m.is_none()
            && let Some(home) = self.home
        {
            let to = self.missions.rally().return_point(state.origin.as_ref(), home.pos_ned_m, &state.pos_ned_m);
            self.return_ned_m = Some(to);
        }
        let dt_s = self.last_nav_us.map_or(0.0, |t| now_us.saturating_sub(t) as f64 * 1e-6).min(0.05);
        self.last_nav_us = Some(now_us);
        let input = NavInput {
            now_us,
            dt_s,
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            yaw_rad: state.euler_rad.z,
            origin: state.origin,
            home_ned_m: self.home.map(|h| h.pos_ned_m),
            home_alt_amsl_m: self.home_alt_amsl_m(),
            return_ned_m: self.return_ned_m,
            landed: out.landed == LandedState::OnGround,
            takeoff_alt_m: self.config.commander.takeoff_alt_m,
            takeoff_acceptance_m: self.config.commander.takeoff_acceptance_m,
        };
        self.navigator.update(out.task, &input)
    }

    /// Rebuilds the controller if it has run, so that no adaptation or integrator carries over.
    fn reset_controller(&mut self) {
        if self.controller_dirty
            && let Ok(c) = try_new_controller(self.config.controller, &self.config.control)
        {
            self.controller = c;
            self.controller_dirty = false;
        }
    }

    fn control(&mut self, state: &EstimatorState, out: &CommanderOutput, reference: Option<Reference>) -> [f64; 4] {
        let Some(reference) = reference else {
            self.reset_controller();
            return [PWM_MIN_US; 4];
        };
        let on_ground = matches!(out.landed, LandedState::OnGround | LandedState::Undefined);
        if on_ground && !state.flags.position_valid {
            self.reset_controller();
            return [PWM_MIN_US; 4];
        }
        let input = ControlInput {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            euler_rad: state.euler_rad,
            rate_frd_radps: state.rate_frd_radps,
            specific_force_frd_mps2: state.specific_force_frd_mps2,
        };
        self.controller_dirty = true;
        self.controller
            .update(&input, &reference)
            .map(|p| if p.is_finite() { p.clamp(PWM_MIN_US, PWM_MAX_US) } else { PWM_MIN_US })
    }
}

#[cfg(test)]
mod tests {
    use ::mavlink::Message as _;
    use ::mavlink::dialects::common::{COMMAND_INT_DATA, MavCmd, MavFrame, MavModeFlag, MavResult, MavSeverity};

    use super::*;
    use crate::core::commander::State;
    use crate::core::estimator::GeoOrigin;
    use crate::core::mavlink::command_long;

    const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
    const DT_US: u64 = 2_000;
    const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397742, lon_deg: 8.545594, alt_amsl_m: 488.0 };
    const HOLD: u32 = (4 << 16) | (3 << 24);
    const TAKEOFF: u32 = (4 << 16) | (2 << 24);
    const POSCTL: u32 = 3 << 16;

    /// A vehicle fed the truth of a vehicle at rest on the ground (the truth source is converged at once).
    fn truth_vehicle() -> Vehicle {
        let mut config = VehicleConfig::default();
        config.estimator.source = EstimatorSource::Truth;
        config.estimator.truth_origin = Some(ORIGIN);
        config.commander.disarm_preflight_s = -1.0;
        Vehicle::new(config).expect("valid config")
    }

    fn at_rest(time_us: u64) -> VehicleInputs {
        let gps = time_us.is_multiple_of(100_000).then_some(GpsSample {
            time_us,
            lat_deg: ORIGIN.lat_deg,
            lon_deg: ORIGIN.lon_deg,
            alt_amsl_m: ORIGIN.alt_amsl_m,
            vel_ned_mps: Vector3::zeros(),
            fix_type: 3,
            satellites: 10,
            eph_m: 0.5,
            epv_m: 0.8,
        });
        VehicleInputs { gps, ..VehicleInputs::at_rest_truth(time_us) }
    }

    /// Steps `v` from `*t_us` for `seconds`, returning every message with its time.
    fn run(v: &mut Vehicle, t_us: &mut u64, seconds: f64) -> Vec<(u64, MavMessage)> {
        let mut out = Vec::new();
        let end = *t_us + (seconds * 1e6) as u64;
        while *t_us < end {
            let o = v.step(*t_us, &at_rest(*t_us));
            out.extend(o.messages.into_iter().map(|m| (*t_us, m)));
            *t_us += DT_US;
        }
        out
    }

    /// A COMMAND_LONG to every component (0) of `target_system`, as pymavlink sends it.
    fn long(command: MavCmd, p: [f32; 7], target_system: u8) -> MavMessage {
        command_long(target_system, 0, command, p)
    }

    fn int(command: MavCmd, p: [f32; 7], frame: MavFrame) -> MavMessage {
        MavMessage::COMMAND_INT(COMMAND_INT_DATA {
            param1: p[0],
            param2: p[1],
            param3: p[2],
            param4: p[3],
            x: 0,
            y: 0,
            z: p[6],
            command,
            target_system: 1,
            target_component: 1,
            frame,
            current: 0,
            autocontinue: 0,
        })
    }

    fn ack_of(replies: &[MavMessage]) -> Option<(MavCmd, MavResult)> {
        replies.iter().find_map(|m| match m {
            MavMessage::COMMAND_ACK(a) => Some((a.command, a.result)),
            _ => None,
        })
    }

    fn heartbeats(msgs: &[(u64, MavMessage)]) -> Vec<(u64, u32, MavModeFlag)> {
        msgs.iter()
            .filter_map(|(t, m)| match m {
                MavMessage::HEARTBEAT(h) => Some((*t, h.custom_mode, h.base_mode)),
                _ => None,
            })
            .collect()
    }

    const ARM: [f32; 7] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

    #[test]
    fn given_a_disarmed_vehicle_when_run_10s_then_heartbeat_at_1hz_of_vehicle_time_and_at_once_on_arm() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        let hb = heartbeats(&run(&mut v, &mut t, 10.0));
        assert_eq!(hb.len(), 10);
        assert!(hb.windows(2).all(|w| w[1].0 - w[0].0 == 1_000_000), "{hb:?}");
        // WHEN armed half-way between two heartbeats THEN the next step sends one, armed.
        run(&mut v, &mut t, 0.5);
        let armed_at = t;
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_ACCEPTED)));
        let hb = heartbeats(&run(&mut v, &mut t, 0.01));
        assert_eq!(hb.len(), 1);
        assert_eq!(hb[0].0, armed_at);
        assert!(hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    }

    #[test]
    fn given_arm_takeoff_and_mode_changes_when_heartbeats_then_px4_custom_and_base_modes() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        let hb = heartbeats(&run(&mut v, &mut t, 0.1));
        let custom = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        assert_eq!(hb[0].1, HOLD);
        assert!(hb[0].2.contains(custom) && !hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        let mode = |main: f32, sub: f32| long(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, main, sub, 0.0, 0.0, 0.0, 0.0], 1);
        let replies = v.handle_message(t, &GCS, &mode(3.0, 0.0));
        assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
        let hb = heartbeats(&run(&mut v, &mut t, 0.01));
        assert_eq!((hb.len(), hb[0].1), (1, POSCTL), "immediate heartbeat on a mode change");
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        let hb = heartbeats(&run(&mut v, &mut t, 0.01));
        assert_eq!(hb[0].1, POSCTL);
        assert!(hb[0].2.contains(custom | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
        assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
        let hb = heartbeats(&run(&mut v, &mut t, 0.01));
        assert_eq!(hb.last().map(|h| h.1), Some(TAKEOFF));
        assert!(hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    }

    #[test]
    fn given_commands_when_handled_then_every_one_is_acked_and_unknown_ones_unsupported() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let nan = f32::NAN;
        for (cmd, p, want) in [
            (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5], MavResult::MAV_RESULT_ACCEPTED),
            (MavCmd::MAV_CMD_NAV_LAND, [0.0; 7], MavResult::MAV_RESULT_DENIED),
            (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, MavResult::MAV_RESULT_ACCEPTED),
            (MavCmd::MAV_CMD_DO_SET_SERVO, [1.0, 1500.0, 0.0, 0.0, 0.0, 0.0, 0.0], MavResult::MAV_RESULT_UNSUPPORTED),
        ] {
            let replies = v.handle_message(t, &GCS, &long(cmd, p, 1));
            assert_eq!(ack_of(&replies), Some((cmd, want)), "{cmd:?}");
            run(&mut v, &mut t, 0.05);
        }
        assert_eq!(v.commander().state(), State::Takeoff);
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7], 1));
        assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_NAV_LAND, MavResult::MAV_RESULT_ACCEPTED)));
        assert_eq!(v.commander().state(), State::Land);
    }

    #[test]
    fn given_an_unconverged_estimator_when_arming_then_denied_with_statustext() {
        let mut v = Vehicle::new(VehicleConfig::default()).expect("defaults are valid");
        let mut t = 0;
        run(&mut v, &mut t, 0.1);
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_DENIED)));
        let text = replies.iter().find_map(|m| match m {
            MavMessage::STATUSTEXT(s) => Some((s.severity, s.text.to_str().unwrap_or("").to_owned())),
            _ => None,
        });
        assert_eq!(
            text,
            Some((MavSeverity::MAV_SEVERITY_WARNING, "Arming denied: estimator not converged".to_owned()))
        );
        assert!(!v.commander().armed());
    }

    #[test]
    fn given_the_same_commands_as_long_and_int_when_handled_then_same_replies_and_state() {
        let nan = f32::NAN;
        let script = [
            (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, 0.0, 0.0, 490.0]),
            (MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
            (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, 0.0, 0.0, 1.5]),
            (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM),
            (MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]),
            (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
            (MavCmd::MAV_CMD_DO_SET_SERVO, [0.0; 7]),
        ];
        let (mut a, mut b, mut ta, mut tb) = (truth_vehicle(), truth_vehicle(), 0, 0);
        run(&mut a, &mut ta, 0.1);
        run(&mut b, &mut tb, 0.1);
        for (cmd, p) in script {
            let ra = a.handle_message(ta, &GCS, &long(cmd, p, 1));
            let rb = b.handle_message(tb, &GCS, &int(cmd, p, MavFrame::MAV_FRAME_GLOBAL));
            assert_eq!(ra, rb, "{cmd:?}");
            assert_eq!(
                (a.commander().state(), a.commander().pending_takeoff_alt_m()),
                (b.commander().state(), b.commander().pending_takeoff_alt_m())
            );
            let ma = run(&mut a, &mut ta, 0.2);
            let mb = run(&mut b, &mut tb, 0.2);
            assert_eq!(heartbeats(&ma), heartbeats(&mb));
        }
        assert_eq!(a.commander().state(), State::Killed);
    }

    #[test]
    fn given_takeoff_altitudes_when_sent_disarmed_then_nan_default_amsl_relative_and_low_relative() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let nan = f32::NAN;
        let mut pending = |alt: f32| {
            let p = [0.0, 0.0, 0.0, nan, nan, nan, alt];
            let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, p, 1));
            assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED), "alt {alt}");
            v.commander().pending_takeoff_alt_m()
        };
        assert_eq!(pending(nan), Some(crate::core::commander::CommanderConfig::default().takeoff_alt_m));
        assert_eq!(pending(491.0), Some(3.0), "AMSL above home at 488 m");
        assert_eq!(pending(1.5), Some(1.5), "below home: relative");
        // A relative-altitude COMMAND_INT frame is taken as given.
        let msg = int(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, nan, 0.0, 0.0, 2.0],
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        );
        v.handle_message(t, &GCS, &msg);
        assert_eq!(v.commander().pending_takeoff_alt_m(), Some(2.0));
        t += DT_US;
        v.step(t, &at_rest(t));
    }

    #[test]
    fn given_a_command_for_another_system_when_handled_then_ignored() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 7));
        assert!(replies.is_empty());
        run(&mut v, &mut t, 0.1);
        assert!(!v.commander().armed());
        let broadcast = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 0));
        assert_eq!(ack_of(&broadcast).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
    }

    #[test]
    fn given_10s_of_vehicle_time_when_counted_then_each_stream_at_its_default_rate() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        run(&mut v, &mut t, 0.9);
        let msgs = run(&mut v, &mut t, 10.0);
        let count = |id: u32| msgs.iter().filter(|(_, m)| m.message_id() == id).count() as i64;
        for (name, id, want) in [
            ("HEARTBEAT", 0, 10),
            ("SYS_STATUS", 1, 10),
            ("GPS_RAW_INT", 24, 50),
            ("ATTITUDE", 30, 200),
            ("ATTITUDE_QUATERNION", 31, 100),
            ("LOCAL_POSITION_NED", 32, 100),
            ("GLOBAL_POSITION_INT", 33, 100),
            ("VFR_HUD", 74, 40),
            ("BATTERY_STATUS", 147, 10),
            ("HOME_POSITION", 242, 5),
            ("EXTENDED_SYS_STATE", 245, 10),
            // The five ACO weight vectors at 2 Hz.
            ("DEBUG_VECT", 250, 100),
        ] {
            assert!((count(id) - want).abs() <= 1, "{name}: {} in 10 s, want {want}", count(id));
        }
        let sys = msgs.iter().find_map(|(_, m)| match m {
            MavMessage::SYS_STATUS(s) => Some(s.clone()),
            _ => None,
        });
        let sys = sys.expect("SYS_STATUS");
        assert!(
            sys.onboard_control_sensors_health
                .contains(::mavlink::dialects::common::MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK)
        );
        assert_eq!((sys.voltage_battery, sys.current_battery, sys.battery_remaining), (u16::MAX, -1, -1));
    }

    #[test]
    fn given_disarmed_or_idle_or_non_finite_inputs_when_stepped_then_pwm_1000_and_never_nan() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        for _ in 0..100 {
            assert_eq!(v.step(t, &at_rest(t)).pwm_us, [PWM_MIN_US; 4], "disarmed");
            t += DT_US;
        }
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        let o = v.step(t, &at_rest(t));
        assert!(o.armed);
        assert_eq!(o.pwm_us, [PWM_MIN_US; 4], "armed idle");
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
        let mut spun_up = false;
        for i in 0..500 {
            t += DT_US;
            let mut inputs = at_rest(t);
            if i % 3 == 0 {
                inputs.imu = Some(ImuSample {
                    time_us: t,
                    accel_frd_mps2: Vector3::repeat(f64::NAN),
                    gyro_frd_radps: Vector3::zeros(),
                });
                if let Some(truth) = inputs.truth.as_mut() {
                    truth.pos_ned_m.x = f64::NAN;
                }
            }
            let pwm = v.step(t, &inputs).pwm_us;
            assert!(pwm.iter().all(|p| p.is_finite() && (PWM_MIN_US..=PWM_MAX_US).contains(p)), "{pwm:?}");
            spun_up |= pwm.iter().any(|p| *p > PWM_MIN_US);
        }
        assert!(spun_up, "the takeoff ran the controller");
        v.handle_message(
            t,
            &GCS,
            &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1),
        );
        t += DT_US;
        assert_eq!(v.step(t, &at_rest(t)).pwm_us, [PWM_MIN_US; 4], "killed");
    }

    #[test]
    fn given_bad_configs_when_built_then_errors() {
        let bad_sysid = VehicleConfig { sysid: 0, ..VehicleConfig::default() };
        assert_eq!(Vehicle::new(bad_sysid).err(), Some(VehicleError::Sysid));
        let mut bad_speed = VehicleConfig::default();
        bad_speed.navigator.takeoff_speed_mps = f64::NAN;
        assert!(matches!(Vehicle::new(bad_speed), Err(VehicleError::Navigator(e)) if e.field == "takeoff_speed_mps"));
    }

    /// The first message of `replies` after the ACK, and the ACK's result.
    fn ack_and_rest(replies: &[MavMessage]) -> (Option<MavResult>, Vec<MavMessage>) {
        let ack = replies.iter().find_map(|m| if let MavMessage::COMMAND_ACK(a) = m { Some(a.result) } else { None });
        (ack, replies.iter().filter(|m| !matches!(m, MavMessage::COMMAND_ACK(_))).cloned().collect())
    }

    #[test]
    fn given_request_message_when_asked_for_the_version_home_and_unknowns_then_answered_or_unsupported() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let request = |id: f32| long(MavCmd::MAV_CMD_REQUEST_MESSAGE, [id, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(148.0)));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
        assert!(matches!(rest.as_slice(), [MavMessage::AUTOPILOT_VERSION(_)]), "{rest:?}");
        // The ACK goes back to its sender.
        let replies = v.handle_message(t, &GCS, &request(148.0));
        let Some(MavMessage::COMMAND_ACK(a)) = replies.first() else { panic!("{replies:?}") };
        assert_eq!((a.target_system, a.target_component), (255, 190));
        // HOME_POSITION exists once the estimate has converged with a global position (here at once, on
        // truth), before arming; without it the request is denied.
        let mut blind = Vehicle::new(VehicleConfig::default()).expect("defaults are valid");
        blind.step(0, &VehicleInputs::default());
        let (ack, _) = ack_and_rest(&blind.handle_message(0, &GCS, &request(242.0)));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_DENIED), "no home yet");
        assert!(!v.commander().armed());
        let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(242.0)));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
        assert!(matches!(rest.as_slice(), [MavMessage::HOME_POSITION(_)]), "{rest:?}");
        let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(9999.0)));
        assert_eq!((ack, rest.len()), (Some(MavResult::MAV_RESULT_UNSUPPORTED), 0));
        // The deprecated REQUEST_AUTOPILOT_CAPABILITIES MAVSDK falls back to is answered too.
        #[allow(deprecated)]
        let caps = long(MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &caps));
        assert!(
            ack == Some(MavResult::MAV_RESULT_ACCEPTED)
                && matches!(rest.as_slice(), [MavMessage::AUTOPILOT_VERSION(_)])
        );
    }

    #[test]
    fn given_set_message_interval_when_applied_then_that_stream_runs_at_its_new_rate_off_and_back_to_default() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let interval =
            |id: f32, us: f32| long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [id, us, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        let count = |msgs: &[(u64, MavMessage)], id: u32| msgs.iter().filter(|(_, m)| m.message_id() == id).count();
        let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &interval(30.0, 10_000.0)));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 200, "ATTITUDE at 100 Hz");
        v.handle_message(t, &GCS, &interval(30.0, -1.0));
        assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 0, "ATTITUDE off");
        v.handle_message(t, &GCS, &interval(30.0, 0.0));
        assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 40, "ATTITUDE back at its default 20 Hz");
        let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &interval(9999.0, 1e5)));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_UNSUPPORTED));
        #[allow(deprecated)]
        let get = long(MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL, [30.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        let (_, rest) = ack_and_rest(&v.handle_message(t, &GCS, &get));
        assert!(matches!(rest.as_slice(), [MavMessage::MESSAGE_INTERVAL(m)] if m.interval_us == 50_000), "{rest:?}");
    }

    #[test]
    fn given_parameters_when_set_then_applied_echoed_saved_and_out_of_range_refused_unchanged() {
        use ::mavlink::dialects::common::{MavParamType, PARAM_SET_DATA};
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let set = |name: &str, value: f32| {
            MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: value,
                target_system: 1,
                target_component: 1,
                param_id: name.into(),
                param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
            })
        };
        let replies = v.handle_message(t, &GCS, &set("MPC_XY_CRUISE", 2.0));
        assert!(matches!(replies.as_slice(), [MavMessage::PARAM_VALUE(p)] if p.param_value == 2.0), "{replies:?}");
        assert_eq!(v.config().navigator.cruise_speed_mps, 2.0, "applied at once");
        assert!(
            matches!(v.take_effects().as_slice(), [ShellEffect::SaveParams(text)] if text.contains("MPC_XY_CRUISE"))
        );
        let before = v.params().clone();
        let replies = v.handle_message(t, &GCS, &set("MPC_XY_CRUISE", 99.0));
        assert!(replies.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(_))), "{replies:?}");
        assert!(replies.iter().any(|m| matches!(m, MavMessage::PARAM_VALUE(p) if p.param_value == 2.0)));
        assert_eq!(v.params(), &before);
        assert_eq!(v.config().navigator.cruise_speed_mps, 2.0);
        assert!(v.take_effects().is_empty(), "a refusal saves nothing");
        // The weight stream follows ACO_WEIGHTS_HZ.
        v.handle_message(t, &GCS, &set("ACO_WEIGHTS_HZ", 10.0));
        assert_eq!(v.mavlink_mut().streams().interval_us(Stream::AdaptiveWeights), 100_000);
        v.take_effects();
        // A value that applies only after a restart is checked now: LOOP_POS_HZ 300 (in range) does not
        // divide LOOP_INNER_HZ 500, nor does LOOP_INNER_HZ 150 take LOOP_POS_HZ 100: refused, with the
        // reason, unchanged, nothing saved (a reboot would have failed to start).
        for (name, value) in [("LOOP_POS_HZ", 300.0), ("LOOP_INNER_HZ", 150.0)] {
            let before = v.params().clone();
            let replies = v.handle_message(t, &GCS, &set(name, value));
            // The reason in MAVLink 2 STATUSTEXT chunks (one id, chunk_seq 0, 1, ...), reassembled.
            let chunks: Vec<_> =
                replies.iter().filter_map(|m| if let MavMessage::STATUSTEXT(s) = m { Some(s) } else { None }).collect();
            assert!(chunks.len() > 1 && chunks.iter().all(|c| c.id == chunks[0].id && c.id != 0), "{chunks:?}");
            assert!(chunks.iter().enumerate().all(|(i, c)| usize::from(c.chunk_seq) == i));
            let text: String = chunks.iter().map(|c| c.text.to_str().unwrap_or_default()).collect();
            assert!(text.starts_with(name) && text.contains("must divide the inner rate"), "{text}");
            assert_eq!(v.params(), &before, "{name}");
            assert!(v.take_effects().is_empty(), "{name}: nothing saved");
        }
    }

    #[test]
    fn given_positions_beyond_the_hard_limit_from_home_then_offboard_and_reposition_refuse_them_with_a_reason() {
        use ::mavlink::dialects::common::{PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA};
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 1.0);
        assert!(v.home().is_some(), "home set at the first converged fix");
        let target = |x: f32, y: f32, z: f32| {
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
                x,
                y,
                z,
                target_system: 1,
                target_component: 1,
                coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
                type_mask: PositionTargetTypemask::from_bits_truncate(2552),
                ..Default::default()
            })
        };
        // GIVEN a finite but absurd offboard position (1e30 m) THEN refused in words, once.
        let replies = v.handle_message(t, &GCS, &target(1e30, -1e30, -1e30));
        let text = replies.iter().find_map(|m| match m {
            MavMessage::STATUSTEXT(s) => s.text.to_str().ok().map(str::to_owned),
            _ => None,
        });
        assert_eq!(text.as_deref(), Some("Offboard: setpoint over 10 km from home"));
        assert!(v.handle_message(t, &GCS, &target(1e30, -1e30, -1e30)).is_empty(), "said once");
        // A setpoint 9.9 km away is a position like any other.
        assert!(v.handle_message(t, &GCS, &target(9_900.0, 0.0, -5.0)).is_empty());
        // GIVEN a DO_REPOSITION 20 km north, in the air THEN refused with the reason.
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        let far = int(
            MavCmd::MAV_CMD_DO_REPOSITION,
            [-1.0, 1.0, 0.0, f32::NAN, 0.0, 0.0, 5.0],
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        );
        let far = match far {
            MavMessage::COMMAND_INT(mut c) => {
                c.x = ((ORIGIN.lat_deg + 0.18) * 1e7) as i32;
                c.y = (ORIGIN.lon_deg * 1e7) as i32;
                MavMessage::COMMAND_INT(c)
            }
            other => other,
        };
        let replies = v.handle_message(t, &GCS, &far);
        assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_DENIED), "{replies:?}");
        let said = replies.iter().any(|m| {
            matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == "Reposition: over 10 km from home"))
        });
        assert!(said, "{replies:?}");
    }

    #[test]
    fn given_a_reboot_when_disarmed_then_the_shell_is_asked_and_when_armed_refused() {
        let (mut v, mut t) = (truth_vehicle(), 0);
        run(&mut v, &mut t, 0.1);
        let reboot = long(MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
        let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &reboot));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(v.take_effects(), vec![ShellEffect::Reboot]);
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &reboot));
        assert_eq!(ack, Some(MavResult::MAV_RESULT_DENIED));
        assert!(v.take_effects().is_empty());
    }

    fn sys_status_of(messages: &[MavMessage]) -> Option<&::mavlink::dialects::common::SYS_STATUS_DATA> {
        messages.iter().rev().find_map(|m| match m {
            MavMessage::SYS_STATUS(s) => Some(s),
            _ => None,
        })
    }

    #[test]
    fn given_a_lost_plant_then_the_fallback_says_critical_disarmed_emergency_armed_and_every_sensor_unhealthy() {
        use ::mavlink::dialects::common::{MavAutopilot, MavState, MavSysStatusSensor as S, MavType};
        let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
            | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | S::MAV_SYS_STATUS_SENSOR_3D_MAG
            | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | S::MAV_SYS_STATUS_SENSOR_GPS
            | S::MAV_SYS_STATUS_PREARM_CHECK;
        // GIVEN a converged vehicle with a pack reading, whose own SYS_STATUS says the IMU, GPS and
        // pre-arm checks are healthy and reports the pack.
        let (mut v, mut t) = (truth_vehicle(), 0);
        let battery = BatterySample { voltage_v: 16.2, remaining: Some(0.9), ..BatterySample::default() };
        let mut stepped = Vec::new();
        while t < 2_000_000 {
            let inputs = VehicleInputs { battery: Some(battery), ..at_rest(t) };
            stepped.extend(v.step(t, &inputs).messages);
            t += DT_US;
        }
        let healthy = sys_status_of(&stepped).expect("SYS_STATUS at 1 Hz").clone();
        let checked = S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_GPS | S::MAV_SYS_STATUS_PREARM_CHECK;
        assert!(healthy.onboard_control_sensors_health.contains(checked), "{healthy:?}");
        assert_eq!(healthy.voltage_battery, 16_200);
        v.set_link_errors(LinkErrors { malformed: 3, signing_rejected: 5 });
        // WHEN the plant is lost (no step comes) and the shell asks for the fallback.
        let lost = v.plant_lost_telemetry();
        // THEN a HEARTBEAT as usual but CRITICAL (disarmed), and a SYS_STATUS with every sensor present
        // and enabled but none healthy, the pack unknown.
        assert_eq!(lost.len(), 2, "{lost:?}");
        let MavMessage::HEARTBEAT(hb) = &lost[0] else { panic!("{lost:?}") };
        assert_eq!(
            (hb.mavtype, hb.autopilot, hb.mavlink_version),
            (MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4, 3)
        );
        assert_eq!(hb.custom_mode, HOLD);
        assert!(!hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        assert_eq!(hb.system_status, MavState::MAV_STATE_CRITICAL);
        let status = sys_status_of(&lost).expect("SYS_STATUS");
        assert!(status.onboard_control_sensors_present.contains(sensors));
        assert!(status.onboard_control_sensors_enabled.contains(sensors));
        assert!((status.onboard_control_sensors_health & sensors).is_empty(), "{status:?}");
        assert!(!status.onboard_control_sensors_present.contains(S::MAV_SYS_STATUS_SENSOR_BATTERY));
        assert_eq!((status.voltage_battery, status.current_battery, status.battery_remaining), (u16::MAX, -1, -1));
        assert_eq!((status.errors_comm, status.errors_count1), (3, 5));
        // Asked again (the next wall second): the same.
        assert_eq!(v.plant_lost_telemetry(), lost);
        // WHEN armed and taking off, then the plant lost THEN EMERGENCY, armed, in TAKEOFF.
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
        v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
        run(&mut v, &mut t, 0.5);
        assert!(v.commander_output().armed);
        let lost = v.plant_lost_telemetry();
        let MavMessage::HEARTBEAT(hb) = &lost[0] else { panic!("{lost:?}") };
        assert_eq!(hb.system_status, MavState::MAV_STATE_EMERGENCY);
        assert!(hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
        assert_eq!(hb.custom_mode, TAKEOFF);
    }
}

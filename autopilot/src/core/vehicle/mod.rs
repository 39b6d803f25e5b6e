//! The vehicle: the estimator, commander, navigator, control stage, plan store and MAVLink services wired
//! into one deterministic object that decides nothing itself. In, once per plant sample: the vehicle time
//! `now_us` (µs, the plant's sensor clock) and [`VehicleInputs`] (IMU at the control rate, 500 Hz by
//! default; mag, baro with it; GPS when a fix arrives; truth for the truth-fed runs). In, whenever a
//! ground station speaks: a MAVLink message with its header (`gcs.rs`). Out, per step: [`VehicleOutputs`]
//! (four PWM commands in µs, 1000-2000, the paper's rotor order; the armed flag; the telemetry due this
//! step); per message: the replies to its sender (COMMAND_ACK, STATUSTEXT). When no step comes (the plant
//! link lost), [`Vehicle::plant_lost_telemetry`]: the HEARTBEAT and SYS_STATUS that say so, for the shell
//! to send on its wall-clock fallback.
//!
//! The step: the sample's time to the plant link's monitor (samples missing or late, `core::plant_link::health`)
//! -> the inputs feed the estimator -> the navigator's progress goes to the commander -> the
//! commander steps on the estimate and the vehicle's facts (the mode and its intent) -> the navigator
//! turns the intent into the one [`Reference`] the controller tracks (position with velocity and
//! acceleration feed-forward from jerk-limited trajectories, or an attitude; `None` for idle) -> the
//! control stage gives the PWM -> the MAVLink layer assembles the telemetry. One control tick per IMU
//! sample (per truth sample with the `Truth` source). Idle -> 1000 µs on every rotor and the controller
//! rebuilt, so nothing adapts or integrates on the ground. PWM is 1000 whenever disarmed, killed or idle,
//! and when the estimate is invalid while armed on the ground; it is clamped to [1000, 2000] and never NaN.
//! The one exception is a motor test (`motor_test.rs`): one motor of the disarmed vehicle at its test
//! value, flagged in [`VehicleOutputs::motor_test`].

use ::mavlink::dialects::common::{MavMessage, MavSeverity};
use nalgebra::Vector3;

use crate::core::commander::{Commander, CommanderInputs, CommanderOutput, Estimate, Facts};
pub use crate::core::config::{AirborneStart, VehicleConfig, VehicleError};
use crate::core::control::{Controller, Reference};
use crate::core::estimator::{Estimator, EstimatorState, GpsSample};
use crate::core::manual::{ManualInput, ManualStatus};
use crate::core::mavlink::failure::FailureInjection;
use crate::core::mavlink::manual::ManualControlService;
use crate::core::mavlink::mission::MissionService;
use crate::core::mavlink::params::ParamService;
use crate::core::mavlink::router::OffboardReceiver;
use crate::core::mavlink::{
    Home, LinkErrors, MavlinkService, Stream, TelemetrySnapshot, estimator_event_message, nav_event_message,
    plant_link_event_message, plant_lost_heartbeat, statustext, sys_status_plant_lost,
};
use crate::core::navigator::{NavEvent, NavInput, Navigator};
use crate::core::params::ParamStore;
use crate::core::plan::{Frame, Plan, SetpointGuard};
use crate::core::plant_link::health::{PlantHealth, PlantLinkStatus};

mod control_stage;
mod gcs;
mod io;
mod motor_test;
mod plan_view;

use control_stage::ControlStage;
pub use io::{LogSnapshot, ShellEffect, VehicleInputs, VehicleOutputs};
use motor_test::MotorTest;
pub use plan_view::PlanView;

/// The motor command range (µs): one definition, the distributor's.
pub use crate::core::control::distributor::{MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US};

/// The interval (µs) of the adaptive-weight stream at `hz` (0 or less: off).
fn weights_interval_us(hz: f32) -> u64 {
    if hz > 0.0 { (1e6 / f64::from(hz)).round() as u64 } else { 0 }
}

/// The vehicle. See the module docs.
pub struct Vehicle {
    config: VehicleConfig,
    estimator: Estimator,
    control: ControlStage,
    commander: Commander,
    navigator: Navigator,
    /// The commander's output of the last step.
    output: CommanderOutput,
    /// The reference the controller tracked at the last step (None: idle).
    reference: Option<Reference>,
    last_gps: Option<GpsSample>,
    /// When a ground station last sent a HEARTBEAT (µs of vehicle time).
    gcs_heartbeat_us: Option<u64>,
    mavlink: MavlinkService,
    link_errors: LinkErrors,
    /// The id of the last chunked STATUSTEXT.
    text_id: u16,
    offboard: OffboardReceiver,
    /// The mission, fence and rally points (the one store), and the service that transfers them.
    plan: Plan,
    missions: MissionService,
    params: ParamStore,
    param_service: ParamService,
    effects: Vec<ShellEffect>,
    /// The pilot's input (radio and joystick), and what it gave at the last step.
    manual: ManualInput,
    manual_status: ManualStatus,
    manual_service: ManualControlService,
    /// The motor test (ACTUATOR_TEST, DO_MOTOR_TEST), disarmed only.
    motor_test: MotorTest,
    /// Failure injection (INJECT_FAILURE): what waits for the plant, and the inputs switched off.
    failures: FailureInjection,
    /// The plant link's health: samples missing and late, on the sample period of LOOP_INNER_HZ.
    plant_health: PlantHealth,
}

impl std::fmt::Debug for Vehicle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Vehicle")
            .field("sysid", &self.config.sysid)
            .field("controller", &self.control.controller().kind())
            .field("state", &self.output.state)
            .field("pwm_us", &self.control.pwm_us())
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
        let control = ControlStage::new(&config)?;
        let mut commander = Commander::new(config.commander)?;
        let output = commander.step(&CommanderInputs::default());
        let mut navigator = Navigator::new(config.navigator);
        if let Some(start) = config.start_airborne {
            commander.start_airborne(Vector3::from(start.hold_ned_m));
            // The hold starts exactly at its point (not from a first, noisy estimate).
            navigator.start_airborne(Vector3::from(start.hold_ned_m), start.yaw_rad);
        }
        let mut mavlink = MavlinkService::new(config.sysid);
        mavlink.streams_mut().set_interval_us(Stream::AdaptiveWeights, weights_interval_us(params.aco_weights_hz()));
        // An airborne start's home is not news: it is not announced.
        mavlink.home_announced(commander.home_ned_m());
        Ok(Self {
            estimator: Estimator::new(config.estimator.clone()),
            control,
            commander,
            navigator,
            output,
            reference: None,
            last_gps: None,
            gcs_heartbeat_us: None,
            mavlink,
            link_errors: LinkErrors::default(),
            text_id: 0,
            offboard: OffboardReceiver::default(),
            plan: Plan::default(),
            missions: MissionService::default(),
            params,
            param_service: ParamService::new(),
            effects: Vec::new(),
            manual: ManualInput::default(),
            manual_status: ManualStatus::default(),
            manual_service: ManualControlService::default(),
            motor_test: MotorTest::default(),
            failures: FailureInjection::default(),
            plant_health: PlantHealth::at_rate_hz(config.control.rates.inner_hz),
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

    /// The navigator (mission, offboard).
    #[must_use]
    pub fn navigator(&self) -> &Navigator {
        &self.navigator
    }

    /// Home as the commander keeps it (its one owner), with its geodetic position once the estimator has
    /// an origin.
    #[must_use]
    pub fn home(&self) -> Option<Home> {
        let origin = self.estimator.state().origin;
        self.commander.home_ned_m().map(|p| Home { pos_ned_m: p, geodetic: origin.map(|o| o.geodetic_from_ned(&p)) })
    }

    /// The reference the controller tracked at the last step (None: motors idle).
    #[must_use]
    pub fn reference(&self) -> Option<&Reference> {
        self.reference.as_ref()
    }

    /// The controller (telemetry, weights).
    #[must_use]
    pub fn controller(&self) -> &dyn Controller {
        self.control.controller()
    }

    /// What the onboard log records of the last step (see [`LogSnapshot`]).
    #[must_use]
    pub fn log_snapshot(&self) -> LogSnapshot {
        LogSnapshot {
            estimate: *self.estimator.state(),
            innovations: self.estimator.innovations(),
            reference: self.reference,
            attitude_setpoint_rad: self.control.controller().attitude_setpoint_rad(),
            pwm_us: self.pwm_us(),
            armed: self.output.armed,
            mode: self.output.mode,
            landed: self.output.landed,
            battery: self.output.battery,
            controller: self.control.controller().kind(),
            manual: self.manual_status,
            plant_link: self.plant_health.status(),
        }
    }

    /// The plant link's health after the last step: samples received, missing and late, the last second's
    /// drop rate, and the shell's byte counts (see [`crate::core::plant_link::health`]).
    #[must_use]
    pub fn plant_link_status(&self) -> PlantLinkStatus {
        self.plant_health.status()
    }

    /// The motor commands of the last step (µs): the controller's, or a motor test's while one runs.
    #[must_use]
    pub fn pwm_us(&self) -> [f64; 4] {
        self.motor_test.last_pwm_us().unwrap_or_else(|| self.control.pwm_us())
    }

    /// Whether a motor test drove the motors at the last step (disarmed).
    #[must_use]
    pub fn motor_test_running(&self) -> bool {
        self.motor_test.last_pwm_us().is_some()
    }

    /// What the shell's links have dropped so far (reported in SYS_STATUS, see [`LinkErrors`]).
    pub fn set_link_errors(&mut self, errors: LinkErrors) {
        self.link_errors = errors;
    }

    /// The MAVLink services (stream rates).
    pub fn mavlink_mut(&mut self) -> &mut MavlinkService {
        &mut self.mavlink
    }

    /// Home altitude (m AMSL): home once set, else the ground under the vehicle; None without an origin.
    fn home_alt_amsl_m(&self) -> Option<f64> {
        // The altitude the geodetic map gives home (`alt_amsl_m - D`), without mapping its latitude and
        // longitude (this runs every step).
        let est = self.estimator.state();
        let ground_d_m = self.commander.home_ned_m().map_or(est.pos_ned_m.z, |h| h.z);
        est.origin.map(|o| o.alt_amsl_m - ground_d_m).filter(|a| a.is_finite())
    }

    /// The frame targets are read in: the origin, home's altitude (or the ground under the vehicle's), the
    /// ground.
    fn frame(&self) -> Frame {
        Frame {
            origin: self.estimator.state().origin,
            home_alt_amsl_m: self.home_alt_amsl_m(),
            ground_d_m: self.commander.home_ned_m().map_or(0.0, |h| h.z),
        }
    }

    /// The checks of targets against home and the geofence, as of now.
    fn guard(&self) -> SetpointGuard<'_> {
        SetpointGuard {
            fence: self.plan.fence(),
            config: &self.config.commander.geofence,
            origin: self.estimator.state().origin.as_ref(),
            home_ned_m: self.commander.home_ned_m(),
        }
    }

    /// What the commander's transitions read of the rest of the vehicle at `now_us`: a mission that can
    /// be flown, offboard setpoints that flow.
    fn facts(&self, now_us: u64) -> Facts {
        Facts {
            mission_valid: self.navigator.mission_len() > 0 && self.estimator.state().origin.is_some(),
            offboard_fresh: self.offboard.fresh(now_us, self.config.navigator.offboard_timeout_s),
            manual_fresh: self.manual.sticks(now_us, &self.config.manual).is_some(),
        }
    }

    /// The snapshot the streams and requested messages are built from, as of the last step.
    fn snapshot<'a>(&'a self, now_us: u64, home: Option<&'a Home>) -> TelemetrySnapshot<'a> {
        TelemetrySnapshot {
            now_us,
            estimate: self.estimator.state(),
            gps: self.last_gps.as_ref(),
            home,
            commander: &self.output,
            pwm_us: self.pwm_us(),
            link_errors: self.link_errors,
            plant_drop_rate_cpct: self.plant_health.status().drop_rate_cpct(),
            mission_seq: (self.navigator.mission_len() > 0).then(|| self.navigator.current_seq()),
            controller: Some(self.control.controller()),
            manual: self.manual_status,
        }
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

    /// One step at `now_us`: estimator -> commander (mode and intent) -> navigator (the reference) ->
    /// control stage (PWM) -> telemetry. See the module docs.
    pub fn step(&mut self, now_us: u64, inputs: &VehicleInputs) -> VehicleOutputs {
        // The plant link's health first: this sample's place in the plant's sequence.
        let plant_text = self.plant_health.step(now_us, inputs.plant_link).map(|e| plant_link_event_message(&e));
        let tick = inputs.feed(now_us, &mut self.estimator, self.config.estimator.source);
        // A source lost, stuck, rejected or regained: said this step.
        let estimator_texts: Vec<MavMessage> =
            self.estimator.take_events().iter().map(estimator_event_message).collect();
        if inputs.gps.is_some() {
            self.last_gps = inputs.gps;
        }
        if let Some(frame) = inputs.rc {
            self.manual.on_rc(now_us, frame, &self.config.manual);
        }
        let (manual_status, pilot_actions) = self.manual.step(now_us, &self.config.manual);
        self.manual_status = manual_status;
        self.navigator.set_sticks(manual_status.sticks);
        // The pilot's switches and gestures, before the commander steps (a refusal is said at once).
        let pilot_refusals: Vec<MavMessage> = pilot_actions
            .into_iter()
            .filter_map(|action| self.pilot_action(now_us, action).err())
            .map(|why| statustext(MavSeverity::MAV_SEVERITY_WARNING, &why))
            .collect();
        let state = *self.estimator.state();
        for progress in self.navigator.take_progress() {
            self.commander.on_progress(progress);
        }
        let estimate = Estimate {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            roll_rad: state.euler_rad.x,
            pitch_rad: state.euler_rad.y,
            yaw_rad: state.euler_rad.z,
            position_valid: state.flags.position_valid,
            converged: state.flags.converged,
            has_origin: state.origin.is_some(),
        };
        let out = self.commander.step(&CommanderInputs {
            now_us,
            estimate,
            throttle_low: self.control.throttle_low(),
            facts: self.facts(now_us),
            gcs_heartbeat_us: self.gcs_heartbeat_us,
            battery: inputs.battery,
            fence_breach: self.fence_breach(&state),
        });
        let home = self.home();
        let nav_input = NavInput {
            now_us,
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            yaw_rad: state.euler_rad.z,
            origin: state.origin,
            home_ned_m: home.map(|h| h.pos_ned_m),
            home_alt_amsl_m: self.home_alt_amsl_m(),
            landed: out.landed == crate::core::commander::LandedState::OnGround,
            position_valid: state.flags.position_valid,
            takeoff_alt_m: self.config.commander.takeoff_alt_m,
            takeoff_acceptance_m: self.config.commander.takeoff_acceptance_m,
        };
        self.reference = self.navigator.update(out.intent, &nav_input, self.plan.rally());
        let pwm_us = self.control.step(tick, &state, &out, self.reference, &self.config);
        // A motor test (disarmed only) drives the outputs instead; arming ends it.
        let motor_test = self.motor_test.step(now_us, out.armed);
        let pwm_us = motor_test.unwrap_or(pwm_us);
        self.output = out;
        let events = std::mem::take(&mut self.output.events);
        // The navigator's events happened in this step before the snapshot is read, so they go first: a
        // MISSION_CURRENT for an item passed on the way (a DO_CHANGE_SPEED) after the stream's one for the
        // item after it would step a ground station's progress back (MAVSDK's did).
        let mut messages = Vec::new();
        for event in self.navigator.take_events() {
            if let NavEvent::Current(seq) = event {
                self.plan.set_current_seq(seq);
            }
            messages.push(nav_event_message(&event));
        }
        let due = self.mavlink.due_with_home(now_us, &events, home.map(|h| h.pos_ned_m));
        messages.extend(due.messages(&self.snapshot(now_us, home.as_ref()), &events));
        messages.extend(estimator_texts);
        messages.extend(plant_text);
        messages.extend(pilot_refusals);
        messages.extend(self.missions.poll(now_us).messages);
        messages.extend(self.param_service.due(&self.params));
        if let Some(ack) = inputs.plant_ack {
            messages.extend(self.failures.on_plant_ack(ack));
        }
        messages.extend(self.failures.step(now_us));
        self.output.events = events;
        VehicleOutputs {
            pwm_us,
            armed: self.output.armed,
            motor_test: motor_test.is_some(),
            messages,
            plant_messages: self.failures.take_plant_messages(),
        }
    }
}

#[cfg(test)]
mod tests;

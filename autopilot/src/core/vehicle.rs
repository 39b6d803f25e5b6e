//! The vehicle: estimator, controller, commander and MAVLink services in one deterministic object. In,
//! once per plant sample: the vehicle time `now_us` (µs, the plant's sensor clock) and [`VehicleInputs`]
//! (IMU at the control rate, 500 Hz by default; mag, baro with it; GPS when a fix arrives; truth for the
//! truth-fed runs). In, whenever a ground station speaks: a MAVLink message with its header. Out, per step:
//! [`VehicleOutputs`] (four PWM commands in µs, 1000-2000, the paper's rotor order; the armed flag; the
//! telemetry due this step); per message: the replies to its sender (COMMAND_ACK, STATUSTEXT).
//!
//! The step: estimator update -> commander step on the estimate -> the commander's [`Setpoint`] as a
//! controller [`Reference`] -> controller update -> PWM. One control tick per IMU sample (per truth sample
//! with the `Truth` source). Setpoints: Idle -> 1000 µs on every rotor and the controller rebuilt, so
//! nothing adapts or integrates on the ground; Hold -> position reference; Climb -> position reference
//! whose down coordinate ramps to the target at `takeoff_speed_mps`; Descend -> position reference whose
//! down coordinate ramps down at the land speed, to at most `land_ramp_below_ground_m` below the ground.
//! PWM is 1000 whenever disarmed, killed or idle, and when the estimate is invalid while armed on the
//! ground; it is clamped to [1000, 2000] and never NaN.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::core::commander::{
    self, Commander, CommanderConfig, CommanderInputs, CommanderOutput, Estimate, Event, LandedState, Setpoint,
};
use crate::core::control::{
    self, ControlInput, Controller, ControllerConfig, ControllerKind, Reference, distributor, try_new_controller,
};
use crate::core::estimator::{
    self, BaroSample, Estimator, EstimatorConfig, EstimatorSource, EstimatorState, GpsSample, ImuSample, MagSample,
    TruthSample,
};
use crate::core::mavlink::{CommandContext, CommandEffect, Home, MavlinkService, TelemetrySnapshot, command_replies};

/// Motor command with the motors stopped (µs).
pub const PWM_MIN_US: f64 = 1000.0;
/// Largest motor command (µs).
pub const PWM_MAX_US: f64 = 2000.0;

/// Everything the vehicle is built from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VehicleConfig {
    /// MAVLink system id (N+1 for instance N).
    pub sysid: u8,
    pub controller: ControllerKind,
    pub control: ControllerConfig,
    pub estimator: EstimatorConfig,
    pub commander: CommanderConfig,
    /// Climb speed of the takeoff reference (m/s; PX4 MPC_TKO_SPEED).
    pub takeoff_speed_mps: f64,
    /// How far below the ground the landing reference may ramp (m), bounding the push into the ground.
    pub land_ramp_below_ground_m: f64,
}

impl Default for VehicleConfig {
    fn default() -> Self {
        Self {
            sysid: 1,
            controller: ControllerKind::Aco,
            control: ControllerConfig::default(),
            estimator: EstimatorConfig::default(),
            commander: CommanderConfig::default(),
            takeoff_speed_mps: 1.0,
            land_ramp_below_ground_m: 0.5,
        }
    }
}

/// Why a [`VehicleConfig`] is unusable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VehicleError {
    #[error("vehicle config: sysid must be 1..=255")]
    Sysid,
    #[error("vehicle config: {field} = {value} must be finite and positive")]
    NotPositive { field: &'static str, value: f64 },
    #[error(transparent)]
    Controller(#[from] control::ConfigError),
    #[error(transparent)]
    Estimator(#[from] estimator::ConfigError),
    #[error(transparent)]
    Commander(#[from] commander::ConfigError),
}

/// One step's sensor inputs (any may be absent).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleInputs {
    pub imu: Option<ImuSample>,
    pub mag: Option<MagSample>,
    pub baro: Option<BaroSample>,
    pub gps: Option<GpsSample>,
    pub truth: Option<TruthSample>,
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

/// Which ramp the down reference is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ramp {
    None,
    Climb,
    Descend,
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
    last_tick_us: Option<u64>,
    ramp: Ramp,
    ramp_d_m: f64,
    /// Down coordinate of the last position reference flown (m).
    last_ref_d_m: Option<f64>,
    throttle_low_pwm_us: f64,
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

fn finite3(v: &Vector3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Vehicle {
    /// A disarmed vehicle on the ground.
    ///
    /// # Errors
    /// [`VehicleError`] naming the first unusable part of `config`.
    pub fn new(config: VehicleConfig) -> Result<Self, VehicleError> {
        if config.sysid == 0 {
            return Err(VehicleError::Sysid);
        }
        for (field, value) in [
            ("takeoff_speed_mps", config.takeoff_speed_mps),
            ("land_ramp_below_ground_m", config.land_ramp_below_ground_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(VehicleError::NotPositive { field, value });
            }
        }
        config.estimator.validate()?;
        let controller = try_new_controller(config.controller, &config.control)?;
        let mut commander = Commander::new(config.commander)?;
        let output = commander.step(&CommanderInputs::default());
        let airframe = &config.control.aco.airframe;
        let throttle_low_pwm_us = distributor::pwm_from_lift_us(0.3 * airframe.hover_rotor_lift_n());
        Ok(Self {
            estimator: Estimator::new(config.estimator.clone()),
            controller,
            controller_dirty: false,
            commander,
            mavlink: MavlinkService::new(config.sysid),
            output,
            last_gps: None,
            home: None,
            pwm_us: [PWM_MIN_US; 4],
            last_tick_us: None,
            ramp: Ramp::None,
            ramp_d_m: 0.0,
            last_ref_d_m: None,
            throttle_low_pwm_us,
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

    /// The MAVLink services (stream rates).
    pub fn mavlink_mut(&mut self) -> &mut MavlinkService {
        &mut self.mavlink
    }

    /// The controller (telemetry, weights).
    #[must_use]
    pub fn controller(&self) -> &dyn Controller {
        self.controller.as_ref()
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
    /// STATUSTEXT on refusal) to the sender; anything else, or anything for another system, gets nothing.
    pub fn handle_message(&mut self, now_us: u64, header: &MavHeader, msg: &MavMessage) -> Vec<MavMessage> {
        let ctx = CommandContext { home_alt_amsl_m: self.home_alt_amsl_m() };
        let Some(cmd) = self.mavlink.on_message(header, msg, &ctx) else {
            return Vec::new();
        };
        let outcome = match cmd.effect {
            CommandEffect::Request(req) => self.commander.request(now_us, req).map_err(|r| Some(r.to_string())),
            CommandEffect::Deny(text) => Err(Some(text)),
            CommandEffect::Unsupported => Err(None),
        };
        command_replies(cmd.command, outcome)
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
        let mean_pwm_us = self.pwm_us.iter().sum::<f64>() / 4.0;
        let estimate = Estimate {
            pos_ned_m: state.pos_ned_m,
            vel_ned_mps: state.vel_ned_mps,
            yaw_rad: state.euler_rad.z,
            position_valid: state.flags.position_valid,
            converged: state.flags.converged,
        };
        let out = self.commander.step(&CommanderInputs {
            now_us,
            estimate,
            throttle_low: mean_pwm_us.is_nan() || mean_pwm_us <= self.throttle_low_pwm_us,
            home_ned_m: self.home.map(|h| h.pos_ned_m),
        });
        if out.events.iter().any(|e| matches!(e, Event::Armed { .. })) && finite3(&state.pos_ned_m) {
            self.home = Some(Home {
                pos_ned_m: state.pos_ned_m,
                geodetic: state.origin.map(|o| o.geodetic_from_ned(&state.pos_ned_m)),
            });
        }
        if tick {
            self.pwm_us = self.control(now_us, &state, &out);
        }
        if !out.motors_enabled {
            self.pwm_us = [PWM_MIN_US; 4];
        }
        let snapshot = TelemetrySnapshot {
            now_us,
            estimate: &state,
            gps: self.last_gps.as_ref(),
            home: self.home.as_ref(),
            commander: &out,
            pwm_us: self.pwm_us,
        };
        let messages = self.mavlink.outbound(now_us, &snapshot, &out.events);
        let armed = out.armed;
        self.output = out;
        VehicleOutputs { pwm_us: self.pwm_us, armed, messages }
    }

    /// Rebuilds the controller if it has run, so that no adaptation or integrator carries over.
    fn reset_controller(&mut self) {
        if self.controller_dirty
            && let Ok(c) = try_new_controller(self.config.controller, &self.config.control)
        {
            self.controller = c;
            self.controller_dirty = false;
        }
        self.ramp = Ramp::None;
        self.last_ref_d_m = None;
    }

    /// The down reference of a ramp of `kind` towards `target_d_m` at `speed_mps`, started at the last
    /// reference (or the estimate) when the ramp begins. Returns (down m, down speed feed-forward m/s).
    fn ramp_d(&mut self, kind: Ramp, est_d_m: f64, target_d_m: f64, speed_mps: f64, dt_s: f64) -> (f64, f64) {
        if self.ramp != kind {
            self.ramp = kind;
            self.ramp_d_m = self.last_ref_d_m.filter(|d| d.is_finite()).unwrap_or(est_d_m);
        }
        let step = speed_mps * dt_s;
        let error = target_d_m - self.ramp_d_m;
        if error.abs() <= step {
            self.ramp_d_m = target_d_m;
            (target_d_m, 0.0)
        } else {
            self.ramp_d_m += step.copysign(error);
            (self.ramp_d_m, speed_mps.copysign(error))
        }
    }

    fn control(&mut self, now_us: u64, state: &EstimatorState, out: &CommanderOutput) -> [f64; 4] {
        let dt_s = self.last_tick_us.map_or(0.0, |t| now_us.saturating_sub(t) as f64 * 1e-6).min(0.05);
        self.last_tick_us = Some(now_us);
        let est_d_m = if state.pos_ned_m.z.is_finite() { state.pos_ned_m.z } else { 0.0 };
        let reference = match out.setpoint {
            Setpoint::Idle => {
                self.reset_controller();
                return [PWM_MIN_US; 4];
            }
            Setpoint::Hold { pos_ned_m, yaw_rad } => {
                self.ramp = Ramp::None;
                Reference::position(pos_ned_m, yaw_rad)
            }
            Setpoint::Climb { pos_ned_m, yaw_rad } => {
                let speed = self.config.takeoff_speed_mps;
                let (d, vd) = self.ramp_d(Ramp::Climb, est_d_m, pos_ned_m.z, speed, dt_s);
                Reference {
                    vel_ned_mps: Vector3::new(0.0, 0.0, vd),
                    ..Reference::position(Vector3::new(pos_ned_m.x, pos_ned_m.y, d), yaw_rad)
                }
            }
            Setpoint::Descend { pos_ne_m, yaw_rad, speed_mps } => {
                let ground_d_m = self.home.map_or(0.0, |h| h.pos_ned_m.z);
                let floor_d_m = ground_d_m + self.config.land_ramp_below_ground_m;
                let (d, vd) = self.ramp_d(Ramp::Descend, est_d_m, floor_d_m, speed_mps, dt_s);
                Reference {
                    vel_ned_mps: Vector3::new(0.0, 0.0, vd),
                    ..Reference::position(Vector3::new(pos_ne_m.x, pos_ne_m.y, d), yaw_rad)
                }
            }
        };
        self.last_ref_d_m = Some(reference.pos_ned_m.z);
        let on_ground = matches!(
            out.landed_state,
            x if x == LandedState::OnGround.mavlink() || x == LandedState::Undefined.mavlink()
        );
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

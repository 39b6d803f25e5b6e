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
use crate::core::navigator::NavigatorConfig;

/// Motor command with the motors stopped (µs).
pub const PWM_MIN_US: f64 = 1000.0;
/// Largest motor command (µs).
pub const PWM_MAX_US: f64 = 2000.0;

/// Everything the vehicle is built from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VehicleConfig {
    /// MAVLink system id (N+1 for instance N).
    pub sysid: u8,
    pub controller: ControllerKind,
    pub control: ControllerConfig,
    pub estimator: EstimatorConfig,
    pub commander: CommanderConfig,
    pub navigator: NavigatorConfig,
    /// Climb speed of the takeoff reference (m/s; PX4 MPC_TKO_SPEED).
    pub takeoff_speed_mps: f64,
    /// How far below the ground the landing reference may ramp (m), bounding the push into the ground.
    pub land_ramp_below_ground_m: f64,
    /// Start armed and holding a point instead of disarmed on the ground (experiments that begin in the
    /// air, as the paper's do: `sitl run --scenario`); home is then the ground below that point.
    pub start_airborne: Option<AirborneStart>,
}

/// Where an airborne start holds (NED m about the estimator's origin, yaw rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AirborneStart {
    pub hold_ned_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
}

impl Default for VehicleConfig {
    fn default() -> Self {
        Self {
            sysid: 1,
            controller: ControllerKind::Aco,
            control: ControllerConfig::default(),
            estimator: EstimatorConfig::default(),
            commander: CommanderConfig::default(),
            navigator: NavigatorConfig::default(),
            takeoff_speed_mps: 1.0,
            land_ramp_below_ground_m: 0.5,
            start_airborne: None,
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
    #[error("vehicle config: start_airborne hold_ned_m and yaw_rad must be finite")]
    StartAirborne,
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
    comm_errors: u64,
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
        let mut home = None;
        if let Some(start) = config.start_airborne {
            let hold = Vector3::from(start.hold_ned_m);
            if !(finite3(&hold) && start.yaw_rad.is_finite()) {
                return Err(VehicleError::StartAirborne);
            }
            commander.start_airborne(hold, start.yaw_rad);
            home = Some(Home { pos_ned_m: Vector3::new(hold.x, hold.y, 0.0), geodetic: None });
        }
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
            home,
            pwm_us: [PWM_MIN_US; 4],
            last_tick_us: None,
            ramp: Ramp::None,
            ramp_d_m: 0.0,
            last_ref_d_m: None,
            throttle_low_pwm_us,
            comm_errors: 0,
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

    /// The malformed frames the shell's links have dropped so far (reported in SYS_STATUS errors_comm).
    pub fn set_comm_errors(&mut self, count: u64) {
        self.comm_errors = count;
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
        if let Some(home) = &mut self.home
            && home.geodetic.is_none()
            && let Some(origin) = state.origin
        {
            home.geodetic = Some(origin.geodetic_from_ned(&home.pos_ned_m));
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
            comm_errors: self.comm_errors,
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

#[cfg(test)]
mod tests {
    use ::mavlink::Message as _;
    use ::mavlink::dialects::common::{COMMAND_INT_DATA, MavCmd, MavFrame, MavModeFlag, MavResult, MavSeverity};
    use nalgebra::UnitQuaternion;

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
        let truth = TruthSample {
            time_us,
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.81),
        };
        let imu =
            ImuSample { time_us, accel_frd_mps2: truth.specific_force_frd_mps2, gyro_frd_radps: Vector3::zeros() };
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
        VehicleInputs { imu: Some(imu), truth: Some(truth), gps, ..VehicleInputs::default() }
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
        assert_eq!(pending(nan), Some(CommanderConfig::default().takeoff_alt_m));
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
            ("ATTITUDE_QUATERNION", 31, 200),
            ("LOCAL_POSITION_NED", 32, 100),
            ("GLOBAL_POSITION_INT", 33, 100),
            ("VFR_HUD", 74, 40),
            ("BATTERY_STATUS", 147, 10),
            ("HOME_POSITION", 242, 5),
            ("EXTENDED_SYS_STATE", 245, 10),
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
        let bad_speed = VehicleConfig { takeoff_speed_mps: f64::NAN, ..VehicleConfig::default() };
        assert!(matches!(Vehicle::new(bad_speed), Err(VehicleError::NotPositive { .. })));
    }
}

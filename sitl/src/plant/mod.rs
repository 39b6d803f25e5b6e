//! The paper's quadrotor as a pure, deterministic plant (spec (b)): in, four PWM commands (µs, held over
//! each step) and a step length (µs); out, the true state ([`Truth`]), sensor samples ([`SensorSample`])
//! and the paper's noisy truth-fed state ([`NoisyState`]). No I/O, no clocks: time is the sum of the step
//! lengths; randomness comes from one seed split into a ChaCha8 stream per subsystem.
//!
//! A step runs in named phases, as ArduPilot's `SIM_Multicopter` and PX4's SIH do (a scenario's timed
//! SIM_ parameter sets are not the plant's: whoever steps it applies those due just before the step, as
//! changes of its wind, airframe, sensors, pack and radio through the methods below):
//! 1. `update_wind`: steady + gust + turbulence, evaluated once at the start of the step and held;
//! 2. `rotor_forces`: the commanded lift k_F·h_i·F10(PWM_i) of each rotor (Eq 10 inverse), held;
//! 3. `equations_of_motion`: RK4 substeps of `integrator_step_s` (1 ms) of the Newton-Euler model with
//!    rotor lag (Eqs 7, 27), the last substep shorter if the step is not a multiple;
//! 4. `ground_contact`: the contact constraint after every substep;
//! 5. `drain_battery`: the pack delivers the rotors' power ([`battery`]);
//! 6. time advances; sensors are reconstructed from the resulting state on demand (`truth`,
//!    `sample_sensors`, `sample_state`).

pub mod airframe;
pub mod battery;
pub mod envelope;
pub mod faults;
pub mod ground;
pub mod payload;
pub mod pulses;
pub mod radio;
pub mod rigid_body;
pub mod rotor;
pub mod sensors;
#[cfg(test)]
pub(crate) mod testing;
pub mod wind;

use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

pub use airframe::{Airframe, AirframeConfig};
pub use battery::{Battery, BatteryConfig, BatteryReading};
pub use envelope::{Feasibility, HoverEnvelope, hover_envelope};
pub use faults::{Fault, FaultError, LinkFaults, Sensor, SensorFaults};
pub use ground::GroundConfig;
pub use payload::Payload;
pub use pulses::{Pulse, PulseTrainConfig};
pub use radio::{Radio, RcSchedule};
pub use rigid_body::RigidBodyState;
pub use sensors::{BaroSample, GpsSample, NoisyState, SensorConfig, SensorSample, Sensors, StateNoise};
pub use wind::{GustConfig, TurbulenceConfig, Wind, WindConfig};

use rigid_body::HeldInputs;

/// Configuration and validation errors of the plant.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    #[error("unknown airframe preset {name:?} (known presets: {known})")]
    UnknownPreset { name: String, known: &'static str },
    #[error("invalid {name} = {value}: {reason}")]
    InvalidValue { name: &'static str, value: String, reason: &'static str },
    #[error("invalid plant configuration: {0}")]
    Toml(#[from] toml::de::Error),
}

/// The random streams of one plant seed: each subsystem (and each noise channel) draws from its own
/// ChaCha8 stream, so switching one on or off never changes what another draws.
pub mod stream {
    pub const WIND: u64 = 1;
    pub const ACCEL_WHITE: u64 = 2;
    pub const ACCEL_WALK: u64 = 3;
    pub const GYRO_WHITE: u64 = 4;
    pub const GYRO_WALK: u64 = 5;
    pub const MAG_WHITE: u64 = 6;
    pub const MAG_WALK: u64 = 7;
    pub const BARO_WHITE: u64 = 8;
    pub const BARO_WALK: u64 = 9;
    pub const GPS_POS_WHITE: u64 = 10;
    pub const GPS_POS_WALK: u64 = 11;
    pub const GPS_VEL_WHITE: u64 = 12;
    pub const GPS_VEL_WALK: u64 = 13;
    pub const STATE_NOISE: u64 = 14;
    /// The accelerometer's readings while it reads garbage (`plant::faults`).
    pub const ACCEL_GARBAGE: u64 = 15;
    /// The gyro's readings while it reads garbage.
    pub const GYRO_GARBAGE: u64 = 16;
    /// Which sensor datagrams the plant link loses (SIM_LINK_LOSS, applied by the plant link).
    pub const LINK_LOSS: u64 = 17;
    /// The crosswind pulse train's draws (`[wind.pulses]`, `plant::pulses`), at construction only.
    pub const WIND_PULSES: u64 = 18;
}

/// The generator of stream `stream` of plant seed `seed`.
#[must_use]
pub fn stream_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Everything that defines a plant. Deserialises from TOML tables `[airframe]`, `[wind]`, `[sensors]`,
/// `[ground]`, `[battery]` and a top-level `integrator_step_s`; every key is optional.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlantConfig {
    pub airframe: Airframe,
    pub wind: WindConfig,
    pub sensors: SensorConfig,
    /// RK4 substep (s); default 1 ms.
    pub integrator_step_s: f64,
    pub ground: GroundConfig,
    /// The flight pack (see [`battery`]).
    pub battery: BatteryConfig,
}

impl Default for PlantConfig {
    /// Nominal airframe, no wind, noise-free sensors, 1 ms RK4, ground at D = 0, a full 6-cell 10 Ah pack.
    fn default() -> Self {
        Self {
            airframe: Airframe::nominal(),
            wind: WindConfig::default(),
            sensors: SensorConfig::default(),
            integrator_step_s: 0.001,
            ground: GroundConfig::default(),
            battery: BatteryConfig::default(),
        }
    }
}

impl PlantConfig {
    /// Parse a TOML document.
    ///
    /// # Errors
    /// [`PlantError::Toml`] for syntax errors, unknown keys and invalid airframe values.
    pub fn from_toml_str(text: &str) -> Result<Self, PlantError> {
        Ok(toml::from_str(text)?)
    }

    /// Check the values that deserialisation does not (airframe values are checked there).
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for an invalid airframe, sensor or ground value, or an integrator step
    /// not in (0, τ_m].
    pub fn validate(&self) -> Result<(), PlantError> {
        self.airframe.validate()?;
        self.sensors.validate()?;
        self.ground.validate()?;
        self.battery.validate()?;
        airframe::positive("integrator_step_s", self.integrator_step_s)?;
        if self.integrator_step_s > self.airframe.motor_tau_s {
            return Err(PlantError::InvalidValue {
                name: "integrator_step_s",
                value: self.integrator_step_s.to_string(),
                reason: "must not exceed the rotor lag airframe.motor_tau_s (RK4 accuracy/stability)",
            });
        }
        Ok(())
    }
}

/// Where and how the plant starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialState {
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    /// ZYX (φ, θ, ψ) (rad).
    pub euler_rad: Vector3<f64>,
    pub rate_frd_radps: Vector3<f64>,
    /// Initial rotor lifts (N); `None` = m·g/4 each for the plant's (true) mass: hover.
    pub rotor_lift_n: Option<[f64; 4]>,
}

impl Default for InitialState {
    /// At rest at the origin, level, heading north, rotors at hover lift.
    fn default() -> Self {
        Self {
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            euler_rad: Vector3::zeros(),
            rate_frd_radps: Vector3::zeros(),
            rotor_lift_n: None,
        }
    }
}

/// The true state at the plant's current time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// Plant time (µs).
    pub time_us: u64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    /// v̇ (m/s², NED), including the ground reaction while resting.
    pub acc_ned_mps2: Vector3<f64>,
    pub q_ned_frd: UnitQuaternion<f64>,
    /// ZYX (φ, θ, ψ) (rad).
    pub euler_rad: Vector3<f64>,
    pub rate_frd_radps: Vector3<f64>,
    /// Rᵀ(v̇ - g e3) (m/s², FRD): what an ideal accelerometer reads.
    pub specific_force_frd_mps2: Vector3<f64>,
    /// Rotor lifts F1..F4 (N).
    pub rotor_lift_n: [f64; 4],
    /// The wind held over the last step (m/s NED).
    pub wind_ned_mps: Vector3<f64>,
    /// Resting on the ground (the contact constraint acted in the last substep, or the initial state
    /// rests on the plane).
    pub on_ground: bool,
}

/// The simulated quadrotor.
#[derive(Debug, Clone)]
pub struct Plant {
    config: PlantConfig,
    state: RigidBodyState,
    time_us: u64,
    last_pwm_us: [f64; 4],
    wind: Wind,
    sensors: Sensors,
    state_noise_rng: ChaCha8Rng,
    on_ground: bool,
    battery: Battery,
    /// The motors run (the actuator command's armed or motor-test flag): they draw power from the pack.
    motors_running: bool,
    /// The airframe's radio receiver (no output unless a schedule or the RC input port gives it one).
    radio: Radio,
    /// Delay and loss of the plant link's sensor datagrams (applied by the plant link).
    link_faults: LinkFaults,
}

impl Plant {
    /// A plant in `initial` state at time 0; all randomness from `seed`.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for an invalid configuration (see [`PlantConfig::validate`],
    /// [`Wind::new`]) or a non-finite initial state, negative initial lifts, or a start below the ground.
    pub fn new(config: PlantConfig, initial: &InitialState, seed: u64) -> Result<Self, PlantError> {
        config.validate()?;
        let wind = Wind::new(&config.wind, stream_rng(seed, stream::WIND))?;
        let sensors = Sensors::new(&config.sensors, seed)?;
        let hover = config.airframe.hover_lift_n();
        let rotor_lift_n = initial.rotor_lift_n.unwrap_or([hover; 4]);
        let state = RigidBodyState {
            pos_ned_m: initial.pos_ned_m,
            vel_ned_mps: initial.vel_ned_mps,
            q_ned_frd: rigid_body::attitude_from_euler(&initial.euler_rad).into_inner(),
            rate_frd_radps: initial.rate_frd_radps,
            rotor_lift_n,
        };
        let finite = state.is_finite() && initial.euler_rad.iter().all(|x| x.is_finite());
        if !finite {
            return Err(PlantError::InvalidValue {
                name: "initial state",
                value: format!("{initial:?}"),
                reason: "must be finite",
            });
        }
        if rotor_lift_n.iter().any(|&f| f < 0.0) {
            return Err(PlantError::InvalidValue {
                name: "initial.rotor_lift_n",
                value: format!("{rotor_lift_n:?}"),
                reason: "lifts must be >= 0",
            });
        }
        if config.ground.enabled && state.pos_ned_m.z > config.ground.ground_d_m {
            return Err(PlantError::InvalidValue {
                name: "initial.pos_ned_m",
                value: format!("{:?}", initial.pos_ned_m),
                reason: "starts below the ground plane (D > ground.ground_d_m)",
            });
        }
        let last_pwm_us = std::array::from_fn(|i| rotor::pwm_holding_lift_us(rotor_lift_n[i], i, &config.airframe));
        let battery = Battery::new(config.battery)?;
        let mut plant = Self {
            battery,
            motors_running: true,
            radio: Radio::default(),
            link_faults: LinkFaults::new(seed),
            state,
            time_us: 0,
            last_pwm_us,
            wind,
            sensors,
            state_noise_rng: stream_rng(seed, stream::STATE_NOISE),
            on_ground: false,
            config,
        };
        // The wind at t = 0 (nothing to advance yet), then whether the start rests on the ground.
        plant.update_wind();
        let free_acc = plant.free_acc_ned_mps2();
        plant.on_ground = ground::is_resting(&plant.state, &free_acc, &plant.config.ground);
        Ok(plant)
    }

    /// Advance by `dt_us` with `pwm_us` held (ZOH). RK4 substeps of `integrator_step_s`; when `dt_us` is
    /// not a multiple, the last substep is shorter. The wind is updated once at the start and held.
    /// NaN/±inf PWM is read as 1000 µs, finite PWM is clamped to 1000-2000 µs.
    pub fn step(&mut self, pwm_us: [f64; 4], dt_us: u64) {
        let pwm_us = pwm_us.map(rotor::sanitize_pwm_us);
        self.last_pwm_us = pwm_us;
        if dt_us == 0 {
            return;
        }
        let wind_ned_mps = self.update_wind();
        let inputs = self.rotor_forces(&pwm_us, wind_ned_mps);
        self.equations_of_motion(&inputs, dt_us as f64 * 1e-6);
        self.drain_battery(dt_us as f64 * 1e-6);
        self.time_us += dt_us;
    }

    /// Phase 5: the pack delivers the rotors' power at the lifts the step ended with. A plant without a
    /// pack (`battery.enabled = false`) skips it: [`Plant::battery`] shows nothing to read.
    fn drain_battery(&mut self, dt_s: f64) {
        if !self.config.battery.enabled {
            return;
        }
        let rho = self.config.airframe.air_density_kgpm3;
        self.battery.step(dt_s, &self.state.rotor_lift_n, self.motors_running, rho);
    }

    /// Whether the motors run from the next step (the armed or motor-test flag of the actuator command): stopped
    /// motors draw nothing from the pack. A new plant's motors run (the paper's runs start in the air).
    pub fn set_motors_running(&mut self, running: bool) {
        self.motors_running = running;
    }

    /// Whether the motors ran in the last step (see [`Plant::set_motors_running`]).
    #[must_use]
    pub fn motors_running(&self) -> bool {
        self.motors_running
    }

    /// The pack (None when the plant simulates none).
    #[must_use]
    pub fn battery(&self) -> Option<&Battery> {
        self.config.battery.enabled.then_some(&self.battery)
    }

    /// The pack, for run-time changes (SIM_BAT_DRAIN, SIM_BAT_MIN_PCT).
    pub fn battery_mut(&mut self) -> &mut Battery {
        &mut self.battery
    }

    /// The sensor faults (SIM_GPS_FAIL and the others, see [`faults`]).
    #[must_use]
    pub fn sensor_faults(&self) -> &SensorFaults {
        self.sensors.faults()
    }

    /// The sensor faults, to fail or clear a sensor from the next sample on.
    pub fn sensor_faults_mut(&mut self) -> &mut SensorFaults {
        self.sensors.faults_mut()
    }

    /// Delay and loss of the plant link's sensor datagrams (SIM_LINK_DELAY, SIM_LINK_LOSS).
    #[must_use]
    pub fn link_faults(&self) -> &LinkFaults {
        &self.link_faults
    }

    /// Delay and loss of the plant link, to change them and to draw the losses.
    pub fn link_faults_mut(&mut self) -> &mut LinkFaults {
        &mut self.link_faults
    }

    /// The radio receiver (what the plant link sends as `RC_CHANNELS`).
    #[must_use]
    pub fn radio(&self) -> &Radio {
        &self.radio
    }

    /// The radio receiver, for its schedule, the RC input port's frames and SIM_RC_FAIL.
    pub fn radio_mut(&mut self) -> &mut Radio {
        &mut self.radio
    }

    /// Phase 1: the wind to hold over this step.
    fn update_wind(&mut self) -> Vector3<f64> {
        let height_m = self.config.ground.ground_d_m - self.state.pos_ned_m.z;
        self.wind.update(self.time_us, height_m, &self.state.vel_ned_mps)
    }

    /// Phase 2: what the rotors are driven towards over this step.
    fn rotor_forces(&self, pwm_us: &[f64; 4], wind_ned_mps: Vector3<f64>) -> HeldInputs {
        HeldInputs { lift_cmd_n: rotor::commanded_lift_n(pwm_us, &self.config.airframe), wind_ned_mps }
    }

    /// Phases 3 and 4: RK4 substeps, each followed by the ground contact.
    fn equations_of_motion(&mut self, inputs: &HeldInputs, dt_s: f64) {
        let h = self.config.integrator_step_s;
        // Whole substeps first; a remainder below a nanosecond is rounding, not a substep.
        let substeps = ((dt_s / h) - 1e-9).ceil().max(1.0) as u64;
        for k in 0..substeps {
            let h_k = if k + 1 == substeps { dt_s - h * (substeps - 1) as f64 } else { h };
            self.state = rigid_body::rk4_step(&self.state, inputs, &self.config.airframe, h_k);
            self.on_ground = ground::apply_contact(&mut self.state, &self.config.ground);
        }
    }

    /// The acceleration at the current state with the held wind, ignoring the ground (the translational
    /// part of the derivative: the commanded lifts only move the rotor lag, so they are not needed).
    fn free_acc_ned_mps2(&self) -> Vector3<f64> {
        let airframe = &self.config.airframe;
        let thrust_n = rotor::mix(&self.state.rotor_lift_n, airframe.arm_m, airframe.yaw_moment_m).thrust_n;
        rigid_body::acceleration_ned_mps2(&self.state, thrust_n, &self.wind.current_ned_mps(), airframe)
    }

    /// Plant time (µs).
    #[must_use]
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// The true state now; acceleration and specific force from the equations of motion at the current
    /// state, wind and last PWM (with the ground reaction while resting).
    #[must_use]
    pub fn truth(&self) -> Truth {
        let q_ned_frd = self.state.attitude();
        let acc_ned_mps2 = ground::constrained_acc_ned_mps2(self.free_acc_ned_mps2(), self.on_ground);
        let gravity_ned = Vector3::new(0.0, 0.0, self.config.airframe.gravity_mps2);
        Truth {
            time_us: self.time_us,
            pos_ned_m: self.state.pos_ned_m,
            vel_ned_mps: self.state.vel_ned_mps,
            acc_ned_mps2,
            q_ned_frd,
            euler_rad: rigid_body::euler_rad(&q_ned_frd),
            rate_frd_radps: self.state.rate_frd_radps,
            specific_force_frd_mps2: q_ned_frd.inverse_transform_vector(&(acc_ned_mps2 - gravity_ned)),
            rotor_lift_n: self.state.rotor_lift_n,
            wind_ned_mps: self.wind.current_ned_mps(),
            on_ground: self.on_ground,
        }
    }

    /// IMU, magnetometer and barometer now, and a GPS sample when one is released now, with the sensor
    /// faults applied (see [`faults`]: a sensor that is off is `None`).
    pub fn sample_sensors(&mut self) -> SensorSample {
        let truth = self.truth();
        self.sensors.sample(&truth)
    }

    /// The paper's truth-fed state with `noise` (its own random stream).
    pub fn sample_state(&mut self, noise: &StateNoise) -> NoisyState {
        let truth = self.truth();
        self.sample_state_of(&truth, noise)
    }

    /// As [`Plant::sample_state`], from a [`Truth`] the caller already took at the current time (saves
    /// evaluating the dynamics twice per tick).
    pub fn sample_state_of(&mut self, truth: &Truth, noise: &StateNoise) -> NoisyState {
        debug_assert_eq!(truth.time_us, self.time_us, "truth must be the current one");
        sensors::noisy_state(truth, noise, &mut self.state_noise_rng)
    }

    /// The integrated state (with the raw quaternion).
    #[must_use]
    pub fn state(&self) -> &RigidBodyState {
        &self.state
    }

    /// The PWM in effect (sanitised), or at t = 0 the PWM that holds the initial lifts.
    #[must_use]
    pub fn last_pwm_us(&self) -> [f64; 4] {
        self.last_pwm_us
    }

    /// The configuration; the airframe part is live (see [`Plant::airframe_mut`]), the wind part is what
    /// the plant was built with (run-time wind changes live in [`Plant::wind_mut`]).
    #[must_use]
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// The airframe, for run-time changes (rotor failure via `rotor_health`, disturbance torque, mass).
    /// Keep it physical ([`Airframe::validate`]): the step does not re-check it.
    pub fn airframe_mut(&mut self) -> &mut Airframe {
        &mut self.config.airframe
    }

    /// The wind (e.g. its gust profile, for metrics relative to the gust onset).
    #[must_use]
    pub fn wind(&self) -> &Wind {
        &self.wind
    }

    /// The wind, for run-time changes (gust on demand, turbulence on/off).
    pub fn wind_mut(&mut self) -> &mut Wind {
        &mut self.wind
    }
}

#[cfg(test)]
mod tests;

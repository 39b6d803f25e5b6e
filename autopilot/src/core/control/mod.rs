//! Flight controllers behind one interface: the paper's ACO (`aco`), the per-channel MRAC baseline
//! (`mrac`, the paper's "common adaptive" CA) and a PX4-style PID cascade (`pid`), all feeding the
//! paper's channel distributor and lift curve (`distributor`, Eqs 10, 26-27).
//!
//! In: a [`ControlInput`] (the vehicle state as measured or estimated, NED/FRD, SI units) and a
//! [`Reference`] once per inner tick. Out: four rotor PWM commands in microseconds, rotors numbered as in
//! the paper (1 right, 2 rear, 3 front, 4 left). The inner loops (attitude, rate, LMS) run on every call;
//! the position loop runs on every `inner_hz / position_hz`-th call, starting with the first.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

pub mod aco;
mod builtin;
pub mod distributor;
pub mod filters;
pub mod frames;
pub mod lms;
pub mod mrac;
pub mod pid;
pub mod rate_level;
pub mod registry;

#[cfg(test)]
mod toy_plant;

pub use aco::{AcoConfig, AcoController, AcoWeights};
pub use distributor::ActuatorLimits;
pub use mrac::{MracConfig, MracController};
pub use pid::{PidConfig, PidController};
pub use registry::{ControllerKind, ControllerType, GainScale, ParseControllerKindError, TunableGain};

/// The controller's view of the vehicle. Frames: NED earth, FRD body; Euler angles ZYX.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlInput {
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    /// (roll phi, pitch theta, yaw psi), ZYX, body FRD -> NED.
    pub euler_rad: Vector3<f64>,
    pub rate_frd_radps: Vector3<f64>,
    /// Accelerometer specific force f = R^T (v_dot - g e3); (0, 0, -g) at rest.
    pub specific_force_frd_mps2: Vector3<f64>,
}

/// What the vehicle is asked to do at this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    pub pos_ned_m: Vector3<f64>,
    /// Velocity feed-forward (zero when the reference is position-only).
    pub vel_ned_mps: Vector3<f64>,
    /// Acceleration feed-forward (zero when the reference is position-only).
    pub acc_ned_mps2: Vector3<f64>,
    /// Jerk of the reference (zero when it has none). The cascades that realise a horizontal acceleration
    /// by tilting (ACO, PID) lead their demand by it over the attitude loop's time constant 1/Kη, so a
    /// jerk-limited trajectory is not followed a tilt-lag behind.
    pub jerk_ned_mps3: Vector3<f64>,
    pub yaw_rad: f64,
    /// Attitude-only mode (the paper's Fig. 5): when set, the N and E loops are off, this (phi, theta,
    /// psi) is the attitude setpoint, and only the D loop runs, holding `pos_ned_m.z`.
    pub attitude_rad: Option<Vector3<f64>>,
    /// Direct thrust (offboard attitude with thrust): when set, the collective is this normalized thrust
    /// ([`distributor::ActuatorLimits::collective_from_frac_n`], 0-1) instead of the D loop's demand.
    pub collective_frac: Option<f64>,
    /// Body rates (FRD, rad/s): the rate level (Acro, offboard body rates, a learned policy's
    /// collective thrust and body rates). Alone (no `attitude_rad`), the position and attitude loops
    /// are off and the rate loop tracks these rates, with `collective_frac` as the thrust (the hover
    /// thrust when it is None). With `attitude_rad`, they are the attitude loop's rate feed-forward.
    /// Only a controller whose type [`ControllerType::flies_rates`] takes it; the vehicle refuses the
    /// others before they see one.
    pub rate_frd_radps: Option<Vector3<f64>>,
}

impl Reference {
    /// Hold a position with a yaw, no feed-forward.
    #[must_use]
    pub fn position(pos_ned_m: Vector3<f64>, yaw_rad: f64) -> Self {
        Self {
            pos_ned_m,
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            jerk_ned_mps3: Vector3::zeros(),
            yaw_rad,
            attitude_rad: None,
            collective_frac: None,
            rate_frd_radps: None,
        }
    }

    /// Attitude-only mode: scripted attitude, altitude held at `pos_d_m`.
    #[must_use]
    pub fn attitude(euler_rad: Vector3<f64>, pos_d_m: f64) -> Self {
        Self {
            pos_ned_m: Vector3::new(0.0, 0.0, pos_d_m),
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            jerk_ned_mps3: Vector3::zeros(),
            yaw_rad: euler_rad.z,
            attitude_rad: Some(euler_rad),
            collective_frac: None,
            rate_frd_radps: None,
        }
    }

    /// The rate level: body rates (FRD, rad/s) with a normalized collective thrust (0-1), yaw and
    /// position unused (the yaw kept for logs).
    #[must_use]
    pub fn rates(rate_frd_radps: Vector3<f64>, collective_frac: f64, yaw_rad: f64) -> Self {
        Self {
            yaw_rad,
            collective_frac: Some(collective_frac),
            rate_frd_radps: Some(rate_frd_radps),
            ..Self::position(Vector3::zeros(), yaw_rad)
        }
    }

    /// True when this is the rate level alone (rates without an attitude).
    #[must_use]
    pub fn is_rates_only(&self) -> bool {
        self.rate_frd_radps.is_some() && self.attitude_rad.is_none()
    }
}

/// The horizontal acceleration that leads a jerk feed-forward over an attitude loop of roll and pitch
/// gains `k_att_per_s` (1/s): `jerk / Kη` on N and E, zero on D (the collective acts at once). A cascade
/// realises a demanded horizontal acceleration by tilting, a first-order lag of time constant 1/Kη; adding
/// this lead makes the realised acceleration follow the reference's instead of lagging it.
#[must_use]
pub fn tilt_lead_mps2(jerk_ned_mps3: &Vector3<f64>, k_att_per_s: &[f64; 3]) -> Vector3<f64> {
    let k_tilt = 0.5 * (k_att_per_s[0] + k_att_per_s[1]);
    if !(k_tilt.is_finite() && k_tilt > 0.0 && jerk_ned_mps3.iter().all(|j| j.is_finite())) {
        return Vector3::zeros();
    }
    Vector3::new(jerk_ned_mps3.x / k_tilt, jerk_ned_mps3.y / k_tilt, 0.0)
}

/// Loop rates. The inner loops (rate, attitude, LMS) run at `inner_hz`; the position loop at
/// `position_hz`, which must divide `inner_hz`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LoopRates {
    pub inner_hz: u32,
    pub position_hz: u32,
}

impl Default for LoopRates {
    fn default() -> Self {
        Self { inner_hz: 500, position_hz: 100 }
    }
}

/// Why a [`LoopRates`] is unusable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum LoopRatesError {
    #[error("loop rates must be positive (inner {inner_hz} Hz, position {position_hz} Hz)")]
    NotPositive { inner_hz: u32, position_hz: u32 },
    #[error("the position rate {position_hz} Hz must divide the inner rate {inner_hz} Hz")]
    NotDivisor { inner_hz: u32, position_hz: u32 },
}

impl LoopRates {
    /// Check that both rates are positive and `position_hz` divides `inner_hz`.
    ///
    /// # Errors
    /// [`LoopRatesError`] naming the offending rates.
    pub fn validate(&self) -> Result<(), LoopRatesError> {
        let (inner_hz, position_hz) = (self.inner_hz, self.position_hz);
        if inner_hz == 0 || position_hz == 0 {
            return Err(LoopRatesError::NotPositive { inner_hz, position_hz });
        }
        if !inner_hz.is_multiple_of(position_hz) {
            return Err(LoopRatesError::NotDivisor { inner_hz, position_hz });
        }
        Ok(())
    }

    /// Inner ticks per position tick, `inner_hz / position_hz` (at least 1, whatever the rates).
    #[must_use]
    pub fn position_divider(&self) -> u64 {
        u64::from((self.inner_hz / self.position_hz.max(1)).max(1))
    }

    /// Inner-loop period Δ (s).
    #[must_use]
    pub fn inner_dt_s(&self) -> f64 {
        1.0 / f64::from(self.inner_hz.max(1))
    }

    /// Position-loop period (s): `position_divider()` inner periods.
    #[must_use]
    pub fn position_dt_s(&self) -> f64 {
        self.inner_dt_s() * self.position_divider() as f64
    }
}

/// The nominal model the controllers are designed on (spec A.3): the paper's quadrotor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Airframe {
    /// Nominal mass m̄ (kg).
    pub mass_kg: f64,
    /// Nominal principal inertia Ī (kg·m²), FRD axes.
    pub inertia_kgm2: [f64; 3],
    /// Arm length l (m), rotor to centre.
    pub arm_m: f64,
    /// Yaw-moment coefficient λ (m): rotor yaw torque per newton of lift.
    pub yaw_moment_m: f64,
    /// Rotor first-order lag τ̄ (s).
    pub rotor_tau_s: f64,
    /// Gravity g (m/s²).
    pub gravity_mps2: f64,
}

impl Default for Airframe {
    fn default() -> Self {
        Self {
            mass_kg: 5.2,
            inertia_kgm2: [0.08, 0.08, 0.12],
            arm_m: 0.24,
            yaw_moment_m: 0.02703,
            rotor_tau_s: 0.04,
            gravity_mps2: 9.81,
        }
    }
}

impl Airframe {
    /// Ī as a vector (kg·m²).
    #[must_use]
    pub fn inertia(&self) -> Vector3<f64> {
        Vector3::from(self.inertia_kgm2)
    }

    /// Lift per rotor in hover, m̄ g / 4 (N).
    #[must_use]
    pub fn hover_rotor_lift_n(&self) -> f64 {
        self.mass_kg * self.gravity_mps2 / 4.0
    }

    /// PWM per rotor in hover (Eq 10), µs.
    #[must_use]
    pub fn hover_pwm_us(&self) -> f64 {
        distributor::pwm_from_lift_us(self.hover_rotor_lift_n())
    }

    /// Nominal gyroscopic term γ(ω) = Ī⁻¹(-ω × Īω) (rad/s², Eq 7/9): `((Īy - Īz)/Īx qr,
    /// (Īz - Īx)/Īy rp, (Īx - Īy)/Īz pq)`; the last is 0 for the paper's Īx = Īy (spec A.4 step 3).
    #[must_use]
    pub fn gyroscopic_radps2(&self, rate_frd_radps: &Vector3<f64>) -> Vector3<f64> {
        let [ix, iy, iz] = self.inertia_kgm2;
        let (p, q, r) = (rate_frd_radps.x, rate_frd_radps.y, rate_frd_radps.z);
        Vector3::new((iy - iz) / ix * q * r, (iz - ix) / iy * r * p, (ix - iy) / iz * p * q)
    }
}

/// A flight controller: one call per inner tick.
pub trait Controller: Send {
    /// One inner tick: the state sampled at this tick -> four PWM commands (µs), never NaN.
    fn update(&mut self, input: &ControlInput, reference: &Reference) -> [f64; 4];
    /// Live reconfiguration: take the gains, adaptation rates, bounds, limits, filter cutoffs and nominal
    /// model of this controller's section of `config` from the next [`Controller::update`] on, keeping
    /// the adaptive state (LMS weights, MRAC gains, PID integrators, filter histories); a value outside
    /// new, tighter bounds is projected onto them. `config.rates` is NOT applied: the loop periods are
    /// fixed when the controller is built (the inner loop runs once per plant sample), so a rate change
    /// needs a new controller. Reconfiguring with the configuration in use changes nothing.
    fn reconfigure(&mut self, config: &ControllerConfig);
    fn kind(&self) -> ControllerKind;
    /// Named internal values for telemetry/logging (adaptive weights, mass estimate, integrators).
    fn telemetry(&self) -> Vec<(&'static str, f64)>;
    /// True if any adaptive weight/gain has ever been clipped by its projection bound (sticky).
    fn weights_at_bounds(&self) -> bool;
    /// The last desired attitude (phi, theta, psi) the position loop produced (for logging/plots).
    fn attitude_setpoint_rad(&self) -> Vector3<f64>;
}

/// Everything needed to build any registered controller: the loop rates, the built-in controllers'
/// typed sections (their parameters bind to these fields at the indices ground stations have cached) and
/// every other controller's table, by table name (`[controller.se3]`), read by that controller alone.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct ControllerConfig {
    pub rates: LoopRates,
    pub aco: AcoConfig,
    pub mrac: MracConfig,
    pub pid: PidConfig,
    /// The tables of the controllers registered beside the built-in ones, by table name. A table no
    /// registered controller owns is refused by [`ControllerConfig::validate`].
    #[serde(flatten)]
    pub tables: BTreeMap<String, toml::Table>,
}

/// Why a [`ControllerConfig`] cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    #[error(transparent)]
    LoopRates(#[from] LoopRatesError),
    #[error("{name} = {value_hz} Hz must lie in (0, {max_hz}) Hz at an inner rate of {inner_hz} Hz")]
    FilterCutoff { name: &'static str, value_hz: f64, max_hz: f64, inner_hz: u32 },
    #[error("{name}.{field} = {value} must be finite and positive")]
    NotPositive { name: &'static str, field: &'static str, value: f64 },
    #[error("{name}.{field} = {value} must be finite and >= 0 (0: off)")]
    Negative { name: &'static str, field: &'static str, value: f64 },
    #[error("[{table}]: {message}")]
    Table { table: String, message: String },
    #[error("[{table}] is no registered controller's table (registered: {registered})")]
    UnknownTable { table: String, registered: String },
}

impl ControllerConfig {
    /// Check the loop rates, then every registered controller's part (a table that is not there is its
    /// defaults), and that every table belongs to a registered controller.
    ///
    /// # Errors
    /// The first [`ConfigError`] found.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.rates.validate()?;
        for kind in registry::all() {
            kind.ty().validate(self)?;
        }
        if let Some(table) = self.tables.keys().find(|t| registry::by_table(t).is_none()) {
            return Err(ConfigError::UnknownTable { table: table.clone(), registered: registry::names() });
        }
        Ok(())
    }

    /// A controller's table read as its typed configuration `T`: `T`'s defaults under what the table sets.
    /// `T` should be `#[serde(default, deny_unknown_fields)]`, so a misspelt key is refused.
    ///
    /// # Errors
    /// [`ConfigError::Table`] when the table does not read as a `T`.
    pub fn section<T: serde::de::DeserializeOwned + Default>(&self, table: &str) -> Result<T, ConfigError> {
        match self.tables.get(table) {
            None => Ok(T::default()),
            Some(t) => toml::Value::Table(t.clone()).try_into().map_err(|e: toml::de::Error| ConfigError::Table {
                table: table.to_owned(),
                message: e.message().to_owned(),
            }),
        }
    }

    /// Writes a controller's typed configuration as its table.
    ///
    /// # Errors
    /// [`ConfigError::Table`] when `value` does not serialise as a TOML table.
    pub fn set_section<T: Serialize>(&mut self, table: &str, value: &T) -> Result<(), ConfigError> {
        let t = toml::Table::try_from(value)
            .map_err(|e| ConfigError::Table { table: table.to_owned(), message: e.to_string() })?;
        self.tables.insert(table.to_owned(), t);
        Ok(())
    }
}

/// Build a controller after validating `config`.
///
/// # Errors
/// [`ConfigError`] when the configuration is unusable (see [`ControllerConfig::validate`]).
pub fn try_new_controller(kind: ControllerKind, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError> {
    config.validate()?;
    kind.ty().build(config)
}

/// Build a controller.
///
/// # Panics
/// If `config` fails [`ControllerConfig::validate`]; validate first, or use [`try_new_controller`].
#[must_use]
pub fn new_controller(kind: ControllerKind, config: &ControllerConfig) -> Box<dyn Controller> {
    match try_new_controller(kind, config) {
        Ok(c) => c,
        Err(e) => panic!("invalid controller configuration: {e}"),
    }
}

/// True when every number the controller reads this tick is finite (the sanitising gate).
#[must_use]
pub fn inputs_finite(input: &ControlInput, reference: &Reference) -> bool {
    let vecs_finite = [
        &input.pos_ned_m,
        &input.vel_ned_mps,
        &input.euler_rad,
        &input.rate_frd_radps,
        &input.specific_force_frd_mps2,
        &reference.pos_ned_m,
        &reference.vel_ned_mps,
        &reference.acc_ned_mps2,
    ]
    .iter()
    .all(|v| v.iter().all(|x| x.is_finite()));
    vecs_finite
        && reference.yaw_rad.is_finite()
        && reference.attitude_rad.is_none_or(|a| a.iter().all(|x| x.is_finite()))
        && reference.collective_frac.is_none_or(f64::is_finite)
        && reference.rate_frd_radps.is_none_or(|w| w.iter().all(|x| x.is_finite()))
}

/// The collective thrust (N) a controller commands this tick: the thrust asked for directly
/// (`reference.collective_frac`, [`distributor::ActuatorLimits::collective_from_frac_n`]) when given,
/// else the vertical thrust `vertical_n` (N) of its position loop, tilt-compensated
/// ([`distributor::collective_thrust_n`]) when `tilt_compensate` and taken as it is otherwise.
#[must_use]
pub fn commanded_collective_n(
    reference: &Reference,
    vertical_n: f64,
    euler_rad: &Vector3<f64>,
    limits: &distributor::ActuatorLimits,
    tilt_compensate: bool,
) -> f64 {
    if let Some(frac) = reference.collective_frac {
        limits.collective_from_frac_n(frac)
    } else if tilt_compensate {
        distributor::collective_thrust_n(vertical_n, euler_rad, limits)
    } else {
        vertical_n
    }
}

/// The attitude setpoint (phi, theta, psi) a position loop leaves: the reference's own in attitude-only
/// mode, else the one extracted from the limited thrust vector and the reference yaw.
#[must_use]
pub fn attitude_setpoint_rad(reference: &Reference, limited: &distributor::LimitedThrust) -> Vector3<f64> {
    match reference.attitude_rad {
        Some(att) => att,
        None => distributor::attitude_from_thrust(limited, reference.yaw_rad),
    }
}

/// A controller's loop schedule: the inner and position periods and which inner tick it is at. The
/// position loop runs on every `inner_hz / position_hz`-th tick, starting with the first, and on the first
/// tick with finite inputs if that came later.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopClock {
    /// Inner-loop period Δ (s).
    pub dt_s: f64,
    /// Position-loop period (s).
    pub pos_dt_s: f64,
    pos_divider: u64,
    tick: u64,
    position_loop_ran: bool,
}

impl LoopClock {
    /// At the first tick, at `rates`.
    #[must_use]
    pub fn new(rates: LoopRates) -> Self {
        Self {
            dt_s: rates.inner_dt_s(),
            pos_dt_s: rates.position_dt_s(),
            pos_divider: rates.position_divider(),
            tick: 0,
            position_loop_ran: false,
        }
    }

    /// True when the position loop is to run at this tick.
    #[must_use]
    pub fn position_loop_due(&self) -> bool {
        self.tick.is_multiple_of(self.pos_divider) || !self.position_loop_ran
    }

    /// The position loop has run.
    pub fn position_loop_done(&mut self) {
        self.position_loop_ran = true;
    }

    /// On to the next tick (every call of the controller counts, finite inputs or not).
    pub fn advance(&mut self) {
        self.tick += 1;
    }
}

/// The output a controller holds between ticks: the PWM commands (µs) it gave last, repeated while its
/// inputs are not finite, and the distributor's saturation report on them, which the baselines freeze on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldOutput {
    pub saturation: distributor::MixerSaturation,
    pub pwm_us: [f64; 4],
}

impl HeldOutput {
    /// Hover PWM on every rotor (Eq 10) and nothing saturated, before the first tick.
    #[must_use]
    pub fn hover(airframe: &Airframe) -> Self {
        Self {
            saturation: distributor::MixerSaturation { roll_pitch_scale: 1.0, yaw_factor: 1.0, ..Default::default() },
            pwm_us: [airframe.hover_pwm_us(); 4],
        }
    }

    /// The tail of every controller's inner tick: the collective `collective_n` (N) and the moment
    /// command `moment_cmd_nm` (N·m, FRD) through the channel distributor (Eqs 26-27) and the lift curve
    /// (Eq 10) to four PWM commands clamped to 1000-2000 µs. A finite result becomes the held output and
    /// is returned; a non-finite one leaves the held output as it was (the last good command is
    /// repeated) and gives None.
    pub fn distribute(
        &mut self,
        collective_n: f64,
        moment_cmd_nm: &Vector3<f64>,
        airframe: &Airframe,
        limits: &distributor::ActuatorLimits,
    ) -> Option<distributor::Distribution> {
        let d = distributor::distribute(collective_n, moment_cmd_nm, airframe, limits);
        if d.pwm_us.iter().all(|p| p.is_finite()) {
            self.saturation = d.saturation;
            self.pwm_us = d.pwm_us;
            Some(d)
        } else {
            None
        }
    }
}

/// Clip each component of `v` to `[-limit_i, limit_i]`.
#[must_use]
pub fn clip_abs(v: &Vector3<f64>, limit: &[f64; 3]) -> Vector3<f64> {
    Vector3::new(v.x.clamp(-limit[0], limit[0]), v.y.clamp(-limit[1], limit[1]), v.z.clamp(-limit[2], limit[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every controller: a non-finite input or reference never gives NaN PWM; the first tick gives hover
    /// PWM, later ones hold the last good command, and no adaptive weight or integrator moves meanwhile.
    #[test]
    fn given_non_finite_input_when_ticked_then_hover_first_then_hold_and_state_untouched() {
        use toy_plant::{hover_input, poisoned_inputs};
        let p = Vector3::new(0.0, 0.0, -2.0);
        let good = hover_input(p, 0.0);
        let mut tilted = good;
        tilted.euler_rad.x = 0.1;
        let r = Reference::position(Vector3::new(0.5, 0.0, -2.0), 0.0);
        let hover = Airframe::default().hover_pwm_us();
        for kind in registry::all() {
            for bad in poisoned_inputs(&good) {
                let mut c = new_controller(kind, &ControllerConfig::default());
                assert_eq!(c.update(&bad, &r), [hover; 4], "{kind}: first tick");
                let held = c.update(&tilted, &r);
                let state = c.telemetry();
                for _ in 0..7 {
                    assert_eq!(c.update(&bad, &r), held, "{kind}: hold");
                }
                assert_eq!(c.telemetry(), state, "{kind}: state moved on bad input");
                assert!(c.update(&tilted, &r).iter().all(|x| x.is_finite()), "{kind}: recovers");
            }
            let mut c = new_controller(kind, &ControllerConfig::default());
            let bad_ref = Reference { yaw_rad: f64::NAN, ..r };
            assert_eq!(c.update(&good, &bad_ref), [hover; 4], "{kind}: bad reference");
        }
    }

    /// Every controller, level at rest with an attitude reference and a direct thrust: the four rotor lifts
    /// add up to the normalized collective (0 = 4 F_min, 1 = 4 F_max), whatever the altitude error; without
    /// the thrust, the altitude loop decides (a vehicle 1 m below its reference asks for more than hover).
    #[test]
    fn given_each_kind_when_a_direct_thrust_is_given_then_the_rotors_sum_to_it() {
        use toy_plant::hover_input;
        let input = hover_input(Vector3::new(0.0, 0.0, -1.0), 0.0);
        let limits = distributor::ActuatorLimits::default();
        let hover_n = Airframe::default().hover_rotor_lift_n() * 4.0;
        for kind in registry::all() {
            for frac in [0.2, 0.46, 0.8] {
                let mut c = new_controller(kind, &ControllerConfig::default());
                let r = Reference { collective_frac: Some(frac), ..Reference::attitude(Vector3::zeros(), -2.0) };
                let mut pwm = [0.0; 4];
                for _ in 0..50 {
                    pwm = c.update(&input, &r);
                }
                let total_n: f64 = pwm.iter().map(|&p| distributor::lift_from_pwm_n(p)).sum();
                let want_n = limits.collective_from_frac_n(frac);
                assert!((total_n - want_n).abs() < 0.05, "{kind} thrust {frac}: {total_n} N, want {want_n} N");
            }
            let mut c = new_controller(kind, &ControllerConfig::default());
            let r = Reference::attitude(Vector3::zeros(), -2.0);
            let mut pwm = [0.0; 4];
            for _ in 0..50 {
                pwm = c.update(&input, &r);
            }
            let total_n: f64 = pwm.iter().map(|&p| distributor::lift_from_pwm_n(p)).sum();
            assert!(total_n > hover_n + 0.5, "{kind}: altitude loop climbs: {total_n} N, hover {hover_n} N");
        }
        assert!((limits.collective_from_frac_n(-1.0) - 4.0 * limits.rotor_min_n).abs() < 1e-12);
        assert!((limits.collective_from_frac_n(2.0) - 4.0 * limits.rotor_max_n).abs() < 1e-12);
    }

    /// Every controller, through the trait: a reconfigure with the configuration in use mid-flight leaves
    /// the closed loop bit-identical, and a rate change in `config.rates` is not applied.
    #[test]
    fn given_each_kind_when_reconfigured_mid_flight_with_same_config_then_bit_identical() {
        use toy_plant::{ToyPlant, fly, pwm_bits};
        let p = Vector3::new(0.0, 0.0, -2.0);
        let target = Vector3::new(0.5, -0.5, -2.5);
        let run = |kind: ControllerKind, reconfigure: Option<&ControllerConfig>| {
            let mut plant = ToyPlant::new(p, Vector3::zeros());
            let mut c = new_controller(kind, &ControllerConfig::default());
            fly(c.as_mut(), &mut plant, 500, 1.0, |_| Reference::position(target, 0.0));
            if let Some(config) = reconfigure {
                c.reconfigure(config);
            }
            let tr = fly(c.as_mut(), &mut plant, 500, 1.0, |_| Reference::position(target, 0.0));
            (pwm_bits(&tr), c.telemetry())
        };
        let other_rates =
            ControllerConfig { rates: LoopRates { inner_hz: 1000, position_hz: 50 }, ..ControllerConfig::default() };
        for kind in registry::all() {
            let plain = run(kind, None);
            assert_eq!(plain, run(kind, Some(&ControllerConfig::default())), "{kind}");
            assert_eq!(plain, run(kind, Some(&other_rates)), "{kind}: rates are not applied live");
        }
    }

    #[test]
    fn given_loop_rates_when_validated_then_divisor_and_positivity_enforced() {
        assert_eq!(LoopRates::default().validate(), Ok(()));
        assert_eq!(LoopRates { inner_hz: 1000, position_hz: 100 }.validate(), Ok(()));
        assert_eq!(LoopRates { inner_hz: 250, position_hz: 50 }.validate(), Ok(()));
        assert_eq!(
            LoopRates { inner_hz: 500, position_hz: 300 }.validate(),
            Err(LoopRatesError::NotDivisor { inner_hz: 500, position_hz: 300 })
        );
        assert!(matches!(
            LoopRates { inner_hz: 0, position_hz: 100 }.validate(),
            Err(LoopRatesError::NotPositive { .. })
        ));
        let cfg =
            ControllerConfig { rates: LoopRates { inner_hz: 500, position_hz: 7 }, ..ControllerConfig::default() };
        assert!(matches!(try_new_controller(ControllerKind::ACO, &cfg), Err(ConfigError::LoopRates(_))));
    }

    #[test]
    fn given_negative_or_nan_competent_ca_option_when_validated_then_rejected_by_name() {
        let mut cfg = ControllerConfig::default();
        cfg.mrac.wi_att_radps = -1.0;
        assert_eq!(cfg.validate(), Err(ConfigError::Negative { name: "mrac", field: "wi_att_radps", value: -1.0 }));
        cfg.mrac.wi_att_radps = 0.0;
        cfg.mrac.e_mod_sigma = f64::NAN;
        assert!(matches!(cfg.validate(), Err(ConfigError::Negative { field: "e_mod_sigma", .. })));
        let competent = ControllerConfig { mrac: MracConfig::competent(), ..ControllerConfig::default() };
        assert_eq!(competent.validate(), Ok(()));
    }

    #[test]
    fn given_low_inner_rate_when_validated_then_filter_cutoff_rejected() {
        let cfg = ControllerConfig { rates: LoopRates { inner_hz: 25, position_hz: 5 }, ..ControllerConfig::default() };
        assert!(matches!(cfg.validate(), Err(ConfigError::FilterCutoff { .. })));
    }

    #[test]
    fn given_partial_json_when_deserialised_then_missing_fields_take_spec_defaults() {
        let cfg: ControllerConfig = serde_json::from_str(
            r#"{"rates": {"inner_hz": 1000, "position_hz": 100},
                "aco": {"adaptation_enabled": false, "gamma_w_t_per_s": 1.0},
                "mrac": {"gamma_theta_pos": 3.0, "freeze_on_saturation": false}}"#,
        )
        .expect("valid config");
        assert_eq!(cfg.rates, LoopRates { inner_hz: 1000, position_hz: 100 });
        assert!(!cfg.aco.adaptation_enabled);
        assert_eq!(cfg.aco.gamma_w_t_per_s, 1.0);
        assert_eq!(cfg.aco.gamma_c_r_per_s, 20.0);
        assert_eq!(cfg.mrac.gamma_theta_pos, 3.0);
        assert_eq!(cfg.mrac.gamma_k_att, 1000.0);
        assert_eq!(cfg.pid, PidConfig::default());
        assert_eq!(cfg.validate(), Ok(()));
        let back: ControllerConfig =
            serde_json::from_str(&serde_json::to_string(&cfg).expect("serialise")).expect("round trip");
        // serde_json's default float parser may be off by one ulp, so compare with a tolerance there.
        assert_eq!(
            (back.rates, back.aco.adaptation_enabled, back.mrac.freeze_on_saturation),
            (cfg.rates, false, false)
        );
        assert!((back.pid.limits.rotor_min_n - cfg.pid.limits.rotor_min_n).abs() < 1e-12);
    }

    #[test]
    fn given_each_kind_when_built_then_reports_its_kind() {
        let cfg = ControllerConfig::default();
        for k in registry::all() {
            assert_eq!(new_controller(k, &cfg).kind(), k);
        }
    }

    #[test]
    fn given_hover_when_gyroscopic_term_then_zero_and_sign_matches_euler_equation() {
        let a = Airframe::default();
        assert_eq!(a.gyroscopic_radps2(&Vector3::zeros()), Vector3::zeros());
        let g = a.gyroscopic_radps2(&Vector3::new(1.0, 2.0, 3.0));
        let i = a.inertia();
        let w = Vector3::new(1.0, 2.0, 3.0);
        let expected = -w.cross(&i.component_mul(&w)).component_div(&i);
        assert!((g - expected).abs().max() < 1e-12);
    }
}

//! Test-only toy plant for closed-loop controller tests: the nominal rigid body (spec (b), nominal
//! column: m = 5.2 kg, I = diag(0.08, 0.08, 0.12), Eq 7 with the gyroscopic term), first-order rotor lag
//! `τ = 0.04 s` driven through the exact upper-branch inverse of Eq 10, the forward mixer (Eq 27) and
//! optional quadratic drag. RK4 at `dt_s`; ZOH on the PWM. In: four PWM (µs). Out: a [`ControlInput`].

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

use super::distributor::{lift_from_pwm_n, mix_forward};
use super::{Airframe, ControlInput};

#[derive(Debug, Clone, Copy)]
struct State {
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    q: Quaternion<f64>,
    omega: Vector3<f64>,
    lift: [f64; 4],
}

/// Time derivative of the state.
#[derive(Debug, Clone, Copy)]
struct Deriv {
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    q: Quaternion<f64>,
    omega: Vector3<f64>,
    lift: [f64; 4],
}

pub struct ToyPlant {
    airframe: Airframe,
    /// True mass (kg); defaults to the nominal.
    pub mass_kg: f64,
    /// ρ CdA / 2 (kg/m); 0 disables drag.
    pub drag_kg_per_m: f64,
    /// True inertia (kg·m²), yaw-moment coefficient (m), rotor lag (s), lift factor, disturbance (N·m).
    pub inertia_kgm2: Vector3<f64>,
    pub yaw_moment_m: f64,
    pub rotor_tau_s: f64,
    pub lift_factor: f64,
    pub torque_dist_nm: Vector3<f64>,
    state: State,
}

impl ToyPlant {
    /// At rest at `pos_ned_m` with attitude `euler_rad` and rotors at hover lift.
    pub fn new(pos_ned_m: Vector3<f64>, euler_rad: Vector3<f64>) -> Self {
        let airframe = Airframe::default();
        let hover = airframe.hover_rotor_lift_n();
        let q = super::frames::quaternion_from_euler(&euler_rad).into_inner();
        Self {
            airframe,
            mass_kg: airframe.mass_kg,
            drag_kg_per_m: 0.0,
            inertia_kgm2: airframe.inertia(),
            yaw_moment_m: airframe.yaw_moment_m,
            rotor_tau_s: airframe.rotor_tau_s,
            lift_factor: 1.0,
            torque_dist_nm: Vector3::zeros(),
            state: State { pos: pos_ned_m, vel: Vector3::zeros(), q, omega: Vector3::zeros(), lift: [hover; 4] },
        }
    }

    /// Set the rotor lifts (N) directly (e.g. to the first command, as a plant at trim).
    pub fn set_lifts(&mut self, lift_n: [f64; 4]) {
        self.state.lift = lift_n;
    }

    fn deriv(&self, s: &State, targets: &[f64; 4]) -> Deriv {
        let a = Airframe { yaw_moment_m: self.yaw_moment_m, rotor_tau_s: self.rotor_tau_s, ..self.airframe };
        let (thrust, moment) = mix_forward(&s.lift, &a);
        let uq = UnitQuaternion::new_normalize(s.q);
        let r = uq.to_rotation_matrix();
        let drag = -self.drag_kg_per_m / self.mass_kg * s.vel.norm() * s.vel;
        let acc = Vector3::new(0.0, 0.0, a.gravity_mps2) - thrust / self.mass_kg * r.matrix().column(2) + drag;
        let inertia = Matrix3::from_diagonal(&self.inertia_kgm2);
        let omega_dot = inertia.try_inverse().unwrap_or_else(Matrix3::identity)
            * (moment + self.torque_dist_nm - s.omega.cross(&(inertia * s.omega)));
        let q_dot = s.q * Quaternion::from_imag(s.omega) * 0.5;
        let mut lift = [0.0; 4];
        for i in 0..4 {
            lift[i] = (targets[i] - s.lift[i]) / a.rotor_tau_s;
        }
        Deriv { pos: s.vel, vel: acc, q: q_dot, omega: omega_dot, lift }
    }

    fn add(s: &State, d: &Deriv, h: f64) -> State {
        let mut lift = s.lift;
        for (l, dl) in lift.iter_mut().zip(d.lift.iter()) {
            *l += h * dl;
        }
        State { pos: s.pos + h * d.pos, vel: s.vel + h * d.vel, q: s.q + d.q * h, omega: s.omega + h * d.omega, lift }
    }

    /// Advance by `dt_s` with `pwm_us` held, RK4 in `substeps` steps.
    pub fn step(&mut self, pwm_us: &[f64; 4], dt_s: f64, substeps: u32) {
        let targets = pwm_us.map(|p| self.lift_factor * lift_from_pwm_n(p));
        let h = dt_s / f64::from(substeps);
        for _ in 0..substeps {
            let s = self.state;
            let k1 = self.deriv(&s, &targets);
            let k2 = self.deriv(&Self::add(&s, &k1, 0.5 * h), &targets);
            let k3 = self.deriv(&Self::add(&s, &k2, 0.5 * h), &targets);
            let k4 = self.deriv(&Self::add(&s, &k3, h), &targets);
            let mut next = s;
            next.pos += h / 6.0 * (k1.pos + 2.0 * k2.pos + 2.0 * k3.pos + k4.pos);
            next.vel += h / 6.0 * (k1.vel + 2.0 * k2.vel + 2.0 * k3.vel + k4.vel);
            next.q += (k1.q + k2.q * 2.0 + k3.q * 2.0 + k4.q) * (h / 6.0);
            next.q = next.q.normalize();
            next.omega += h / 6.0 * (k1.omega + 2.0 * k2.omega + 2.0 * k3.omega + k4.omega);
            for i in 0..4 {
                next.lift[i] += h / 6.0 * (k1.lift[i] + 2.0 * k2.lift[i] + 2.0 * k3.lift[i] + k4.lift[i]);
            }
            self.state = next;
        }
    }

    /// Truth sampled now: position, velocity, ZYX Euler, body rates, accelerometer `Rᵀ(v̇ - g e3)`.
    pub fn sense(&self) -> ControlInput {
        let uq = UnitQuaternion::new_normalize(self.state.q);
        let (roll, pitch, yaw) = uq.euler_angles();
        let g = Vector3::new(0.0, 0.0, self.airframe.gravity_mps2);
        let accel = self.deriv(&self.state, &self.state.lift).vel;
        ControlInput {
            pos_ned_m: self.state.pos,
            vel_ned_mps: self.state.vel,
            euler_rad: Vector3::new(roll, pitch, yaw),
            rate_frd_radps: self.state.omega,
            specific_force_frd_mps2: uq.inverse() * (accel - g),
        }
    }
}

/// One sample of a closed-loop run: time (s), the input the controller saw, its PWM answer.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub t_s: f64,
    pub input: ControlInput,
    pub pwm_us: [f64; 4],
}

/// Fly `ctrl` around `plant` for `seconds` at `inner_hz` (plant RK4 at 1 ms or finer), asking
/// `reference(t)`. Panics on a NaN PWM; returns every tick.
pub fn fly(
    ctrl: &mut dyn super::Controller,
    plant: &mut ToyPlant,
    inner_hz: u32,
    seconds: f64,
    reference: impl Fn(f64) -> super::Reference,
) -> Vec<Sample> {
    let dt_s = 1.0 / f64::from(inner_hz);
    let substeps = (dt_s / 1e-3).ceil().max(1.0) as u32;
    let n = (seconds * f64::from(inner_hz)).round() as usize;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let t_s = k as f64 * dt_s;
        let input = plant.sense();
        let pwm_us = ctrl.update(&input, &reference(t_s));
        assert!(pwm_us.iter().all(|p| p.is_finite() && (1000.0..=2000.0).contains(p)), "t {t_s}: {pwm_us:?}");
        out.push(Sample { t_s, input, pwm_us });
        plant.step(&pwm_us, dt_s, substeps);
    }
    out
}

/// The last sample at or before `t_s`.
pub fn at(trace: &[Sample], t_s: f64) -> &Sample {
    let i = trace.iter().rposition(|s| s.t_s <= t_s + 1e-9).unwrap_or(0);
    &trace[i]
}

/// Largest |value| of `f` over samples with `t >= from_s`.
pub fn max_after(trace: &[Sample], from_s: f64, f: impl Fn(&Sample) -> f64) -> f64 {
    trace.iter().filter(|s| s.t_s >= from_s).map(|s| f(s).abs()).fold(0.0, f64::max)
}

/// The spec's mismatch truth (spec (b)): m 5.4 kg, I × 1.3, λ × 1.2, τ 0.05 s, k_F 0.99,
/// τ_dist (0.06, -0.06, 0) N·m, rotors starting at the true hover lift.
pub fn mismatch(plant: &mut ToyPlant) {
    plant.mass_kg = 5.4;
    plant.inertia_kgm2 *= 1.3;
    plant.yaw_moment_m *= 1.2;
    plant.rotor_tau_s = 0.05;
    plant.lift_factor = 0.99;
    plant.torque_dist_nm = Vector3::new(0.06, -0.06, 0.0);
    plant.set_lifts([5.4 * 9.81 / 4.0; 4]);
}

/// A hover `ControlInput` at `pos_ned_m` with yaw `yaw_rad`: at rest, level, accelerometer (0, 0, -g).
pub fn hover_input(pos_ned_m: Vector3<f64>, yaw_rad: f64) -> ControlInput {
    ControlInput {
        pos_ned_m,
        vel_ned_mps: Vector3::zeros(),
        euler_rad: Vector3::new(0.0, 0.0, yaw_rad),
        rate_frd_radps: Vector3::zeros(),
        specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.81),
    }
}

/// Inputs with one non-finite field each.
pub fn poisoned_inputs(base: &ControlInput) -> Vec<ControlInput> {
    let mut v = Vec::new();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut i = *base;
        i.pos_ned_m.x = bad;
        v.push(i);
        let mut i = *base;
        i.vel_ned_mps.z = bad;
        v.push(i);
        let mut i = *base;
        i.euler_rad.y = bad;
        v.push(i);
        let mut i = *base;
        i.rate_frd_radps.z = bad;
        v.push(i);
        let mut i = *base;
        i.specific_force_frd_mps2.z = bad;
        v.push(i);
    }
    v
}

/// A flight with a live reconfigure between two legs: the second leg, the controller's state (weights,
/// gains or integrators, as `state` reads them) just before and just after the reconfigure, and the
/// controller.
pub type Reconfigured<S, C> = (Vec<Sample>, S, S, C);

/// The reconfiguration harness of every controller: `controller` around the mismatch plant (started at
/// rest at `(0, 0, -1.5)` m NED) for `first.1` seconds flying to `first.0`, so its adaptive state moves
/// away from the nominal, then [`super::Controller::reconfigure`] with `config` when given, then
/// `second.1` seconds flying to `second.0`, both at 500 Hz.
pub fn fly_reconfigured<C: super::Controller, S>(
    mut controller: C,
    first: (Vector3<f64>, f64),
    config: Option<&super::ControllerConfig>,
    second: (Vector3<f64>, f64),
    state: impl Fn(&C) -> S,
) -> Reconfigured<S, C> {
    let mut plant = ToyPlant::new(Vector3::new(0.0, 0.0, -1.5), Vector3::zeros());
    mismatch(&mut plant);
    fly(&mut controller, &mut plant, 500, first.1, |_| super::Reference::position(first.0, 0.0));
    let before = state(&controller);
    if let Some(config) = config {
        super::Controller::reconfigure(&mut controller, config);
    }
    let after = state(&controller);
    let tr = fly(&mut controller, &mut plant, 500, second.1, |_| super::Reference::position(second.0, 0.0));
    (tr, before, after, controller)
}

/// Every PWM command of a trace as bits, for bit-identity checks.
pub fn pwm_bits(trace: &[Sample]) -> Vec<[u64; 4]> {
    trace.iter().map(|s| s.pwm_us.map(f64::to_bits)).collect()
}

/// What a reconfigure with the configuration in use must leave alone, given the run without it (`plain`)
/// and the run with it (`same`): the adaptive state across the reconfigure, the second leg's PWM to the
/// bit and the controller's telemetry after it.
pub fn assert_same_config_reconfigure_is_bit_identical<C: super::Controller, S: PartialEq + std::fmt::Debug>(
    plain: &Reconfigured<S, C>,
    same: &Reconfigured<S, C>,
) {
    let (plain_leg, before, _, c_plain) = plain;
    let (same_leg, _, after, c_same) = same;
    assert_eq!(before, after);
    assert_eq!(pwm_bits(plain_leg), pwm_bits(same_leg));
    assert_eq!(c_plain.telemetry(), c_same.telemetry());
}

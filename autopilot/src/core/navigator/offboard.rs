//! Offboard control: the setpoints a companion computer or a script streams (SET_POSITION_TARGET_*,
//! SET_ATTITUDE_TARGET), flown while they are fresh (younger than `offboard_timeout_s` of vehicle time).
//! In: the latest [`OffboardSetpoint`] in local NED (m, m/s, m/s², rad) (its freshness is the vehicle's
//! offboard receiver's, read by the commander), and per
//! step the [`Planner`] and [`NavInput`]. Out: the controller's reference.
//!
//! - A position alone is a target: flown to along a jerk-limited leg, replanned when it moves.
//! - A position with velocity (and acceleration) is a trajectory the sender shapes: tracked as given,
//!   with its feed-forward.
//! - A velocity alone moves a carrot from the vehicle's position, at most 1 m ahead of it.
//! - An attitude holds the altitude where attitude control began, or with a thrust sets the collective;
//!   body rates with it are its rate feed-forward.
//! - Body rates alone are the rate level: the rates with the thrust (hover thrust without one).
//!
//! Yaw is the setpoint's, or integrated from its yaw rate, or held.

use nalgebra::Vector3;

use super::leg::{Leg, MIN_LEG_M, Motion3};
use super::{NavInput, Planner, track};
use crate::core::control::Reference;
use crate::core::control::frames::wrap_pi;

/// How far a velocity setpoint's carrot may run ahead of the vehicle (m).
const CARROT_MAX_M: f64 = 1.0;

/// An offboard setpoint (SET_POSITION_TARGET_* or SET_ATTITUDE_TARGET), already in local NED.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OffboardSetpoint {
    pub pos_ned_m: Option<Vector3<f64>>,
    pub vel_ned_mps: Option<Vector3<f64>>,
    pub acc_ned_mps2: Option<Vector3<f64>>,
    pub yaw_rad: Option<f64>,
    pub yaw_rate_radps: Option<f64>,
    /// Attitude (ZYX Euler rad); without `thrust_frac` the altitude is held where offboard attitude
    /// control began.
    pub attitude_rad: Option<Vector3<f64>>,
    /// Normalized collective thrust 0-1 with an attitude or body rates (SET_ATTITUDE_TARGET.thrust).
    pub thrust_frac: Option<f64>,
    /// Body rates (FRD rad/s): alone, the rate level; with an attitude, its feed-forward.
    pub rate_frd_radps: Option<Vector3<f64>>,
}

/// Offboard state. See the module docs.
#[derive(Debug, Clone, Default)]
pub(crate) struct Offboard {
    latest: Option<OffboardSetpoint>,
    carrot_ned_m: Option<Vector3<f64>>,
    yaw_rad: Option<f64>,
    attitude_hold_d_m: Option<f64>,
    /// The leg to a position target, and the target.
    target: Option<(Vector3<f64>, Leg)>,
}

impl Offboard {
    pub fn set(&mut self, setpoint: OffboardSetpoint) {
        self.latest = Some(setpoint);
    }

    /// Offboard control ended: the next entry starts afresh from the vehicle.
    pub fn leave(&mut self) {
        self.carrot_ned_m = None;
        self.yaw_rad = None;
        self.attitude_hold_d_m = None;
        self.target = None;
    }

    pub fn step(&mut self, p: &mut Planner, input: &NavInput) -> Reference {
        let Some(sp) = self.latest else {
            // Nothing streamed yet: stop where the reference is (the commander leaves on timeout).
            if self.target.is_none() {
                self.target = Some((p.start(input).pos_ned_m, p.stop(input)));
            }
            let Some((_, leg)) = self.target.as_mut() else { return track(&p.start(input), p.yaw_rad) };
            let m = p.fly(leg, input);
            return track(&m, p.yaw_rad);
        };
        if let Some(euler_rad) = sp.attitude_rad {
            if sp.thrust_frac.is_some() {
                // Direct thrust: were the thrust dropped later, hold the altitude the vehicle is at then.
                self.attitude_hold_d_m = Some(input.pos_ned_m.z);
            }
            let pos_d_m = *self.attitude_hold_d_m.get_or_insert(input.pos_ned_m.z);
            p.last = None;
            self.target = None;
            return Reference {
                collective_frac: sp.thrust_frac,
                rate_frd_radps: sp.rate_frd_radps,
                ..Reference::attitude(euler_rad, pos_d_m)
            };
        }
        if let Some(rates) = sp.rate_frd_radps {
            // The rate level: nothing held but the rates; the next attitude starts from here.
            self.attitude_hold_d_m = None;
            p.last = None;
            self.target = None;
            return Reference {
                collective_frac: sp.thrust_frac,
                rate_frd_radps: Some(rates),
                ..Reference::position(input.pos_ned_m, input.yaw_rad)
            };
        }
        self.attitude_hold_d_m = None;
        let yaw = match (sp.yaw_rad, sp.yaw_rate_radps) {
            (Some(y), _) => y,
            (None, Some(rate)) => wrap_pi(self.yaw_rad.unwrap_or(input.yaw_rad) + rate * p.dt_s),
            (None, None) => self.yaw_rad.unwrap_or(input.yaw_rad),
        };
        self.yaw_rad = Some(yaw);
        p.yaw_rad = yaw;
        let m = match (sp.pos_ned_m, sp.vel_ned_mps) {
            (Some(pos), None) if sp.acc_ned_mps2.is_none() => {
                self.carrot_ned_m = None;
                if self.target.as_ref().is_none_or(|(t, _)| (t - pos).norm() > MIN_LEG_M) {
                    self.target = Some((pos, p.retarget(input, pos)));
                }
                let Some((_, leg)) = self.target.as_mut() else { return track(&p.start(input), yaw) };
                p.fly(leg, input)
            }
            (Some(pos), vel) => {
                self.carrot_ned_m = None;
                self.target = None;
                Motion3 {
                    pos_ned_m: pos,
                    vel_ned_mps: vel.unwrap_or_else(Vector3::zeros),
                    acc_ned_mps2: sp.acc_ned_mps2.unwrap_or_else(Vector3::zeros),
                    jerk_ned_mps3: Vector3::zeros(),
                }
            }
            (None, vel) => {
                self.target = None;
                let vel = vel.unwrap_or_else(Vector3::zeros);
                let carrot = self.carrot_ned_m.unwrap_or(input.pos_ned_m) + vel * p.dt_s;
                let ahead = carrot - input.pos_ned_m;
                let carrot = if ahead.norm() > CARROT_MAX_M {
                    input.pos_ned_m + ahead * (CARROT_MAX_M / ahead.norm())
                } else {
                    carrot
                };
                self.carrot_ned_m = Some(carrot);
                Motion3 {
                    pos_ned_m: carrot,
                    vel_ned_mps: vel,
                    acc_ned_mps2: sp.acc_ned_mps2.unwrap_or_else(Vector3::zeros),
                    jerk_ned_mps3: Vector3::zeros(),
                }
            }
        };
        p.last = Some(m);
        track(&m, yaw)
    }
}

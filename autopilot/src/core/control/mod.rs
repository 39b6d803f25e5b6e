//! Flight controllers behind one interface: the paper's ACO (`aco`), the per-channel MRAC baseline
//! (`mrac`, the paper's "common adaptive" CA) and a PX4-style PID cascade (`pid`), all feeding the
//! paper's channel distributor and lift curve (`distributor`, Eqs 10, 26-27).
//!
//! In: a [`ControlInput`] (the vehicle state as measured or estimated, NED/FRD, SI units) and a
//! [`Reference`] once per inner tick. Out: four rotor PWM commands in microseconds, rotors numbered as in
//! the paper (1 right, 2 rear, 3 front, 4 left). The inner loops (attitude, rate, LMS) run on every call;
//! the position loop runs on every `inner_hz / position_hz`-th call, starting with the first.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

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
    pub yaw_rad: f64,
    /// Attitude-only mode (the paper's Fig. 5): when set, the N and E loops are off, this (phi, theta,
    /// psi) is the attitude setpoint, and only the D loop runs, holding `pos_ned_m.z`.
    pub attitude_rad: Option<Vector3<f64>>,
}

impl Reference {
    /// Hold a position with a yaw, no feed-forward.
    #[must_use]
    pub fn position(pos_ned_m: Vector3<f64>, yaw_rad: f64) -> Self {
        Self {
            pos_ned_m,
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            yaw_rad,
            attitude_rad: None,
        }
    }

    /// Attitude-only mode: scripted attitude, altitude held at `pos_d_m`.
    #[must_use]
    pub fn attitude(euler_rad: Vector3<f64>, pos_d_m: f64) -> Self {
        Self {
            pos_ned_m: Vector3::new(0.0, 0.0, pos_d_m),
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            yaw_rad: euler_rad.z,
            attitude_rad: Some(euler_rad),
        }
    }
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

/// Which controller. Parsed from `aco`, `ca`, `pid`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    Aco,
    Ca,
    Pid,
}

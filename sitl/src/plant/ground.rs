//! Ground contact with the plane D = `ground_d_m` (default 0): in, the state after each RK4 substep
//! (1 ms); out, the state with the contact constraint applied and whether the vehicle rests on the ground.
//!
//! The model is a kinematic constraint, like ArduPilot SITL's `GROUND_BEHAVIOR_NO_MOVEMENT`, rather than
//! a stiff spring-damper (which would need sub-millisecond steps to be stable and would bounce):
//!
//! - it acts only when a substep ends strictly below the plane (D > ground_d_m). A vehicle exactly on the
//!   plane whose net force points up is never touched, so a climb from D = 0 is bit-identical to a run
//!   without ground;
//! - then D is set to the plane, the downward velocity is removed (a perfectly inelastic, non-bouncing
//!   touchdown) and so is the horizontal velocity (the feet stick: no sliding, in wind too);
//! - roll and pitch are set to zero, keeping the heading (the vehicle settles on its landing gear), and
//!   the body rates are zeroed (the gear holds it against rotor moments and disturbance torques);
//! - while resting, the truth acceleration is zero (the ground reaction cancels gravity and any thrust
//!   short of lift-off), so the accelerometer reads (0, 0, -g).
//!
//! This airframe cannot idle: its minimum lift 4 × 11.277 N is below m·g (51 N), so disarmed at 1000 µs it
//! sits on the ground, held by this constraint every substep.

use nalgebra::{UnitQuaternion, Vector3};
use serde::Deserialize;

use super::PlantError;
use super::airframe::finite;
use super::rigid_body::RigidBodyState;

/// The `[ground]` table.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundConfig {
    /// Whether there is a ground at all (off: the vehicle falls forever).
    pub enabled: bool,
    /// D of the ground plane (m, NED; 0 = home altitude).
    pub ground_d_m: f64,
}

impl Default for GroundConfig {
    fn default() -> Self {
        Self { enabled: true, ground_d_m: 0.0 }
    }
}

impl GroundConfig {
    /// Check the values.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for a non-finite `ground_d_m`.
    pub fn validate(&self) -> Result<(), PlantError> {
        finite("ground.ground_d_m", self.ground_d_m)
    }
}

/// Apply the contact constraint (module docs) to `state` after a substep; true if it acted.
pub fn apply_contact(state: &mut RigidBodyState, config: &GroundConfig) -> bool {
    if !config.enabled || state.pos_ned_m.z <= config.ground_d_m {
        return false;
    }
    state.pos_ned_m.z = config.ground_d_m;
    state.vel_ned_mps.x = 0.0;
    state.vel_ned_mps.y = 0.0;
    state.vel_ned_mps.z = state.vel_ned_mps.z.min(0.0);
    state.rate_frd_radps = Vector3::zeros();
    let q = state.q_ned_frd;
    if q.i != 0.0 || q.j != 0.0 {
        let (_, _, yaw) = UnitQuaternion::new_normalize(q).euler_angles();
        state.q_ned_frd = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw).into_inner();
    }
    true
}

/// Whether a state that has not been stepped yet (the initial state) rests on the ground: on the plane,
/// not moving up, and pressed down by its net force `acc_ned_mps2` by more than rounding (1e-9 m/s²), so
/// a start at exactly hover lift on the plane does not count as resting.
#[must_use]
pub fn is_resting(state: &RigidBodyState, acc_ned_mps2: &Vector3<f64>, config: &GroundConfig) -> bool {
    config.enabled
        && state.pos_ned_m.z >= config.ground_d_m
        && state.vel_ned_mps.z >= 0.0
        && acc_ned_mps2.z > RESTING_ACC_MPS2
}

/// Net downward acceleration (m/s²) above which an initial state on the plane counts as pressed into it.
const RESTING_ACC_MPS2: f64 = 1e-9;

/// The acceleration (m/s², NED) of a vehicle given its free acceleration: zero while it rests on the
/// ground and is pressed into it, the free acceleration otherwise (including at lift-off).
#[must_use]
pub fn constrained_acc_ned_mps2(free_acc_ned_mps2: Vector3<f64>, on_ground: bool) -> Vector3<f64> {
    if on_ground && free_acc_ned_mps2.z >= 0.0 { Vector3::zeros() } else { free_acc_ned_mps2 }
}

#[cfg(test)]
mod tests {
    use super::super::{InitialState, Plant, PlantConfig};
    use super::*;
    use crate::plant::airframe::Airframe;

    fn plant_with_ground(enabled: bool, initial: &InitialState, airframe: Airframe) -> Plant {
        let config =
            PlantConfig { airframe, ground: GroundConfig { enabled, ground_d_m: 0.0 }, ..PlantConfig::default() };
        Plant::new(config, initial, 9).unwrap()
    }

    #[test]
    fn given_a_disarmed_vehicle_on_the_ground_when_held_at_min_pwm_for_10_s_then_it_neither_sinks_nor_bounces() {
        // Rotors start at hover lift and spin down: the first tens of ms press it into the ground.
        let mut plant = plant_with_ground(true, &InitialState::default(), Airframe::mismatch());
        for k in 0..5000 {
            plant.step([1000.0; 4], 2000);
            let t = plant.truth();
            assert_eq!(t.pos_ned_m.z, 0.0, "step {k}");
            if k >= 50 {
                assert!(t.on_ground);
                assert!(t.vel_ned_mps.norm() < 1e-6 && t.rate_frd_radps.norm() < 1e-6, "step {k}: {t:?}");
                assert_eq!(t.acc_ned_mps2, Vector3::zeros());
            }
        }
        let t = plant.truth();
        // Only the first substep, before the contact acted, moved it (by nanometres).
        assert!(t.pos_ned_m.norm() < 1e-6, "{t:?}");
        // The mismatch plant's disturbance torque did not tip it over.
        assert!(t.euler_rad.x == 0.0 && t.euler_rad.y == 0.0 && t.euler_rad.z.abs() < 1e-6, "{t:?}");
    }

    #[test]
    fn given_no_thrust_when_dropped_from_half_a_metre_then_it_lands_and_rests_without_passing_the_floor() {
        let initial = InitialState {
            pos_ned_m: Vector3::new(0.0, 0.0, -0.5),
            euler_rad: Vector3::new(0.2, -0.1, 0.7),
            rotor_lift_n: Some([0.0; 4]),
            ..InitialState::default()
        };
        let airframe = Airframe { rotor_health: [0.0; 4], ..Airframe::nominal() };
        let mut plant = plant_with_ground(true, &initial, airframe);
        let mut touched_at = None;
        for k in 0..1000 {
            plant.step([1000.0; 4], 2000);
            let t = plant.truth();
            assert!(t.pos_ned_m.z <= 0.0, "step {k}: {t:?}");
            if t.on_ground && touched_at.is_none() {
                touched_at = Some(k);
            }
        }
        // Free fall from 0.5 m takes sqrt(2·0.5/9.81) = 0.319 s (drag barely matters).
        let touched_s = touched_at.unwrap() as f64 * 0.002;
        assert!((touched_s - 0.319).abs() < 0.01, "{touched_s}");
        let t = plant.truth();
        assert!(t.on_ground && t.vel_ned_mps.norm() < 1e-6 && t.pos_ned_m.z == 0.0);
        // It settled level on its gear, heading kept.
        assert!(t.euler_rad.x.abs() < 1e-12 && t.euler_rad.y.abs() < 1e-12);
        assert!((t.euler_rad.z - 0.7).abs() < 1e-9, "{t:?}");
    }

    #[test]
    fn given_a_climb_from_d_0_at_hover_plus_lift_when_compared_with_no_ground_then_trajectories_are_identical() {
        for airframe in [Airframe::nominal(), Airframe::mismatch()] {
            let mut with = plant_with_ground(true, &InitialState::default(), airframe.clone());
            let mut without = plant_with_ground(false, &InitialState::default(), airframe);
            assert!(!with.truth().on_ground);
            for k in 0..500 {
                // From the golden translation run's first command (1837 µs) up to full thrust.
                let pwm = [(1837.0 + k as f64).min(2000.0); 4];
                with.step(pwm, 2000);
                without.step(pwm, 2000);
                let (a, b) = (with.truth(), without.truth());
                assert_eq!(a, b, "step {k}");
                assert!(!a.on_ground);
            }
            assert!(with.truth().pos_ned_m.z < -0.1, "{:?}", with.truth());
        }
    }

    #[test]
    fn given_a_grounded_vehicle_when_thrust_exceeds_weight_then_it_takes_off() {
        let initial = InitialState { rotor_lift_n: Some([11.277; 4]), ..InitialState::default() };
        let mut plant = plant_with_ground(true, &initial, Airframe::nominal());
        assert!(plant.truth().on_ground);
        assert_eq!(plant.truth().acc_ned_mps2, Vector3::zeros());
        for _ in 0..250 {
            plant.step([1000.0; 4], 2000);
        }
        assert!(plant.truth().on_ground);
        for _ in 0..1000 {
            plant.step([1800.0; 4], 2000);
        }
        let t = plant.truth();
        assert!(!t.on_ground && t.pos_ned_m.z < -0.5, "{t:?}");
    }

    #[test]
    fn given_ground_config_when_parsed_then_defaults_and_errors_apply() {
        let g: GroundConfig = toml::from_str("ground_d_m = 2.5").unwrap();
        assert!(g.enabled && g.ground_d_m == 2.5);
        let bad = GroundConfig { enabled: true, ground_d_m: f64::NAN };
        assert!(bad.validate().is_err());
    }
}

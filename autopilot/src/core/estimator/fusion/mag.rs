//! The fused estimator's magnetometer: heading only, from the tilt-compensated field plus the
//! declination, with the tilt error's leak into the levelled heading in its observation row, the dip
//! learnt at heading alignment, and the yaw reset after an outage or a persistently refused heading.

use nalgebra::{UnitQuaternion, Vector3};

use crate::core::control::frames::wrap_pi;

use super::super::MagSample;
use super::super::eskf::{ErrVec, Outcome, ScalarObs, idx};
use super::super::health::{AIDING_MOTION, STUCK_MIN_REPEATS};
use super::{Fusion, Stage, us};

/// A magnetometer whose heading innovations fail the gate this long gets its yaw reset to it (µs).
const MAG_RESET_AFTER_US: u64 = 5_000_000;
/// The magnetometer heading needs a horizontal field of at least this fraction of the total.
const MIN_HORIZONTAL_FIELD_FRACTION: f64 = 0.1;

impl Fusion {
    /// Heading (rad) of the tilt-compensated field plus the declination; `None` when the field is
    /// nearly vertical in the level frame.
    pub(super) fn mag_heading_rad(
        &self,
        q_ned_frd: &UnitQuaternion<f64>,
        field_frd_gauss: &Vector3<f64>,
    ) -> Option<f64> {
        let (roll_rad, pitch_rad, _) = q_ned_frd.euler_angles();
        let level = UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, 0.0) * field_frd_gauss;
        let horizontal = level.x.hypot(level.y);
        (horizontal >= MIN_HORIZONTAL_FIELD_FRACTION * level.norm())
            .then(|| wrap_pi(self.config.mag_declination_deg.to_radians() - level.y.atan2(level.x)))
    }

    pub(super) fn learn_inclination(&mut self, q_ned_frd: &UnitQuaternion<f64>, field_frd_gauss: &Vector3<f64>) {
        let field_ned = q_ned_frd * field_frd_gauss;
        self.field_tan_incl = field_ned.z / field_ned.x.hypot(field_ned.y);
    }

    pub fn update_mag(&mut self, mag: &MagSample) {
        let now = self.now_us.unwrap_or(0);
        self.last_mag_rx_us = Some(now);
        let field = mag.field_frd_gauss;
        let values = [field.x, field.y, field.z];
        self.last_mag_gauss = Some(values);
        let (witness, stuck_us) = (self.imu_witness(), us(self.config.mag_stuck_time_s));
        let stuck = self.mag_stuck.observe(values, now, witness, STUCK_MIN_REPEATS, stuck_us);
        let aiding = self.aiding_witness();
        self.accel_stuck.witness(aiding, &AIDING_MOTION);
        self.gyro_stuck.witness(aiding, &AIDING_MOTION);
        if stuck && matches!(self.stage, Stage::Running(_)) {
            // Not fused: the heading is held on the gyro (and GPS velocity through the covariance).
            self.mag_rejected_since_us = None;
            self.refresh();
            return;
        }
        let mag_was_ok = self.mag_fresh();
        let q_ned_frd = match &mut self.stage {
            Stage::Aligning(alignment) => {
                if let Some(a) = alignment {
                    a.mag_sum_frd_gauss += mag.field_frd_gauss;
                    a.mag_count += 1;
                }
                return;
            }
            Stage::Running(f) => f.x.q_ned_frd,
        };
        let Some(heading_rad) = self.mag_heading_rad(&q_ned_frd, &mag.field_frd_gauss) else {
            self.refresh();
            return;
        };
        let residual_rad = wrap_pi(heading_rad - q_ned_frd.euler_angles().2);
        if !self.yaw_aligned {
            self.reset_yaw(residual_rad, &mag.field_frd_gauss);
            self.refresh();
            return;
        }
        // residual ≈ dtheta_d - tan(I) (cos D dtheta_n + sin D dtheta_e): the tilt error used to level the
        // field leaks into the measured heading in proportion to the tangent of the field's dip I.
        let decl_rad = self.config.mag_declination_deg.to_radians();
        let mut h = ErrVec::zeros();
        h[idx::ATT] = -self.field_tan_incl * decl_rad.cos();
        h[idx::ATT + 1] = -self.field_tan_incl * decl_rad.sin();
        h[idx::ATT + 2] = 1.0;
        let obs = ScalarObs { h, residual: residual_rad, variance: self.config.mag_heading_noise_rad.powi(2) };
        self.innovations.heading_rad = residual_rad;
        let Stage::Running(f) = &mut self.stage else { return };
        let outcome = f.fuse(&[obs], self.config.innovation_gate_sigma);
        self.innovations.heading_rejected = matches!(outcome, Outcome::Rejected { .. });
        match outcome {
            Outcome::Fused { correction, .. } => {
                Self::note_correction(&mut self.history, &correction);
                self.last_mag_fused_us = Some(now);
                self.mag_rejected_since_us = None;
            }
            Outcome::Rejected { .. } => {
                self.gated += 1;
                let since = *self.mag_rejected_since_us.get_or_insert(now);
                // Back after an outage, or persistently inconsistent: trust the magnetometer's heading.
                if !mag_was_ok || now.saturating_sub(since) >= MAG_RESET_AFTER_US {
                    self.reset_yaw(residual_rad, &mag.field_frd_gauss);
                }
            }
        }
        self.refresh();
    }

    /// Rotates the estimate by `dyaw_rad` about NED down and restarts the yaw uncertainty.
    fn reset_yaw(&mut self, dyaw_rad: f64, field_frd_gauss: &Vector3<f64>) {
        let Stage::Running(f) = &mut self.stage else { return };
        let mut q = (UnitQuaternion::from_euler_angles(0.0, 0.0, dyaw_rad) * f.x.q_ned_frd).into_inner();
        q.normalize_mut();
        f.x.q_ned_frd = UnitQuaternion::new_unchecked(q);
        f.reset_component(idx::ATT + 2, self.config.init_yaw_std_rad.powi(2));
        let q = f.x.q_ned_frd;
        self.learn_inclination(&q, field_frd_gauss);
        self.yaw_aligned = true;
        self.mag_rejected_since_us = None;
        self.last_mag_fused_us = self.now_us;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimator::EstimatorConfig;

    #[test]
    fn given_a_small_attitude_error_when_the_heading_is_levelled_with_it_then_the_residual_matches_the_observation_row()
    {
        let fusion = Fusion::new(&EstimatorConfig::default());
        let (decl, incl) = (3.3_f64.to_radians(), 63.6_f64.to_radians());
        let field_ned = Vector3::new(incl.cos() * decl.cos(), incl.cos() * decl.sin(), incl.sin()) * 0.48;
        let q_true = UnitQuaternion::from_euler_angles(0.2, -0.1, 1.0);
        let field_frd = q_true.inverse() * field_ned;
        // The estimate is off by dtheta (NED axes): q_true = exp(dtheta) q_est.
        let dtheta = Vector3::new(0.004, -0.006, 0.005);
        let q_est = UnitQuaternion::from_scaled_axis(-dtheta) * q_true;
        let heading = fusion.mag_heading_rad(&q_est, &field_frd).unwrap();
        let residual = wrap_pi(heading - q_est.euler_angles().2);
        let h = Vector3::new(-incl.tan() * decl.cos(), -incl.tan() * decl.sin(), 1.0);
        assert!((residual - h.dot(&dtheta)).abs() < 1e-4, "residual {residual} vs h.dtheta {}", h.dot(&dtheta));
        // Ignoring the leak of the tilt error into the heading would be wrong by about twice the tilt error.
        assert!((residual - dtheta.z).abs() > 0.005);
    }
}

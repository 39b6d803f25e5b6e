//! The fused estimator's GPS: the fix's quality and stuck checks, the origin at the first fix, the delayed
//! state at the time the fix was valid (latency compensation), the reset of position and velocity when
//! aiding (re)starts, and the sequential velocity then position fusion with the attitude-consistency
//! check on the velocity innovation.

use super::super::eskf::{ErrVec, Outcome, ScalarObs, idx};
use super::super::health::STUCK_MIN_REPEATS;
use super::super::{GeoOrigin, GpsSample};
use super::{Fusion, Refused, Stage, us};

/// Time constant of the low-passed GPS velocity innovation used by the attitude-settled check (µs).
const VEL_NIS_TAU_US: f64 = 2.0e6;

impl Fusion {
    fn gps_quality_ok(&self, gps: &GpsSample) -> bool {
        gps.satellites >= self.config.gps_min_satellites
            && gps.eph_m <= self.config.gps_max_eph_m
            && gps.epv_m <= self.config.gps_max_epv_m
    }

    /// A usable fix arrived at `now_us`: notes it for the lost and stuck checks; whether it is stuck.
    fn observe_gps(&mut self, gps: &GpsSample, now_us: u64) -> bool {
        self.last_gps_rx_us = Some(now_us);
        let v = gps.vel_ned_mps;
        let values = [gps.lat_deg, gps.lon_deg, gps.alt_amsl_m, v.x, v.y, v.z];
        let (witness, stuck_us) = (self.imu_witness(), us(self.config.stuck_time_s));
        let stuck = self.gps_stuck.observe(values, now_us, witness, STUCK_MIN_REPEATS, stuck_us);
        if stuck {
            // Skipped, not refused by the gate: when it moves again it is a return after an outage.
            self.gps_rejected_since_us = None;
        }
        stuck
    }

    pub fn update_gps(&mut self, gps: &GpsSample) -> Result<(), Refused> {
        self.advance(gps.time_us);
        let now = self.now_us.unwrap_or(gps.time_us);
        if !self.gps_quality_ok(gps) {
            self.refresh();
            return Ok(());
        }
        if !matches!(self.stage, Stage::Running(_)) || !self.imu_ok() {
            self.observe_gps(gps, now);
            self.refresh();
            return Ok(());
        }
        // The delayed state: at the time the fix was valid, or (compensation off) the current one.
        let valid_us = gps.time_us.saturating_sub(self.config.gps_delay_us).min(now);
        let lookup_us = if self.config.latency_compensation { valid_us } else { u64::MAX };
        let Some((pos_then_ned_m, vel_then_ned_mps)) = self.history.state_at(lookup_us) else {
            self.refresh();
            return Err(Refused::TooOld);
        };
        if self.observe_gps(gps, now) {
            self.refresh();
            return Ok(());
        }
        let first_fix = self.origin.is_none();
        let origin = *self.origin.get_or_insert(GeoOrigin {
            lat_deg: gps.lat_deg,
            lon_deg: gps.lon_deg,
            alt_amsl_m: gps.alt_amsl_m,
        });
        let gps_pos_ned_m = origin.ned_from_geodetic(gps.lat_deg, gps.lon_deg, gps.alt_amsl_m);
        let c = &self.config;
        let pos_var_m2 = [
            gps.eph_m.max(c.gps_pos_noise_m).powi(2),
            gps.eph_m.max(c.gps_pos_noise_m).powi(2),
            gps.epv_m.max(c.gps_hgt_noise_m).powi(2),
        ];
        let vel_var_m2ps2 = c.gps_vel_noise_mps.powi(2);
        let gate = c.innovation_gate_sigma;
        // A GPS whose positions the gate has been refusing does not get the state reset to it: it has to
        // come back within the gate (a jump is not followed).
        let restart = !self.gps_fresh() && self.gps_rejected_since_us.is_none();
        let Stage::Running(f) = &mut self.stage else { return Ok(()) };

        if restart {
            // Aiding (re)starts: take the GPS position and velocity, moved to now by what the state did
            // since the fix was valid. The height is taken only at the first fix; afterwards the baro kept it.
            let mut dx = ErrVec::zeros();
            for i in 0..3 {
                dx[idx::VEL + i] = gps.vel_ned_mps[i] - vel_then_ned_mps[i];
                f.reset_component(idx::VEL + i, vel_var_m2ps2);
            }
            for i in 0..(if first_fix { 3 } else { 2 }) {
                dx[idx::POS + i] = gps_pos_ned_m[i] - pos_then_ned_m[i];
                f.reset_component(idx::POS + i, pos_var_m2[i]);
            }
            // The barometer keeps agreeing with the moved height.
            dx[idx::BARO] = dx[idx::POS + 2];
            f.inject(&dx);
            Self::note_correction(&mut self.history, &dx);
            self.gps_aiding_since_us = Some(now);
            self.last_gps_fused_us = Some(now);
            self.vel_nis_lp = 1.0;
            self.last_vel_nis_us = Some(now);
            self.fake_pos_hold_ne_m = None;
            self.refresh();
            return Ok(());
        }

        let vel_obs: [ScalarObs; 3] = std::array::from_fn(|i| {
            ScalarObs::direct(idx::VEL + i, gps.vel_ned_mps[i] - vel_then_ned_mps[i], vel_var_m2ps2)
        });
        // Horizontal velocity innovation, normalised by its predicted variance: a tilt error shows up here
        // first (it accelerates the estimate at g * tilt), so it is the attitude-consistency check.
        let vel_nis = (0..2)
            .map(|i| vel_obs[i].residual.powi(2) / (f.p[(idx::VEL + i, idx::VEL + i)] + vel_var_m2ps2))
            .sum::<f64>()
            / 2.0;
        self.innovations.gps_vel_ned_mps = vel_obs.map(|o| o.residual);
        let outcome = f.fuse(&vel_obs, gate);
        self.innovations.gps_vel_rejected = matches!(outcome, Outcome::Rejected { .. });
        match outcome {
            Outcome::Fused { correction, .. } => Self::note_correction(&mut self.history, &correction),
            Outcome::Rejected { .. } => self.gated += 1,
        }
        // Sequential: the position residual sees what the velocity update did to the delayed state.
        let pos_then_ned_m = self.history.state_at(lookup_us).map_or(pos_then_ned_m, |(p, _)| p);
        let pos_obs: [ScalarObs; 3] = std::array::from_fn(|i| {
            ScalarObs::direct(idx::POS + i, gps_pos_ned_m[i] - pos_then_ned_m[i], pos_var_m2[i])
        });
        self.innovations.gps_pos_ned_m = pos_obs.map(|o| o.residual);
        // Whether the horizontal position on its own fails the gate: what "rejected" judges (a vertical
        // disagreement alone, as at a touchdown the filter has not yet followed, is not a GPS fault).
        let hor_nis = (0..2)
            .map(|i| pos_obs[i].residual.powi(2) / (f.p[(idx::POS + i, idx::POS + i)] + pos_var_m2[i]))
            .fold(0.0, f64::max);
        let outcome = f.fuse(&pos_obs, gate);
        self.innovations.gps_pos_rejected = matches!(outcome, Outcome::Rejected { .. });
        match outcome {
            Outcome::Fused { correction, .. } => {
                Self::note_correction(&mut self.history, &correction);
                self.last_gps_fused_us = Some(now);
                self.gps_rejected_since_us = None;
            }
            Outcome::Rejected { .. } => {
                self.gated += 1;
                if hor_nis > gate * gate {
                    self.gps_rejected_since_us.get_or_insert(now);
                } else {
                    self.gps_rejected_since_us = None;
                }
            }
        }
        let dt_us = self.last_vel_nis_us.map_or(0, |t| now.saturating_sub(t)) as f64;
        self.vel_nis_lp += dt_us / (VEL_NIS_TAU_US + dt_us) * (vel_nis - self.vel_nis_lp);
        self.last_vel_nis_us = Some(now);
        self.refresh();
        Ok(())
    }
}

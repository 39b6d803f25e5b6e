//! The setpoint guard: every check of a target the vehicle is asked to fly to, beside the geofence. In: a
//! local NED point (m), or a mission's [`NavItem`]s with the [`Frame`] they are read in, or the estimate's
//! position and velocity; the uploaded [`Fence`], its [`GeofenceConfig`] (GF_*), the origin and home. Out:
//! why the point may not be flown (farther than [`MAX_SETPOINT_FROM_HOME_M`] from home, or outside the
//! geofence), or the breach predicted where the vehicle would stop braking as the navigator brakes.

use nalgebra::Vector3;

use super::geofence::{Fence, GeofenceConfig, Violation};
use super::resolve::{Frame, resolve};
use crate::core::estimator::GeoOrigin;
use crate::core::mission::{NavCommand, NavItem, NavTarget};

/// The farthest from home (m, in 3D) a commanded position may be: an offboard position setpoint, a
/// DO_REPOSITION or a mission item beyond it is refused with a reason, not flown (a setpoint of 1e30 m is
/// finite, but no flight of this airframe goes there).
pub const MAX_SETPOINT_FROM_HOME_M: f64 = 10_000.0;

/// The checks of targets against home and the geofence, as of now (a borrowed view).
#[derive(Debug, Clone, Copy)]
pub struct SetpointGuard<'a> {
    pub fence: &'a Fence,
    pub config: &'a GeofenceConfig,
    pub origin: Option<&'a GeoOrigin>,
    /// Home (NED m), None until set.
    pub home_ned_m: Option<Vector3<f64>>,
}

impl SetpointGuard<'_> {
    /// Why the vehicle will not fly to `pos_ned_m` (NED m): farther than [`MAX_SETPOINT_FROM_HOME_M`] from
    /// home, or outside the geofence.
    ///
    /// # Errors
    /// The reason, in words for a STATUSTEXT.
    pub fn check(&self, pos_ned_m: &Vector3<f64>) -> Result<(), String> {
        if let Some(home) = self.home_ned_m
            && (pos_ned_m - home).norm() > MAX_SETPOINT_FROM_HOME_M
        {
            return Err(format!("over {:.0} km from home", MAX_SETPOINT_FROM_HOME_M / 1000.0));
        }
        match self.fence.violation(self.config, self.origin, self.home_ned_m, pos_ned_m) {
            Some(v) => Err(v.to_string()),
            None => Ok(()),
        }
    }

    /// Why the mission cannot be flown: an item whose point (resolved as the navigator will fly it) is
    /// outside the geofence or too far. Items at "here" (and those the frame cannot place yet: no origin)
    /// have nothing to check until they are flown.
    ///
    /// # Errors
    /// `Mission: item N <why>`.
    pub fn check_mission(&self, items: &[NavItem], frame: &Frame) -> Result<(), String> {
        for item in items {
            let target = match item.command {
                NavCommand::Waypoint { target, .. }
                | NavCommand::LoiterTime { target, .. }
                | NavCommand::LoiterUnlimited { target, .. }
                | NavCommand::Land { target, .. } => target,
                _ => continue,
            };
            if matches!(target, NavTarget::Here { .. }) {
                continue;
            }
            let Ok(p) = resolve(&target, frame, Vector3::zeros()) else { continue };
            if let Err(why) = self.check(&p) {
                return Err(format!("Mission: item {} {why}", item.seq));
            }
        }
        Ok(())
    }

    /// The geofence breach predicted from the estimate (NED m, m/s): at the position, or where a stop at
    /// `acc_mps2` and `jerk_mps3` (MPC_ACC_HOR, MPC_JERK_AUTO) would end.
    #[must_use]
    pub fn predicted_breach(
        &self,
        pos_ned_m: &Vector3<f64>,
        vel_ned_mps: &Vector3<f64>,
        acc_mps2: f64,
        jerk_mps3: f64,
    ) -> Option<Violation> {
        self.fence.predicted_breach(
            self.config,
            self.origin,
            self.home_ned_m,
            pos_ned_m,
            vel_ned_mps,
            acc_mps2,
            jerk_mps3,
        )
    }
}

//! The plan as a viewer draws it: home, the mission's points, the geofence's zones and the rally points,
//! all in the vehicle's local NED (m), resolved by the same resolver the navigator flies them with.

use nalgebra::{Vector2, Vector3};

use crate::core::mission::NavCommand;
use crate::core::plan::geofence::Zone;
use crate::core::plan::resolve;

use super::Vehicle;

/// What a viewer draws of the plan (every point in the vehicle's local NED, m, about the estimator's
/// origin). Items the vehicle cannot place yet (no origin, no home altitude) are left out; a zone needs
/// the origin.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlanView {
    pub home_ned_m: Option<Vector3<f64>>,
    /// The mission's points in order, each with its sequence number.
    pub mission_ned_m: Vec<(u16, Vector3<f64>)>,
    /// The item the navigator flies now (None: no mission).
    pub mission_current: Option<u16>,
    /// Polygon zones (NE m), inclusion or not.
    pub fence_polygons_ne_m: Vec<(bool, Vec<Vector2<f64>>)>,
    /// Circle zones: centre (NE m), radius (m), inclusion or not.
    pub fence_circles_ne_m: Vec<(bool, Vector2<f64>, f64)>,
    /// GF_MAX_VER_DIST as a down coordinate (m NED) above home, when set.
    pub fence_max_d_m: Option<f64>,
    /// GF_MAX_HOR_DIST about home (m), when set.
    pub fence_max_hor_m: Option<f64>,
    pub rally_ned_m: Vec<Vector3<f64>>,
}

impl Vehicle {
    /// The plan as a viewer draws it, now (see [`PlanView`]).
    #[must_use]
    pub fn plan_view(&self) -> PlanView {
        let frame = self.frame();
        let home_ned_m = self.commander.home_ned_m();
        let here = self.estimator.state().pos_ned_m;
        let mission_ned_m = self
            .plan
            .items()
            .iter()
            .filter_map(|item| {
                let target = match item.command {
                    NavCommand::Waypoint { target, .. }
                    | NavCommand::LoiterTime { target, .. }
                    | NavCommand::LoiterUnlimited { target, .. }
                    | NavCommand::Land { target, .. } => target,
                    NavCommand::Takeoff { .. }
                    | NavCommand::ReturnToLaunch
                    | NavCommand::Delay { .. }
                    | NavCommand::Jump { .. }
                    | NavCommand::ChangeSpeed { .. } => return None,
                };
                resolve(&target, &frame, here).ok().map(|p| (item.seq, p))
            })
            .collect();
        let mission_current = (self.navigator.mission_len() > 0).then(|| self.navigator.current_seq());
        let (mut polygons, mut circles) = (Vec::new(), Vec::new());
        if let Some(origin) = frame.origin {
            let ne = |(lat, lon): (f64, f64)| origin.ned_from_geodetic(lat, lon, origin.alt_amsl_m).xy();
            for zone in self.plan.fence().zones() {
                match zone {
                    Zone::Polygon { inclusion, vertices_deg } => {
                        polygons.push((*inclusion, vertices_deg.iter().map(|&v| ne(v)).collect()));
                    }
                    Zone::Circle { inclusion, center_deg, radius_m } => {
                        circles.push((*inclusion, ne(*center_deg), *radius_m));
                    }
                }
            }
        }
        let geofence = &self.config.commander.geofence;
        let ground_d_m = home_ned_m.map_or(0.0, |h| h.z);
        let rally_ned_m = match frame.origin {
            Some(origin) => {
                self.plan.rally().points_ne_m(&origin).into_iter().map(|p| Vector3::new(p.x, p.y, ground_d_m)).collect()
            }
            None => Vec::new(),
        };
        PlanView {
            home_ned_m,
            mission_ned_m,
            mission_current,
            fence_polygons_ne_m: polygons,
            fence_circles_ne_m: circles,
            fence_max_d_m: (geofence.max_ver_dist_m > 0.0).then_some(ground_d_m - geofence.max_ver_dist_m),
            fence_max_hor_m: (geofence.max_hor_dist_m > 0.0).then_some(geofence.max_hor_dist_m),
            rally_ned_m,
        }
    }
}

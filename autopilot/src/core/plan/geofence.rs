//! The geofence and the rally points: what a ground station uploads with the mission protocol's FENCE
//! (`mission_type` 1) and RALLY (2) transfers, validated, and the checks the vehicle makes against them.
//! In: mission items (as [`MissionItem`]), the estimator's origin, home, a position and velocity (NED m,
//! m/s). Out: a [`Fence`] or [`Rally`], or the [`MissionError`] of the first bad item; whether a point is
//! inside ([`Fence::violation`]), and whether the vehicle will leave it before it can stop
//! ([`Fence::predicted_breach`]).
//!
//! Fence items (MAVLink's geofence commands, as QGroundControl, MAVSDK and PX4 use them): polygon vertices
//! NAV_FENCE_POLYGON_VERTEX_INCLUSION (5001) / _EXCLUSION (5002), param1 the polygon's vertex count (>= 3,
//! its vertices consecutive items), param2 the inclusion group (ignored); circles
//! NAV_FENCE_CIRCLE_INCLUSION (5003) / _EXCLUSION (5004), param1 the radius (m); NAV_FENCE_RETURN_POINT
//! (5000) is kept for the ground station and not flown. Rally items: NAV_RALLY_POINT (5100). Every item is
//! in a global frame with latitude and longitude set; altitudes are not part of a fence.
//!
//! The rules are PX4's: inside the fence means inside at least one inclusion zone (when there is one) and
//! outside every exclusion zone, and, with `GF_MAX_HOR_DIST` / `GF_MAX_VER_DIST` > 0, no farther from home
//! horizontally / higher above home than that. A breach is predicted from the position and velocity: the
//! point where the vehicle would stop if it started braking now (the jerk-limited stopping distance at
//! `MPC_ACC_HOR` and `MPC_JERK_AUTO`, plus a reaction time of [`REACTION_S`]) must be inside too.

use ::mavlink::dialects::common::MavCmd;
use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::estimator::GeoOrigin;
use crate::core::mavlink::units::dege7_to_deg;
use crate::core::mission::{LAT_LIMIT_DEGE7, LON_LIMIT_DEGE7, MissionError, MissionItem, XY_UNSET, is_global_frame};

/// The time the vehicle keeps going before its brake takes hold (s): the controller's lag.
pub const REACTION_S: f64 = 0.5;

/// The commands a fence may hold.
pub const FENCE_COMMANDS: [MavCmd; 5] = [
    MavCmd::MAV_CMD_NAV_FENCE_RETURN_POINT,
    MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
    MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
    MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
];

/// The fence's parameters (PX4 names in the field docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeofenceConfig {
    /// What the vehicle does on a breach (GF_ACTION: 0 none, 1 warning, 2 hold, 3 return, 4 terminate,
    /// 5 land; see [`crate::core::commander::failsafe::geofence_action`]).
    pub action: u32,
    /// Largest horizontal distance from home (m; GF_MAX_HOR_DIST; 0 = no limit).
    pub max_hor_dist_m: f64,
    /// Largest height above home (m; GF_MAX_VER_DIST; 0 = no limit).
    pub max_ver_dist_m: f64,
}

impl Default for GeofenceConfig {
    /// PX4's: hold on a breach, no distance limits.
    fn default() -> Self {
        Self { action: 2, max_hor_dist_m: 0.0, max_ver_dist_m: 0.0 }
    }
}

/// A zone of the fence, geodetic (deg).
#[derive(Debug, Clone, PartialEq)]
pub enum Zone {
    Polygon { inclusion: bool, vertices_deg: Vec<(f64, f64)> },
    Circle { inclusion: bool, center_deg: (f64, f64), radius_m: f64 },
}

impl Zone {
    fn inclusion(&self) -> bool {
        match self {
            Self::Polygon { inclusion, .. } | Self::Circle { inclusion, .. } => *inclusion,
        }
    }

    /// Whether the NE point `p` (m about `origin`) is inside the zone.
    fn contains(&self, origin: &GeoOrigin, p: Vector2<f64>) -> bool {
        let ne = |(lat, lon): (f64, f64)| origin.ned_from_geodetic(lat, lon, origin.alt_amsl_m).xy();
        match self {
            Self::Circle { center_deg, radius_m, .. } => (p - ne(*center_deg)).norm() <= *radius_m,
            Self::Polygon { vertices_deg, .. } => {
                // Crossing number: a ray from p toward +east crosses the boundary an odd number of times.
                let v: Vec<Vector2<f64>> = vertices_deg.iter().map(|&d| ne(d)).collect();
                let mut inside = false;
                for i in 0..v.len() {
                    let (a, b) = (v[i], v[(i + 1) % v.len()]);
                    if (a.x > p.x) != (b.x > p.x) {
                        let east_at = a.y + (p.x - a.x) / (b.x - a.x) * (b.y - a.y);
                        if p.y < east_at {
                            inside = !inside;
                        }
                    }
                }
                inside
            }
        }
    }
}

/// Why a point is outside the fence; `Display` fits a STATUSTEXT.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, thiserror::Error)]
pub enum Violation {
    #[error("beyond GF_MAX_HOR_DIST")]
    MaxHorizontal,
    #[error("above GF_MAX_VER_DIST")]
    MaxVertical,
    #[error("outside the fence")]
    OutsideInclusion,
    #[error("in an exclusion zone")]
    InsideExclusion,
}

/// A validated fence: the items as uploaded (for downloads and persistence) and their zones.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Fence {
    items: Vec<MissionItem>,
    zones: Vec<Zone>,
}

fn invalid(seq: u16, param: u8, reason: &'static str) -> MissionError {
    MissionError::InvalidParam { seq, param, reason }
}

/// Checks what every fence and rally item needs: a global frame and a latitude and longitude in range.
fn check_global_position(item: &MissionItem) -> Result<(f64, f64), MissionError> {
    let seq = item.seq;
    if !is_global_frame(item.frame) {
        return Err(MissionError::UnsupportedFrame { seq, frame: item.frame as u32, command: item.command as u32 });
    }
    if item.x == XY_UNSET || !(-LAT_LIMIT_DEGE7..=LAT_LIMIT_DEGE7).contains(&item.x) {
        return Err(invalid(seq, 5, "latitude not set or out of range"));
    }
    if item.y == XY_UNSET || !(-LON_LIMIT_DEGE7..=LON_LIMIT_DEGE7).contains(&item.y) {
        return Err(invalid(seq, 6, "longitude not set or out of range"));
    }
    Ok((dege7_to_deg(item.x), dege7_to_deg(item.y)))
}

/// Checks one fence item on its own (as it arrives in an upload); [`Fence::new`] checks how the items
/// go together.
///
/// # Errors
/// The first rule of the module docs the item breaks.
pub fn validate_fence_item(item: &MissionItem) -> Result<(), MissionError> {
    use MavCmd as C;
    if !FENCE_COMMANDS.contains(&item.command) {
        return Err(MissionError::UnsupportedCommand { seq: item.seq, command: item.command as u32 });
    }
    check_global_position(item)?;
    let n = item.param1;
    match item.command {
        C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION | C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
            if !(n.is_finite() && n.fract() == 0.0 && (3.0..=1000.0).contains(&n)) =>
        {
            Err(invalid(item.seq, 1, "vertex count must be 3 or more"))
        }
        C::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | C::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
            if !(n.is_finite() && n > 0.0) =>
        {
            Err(invalid(item.seq, 1, "circle radius must be > 0"))
        }
        _ => Ok(()),
    }
}

/// Checks one rally item.
///
/// # Errors
/// A command other than NAV_RALLY_POINT, or a position that is not a global one.
pub fn validate_rally_item(item: &MissionItem) -> Result<(), MissionError> {
    if item.command != MavCmd::MAV_CMD_NAV_RALLY_POINT {
        return Err(MissionError::UnsupportedCommand { seq: item.seq, command: item.command as u32 });
    }
    check_global_position(item)?;
    if !item.z.is_finite() {
        return Err(invalid(item.seq, 7, "altitude not finite"));
    }
    Ok(())
}

impl Fence {
    /// A fence from its items in order.
    ///
    /// # Errors
    /// The first bad item ([`validate_fence_item`]), a sequence out of order, or a polygon whose vertex
    /// count does not match its consecutive vertices.
    pub fn new(items: Vec<MissionItem>) -> Result<Self, MissionError> {
        use MavCmd as C;
        let mut zones = Vec::new();
        let mut i = 0;
        while i < items.len() {
            let item = &items[i];
            if usize::from(item.seq) != i {
                return Err(MissionError::Sequence { index: i, seq: item.seq });
            }
            validate_fence_item(item)?;
            let at = |it: &MissionItem| (dege7_to_deg(it.x), dege7_to_deg(it.y));
            match item.command {
                C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION | C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION => {
                    let n = item.param1 as usize;
                    let vertices = items.get(i..i + n).filter(|vs| {
                        vs.iter().enumerate().all(|(k, v)| {
                            v.command == item.command && v.param1 == item.param1 && usize::from(v.seq) == i + k
                        })
                    });
                    let Some(vertices) = vertices else {
                        return Err(invalid(item.seq, 1, "polygon vertex count mismatch"));
                    };
                    for v in vertices {
                        validate_fence_item(v)?;
                    }
                    let inclusion = item.command == C::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION;
                    zones.push(Zone::Polygon { inclusion, vertices_deg: vertices.iter().map(at).collect() });
                    i += n;
                }
                C::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | C::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION => {
                    let inclusion = item.command == C::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION;
                    zones.push(Zone::Circle { inclusion, center_deg: at(item), radius_m: f64::from(item.param1) });
                    i += 1;
                }
                _ => i += 1,
            }
        }
        Ok(Self { items, zones })
    }

    /// The items as uploaded.
    #[must_use]
    pub fn items(&self) -> &[MissionItem] {
        &self.items
    }

    #[must_use]
    pub fn zones(&self) -> &[Zone] {
        &self.zones
    }

    /// Why `pos_ned_m` is outside the fence, or None when inside (and when there is nothing to check:
    /// no zones and no distance limits). Zones need the `origin`; distance limits need `home_ned_m`.
    #[must_use]
    pub fn violation(
        &self,
        config: &GeofenceConfig,
        origin: Option<&GeoOrigin>,
        home_ned_m: Option<Vector3<f64>>,
        pos_ned_m: &Vector3<f64>,
    ) -> Option<Violation> {
        if let Some(home) = home_ned_m {
            if config.max_hor_dist_m > 0.0 && (pos_ned_m - home).xy().norm() > config.max_hor_dist_m {
                return Some(Violation::MaxHorizontal);
            }
            if config.max_ver_dist_m > 0.0 && home.z - pos_ned_m.z > config.max_ver_dist_m {
                return Some(Violation::MaxVertical);
            }
        }
        let origin = origin?;
        let p = pos_ned_m.xy();
        if self.zones.iter().any(|z| !z.inclusion() && z.contains(origin, p)) {
            return Some(Violation::InsideExclusion);
        }
        let mut inclusions = self.zones.iter().filter(|z| z.inclusion()).peekable();
        if inclusions.peek().is_some() && !inclusions.any(|z| z.contains(origin, p)) {
            return Some(Violation::OutsideInclusion);
        }
        None
    }

    /// Whether the vehicle at `pos_ned_m` moving at `vel_ned_mps` would stop outside the fence if it
    /// started braking now, at `acc_mps2` with jerk `jerk_mps3` (see the module docs); the violation
    /// of the stopping point (or of the position itself).
    #[must_use]
    #[allow(clippy::too_many_arguments)]
    pub fn predicted_breach(
        &self,
        config: &GeofenceConfig,
        origin: Option<&GeoOrigin>,
        home_ned_m: Option<Vector3<f64>>,
        pos_ned_m: &Vector3<f64>,
        vel_ned_mps: &Vector3<f64>,
        acc_mps2: f64,
        jerk_mps3: f64,
    ) -> Option<Violation> {
        let stop = pos_ned_m + stopping_offset_m(vel_ned_mps, acc_mps2, jerk_mps3);
        self.violation(config, origin, home_ned_m, pos_ned_m)
            .or_else(|| self.violation(config, origin, home_ned_m, &stop))
    }
}

/// Where the vehicle stops relative to where it is (m, NED) if it starts braking now: per axis
/// v·t_r + v²/(2a) + |v|·a/(2j) in the direction of motion (the reaction time, the braking at `acc_mps2`,
/// and the jerk-limited ramp into it).
#[must_use]
pub fn stopping_offset_m(vel_ned_mps: &Vector3<f64>, acc_mps2: f64, jerk_mps3: f64) -> Vector3<f64> {
    vel_ned_mps.map(|v| {
        let s = v.abs();
        v.signum() * (s * REACTION_S + s * s / (2.0 * acc_mps2.max(0.1)) + s * acc_mps2 / (2.0 * jerk_mps3.max(0.1)))
    })
}

/// Validated rally points: the items as uploaded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Rally {
    items: Vec<MissionItem>,
}

impl Rally {
    /// Rally points from their items in order.
    ///
    /// # Errors
    /// The first bad item, or a sequence out of order.
    pub fn new(items: Vec<MissionItem>) -> Result<Self, MissionError> {
        for (i, item) in items.iter().enumerate() {
            if usize::from(item.seq) != i {
                return Err(MissionError::Sequence { index: i, seq: item.seq });
            }
            validate_rally_item(item)?;
        }
        Ok(Self { items })
    }

    #[must_use]
    pub fn items(&self) -> &[MissionItem] {
        &self.items
    }

    /// The rally points' horizontal positions (NE m about `origin`).
    #[must_use]
    pub fn points_ne_m(&self, origin: &GeoOrigin) -> Vec<Vector2<f64>> {
        self.items
            .iter()
            .map(|it| origin.ned_from_geodetic(dege7_to_deg(it.x), dege7_to_deg(it.y), origin.alt_amsl_m).xy())
            .collect()
    }

    /// Where a return from `pos_ned_m` goes: the nearest rally point when it is closer (horizontally) than
    /// home, else home. The point is at home's down coordinate (the ground is taken as level).
    #[must_use]
    pub fn return_point(
        &self,
        origin: Option<&GeoOrigin>,
        home_ned_m: Vector3<f64>,
        pos_ned_m: &Vector3<f64>,
    ) -> Vector3<f64> {
        let Some(origin) = origin else { return home_ned_m };
        let here = pos_ned_m.xy();
        let home_d = (home_ned_m.xy() - here).norm();
        self.points_ne_m(origin)
            .into_iter()
            .map(|p| ((p - here).norm(), p))
            .filter(|(d, _)| *d < home_d)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(home_ned_m, |(_, p)| Vector3::new(p.x, p.y, home_ned_m.z))
    }
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::MavFrame;

    use super::*;

    const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397742, lon_deg: 8.545594, alt_amsl_m: 488.0 };

    fn at(seq: u16, command: MavCmd, param1: f32, n_m: f64, e_m: f64) -> MissionItem {
        let (lat, lon, _) = ORIGIN.geodetic_from_ned(&Vector3::new(n_m, e_m, 0.0));
        MissionItem {
            seq,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            command,
            param1,
            param2: 0.0,
            param3: 0.0,
            param4: 0.0,
            x: (lat * 1e7).round() as i32,
            y: (lon * 1e7).round() as i32,
            z: 0.0,
            autocontinue: false,
        }
    }

    /// A square inclusion polygon 40 m a side around the origin, and a 5 m exclusion circle at (10, 10).
    fn fence() -> Fence {
        let v = MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION;
        Fence::new(vec![
            at(0, v, 4.0, -20.0, -20.0),
            at(1, v, 4.0, 20.0, -20.0),
            at(2, v, 4.0, 20.0, 20.0),
            at(3, v, 4.0, -20.0, 20.0),
            at(4, MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 5.0, 10.0, 10.0),
        ])
        .expect("valid fence")
    }

    #[test]
    fn given_a_polygon_and_an_exclusion_circle_then_points_are_judged_as_px4_does() {
        let f = fence();
        let c = GeofenceConfig::default();
        let check = |n: f64, e: f64| f.violation(&c, Some(&ORIGIN), None, &Vector3::new(n, e, -5.0));
        assert_eq!(check(0.0, 0.0), None);
        assert_eq!(check(19.0, -19.0), None);
        assert_eq!(check(21.0, 0.0), Some(Violation::OutsideInclusion));
        assert_eq!(check(0.0, -25.0), Some(Violation::OutsideInclusion));
        assert_eq!(check(11.0, 9.0), Some(Violation::InsideExclusion));
        assert_eq!(f.violation(&c, None, None, &Vector3::new(100.0, 0.0, 0.0)), None, "no origin: zones unknown");
    }

    #[test]
    fn given_distance_limits_then_they_apply_from_home() {
        let c = GeofenceConfig { max_hor_dist_m: 10.0, max_ver_dist_m: 20.0, ..GeofenceConfig::default() };
        let f = Fence::default();
        let home = Some(Vector3::new(1.0, 1.0, 0.0));
        assert_eq!(f.violation(&c, None, home, &Vector3::new(10.9, 1.0, -19.0)), None);
        assert_eq!(f.violation(&c, None, home, &Vector3::new(11.1, 1.0, -1.0)), Some(Violation::MaxHorizontal));
        assert_eq!(f.violation(&c, None, home, &Vector3::new(1.0, 1.0, -20.5)), Some(Violation::MaxVertical));
    }

    #[test]
    fn given_motion_toward_the_limit_then_the_breach_is_predicted_before_the_limit() {
        let c = GeofenceConfig { max_hor_dist_m: 10.0, ..GeofenceConfig::default() };
        let f = Fence::default();
        let home = Some(Vector3::zeros());
        let v = Vector3::new(1.0, 0.0, 0.0);
        // At 1 m/s, 0.5 m/s² and 1 m/s³ the stop is 0.5 + 1.0 + 0.25 = 1.75 m ahead.
        assert!((stopping_offset_m(&v, 0.5, 1.0).x - 1.75).abs() < 1e-12);
        let breach =
            |n: f64, v: &Vector3<f64>| f.predicted_breach(&c, None, home, &Vector3::new(n, 0.0, -5.0), v, 0.5, 1.0);
        assert_eq!(breach(8.2, &v), None);
        assert_eq!(breach(8.3, &v), Some(Violation::MaxHorizontal));
        assert_eq!(breach(8.3, &-v), None, "moving back in");
    }

    #[test]
    fn given_bad_fence_items_then_the_upload_is_refused_naming_the_item() {
        let v = MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION;
        let short = Fence::new(vec![at(0, v, 4.0, 0.0, 0.0), at(1, v, 4.0, 1.0, 0.0), at(2, v, 4.0, 1.0, 1.0)]);
        assert_eq!(short.unwrap_err().to_string(), "item 0: polygon vertex count mismatch");
        let two = Fence::new(vec![at(0, v, 2.0, 0.0, 0.0), at(1, v, 2.0, 1.0, 0.0)]);
        assert_eq!(two.unwrap_err().to_string(), "item 0: vertex count must be 3 or more");
        let circle = Fence::new(vec![at(0, MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, 0.0, 0.0, 0.0)]);
        assert!(circle.is_err());
        let wp = Fence::new(vec![at(0, MavCmd::MAV_CMD_NAV_WAYPOINT, 0.0, 0.0, 0.0)]);
        assert!(matches!(wp, Err(MissionError::UnsupportedCommand { .. })));
        let rally = Rally::new(vec![at(0, MavCmd::MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, 5.0, 0.0, 0.0)]);
        assert!(rally.is_err());
    }

    #[test]
    fn given_rally_points_then_a_return_goes_to_the_nearest_only_when_closer_than_home() {
        let r = Rally::new(vec![
            at(0, MavCmd::MAV_CMD_NAV_RALLY_POINT, 0.0, 30.0, 0.0),
            at(1, MavCmd::MAV_CMD_NAV_RALLY_POINT, 0.0, 0.0, 50.0),
        ])
        .unwrap();
        let home = Vector3::new(0.0, 0.0, 0.2);
        let to = r.return_point(Some(&ORIGIN), home, &Vector3::new(25.0, 0.0, -5.0));
        assert!((to - Vector3::new(30.0, 0.0, 0.2)).norm() < 0.01, "{to:?}");
        assert_eq!(r.return_point(Some(&ORIGIN), home, &Vector3::new(5.0, 0.0, -5.0)), home);
    }
}

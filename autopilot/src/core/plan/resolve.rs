//! Where a commanded point is: the one resolver of every target the vehicle is given (a command's point,
//! an offboard global setpoint, a mission item, and the checks made of them). In: a [`NavTarget`] (here, or
//! WGS-84 latitude/longitude with an altitude AMSL, above home, or unset for "the current altitude"), the
//! [`Frame`] it is read in (the estimator's geodetic origin, home's altitude AMSL, the ground's down
//! coordinate) and where "here" is (NED m). Out: the point in local NED (m), or why it has none.
//!
//! The rules, the same for every caller: a mission item at latitude/longitude (0, 0) or unset is "here"
//! ([`crate::core::mission::nav_items`] reads it so); a relative altitude is above home's altitude, and
//! needs one; a global point needs the origin; an unset altitude (NaN) keeps here's.

use nalgebra::Vector3;
use thiserror::Error;

use crate::core::estimator::GeoOrigin;
use crate::core::mission::NavTarget;

/// What a target is read against.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Frame {
    /// The estimator's geodetic origin (None: no global position yet).
    pub origin: Option<GeoOrigin>,
    /// Home's altitude (m AMSL): home's once set, else the ground under the vehicle (None: no origin).
    pub home_alt_amsl_m: Option<f64>,
    /// The ground's down coordinate (m, NED): home's, 0 without one.
    pub ground_d_m: f64,
}

/// Why a target has no local point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum Unresolved {
    #[error("no global position yet")]
    NoOrigin,
    #[error("no home altitude yet")]
    NoHomeAltitude,
    #[error("invalid position")]
    Invalid,
}

/// The local NED point (m) of `target` in `frame`, with `here_ned_m` for "here" (see the module docs).
///
/// # Errors
/// [`Unresolved`] when the frame lacks what the target needs, or the point is not finite.
pub fn resolve(target: &NavTarget, frame: &Frame, here_ned_m: Vector3<f64>) -> Result<Vector3<f64>, Unresolved> {
    let point = match *target {
        NavTarget::Here { alt_rel_m } => {
            Vector3::new(here_ned_m.x, here_ned_m.y, alt_rel_m.map_or(here_ned_m.z, |a| frame.ground_d_m - a))
        }
        NavTarget::Global { lat_deg, lon_deg, alt_m, relative } => {
            let origin = frame.origin.ok_or(Unresolved::NoOrigin)?;
            let alt_amsl_m = if alt_m.is_nan() {
                origin.alt_amsl_m - here_ned_m.z
            } else if relative {
                frame.home_alt_amsl_m.ok_or(Unresolved::NoHomeAltitude)? + alt_m
            } else {
                alt_m
            };
            origin.ned_from_geodetic(lat_deg, lon_deg, alt_amsl_m)
        }
    };
    if point.iter().all(|x| x.is_finite()) { Ok(point) } else { Err(Unresolved::Invalid) }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };

    fn frame() -> Frame {
        Frame { origin: Some(ORIGIN), home_alt_amsl_m: Some(490.0), ground_d_m: -2.0 }
    }

    #[test]
    fn given_here_with_a_relative_altitude_when_resolved_then_it_is_above_the_ground_at_here() {
        let here = Vector3::new(3.0, -4.0, -7.0);
        let p = resolve(&NavTarget::Here { alt_rel_m: Some(5.0) }, &frame(), here).unwrap();
        assert_eq!(p, Vector3::new(3.0, -4.0, -7.0));
        let p = resolve(&NavTarget::Here { alt_rel_m: None }, &frame(), here).unwrap();
        assert_eq!(p, here);
    }

    #[test]
    fn given_a_global_point_when_resolved_then_relative_altitudes_are_above_home_and_amsl_ones_absolute() {
        let target =
            |relative, alt_m| NavTarget::Global { lat_deg: ORIGIN.lat_deg, lon_deg: ORIGIN.lon_deg, alt_m, relative };
        let here = Vector3::new(1.0, 1.0, -1.0);
        assert_eq!(resolve(&target(true, 10.0), &frame(), here).unwrap().z, 488.0 - 500.0);
        assert_eq!(resolve(&target(false, 500.0), &frame(), here).unwrap().z, 488.0 - 500.0);
        // An unset altitude keeps here's.
        assert!((resolve(&target(false, f64::NAN), &frame(), here).unwrap().z - here.z).abs() < 1e-9);
    }

    #[test]
    fn given_a_frame_without_origin_or_home_altitude_when_resolved_then_it_says_which() {
        let global = NavTarget::Global { lat_deg: 47.0, lon_deg: 8.0, alt_m: 5.0, relative: true };
        let no_origin = Frame { origin: None, ..frame() };
        assert_eq!(resolve(&global, &no_origin, Vector3::zeros()), Err(Unresolved::NoOrigin));
        let no_home = Frame { home_alt_amsl_m: None, ..frame() };
        assert_eq!(resolve(&global, &no_home, Vector3::zeros()), Err(Unresolved::NoHomeAltitude));
        let far = NavTarget::Global { lat_deg: f64::INFINITY, lon_deg: 8.0, alt_m: 5.0, relative: false };
        assert_eq!(resolve(&far, &frame(), Vector3::zeros()), Err(Unresolved::Invalid));
    }
}

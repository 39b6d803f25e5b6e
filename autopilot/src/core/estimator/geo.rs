//! Geodetic <-> local NED about the estimator's origin. In: WGS-84 latitude/longitude (deg) and altitude
//! AMSL (m), or a NED position (m) about the origin. Out: the other one. Called at the GPS rate.
//!
//! Flat earth (the tangent plane at the origin): `N = dlat (M + h0)`, `E = dlon (N_t + h0) cos lat0`,
//! `D = h0 - h`, with `M` the WGS-84 meridian radius and `N_t` the transverse (prime-vertical) radius at
//! the origin latitude. This is the map the SITL plant uses, so the plant's NED and ours agree to rounding
//! about the same origin. Its error against the ellipsoid grows as `(distance / R)^2`: about a centimetre
//! at 10 km, far below GPS noise for the few-kilometre range of a small quadrotor. Longitude differences
//! are wrapped into [-180, 180) deg so an origin near the antimeridian works.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// WGS-84 semi-major axis (m).
pub const WGS84_A_M: f64 = 6_378_137.0;
/// WGS-84 first eccentricity squared.
pub const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// The geodetic point where local NED is `(0, 0, 0)`: the estimator latches it at the first good 3D fix.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoOrigin {
    /// Latitude (deg, WGS-84).
    pub lat_deg: f64,
    /// Longitude (deg, WGS-84).
    pub lon_deg: f64,
    /// Altitude above mean sea level (m); local `D = alt_amsl_m - h`.
    pub alt_amsl_m: f64,
}

/// Wraps an angle difference in degrees into [-180, 180).
fn wrap_deg(angle_deg: f64) -> f64 {
    (angle_deg + 180.0).rem_euclid(360.0) - 180.0
}

impl GeoOrigin {
    /// Metres per radian of latitude and of longitude at the origin: `(M + h0, (N_t + h0) cos lat0)`.
    #[must_use]
    pub fn metres_per_radian(&self) -> (f64, f64) {
        let lat_rad = self.lat_deg.to_radians();
        let s2 = 1.0 - WGS84_E2 * lat_rad.sin().powi(2);
        let meridian_m = WGS84_A_M * (1.0 - WGS84_E2) / (s2 * s2.sqrt());
        let transverse_m = WGS84_A_M / s2.sqrt();
        (meridian_m + self.alt_amsl_m, (transverse_m + self.alt_amsl_m) * lat_rad.cos())
    }

    /// The NED position (m) of a geodetic point about this origin.
    #[must_use]
    pub fn ned_from_geodetic(&self, lat_deg: f64, lon_deg: f64, alt_amsl_m: f64) -> Vector3<f64> {
        let (north_m_per_rad, east_m_per_rad) = self.metres_per_radian();
        Vector3::new(
            (lat_deg - self.lat_deg).to_radians() * north_m_per_rad,
            wrap_deg(lon_deg - self.lon_deg).to_radians() * east_m_per_rad,
            self.alt_amsl_m - alt_amsl_m,
        )
    }

    /// The geodetic point `(lat_deg, lon_deg, alt_amsl_m)` of a NED position (m) about this origin; the
    /// inverse of [`GeoOrigin::ned_from_geodetic`]. A longitude past ±180 (an origin at the antimeridian)
    /// is wrapped into [-180, 180); one in range is left as summed, so no fix loses its last bits to the
    /// wrap. The simulator's GPS uses this same map.
    #[must_use]
    pub fn geodetic_from_ned(&self, pos_ned_m: &Vector3<f64>) -> (f64, f64, f64) {
        let (north_m_per_rad, east_m_per_rad) = self.metres_per_radian();
        let lon_deg = self.lon_deg + (pos_ned_m.y / east_m_per_rad).to_degrees();
        (
            self.lat_deg + (pos_ned_m.x / north_m_per_rad).to_degrees(),
            if (-180.0..180.0).contains(&lon_deg) { lon_deg } else { wrap_deg(lon_deg) },
            self.alt_amsl_m - pos_ned_m.z,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ZURICH: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };

    #[test]
    fn given_a_point_when_mapped_to_ned_and_back_then_it_round_trips_to_a_micrometre() {
        let pos_ned_m = Vector3::new(1234.5, -987.6, -55.5);
        let (lat, lon, alt) = ZURICH.geodetic_from_ned(&pos_ned_m);
        let back = ZURICH.ned_from_geodetic(lat, lon, alt);
        assert!((back - pos_ned_m).norm() < 1e-6, "{back} vs {pos_ned_m}");
        assert!((alt - 543.5).abs() < 1e-12);
    }

    #[test]
    fn given_one_arc_second_north_and_east_when_mapped_then_the_wgs84_radii_give_the_known_lengths() {
        // At 47.4 deg: 1" of latitude is 30.89 m, 1" of longitude 20.97 m (ellipsoidal values, + 488 m).
        let p = ZURICH.ned_from_geodetic(ZURICH.lat_deg + 1.0 / 3600.0, ZURICH.lon_deg + 1.0 / 3600.0, 488.0);
        assert!((p.x - 30.885).abs() < 0.01, "north {}", p.x);
        assert!((p.y - 20.971).abs() < 0.01, "east {}", p.y);
        assert!(p.z.abs() < 1e-12);
    }

    #[test]
    fn given_an_origin_at_the_antimeridian_when_a_point_lies_across_it_then_east_is_small() {
        let origin = GeoOrigin { lat_deg: 0.0, lon_deg: 179.9999, alt_amsl_m: 0.0 };
        let p = origin.ned_from_geodetic(0.0, -179.9999, 0.0);
        assert!(p.y > 0.0 && p.y < 30.0, "east {}", p.y);
        let (_, lon, _) = origin.geodetic_from_ned(&p);
        assert!((lon + 179.9999).abs() < 1e-9, "lon {lon}");
    }
}

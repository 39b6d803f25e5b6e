//! Ground truth: `HIL_STATE_QUATERNION` (every plant step, lat/lon/alt about the plant's home) and the
//! optional precise `ODOMETRY` ([`LocalTruth`]), to and from the estimator's [`TruthSample`].

use mavlink::dialects::common::{HIL_STATE_QUATERNION_DATA, MavFrame, ODOMETRY_DATA};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use super::vec3_f64;
use crate::core::estimator::{GeoOrigin, TruthSample};
use crate::core::mavlink::units::{
    cmps_i16_to_mps, deg_to_dege7, dege7_to_deg, m_to_mm, mg_to_mps2, mm_to_m, mps_to_cmps_i16, mps2_to_mg,
    to_centi_u16,
};

// ---------------------------------------------------------------------------------------------------------
// HIL_STATE_QUATERNION
// ---------------------------------------------------------------------------------------------------------

/// [`TruthSample`] -> `HIL_STATE_QUATERNION`: position mapped to lat/lon (degE7) and alt (mm AMSL) about
/// `home` (the plant's NED origin, same flat-earth map as the plant's), velocity NED cm/s, quaternion
/// [w, x, y, z] FRD -> NED, rates rad/s FRD, specific force mG FRD; both airspeed fields `airspeed_mps` in
/// cm/s.
#[must_use]
pub fn encode_hil_state_quaternion(
    truth: &TruthSample,
    home: &GeoOrigin,
    airspeed_mps: f64,
) -> HIL_STATE_QUATERNION_DATA {
    let (lat_deg, lon_deg, alt_amsl_m) = home.geodetic_from_ned(&truth.pos_ned_m);
    let q = truth.q_ned_frd.quaternion();
    let airspeed_cmps = to_centi_u16(airspeed_mps);
    HIL_STATE_QUATERNION_DATA {
        time_usec: truth.time_us,
        attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        rollspeed: truth.rate_frd_radps.x as f32,
        pitchspeed: truth.rate_frd_radps.y as f32,
        yawspeed: truth.rate_frd_radps.z as f32,
        lat: deg_to_dege7(lat_deg),
        lon: deg_to_dege7(lon_deg),
        alt: m_to_mm(alt_amsl_m),
        vx: mps_to_cmps_i16(truth.vel_ned_mps.x),
        vy: mps_to_cmps_i16(truth.vel_ned_mps.y),
        vz: mps_to_cmps_i16(truth.vel_ned_mps.z),
        ind_airspeed: airspeed_cmps,
        true_airspeed: airspeed_cmps,
        xacc: mps2_to_mg(truth.specific_force_frd_mps2.x),
        yacc: mps2_to_mg(truth.specific_force_frd_mps2.y),
        zacc: mps2_to_mg(truth.specific_force_frd_mps2.z),
    }
}

/// `HIL_STATE_QUATERNION` -> [`TruthSample`], position in NED about `home`. The quaternion is renormalised;
/// a zero or non-finite one decodes as non-finite (the estimator refuses it).
#[must_use]
pub fn decode_hil_state_quaternion(msg: &HIL_STATE_QUATERNION_DATA, home: &GeoOrigin) -> TruthSample {
    let [w, x, y, z] = msg.attitude_quaternion.map(f64::from);
    TruthSample {
        time_us: msg.time_usec,
        pos_ned_m: home.ned_from_geodetic(dege7_to_deg(msg.lat), dege7_to_deg(msg.lon), mm_to_m(msg.alt)),
        vel_ned_mps: Vector3::new(cmps_i16_to_mps(msg.vx), cmps_i16_to_mps(msg.vy), cmps_i16_to_mps(msg.vz)),
        q_ned_frd: UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z)),
        rate_frd_radps: vec3_f64(msg.rollspeed, msg.pitchspeed, msg.yawspeed),
        specific_force_frd_mps2: Vector3::new(mg_to_mps2(msg.xacc), mg_to_mps2(msg.yacc), mg_to_mps2(msg.zacc)),
    }
}

// ---------------------------------------------------------------------------------------------------------
// ODOMETRY (precise truth)
// ---------------------------------------------------------------------------------------------------------

/// Truth in the plant's local NED frame at float precision, sent as `ODOMETRY` (frame LOCAL_NED, child
/// BODY_FRD) after `HIL_STATE_QUATERNION` when the plant is asked to: degE7 latitude and longitude
/// quantise the position to ±5.6 mm, which is a quarter of the paper's 2 cm state noise and the size of
/// the steady hover error of the truth-fed runs. Position m, velocity m/s, rates rad/s (f32: ≤ 6e-8
/// relative); the covariances are "unknown" (NaN first element).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalTruth {
    pub time_us: u64,
    pub pos_ned_m: Vector3<f64>,
    pub vel_ned_mps: Vector3<f64>,
    pub q_ned_frd: UnitQuaternion<f64>,
    pub rate_frd_radps: Vector3<f64>,
}

impl LocalTruth {
    /// `truth` with its position, velocity, attitude and rates replaced by these (same sample time).
    #[must_use]
    pub fn refine(&self, truth: &TruthSample) -> TruthSample {
        TruthSample {
            pos_ned_m: self.pos_ned_m,
            vel_ned_mps: self.vel_ned_mps,
            q_ned_frd: self.q_ned_frd,
            rate_frd_radps: self.rate_frd_radps,
            ..*truth
        }
    }
}

/// [`TruthSample`] (position in the plant's NED about its home) -> `ODOMETRY`.
#[must_use]
pub fn encode_odometry(truth: &TruthSample) -> ODOMETRY_DATA {
    let q = truth.q_ned_frd.quaternion();
    let mut unknown = [0.0_f32; 21];
    unknown[0] = f32::NAN;
    ODOMETRY_DATA {
        time_usec: truth.time_us,
        x: truth.pos_ned_m.x as f32,
        y: truth.pos_ned_m.y as f32,
        z: truth.pos_ned_m.z as f32,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        vx: truth.vel_ned_mps.x as f32,
        vy: truth.vel_ned_mps.y as f32,
        vz: truth.vel_ned_mps.z as f32,
        rollspeed: truth.rate_frd_radps.x as f32,
        pitchspeed: truth.rate_frd_radps.y as f32,
        yawspeed: truth.rate_frd_radps.z as f32,
        pose_covariance: unknown,
        velocity_covariance: unknown,
        frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        child_frame_id: MavFrame::MAV_FRAME_BODY_FRD,
        ..Default::default()
    }
}

/// `ODOMETRY` -> [`LocalTruth`], or `None` unless its frames are LOCAL_NED / BODY_FRD (the plant's truth;
/// anything else is some other source's odometry).
#[must_use]
pub fn decode_odometry(msg: &ODOMETRY_DATA) -> Option<LocalTruth> {
    if msg.frame_id != MavFrame::MAV_FRAME_LOCAL_NED || msg.child_frame_id != MavFrame::MAV_FRAME_BODY_FRD {
        return None;
    }
    let [w, x, y, z] = msg.q.map(f64::from);
    Some(LocalTruth {
        time_us: msg.time_usec,
        pos_ned_m: vec3_f64(msg.x, msg.y, msg.z),
        vel_ned_mps: vec3_f64(msg.vx, msg.vy, msg.vz),
        q_ned_frd: UnitQuaternion::new_normalize(Quaternion::new(w, x, y, z)),
        rate_frd_radps: vec3_f64(msg.rollspeed, msg.pitchspeed, msg.yawspeed),
    })
}

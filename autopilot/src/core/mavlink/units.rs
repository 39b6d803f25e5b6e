//! MAVLink's wire units, written once for the plant protocol (`core::plant_link`) and the ground-station
//! messages (`telemetry`, `command`, `offboard`, the geofence): degE7 angles, mm lengths, cm/s speeds,
//! centi-unit accuracies, milli-g, centidegree headings. Each names its units; the integer ones round to
//! nearest and saturate at their type's range (NaN -> 0, as `as` casts do), unless they say otherwise.

/// Standard gravity (m/s²) per g, for milli-g fields (`HIL_STATE_QUATERNION`).
pub const MPS2_PER_G: f64 = 9.806_65;

/// The "unknown" value of MAVLink's u16 accuracy, speed, course and heading fields (`HIL_GPS`,
/// `HIL_STATE_QUATERNION`, `GPS_RAW_INT`, `GLOBAL_POSITION_INT`).
pub const UNKNOWN_U16: u16 = u16::MAX;
/// Degrees -> degE7 (i32), rounded, saturating.
#[must_use]
pub fn deg_to_dege7(angle_deg: f64) -> i32 {
    (angle_deg * 1e7).round() as i32
}

/// degE7 -> degrees.
#[must_use]
pub fn dege7_to_deg(angle_dege7: i32) -> f64 {
    f64::from(angle_dege7) * 1e-7
}

/// Metres -> millimetres (i32), rounded, saturating.
#[must_use]
pub fn m_to_mm(length_m: f64) -> i32 {
    (length_m * 1e3).round() as i32
}

/// Millimetres -> metres.
#[must_use]
pub fn mm_to_m(length_mm: i32) -> f64 {
    f64::from(length_mm) * 1e-3
}

/// Signed speed m/s -> cm/s (i16), rounded, saturating at ±327.67 m/s.
#[must_use]
pub fn mps_to_cmps_i16(speed_mps: f64) -> i16 {
    (speed_mps * 100.0).round() as i16
}

/// cm/s (i16) -> m/s.
#[must_use]
pub fn cmps_i16_to_mps(speed_cmps: i16) -> f64 {
    f64::from(speed_cmps) * 0.01
}

/// Non-negative metres or m/s -> centi-units (u16), rounded, saturating below [`UNKNOWN_U16`]; non-finite
/// or negative -> [`UNKNOWN_U16`] (the protocol's "unknown").
#[must_use]
pub fn to_centi_u16(value: f64) -> u16 {
    if value.is_finite() && value >= 0.0 {
        (value * 100.0).round().min(f64::from(UNKNOWN_U16 - 1)) as u16
    } else {
        UNKNOWN_U16
    }
}

/// Centi-units (u16) -> units; [`UNKNOWN_U16`] -> +inf.
#[must_use]
pub fn centi_u16_to(value_centi: u16) -> f64 {
    if value_centi == UNKNOWN_U16 { f64::INFINITY } else { f64::from(value_centi) * 0.01 }
}

/// Specific force m/s² -> milli-g (i16), rounded, saturating at ±32.767 g.
#[must_use]
pub fn mps2_to_mg(accel_mps2: f64) -> i16 {
    (accel_mps2 / MPS2_PER_G * 1e3).round() as i16
}

/// Milli-g (i16) -> m/s².
#[must_use]
pub fn mg_to_mps2(accel_mg: i16) -> f64 {
    f64::from(accel_mg) * 1e-3 * MPS2_PER_G
}

/// An angle (rad) -> centidegrees 0..35999 (a heading or course over ground), rounded; non-finite ->
/// [`UNKNOWN_U16`].
#[must_use]
pub fn rad_to_cdeg_0_360(angle_rad: f64) -> u16 {
    if !angle_rad.is_finite() {
        return UNKNOWN_U16;
    }
    ((angle_rad.to_degrees().rem_euclid(360.0) * 100.0).round() as u16) % 36_000
}

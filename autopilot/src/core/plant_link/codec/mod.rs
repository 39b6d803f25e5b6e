//! The plant protocol's messages to and from the autopilot's samples (see [`crate::core::plant_link`] for
//! the protocol): one submodule per kind of message (the sensors, the truth, the actuators, the battery
//! and the radio) and the dispatch of a decoded frame here. The plant-independent encoders live here too
//! (from the neutral [`HilSensorFields`] and the estimator types), so both ends share one definition of
//! every scale factor; `sitl::link` only maps its plant types onto them.
//!
//! # Scaling and round-trip precision (encode then decode)
//!
//! | quantity | wire field | wire unit / type | round-trip error |
//! |---|---|---|---|
//! | time | `time_usec` | µs, u64 | exact |
//! | specific force, rates, field | `x/y/zacc`, `x/y/zgyro`, `x/y/zmag` | m/s², rad/s, gauss; f32 | ≤ 2⁻²⁴·\|x\| (6e-8 relative) |
//! | pressure, pressure altitude, temperature | `abs_pressure`, `pressure_alt`, `temperature` | hPa, m, °C; f32 | ≤ 2⁻²⁴·\|x\| (3e-5 m at 500 m) |
//! | GPS / truth latitude, longitude | `lat`, `lon` | degE7, i32 | ≤ 0.5e-7 deg (≤ 5.6 mm north, ≤ 5.6 mm·cos φ east) |
//! | GPS / truth altitude | `alt` | mm AMSL, i32 | ≤ 0.5 mm |
//! | GPS / truth velocity | `vn/ve/vd`, `vx/vy/vz` | cm/s, i16 (±327.67 m/s, saturating) | ≤ 0.5 cm/s |
//! | GPS accuracy | `eph`, `epv` | cm, u16 (65535 = unknown -> +inf, refused by the estimator) | ≤ 0.5 cm |
//! | truth attitude | `attitude_quaternion` | [w, x, y, z] FRD -> NED, f32 | ≤ 1.2e-7 rad |
//! | truth specific force | `xacc/yacc/zacc` | mG (1 mG = 9.80665e-3 m/s²), i16 (±32.767 g, saturating) | ≤ 4.9e-3 m/s² |
//! | precise truth (optional) | `ODOMETRY` x/y/z, vx/vy/vz, q, rates | m, m/s, rad/s NED/FRD; f32 | ≤ 6e-8 relative |
//! | motor command | `controls[0..4]` | (pwm_us - 1000)/1000, f32 | ≤ 3e-5 µs |
//! | pack voltage | `voltages` (per cell), `voltages_ext` | mV, u16 | ≤ 0.5 mV per cell |
//! | pack current, charge, energy | `current_battery`, `current_consumed`, `energy_consumed` | cA i16, mAh i32, hJ i32 | ≤ 5 mA, 0.5 mAh, 50 J |
//! | state of charge | `battery_remaining` | %, i8, truncated (a gauge never overstates) | < 1 % low |
//!
//! Integer fields saturate at their range (NaN encodes as 0). The extension fields (`HIL_SENSOR.id`,
//! `HIL_GPS.id`, `HIL_GPS.yaw`) are left 0 (sensor instance 0, no GPS yaw); MAVLink 2 truncates trailing
//! zeros, as the protocol allows.
//!
//! The frames themselves (MAVLink v2 and v1 out, [`FrameDecoder`] in) are [`crate::core::mavlink::frame`]'s,
//! shared with the ground-station links; their names are re-exported here.

mod actuators;
mod battery_rc;
mod sensors;
#[cfg(test)]
mod tests;
mod truth;

use mavlink::dialects::common::{COMMAND_LONG_DATA, MavCmd, MavMessage, MavResult};
use nalgebra::Vector3;

use crate::core::battery::BatterySample;
use crate::core::estimator::{GeoOrigin, GpsSample, TruthSample};
use crate::core::manual::RcFrame;
pub use crate::core::mavlink::frame::{DecodedFrame, DecoderStats, FrameDecoder, encode_frame_v1, encode_frame_v2};
pub use actuators::{
    ActuatorCommand, MODE_FLAG_SAFETY_ARMED, PWM_MAX_US, PWM_MIN_US, control_to_pwm_us, decode_actuator_controls,
    encode_actuator_controls, pwm_us_to_control,
};
pub use battery_rc::{decode_battery_status, decode_rc_channels, encode_battery_status, encode_rc_channels};
pub use sensors::{
    HilBaroFields, HilSensorFields, SensorSamples, course_deg, decode_hil_gps, decode_hil_sensor, encode_hil_gps,
    encode_hil_sensor,
};
pub use truth::{
    LocalTruth, decode_hil_state_quaternion, decode_odometry, encode_hil_state_quaternion, encode_odometry,
};

/// Standard gravity (m/s²) per g, for the milli-g fields of `HIL_STATE_QUATERNION`.
pub const MPS2_PER_G: f64 = 9.806_65;

/// `HIL_GPS`/`HIL_STATE_QUATERNION` "unknown" value of the u16 accuracy, speed and course fields.
pub const UNKNOWN_U16: u16 = u16::MAX;
// ---------------------------------------------------------------------------------------------------------
// Scalar conversions (each names its units; integer ones round to nearest and saturate, NaN -> 0)
// ---------------------------------------------------------------------------------------------------------

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
fn vec3_f32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

fn vec3_f64(x: f32, y: f32, z: f32) -> Vector3<f64> {
    Vector3::new(f64::from(x), f64::from(y), f64::from(z))
}

// ---------------------------------------------------------------------------------------------------------
// Dispatch and framing
// ---------------------------------------------------------------------------------------------------------

/// The plant's answer to a command the autopilot forwarded on the plant link (`COMMAND_ACK`): which
/// command (its MAVLink id, e.g. 420 for MAV_CMD_INJECT_FAILURE) and the result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantCommandAck {
    pub command_id: u32,
    pub result: MavResult,
}

/// The COMMAND_LONG that forwards a failure injection to the plant (see [`crate::core::plant_link`]): unit, type and
/// instance as MAV_CMD_INJECT_FAILURE's param1..3, addressed to whoever is at the other end of the link.
#[must_use]
pub fn encode_inject_failure(unit: u8, failure_type: u8, instance: u8) -> COMMAND_LONG_DATA {
    COMMAND_LONG_DATA {
        param1: f32::from(unit),
        param2: f32::from(failure_type),
        param3: f32::from(instance),
        command: MavCmd::MAV_CMD_INJECT_FAILURE,
        target_system: 0,
        target_component: 0,
        ..Default::default()
    }
}

/// A decoded plant-protocol message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HilInput {
    Sensor(HilSensorFields),
    Gps(GpsSample),
    Truth(TruthSample),
    /// Precise truth, refining the `Truth` of the same datagram.
    LocalTruth(LocalTruth),
    Actuators(ActuatorCommand),
    Battery(BatterySample),
    /// The board's radio receiver.
    Rc(RcFrame),
    /// The plant's answer to a forwarded command.
    CommandAck(PlantCommandAck),
}

/// The plant-protocol content of `msg` (truth positions about `home`), or `None` for any other message.
#[must_use]
pub fn decode_hil_message(msg: &MavMessage, home: &GeoOrigin) -> Option<HilInput> {
    match msg {
        MavMessage::HIL_SENSOR(m) => Some(HilInput::Sensor(decode_hil_sensor(m))),
        MavMessage::HIL_GPS(m) => Some(HilInput::Gps(decode_hil_gps(m))),
        MavMessage::HIL_STATE_QUATERNION(m) => Some(HilInput::Truth(decode_hil_state_quaternion(m, home))),
        MavMessage::ODOMETRY(m) => decode_odometry(m).map(HilInput::LocalTruth),
        MavMessage::HIL_ACTUATOR_CONTROLS(m) => Some(HilInput::Actuators(decode_actuator_controls(m))),
        MavMessage::BATTERY_STATUS(m) => Some(HilInput::Battery(decode_battery_status(m))),
        MavMessage::RC_CHANNELS(m) => Some(HilInput::Rc(decode_rc_channels(m))),
        MavMessage::COMMAND_ACK(m) => {
            Some(HilInput::CommandAck(PlantCommandAck { command_id: m.command as u32, result: m.result }))
        }
        _ => None,
    }
}

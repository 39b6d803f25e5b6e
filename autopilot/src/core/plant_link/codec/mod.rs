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
    ActuatorCommand, MODE_FLAG_SAFETY_ARMED, MOTOR_PWM_MAX_US, MOTOR_PWM_MIN_US, control_to_pwm_us,
    decode_actuator_controls, encode_actuator_controls, pwm_us_to_control,
};
pub use battery_rc::{decode_battery_status, decode_rc_channels, encode_battery_status, encode_rc_channels};
pub use sensors::{
    HilBaroFields, HilSensorFields, SensorSamples, course_deg, decode_hil_gps, decode_hil_sensor, encode_hil_gps,
    encode_hil_sensor,
};
pub use truth::{
    LocalTruth, decode_hil_state_quaternion, decode_odometry, encode_hil_state_quaternion, encode_odometry,
};

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
pub fn encode_inject_failure([unit, failure_type, instance]: [f32; 3]) -> COMMAND_LONG_DATA {
    COMMAND_LONG_DATA {
        param1: unit,
        param2: failure_type,
        param3: instance,
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

//! The plant's answer to a MAV_CMD_INJECT_FAILURE the autopilot forwards over the plant link
//! (`COMMAND_LONG` 420: param1 failure unit, param2 failure type, param3 instance, 0 = all): a pure mapping
//! ([`failure_sets`]) from the request to SIM_ parameter sets, which the SIM_ parameter service applies as
//! a ground station's sets (so the plant's SIM_ port always shows the injected state, and an injection and
//! a set of the same parameters are the same thing). The table (MAVLink `FAILURE_UNIT` / `FAILURE_TYPE`
//! numbers):
//!
//! | unit | OK (0) | OFF (1) | STUCK (2) | GARBAGE (3) | WRONG (4) |
//! |---|---|---|---|---|---|
//! | MOTOR (101; instance 1..4, 0 = all) | SIM_MOTn_EFF = 1 | SIM_MOTn_EFF = 0 | - | - | SIM_MOTn_EFF = SIM_MOT_WRNG_EFF |
//! | GPS (4) | SIM_GPS_FAIL = 0 | 1 | 2 | - | 4 (jump by SIM_GPS_JUMP_N/E) |
//! | BARO (3) | SIM_BARO_FAIL = 0 | 1 | 2 | - | - |
//! | MAG (2) | SIM_MAG_FAIL = 0 | 1 | 2 | - | - |
//! | ACCEL (1) | SIM_ACC_FAIL = 0 | - | 2 | 3 | - |
//! | GYRO (0) | SIM_GYRO_FAIL = 0 | - | 2 | 3 | - |
//! | BATTERY (100) | SIM_BAT_FAIL = 0 | 1 | - | - | - |
//! | RC_SIGNAL (104) | SIM_RC_FAIL = 0 | 1 | - | - | - |
//!
//! Every other combination, any other unit or type (5 SLOW, 6 DELAYED, 7 INTERMITTENT), an instance other
//! than 0 or 1 for a unit the plant has one of, and a motor the quadrotor does not have (instance > 4) are
//! `MAV_RESULT_UNSUPPORTED`, nothing changed. A parameter that is not a whole number >= 0 (NaN, 2.5, -1),
//! or a set the plant refuses (a battery fault on a plant without a pack), is `MAV_RESULT_DENIED`, nothing
//! changed. The motor rows need the plant's SIM_MOTn_EFF parameters: looked up by name, a plant without
//! them answers those rows UNSUPPORTED.

use mavlink::dialects::common::{MavMessage, MavResult};

use crate::plant::{Fault, Sensor};

/// MAVLink `FAILURE_UNIT` numbers the plant knows.
pub mod failure_unit {
    pub const SENSOR_GYRO: u32 = 0;
    pub const SENSOR_ACCEL: u32 = 1;
    pub const SENSOR_MAG: u32 = 2;
    pub const SENSOR_BARO: u32 = 3;
    pub const SENSOR_GPS: u32 = 4;
    pub const SYSTEM_BATTERY: u32 = 100;
    pub const SYSTEM_MOTOR: u32 = 101;
    pub const SYSTEM_RC_SIGNAL: u32 = 104;
    pub const SYSTEM_MAVLINK_SIGNAL: u32 = 105;
}

/// The motors of the quadrotor (instances 1..=MOTORS).
pub const MOTORS: u32 = 4;

/// An injection request as `COMMAND_LONG` carries it: param1, param2, param3 (floats on the wire).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureRequest {
    /// Failure unit (param1).
    pub unit: f32,
    /// Failure type (param2).
    pub failure_type: f32,
    /// Instance, 0 = all (param3).
    pub instance: f32,
}

/// Why a request changes nothing: the ACK's result and a text for the plant's SIM_ port.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// `MAV_RESULT_UNSUPPORTED` or `MAV_RESULT_DENIED`.
    pub result: MavResult,
    pub reason: String,
}

impl Refusal {
    fn unsupported(reason: impl Into<String>) -> Self {
        Self { result: MavResult::MAV_RESULT_UNSUPPORTED, reason: reason.into() }
    }

    fn denied(reason: impl Into<String>) -> Self {
        Self { result: MavResult::MAV_RESULT_DENIED, reason: reason.into() }
    }
}

/// What the plant did with one request: the ACK's result, a text saying what happened, and the messages
/// for the SIM_ port's clients (PARAM_VALUE of each parameter changed, and the text).
#[derive(Debug, Clone, PartialEq)]
pub struct Injection {
    pub result: MavResult,
    pub text: String,
    pub messages: Vec<MavMessage>,
}

/// `value` (param`n`, named `what`) as a whole number >= 0.
fn whole(value: f32, what: &str) -> Result<u32, Refusal> {
    if value.is_finite() && value >= 0.0 && value.fract() == 0.0 && value <= u32::MAX as f32 {
        Ok(value as u32)
    } else {
        Err(Refusal::denied(format!("{what} {value} is not a whole number >= 0")))
    }
}

/// The sensor of a sensor failure unit.
fn sensor_of(unit: u32) -> Option<Sensor> {
    match unit {
        failure_unit::SENSOR_GYRO => Some(Sensor::Gyro),
        failure_unit::SENSOR_ACCEL => Some(Sensor::Accel),
        failure_unit::SENSOR_MAG => Some(Sensor::Mag),
        failure_unit::SENSOR_BARO => Some(Sensor::Baro),
        failure_unit::SENSOR_GPS => Some(Sensor::Gps),
        _ => None,
    }
}

/// The fault parameter of a sensor.
fn sensor_param(sensor: Sensor) -> &'static str {
    match sensor {
        Sensor::Gps => "SIM_GPS_FAIL",
        Sensor::Baro => "SIM_BARO_FAIL",
        Sensor::Mag => "SIM_MAG_FAIL",
        Sensor::Accel => "SIM_ACC_FAIL",
        Sensor::Gyro => "SIM_GYRO_FAIL",
    }
}

/// The motor thrust parameter of motor `n` (1..4).
#[must_use]
pub fn motor_param(n: u32) -> String {
    format!("SIM_MOT{n}_EFF")
}

/// A unit the plant has exactly one of accepts instance 0 (all) or 1.
fn single(instance: u32, what: &str) -> Result<(), Refusal> {
    if instance <= 1 {
        Ok(())
    } else {
        Err(Refusal::unsupported(format!("the plant has one {what}, not instance {instance}")))
    }
}

/// The SIM_ parameter sets that inject `request` (see the module docs), in order; `value_of(name)` is the
/// current value of a SIM_ parameter (`None` when the plant has no such parameter).
///
/// # Errors
/// [`Refusal`]: UNSUPPORTED for a combination the plant does not simulate, DENIED for a parameter that is
/// not a whole number >= 0.
pub fn failure_sets(
    request: &FailureRequest,
    value_of: impl Fn(&str) -> Option<f32>,
) -> Result<Vec<(String, f32)>, Refusal> {
    let unit = whole(request.unit, "failure unit")?;
    let type_number = whole(request.failure_type, "failure type")?;
    let instance = whole(request.instance, "instance")?;
    let fault = Fault::from_failure_type(type_number)
        .ok_or_else(|| Refusal::unsupported(format!("failure type {type_number} is not simulated by the plant")))?;
    let no = |what: &str| Refusal::unsupported(format!("{what} {} is not simulated by the plant", fault.word()));
    if let Some(sensor) = sensor_of(unit) {
        single(instance, sensor.name())?;
        if !sensor.faults().contains(&fault) {
            return Err(no(sensor.name()));
        }
        return Ok(vec![(sensor_param(sensor).to_owned(), f32::from(fault.failure_type()))]);
    }
    match unit {
        failure_unit::SYSTEM_BATTERY | failure_unit::SYSTEM_RC_SIGNAL => {
            let (what, param) =
                if unit == failure_unit::SYSTEM_BATTERY { ("battery", "SIM_BAT_FAIL") } else { ("RC", "SIM_RC_FAIL") };
            single(instance, what)?;
            match fault {
                Fault::Ok => Ok(vec![(param.to_owned(), 0.0)]),
                Fault::Off => Ok(vec![(param.to_owned(), 1.0)]),
                _ => Err(no(what)),
            }
        }
        failure_unit::SYSTEM_MOTOR => {
            if instance > MOTORS {
                return Err(Refusal::unsupported(format!("the quadrotor has motors 1..{MOTORS}, not {instance}")));
            }
            let efficiency = match fault {
                Fault::Ok => 1.0,
                Fault::Off => 0.0,
                Fault::Wrong => value_of("SIM_MOT_WRNG_EFF")
                    .ok_or_else(|| Refusal::unsupported("SIM_MOT_WRNG_EFF is not a parameter of this plant"))?,
                _ => return Err(no("motor")),
            };
            let motors: Vec<u32> = if instance == 0 { (1..=MOTORS).collect() } else { vec![instance] };
            motors
                .into_iter()
                .map(|n| {
                    let name = motor_param(n);
                    match value_of(&name) {
                        Some(_) => Ok((name, efficiency)),
                        None => Err(Refusal::unsupported(format!("{name} is not a parameter of this plant"))),
                    }
                })
                .collect()
        }
        failure_unit::SYSTEM_MAVLINK_SIGNAL => {
            Err(Refusal::unsupported("the ground-station link is the autopilot's, not the plant's"))
        }
        _ => Err(Refusal::unsupported(format!("failure unit {unit} is not simulated by the plant"))),
    }
}

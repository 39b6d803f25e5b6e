//! The plant's answer to a MAV_CMD_INJECT_FAILURE the autopilot forwards over the plant link
//! (`COMMAND_LONG` 420: param1 failure unit, param2 failure type, param3 instance, 0 = all), read as the
//! autopilot's own [`FailureRequest`] ([`request_of`]), and a pure mapping ([`failure_sets`], on the
//! `mavlink` crate's `FailureUnit` and `FailureType`) from the request to SIM_ parameter sets, which the SIM_ parameter service applies as
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

use autopilot::core::mavlink::failure::FailureRequest;
use mavlink::dialects::common::{FailureUnit, MavMessage, MavResult};

use crate::plant::{Fault, Sensor};

/// The motors of the quadrotor (instances 1..=MOTORS).
pub const MOTORS: u32 = 4;

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

/// The request a forwarded `COMMAND_LONG` carries in param1..param3 (unit, type, instance), each a whole
/// number >= 0.
///
/// # Errors
/// [`Refusal`] DENIED for the first parameter that is not (NaN, 2.5, -1), nothing changed.
pub fn request_of([unit, failure_type, instance]: [f32; 3]) -> Result<FailureRequest, Refusal> {
    Ok(FailureRequest {
        unit_id: whole(unit, "failure unit")?,
        type_id: whole(failure_type, "failure type")?,
        instance: whole(instance, "instance")?,
    })
}

/// The sensor of a sensor failure unit.
fn sensor_of(unit: Option<FailureUnit>) -> Option<Sensor> {
    match unit? {
        FailureUnit::FAILURE_UNIT_SENSOR_GYRO => Some(Sensor::Gyro),
        FailureUnit::FAILURE_UNIT_SENSOR_ACCEL => Some(Sensor::Accel),
        FailureUnit::FAILURE_UNIT_SENSOR_MAG => Some(Sensor::Mag),
        FailureUnit::FAILURE_UNIT_SENSOR_BARO => Some(Sensor::Baro),
        FailureUnit::FAILURE_UNIT_SENSOR_GPS => Some(Sensor::Gps),
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
/// [`Refusal`] UNSUPPORTED for a combination the plant does not simulate.
pub fn failure_sets(
    request: &FailureRequest,
    value_of: impl Fn(&str) -> Option<f32>,
) -> Result<Vec<(String, f32)>, Refusal> {
    let (unit, instance) = (request.unit(), request.instance);
    let fault = request.failure_type().and_then(Fault::from_mavlink).ok_or_else(|| {
        Refusal::unsupported(format!("failure type {} is not simulated by the plant", request.type_id))
    })?;
    let no = |what: &str| Refusal::unsupported(format!("{what} {} is not simulated by the plant", fault.word()));
    if let Some(sensor) = sensor_of(unit) {
        single(instance, sensor.name())?;
        if !sensor.faults().contains(&fault) {
            return Err(no(sensor.name()));
        }
        return Ok(vec![(sensor_param(sensor).to_owned(), f32::from(fault.failure_type()))]);
    }
    match unit {
        Some(FailureUnit::FAILURE_UNIT_SYSTEM_BATTERY | FailureUnit::FAILURE_UNIT_SYSTEM_RC_SIGNAL) => {
            let (what, param) = if request.is_unit(FailureUnit::FAILURE_UNIT_SYSTEM_BATTERY) {
                ("battery", "SIM_BAT_FAIL")
            } else {
                ("RC", "SIM_RC_FAIL")
            };
            single(instance, what)?;
            match fault {
                Fault::Ok => Ok(vec![(param.to_owned(), 0.0)]),
                Fault::Off => Ok(vec![(param.to_owned(), 1.0)]),
                _ => Err(no(what)),
            }
        }
        Some(FailureUnit::FAILURE_UNIT_SYSTEM_MOTOR) => {
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
        Some(FailureUnit::FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL) => {
            Err(Refusal::unsupported("the ground-station link is the autopilot's, not the plant's"))
        }
        _ => Err(Refusal::unsupported(format!("failure unit {} is not simulated by the plant", request.unit_id))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plant's SIM_ parameters after the merge with part D (SIM_MOT1_EFF..SIM_MOT4_EFF), with the weak
    /// motor's thrust at 0.55 so that its value is seen to be read.
    fn with_motors(name: &str) -> Option<f32> {
        match name {
            "SIM_MOT1_EFF" | "SIM_MOT2_EFF" | "SIM_MOT3_EFF" | "SIM_MOT4_EFF" => Some(1.0),
            "SIM_MOT_WRNG_EFF" => Some(0.55),
            n if n.starts_with("SIM_") => Some(0.0),
            _ => None,
        }
    }

    /// A plant without motor parameters.
    fn without_motors(name: &str) -> Option<f32> {
        with_motors(name).filter(|_| !name.starts_with("SIM_MOT") || name == "SIM_MOT_WRNG_EFF")
    }

    fn sets(unit: u32, failure_type: u32, instance: u32) -> Result<Sets, Refusal> {
        failure_sets(&FailureRequest { unit_id: unit, type_id: failure_type, instance }, with_motors)
    }

    fn one(name: &str, value: f32) -> Result<Sets, MavResult> {
        Ok(vec![(name.to_owned(), value)])
    }

    /// SIM_ parameter sets, in order.
    type Sets = Vec<(String, f32)>;

    /// The design's table, written out: every implemented (unit, type) and its sets for instance 0.
    fn table() -> Vec<((u32, u32), Sets)> {
        let motors = |v: f32| (1..=4).map(|n| (format!("SIM_MOT{n}_EFF"), v)).collect::<Vec<_>>();
        let s = |name: &str, v: f32| vec![(name.to_owned(), v)];
        vec![
            ((101, 0), motors(1.0)),
            ((101, 1), motors(0.0)),
            ((101, 4), motors(0.55)),
            ((4, 0), s("SIM_GPS_FAIL", 0.0)),
            ((4, 1), s("SIM_GPS_FAIL", 1.0)),
            ((4, 2), s("SIM_GPS_FAIL", 2.0)),
            ((4, 4), s("SIM_GPS_FAIL", 4.0)),
            ((3, 0), s("SIM_BARO_FAIL", 0.0)),
            ((3, 1), s("SIM_BARO_FAIL", 1.0)),
            ((3, 2), s("SIM_BARO_FAIL", 2.0)),
            ((2, 0), s("SIM_MAG_FAIL", 0.0)),
            ((2, 1), s("SIM_MAG_FAIL", 1.0)),
            ((2, 2), s("SIM_MAG_FAIL", 2.0)),
            ((1, 0), s("SIM_ACC_FAIL", 0.0)),
            ((1, 2), s("SIM_ACC_FAIL", 2.0)),
            ((1, 3), s("SIM_ACC_FAIL", 3.0)),
            ((0, 0), s("SIM_GYRO_FAIL", 0.0)),
            ((0, 2), s("SIM_GYRO_FAIL", 2.0)),
            ((0, 3), s("SIM_GYRO_FAIL", 3.0)),
            ((100, 0), s("SIM_BAT_FAIL", 0.0)),
            ((100, 1), s("SIM_BAT_FAIL", 1.0)),
            ((104, 0), s("SIM_RC_FAIL", 0.0)),
            ((104, 1), s("SIM_RC_FAIL", 1.0)),
        ]
    }

    #[test]
    fn given_each_row_of_the_table_then_the_request_maps_to_its_sets_and_every_other_type_is_unsupported() {
        let table = table();
        let units = [0, 1, 2, 3, 4, 5, 6, 7, 100, 101, 102, 103, 104, 105, 999];
        for unit in units {
            for failure_type in 0..=8 {
                let got = sets(unit, failure_type, 0);
                match table.iter().find(|(key, _)| *key == (unit, failure_type)) {
                    Some((_, want)) => assert_eq!(got.as_ref(), Ok(want), "unit {unit} type {failure_type}"),
                    None => {
                        let refusal = got.expect_err("not in the table");
                        assert_eq!(
                            refusal.result,
                            MavResult::MAV_RESULT_UNSUPPORTED,
                            "unit {unit} type {failure_type}"
                        );
                        assert!(!refusal.reason.is_empty());
                    }
                }
            }
        }
        assert_eq!(table.len(), 23, "every cell of the design's table");
    }

    #[test]
    fn given_instances_then_0_and_1_address_a_single_unit_each_motor_is_its_own_and_others_are_unsupported() {
        assert_eq!(sets(4, 1, 1).map_err(|r| r.result), one("SIM_GPS_FAIL", 1.0));
        assert_eq!(sets(100, 1, 1).map_err(|r| r.result), one("SIM_BAT_FAIL", 1.0));
        let two = sets(4, 1, 2).expect_err("one GPS");
        assert_eq!(
            (two.result, two.reason.as_str()),
            (MavResult::MAV_RESULT_UNSUPPORTED, "the plant has one GPS, not instance 2")
        );
        assert_eq!(sets(104, 1, 3).expect_err("one radio").result, MavResult::MAV_RESULT_UNSUPPORTED);
        assert_eq!(sets(101, 4, 3).map_err(|r| r.result), one("SIM_MOT3_EFF", 0.55), "motor 3 alone");
        assert_eq!(sets(101, 1, 1).map_err(|r| r.result), one("SIM_MOT1_EFF", 0.0));
        let five = sets(101, 1, 5).expect_err("a quadrotor");
        assert_eq!(
            (five.result, five.reason.as_str()),
            (MavResult::MAV_RESULT_UNSUPPORTED, "the quadrotor has motors 1..4, not 5")
        );
    }

    #[test]
    fn given_values_that_are_not_whole_numbers_then_the_request_is_denied() {
        for (unit, failure_type, instance, what) in [
            (f32::NAN, 1.0, 0.0, "failure unit NaN"),
            (4.5, 1.0, 0.0, "failure unit 4.5"),
            (4.0, -1.0, 0.0, "failure type -1"),
            (4.0, 1.0, 0.5, "instance 0.5"),
            (4.0, f32::INFINITY, 0.0, "failure type inf"),
        ] {
            let refusal = request_of([unit, failure_type, instance]).expect_err(what);
            assert_eq!(refusal.result, MavResult::MAV_RESULT_DENIED, "{what}");
            assert_eq!(refusal.reason, format!("{what} is not a whole number >= 0"));
        }
    }

    #[test]
    fn given_a_plant_without_motor_parameters_then_every_motor_row_is_unsupported_naming_the_parameter() {
        for failure_type in [0, 1, 4] {
            let request = FailureRequest { unit_id: 101, type_id: failure_type, instance: 2 };
            let refusal = failure_sets(&request, without_motors).expect_err("no SIM_MOT2_EFF");
            assert_eq!(refusal.result, MavResult::MAV_RESULT_UNSUPPORTED);
            assert_eq!(refusal.reason, "SIM_MOT2_EFF is not a parameter of this plant");
        }
        let gps = FailureRequest { unit_id: 4, type_id: 1, instance: 0 };
        assert_eq!(failure_sets(&gps, without_motors).map_err(|r| r.result), one("SIM_GPS_FAIL", 1.0));
    }
}

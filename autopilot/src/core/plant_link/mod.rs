//! The plant protocol (MAVLink 2 HIL messages, as PX4 uses with its simulators), pure: no sockets, clocks or
//! files. In from the plant: byte streams or datagrams holding `HIL_SENSOR` (every plant step, 500 Hz by
//! default), `HIL_GPS` (when a fix is released, 10 Hz by default), `HIL_STATE_QUATERNION` (ground truth,
//! every step), `BATTERY_STATUS` (the pack, 10 Hz) and `RC_CHANNELS` (the board's radio receiver, as it
//! reads it; the [`RcFrame`](crate::core::manual::RcFrame) for the vehicle's manual control); out to the estimator: [`ImuSample`](crate::core::estimator::ImuSample),
//! [`MagSample`](crate::core::estimator::MagSample), [`BaroSample`](crate::core::estimator::BaroSample),
//! [`GpsSample`](crate::core::estimator::GpsSample) and [`TruthSample`](crate::core::estimator::TruthSample),
//! and to the battery monitor a [`BatterySample`](crate::core::battery::BatterySample). Out to the plant, once per sensor sample: the four motor commands as
//! `HIL_ACTUATOR_CONTROLS` (`controls[i] = (pwm_us - 1000) / 1000` for the paper's rotors 1..4, the armed
//! flag in `mode`, `time_usec` echoing the sensor sample it answers).
//!
//! # Forwarded commands (failure injection)
//!
//! A ground station's MAV_CMD_INJECT_FAILURE (420) is the plant's business: the autopilot (with
//! `SYS_FAILURE_EN` = 1, `core::mavlink::failure`) forwards it as a `COMMAND_LONG` (command 420, param1 the
//! FAILURE_UNIT, param2 the FAILURE_TYPE, param3 the instance, 0 = all; target 0/0) written on the plant
//! link just before the step's `HIL_ACTUATOR_CONTROLS`, in the same datagram or serial write. The plant
//! answers each with exactly one `COMMAND_ACK` (command 420; ACCEPTED, UNSUPPORTED for a combination it
//! does not simulate, DENIED for one it refuses) before the `HIL_SENSOR` of a following step (the sensor
//! message stays last: the autopilot ticks on it). A real board that does not know the command simply
//! never answers; the autopilot then answers the ground station UNSUPPORTED after 0.3 s.
//!
//! # Who runs the motors
//!
//! The plant runs its motors on `controls` when `mode` has `MAV_MODE_FLAG_SAFETY_ARMED` (the vehicle is
//! armed) or `MAV_MODE_FLAG_TEST_ENABLED` (a motor test, MAV_CMD_ACTUATOR_TEST or MAV_CMD_DO_MOTOR_TEST,
//! drives the outputs of the disarmed vehicle, as PX4's actuator test drives a disarmed board's ESCs);
//! with neither it holds every motor at 1000 µs whatever `controls` says
//! ([`ActuatorCommand::effective_pwm_us`]). The test flag is its own bit rather than a borrowed "armed",
//! so that the plant (and a log of the link) can tell a bench test from a flight.
//!
//!
//! # The module
//!
//! - [`codec`]: each message to and from its samples, and the frames (its names are re-exported here);
//! - [`budget`]: the bytes per second the protocol needs at a plant rate, against a serial line's baud;
//! - [`health`]: the link as the vehicle sees it (samples missing and late, the drop rate, byte counts).

pub mod budget;
pub mod codec;
pub mod health;

pub use codec::*;

/// The plant's default UDP port (the plant listens on it), as PX4's simulators.
pub const DEFAULT_PLANT_PORT: u16 = 4560;

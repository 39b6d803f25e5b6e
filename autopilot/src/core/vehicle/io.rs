//! What goes into and out of the vehicle: one step's sensor inputs (and how they feed the estimator), its
//! outputs (PWM, armed, telemetry), the snapshot the onboard log records, and what the vehicle asks of the
//! shell around it.

use ::mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;

use crate::core::battery::{BatterySample, BatteryStatus};
use crate::core::commander::{FlightMode, LandedState};
use crate::core::control::{ControllerKind, Reference};
use crate::core::estimator::{
    BaroSample, Estimator, EstimatorSource, EstimatorState, GpsSample, ImuSample, Innovations, MagSample, TruthSample,
};
use crate::core::manual::{ManualStatus, RcFrame};
use crate::core::plant_link::PlantCommandAck;
use crate::core::plant_link::health::{PlantLinkCounters, PlantLinkStatus};

/// One step's sensor inputs (any may be absent).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleInputs {
    pub imu: Option<ImuSample>,
    pub mag: Option<MagSample>,
    pub baro: Option<BaroSample>,
    pub gps: Option<GpsSample>,
    pub truth: Option<TruthSample>,
    /// A reading of the pack (BATTERY_STATUS from the plant or the ARM board).
    pub battery: Option<BatterySample>,
    /// A frame of the radio receiver (RC_CHANNELS from the plant or the ARM board).
    pub rc: Option<RcFrame>,
    /// The plant's answer to a command the vehicle forwarded to it (a failure injection).
    pub plant_ack: Option<PlantCommandAck>,
    /// What the shell has counted on the plant link so far (bytes each way, malformed frames), for the
    /// link's health ([`crate::core::plant_link::health`]); `None` from a host that does not count (the last
    /// counts hold).
    pub plant_link: Option<PlantLinkCounters>,
}

impl VehicleInputs {
    /// Feeds what arrived into `estimator` at `now_us` (its clock advances without an IMU sample); whether
    /// a control tick is due: an IMU sample, or a truth sample with the `Truth` source.
    pub(crate) fn feed(&self, now_us: u64, estimator: &mut Estimator, source: EstimatorSource) -> bool {
        let truth_source = source == EstimatorSource::Truth;
        let mut tick = false;
        if let Some(imu) = &self.imu {
            estimator.update_imu(imu);
            tick = !truth_source;
        } else {
            estimator.update_clock(now_us);
        }
        if let Some(mag) = &self.mag {
            estimator.update_mag(mag);
        }
        if let Some(baro) = &self.baro {
            estimator.update_baro(baro);
        }
        if let Some(gps) = &self.gps {
            estimator.update_gps(gps);
        }
        if let Some(truth) = &self.truth {
            estimator.update_truth(truth);
            tick |= truth_source;
        }
        tick
    }

    #[cfg(test)]
    /// A truth-fed vehicle at rest, level, at the origin: the truth and the IMU reading gravity (tests).
    pub(crate) fn at_rest_truth(time_us: u64) -> Self {
        use nalgebra::UnitQuaternion;
        let truth = TruthSample {
            time_us,
            pos_ned_m: Vector3::zeros(),
            vel_ned_mps: Vector3::zeros(),
            q_ned_frd: UnitQuaternion::identity(),
            rate_frd_radps: Vector3::zeros(),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -crate::core::estimator::eskf::GRAVITY_MPS2),
        };
        let imu =
            ImuSample { time_us, accel_frd_mps2: truth.specific_force_frd_mps2, gyro_frd_radps: Vector3::zeros() };
        Self { imu: Some(imu), truth: Some(truth), ..Self::default() }
    }
}

/// One step's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleOutputs {
    /// Motor commands (µs), rotors 1..4 as in the paper; 1000 when the motors are off.
    pub pwm_us: [f64; 4],
    pub armed: bool,
    /// A motor test drives the outputs this step (the vehicle is disarmed): the plant must run them.
    pub motor_test: bool,
    /// Telemetry due this step (HEARTBEAT, STATUSTEXT of events, streams), for every ground station.
    pub messages: Vec<MavMessage>,
    /// Messages for the plant, to write on the plant link before this step's actuator message (a
    /// forwarded failure injection; see `core::plant_link`).
    pub plant_messages: Vec<MavMessage>,
}

impl VehicleOutputs {
    /// Whether the motors run on these outputs: armed, or a motor test while disarmed.
    #[must_use]
    pub fn motors_running(&self) -> bool {
        self.armed || self.motor_test
    }
}

/// What the onboard log records of the vehicle after a step, copied out so that the shell encodes it
/// without reaching into the vehicle: the estimate and the fused filter's innovations, the reference
/// flown and the controller's attitude setpoint, the motor commands, the commander's state and the plant
/// link's health. The controller's own values (adaptive weights and the rest) are
/// [`crate::core::control::Controller::telemetry`].
#[derive(Debug, Clone, PartialEq)]
pub struct LogSnapshot {
    pub estimate: EstimatorState,
    pub innovations: Innovations,
    /// The reference of the last step (None: motors idle).
    pub reference: Option<Reference>,
    /// The attitude (roll, pitch, yaw) the controller's position loop last asked for (rad).
    pub attitude_setpoint_rad: Vector3<f64>,
    /// Motor commands (µs), rotors 1..4 as in the paper (a motor test's while one runs).
    pub pwm_us: [f64; 4],
    pub armed: bool,
    pub mode: FlightMode,
    pub landed: LandedState,
    pub battery: BatteryStatus,
    pub controller: ControllerKind,
    /// The pilot's input: the sticks in use (manual_control_setpoint) and the last radio frame (input_rc).
    pub manual: ManualStatus,
    /// The plant link's health: samples missing and late, drop rate, bytes (plant_link_status).
    pub plant_link: PlantLinkStatus,
}

/// What the vehicle asks of the shell around it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ShellEffect {
    /// Restart the autopilot (PREFLIGHT_REBOOT_SHUTDOWN): rebuild the vehicle from its configuration and
    /// what is persisted.
    Reboot,
    /// Persist the mission: its QGC WPL 110 text (empty mission: only the header).
    SaveMission(String),
    /// Persist the parameters: their text (`NAME<TAB>VALUE` lines, those that differ from the defaults).
    SaveParams(String),
    /// Persist the geofence: its items as QGC WPL 110 text (empty: only the header).
    SaveFence(String),
    /// Persist the rally points: their items as QGC WPL 110 text (empty: only the header).
    SaveRally(String),
}

//! Failure injection (MAV_CMD_INJECT_FAILURE, 420) with PX4's semantics, gated by `SYS_FAILURE_EN`. In:
//! the decoded injection ([`FailureRequest`]) with its sender, the plant's answer to a forwarded one
//! ([`PlantCommandAck`]), vehicle time. Out: the COMMAND_LONG to forward on the plant link, the
//! COMMAND_ACK (and a STATUSTEXT) for the ground station, and two filters the vehicle applies to what it
//! hears (the ground-station link, manual control).
//!
//! Who simulates what: a fault of something the plant simulates (a motor, GPS, baro, magnetometer,
//! accelerometer, gyro, the pack, the board's radio) is the plant's: it is forwarded, and the plant's
//! COMMAND_ACK is the answer (ACCEPTED, UNSUPPORTED for a combination it does not simulate, DENIED for a
//! value it refuses; see `core::plant_link` for the protocol). A plant that does not answer within
//! [`PLANT_ANSWER_TIMEOUT_US`] of vehicle time (a real board that does not know the command) gets the
//! ground station UNSUPPORTED. The autopilot's own inputs are its own, as in PX4 where the MAVLink module
//! handles the link's failure: `MAVLINK_SIGNAL` OFF makes the vehicle deaf to every ground-station message
//! but this command (so OK can restore it), and `RC_SIGNAL` OFF, once the plant has silenced the board's
//! radio, makes it ignore MANUAL_CONTROL and RC_CHANNELS_OVERRIDE too.
//!
//! What never happens here: the vehicle's reactions. The estimator and the commander do not see this
//! module; they react to the data the fault changes (a GPS that stops, a rotor that lifts less), as they
//! would to the fault itself.

use ::mavlink::dialects::common::{
    COMMAND_ACK_DATA, FailureType, FailureUnit, MavCmd, MavMessage, MavResult, MavSeverity,
};

use super::telemetry::statustext;
use crate::core::plant_link::{PlantCommandAck, encode_inject_failure};

/// How long the vehicle waits for the plant's answer to a forwarded injection (µs of vehicle time).
pub const PLANT_ANSWER_TIMEOUT_US: u64 = 300_000;

/// Every FAILURE_UNIT the MAVLink dialect names (each one's number is its value).
const UNITS: [FailureUnit; 17] = {
    use FailureUnit::*;
    [
        FAILURE_UNIT_SENSOR_GYRO,
        FAILURE_UNIT_SENSOR_ACCEL,
        FAILURE_UNIT_SENSOR_MAG,
        FAILURE_UNIT_SENSOR_BARO,
        FAILURE_UNIT_SENSOR_GPS,
        FAILURE_UNIT_SENSOR_OPTICAL_FLOW,
        FAILURE_UNIT_SENSOR_VIO,
        FAILURE_UNIT_SENSOR_DISTANCE_SENSOR,
        FAILURE_UNIT_SENSOR_AIRSPEED,
        FAILURE_UNIT_SYSTEM_BATTERY,
        FAILURE_UNIT_SYSTEM_MOTOR,
        FAILURE_UNIT_SYSTEM_SERVO,
        FAILURE_UNIT_SYSTEM_AVOIDANCE,
        FAILURE_UNIT_SYSTEM_RC_SIGNAL,
        FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL,
        FAILURE_UNIT_SYSTEM_ESC,
        FAILURE_UNIT_SYSTEM_TRAFFIC_AVOIDANCE,
    ]
};

/// Every FAILURE_TYPE the MAVLink dialect names.
const TYPES: [FailureType; 9] = {
    use FailureType::*;
    [
        FAILURE_TYPE_OK,
        FAILURE_TYPE_OFF,
        FAILURE_TYPE_STUCK,
        FAILURE_TYPE_GARBAGE,
        FAILURE_TYPE_WRONG,
        FAILURE_TYPE_SLOW,
        FAILURE_TYPE_DELAYED,
        FAILURE_TYPE_INTERMITTENT,
        FAILURE_TYPE_DRIFT,
    ]
};

/// One MAV_CMD_INJECT_FAILURE, as the autopilot decodes it and the plant applies it: param1 the unit
/// (MAVLink's FAILURE_UNIT), param2 the type (FAILURE_TYPE), param3 the instance (0 = all). The numbers are
/// kept as sent, so that a unit or type the dialect does not name (unit 200, type 9) is still carried,
/// forwarded and answered in its own words; [`FailureRequest::unit`] and [`FailureRequest::failure_type`]
/// read them as the dialect's [`FailureUnit`] and [`FailureType`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FailureRequest {
    /// FAILURE_UNIT number (param1).
    pub unit_id: u32,
    /// FAILURE_TYPE number (param2).
    pub type_id: u32,
    /// Instance, 0 = all (param3).
    pub instance: u32,
}

impl FailureRequest {
    /// `failure_type` of `unit` `instance` (0 = all).
    #[must_use]
    pub fn new(unit: FailureUnit, failure_type: FailureType, instance: u32) -> Self {
        Self { unit_id: unit as u32, type_id: failure_type as u32, instance }
    }

    /// The request in a command's parameters; None when one is not a whole number 0-255 (a malformed
    /// command, refused with DENIED by the caller).
    #[must_use]
    pub fn from_params(param1: f32, param2: f32, param3: f32) -> Option<Self> {
        let byte = |x: f32| (x.is_finite() && x.fract() == 0.0 && (0.0..=255.0).contains(&x)).then_some(x as u32);
        Some(Self { unit_id: byte(param1)?, type_id: byte(param2)?, instance: byte(param3)? })
    }

    /// param1..param3 of the command that carries it.
    #[must_use]
    pub fn params(&self) -> [f32; 3] {
        [self.unit_id as f32, self.type_id as f32, self.instance as f32]
    }

    /// The unit, if the dialect names it.
    #[must_use]
    pub fn unit(&self) -> Option<FailureUnit> {
        UNITS.into_iter().find(|u| *u as u32 == self.unit_id)
    }

    /// The failure type, if the dialect names it.
    #[must_use]
    pub fn failure_type(&self) -> Option<FailureType> {
        TYPES.into_iter().find(|t| *t as u32 == self.type_id)
    }

    /// Whether it is of `unit`.
    #[must_use]
    pub fn is_unit(&self, unit: FailureUnit) -> bool {
        self.unit_id == unit as u32
    }

    /// Whether it is of `failure_type`.
    #[must_use]
    pub fn is_type(&self, failure_type: FailureType) -> bool {
        self.type_id == failure_type as u32
    }

    /// How a ground station's operator reads it ("gps off", "motor 1 wrong").
    #[must_use]
    pub fn describe(&self) -> String {
        use FailureType::*;
        use FailureUnit::*;
        let unit = self.unit().map(|u| match u {
            FAILURE_UNIT_SENSOR_GYRO => "gyro",
            FAILURE_UNIT_SENSOR_ACCEL => "accel",
            FAILURE_UNIT_SENSOR_MAG => "mag",
            FAILURE_UNIT_SENSOR_BARO => "baro",
            FAILURE_UNIT_SENSOR_GPS => "gps",
            FAILURE_UNIT_SENSOR_OPTICAL_FLOW => "optical flow",
            FAILURE_UNIT_SENSOR_VIO => "vio",
            FAILURE_UNIT_SENSOR_DISTANCE_SENSOR => "distance sensor",
            FAILURE_UNIT_SENSOR_AIRSPEED => "airspeed",
            FAILURE_UNIT_SYSTEM_BATTERY => "battery",
            FAILURE_UNIT_SYSTEM_MOTOR => "motor",
            FAILURE_UNIT_SYSTEM_SERVO => "servo",
            FAILURE_UNIT_SYSTEM_AVOIDANCE => "avoidance",
            FAILURE_UNIT_SYSTEM_RC_SIGNAL => "rc signal",
            FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL => "mavlink signal",
            FAILURE_UNIT_SYSTEM_ESC => "esc",
            FAILURE_UNIT_SYSTEM_TRAFFIC_AVOIDANCE => "traffic avoidance",
        });
        let what = self.failure_type().map(|t| match t {
            FAILURE_TYPE_OK => "ok",
            FAILURE_TYPE_OFF => "off",
            FAILURE_TYPE_STUCK => "stuck",
            FAILURE_TYPE_GARBAGE => "garbage",
            FAILURE_TYPE_WRONG => "wrong",
            FAILURE_TYPE_SLOW => "slow",
            FAILURE_TYPE_DELAYED => "delayed",
            FAILURE_TYPE_INTERMITTENT => "intermittent",
            FAILURE_TYPE_DRIFT => "drift",
        });
        let unit = unit.map_or_else(|| format!("unit {}", self.unit_id), str::to_owned);
        let what = what.map_or_else(|| format!("type {}", self.type_id), str::to_owned);
        if self.instance == 0 { format!("{unit} {what}") } else { format!("{unit} {} {what}", self.instance) }
    }

    /// An OFF or OK of it (the only types the autopilot's own inputs take).
    fn off_or_ok(&self) -> bool {
        self.is_type(FailureType::FAILURE_TYPE_OFF) || self.is_type(FailureType::FAILURE_TYPE_OK)
    }
}

/// Who asked (the ACK goes back to them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Requester {
    pub system: u8,
    pub component: u8,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Pending {
    request: FailureRequest,
    from: Requester,
    deadline_us: u64,
}

/// The failure-injection service's state: what waits for the plant, and the two input filters.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FailureInjection {
    pending: Option<Pending>,
    to_plant: Vec<FailureRequest>,
    /// MAVLINK_SIGNAL OFF: the vehicle hears nothing from a ground station but this command.
    gcs_link_off: bool,
    /// RC_SIGNAL OFF (accepted by the plant): MANUAL_CONTROL and RC_CHANNELS_OVERRIDE are ignored.
    manual_off: bool,
}

impl FailureInjection {
    /// An injection from `from` at `now_us`, `enabled` by SYS_FAILURE_EN: the replies to send at once
    /// (none while it waits for the plant: the ACK comes from [`FailureInjection::on_plant_ack`] or
    /// [`FailureInjection::step`]).
    pub fn inject(&mut self, now_us: u64, from: Requester, request: FailureRequest, enabled: bool) -> Vec<MavMessage> {
        if !enabled {
            return reply(from, MavResult::MAV_RESULT_DENIED, Some("Injection denied: SYS_FAILURE_EN is 0"));
        }
        if request.is_unit(FailureUnit::FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL) {
            return if request.off_or_ok() && request.instance <= 1 {
                self.gcs_link_off = request.is_type(FailureType::FAILURE_TYPE_OFF);
                accepted(from, &request)
            } else {
                unsupported(from, &request)
            };
        }
        if request.is_unit(FailureUnit::FAILURE_UNIT_SYSTEM_RC_SIGNAL) && !request.off_or_ok() {
            return unsupported(from, &request);
        }
        match self.pending {
            // A ground station's retransmission of the command that waits: it is still on its way.
            Some(p) if p.request == request && p.from == from => Vec::new(),
            Some(_) => reply(
                from,
                MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
                Some("Injection: the plant has not answered yet"),
            ),
            None => {
                self.pending = Some(Pending { request, from, deadline_us: now_us + PLANT_ANSWER_TIMEOUT_US });
                self.to_plant.push(request);
                Vec::new()
            }
        }
    }

    /// The COMMAND_LONGs to write on the plant link before this step's actuator message (drained).
    pub fn take_plant_messages(&mut self) -> Vec<MavMessage> {
        self.to_plant.drain(..).map(|r| MavMessage::COMMAND_LONG(encode_inject_failure(r.params()))).collect()
    }

    /// The plant's answer: the ACK (and what it means in words) for the ground station that asked. An
    /// answer to nothing pending (late, after the timeout) changes nothing.
    pub fn on_plant_ack(&mut self, ack: PlantCommandAck) -> Vec<MavMessage> {
        if ack.command_id != MavCmd::MAV_CMD_INJECT_FAILURE as u32 {
            return Vec::new();
        }
        let Some(p) = self.pending.take() else { return Vec::new() };
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => {
                if p.request.is_unit(FailureUnit::FAILURE_UNIT_SYSTEM_RC_SIGNAL) {
                    self.manual_off = p.request.is_type(FailureType::FAILURE_TYPE_OFF);
                }
                accepted(p.from, &p.request)
            }
            MavResult::MAV_RESULT_UNSUPPORTED => unsupported(p.from, &p.request),
            result => {
                let text = format!("Injection refused by the plant: {}", p.request.describe());
                reply(p.from, result, Some(&text))
            }
        }
    }

    /// Vehicle time advances: a forwarded injection the plant has not answered in time is UNSUPPORTED.
    pub fn step(&mut self, now_us: u64) -> Vec<MavMessage> {
        match self.pending {
            Some(p) if now_us >= p.deadline_us => {
                self.pending = None;
                let text = format!("Injection: no plant answer ({})", p.request.describe());
                reply(p.from, MavResult::MAV_RESULT_UNSUPPORTED, Some(&text))
            }
            _ => Vec::new(),
        }
    }

    /// Whether the vehicle hears `msg` from a ground station: everything, unless MAVLINK_SIGNAL is off
    /// (then only MAV_CMD_INJECT_FAILURE, so the link can be restored), and no manual control while
    /// RC_SIGNAL is off.
    #[must_use]
    pub fn hears(&self, msg: &MavMessage) -> bool {
        let injection = matches!(msg, MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_INJECT_FAILURE);
        let manual = matches!(msg, MavMessage::MANUAL_CONTROL(_) | MavMessage::RC_CHANNELS_OVERRIDE(_));
        (!self.gcs_link_off || injection) && !(self.manual_off && manual)
    }

    /// Whether MAVLINK_SIGNAL OFF is in effect.
    #[must_use]
    pub fn gcs_link_off(&self) -> bool {
        self.gcs_link_off
    }
}

fn ack(from: Requester, result: MavResult) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_INJECT_FAILURE,
        result,
        target_system: from.system,
        target_component: from.component,
        ..Default::default()
    })
}

/// The ACK and, when there is one, a text (at most 50 bytes: one STATUSTEXT).
fn reply(from: Requester, result: MavResult, text: Option<&str>) -> Vec<MavMessage> {
    let mut out = vec![ack(from, result)];
    out.extend(text.map(|t| statustext(MavSeverity::MAV_SEVERITY_WARNING, t)));
    out
}

fn accepted(from: Requester, request: &FailureRequest) -> Vec<MavMessage> {
    let text = format!("Failure injected: {}", request.describe());
    vec![ack(from, MavResult::MAV_RESULT_ACCEPTED), statustext(MavSeverity::MAV_SEVERITY_INFO, &text)]
}

fn unsupported(from: Requester, request: &FailureRequest) -> Vec<MavMessage> {
    let text = format!("Injection not supported: {}", request.describe());
    reply(from, MavResult::MAV_RESULT_UNSUPPORTED, Some(&text))
}

#[cfg(test)]
mod tests {
    use super::*;

    use FailureUnit::*;

    const GCS: Requester = Requester { system: 255, component: 190 };
    const OK: u32 = FailureType::FAILURE_TYPE_OK as u32;
    const OFF: u32 = FailureType::FAILURE_TYPE_OFF as u32;

    /// A unit's number.
    fn u(unit: FailureUnit) -> u32 {
        unit as u32
    }

    fn req(unit_id: u32, type_id: u32, instance: u32) -> FailureRequest {
        FailureRequest { unit_id, type_id, instance }
    }

    fn result_of(messages: &[MavMessage]) -> Option<MavResult> {
        messages.iter().find_map(|m| match m {
            MavMessage::COMMAND_ACK(a) => {
                assert_eq!((a.target_system, a.target_component), (GCS.system, GCS.component));
                assert_eq!(a.command, MavCmd::MAV_CMD_INJECT_FAILURE);
                Some(a.result)
            }
            _ => None,
        })
    }

    fn text_of(messages: &[MavMessage]) -> String {
        messages
            .iter()
            .find_map(|m| match m {
                MavMessage::STATUSTEXT(s) => {
                    Some(String::from_utf8_lossy(&s.text.to_vec()).trim_end_matches('\0').to_owned())
                }
                _ => None,
            })
            .unwrap_or_default()
    }

    fn plant_ack(result: MavResult) -> PlantCommandAck {
        PlantCommandAck { command_id: 420, result }
    }

    #[test]
    fn given_sys_failure_en_0_when_any_failure_is_injected_then_it_is_denied_and_nothing_goes_to_the_plant() {
        let mut f = FailureInjection::default();
        for r in [
            req(u(FAILURE_UNIT_SENSOR_GPS), OFF, 0),
            req(u(FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL), OFF, 0),
            req(200, 9, 0),
        ] {
            let out = f.inject(0, GCS, r, false);
            assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_DENIED));
            assert_eq!(text_of(&out), "Injection denied: SYS_FAILURE_EN is 0");
        }
        assert!(f.take_plant_messages().is_empty());
        assert!(f.hears(&MavMessage::HEARTBEAT(Default::default())));
    }

    #[test]
    fn given_a_plant_fault_when_injected_then_it_is_forwarded_once_and_the_plants_ack_is_the_answer() {
        let mut f = FailureInjection::default();
        assert!(f.inject(1_000, GCS, req(u(FAILURE_UNIT_SENSOR_GPS), OFF, 0), true).is_empty());
        let forwarded = f.take_plant_messages();
        assert_eq!(forwarded.len(), 1);
        let MavMessage::COMMAND_LONG(c) = &forwarded[0] else { panic!("{forwarded:?}") };
        assert_eq!((c.command, c.param1, c.param2, c.param3), (MavCmd::MAV_CMD_INJECT_FAILURE, 4.0, 1.0, 0.0));
        assert!(f.take_plant_messages().is_empty(), "drained");
        // A retransmission of the same command while it waits is not forwarded again.
        assert!(f.inject(2_000, GCS, req(u(FAILURE_UNIT_SENSOR_GPS), OFF, 0), true).is_empty());
        assert!(f.take_plant_messages().is_empty());
        let out = f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(text_of(&out), "Failure injected: gps off");
        // A second answer to nothing is ignored.
        assert!(f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_ACCEPTED)).is_empty());
    }

    #[test]
    fn given_the_plant_answers_unsupported_or_refuses_then_the_ground_station_gets_that_result_in_words() {
        let mut f = FailureInjection::default();
        f.inject(0, GCS, req(5, OFF, 0), true);
        let out = f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_UNSUPPORTED));
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_UNSUPPORTED));
        assert_eq!(text_of(&out), "Injection not supported: optical flow off");
        f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_MOTOR), 4, 7), true);
        let out = f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_DENIED));
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_DENIED));
        assert_eq!(text_of(&out), "Injection refused by the plant: motor 7 wrong");
    }

    #[test]
    fn given_no_plant_answer_when_0_3_s_of_vehicle_time_pass_then_unsupported_and_a_new_injection_is_taken() {
        let mut f = FailureInjection::default();
        f.inject(1_000_000, GCS, req(u(FAILURE_UNIT_SENSOR_BARO), 2, 0), true);
        assert!(f.step(1_299_999).is_empty());
        let out = f.step(1_300_000);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_UNSUPPORTED));
        assert_eq!(text_of(&out), "Injection: no plant answer (baro stuck)");
        assert!(f.step(2_000_000).is_empty(), "answered once");
        f.take_plant_messages();
        assert!(f.inject(2_000_000, GCS, req(u(FAILURE_UNIT_SENSOR_MAG), 1, 0), true).is_empty());
        assert_eq!(f.take_plant_messages().len(), 1);
    }

    #[test]
    fn given_one_injection_waiting_when_a_different_one_comes_then_it_is_temporarily_rejected() {
        let mut f = FailureInjection::default();
        f.inject(0, GCS, req(u(FAILURE_UNIT_SENSOR_GPS), OFF, 0), true);
        let out = f.inject(0, GCS, req(u(FAILURE_UNIT_SENSOR_BARO), OFF, 0), true);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
        assert_eq!(f.take_plant_messages().len(), 1, "only the first went to the plant");
    }

    #[test]
    fn given_mavlink_signal_off_then_only_the_injection_command_is_heard_until_ok_restores_the_link() {
        let mut f = FailureInjection::default();
        let out = f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL), OFF, 0), true);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_ACCEPTED));
        assert!(f.take_plant_messages().is_empty(), "the link is the autopilot's own");
        assert!(!f.hears(&MavMessage::HEARTBEAT(Default::default())));
        let arm = crate::core::mavlink::command_long(1, 1, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7]);
        assert!(!f.hears(&arm));
        let ok = crate::core::mavlink::command_long(
            1,
            1,
            MavCmd::MAV_CMD_INJECT_FAILURE,
            [105.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        assert!(f.hears(&ok));
        let out = f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL), OK, 0), true);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_ACCEPTED));
        assert!(f.hears(&MavMessage::HEARTBEAT(Default::default())));
        let out = f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL), 2, 0), true);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_UNSUPPORTED));
    }

    #[test]
    fn given_rc_signal_off_accepted_by_the_plant_then_manual_control_is_ignored_until_ok() {
        let mut f = FailureInjection::default();
        let sticks = MavMessage::MANUAL_CONTROL(Default::default());
        f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_RC_SIGNAL), OFF, 0), true);
        assert_eq!(f.take_plant_messages().len(), 1, "the board's radio is the plant's");
        assert!(f.hears(&sticks), "not before the plant accepted it");
        f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(!f.hears(&sticks));
        assert!(!f.hears(&MavMessage::RC_CHANNELS_OVERRIDE(Default::default())));
        assert!(f.hears(&MavMessage::HEARTBEAT(Default::default())));
        f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_RC_SIGNAL), OK, 0), true);
        f.on_plant_ack(plant_ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(f.hears(&sticks));
        let out = f.inject(0, GCS, req(u(FAILURE_UNIT_SYSTEM_RC_SIGNAL), 2, 0), true);
        assert_eq!(result_of(&out), Some(MavResult::MAV_RESULT_UNSUPPORTED));
    }

    #[test]
    fn given_params_that_are_not_whole_bytes_then_no_request_is_made() {
        assert_eq!(FailureRequest::from_params(4.0, 1.0, 0.0), Some(req(4, 1, 0)));
        for bad in [(4.5, 1.0, 0.0), (f32::NAN, 1.0, 0.0), (4.0, -1.0, 0.0), (4.0, 1.0, 256.0)] {
            assert_eq!(FailureRequest::from_params(bad.0, bad.1, bad.2), None, "{bad:?}");
        }
    }

    proptest::proptest! {
        /// Any sequence of injections (any unit, type, instance, enabled or not), plant answers (any
        /// result, wanted or not) and time steps: every injection is answered exactly once (at once, or by
        /// the plant's ACK, or by the timeout), a retransmission of the waiting one only by that one answer,
        /// and nothing goes to the plant that is not waiting for its answer.
        #[test]
        fn every_injection_gets_exactly_one_answer_whatever_the_plant_does(
            events in proptest::collection::vec((0u8..4, 0usize..8, 0u8..=4, 0u8..=1, proptest::bool::weighted(0.9), 0u8..5), 1..60)
        ) {
            let mut f = FailureInjection::default();
            let mut now_us = 0;
            let (mut asked, mut answered, mut waiting_forwarded) = (0usize, 0usize, 0usize);
            let mut last_asked: Option<FailureRequest> = None;
            for (what, unit, kind, instance, enabled, result) in events {
                let results = [
                    MavResult::MAV_RESULT_ACCEPTED,
                    MavResult::MAV_RESULT_UNSUPPORTED,
                    MavResult::MAV_RESULT_DENIED,
                    MavResult::MAV_RESULT_FAILED,
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
                ];
                // A few units, so that retransmissions and collisions with the waiting one are common.
                let unit = [u(FAILURE_UNIT_SENSOR_GYRO), u(FAILURE_UNIT_SENSOR_BARO), u(FAILURE_UNIT_SENSOR_GPS), 5, u(FAILURE_UNIT_SYSTEM_MOTOR), u(FAILURE_UNIT_SYSTEM_RC_SIGNAL), u(FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL), 200][unit];
                let out = match what {
                    0 => {
                        let r = req(unit, u32::from(kind), u32::from(instance));
                        let retransmission = enabled && f.pending.is_some_and(|p| p.request == r && p.from == GCS);
                        if !retransmission {
                            asked += 1;
                        }
                        last_asked = Some(r);
                        f.inject(now_us, GCS, r, enabled)
                    }
                    1 => f.on_plant_ack(plant_ack(results[usize::from(result)])),
                    2 => {
                        now_us += u64::from(result) * 100_000;
                        f.step(now_us)
                    }
                    _ => {
                        waiting_forwarded += f.take_plant_messages().len();
                        Vec::new()
                    }
                };
                let acks = out.iter().filter(|m| matches!(m, MavMessage::COMMAND_ACK(_))).count();
                proptest::prop_assert!(acks <= 1);
                answered += acks;
                proptest::prop_assert!(waiting_forwarded <= asked);
            }
            // Whatever still waits is answered by the timeout.
            answered += f.step(now_us + PLANT_ANSWER_TIMEOUT_US).iter().filter(|m| matches!(m, MavMessage::COMMAND_ACK(_))).count();
            proptest::prop_assert_eq!(answered, asked, "last asked {:?}", last_asked);
        }
    }
}

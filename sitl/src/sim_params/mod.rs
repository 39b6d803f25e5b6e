//! The plant as its own MAVLink component: SIM_ parameters that change the wind while the SITL runs, as
//! ArduPilot users set `SIM_*` parameters (e.g. a Beaufort-4 gust from a ground-station script), and the
//! plant's true state (SIM_STATE, 50 Hz of plant time) for any client to judge a flight by.
//!
//! In: MAVLink datagrams on UDP 127.0.0.1:[`SIM_PARAM_PORT_BASE`] + N (instance N) addressed to system
//! N+1 (or 0), component [`PLANT_COMPONENT_ID`] (or 0): PARAM_REQUEST_LIST, PARAM_REQUEST_READ
//! (by `param_index` when >= 0, else by `param_id`) and PARAM_SET; any other message (a client's
//! HEARTBEAT) only makes its sender a peer. Out, to the sender's address in the MAVLink version it used:
//! PARAM_VALUE (`param_count` = [`SIM_PARAMS`]`.len()`, `param_index` = its table index; the reals REAL32,
//! the whole-numbered SIM_GUST_ON, SIM_TURB and SIM_BEAUFORT INT32 in PX4's bytewise encoding, as the
//! autopilot's integers, and a set of them takes INT32 or a whole REAL32 alike), STATUSTEXT for a refused
//! set (then the unchanged value echoed) and for a gust started or
//! released (INFO, with the plant time `t=`, sent before the echo); and a HEARTBEAT
//! (MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID) once per wall second to every peer heard in the
//! last [`PEER_EXPIRY`], so `wait_heartbeat` works on the port.
//!
//! Why that heartbeat type: the plant is not a vehicle. MAV_AUTOPILOT_INVALID says "not a flight
//! controller", and MAV_TYPE_ONBOARD_CONTROLLER is one of the types ground stations already class as a
//! component rather than a vehicle (pymavlink's `probably_vehicle_heartbeat` skips it, as it skips
//! INVALID), so a ground station pointed at this port never shows a phantom second vehicle. A client
//! addresses the plant as (N+1, 51), or with target 0 / 0.
//!
//! A set takes effect at the next plant step (the wind is evaluated at the start of each step). The
//! [`SimParamService`] is pure (messages and a plant in, replies out); [`SimParamLink`] is its socket,
//! polled by the plant server between steps with the server's service (the plant link's `PlantHook`: every 50 steps and at least
//! every 20 ms of wall time while the plant waits, never once per step).
//!
//! The parameter machinery is the autopilot's, not a copy: [`SIM_PARAMS`] is a table of the autopilot's
//! [`ParamDef`] with no docs group and no config binding ([`SimParamDef`] = `ParamDef<(), ()>`), its values
//! live in the autopilot's [`ParamStore`] over that table, and the protocol (addressing, lookup by index or
//! id, type decoding, range and kind checks, PARAM_VALUE encoding, refusal texts) is the autopilot's [`ParamService`] for
//! component [`PLANT_COMPONENT_ID`]. What is the plant's own is `apply`, the hook
//! [`ParamService::on_message_with`] calls with a set that passed the table's check: it changes the wind,
//! moves SIM_BEAUFORT and SIM_GUST_SPD together and writes the gust's note, or refuses with the wind's own
//! reason. A refusal therefore reads as the autopilot's does (`SIM_GUST_SPD: 40 not in 0..30`, `unknown
//! parameter SIM_NOPE`, `SIM_TURB: the plant refused it: ...`), and a list request, which the shared
//! service streams a few values per call, is drained at once (every value in one reply).
//!
//! The gust: SIM_GUST_ON = 1 starts the spec's 1-cos gust at the current plant time with the current
//! SIM_GUST_SPD (m/s), SIM_GUST_DIR (deg, the direction it blows toward, 0 = north, 90 = east) and
//! SIM_GUST_RISE (s); SIM_GUST_ON = 0 releases it: it falls over its rise time from now (or from the end
//! of its rise, if released while still rising). Changing SPD, DIR or RISE while a gust blows changes the
//! next gust, not this one (a step in the wind would defeat the 1-cos shape); a new gust replaces any
//! earlier one, even one still falling. SIM_TURB = 1 adds the spec's Gauss-Markov turbulence (σ = 1.3,
//! 1.3, 0.67 m/s; τ = 1.76, 1.76, 0.22 s) scaled by the gust profile, so it only blows while a gust does
//! (it replaces a configured turbulence model; 0 switches any off). SIM_BEAUFORT = n sets SIM_GUST_SPD to
//! force n's mid-range speed; it follows SIM_GUST_SPD (the highest force whose range starts at or below
//! the speed). At start every value reflects the plant's configured wind (the table's default otherwise),
//! SIM_GUST_ON = 1 only if a configured gust blows at that moment, SIM_TURB = 1 if any turbulence model is
//! on.
//!
//! The truth: the plant publishes its true state on the same port, so any client can judge a flight
//! against it (the estimate the autopilot reports is not the truth). To every live peer (one that spoke in
//! the last [`PEER_EXPIRY`]), at [`TRUTH_RATE_HZ`] = 50 Hz of plant time (after each plant step that
//! reaches a multiple of [`TRUTH_PERIOD_US`] = 20 ms; none while the plant waits for its autopilot), one
//! datagram of two messages in the peer's MAVLink version: SYSTEM_TIME (`time_boot_ms` = the plant time in
//! ms, which is the autopilot's `time_boot_ms` clock, so a client pairs the truth with the vehicle's
//! telemetry; `time_unix_usec` = 0, unknown) and then SIM_STATE (id 108) of the plant at that time:
//! `q1..q4` the attitude quaternion NED <- FRD (Hamilton, w x y z), `roll/pitch/yaw` its ZYX Euler angles
//! (rad), `xacc/yacc/zacc` the specific force in FRD (m/s², what an ideal accelerometer reads: -9.81 on
//! `zacc` at rest), `xgyro/ygyro/zgyro` the body rates FRD (rad/s), `lat/lon` (deg, f32, about 0.4 m
//! resolution) and the extension fields `lat_int/lon_int` (degE7, about 1 cm; MAVLink 2 only, 0 on a
//! MAVLink 1 link), `alt` (m AMSL), `vn/ve/vd` the velocity NED (m/s), and `std_dev_horz = std_dev_vert =
//! 0` (the truth, not an estimate). The position is the plant's local NED mapped to WGS-84 about the
//! plant's home (`[sensors.home]`) by the map its GPS uses, [`geodetic_from_ned`], so a fix and the
//! truth agree to the GPS noise. Samples taken between two polls go out at the next poll (every
//! 50 plant steps (the plant link's `HOOK_EVERY_STEPS`), or every 20 ms of wall time while the plant waits), in order.
//!
//! The pack: SIM_BAT_DRAIN (s, PX4's) > 0 drains it linearly from full to empty in that time while the
//! motors run (0: by the current the rotors draw, the default), SIM_BAT_MIN_PCT (%, PX4's; default 0
//! here, 50 in PX4) is the floor its state of charge never falls below; both act from the next step and
//! start at the plant's `[battery]` values.
//!
//! The radio: SIM_RC_FAIL = 1 silences the airframe's radio receiver ([`crate::plant::Radio`]): no
//! `RC_CHANNELS` goes to the autopilot from the next plant step until it is set back to 0, to rehearse
//! RC loss; the held frame (RC input port, schedule) is kept and comes back with it.
//!
//! The board's faults: SIM_GPS_FAIL, SIM_BARO_FAIL, SIM_MAG_FAIL, SIM_ACC_FAIL, SIM_GYRO_FAIL (a MAVLink
//! FAILURE_TYPE each), SIM_GPS_JUMP_N/E, SIM_BAT_FAIL, SIM_MOT_WRNG_EFF, SIM_LINK_DELAY and SIM_LINK_LOSS
//! (`sim_params/sensors.rs`, start values read from the plant). A MAV_CMD_INJECT_FAILURE the autopilot forwards on
//! the plant link is a set of these ([`failure_sets`], [`SimParamService::inject_failure`]); what it
//! changed goes to every live peer at the next poll (an INFO text and the PARAM_VALUEs).
//!
//! The airframe (`sim_params/airframe.rs`): SIM_MOT1_EFF..SIM_MOT4_EFF multiply rotor 1..4's lift (its
//! health, 1 healthy, 0 failed; ArduPilot's SIM_ENGINE_MUL), SIM_PAYLOAD_KG adds a point mass at
//! (SIM_CG_OFS_X, SIM_CG_OFS_Y) m FRD from the body origin ([`crate::plant::Payload`]: its weight's torque and
//! its inertia). All act from
//! the next plant step and start at the plant's airframe values. A scenario's `[[event]]` sets any of these
//! parameters at a plant time, through this same service ([`events`]).

mod airframe;
pub mod events;
mod inject;
mod port;
mod sensors;
mod truth;

pub use events::{EventSpec, SimEvent, SimEvents};
pub use inject::{Injection, Refusal, failure_sets, request_of};
pub use port::{HEARTBEAT_PERIOD, PEER_EXPIRY, SimParamLink, heartbeat};
pub use truth::{
    TRUTH_PERIOD_US, TRUTH_RATE_HZ, TruthPeriods, TruthStream, hil_state_quaternion, sim_state, truth_messages,
};

use autopilot::core::mavlink::failure::FailureRequest;
use autopilot::core::mavlink::params::{Applied, ParamService, encode_value, param_value};
use autopilot::core::mavlink::{statustext, statustext_chunks};
use autopilot::core::params::{ParamDef, ParamError, ParamKind, ParamStore};
use mavlink::dialects::common::{MavMessage, MavResult, MavSeverity, PARAM_SET_DATA};
use mavlink::types::CharArray;
use nalgebra::Vector3;

use crate::plant::wind::{BEAUFORT, GaussMarkovConfig, beaufort};
use crate::plant::{GustConfig, Plant, TurbulenceConfig, Wind};

/// Instance N's SIM_ parameter port is this + N (on 127.0.0.1; the instance port scheme is
/// `autopilot::runtime::ports`).
pub use autopilot::runtime::ports::SIM_PARAM_PORT_BASE;
/// MAVLink component id the plant sends with, on the plant link and on its SIM_ port
/// (`MAV_COMP_ID_USER1`..: any; PX4 ignores it for HIL).
pub const PLANT_COMPONENT_ID: u8 = 51;
/// Plant time of a gust that is installed but never blows (s): a gust must exist for the turbulence to
/// be scaled by it, and "no gust yet" is a gust whose onset is 30 years away.
const DORMANT_ONSET_S: f64 = 1e9;
/// Release time of a gust that holds until SIM_GUST_ON = 0 (s of plant time).
const HOLD_UNTIL_S: f64 = 2e9;

/// Index of each parameter in [`SIM_PARAMS`] (its `param_index`; never reused).
mod idx {
    pub const WIND_N: usize = 0;
    pub const WIND_E: usize = 1;
    pub const WIND_D: usize = 2;
    pub const GUST_SPD: usize = 3;
    pub const GUST_DIR: usize = 4;
    pub const GUST_RISE: usize = 5;
    pub const GUST_ON: usize = 6;
    pub const TURB: usize = 7;
    pub const BEAUFORT: usize = 8;
    pub const BAT_DRAIN: usize = 9;
    pub const BAT_MIN_PCT: usize = 10;
    pub const RC_FAIL: usize = 11;
    pub const GPS_FAIL: usize = 12;
    pub const BARO_FAIL: usize = 13;
    pub const MAG_FAIL: usize = 14;
    pub const ACC_FAIL: usize = 15;
    pub const GYRO_FAIL: usize = 16;
    pub const GPS_JUMP_N: usize = 17;
    pub const GPS_JUMP_E: usize = 18;
    pub const BAT_FAIL: usize = 19;
    pub const MOT_WRNG_EFF: usize = 20;
    pub const LINK_DELAY: usize = 21;
    pub const LINK_LOSS: usize = 22;
    pub const MOT1_EFF: usize = 23;
    pub const MOT4_EFF: usize = 26;
    pub const PAYLOAD_KG: usize = 27;
    pub const CG_OFS_X: usize = 28;
    pub const CG_OFS_Y: usize = 29;
}

/// A SIM_ parameter: the autopilot's parameter definition with no docs group and no config binding (the
/// service applies each set to the plant itself).
pub type SimParamDef = ParamDef<(), ()>;

/// A real-valued SIM_ parameter.
const fn real(
    name: &'static str,
    default: f32,
    min: f32,
    max: f32,
    unit: &'static str,
    description: &'static str,
) -> SimParamDef {
    SimParamDef {
        name,
        group: (),
        kind: ParamKind::Real,
        default,
        min,
        max,
        unit,
        restart: false,
        description,
        binding: (),
    }
}

/// A whole-numbered SIM_ parameter (0/1 for a switch): INT32 on the wire.
const fn whole(name: &'static str, default: f32, min: f32, max: f32, description: &'static str) -> SimParamDef {
    SimParamDef {
        name,
        group: (),
        kind: ParamKind::Integer,
        default,
        min,
        max,
        unit: "",
        restart: false,
        description,
        binding: (),
    }
}

/// The SIM_ parameters. The defaults are the values with no wind configured (the plant's configured wind
/// overrides them at start).
pub static SIM_PARAMS: [SimParamDef; 30] = [
    real("SIM_WIND_N", 0.0, -30.0, 30.0, "m/s", "Steady wind toward north (NED)"),
    real("SIM_WIND_E", 0.0, -30.0, 30.0, "m/s", "Steady wind toward east (NED)"),
    real("SIM_WIND_D", 0.0, -10.0, 10.0, "m/s", "Steady wind downward (NED)"),
    real("SIM_GUST_SPD", 6.7, 0.0, 30.0, "m/s", "Peak speed of the next gust (6.7 = Beaufort 4, the spec's gust)"),
    real("SIM_GUST_DIR", 90.0, 0.0, 360.0, "deg", "Direction the next gust blows toward (0 north, 90 east)"),
    real("SIM_GUST_RISE", 1.0, 0.1, 10.0, "s", "Rise and fall time of the next 1-cos gust"),
    whole("SIM_GUST_ON", 0.0, 0.0, 1.0, "1 starts a gust now with SIM_GUST_SPD/DIR/RISE; 0 releases it"),
    whole("SIM_TURB", 0.0, 0.0, 1.0, "1: the spec's Gauss-Markov turbulence, scaled by the gust profile"),
    whole(
        "SIM_BEAUFORT",
        4.0,
        0.0,
        8.0,
        "Beaufort force of SIM_GUST_SPD; setting it sets SIM_GUST_SPD to the force's mid speed",
    ),
    real(
        "SIM_BAT_DRAIN",
        0.0,
        0.0,
        86_400.0,
        "s",
        "> 0: the pack drains linearly from full to empty in this time while the motors run; 0: by the current drawn",
    ),
    real("SIM_BAT_MIN_PCT", 0.0, 0.0, 100.0, "%", "The pack's state of charge never falls below this"),
    whole(
        "SIM_RC_FAIL",
        0.0,
        0.0,
        1.0,
        "1: the radio receiver has no output (no RC_CHANNELS sent), to rehearse RC loss",
    ),
    whole("SIM_GPS_FAIL", 0.0, 0.0, 4.0, "GPS fault (MAVLink FAILURE_TYPE): 0 ok, 1 off, 2 stuck, 4 wrong (jumped)"),
    whole("SIM_BARO_FAIL", 0.0, 0.0, 2.0, "Barometer fault (MAVLink FAILURE_TYPE): 0 ok, 1 off, 2 stuck"),
    whole("SIM_MAG_FAIL", 0.0, 0.0, 2.0, "Magnetometer fault (MAVLink FAILURE_TYPE): 0 ok, 1 off, 2 stuck"),
    whole(
        "SIM_ACC_FAIL",
        0.0,
        0.0,
        3.0,
        "Accelerometer fault (MAVLink FAILURE_TYPE): 0 ok, 2 stuck, 3 garbage (±16 g)",
    ),
    whole("SIM_GYRO_FAIL", 0.0, 0.0, 3.0, "Gyro fault (MAVLink FAILURE_TYPE): 0 ok, 2 stuck, 3 garbage (±35 rad/s)"),
    real("SIM_GPS_JUMP_N", 50.0, -10_000.0, 10_000.0, "m", "North offset of the fix while SIM_GPS_FAIL = 4 (wrong)"),
    real("SIM_GPS_JUMP_E", 0.0, -10_000.0, 10_000.0, "m", "East offset of the fix while SIM_GPS_FAIL = 4 (wrong)"),
    whole("SIM_BAT_FAIL", 0.0, 0.0, 1.0, "1: the battery monitor reports the pack empty (0 %, empty voltage), as PX4"),
    real(
        "SIM_MOT_WRNG_EFF",
        0.7,
        0.0,
        1.0,
        "",
        "Thrust a motor keeps after an injected motor WRONG failure (fraction of nominal)",
    ),
    whole("SIM_LINK_DELAY", 0.0, 0.0, 1000.0, "Added delay of the plant's sensor datagrams to the autopilot (ms)"),
    real(
        "SIM_LINK_LOSS",
        0.0,
        0.0,
        90.0,
        "%",
        "Chance that a sensor datagram to the autopilot is lost (the plant steps on with the last actuators)",
    ),
    real("SIM_MOT1_EFF", 1.0, 0.0, 1.0, "", "Rotor 1 (right) thrust multiplier: 1 healthy, 0 failed (SIM_ENGINE_MUL)"),
    real("SIM_MOT2_EFF", 1.0, 0.0, 1.0, "", "Rotor 2 (rear) thrust multiplier: 1 healthy, 0 failed"),
    real("SIM_MOT3_EFF", 1.0, 0.0, 1.0, "", "Rotor 3 (front) thrust multiplier: 1 healthy, 0 failed"),
    real("SIM_MOT4_EFF", 1.0, 0.0, 1.0, "", "Rotor 4 (left) thrust multiplier: 1 healthy, 0 failed"),
    real("SIM_PAYLOAD_KG", 0.0, 0.0, 10.0, "kg", "Payload: a point mass added to the airframe at SIM_CG_OFS_X/Y"),
    real("SIM_CG_OFS_X", 0.0, -0.5, 0.5, "m", "Where the payload sits, forward of the body origin (FRD x)"),
    real("SIM_CG_OFS_Y", 0.0, -0.5, 0.5, "m", "Where the payload sits, right of the body origin (FRD y)"),
];

/// Whether a set of `name` to `value` can be taken by any plant, without one at hand (a scenario file's
/// set is checked when it loads): the table's range and kind, and a failure type the sensor has. What only
/// a given plant can refuse (a battery fault without a pack) is not checked here.
///
/// # Errors
/// The refusal as the SIM_ port words it (`unknown parameter X`, `X: 5 not in 0..4`, `SIM_ACC_FAIL: only
/// 0 ok, 2 stuck, 3 garbage`).
pub fn check_set(name: &str, value: f32) -> Result<(), String> {
    let Some(index) = SIM_PARAMS.iter().position(|d| d.name == name) else {
        return Err(ParamError::Unknown { name: name.to_owned() }.to_string());
    };
    let d = &SIM_PARAMS[index];
    d.check(value).map_err(|e| e.to_string())?;
    sensors::check(index, value).map_err(|reason| ParamError::Refused { name: d.name, reason }.to_string())
}

/// The Beaufort force of a wind speed (m/s): the highest force whose range starts at or below it.
#[must_use]
pub fn beaufort_force_of(speed_mps: f64) -> u8 {
    BEAUFORT.iter().rev().find(|b| b.min_mps <= speed_mps).map_or(0, |b| b.force)
}

/// The unit vector (NED) of a direction toward `deg` (0 north, 90 east), horizontal.
#[must_use]
pub fn direction_ned(deg: f64) -> Vector3<f64> {
    let rad = deg.to_radians();
    Vector3::new(rad.cos(), rad.sin(), 0.0)
}

/// The SIM_ parameters' state: their values (as carried on the wire, f32) in the autopilot's
/// [`ParamStore`], the PARAM protocol in the autopilot's [`ParamService`] (for component
/// [`PLANT_COMPONENT_ID`]), and the system id.
#[derive(Debug, Clone, PartialEq)]
pub struct SimParamService {
    system_id: u8,
    store: ParamStore<(), ()>,
    protocol: ParamService,
    /// What sets made through [`SimParamService::set_now`] have to tell every peer (their PARAM_VALUE echoes
    /// and notes), sent by the SIM_ port at its next poll.
    outbox: Vec<MavMessage>,
}

impl SimParamService {
    /// The service of system `system_id`, its values read from the plant's wind as configured: the steady
    /// wind, the configured gust's amplitude, direction and rise (else the table's defaults), whether that
    /// gust blows at the current plant time, and whether a turbulence model is on. They are taken as they
    /// are, even outside the table's ranges (a configured wind is the plant's, not a ground station's).
    #[must_use]
    pub fn new(system_id: u8, plant: &Plant) -> Self {
        let wind = plant.wind();
        let mut values: [f32; SIM_PARAMS.len()] = std::array::from_fn(|i| SIM_PARAMS[i].default);
        let steady = wind.steady_ned_mps();
        for (i, v) in [idx::WIND_N, idx::WIND_E, idx::WIND_D].into_iter().zip(steady.iter()) {
            values[i] = *v as f32;
        }
        if let Some(g) = wind.gust() {
            values[idx::GUST_SPD] = g.amplitude_mps as f32;
            values[idx::GUST_DIR] = g.direction_ned.y.atan2(g.direction_ned.x).to_degrees().rem_euclid(360.0) as f32;
            values[idx::GUST_RISE] = g.rise_s as f32;
            values[idx::GUST_ON] = f32::from(u8::from(g.scale(plant.time_us() as f64 * 1e-6) > 0.0));
        }
        values[idx::TURB] = f32::from(u8::from(wind.has_turbulence()));
        values[idx::BEAUFORT] = f32::from(beaufort_force_of(f64::from(values[idx::GUST_SPD])));
        let battery = plant.config().battery;
        values[idx::BAT_DRAIN] = battery.drain_s as f32;
        values[idx::BAT_MIN_PCT] = (battery.min_remaining * 100.0) as f32;
        values[idx::RC_FAIL] = f32::from(u8::from(plant.radio().failed()));
        sensors::initial_values(plant, &mut values);
        airframe::initial_values(plant, &mut values);
        Self {
            system_id,
            store: ParamStore::from_fn(&SIM_PARAMS, |i, _| values[i]),
            protocol: ParamService::for_component(PLANT_COMPONENT_ID),
            outbox: Vec::new(),
        }
    }

    /// Set parameter `index` to `value` now, as a PARAM_SET received on the port would (the same check,
    /// apply and store; a scenario's `[[event]]`); its replies wait in the outbox for the port's peers.
    ///
    /// # Errors
    /// The refusal a ground station would read (nothing changed), or an index past the table.
    pub fn set_now(&mut self, index: usize, value: f32, plant: &mut Plant) -> Result<(), String> {
        let d = SIM_PARAMS.get(index).ok_or_else(|| format!("no SIM_ parameter at index {index}"))?;
        let msg = MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: encode_value(d.kind, value),
            target_system: 0,
            target_component: 0,
            param_id: CharArray::from(d.name),
            param_type: d.kind.mav_param_type(),
        });
        let replies = self.on_message(&msg, plant);
        if let Some(MavMessage::STATUSTEXT(t)) = replies.first()
            && t.severity == MavSeverity::MAV_SEVERITY_WARNING
        {
            let text: &[u8; 50] = &t.text;
            let len = text.iter().position(|&b| b == 0).unwrap_or(text.len());
            return Err(String::from_utf8_lossy(&text[..len]).into_owned());
        }
        self.outbox.extend(replies);
        Ok(())
    }

    /// The replies of [`SimParamService::set_now`] not yet sent, oldest first.
    pub fn take_outbox(&mut self) -> Vec<MavMessage> {
        std::mem::take(&mut self.outbox)
    }

    /// The system id the service answers for.
    #[must_use]
    pub fn system_id(&self) -> u8 {
        self.system_id
    }

    /// Answer for system `system_id` from now on (the SIM_ port's, when one is attached to the plant link).
    pub fn set_system_id(&mut self, system_id: u8) {
        self.system_id = system_id;
    }

    /// Queue `messages` for every peer of the SIM_ port, sent at its next poll (what a forwarded failure
    /// injection changed).
    pub fn tell_peers(&mut self, messages: &[MavMessage]) {
        self.outbox.extend_from_slice(messages);
    }

    /// The current value of parameter `index`.
    #[must_use]
    pub fn value(&self, index: usize) -> Option<f32> {
        self.store.get_index(index)
    }

    /// The current value of parameter `name`.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<f32> {
        self.store.get(name)
    }

    /// Set parameter `name` to `value` as a ground station's PARAM_SET does (the table's check, then the
    /// plant's), acting from the plant's next step: the messages for the port's clients (a note, then the
    /// PARAM_VALUE of it and of any parameter that follows it).
    ///
    /// # Errors
    /// The refusal as the port words it (`unknown parameter X`, `X: 5 not in 0..4`, `X: the plant refused
    /// it: ...`); nothing changed then.
    pub fn set(&mut self, name: &str, value: f32, plant: &mut Plant) -> Result<Vec<MavMessage>, String> {
        let index =
            self.store.index_of(name).ok_or_else(|| ParamError::Unknown { name: name.to_owned() }.to_string())?;
        let d = &SIM_PARAMS[index];
        d.check(value).map_err(|e| e.to_string())?;
        let applied = apply(&mut self.store, index, value, plant)
            .map_err(|reason| ParamError::Refused { name: d.name, reason }.to_string())?;
        self.store.set_index(index, value).map_err(|e| e.to_string())?;
        let mut out: Vec<MavMessage> =
            applied.note.map(|text| statustext(MavSeverity::MAV_SEVERITY_INFO, &text)).into_iter().collect();
        out.extend(std::iter::once(index).chain(applied.also_changed).filter_map(|i| param_value(&self.store, i)));
        Ok(out)
    }

    /// Answer the MAV_CMD_INJECT_FAILURE the autopilot forwarded with `params` (its param1..param3):
    /// DENIED when one is not a whole number >= 0 ([`request_of`]), else [`SimParamService::inject_failure`].
    pub fn inject_forwarded(&mut self, params: [f32; 3], plant: &mut Plant) -> Injection {
        match request_of(params) {
            Ok(request) => self.inject_failure(&request, plant),
            Err(r) => refused(r),
        }
    }

    /// Answer a failure injection ([`failure_sets`]): apply its sets in order through
    /// [`SimParamService::set`], all or none (a set the plant refuses undoes the ones before it and
    /// answers DENIED).
    pub fn inject_failure(&mut self, request: &FailureRequest, plant: &mut Plant) -> Injection {
        let sets = match failure_sets(request, |name| self.get(name)) {
            Ok(sets) => sets,
            Err(r) => return refused(r),
        };
        let mut done: Vec<(&str, f32)> = Vec::new();
        let mut messages = Vec::new();
        for (name, value) in &sets {
            let old = self.get(name).unwrap_or(*value);
            match self.set(name, *value, plant) {
                Ok(echo) => {
                    messages.extend(echo);
                    done.push((name, old));
                }
                Err(reason) => {
                    for (name, old) in done.into_iter().rev() {
                        // Back to a value the plant had: accepted as it was before.
                        let _ = self.set(name, old, plant);
                    }
                    return refused(Refusal { result: MavResult::MAV_RESULT_DENIED, reason });
                }
            }
        }
        let list: Vec<String> = sets.iter().map(|(name, value)| format!("{name} = {value}")).collect();
        let text = format!("failure injected: {}", list.join(", "));
        let mut out = statustext_chunks(MavSeverity::MAV_SEVERITY_INFO, &text, 1);
        out.extend(messages);
        Injection { result: MavResult::MAV_RESULT_ACCEPTED, text, messages: out }
    }

    /// The replies to one received message (in order); applies a set to `plant`'s wind at once, so it
    /// acts from the plant's next step. A list request is answered whole (the autopilot's stream, drained
    /// at once: every value). A message not addressed to us, or not a PARAM request, gets nothing.
    pub fn on_message(&mut self, msg: &MavMessage, plant: &mut Plant) -> Vec<MavMessage> {
        let reply = self
            .protocol
            .on_message_with(self.system_id, msg, &mut self.store, |store, i, v| apply(store, i, v, plant));
        let mut out = reply.messages;
        while self.protocol.list_in_progress() {
            out.extend(self.protocol.due(&self.store));
        }
        out
    }
}

/// An injection that changed nothing: the ACK's result and the warning saying why.
fn refused(r: Refusal) -> Injection {
    let text = format!("failure injection refused: {}", r.reason);
    let messages = statustext_chunks(MavSeverity::MAV_SEVERITY_WARNING, &text, 1);
    Injection { result: r.result, text, messages }
}

/// The value of SIM_ parameter `index` in `store` (the table's default if the index were not in it).
fn value_of(store: &ParamStore<(), ()>, index: usize) -> f32 {
    store.get_index(index).unwrap_or(SIM_PARAMS[index].default)
}

/// Apply a set of parameter `index` to `value` (range-checked already, not yet stored) to the plant's
/// wind, and to the parameter that follows it (SIM_BEAUFORT from SIM_GUST_SPD and back). Returns the
/// followers to echo and a note for the ground station (a gust started or released); a refusal is the
/// wind's own, with nothing changed.
fn apply(store: &mut ParamStore<(), ()>, index: usize, value: f32, plant: &mut Plant) -> Result<Applied, String> {
    let refused = |e: crate::plant::PlantError| format!("the plant refused it: {e}");
    let now_s = plant.time_us() as f64 * 1e-6;
    let mut applied = Applied::default();
    match index {
        idx::WIND_N | idx::WIND_E | idx::WIND_D => {
            let mut steady = plant.wind().steady_ned_mps();
            steady[index - idx::WIND_N] = f64::from(value);
            plant.wind_mut().set_steady_ned_mps(steady);
        }
        idx::GUST_SPD => {
            let force = f32::from(beaufort_force_of(f64::from(value)));
            if force != value_of(store, idx::BEAUFORT) {
                store.set_index(idx::BEAUFORT, force).map_err(|e| e.to_string())?;
                applied.also_changed.push(idx::BEAUFORT);
            }
        }
        idx::BEAUFORT => {
            let speed = beaufort(value as u8).map_err(refused)?.mid_mps() as f32;
            store.set_index(idx::GUST_SPD, speed).map_err(|e| e.to_string())?;
            applied.also_changed.push(idx::GUST_SPD);
        }
        idx::GUST_ON if value != value_of(store, idx::GUST_ON) => {
            applied.note = Some(if value == 1.0 {
                let gust = held_gust(store, now_s);
                plant.wind_mut().set_gust(Some(&gust)).map_err(refused)?;
                format!(
                    "gust {:.1} m/s to {:.0} deg, rise {:.1} s, t={now_s:.2}",
                    value_of(store, idx::GUST_SPD),
                    value_of(store, idx::GUST_DIR),
                    value_of(store, idx::GUST_RISE)
                )
            } else {
                let release_s = release(plant.wind_mut(), now_s).map_err(refused)?;
                format!("gust released, t={release_s:.2}")
            });
        }
        idx::BAT_DRAIN => plant.battery_mut().set_drain_s(f64::from(value)),
        idx::BAT_MIN_PCT => plant.battery_mut().set_min_remaining(f64::from(value) / 100.0),
        idx::RC_FAIL => plant.radio_mut().set_failed(value == 1.0),
        i if sensors::owns(i) => sensors::apply(i, value, plant)?,
        idx::MOT1_EFF..=idx::CG_OFS_Y => applied = airframe::apply(index, value, plant),
        idx::TURB if value != value_of(store, idx::TURB) => {
            if value == 1.0 {
                if plant.wind().gust().is_none() {
                    let dormant = GustConfig { onset_s: DORMANT_ONSET_S, ..held_gust(store, now_s) };
                    plant.wind_mut().set_gust(Some(&dormant)).map_err(refused)?;
                }
                let spec = GaussMarkovConfig { scale_with_gust: true, ..GaussMarkovConfig::default() };
                plant.wind_mut().set_turbulence(Some(&TurbulenceConfig::GaussMarkov(spec))).map_err(refused)?;
            } else {
                plant.wind_mut().set_turbulence(None).map_err(refused)?;
            }
        }
        _ => {}
    }
    Ok(applied)
}

/// A gust from the current SIM_GUST_SPD/DIR/RISE, rising from `onset_s` and held until released.
fn held_gust(store: &ParamStore<(), ()>, onset_s: f64) -> GustConfig {
    let rise_s = f64::from(value_of(store, idx::GUST_RISE));
    let dir = direction_ned(f64::from(value_of(store, idx::GUST_DIR)));
    GustConfig {
        amplitude_mps: Some(f64::from(value_of(store, idx::GUST_SPD))),
        direction_ned: [dir.x, dir.y, dir.z],
        onset_s,
        rise_s,
        release_s: HOLD_UNTIL_S.max(onset_s + rise_s),
        fall_s: rise_s,
    }
}

/// Release the wind's gust at `now_s`: one still rising falls from the end of its rise, one not yet begun
/// never begins, one already falling is left alone. Returns the release time.
fn release(wind: &mut Wind, now_s: f64) -> Result<f64, crate::plant::PlantError> {
    let Some(g) = wind.gust().copied() else { return Ok(now_s) };
    let d = g.direction_ned;
    let mut config = GustConfig {
        amplitude_mps: Some(g.amplitude_mps),
        direction_ned: [d.x, d.y, d.z],
        onset_s: g.onset_s,
        rise_s: g.rise_s,
        release_s: g.release_s,
        fall_s: g.fall_s,
    };
    if now_s < g.onset_s {
        config.onset_s = DORMANT_ONSET_S.max(g.onset_s);
        config.release_s = HOLD_UNTIL_S.max(config.onset_s + g.rise_s);
    } else if now_s < g.release_s {
        config.release_s = now_s.max(g.onset_s + g.rise_s);
    } else {
        return Ok(g.release_s);
    }
    wind.set_gust(Some(&config))?;
    Ok(config.release_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::sensors::{HomeConfig, geodetic_from_ned};
    use crate::plant::{InitialState, PlantConfig, WindConfig};
    use autopilot::core::mavlink::params::{decode_value, param_name};
    use autopilot::core::params::ParamError;
    use mavlink::dialects::common::SIM_STATE_DATA;
    use mavlink::dialects::common::{MavParamType, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA};
    use mavlink::types::CharArray;
    use mavlink::{MavHeader, MavlinkVersion};
    use std::net::UdpSocket;
    use std::time::Duration;

    use autopilot::core::plant_link::{FrameDecoder, encode_frame_v1, encode_frame_v2};

    fn index_of(name: &str) -> Option<usize> {
        SIM_PARAMS.iter().position(|d| d.name == name)
    }

    const SYS: u8 = 3;
    /// `param_count` of every PARAM_VALUE: the table's length.
    const COUNT: u16 = SIM_PARAMS.len() as u16;

    fn plant_with(wind: WindConfig) -> Plant {
        Plant::new(PlantConfig { wind, ..PlantConfig::default() }, &InitialState::default(), 1).expect("plant")
    }

    fn calm_plant() -> Plant {
        plant_with(WindConfig::default())
    }

    fn set_msg(name: &str, value: f32) -> MavMessage {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: SYS,
            target_component: PLANT_COMPONENT_ID,
            param_id: CharArray::from(name),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })
    }

    fn set_int32(name: &str, value: i32) -> MavMessage {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: f32::from_bits(value as u32),
            target_system: SYS,
            target_component: PLANT_COMPONENT_ID,
            param_id: CharArray::from(name),
            param_type: MavParamType::MAV_PARAM_TYPE_INT32,
        })
    }

    /// `(name, value, index, count)` of every PARAM_VALUE, the value decoded by its `param_type`, which
    /// must be the parameter's.
    fn values(replies: &[MavMessage]) -> Vec<(String, f32, u16, u16)> {
        replies
            .iter()
            .filter_map(|m| match m {
                MavMessage::PARAM_VALUE(v) => {
                    let name = param_name(&v.param_id);
                    let d = &SIM_PARAMS[index_of(&name).expect("a SIM_ parameter")];
                    assert_eq!(v.param_type, d.kind.mav_param_type(), "{name}");
                    let value = decode_value(v.param_type, v.param_value).expect("decodes");
                    Some((name, value, v.param_index, v.param_count))
                }
                _ => None,
            })
            .collect()
    }

    fn texts(replies: &[MavMessage]) -> Vec<String> {
        replies
            .iter()
            .filter_map(|m| match m {
                MavMessage::STATUSTEXT(t) => {
                    let bytes: &[u8; 50] = &t.text;
                    let len = bytes.iter().position(|&b| b == 0).unwrap_or(50);
                    Some(String::from_utf8_lossy(&bytes[..len]).into_owned())
                }
                _ => None,
            })
            .collect()
    }

    /// Step the plant on the ground (motors off) until plant time `t_s`.
    fn step_to(plant: &mut Plant, t_s: f64) {
        while (plant.time_us() as f64) < t_s * 1e6 - 1.0 {
            plant.step([1000.0; 4], 2000);
        }
    }

    #[test]
    fn given_the_table_then_names_fit_mavlink_defaults_are_in_range_and_indices_are_stable() {
        for (i, d) in SIM_PARAMS.iter().enumerate() {
            assert!(d.name.len() <= 16 && d.name.starts_with("SIM_"), "{}", d.name);
            assert!(d.min <= d.default && d.default <= d.max, "{}", d.name);
            assert!(d.check(d.default).is_ok(), "{}", d.name);
            if d.kind != ParamKind::Real {
                // As the autopilot's table: within ±2^23, so a float sent as INT32 is out of range.
                assert!(-8_388_608.0 <= d.min && d.max < 8_388_608.0, "{}", d.name);
            }
            assert!(!d.description.is_empty());
            assert_eq!(index_of(d.name), Some(i));
        }
        let names: Vec<_> = SIM_PARAMS.iter().map(|d| d.name).collect();
        assert_eq!(
            names,
            [
                "SIM_WIND_N",
                "SIM_WIND_E",
                "SIM_WIND_D",
                "SIM_GUST_SPD",
                "SIM_GUST_DIR",
                "SIM_GUST_RISE",
                "SIM_GUST_ON",
                "SIM_TURB",
                "SIM_BEAUFORT",
                "SIM_BAT_DRAIN",
                "SIM_BAT_MIN_PCT",
                "SIM_RC_FAIL",
                "SIM_GPS_FAIL",
                "SIM_BARO_FAIL",
                "SIM_MAG_FAIL",
                "SIM_ACC_FAIL",
                "SIM_GYRO_FAIL",
                "SIM_GPS_JUMP_N",
                "SIM_GPS_JUMP_E",
                "SIM_BAT_FAIL",
                "SIM_MOT_WRNG_EFF",
                "SIM_LINK_DELAY",
                "SIM_LINK_LOSS",
                "SIM_MOT1_EFF",
                "SIM_MOT2_EFF",
                "SIM_MOT3_EFF",
                "SIM_MOT4_EFF",
                "SIM_PAYLOAD_KG",
                "SIM_CG_OFS_X",
                "SIM_CG_OFS_Y",
            ]
        );
        let spd = &SIM_PARAMS[idx::GUST_SPD];
        assert!(matches!(spd.check(30.5), Err(ParamError::OutOfRange { .. })));
        assert!(matches!(spd.check(f32::NAN), Err(ParamError::NotFinite { .. })));
        assert!(matches!(SIM_PARAMS[idx::GUST_ON].check(0.5), Err(ParamError::NotWhole { .. })));
        assert_eq!(beaufort_force_of(6.7), 4);
        assert_eq!(beaufort_force_of(0.0), 0);
        assert_eq!(beaufort_force_of(5.45), 3);
        assert_eq!(beaufort_force_of(30.0), 8);
        assert!((direction_ned(90.0) - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn given_sim_rc_fail_set_then_the_receiver_has_no_output_until_it_is_cleared() {
        let mut plant = calm_plant();
        let frame = autopilot::core::manual::RcFrame::of(&[1500; 8]);
        plant.radio_mut().set_port_frame(frame);
        let mut s = SimParamService::new(SYS, &plant);
        assert_eq!(s.get("SIM_RC_FAIL"), Some(0.0));
        assert_eq!(
            values(&s.on_message(&set_msg("SIM_RC_FAIL", 1.0), &mut plant)),
            [("SIM_RC_FAIL".into(), 1.0, 11, COUNT)]
        );
        assert!(plant.radio().failed());
        assert_eq!(plant.radio().output(plant.time_us()), None);
        let refused = s.on_message(&set_msg("SIM_RC_FAIL", 2.0), &mut plant);
        assert_eq!(values(&refused), [("SIM_RC_FAIL".into(), 1.0, 11, COUNT)], "refused: the value echoed unchanged");
        assert!(plant.radio().failed());
        s.on_message(&set_msg("SIM_RC_FAIL", 0.0), &mut plant);
        assert_eq!(plant.radio().output(plant.time_us()), Some(frame), "the held frame comes back");
    }

    #[test]
    fn given_a_configured_wind_when_the_service_starts_then_its_values_reflect_it() {
        let calm = SimParamService::new(SYS, &calm_plant());
        assert_eq!(calm.get("SIM_GUST_SPD"), Some(6.7));
        assert_eq!(calm.get("SIM_GUST_DIR"), Some(90.0));
        assert_eq!(calm.get("SIM_GUST_ON"), Some(0.0));
        assert_eq!(calm.get("SIM_BEAUFORT"), Some(4.0));
        let windy: WindConfig = toml::from_str(
            "steady_ned_mps = [1.0, -2.0, 0.5]\n[gust]\namplitude_mps = 3.0\ndirection_ned = [1.0, 0.0, 0.0]\n\
             rise_s = 2.0\nonset_s = 0.0\n[turbulence]\nmodel = \"dryden\"\n",
        )
        .expect("toml");
        let s = SimParamService::new(SYS, &plant_with(windy));
        let got: Vec<f32> = (0..SIM_PARAMS.len()).map(|i| s.value(i).expect("value")).collect();
        assert_eq!(
            got,
            [
                1.0, -2.0, 0.5, 3.0, 0.0, 2.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, // wind, pack, radio
                0.0, 0.0, 0.0, 0.0, 0.0, 50.0, 0.0, 0.0, 0.7, 0.0,
                0.0, // no faults, the default jump and weak motor
                1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 // four healthy rotors, no payload
            ]
        );
    }

    #[test]
    fn given_a_list_request_then_every_parameter_is_answered_in_its_type_with_count_and_index() {
        let mut plant = calm_plant();
        let mut s = SimParamService::new(SYS, &plant);
        let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: 0, target_component: 0 });
        let replies = s.on_message(&list, &mut plant);
        let got = values(&replies);
        assert_eq!(got.len(), SIM_PARAMS.len());
        for (i, (name, _, index, count)) in got.iter().enumerate() {
            assert_eq!((name.as_str(), *index as usize, *count as usize), (SIM_PARAMS[i].name, i, SIM_PARAMS.len()));
        }
        // The reals are REAL32; the switches and the Beaufort force are INT32 with their bytes as they are.
        let types: Vec<_> = replies
            .iter()
            .filter_map(|m| match m {
                MavMessage::PARAM_VALUE(v) => Some((v.param_type, v.param_value.to_bits())),
                _ => None,
            })
            .collect();
        let (real, int) = (MavParamType::MAV_PARAM_TYPE_REAL32, MavParamType::MAV_PARAM_TYPE_INT32);
        let gust_spd = 6.7_f32.to_bits();
        assert_eq!(
            types[idx::GUST_SPD..=idx::LINK_LOSS],
            [
                (real, gust_spd),
                (real, 90.0_f32.to_bits()),
                (real, 1.0_f32.to_bits()),
                (int, 0),
                (int, 0),
                (int, 4),
                (real, 0.0_f32.to_bits()),
                (real, 0.0_f32.to_bits()),
                (int, 0),
                // The faults: five sensors' FAILURE_TYPE, the jump, the pack, the weak motor, the link.
                (int, 0),
                (int, 0),
                (int, 0),
                (int, 0),
                (int, 0),
                (real, 50.0_f32.to_bits()),
                (real, 0.0_f32.to_bits()),
                (int, 0),
                (real, 0.7_f32.to_bits()),
                (int, 0),
                (real, 0.0_f32.to_bits())
            ]
        );
        // The airframe's are REAL32: four healthy rotors, no payload.
        let one = (real, 1.0_f32.to_bits());
        let zero = (real, 0.0_f32.to_bits());
        assert_eq!(types[idx::MOT1_EFF..], [one, one, one, one, zero, zero, zero]);
        // Another system's request, or one for the autopilot's component, is not ours.
        let theirs = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: 1, target_component: 0 });
        assert!(s.on_message(&theirs, &mut plant).is_empty());
        let autopilot =
            MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system: SYS, target_component: 1 });
        assert!(s.on_message(&autopilot, &mut plant).is_empty());
        // A client's heartbeat gets nothing.
        assert!(s.on_message(&heartbeat(), &mut plant).is_empty());
    }

    #[test]
    fn given_read_requests_then_they_are_answered_by_name_and_by_index_and_unknown_names_get_the_reason() {
        let mut plant = calm_plant();
        let mut s = SimParamService::new(SYS, &plant);
        let read = |index: i16, name: &str| {
            MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: index,
                target_system: SYS,
                target_component: 0,
                param_id: CharArray::from(name),
            })
        };
        assert_eq!(
            values(&s.on_message(&read(-1, "SIM_GUST_RISE"), &mut plant)),
            [("SIM_GUST_RISE".into(), 1.0, 5, COUNT)]
        );
        assert_eq!(values(&s.on_message(&read(8, ""), &mut plant)), [("SIM_BEAUFORT".into(), 4.0, 8, COUNT)]);
        assert!(s.on_message(&read(COUNT as i16, ""), &mut plant).is_empty(), "past the table");
        let unknown = s.on_message(&read(-1, "SIM_NOPE"), &mut plant);
        assert!(values(&unknown).is_empty());
        assert_eq!(texts(&unknown), ["unknown parameter SIM_NOPE"], "the reason, not silence");
    }

    #[test]
    fn given_sets_then_good_values_are_echoed_and_bad_ones_refused_with_the_value_unchanged() {
        let mut plant = calm_plant();
        let mut s = SimParamService::new(SYS, &plant);
        let replies = s.on_message(&set_msg("SIM_WIND_N", 2.5), &mut plant);
        assert_eq!(values(&replies), [("SIM_WIND_N".into(), 2.5, 0, COUNT)]);
        assert_eq!(plant.wind().steady_ned_mps(), Vector3::new(2.5, 0.0, 0.0));

        // The autopilot's refusal texts, word for word.
        for (name, bad, text) in [
            ("SIM_GUST_SPD", 31.0, "SIM_GUST_SPD: 31 not in 0..30"),
            ("SIM_GUST_SPD", f32::NAN, "SIM_GUST_SPD: NaN is not finite"),
            ("SIM_GUST_ON", 0.5, "SIM_GUST_ON: 0.5 is not a whole number"),
            ("SIM_WIND_E", -40.0, "SIM_WIND_E: -40 not in -30..30"),
        ] {
            let before = s.get(name).expect("known");
            let replies = s.on_message(&set_msg(name, bad), &mut plant);
            assert_eq!(texts(&replies), [text], "{name} = {bad}: {replies:?}");
            assert_eq!(values(&replies), [(name.to_owned(), before, index_of(name).unwrap() as u16, COUNT)]);
            assert_eq!(s.get(name), Some(before));
        }
        assert_eq!(plant.wind().steady_ned_mps(), Vector3::new(2.5, 0.0, 0.0));
        let unknown = s.on_message(&set_msg("SIM_NOPE", 1.0), &mut plant);
        assert!(values(&unknown).is_empty());
        assert_eq!(texts(&unknown), ["unknown parameter SIM_NOPE"]);

        // Beaufort sets the gust speed, and the gust speed moves the Beaufort force.
        let replies = s.on_message(&set_msg("SIM_BEAUFORT", 6.0), &mut plant);
        assert_eq!(values(&replies), [("SIM_BEAUFORT".into(), 6.0, 8, COUNT), ("SIM_GUST_SPD".into(), 12.3, 3, COUNT)]);
        // As a PX4 script sets an integer: INT32, bytewise; echoed so.
        let replies = s.on_message(&set_int32("SIM_BEAUFORT", 5), &mut plant);
        assert_eq!(values(&replies), [("SIM_BEAUFORT".into(), 5.0, 8, COUNT), ("SIM_GUST_SPD".into(), 9.35, 3, COUNT)]);
        let MavMessage::PARAM_VALUE(echo) = &replies[0] else { panic!("{replies:?}") };
        assert_eq!((echo.param_type, echo.param_value.to_bits()), (MavParamType::MAV_PARAM_TYPE_INT32, 5));
        // A float where the int32's bytes belong is out of range, and an int32 for a real is refused.
        let replies = s.on_message(&set_int32("SIM_BEAUFORT", 6.0_f32.to_bits() as i32), &mut plant);
        assert_eq!(texts(&replies), ["SIM_BEAUFORT: 1.0863247e9 not in 0..8"]);
        let replies = s.on_message(&set_int32("SIM_GUST_SPD", 7), &mut plant);
        assert_eq!(texts(&replies), ["SIM_GUST_SPD: sent as INT32, it is REAL32"]);
        assert_eq!((s.get("SIM_BEAUFORT"), s.get("SIM_GUST_SPD")), (Some(5.0), Some(9.35)));
        let replies = s.on_message(&set_msg("SIM_GUST_SPD", 6.7), &mut plant);
        assert_eq!(values(&replies), [("SIM_GUST_SPD".into(), 6.7, 3, COUNT), ("SIM_BEAUFORT".into(), 4.0, 8, COUNT)]);
    }

    #[test]
    fn given_gust_on_then_off_then_the_gust_rises_holds_and_falls_at_those_plant_times() {
        let mut plant = calm_plant();
        let mut s = SimParamService::new(SYS, &plant);
        step_to(&mut plant, 2.0);
        for (name, v) in [("SIM_GUST_SPD", 6.7), ("SIM_GUST_DIR", 90.0), ("SIM_GUST_RISE", 1.0)] {
            assert_eq!(values(&s.on_message(&set_msg(name, v), &mut plant)).len(), 1);
        }
        assert_eq!(plant.truth().wind_ned_mps, Vector3::zeros());
        let on = s.on_message(&set_msg("SIM_GUST_ON", 1.0), &mut plant);
        assert_eq!(values(&on), [("SIM_GUST_ON".into(), 1.0, 6, COUNT)]);
        assert!(texts(&on)[0].contains("t=2.00"), "{:?}", texts(&on));
        // The wind is evaluated at the start of each step: the step from t = 2.0 holds s(2.0) = 0.
        plant.step([1000.0; 4], 2000);
        assert_eq!(plant.truth().wind_ned_mps, Vector3::zeros());
        let amplitude = f64::from(6.7_f32);
        step_to(&mut plant, 2.5);
        plant.step([1000.0; 4], 2000); // holds s(2.5) = 0.5
        let half = plant.truth().wind_ned_mps;
        assert!((half - Vector3::new(0.0, 0.5 * amplitude, 0.0)).norm() < 1e-6, "{half:?}");
        step_to(&mut plant, 9.998);
        plant.step([1000.0; 4], 2000); // holds s(9.998) = 1, ends at t = 10.0
        let full = plant.truth().wind_ned_mps;
        assert!((full - Vector3::new(0.0, amplitude, 0.0)).norm() < 1e-6, "toward east: {full:?}");

        let off = s.on_message(&set_msg("SIM_GUST_ON", 0.0), &mut plant);
        assert!(texts(&off)[0].contains("t=10.00"), "{:?}", texts(&off));
        step_to(&mut plant, 10.5);
        plant.step([1000.0; 4], 2000);
        assert!((plant.truth().wind_ned_mps.y - 0.5 * amplitude).abs() < 1e-6);
        step_to(&mut plant, 11.0);
        plant.step([1000.0; 4], 2000);
        assert!(plant.truth().wind_ned_mps.norm() < 1e-9);

        // A second gust toward north-west, released while still rising: it falls from the end of the rise.
        s.on_message(&set_msg("SIM_GUST_DIR", 315.0), &mut plant);
        s.on_message(&set_msg("SIM_GUST_SPD", 4.0), &mut plant);
        step_to(&mut plant, 20.0);
        s.on_message(&set_msg("SIM_GUST_ON", 1.0), &mut plant);
        step_to(&mut plant, 20.2);
        let off = s.on_message(&set_msg("SIM_GUST_ON", 0.0), &mut plant);
        assert!(texts(&off)[0].contains("t=21.00"), "{:?}", texts(&off));
        let g = plant.wind().gust().copied().expect("gust");
        let dir = g.direction_ned;
        assert!((dir - Vector3::new(0.5_f64.sqrt(), -(0.5_f64.sqrt()), 0.0)).norm() < 1e-6, "{dir:?}");
        assert!((g.velocity_ned_mps(21.0).norm() - 4.0).abs() < 1e-6);
        assert!(g.velocity_ned_mps(22.0).norm() < 1e-9);
    }

    #[test]
    fn given_turbulence_on_then_it_blows_only_with_the_gust_and_off_removes_it() {
        let mut plant = calm_plant();
        let mut s = SimParamService::new(SYS, &plant);
        assert_eq!(values(&s.on_message(&set_msg("SIM_TURB", 1.0), &mut plant)), [("SIM_TURB".into(), 1.0, 7, COUNT)]);
        assert!(plant.wind().has_turbulence());
        step_to(&mut plant, 1.0);
        assert_eq!(plant.truth().wind_ned_mps, Vector3::zeros(), "no gust, no turbulence");
        s.on_message(&set_msg("SIM_GUST_ON", 1.0), &mut plant);
        let mut max_north = 0.0_f64;
        while plant.time_us() < 5_000_000 {
            plant.step([1000.0; 4], 2000);
            max_north = max_north.max(plant.truth().wind_ned_mps.x.abs());
        }
        assert!(max_north > 0.1, "turbulence across the gust: {max_north}");
        s.on_message(&set_msg("SIM_TURB", 0.0), &mut plant);
        assert!(!plant.wind().has_turbulence());
        plant.step([1000.0; 4], 2000);
        plant.step([1000.0; 4], 2000);
        assert!(plant.truth().wind_ned_mps.x.abs() < 1e-12);
    }

    /// A plant in the air away from home, moving, tilted and turning (motors running).
    pub(super) fn flying_plant() -> Plant {
        let start = InitialState {
            pos_ned_m: Vector3::new(120.5, -80.25, -30.0),
            vel_ned_mps: Vector3::new(1.5, -0.7, 0.3),
            euler_rad: Vector3::new(0.1, -0.05, 1.2),
            rate_frd_radps: Vector3::new(0.2, -0.1, 0.3),
            ..InitialState::default()
        };
        let mut plant = Plant::new(PlantConfig::default(), &start, 1).expect("plant");
        plant.set_motors_running(true);
        plant
    }

    /// `(time_boot_ms, SIM_STATE)` of each truth sample, checking each is SYSTEM_TIME then SIM_STATE.
    fn samples(taken: &[[MavMessage; 2]]) -> Vec<(u32, SIM_STATE_DATA)> {
        taken
            .iter()
            .map(|pair| match pair {
                [MavMessage::SYSTEM_TIME(t), MavMessage::SIM_STATE(s)] => (t.time_boot_ms, s.clone()),
                other => panic!("not SYSTEM_TIME then SIM_STATE: {other:?}"),
            })
            .collect()
    }

    /// The position of a SIM_STATE in the plant's NED, through the inverse of the GPS map.
    fn sim_state_ned_m(s: &SIM_STATE_DATA, home: &HomeConfig) -> Vector3<f64> {
        let geo = crate::plant::sensors::Geodetic {
            lat_deg: f64::from(s.lat_int) * 1e-7,
            lon_deg: f64::from(s.lon_int) * 1e-7,
            alt_amsl_m: f64::from(s.alt),
        };
        crate::plant::sensors::ned_from_geodetic(home, &geo)
    }

    #[test]
    fn given_a_flying_plant_then_sim_state_is_its_truth_to_f32_and_its_position_to_a_centimetre_in_the_gps_map() {
        let mut plant = flying_plant();
        for _ in 0..250 {
            plant.step([1600.0, 1550.0, 1500.0, 1450.0], 2000);
        }
        let truth = plant.truth();
        let home = plant.config().sensors.home;
        let s = sim_state(&truth, &home);
        let close = |got: f32, want: f64, what: &str| {
            assert!((f64::from(got) - want).abs() <= 1e-6 * want.abs().max(1.0), "{what}: {got} vs {want}");
        };
        let q = truth.q_ned_frd.quaternion();
        for (got, want, what) in [
            (s.q1, q.w, "q1 = w"),
            (s.q2, q.i, "q2 = x"),
            (s.q3, q.j, "q3 = y"),
            (s.q4, q.k, "q4 = z"),
            (s.roll, truth.euler_rad.x, "roll"),
            (s.pitch, truth.euler_rad.y, "pitch"),
            (s.yaw, truth.euler_rad.z, "yaw"),
            (s.xacc, truth.specific_force_frd_mps2.x, "xacc"),
            (s.yacc, truth.specific_force_frd_mps2.y, "yacc"),
            (s.zacc, truth.specific_force_frd_mps2.z, "zacc"),
            (s.xgyro, truth.rate_frd_radps.x, "xgyro"),
            (s.ygyro, truth.rate_frd_radps.y, "ygyro"),
            (s.zgyro, truth.rate_frd_radps.z, "zgyro"),
            (s.vn, truth.vel_ned_mps.x, "vn"),
            (s.ve, truth.vel_ned_mps.y, "ve"),
            (s.vd, truth.vel_ned_mps.z, "vd"),
        ] {
            close(got, want, what);
        }
        // Something moved, so the comparison above is not of zeros.
        assert!(truth.rate_frd_radps.norm() > 0.05 && truth.vel_ned_mps.norm() > 0.5, "{truth:?}");
        // The position is the GPS model's map of the truth: the f32 degrees as it gives them, the degE7
        // to 1e-7 deg, and back through its inverse within a centimetre.
        let geo = geodetic_from_ned(&home, &truth.pos_ned_m);
        assert_eq!((s.lat, s.lon, s.alt), (geo.lat_deg as f32, geo.lon_deg as f32, geo.alt_amsl_m as f32));
        assert!((f64::from(s.lat_int) * 1e-7 - geo.lat_deg).abs() <= 0.5e-7);
        assert!((f64::from(s.lon_int) * 1e-7 - geo.lon_deg).abs() <= 0.5e-7);
        let back = sim_state_ned_m(&s, &home);
        assert!((back - truth.pos_ned_m).norm() < 0.01, "{back} vs {}", truth.pos_ned_m);
        assert!((f64::from(s.alt) - (home.alt_amsl_m - truth.pos_ned_m.z)).abs() < 1e-4, "alt AMSL");
        assert_eq!((s.std_dev_horz, s.std_dev_vert), (0.0, 0.0), "the truth, exact");
        // At rest on the ground an ideal accelerometer reads -g on z.
        let rest = sim_state(&calm_plant().truth(), &home);
        assert!((rest.zacc + 9.81).abs() < 0.01 && rest.xacc.abs() < 1e-6, "{rest:?}");
    }

    #[test]
    fn given_plant_steps_then_the_truth_is_sampled_every_20_ms_of_plant_time_and_only_for_listeners() {
        // GIVEN the stream of a plant at t = 0 stepping at 2 ms (500 Hz).
        let mut plant = flying_plant();
        let home = plant.config().sensors.home;
        let mut stream = TruthStream::new(plant.time_us());
        let mut truths = Vec::new();
        // WHEN it steps 2 s of plant time with a listener.
        while plant.time_us() < 2_000_000 {
            plant.step([1550.0; 4], 2000);
            stream.stepped(&plant, true);
            truths.push(plant.truth());
        }
        // THEN there is one sample per 20 ms at t = 20, 40, ... 2000 ms, each the truth at that time.
        let got = samples(&stream.take());
        assert_eq!(got.len(), 100);
        for (k, (t_ms, s)) in got.iter().enumerate() {
            let want_ms = 20 * (k as u32 + 1);
            assert_eq!(*t_ms, want_ms);
            let truth = truths.iter().find(|t| t.time_us == u64::from(want_ms) * 1000).expect("a step there");
            assert_eq!(*s, sim_state(truth, &home));
        }
        assert!(stream.take().is_empty(), "handed over once");

        // AND with a 3 ms step it samples at the first step of each 20 ms period (21, 42, 60, 81, ...).
        let mut plant = flying_plant();
        let mut stream = TruthStream::new(plant.time_us());
        while plant.time_us() < 120_000 {
            plant.step([1550.0; 4], 3000);
            stream.stepped(&plant, true);
        }
        let times: Vec<u32> = samples(&stream.take()).iter().map(|(t, _)| *t).collect();
        assert_eq!(times, [21, 42, 60, 81, 102, 120]);

        // AND nobody listening: nothing is built.
        let mut stream = TruthStream::new(plant.time_us());
        for _ in 0..50 {
            plant.step([1550.0; 4], 2000);
            stream.stepped(&plant, false);
        }
        assert!(stream.take().is_empty());
    }

    #[test]
    fn given_peers_of_both_versions_then_each_gets_the_truth_at_50_hz_in_its_version_and_v1_lacks_lat_int() {
        // GIVEN the service with a MAVLink 2 and a MAVLink 1 client that said HEARTBEAT.
        let mut plant = flying_plant();
        let home = plant.config().sensors.home;
        let mut service = SimParamService::new(SYS, &plant);
        let mut link = SimParamLink::bind("127.0.0.1:0", SYS, &plant).expect("bind");
        let addr = link.local_addr().expect("addr");
        let gcs = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let v2 = UdpSocket::bind("127.0.0.1:0").expect("client");
        let v1 = UdpSocket::bind("127.0.0.1:0").expect("client");
        v2.send_to(&encode_frame_v2(gcs, &heartbeat()), addr).expect("send");
        v1.send_to(&encode_frame_v1(gcs, &heartbeat()).expect("v1"), addr).expect("send");
        std::thread::sleep(Duration::from_millis(50));
        link.poll(&mut service, &mut plant).expect("poll");
        // WHEN the plant steps 0.2 s (100 steps at 2 ms) as the plant server steps it, polled every 50.
        let mut truths = Vec::new();
        for step in 1..=100 {
            plant.step([1550.0; 4], 2000);
            link.stepped(&plant);
            truths.push(plant.truth());
            if step % 50 == 0 {
                link.poll(&mut service, &mut plant).expect("poll");
            }
        }
        // THEN each client has 10 datagrams of SYSTEM_TIME then SIM_STATE at t = 20..200 ms, in its
        // version, from (SYS, 51); the MAVLink 1 one without the degE7 extension fields.
        for (client, version) in [(&v2, MavlinkVersion::V2), (&v1, MavlinkVersion::V1)] {
            client.set_read_timeout(Some(Duration::from_millis(500))).expect("timeout");
            let mut decoder = FrameDecoder::new();
            let mut buf = [0u8; 2048];
            let mut got = Vec::new();
            while got.len() < 10 {
                let (n, _) = client.recv_from(&mut buf).expect("a datagram");
                let frames = decoder.decode_datagram(&buf[..n]);
                if matches!(frames[0].message, MavMessage::HEARTBEAT(_)) {
                    continue;
                }
                assert!(frames.iter().all(|f| f.version == version
                    && f.header.system_id == u32::from(SYS)
                    && f.header.component_id == PLANT_COMPONENT_ID));
                let pair: [MavMessage; 2] = [frames[0].message.clone(), frames[1].message.clone()];
                assert_eq!(frames.len(), 2, "one sample per datagram");
                got.extend(samples(&[pair]));
            }
            let times: Vec<u32> = got.iter().map(|(t, _)| *t).collect();
            assert_eq!(times, (1..=10).map(|k| 20 * k).collect::<Vec<u32>>());
            for (t_ms, s) in &got {
                let truth = truths.iter().find(|t| t.time_us == u64::from(*t_ms) * 1000).expect("a step");
                let want = sim_state(truth, &home);
                match version {
                    MavlinkVersion::V2 => assert_eq!(*s, want),
                    MavlinkVersion::V1 => {
                        assert_eq!(*s, SIM_STATE_DATA { lat_int: 0, lon_int: 0, ..want });
                    }
                }
            }
        }
    }

    #[test]
    fn given_a_socket_client_then_replies_go_to_it_and_heartbeats_follow_in_its_version() {
        let mut plant = calm_plant();
        let mut service = SimParamService::new(SYS, &plant);
        let mut link = SimParamLink::bind("127.0.0.1:0", SYS, &plant).expect("bind");
        let addr = link.local_addr().expect("addr");
        let client = UdpSocket::bind("127.0.0.1:0").expect("client");
        client.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        let gcs = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        client.send_to(&encode_frame_v2(gcs, &set_msg("SIM_GUST_SPD", 5.0)), addr).expect("send");
        std::thread::sleep(Duration::from_millis(50));
        link.poll(&mut service, &mut plant).expect("poll");
        let mut decoder = FrameDecoder::new();
        let mut buf = [0u8; 2048];
        let mut got = Vec::new();
        while got.len() < 3 {
            let (n, _) = client.recv_from(&mut buf).expect("reply");
            got.extend(decoder.decode_datagram(&buf[..n]));
        }
        assert!(
            got.iter().all(|f| f.header.system_id == u32::from(SYS) && f.header.component_id == PLANT_COMPONENT_ID)
        );
        assert!(got.iter().any(|f| matches!(f.message, MavMessage::HEARTBEAT(_))), "a heartbeat: {got:?}");
        let echoed: Vec<_> = got.iter().map(|f| f.message.clone()).collect();
        assert_eq!(
            values(&echoed)[..2],
            [("SIM_GUST_SPD".into(), 5.0, 3, COUNT), ("SIM_BEAUFORT".into(), 3.0, 8, COUNT)]
        );
        assert_eq!(service.get("SIM_GUST_SPD"), Some(5.0));
        // No more heartbeats before a second has passed.
        link.poll(&mut service, &mut plant).expect("poll");
        client.set_read_timeout(Some(Duration::from_millis(100))).expect("timeout");
        assert!(client.recv_from(&mut buf).is_err());

        // A MAVLink 1 client is answered in MAVLink 1.
        let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: 0,
            target_system: SYS,
            target_component: PLANT_COMPONENT_ID,
            param_id: CharArray::from(""),
        });
        client.send_to(&encode_frame_v1(gcs, &read).expect("v1"), addr).expect("send");
        std::thread::sleep(Duration::from_millis(50));
        link.poll(&mut service, &mut plant).expect("poll");
        client.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
        let (n, _) = client.recv_from(&mut buf).expect("reply");
        let frames = decoder.decode_datagram(&buf[..n]);
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].version, MavlinkVersion::V1);
        assert_eq!(values(&[frames[0].message.clone()]), [("SIM_WIND_N".into(), 0.0, 0, COUNT)]);
    }
}

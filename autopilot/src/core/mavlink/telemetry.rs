//! Telemetry streams on vehicle time. In, once per vehicle step: `now_us` (µs, the plant's sensor clock)
//! and a [`TelemetrySnapshot`] (the estimate with its origin, the last GPS fix, home, the commander's
//! output, the motor commands). Out: the messages whose interval has elapsed, at the default rates
//! ([`Stream::default_interval_us`]): SYS_STATUS 1 Hz, ATTITUDE 20 Hz, ATTITUDE_QUATERNION 10 Hz (as
//! PX4's normal mode), LOCAL_POSITION_NED 10 Hz, GLOBAL_POSITION_INT 10 Hz (once an origin exists),
//! GPS_RAW_INT 5 Hz (once a fix arrived), EXTENDED_SYS_STATE 1 Hz, HOME_POSITION 0.5 Hz (once home is
//! set), VFR_HUD 4 Hz, BATTERY_STATUS 1 Hz, MISSION_CURRENT 1 Hz (once a mission is loaded), RC_CHANNELS
//! 5 Hz (PX4's normal-link rate, once a radio frame has arrived; QGroundControl's radio page reads it), and
//! the controller's adaptive weights and mass estimate as DEBUG_VECTs ([`WEIGHT_VECTORS`]; 2 Hz by default,
//! the ACO_WEIGHTS_HZ parameter). A stream due without its data is skipped, not queued. Every rate can
//! be changed per message id (SET_MESSAGE_INTERVAL).
//!
//! Units on the wire: angles rad (ATTITUDE) or cdeg, positions degE7 and mm, speeds cm/s. The battery is
//! the pack's latest reading (from the plant or the ARM board, see `core::battery`): SYS_STATUS voltage
//! (mV), current (cA) and remaining (%), BATTERY_STATUS in full with the warning level as
//! `charge_state`; without a reading in the last 5 s, MAVLink's "unknown" values (voltage UINT16_MAX,
//! current -1, remaining -1, temperature INT16_MAX, consumption -1).
//!
//! The plant link (the ARM board's serial line, or UDP to the SITL plant) in SYS_STATUS: `drop_rate_comm`
//! is its samples missing over the last second (`core::plant_link::health`), in MAVLink's centi-percent; the
//! ground-station links have no such count (a lost ground-station datagram is not seen). `errors_comm`
//! counts malformed frames on every link, the plant's and the ground stations' ([`LinkErrors`]).
//!
//! STATUSTEXT and the texts of events are `text`'s (re-exported here).

use ::mavlink::dialects::common::{
    ATTITUDE_DATA, ATTITUDE_QUATERNION_DATA, BATTERY_STATUS_DATA, DEBUG_VECT_DATA, EXTENDED_SYS_STATE_DATA,
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, MavBatteryChargeState, MavBatteryFunction, MavBatteryType, MavMessage, MavSysStatusSensor,
    MavVtolState, RC_CHANNELS_DATA, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use nalgebra::Vector3;

use super::units::{deg_to_dege7, m_to_mm, mps_to_cmps_i16, rad_to_cdeg_0_360, to_centi_u16};
use super::{identity, next_due_us};
use crate::core::battery::{BatteryStatus, BatteryWarning};
use crate::core::commander::{CommanderOutput, LandedState};
use crate::core::control::Controller;
use crate::core::estimator::{EstimatorFlags, EstimatorState, GpsSample};
use crate::core::manual::ManualStatus;
use crate::core::plant_link::health::DROP_RATE_FULL_CPCT;
use crate::core::plant_link::{encode_battery_status, encode_rc_channels};

mod text;
pub use text::{
    estimator_event_message, event_severity, nav_event_message, plant_link_event_message, statustext, statustext_chunks,
};

/// Home: where the vehicle armed (m, NED about the estimator's origin) and, with an origin, geodetic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Home {
    pub pos_ned_m: Vector3<f64>,
    /// (lat deg, lon deg, alt m AMSL), when the estimator has an origin.
    pub geodetic: Option<(f64, f64, f64)>,
}

/// What the streams report, at one vehicle step.
#[derive(Clone, Copy)]
pub struct TelemetrySnapshot<'a> {
    pub now_us: u64,
    pub estimate: &'a EstimatorState,
    pub gps: Option<&'a GpsSample>,
    pub home: Option<&'a Home>,
    pub commander: &'a CommanderOutput,
    /// The motor commands of this step (µs).
    pub pwm_us: [f64; 4],
    /// What the links have dropped so far (SYS_STATUS errors_comm and errors_count1).
    pub link_errors: LinkErrors,
    /// The plant link's samples missing over the last second, centi-percent (SYS_STATUS drop_rate_comm).
    pub plant_drop_rate_cpct: u16,
    /// The mission item being flown towards, when a mission is loaded (MISSION_CURRENT).
    pub mission_seq: Option<u16>,
    /// The controller, for the adaptive-weight stream.
    pub controller: Option<&'a dyn Controller>,
    /// The pilot's input: the sticks in use and the last radio frame (RC_CHANNELS, MANUAL_CONTROL).
    pub manual: ManualStatus,
}

impl std::fmt::Debug for TelemetrySnapshot<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TelemetrySnapshot").field("now_us", &self.now_us).finish_non_exhaustive()
    }
}

/// The periodic streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stream {
    SysStatus,
    Attitude,
    AttitudeQuaternion,
    LocalPositionNed,
    GlobalPositionInt,
    GpsRawInt,
    ExtendedSysState,
    HomePosition,
    VfrHud,
    BatteryStatus,
    MissionCurrent,
    /// The controller's adaptive weights and mass estimate, as DEBUG_VECTs ([`WEIGHT_VECTORS`]).
    AdaptiveWeights,
    /// The radio's last frame ([`rc_channels`]).
    RcChannels,
}

impl Stream {
    pub const ALL: [Self; 13] = [
        Self::SysStatus,
        Self::Attitude,
        Self::AttitudeQuaternion,
        Self::LocalPositionNed,
        Self::GlobalPositionInt,
        Self::GpsRawInt,
        Self::ExtendedSysState,
        Self::HomePosition,
        Self::VfrHud,
        Self::BatteryStatus,
        Self::MissionCurrent,
        Self::AdaptiveWeights,
        Self::RcChannels,
    ];

    /// The MAVLink message id.
    #[must_use]
    pub const fn message_id(self) -> u32 {
        match self {
            Self::SysStatus => 1,
            Self::Attitude => 30,
            Self::AttitudeQuaternion => 31,
            Self::LocalPositionNed => 32,
            Self::GlobalPositionInt => 33,
            Self::GpsRawInt => 24,
            Self::ExtendedSysState => 245,
            Self::HomePosition => 242,
            Self::VfrHud => 74,
            Self::BatteryStatus => 147,
            Self::MissionCurrent => 42,
            Self::AdaptiveWeights => 250,
            Self::RcChannels => 65,
        }
    }

    /// The default interval (µs of vehicle time).
    #[must_use]
    pub const fn default_interval_us(self) -> u64 {
        match self {
            Self::SysStatus | Self::ExtendedSysState | Self::BatteryStatus | Self::MissionCurrent => 1_000_000,
            Self::AdaptiveWeights => 500_000,
            Self::Attitude => 50_000,
            Self::AttitudeQuaternion | Self::LocalPositionNed | Self::GlobalPositionInt => 100_000,
            Self::GpsRawInt => 200_000,
            Self::HomePosition => 2_000_000,
            Self::VfrHud => 250_000,
            Self::RcChannels => 200_000,
        }
    }

    /// The stream of a MAVLink message id.
    #[must_use]
    pub fn of_message(message_id: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.message_id() == message_id)
    }

    /// The messages of one emission for `snap` (several DEBUG_VECTs for the weights, one for the
    /// others; none when the data does not exist yet).
    #[must_use]
    pub fn messages(self, snap: &TelemetrySnapshot<'_>) -> Vec<MavMessage> {
        match self {
            Self::AdaptiveWeights => snap.controller.map(|c| adaptive_weights(snap.now_us, c)).unwrap_or_default(),
            _ => self.message(snap).into_iter().collect(),
        }
    }

    /// The message for `snap`, or `None` when its data does not exist yet (no origin, no fix, no home, no
    /// mission); the first weight for [`Stream::AdaptiveWeights`].
    #[must_use]
    pub fn message(self, snap: &TelemetrySnapshot<'_>) -> Option<MavMessage> {
        match self {
            Self::SysStatus => Some(sys_status(
                &snap.estimate.flags,
                &snap.commander.battery,
                snap.link_errors,
                snap.plant_drop_rate_cpct,
                &snap.manual,
            )),
            Self::Attitude => Some(attitude(snap)),
            Self::AttitudeQuaternion => Some(attitude_quaternion(snap)),
            Self::LocalPositionNed => Some(local_position_ned(snap)),
            Self::GlobalPositionInt => global_position_int(snap),
            Self::GpsRawInt => snap.gps.map(gps_raw_int),
            Self::ExtendedSysState => Some(extended_sys_state(snap.commander.landed)),
            Self::HomePosition => snap.home.and_then(home_position),
            Self::VfrHud => Some(vfr_hud(snap)),
            Self::BatteryStatus => Some(battery_status(&snap.commander.battery)),
            Self::MissionCurrent => snap.mission_seq.map(mission_current),
            Self::AdaptiveWeights => snap.controller.and_then(|c| adaptive_weights(snap.now_us, c).into_iter().next()),
            Self::RcChannels => rc_channels(snap.now_us, &snap.manual),
        }
    }
}

/// The weight stream's vectors: per controller, a DEBUG_VECT name (at most 10 characters) and the three
/// [`Controller::telemetry`] values it carries as x, y, z. ACO (Eq 11-14): the translation LMS weights
/// `w_t` and biases `b_t` (m/s²) and the mass estimate `m_est` (kg) per NED axis, the attitude LMS
/// weights `c_r` and biases `d_r` (rad/s²) per body axis. The common adaptive controller: each MRAC
/// parameter (k1, k2, kr, theta) over roll, pitch, yaw (`.rpy`) and over N, E, D (`.ned`). PID: the
/// velocity (m/s²) and rate (N·m) integrators.
pub const WEIGHT_VECTORS: [(&str, [&str; 3]); 15] = [
    ("aco.w_t", ["aco.w_t_n", "aco.w_t_e", "aco.w_t_d"]),
    ("aco.b_t", ["aco.b_t_n_mps2", "aco.b_t_e_mps2", "aco.b_t_d_mps2"]),
    ("aco.c_r", ["aco.c_r_x", "aco.c_r_y", "aco.c_r_z"]),
    ("aco.d_r", ["aco.d_r_x_radps2", "aco.d_r_y_radps2", "aco.d_r_z_radps2"]),
    ("aco.m_est", ["aco.mass_est_n_kg", "aco.mass_est_e_kg", "aco.mass_est_d_kg"]),
    ("ca.k1.rpy", ["ca.roll.k1", "ca.pitch.k1", "ca.yaw.k1"]),
    ("ca.k2.rpy", ["ca.roll.k2", "ca.pitch.k2", "ca.yaw.k2"]),
    ("ca.kr.rpy", ["ca.roll.kr", "ca.pitch.kr", "ca.yaw.kr"]),
    ("ca.th.rpy", ["ca.roll.theta", "ca.pitch.theta", "ca.yaw.theta"]),
    ("ca.k1.ned", ["ca.n.k1", "ca.e.k1", "ca.d.k1"]),
    ("ca.k2.ned", ["ca.n.k2", "ca.e.k2", "ca.d.k2"]),
    ("ca.kr.ned", ["ca.n.kr", "ca.e.kr", "ca.d.kr"]),
    ("ca.th.ned", ["ca.n.theta", "ca.e.theta", "ca.d.theta"]),
    ("pid.vel_i", ["pid.vel_int_n_mps2", "pid.vel_int_e_mps2", "pid.vel_int_d_mps2"]),
    ("pid.rate_i", ["pid.rate_int_x_nm", "pid.rate_int_y_nm", "pid.rate_int_z_nm"]),
];

/// MISSION_CURRENT for the item `seq` the mission flies towards: the one builder (the stream, a
/// MISSION_SET_CURRENT's answer and the navigator's moves all send this).
#[must_use]
pub fn mission_current(seq: u16) -> MavMessage {
    MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA { seq, ..Default::default() })
}

/// One DEBUG_VECT per [`WEIGHT_VECTORS`] entry whose three values `controller` reports: 5 for ACO,
/// 8 for the common adaptive controller, 2 for PID (three values to a message rather than one
/// NAMED_VALUE_FLOAT each, as every message costs each ground-station target a datagram).
#[must_use]
pub fn adaptive_weights(now_us: u64, controller: &dyn Controller) -> Vec<MavMessage> {
    let values = controller.telemetry();
    let value = |name: &str| values.iter().find(|(n, _)| *n == name).map(|&(_, v)| v as f32);
    WEIGHT_VECTORS
        .iter()
        .filter_map(|(vector, [x, y, z])| {
            Some(MavMessage::DEBUG_VECT(DEBUG_VECT_DATA {
                time_usec: now_us,
                x: value(x)?,
                y: value(y)?,
                z: value(z)?,
                name: (*vector).into(),
            }))
        })
        .collect()
}

/// Per-stream intervals and due times on vehicle time. A stream is first sent at the first step, then
/// every interval without drift (restarting if the steps fell behind by more than one interval).
#[derive(Debug, Clone, PartialEq)]
pub struct StreamScheduler {
    /// Per stream of [`Stream::ALL`]: interval (µs; 0 = off) and next due time.
    interval_us: [u64; Stream::ALL.len()],
    due_us: [Option<u64>; Stream::ALL.len()],
}

impl Default for StreamScheduler {
    fn default() -> Self {
        Self { interval_us: Stream::ALL.map(Stream::default_interval_us), due_us: [None; Stream::ALL.len()] }
    }
}

impl StreamScheduler {
    fn index(stream: Stream) -> usize {
        Stream::ALL.iter().position(|s| *s == stream).unwrap_or(0)
    }

    /// Sets a stream's interval (µs; 0 turns it off); it restarts at the next step.
    pub fn set_interval_us(&mut self, stream: Stream, interval_us: u64) {
        let i = Self::index(stream);
        self.interval_us[i] = interval_us;
        self.due_us[i] = None;
    }

    #[must_use]
    pub fn interval_us(&self, stream: Stream) -> u64 {
        self.interval_us[Self::index(stream)]
    }

    /// The streams due at `now_us`, in [`Stream::ALL`] order; their next due times advance.
    pub fn due(&mut self, now_us: u64) -> Vec<Stream> {
        let mut out = Vec::new();
        for (i, stream) in Stream::ALL.into_iter().enumerate() {
            let interval = self.interval_us[i];
            if interval == 0 || self.due_us[i].is_some_and(|due| now_us < due) {
                continue;
            }
            self.due_us[i] = Some(next_due_us(self.due_us[i], now_us, interval, false));
            out.push(stream);
        }
        out
    }
}

/// Milliseconds since boot (the plant's clock starts at 0), wrapping as MAVLink's u32 does.
fn time_boot_ms(now_us: u64) -> u32 {
    (now_us / 1000) as u32
}

fn sensors(bits: &[(bool, MavSysStatusSensor)]) -> MavSysStatusSensor {
    bits.iter().filter(|(on, _)| *on).fold(MavSysStatusSensor::empty(), |acc, (_, b)| acc | *b)
}

/// RC_CHANNELS as PX4 streams it, from the radio's last frame (None before the first): channels beyond
/// the frame's count as UINT16_MAX, `chancount` the frame's; `rssi` the frame's while the radio is fresh,
/// 0 once it is lost (PX4 reports 0 without channels).
#[must_use]
pub fn rc_channels(now_us: u64, manual: &ManualStatus) -> Option<MavMessage> {
    let frame = manual.rc?;
    let mut m: RC_CHANNELS_DATA = encode_rc_channels(&frame, time_boot_ms(now_us));
    let count = usize::from(m.chancount);
    for (i, channel) in [
        &mut m.chan1_raw,
        &mut m.chan2_raw,
        &mut m.chan3_raw,
        &mut m.chan4_raw,
        &mut m.chan5_raw,
        &mut m.chan6_raw,
        &mut m.chan7_raw,
        &mut m.chan8_raw,
        &mut m.chan9_raw,
        &mut m.chan10_raw,
        &mut m.chan11_raw,
        &mut m.chan12_raw,
        &mut m.chan13_raw,
        &mut m.chan14_raw,
        &mut m.chan15_raw,
        &mut m.chan16_raw,
        &mut m.chan17_raw,
        &mut m.chan18_raw,
    ]
    .into_iter()
    .enumerate()
    {
        if i >= count {
            *channel = u16::MAX;
        }
    }
    if count == 0 || !manual.rc_fresh {
        m.rssi = 0;
    }
    Some(MavMessage::RC_CHANNELS(m))
}

/// SYS_STATUS: gyro, accel, mag, baro, GPS and PREARM_CHECK present and enabled; healthy from the estimator
/// flags (IMU: attitude valid and the IMU not faulted; mag, baro, GPS: fused within their timeouts and not
/// faulted, so a lost, stuck or rejected source clears its bit; PREARM_CHECK: converged, i.e. armable). The battery present while it
/// reports, healthy above its critical level; its voltage, current and remaining. The RC receiver present
/// and enabled once a radio frame has arrived, healthy while the radio is fresh (`manual.rc_fresh`).
/// `errors_comm` and `errors_count1`: see [`LinkErrors`]. `drop_rate_comm`: `plant_drop_rate_cpct`, the
/// plant link's samples missing over the last second (centi-percent, 0..=10000; see the module docs).
#[must_use]
pub fn sys_status(
    flags: &EstimatorFlags,
    battery: &BatteryStatus,
    errors: LinkErrors,
    plant_drop_rate_cpct: u16,
    manual: &ManualStatus,
) -> MavMessage {
    use MavSysStatusSensor as S;
    let all = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
        | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
        | S::MAV_SYS_STATUS_SENSOR_3D_MAG
        | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
        | S::MAV_SYS_STATUS_SENSOR_GPS
        | S::MAV_SYS_STATUS_PREARM_CHECK
        | if battery.sample.is_some() { S::MAV_SYS_STATUS_SENSOR_BATTERY } else { S::empty() }
        | if manual.rc.is_some() { S::MAV_SYS_STATUS_SENSOR_RC_RECEIVER } else { S::empty() };
    let health = sensors(&[
        // No geofence exists, so none is breached: healthy, neither present nor enabled (MAVProxy reads
        // a clear health bit as a breach).
        (true, S::MAV_SYS_STATUS_GEOFENCE),
        (flags.attitude_valid && flags.health.imu.is_none(), S::MAV_SYS_STATUS_SENSOR_3D_GYRO),
        (flags.attitude_valid && flags.health.imu.is_none(), S::MAV_SYS_STATUS_SENSOR_3D_ACCEL),
        (flags.mag_ok, S::MAV_SYS_STATUS_SENSOR_3D_MAG),
        (flags.baro_ok, S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE),
        (flags.gps_ok, S::MAV_SYS_STATUS_SENSOR_GPS),
        (flags.converged, S::MAV_SYS_STATUS_PREARM_CHECK),
        (battery.level < BatteryWarning::Critical, S::MAV_SYS_STATUS_SENSOR_BATTERY),
        (manual.rc.is_some() && manual.rc_fresh, S::MAV_SYS_STATUS_SENSOR_RC_RECEIVER),
    ]);
    let sample = battery.sample;
    MavMessage::SYS_STATUS(SYS_STATUS_DATA {
        onboard_control_sensors_present: all,
        onboard_control_sensors_enabled: all,
        onboard_control_sensors_health: health,
        load: 0,
        voltage_battery: sample.map_or(u16::MAX, |b| (b.voltage_v * 1e3).round().clamp(0.0, 65_534.0) as u16),
        current_battery: sample
            .and_then(|b| b.current_a)
            .map_or(-1, |a| (a * 100.0).round().clamp(0.0, f64::from(i16::MAX)) as i16),
        battery_remaining: battery.remaining_pct().map_or(-1, |p| p as i8),
        drop_rate_comm: plant_drop_rate_cpct.min(DROP_RATE_FULL_CPCT),
        errors_comm: u16::try_from(errors.malformed).unwrap_or(u16::MAX),
        errors_count1: u16::try_from(errors.signing_rejected).unwrap_or(u16::MAX),
        ..SYS_STATUS_DATA::default()
    })
}

/// SYS_STATUS while the plant link is lost (no sensor sample arrives): the sensors stay present and
/// enabled but none is healthy (gyro, accel, mag, baro, GPS, and PREARM_CHECK: nothing could be checked),
/// and the battery and the radio, read over the same link, are not reported (MAVLink's unknown values for
/// the battery, as with no reading). The error counts as in [`sys_status`]; `drop_rate_comm` 10000 (100 %):
/// no sample has arrived for the last second.
#[must_use]
pub fn sys_status_plant_lost(errors: LinkErrors) -> MavMessage {
    let (flags, battery, manual) = (EstimatorFlags::default(), BatteryStatus::default(), ManualStatus::default());
    sys_status(&flags, &battery, errors, DROP_RATE_FULL_CPCT, &manual)
}

/// What the shell's links have dropped so far, as SYS_STATUS reports it (each saturating at 65535).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkErrors {
    /// Malformed frames on every link, the plant's and the ground stations': `errors_comm`.
    pub malformed: u64,
    /// Valid frames the ground-station links dropped for MAVLink signing (unsigned, another key,
    /// replayed or stale): `errors_count1`, the first autopilot-specific count.
    pub signing_rejected: u64,
}

fn attitude(snap: &TelemetrySnapshot<'_>) -> MavMessage {
    let (e, w) = (snap.estimate.euler_rad, snap.estimate.rate_frd_radps);
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: time_boot_ms(snap.now_us),
        roll: e.x as f32,
        pitch: e.y as f32,
        yaw: e.z as f32,
        rollspeed: w.x as f32,
        pitchspeed: w.y as f32,
        yawspeed: w.z as f32,
    })
}

fn attitude_quaternion(snap: &TelemetrySnapshot<'_>) -> MavMessage {
    let q = snap.estimate.q_ned_frd;
    let w = snap.estimate.rate_frd_radps;
    MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
        time_boot_ms: time_boot_ms(snap.now_us),
        q1: q.w as f32,
        q2: q.i as f32,
        q3: q.j as f32,
        q4: q.k as f32,
        rollspeed: w.x as f32,
        pitchspeed: w.y as f32,
        yawspeed: w.z as f32,
        ..Default::default()
    })
}

fn local_position_ned(snap: &TelemetrySnapshot<'_>) -> MavMessage {
    let (p, v) = (snap.estimate.pos_ned_m, snap.estimate.vel_ned_mps);
    MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
        time_boot_ms: time_boot_ms(snap.now_us),
        x: p.x as f32,
        y: p.y as f32,
        z: p.z as f32,
        vx: v.x as f32,
        vy: v.y as f32,
        vz: v.z as f32,
    })
}

/// GLOBAL_POSITION_INT from the estimate and its origin; relative altitude above home (above the origin
/// before home is set).
fn global_position_int(snap: &TelemetrySnapshot<'_>) -> Option<MavMessage> {
    let est = snap.estimate;
    let origin = est.origin?;
    let (lat_deg, lon_deg, alt_amsl_m) = origin.geodetic_from_ned(&est.pos_ned_m);
    let home_d_m = snap.home.map_or(0.0, |h| h.pos_ned_m.z);
    let v = est.vel_ned_mps;
    Some(MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: time_boot_ms(snap.now_us),
        lat: deg_to_dege7(lat_deg),
        lon: deg_to_dege7(lon_deg),
        alt: m_to_mm(alt_amsl_m),
        relative_alt: m_to_mm(home_d_m - est.pos_ned_m.z),
        vx: mps_to_cmps_i16(v.x),
        vy: mps_to_cmps_i16(v.y),
        vz: mps_to_cmps_i16(v.z),
        hdg: rad_to_cdeg_0_360(est.euler_rad.z),
    }))
}

fn gps_raw_int(gps: &GpsSample) -> MavMessage {
    let fix_type = match gps.fix_type {
        0 => GpsFixType::GPS_FIX_TYPE_NO_GPS,
        1 => GpsFixType::GPS_FIX_TYPE_NO_FIX,
        2 => GpsFixType::GPS_FIX_TYPE_2D_FIX,
        3 => GpsFixType::GPS_FIX_TYPE_3D_FIX,
        4 => GpsFixType::GPS_FIX_TYPE_DGPS,
        5 => GpsFixType::GPS_FIX_TYPE_RTK_FLOAT,
        _ => GpsFixType::GPS_FIX_TYPE_RTK_FIXED,
    };
    let v = gps.vel_ned_mps;
    let ground_mps = v.xy().norm();
    MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
        time_usec: gps.time_us,
        lat: deg_to_dege7(gps.lat_deg),
        lon: deg_to_dege7(gps.lon_deg),
        alt: m_to_mm(gps.alt_amsl_m),
        eph: to_centi_u16(gps.eph_m),
        epv: to_centi_u16(gps.epv_m),
        vel: to_centi_u16(ground_mps),
        cog: if ground_mps > 0.1 { rad_to_cdeg_0_360(v.y.atan2(v.x)) } else { u16::MAX },
        fix_type,
        satellites_visible: gps.satellites,
        ..Default::default()
    })
}

fn extended_sys_state(landed: LandedState) -> MavMessage {
    MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
        vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
        landed_state: identity::mav_landed_state(landed),
    })
}

fn home_position(home: &Home) -> Option<MavMessage> {
    let (lat_deg, lon_deg, alt_amsl_m) = home.geodetic?;
    let p = home.pos_ned_m;
    Some(MavMessage::HOME_POSITION(HOME_POSITION_DATA {
        latitude: deg_to_dege7(lat_deg),
        longitude: deg_to_dege7(lon_deg),
        altitude: m_to_mm(alt_amsl_m),
        x: p.x as f32,
        y: p.y as f32,
        z: p.z as f32,
        q: [1.0, 0.0, 0.0, 0.0],
        ..HOME_POSITION_DATA::default()
    }))
}

/// VFR_HUD: no airspeed sensor, so airspeed is the ground speed (no wind estimate); altitude AMSL (or
/// -D about the start point without an origin); throttle % from the mean motor command.
fn vfr_hud(snap: &TelemetrySnapshot<'_>) -> MavMessage {
    let est = snap.estimate;
    let ground_mps = est.vel_ned_mps.xy().norm();
    let alt_m = est.origin.map_or(-est.pos_ned_m.z, |o| o.alt_amsl_m - est.pos_ned_m.z);
    let mean_pwm_us = snap.pwm_us.iter().sum::<f64>() / 4.0;
    let throttle_pct = ((mean_pwm_us - 1000.0) / 10.0).clamp(0.0, 100.0);
    let heading_deg = i16::try_from(rad_to_cdeg_0_360(est.euler_rad.z) / 100).unwrap_or(0);
    MavMessage::VFR_HUD(VFR_HUD_DATA {
        airspeed: ground_mps as f32,
        groundspeed: ground_mps as f32,
        alt: alt_m as f32,
        climb: -est.vel_ned_mps.z as f32,
        heading: heading_deg,
        throttle: if throttle_pct.is_finite() { throttle_pct.round() as u16 } else { 0 },
    })
}

/// BATTERY_STATUS with every value unknown, as MAVLink spells it.
/// BATTERY_STATUS: the pack's latest reading with the monitor's level as `charge_state` (OK, LOW,
/// CRITICAL, EMERGENCY); with no reading, MAVLink's unknown values.
fn battery_status(battery: &BatteryStatus) -> MavMessage {
    use MavBatteryChargeState as C;
    let Some(sample) = battery.sample else {
        return MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: -1,
            energy_consumed: -1,
            temperature: i16::MAX,
            voltages: [u16::MAX; 10],
            current_battery: -1,
            id: 0,
            battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
            mavtype: MavBatteryType::MAV_BATTERY_TYPE_UNKNOWN,
            battery_remaining: -1,
            ..Default::default()
        });
    };
    let charge_state = match battery.level {
        BatteryWarning::None => C::MAV_BATTERY_CHARGE_STATE_OK,
        BatteryWarning::Low => C::MAV_BATTERY_CHARGE_STATE_LOW,
        BatteryWarning::Critical => C::MAV_BATTERY_CHARGE_STATE_CRITICAL,
        BatteryWarning::Emergency => C::MAV_BATTERY_CHARGE_STATE_EMERGENCY,
    };
    MavMessage::BATTERY_STATUS(encode_battery_status(&sample, charge_state))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::control::{ControllerConfig, ControllerKind, new_controller};

    /// Each controller's weights arrive as named triples carrying exactly its telemetry values, in the
    /// table's axis order.
    #[test]
    fn given_each_controller_when_the_weights_are_emitted_then_every_vector_carries_its_telemetry() {
        for (kind, expected) in [(ControllerKind::ACO, 5), (ControllerKind::CA, 8), (ControllerKind::PID, 2)] {
            let controller = new_controller(kind, &ControllerConfig::default());
            let values = controller.telemetry();
            let messages = adaptive_weights(1_500_000, controller.as_ref());
            assert_eq!(messages.len(), expected, "{kind:?}");
            for message in messages {
                let MavMessage::DEBUG_VECT(v) = message else { panic!("{message:?}") };
                assert_eq!(v.time_usec, 1_500_000);
                let name = v.name.to_str().expect("ascii name").to_owned();
                let (_, fields) = WEIGHT_VECTORS.iter().find(|(n, _)| *n == name).expect("a table name");
                for (field, got) in fields.iter().zip([v.x, v.y, v.z]) {
                    let want = values.iter().find(|(n, _)| n == field).expect("reported").1 as f32;
                    assert_eq!(got.to_bits(), want.to_bits(), "{name}: {field}");
                }
            }
        }
        // The mass estimate starts at the nominal mass on every axis.
        let aco = new_controller(ControllerKind::ACO, &ControllerConfig::default());
        let m_est = adaptive_weights(0, aco.as_ref())
            .into_iter()
            .find_map(|m| match m {
                MavMessage::DEBUG_VECT(v) if v.name.to_str() == Ok("aco.m_est") => Some(v),
                _ => None,
            })
            .expect("aco.m_est");
        let nominal = ControllerConfig::default().aco.airframe.mass_kg as f32;
        assert_eq!([m_est.x, m_est.y, m_est.z], [nominal; 3]);
    }

    #[test]
    fn given_each_source_faulted_when_sys_status_is_built_then_only_its_health_bits_are_cleared() {
        use crate::core::estimator::{SourceFault, SourceHealth};
        use MavSysStatusSensor as S;
        let healthy = EstimatorFlags {
            attitude_valid: true,
            velocity_valid: true,
            position_valid: true,
            converged: true,
            gps_ok: true,
            baro_ok: true,
            mag_ok: true,
            ..EstimatorFlags::default()
        };
        let health_of = |flags: &EstimatorFlags| {
            let m = sys_status(flags, &BatteryStatus::default(), LinkErrors::default(), 0, &ManualStatus::default());
            let MavMessage::SYS_STATUS(s) = m else { panic!("{m:?}") };
            s.onboard_control_sensors_health
        };
        let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
            | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | S::MAV_SYS_STATUS_SENSOR_3D_MAG
            | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | S::MAV_SYS_STATUS_SENSOR_GPS;
        assert!(health_of(&healthy).contains(sensors));
        // The estimator clears gps_ok, baro_ok and mag_ok with their source's fault; the IMU's fault is read
        // here, as the attitude stays valid on a stuck or garbage IMU until it drifts.
        let cases = [
            (
                EstimatorFlags { gps_ok: false, ..healthy },
                SourceHealth { gps: Some(SourceFault::Lost), ..SourceHealth::default() },
                S::MAV_SYS_STATUS_SENSOR_GPS,
            ),
            (
                EstimatorFlags { baro_ok: false, ..healthy },
                SourceHealth { baro: Some(SourceFault::Stuck), ..SourceHealth::default() },
                S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE,
            ),
            (
                EstimatorFlags { mag_ok: false, ..healthy },
                SourceHealth { mag: Some(SourceFault::Rejected), ..SourceHealth::default() },
                S::MAV_SYS_STATUS_SENSOR_3D_MAG,
            ),
            (
                healthy,
                SourceHealth { imu: Some(SourceFault::Stuck), ..SourceHealth::default() },
                S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL,
            ),
        ];
        for (flags, health, cleared) in cases {
            let got = health_of(&EstimatorFlags { health, ..flags });
            assert_eq!(got & sensors, sensors - cleared, "{health:?}");
        }
    }

    #[test]
    fn given_the_table_then_every_name_fits_debug_vect() {
        for (name, _) in WEIGHT_VECTORS {
            assert!(name.len() <= 10, "{name}");
        }
    }
}

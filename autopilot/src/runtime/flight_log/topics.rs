//! What the flight log records: the topics and their rates, each topic's ULog format, one record of a
//! topic from the vehicle's snapshot, and the header and definitions that start a flight's file.

use nalgebra::{UnitQuaternion, Vector3};

use crate::runtime::ulog::{self, Field, FieldType, Record, Topic, Value};
use crate::runtime::utc::UtcTime;
// Standard gravity (m/s²), to turn the specific force into an acceleration.
use crate::core::battery::BatteryWarning;
use crate::core::commander::FlightMode;
use crate::core::estimator::eskf::GRAVITY_MPS2 as G_MPS2;
use crate::core::estimator::{HeightSource, SourceFault};
use crate::core::manual::{ManualSource, RC_CHANNELS_MAX};
use crate::core::params::{ParamKind, ParamStore};
use crate::core::vehicle::{LogSnapshot, Vehicle};

/// The logged topics and the interval (µs of vehicle time) each is sampled at. PX4's topic names, and
/// the fields of PX4's messages that this vehicle has, with their names and types; `controller_status`
/// (every value of [`crate::core::control::Controller::telemetry`]) and `aco_weights` (ACO only) are
/// this autopilot's own. `vehicle_status` is also logged whenever the arming state or the mode changes.
/// PX4's default logger profile takes attitude and setpoints at 20-50 Hz and positions at 10 Hz; the
/// control-side topics are taken at 50 Hz here because the controller is what this autopilot studies.
/// The pilot's input at PX4's default intervals: `input_rc` (the radio's last frame) every 500 ms once a
/// frame has arrived, `manual_control_setpoint` (the sticks in use) every 200 ms once sticks have been in
/// use (see [`logged`]). `estimator_status_flags` is PX4's topic reduced to the fields this estimator has,
/// plus its own per-source fault codes (see [`px4_fault`]). `plant_link_status` is this autopilot's own:
/// the plant link's byte counts and rates, its bad frames, its samples missing and late and the last
/// second's drop rate ([`crate::core::plant_link::health`]), once a second.
pub const TOPICS: [(&str, u64); 14] = [
    ("vehicle_status", 1_000_000),
    ("vehicle_attitude", 20_000),
    ("vehicle_local_position", 20_000),
    ("vehicle_local_position_setpoint", 20_000),
    ("vehicle_attitude_setpoint", 20_000),
    ("actuator_outputs", 20_000),
    ("controller_status", 20_000),
    ("estimator_innovations", 100_000),
    ("estimator_status_flags", 100_000),
    ("battery_status", 200_000),
    ("aco_weights", 100_000),
    ("input_rc", 500_000),
    ("manual_control_setpoint", 200_000),
    ("plant_link_status", 1_000_000),
];

/// Whether topic `name` has a record at this step: `input_rc` once a radio frame has arrived,
/// `manual_control_setpoint` while sticks are in use or once they have been in this flight (`manual_seen`;
/// then with `valid` false, as PX4 publishes the loss); every other topic always.
pub(super) fn logged(name: &str, snap: &LogSnapshot, manual_seen: bool) -> bool {
    match name {
        "input_rc" => snap.manual.rc.is_some(),
        "manual_control_setpoint" => manual_seen || snap.manual.sticks.is_some(),
        _ => true,
    }
}

/// PX4's `input_rc.rssi` (0-100, -1 unknown) of RC_CHANNELS' (0-254, 255 unknown).
fn px4_rssi(rssi: u8) -> i32 {
    if rssi == u8::MAX { -1 } else { (f64::from(rssi) * 100.0 / 254.0).round() as i32 }
}

/// PX4's `manual_control_setpoint.data_source`: 1 the radio, 2 MAVLink (instance 0), 0 none.
const fn px4_data_source(source: Option<ManualSource>) -> u8 {
    match source {
        Some(ManualSource::Rc) => 1,
        Some(ManualSource::Joystick) => 2,
        None => 0,
    }
}

/// `aco_weights`: the ACO weight vectors and the telemetry names of their N/E/D or x/y/z values.
const ACO_WEIGHTS: [(&str, [&str; 3]); 5] = [
    ("w_t", ["aco.w_t_n", "aco.w_t_e", "aco.w_t_d"]),
    ("b_t", ["aco.b_t_n_mps2", "aco.b_t_e_mps2", "aco.b_t_d_mps2"]),
    ("c_r", ["aco.c_r_x", "aco.c_r_y", "aco.c_r_z"]),
    ("d_r", ["aco.d_r_x_radps2", "aco.d_r_y_radps2", "aco.d_r_z_radps2"]),
    ("mass_est", ["aco.mass_est_n_kg", "aco.mass_est_e_kg", "aco.mass_est_d_kg"]),
];

/// PX4's `vehicle_status.nav_state` of a mode.
#[must_use]
pub const fn px4_nav_state(mode: FlightMode) -> u8 {
    match mode {
        FlightMode::Altitude => 1,
        FlightMode::Position => 2,
        FlightMode::Mission => 3,
        FlightMode::Hold => 4,
        FlightMode::ReturnToLaunch => 5,
        FlightMode::Offboard => 14,
        FlightMode::Takeoff => 17,
        FlightMode::Land => 18,
        FlightMode::Manual => 0,
        FlightMode::Stabilized => 15,
        FlightMode::Acro => 10,
    }
}

/// PX4's `battery_status.warning` of a level.
const fn px4_battery_warning(level: BatteryWarning) -> u8 {
    match level {
        BatteryWarning::None => 0,
        BatteryWarning::Low => 1,
        BatteryWarning::Critical => 2,
        BatteryWarning::Emergency => 3,
    }
}

/// A source's fault in `estimator_status_flags`' `*_fault` fields: 0 healthy, 1 lost, 2 stuck, 3 rejected.
#[must_use]
pub const fn px4_fault(fault: Option<SourceFault>) -> u8 {
    match fault {
        None => 0,
        Some(SourceFault::Lost) => 1,
        Some(SourceFault::Stuck) => 2,
        Some(SourceFault::Rejected) => 3,
    }
}

/// A telemetry name as a ULog field name: without the controller's prefix, dots as underscores
/// (`ca.roll.k1` -> `roll_k1`).
fn field_name(telemetry: &str) -> String {
    let bare = telemetry.split_once('.').map_or(telemetry, |(_, rest)| rest);
    bare.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect()
}

/// The fields (after `timestamp`) of topic `name`; `telemetry` names the controller's values.
pub(super) fn fields(name: &str, telemetry: &[&'static str]) -> Vec<Field> {
    use FieldType::{Bool, F32, F64, I32, U8, U16, U32, U64};
    let f = |n: &str| Field::scalar(F32, n);
    match name {
        "vehicle_status" => vec![
            Field::scalar(U64, "armed_time"),
            Field::scalar(U8, "arming_state"),
            Field::scalar(U8, "nav_state"),
            Field::scalar(U8, "vehicle_type"),
            Field::scalar(U8, "system_type"),
            Field::scalar(U8, "system_id"),
            Field::scalar(U8, "component_id"),
            Field::scalar(Bool, "is_vtol"),
        ],
        "vehicle_attitude" => vec![Field::scalar(U64, "timestamp_sample"), Field::array(F32, 4, "q")],
        "vehicle_local_position" => {
            let mut v = vec![Field::scalar(U64, "timestamp_sample"), Field::scalar(F64, "ref_lat")];
            v.push(Field::scalar(F64, "ref_lon"));
            v.extend(["x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "heading", "ref_alt"].map(f));
            v.extend(
                ["xy_valid", "z_valid", "v_xy_valid", "v_z_valid", "xy_global", "z_global"]
                    .map(|n| Field::scalar(Bool, n)),
            );
            v
        }
        "vehicle_local_position_setpoint" => {
            let mut v: Vec<Field> = ["x", "y", "z", "yaw", "vx", "vy", "vz"].map(f).into();
            v.push(Field::array(F32, 3, "acceleration"));
            v.push(Field::array(F32, 3, "jerk"));
            v
        }
        "vehicle_attitude_setpoint" => {
            let mut v: Vec<Field> = ["roll_body", "pitch_body", "yaw_body"].map(f).into();
            v.push(Field::array(F32, 4, "q_d"));
            v
        }
        "actuator_outputs" => vec![Field::scalar(U32, "noutputs"), Field::array(F32, 16, "output")],
        "controller_status" => telemetry.iter().map(|n| f(&field_name(n))).collect(),
        "estimator_innovations" => vec![
            Field::scalar(U64, "timestamp_sample"),
            Field::array(F32, 2, "gps_hvel"),
            f("gps_vvel"),
            Field::array(F32, 2, "gps_hpos"),
            f("gps_vpos"),
            f("baro_vpos"),
            f("heading"),
        ],
        "estimator_status_flags" => {
            let mut v = vec![Field::scalar(U64, "timestamp_sample")];
            v.extend(ESTIMATOR_STATUS_BOOLS.map(|n| Field::scalar(Bool, n)));
            v.extend(["gps_fault", "baro_fault", "mag_fault", "imu_fault"].map(|n| Field::scalar(U8, n)));
            v
        }
        "battery_status" => {
            let mut v: Vec<Field> = ["voltage_v", "current_a", "discharged_mah", "remaining"].map(f).into();
            v.extend([Field::scalar(U8, "warning"), Field::scalar(U8, "cell_count"), Field::scalar(Bool, "connected")]);
            v
        }
        "aco_weights" => ACO_WEIGHTS.iter().map(|(n, _)| Field::array(F32, 3, n)).collect(),
        "input_rc" => vec![
            Field::scalar(U64, "timestamp_last_signal"),
            Field::scalar(U8, "channel_count"),
            Field::scalar(I32, "rssi"),
            Field::scalar(Bool, "rc_failsafe"),
            Field::scalar(Bool, "rc_lost"),
            Field::array(U16, RC_CHANNELS_MAX, "values"),
        ],
        "manual_control_setpoint" => {
            let mut v = vec![Field::scalar(Bool, "valid"), Field::scalar(U8, "data_source")];
            v.extend(["roll", "pitch", "yaw", "throttle"].map(f));
            v
        }
        "plant_link_status" => vec![
            Field::scalar(U64, "rx_bytes"),
            f("rx_bytes_per_s"),
            Field::scalar(U64, "tx_bytes"),
            f("tx_bytes_per_s"),
            Field::scalar(U64, "bad_frames"),
            Field::scalar(U64, "received_samples"),
            Field::scalar(U64, "missing_samples"),
            Field::scalar(U64, "late_samples"),
            f("drop_rate_pct"),
        ],
        _ => Vec::new(),
    }
}

/// `estimator_status_flags`' boolean fields, PX4's names: the filter's control status (`cs_*`: tilt and
/// yaw aligned, GPS fused, magnetic heading fused, baro the height source, GPS altitude fused, the
/// magnetometer declared faulty) and the innovation checks of the latest measurements (`reject_*`: the
/// GPS velocity and position are gated as 3-vectors, so horizontal and vertical share a flag; `reject_ver_pos`
/// is the GPS position's or the barometer's).
const ESTIMATOR_STATUS_BOOLS: [&str; 12] = [
    "cs_tilt_align",
    "cs_yaw_align",
    "cs_gps",
    "cs_mag_hdg",
    "cs_baro_hgt",
    "cs_gps_hgt",
    "cs_mag_fault",
    "reject_hor_vel",
    "reject_ver_vel",
    "reject_hor_pos",
    "reject_ver_pos",
    "reject_yaw",
];

/// What a record needs besides the vehicle's snapshot.
pub(super) struct RecordContext<'a> {
    pub(super) sysid: u8,
    /// Vehicle time of arming (`vehicle_status.armed_time`).
    pub(super) armed_at_us: u64,
    /// The controller's telemetry now.
    pub(super) telemetry: &'a [(&'static str, f64)],
    /// The telemetry names `controller_status` declared when the flight started.
    pub(super) telemetry_names: &'a [&'static str],
}

/// One record of topic `name` at `now_us`.
pub(super) fn record(name: &str, now_us: u64, snap: &LogSnapshot, ctx: &RecordContext<'_>) -> Record {
    let r = Record::new(now_us);
    let telemetry = ctx.telemetry;
    let est = &snap.estimate;
    let value = |n: &str| telemetry.iter().find(|(t, _)| *t == n).map_or(f64::NAN, |&(_, v)| v);
    let nan3 = [f64::NAN; 3];
    match name {
        "vehicle_status" => r
            .u64(ctx.armed_at_us)
            .u8(if snap.armed { 2 } else { 1 })
            .u8(px4_nav_state(snap.mode))
            .u8(1) // rotary wing
            .u8(2) // MAV_TYPE_QUADROTOR
            .u8(ctx.sysid)
            .u8(1)
            .bool(false),
        "vehicle_attitude" => {
            let q = est.q_ned_frd;
            r.u64(est.time_us).f32s(&[q.w, q.i, q.j, q.k])
        }
        "vehicle_local_position" => {
            let (lat, lon, alt) =
                est.origin.map_or((f64::NAN, f64::NAN, f64::NAN), |o| (o.lat_deg, o.lon_deg, o.alt_amsl_m));
            let acc = est.q_ned_frd * est.specific_force_frd_mps2 + Vector3::new(0.0, 0.0, G_MPS2);
            let (p, v, flags) = (est.pos_ned_m, est.vel_ned_mps, est.flags);
            r.u64(est.time_us)
                .f64(lat)
                .f64(lon)
                .f32s(&[p.x, p.y, p.z, v.x, v.y, v.z, acc.x, acc.y, acc.z, est.euler_rad.z, alt])
                .bool(flags.position_valid)
                .bool(flags.position_valid)
                .bool(flags.velocity_valid)
                .bool(flags.velocity_valid)
                .bool(est.origin.is_some())
                .bool(est.origin.is_some())
        }
        "vehicle_local_position_setpoint" => match &snap.reference {
            Some(rf) => {
                let (x, y) =
                    if rf.attitude_rad.is_some() { (f64::NAN, f64::NAN) } else { (rf.pos_ned_m.x, rf.pos_ned_m.y) };
                let (v, a, j) = (rf.vel_ned_mps, rf.acc_ned_mps2, rf.jerk_ned_mps3);
                r.f32s(&[x, y, rf.pos_ned_m.z, rf.yaw_rad, v.x, v.y, v.z, a.x, a.y, a.z, j.x, j.y, j.z])
            }
            None => r.f32s(&[f64::NAN; 13]),
        },
        "vehicle_attitude_setpoint" => {
            let sp = if snap.reference.is_some() { snap.attitude_setpoint_rad } else { Vector3::from(nan3) };
            let q = UnitQuaternion::from_euler_angles(sp.x, sp.y, sp.z);
            let q_d = if sp.iter().all(|x| x.is_finite()) { [q.w, q.i, q.j, q.k] } else { [f64::NAN; 4] };
            r.f32s(&[sp.x, sp.y, sp.z]).f32s(&q_d)
        }
        "actuator_outputs" => {
            let mut out = [0.0; 16];
            out[..4].copy_from_slice(&snap.pwm_us);
            r.u32(4).f32s(&out)
        }
        "controller_status" => ctx.telemetry_names.iter().fold(r, |r, n| r.f32(value(n))),
        "estimator_innovations" => {
            let i = &snap.innovations;
            r.u64(est.time_us).f32s(&i.gps_vel_ned_mps).f32s(&i.gps_pos_ned_m).f32(i.baro_alt_m).f32(i.heading_rad)
        }
        "estimator_status_flags" => {
            let (flags, i) = (&est.flags, &snap.innovations);
            let health = flags.health;
            let bools = [
                flags.attitude_valid,                      // cs_tilt_align
                flags.attitude_valid,                      // cs_yaw_align
                flags.gps_ok,                              // cs_gps
                flags.mag_ok,                              // cs_mag_hdg
                flags.height_source == HeightSource::Baro, // cs_baro_hgt
                flags.gps_ok,                              // cs_gps_hgt: GPS altitude fused with every fix
                health.mag.is_some(),                      // cs_mag_fault
                i.gps_vel_rejected,                        // reject_hor_vel
                i.gps_vel_rejected,                        // reject_ver_vel
                i.gps_pos_rejected,                        // reject_hor_pos
                i.gps_pos_rejected || i.baro_rejected,     // reject_ver_pos
                i.heading_rejected,                        // reject_yaw
            ];
            bools
                .iter()
                .fold(r.u64(est.time_us), |r, &b| r.bool(b))
                .u8(px4_fault(health.gps))
                .u8(px4_fault(health.baro))
                .u8(px4_fault(health.mag))
                .u8(px4_fault(health.imu))
        }
        "battery_status" => {
            let s = snap.battery.sample;
            r.f32(s.map_or(0.0, |s| s.voltage_v))
                .f32(s.and_then(|s| s.current_a).unwrap_or(-1.0))
                .f32(s.and_then(|s| s.consumed_mah).unwrap_or(-1.0))
                .f32(s.and_then(|s| s.remaining).unwrap_or(-1.0))
                .u8(px4_battery_warning(snap.battery.level))
                .u8(s.map_or(0, |s| s.cells))
                .bool(s.is_some())
        }
        "aco_weights" => ACO_WEIGHTS.iter().fold(r, |r, (_, names)| r.f32s(&names.map(value))),
        "input_rc" => {
            let frame = snap.manual.rc.unwrap_or_default();
            // The receiver's own failsafe: a frame without channels or without signal.
            let failsafe = snap.manual.rc.is_some() && (frame.count == 0 || frame.rssi == 0);
            let r = r
                .u64(snap.manual.rc_at_us.unwrap_or(0))
                .u8(frame.count)
                .i32(px4_rssi(frame.rssi))
                .bool(failsafe)
                .bool(!snap.manual.rc_fresh);
            frame.channels_us.iter().fold(r, |r, &c| r.u16(c))
        }
        "manual_control_setpoint" => {
            let m = &snap.manual;
            // PX4's throttle is [-1, 1] (-1 minimum); the sticks' is [0, 1].
            let sticks = m.sticks.map_or([f64::NAN; 4], |s| [s.roll, s.pitch, s.yaw, 2.0 * s.throttle - 1.0]);
            r.bool(m.sticks.is_some()).u8(px4_data_source(m.source)).f32s(&sticks)
        }
        "plant_link_status" => {
            let p = &snap.plant_link;
            r.u64(p.counters.rx_bytes)
                .f32(p.rx_bytes_per_s)
                .u64(p.counters.tx_bytes)
                .f32(p.tx_bytes_per_s)
                .u64(p.counters.bad_frames)
                .u64(p.received_samples)
                .u64(p.missing_samples)
                .u64(p.late_samples)
                .f32(p.drop_rate_pct())
        }
        _ => r,
    }
}

/// A parameter's value as PX4 types it in a log.
pub(super) fn param_value(kind: ParamKind, value: f32) -> Value {
    match kind {
        ParamKind::Real => Value::F32(value),
        ParamKind::Integer | ParamKind::Boolean => Value::I32(value as i32),
    }
}

/// The header and definitions of a flight starting at `now_us` (vehicle time) and `wall_us` (Unix
/// time): flag bits, formats, information, parameters and their defaults, subscriptions.
pub(super) fn definitions(now_us: u64, wall_us: u64, vehicle: &Vehicle, topics: &[Topic]) -> Vec<u8> {
    let mut out = ulog::header(now_us).to_vec();
    out.extend(ulog::flag_bits());
    for t in topics {
        out.extend(t.format_message().unwrap_or_default());
    }
    let controller = vehicle.controller().kind().as_str().to_owned();
    let infos = [
        ("sys_name", Value::Str("ACO autopilot".into())),
        ("ver_hw", Value::Str("ACO_QUADROTOR".into())),
        ("ver_sw", Value::Str(env!("CARGO_PKG_VERSION").into())),
        ("sys_toolchain", Value::Str("rustc".into())),
        ("time_ref_utc", Value::I32(0)),
        ("controller", Value::Str(controller)),
        ("estimator", Value::Str(format!("{:?}", vehicle.config().estimator.source).to_lowercase())),
        (
            "log_start_utc",
            Value::Str(format!(
                "{} {} UTC",
                UtcTime::from_unix_us(wall_us).date(),
                UtcTime::from_unix_us(wall_us).time(':')
            )),
        ),
    ];
    for (name, value) in &infos {
        out.extend(ulog::info(name, value).unwrap_or_default());
    }
    let store: &ParamStore = vehicle.params();
    for (def, value) in store.iter() {
        out.extend(ulog::parameter(def.name, &param_value(def.kind, value)).unwrap_or_default());
    }
    for (def, value) in store.iter() {
        if value.to_bits() != def.default.to_bits() {
            let default = param_value(def.kind, def.default);
            out.extend(ulog::default_parameter(ulog::DEFAULT_TYPE_SYSTEM, def.name, &default).unwrap_or_default());
        }
    }
    for t in topics {
        out.extend(t.subscription(0).unwrap_or_default());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::VehicleConfig;
    use crate::core::control::ControllerKind;
    use crate::runtime::flight_log::sampler::tests::vehicle;

    #[test]
    fn field_names_drop_the_controller_prefix_and_dots() {
        assert_eq!(field_name("aco.w_t_n"), "w_t_n");
        assert_eq!(field_name("ca.roll.k1"), "roll_k1");
        assert_eq!(field_name("plain"), "plain");
        // Every controller's telemetry gives distinct, plain field names.
        for kind in [ControllerKind::ACO, ControllerKind::CA, ControllerKind::PID] {
            let c = crate::core::control::new_controller(kind, &VehicleConfig::default().control);
            let names: Vec<String> = c.telemetry().iter().map(|(n, _)| field_name(n)).collect();
            let unique: std::collections::HashSet<&String> = names.iter().collect();
            assert_eq!(unique.len(), names.len(), "{kind}: {names:?}");
            assert!(names.iter().all(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')));
        }
        // Each topic's record matches its format for every controller.
        let v = vehicle();
        let snap = v.log_snapshot();
        let telemetry = v.controller().telemetry();
        let names: Vec<&'static str> = telemetry.iter().map(|(n, _)| *n).collect();
        let ctx = RecordContext { sysid: 1, armed_at_us: 0, telemetry: &telemetry, telemetry_names: &names };
        for (i, (name, _)) in TOPICS.iter().enumerate() {
            let topic = Topic::new(name, i as u16, fields(name, &names));
            assert!(topic.data(&record(name, 0, &snap, &ctx)).is_ok(), "{name}");
        }
    }

    #[test]
    fn given_a_baro_stuck_and_the_gps_rejected_when_logged_then_estimator_status_flags_says_so_in_px4_names() {
        use crate::core::estimator::SourceHealth;
        let v = vehicle();
        let mut snap = v.log_snapshot();
        let flags = &mut snap.estimate.flags;
        flags.health = SourceHealth {
            gps: Some(SourceFault::Rejected),
            baro: Some(SourceFault::Stuck),
            ..SourceHealth::default()
        };
        flags.height_source = HeightSource::Gps;
        (flags.attitude_valid, flags.gps_ok, flags.mag_ok) = (true, false, true);
        snap.innovations.gps_pos_rejected = true;
        let ctx = RecordContext { sysid: 1, armed_at_us: 0, telemetry: &[], telemetry_names: &[] };
        let name = "estimator_status_flags";
        let topic = Topic::new(name, 0, fields(name, &[]));
        let bytes = topic.data(&record(name, 0, &snap, &ctx)).expect("matches its format");
        let names: Vec<String> = topic_field_names(name);
        let at = |field: &str| {
            // Header (3) + msg_id (2) + timestamp (8) + timestamp_sample (8), then one byte per field.
            bytes[21 + names.iter().position(|n| n == field).expect(field)]
        };
        let on = |field: &str| at(field) == 1;
        assert!(on("cs_tilt_align") && on("cs_mag_hdg") && !on("cs_gps") && !on("cs_baro_hgt") && !on("cs_gps_hgt"));
        assert!(on("reject_hor_pos") && on("reject_ver_pos") && !on("reject_hor_vel") && !on("reject_yaw"));
        assert_eq!([at("gps_fault"), at("baro_fault"), at("mag_fault"), at("imu_fault")], [3, 2, 0, 0]);
        assert_eq!(bytes.len(), 21 + names.len());
    }

    /// The field names of `topic` after its timestamps.
    fn topic_field_names(topic: &str) -> Vec<String> {
        fields(topic, &[]).iter().skip(1).map(|f| f.name.clone()).collect()
    }
}

//! Vehicle tests: commands and their replies, telemetry cadences, parameters, PWM limits and the
//! plant-lost fallback, on a truth-fed vehicle in simulated time.

use ::mavlink::Message as _;
use ::mavlink::dialects::common::{COMMAND_INT_DATA, MavCmd, MavFrame, MavModeFlag, MavResult, MavSeverity};

use super::*;
use crate::core::battery::BatterySample;
use crate::core::commander::State;
use crate::core::estimator::GeoOrigin;
use crate::core::estimator::{EstimatorSource, ImuSample};
use crate::core::mavlink::command_long;
use ::mavlink::MavHeader;

const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
const DT_US: u64 = 2_000;
const ORIGIN: GeoOrigin = GeoOrigin { lat_deg: 47.397742, lon_deg: 8.545594, alt_amsl_m: 488.0 };
const HOLD: u32 = (4 << 16) | (3 << 24);
const TAKEOFF: u32 = (4 << 16) | (2 << 24);
const POSCTL: u32 = 3 << 16;

/// A vehicle fed the truth of a vehicle at rest on the ground (the truth source is converged at once).
fn truth_vehicle() -> Vehicle {
    let mut config = VehicleConfig::default();
    config.estimator.source = EstimatorSource::Truth;
    config.estimator.truth_origin = Some(ORIGIN);
    config.commander.disarm_preflight_s = -1.0;
    Vehicle::new(config).expect("valid config")
}

fn at_rest(time_us: u64) -> VehicleInputs {
    let gps = time_us.is_multiple_of(100_000).then_some(GpsSample {
        time_us,
        lat_deg: ORIGIN.lat_deg,
        lon_deg: ORIGIN.lon_deg,
        alt_amsl_m: ORIGIN.alt_amsl_m,
        vel_ned_mps: Vector3::zeros(),
        fix_type: 3,
        satellites: 10,
        eph_m: 0.5,
        epv_m: 0.8,
    });
    VehicleInputs { gps, ..VehicleInputs::at_rest_truth(time_us) }
}

/// Steps `v` from `*t_us` for `seconds`, returning every message with its time.
fn run(v: &mut Vehicle, t_us: &mut u64, seconds: f64) -> Vec<(u64, MavMessage)> {
    let mut out = Vec::new();
    let end = *t_us + (seconds * 1e6) as u64;
    while *t_us < end {
        let o = v.step(*t_us, &at_rest(*t_us));
        out.extend(o.messages.into_iter().map(|m| (*t_us, m)));
        *t_us += DT_US;
    }
    out
}

/// A COMMAND_LONG to every component (0) of `target_system`, as pymavlink sends it.
fn long(command: MavCmd, p: [f32; 7], target_system: u8) -> MavMessage {
    command_long(target_system, 0, command, p)
}

fn int(command: MavCmd, p: [f32; 7], frame: MavFrame) -> MavMessage {
    MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        x: 0,
        y: 0,
        z: p[6],
        command,
        target_system: 1,
        target_component: 1,
        frame,
        current: 0,
        autocontinue: 0,
    })
}

fn ack_of(replies: &[MavMessage]) -> Option<(MavCmd, MavResult)> {
    replies.iter().find_map(|m| match m {
        MavMessage::COMMAND_ACK(a) => Some((a.command, a.result)),
        _ => None,
    })
}

fn heartbeats(msgs: &[(u64, MavMessage)]) -> Vec<(u64, u32, MavModeFlag)> {
    msgs.iter()
        .filter_map(|(t, m)| match m {
            MavMessage::HEARTBEAT(h) => Some((*t, h.custom_mode, h.base_mode)),
            _ => None,
        })
        .collect()
}

const ARM: [f32; 7] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

#[test]
fn given_a_disarmed_vehicle_when_run_10s_then_heartbeat_at_1hz_of_vehicle_time_and_at_once_on_arm() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    let hb = heartbeats(&run(&mut v, &mut t, 10.0));
    assert_eq!(hb.len(), 10);
    assert!(hb.windows(2).all(|w| w[1].0 - w[0].0 == 1_000_000), "{hb:?}");
    // WHEN armed half-way between two heartbeats THEN the next step sends one, armed.
    run(&mut v, &mut t, 0.5);
    let armed_at = t;
    let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_ACCEPTED)));
    let hb = heartbeats(&run(&mut v, &mut t, 0.01));
    assert_eq!(hb.len(), 1);
    assert_eq!(hb[0].0, armed_at);
    assert!(hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
}

#[test]
fn given_arm_takeoff_and_mode_changes_when_heartbeats_then_px4_custom_and_base_modes() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    let hb = heartbeats(&run(&mut v, &mut t, 0.1));
    let custom = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    assert_eq!(hb[0].1, HOLD);
    assert!(hb[0].2.contains(custom) && !hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    let mode = |main: f32, sub: f32| long(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, main, sub, 0.0, 0.0, 0.0, 0.0], 1);
    // POSCTL flies the sticks: a joystick's MANUAL_CONTROL first (throttle centred).
    let sticks = MavMessage::MANUAL_CONTROL(::mavlink::dialects::common::MANUAL_CONTROL_DATA {
        target: 1,
        z: 500,
        ..Default::default()
    });
    v.handle_message(t, &GCS, &sticks);
    let replies = v.handle_message(t, &GCS, &mode(3.0, 0.0));
    assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
    let hb = heartbeats(&run(&mut v, &mut t, 0.01));
    assert_eq!((hb.len(), hb[0].1), (1, POSCTL), "immediate heartbeat on a mode change");
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    let hb = heartbeats(&run(&mut v, &mut t, 0.01));
    assert_eq!(hb[0].1, POSCTL);
    assert!(hb[0].2.contains(custom | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
    assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
    let hb = heartbeats(&run(&mut v, &mut t, 0.01));
    assert_eq!(hb.last().map(|h| h.1), Some(TAKEOFF));
    assert!(hb[0].2.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
}

#[test]
fn given_commands_when_handled_then_every_one_is_acked_and_unknown_ones_unsupported() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let nan = f32::NAN;
    for (cmd, p, want) in [
        (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5], MavResult::MAV_RESULT_ACCEPTED),
        (MavCmd::MAV_CMD_NAV_LAND, [0.0; 7], MavResult::MAV_RESULT_DENIED),
        (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, MavResult::MAV_RESULT_ACCEPTED),
        (MavCmd::MAV_CMD_DO_SET_SERVO, [1.0, 1500.0, 0.0, 0.0, 0.0, 0.0, 0.0], MavResult::MAV_RESULT_UNSUPPORTED),
    ] {
        let replies = v.handle_message(t, &GCS, &long(cmd, p, 1));
        assert_eq!(ack_of(&replies), Some((cmd, want)), "{cmd:?}");
        run(&mut v, &mut t, 0.05);
    }
    assert_eq!(v.commander().state(), State::Takeoff);
    let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7], 1));
    assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_NAV_LAND, MavResult::MAV_RESULT_ACCEPTED)));
    assert_eq!(v.commander().state(), State::Land);
}

#[test]
fn given_an_unconverged_estimator_when_arming_then_denied_with_statustext() {
    let mut v = Vehicle::new(VehicleConfig::default()).expect("defaults are valid");
    let mut t = 0;
    run(&mut v, &mut t, 0.1);
    let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    assert_eq!(ack_of(&replies), Some((MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, MavResult::MAV_RESULT_DENIED)));
    let text = replies.iter().find_map(|m| match m {
        MavMessage::STATUSTEXT(s) => Some((s.severity, s.text.to_str().unwrap_or("").to_owned())),
        _ => None,
    });
    assert_eq!(text, Some((MavSeverity::MAV_SEVERITY_WARNING, "Arming denied: estimator not converged".to_owned())));
    assert!(!v.commander().armed());
}

#[test]
fn given_the_same_commands_as_long_and_int_when_handled_then_same_replies_and_state() {
    let nan = f32::NAN;
    let script = [
        (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, 0.0, 0.0, 490.0]),
        (MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
        (MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, 0.0, 0.0, 1.5]),
        (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM),
        (MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]),
        (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (MavCmd::MAV_CMD_DO_SET_SERVO, [0.0; 7]),
    ];
    let (mut a, mut b, mut ta, mut tb) = (truth_vehicle(), truth_vehicle(), 0, 0);
    run(&mut a, &mut ta, 0.1);
    run(&mut b, &mut tb, 0.1);
    for (cmd, p) in script {
        let ra = a.handle_message(ta, &GCS, &long(cmd, p, 1));
        let rb = b.handle_message(tb, &GCS, &int(cmd, p, MavFrame::MAV_FRAME_GLOBAL));
        assert_eq!(ra, rb, "{cmd:?}");
        assert_eq!(
            (a.commander().state(), a.commander().pending_takeoff_alt_m()),
            (b.commander().state(), b.commander().pending_takeoff_alt_m())
        );
        let ma = run(&mut a, &mut ta, 0.2);
        let mb = run(&mut b, &mut tb, 0.2);
        assert_eq!(heartbeats(&ma), heartbeats(&mb));
    }
    assert_eq!(a.commander().state(), State::Killed);
}

#[test]
fn given_takeoff_altitudes_when_sent_disarmed_then_nan_default_amsl_relative_and_low_relative() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let nan = f32::NAN;
    let mut pending = |alt: f32| {
        let p = [0.0, 0.0, 0.0, nan, nan, nan, alt];
        let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, p, 1));
        assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED), "alt {alt}");
        v.commander().pending_takeoff_alt_m()
    };
    assert_eq!(pending(nan), Some(crate::core::commander::CommanderConfig::default().takeoff_alt_m));
    assert_eq!(pending(491.0), Some(3.0), "AMSL above home at 488 m");
    assert_eq!(pending(1.5), Some(1.5), "below home: relative");
    // A relative-altitude COMMAND_INT frame is taken as given.
    let msg =
        int(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, 0.0, 0.0, 2.0], MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
    v.handle_message(t, &GCS, &msg);
    assert_eq!(v.commander().pending_takeoff_alt_m(), Some(2.0));
    t += DT_US;
    v.step(t, &at_rest(t));
}

#[test]
fn given_a_command_for_another_system_when_handled_then_ignored() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let replies = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 7));
    assert!(replies.is_empty());
    run(&mut v, &mut t, 0.1);
    assert!(!v.commander().armed());
    let broadcast = v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 0));
    assert_eq!(ack_of(&broadcast).map(|a| a.1), Some(MavResult::MAV_RESULT_ACCEPTED));
}

#[test]
fn given_10s_of_vehicle_time_when_counted_then_each_stream_at_its_default_rate() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    run(&mut v, &mut t, 0.9);
    let msgs = run(&mut v, &mut t, 10.0);
    let count = |id: u32| msgs.iter().filter(|(_, m)| m.message_id() == id).count() as i64;
    for (name, id, want) in [
        ("HEARTBEAT", 0, 10),
        ("SYS_STATUS", 1, 10),
        ("GPS_RAW_INT", 24, 50),
        ("ATTITUDE", 30, 200),
        ("ATTITUDE_QUATERNION", 31, 100),
        ("LOCAL_POSITION_NED", 32, 100),
        ("GLOBAL_POSITION_INT", 33, 100),
        ("VFR_HUD", 74, 40),
        ("BATTERY_STATUS", 147, 10),
        ("HOME_POSITION", 242, 5),
        ("EXTENDED_SYS_STATE", 245, 10),
        // The five ACO weight vectors at 2 Hz.
        ("DEBUG_VECT", 250, 100),
    ] {
        assert!((count(id) - want).abs() <= 1, "{name}: {} in 10 s, want {want}", count(id));
    }
    let sys = msgs.iter().find_map(|(_, m)| match m {
        MavMessage::SYS_STATUS(s) => Some(s.clone()),
        _ => None,
    });
    let sys = sys.expect("SYS_STATUS");
    assert!(
        sys.onboard_control_sensors_health
            .contains(::mavlink::dialects::common::MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK)
    );
    assert_eq!((sys.voltage_battery, sys.current_battery, sys.battery_remaining), (u16::MAX, -1, -1));
}

#[test]
fn given_disarmed_or_idle_or_non_finite_inputs_when_stepped_then_pwm_1000_and_never_nan() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    for _ in 0..100 {
        assert_eq!(v.step(t, &at_rest(t)).pwm_us, [MOTOR_PWM_MIN_US; 4], "disarmed");
        t += DT_US;
    }
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    let o = v.step(t, &at_rest(t));
    assert!(o.armed);
    assert_eq!(o.pwm_us, [MOTOR_PWM_MIN_US; 4], "armed idle");
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
    let mut spun_up = false;
    for i in 0..500 {
        t += DT_US;
        let mut inputs = at_rest(t);
        if i % 3 == 0 {
            inputs.imu = Some(ImuSample {
                time_us: t,
                accel_frd_mps2: Vector3::repeat(f64::NAN),
                gyro_frd_radps: Vector3::zeros(),
            });
            if let Some(truth) = inputs.truth.as_mut() {
                truth.pos_ned_m.x = f64::NAN;
            }
        }
        let pwm = v.step(t, &inputs).pwm_us;
        assert!(pwm.iter().all(|p| p.is_finite() && (MOTOR_PWM_MIN_US..=MOTOR_PWM_MAX_US).contains(p)), "{pwm:?}");
        spun_up |= pwm.iter().any(|p| *p > MOTOR_PWM_MIN_US);
    }
    assert!(spun_up, "the takeoff ran the controller");
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1));
    t += DT_US;
    assert_eq!(v.step(t, &at_rest(t)).pwm_us, [MOTOR_PWM_MIN_US; 4], "killed");
}

#[test]
fn given_bad_configs_when_built_then_errors() {
    let bad_sysid = VehicleConfig { sysid: 0, ..VehicleConfig::default() };
    assert_eq!(Vehicle::new(bad_sysid).err(), Some(VehicleError::Sysid));
    let mut bad_speed = VehicleConfig::default();
    bad_speed.navigator.takeoff_speed_mps = f64::NAN;
    assert!(matches!(Vehicle::new(bad_speed), Err(VehicleError::Navigator(e)) if e.field == "takeoff_speed_mps"));
}

/// The first message of `replies` after the ACK, and the ACK's result.
fn ack_and_rest(replies: &[MavMessage]) -> (Option<MavResult>, Vec<MavMessage>) {
    let ack = replies.iter().find_map(|m| if let MavMessage::COMMAND_ACK(a) = m { Some(a.result) } else { None });
    (ack, replies.iter().filter(|m| !matches!(m, MavMessage::COMMAND_ACK(_))).cloned().collect())
}

#[test]
fn given_request_message_when_asked_for_the_version_home_and_unknowns_then_answered_or_unsupported() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let request = |id: f32| long(MavCmd::MAV_CMD_REQUEST_MESSAGE, [id, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(148.0)));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    assert!(matches!(rest.as_slice(), [MavMessage::AUTOPILOT_VERSION(_)]), "{rest:?}");
    // The ACK goes back to its sender.
    let replies = v.handle_message(t, &GCS, &request(148.0));
    let Some(MavMessage::COMMAND_ACK(a)) = replies.first() else { panic!("{replies:?}") };
    assert_eq!((a.target_system, a.target_component), (255, 190));
    // HOME_POSITION exists once the estimate has converged with a global position (here at once, on
    // truth), before arming; without it the request is denied.
    let mut blind = Vehicle::new(VehicleConfig::default()).expect("defaults are valid");
    blind.step(0, &VehicleInputs::default());
    let (ack, _) = ack_and_rest(&blind.handle_message(0, &GCS, &request(242.0)));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_DENIED), "no home yet");
    assert!(!v.commander().armed());
    let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(242.0)));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    assert!(matches!(rest.as_slice(), [MavMessage::HOME_POSITION(_)]), "{rest:?}");
    let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &request(9999.0)));
    assert_eq!((ack, rest.len()), (Some(MavResult::MAV_RESULT_UNSUPPORTED), 0));
    // The deprecated REQUEST_AUTOPILOT_CAPABILITIES MAVSDK falls back to is answered too.
    #[allow(deprecated)]
    let caps = long(MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let (ack, rest) = ack_and_rest(&v.handle_message(t, &GCS, &caps));
    assert!(
        ack == Some(MavResult::MAV_RESULT_ACCEPTED) && matches!(rest.as_slice(), [MavMessage::AUTOPILOT_VERSION(_)])
    );
}

#[test]
fn given_set_message_interval_when_applied_then_that_stream_runs_at_its_new_rate_off_and_back_to_default() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let interval = |id: f32, us: f32| long(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [id, us, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let count = |msgs: &[(u64, MavMessage)], id: u32| msgs.iter().filter(|(_, m)| m.message_id() == id).count();
    let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &interval(30.0, 10_000.0)));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 200, "ATTITUDE at 100 Hz");
    v.handle_message(t, &GCS, &interval(30.0, -1.0));
    assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 0, "ATTITUDE off");
    v.handle_message(t, &GCS, &interval(30.0, 0.0));
    assert_eq!(count(&run(&mut v, &mut t, 2.0), 30), 40, "ATTITUDE back at its default 20 Hz");
    let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &interval(9999.0, 1e5)));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_UNSUPPORTED));
    #[allow(deprecated)]
    let get = long(MavCmd::MAV_CMD_GET_MESSAGE_INTERVAL, [30.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let (_, rest) = ack_and_rest(&v.handle_message(t, &GCS, &get));
    assert!(matches!(rest.as_slice(), [MavMessage::MESSAGE_INTERVAL(m)] if m.interval_us == 50_000), "{rest:?}");
}

#[test]
fn given_parameters_when_set_then_applied_echoed_saved_and_out_of_range_refused_unchanged() {
    use ::mavlink::dialects::common::{MavParamType, PARAM_SET_DATA};
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let set = |name: &str, value: f32| {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })
    };
    let replies = v.handle_message(t, &GCS, &set("MPC_XY_CRUISE", 2.0));
    assert!(matches!(replies.as_slice(), [MavMessage::PARAM_VALUE(p)] if p.param_value == 2.0), "{replies:?}");
    assert_eq!(v.config().navigator.cruise_speed_mps, 2.0, "applied at once");
    assert!(matches!(v.take_effects().as_slice(), [ShellEffect::SaveParams(text)] if text.contains("MPC_XY_CRUISE")));
    let before = v.params().clone();
    let replies = v.handle_message(t, &GCS, &set("MPC_XY_CRUISE", 99.0));
    assert!(replies.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(_))), "{replies:?}");
    assert!(replies.iter().any(|m| matches!(m, MavMessage::PARAM_VALUE(p) if p.param_value == 2.0)));
    assert_eq!(v.params(), &before);
    assert_eq!(v.config().navigator.cruise_speed_mps, 2.0);
    assert!(v.take_effects().is_empty(), "a refusal saves nothing");
    // The weight stream follows ACO_WEIGHTS_HZ.
    v.handle_message(t, &GCS, &set("ACO_WEIGHTS_HZ", 10.0));
    assert_eq!(v.mavlink_mut().streams().interval_us(Stream::AdaptiveWeights), 100_000);
    v.take_effects();
    // A value that applies only after a restart is checked now: LOOP_POS_HZ 300 (in range) does not
    // divide LOOP_INNER_HZ 500, nor does LOOP_INNER_HZ 150 take LOOP_POS_HZ 100: refused, with the
    // reason, unchanged, nothing saved (a reboot would have failed to start).
    for (name, value) in [("LOOP_POS_HZ", 300.0), ("LOOP_INNER_HZ", 150.0)] {
        let before = v.params().clone();
        let replies = v.handle_message(t, &GCS, &set(name, value));
        // The reason in MAVLink 2 STATUSTEXT chunks (one id, chunk_seq 0, 1, ...), reassembled.
        let chunks: Vec<_> =
            replies.iter().filter_map(|m| if let MavMessage::STATUSTEXT(s) = m { Some(s) } else { None }).collect();
        assert!(chunks.len() > 1 && chunks.iter().all(|c| c.id == chunks[0].id && c.id != 0), "{chunks:?}");
        assert!(chunks.iter().enumerate().all(|(i, c)| usize::from(c.chunk_seq) == i));
        let text: String = chunks.iter().map(|c| c.text.to_str().unwrap_or_default()).collect();
        assert!(text.starts_with(name) && text.contains("must divide the inner rate"), "{text}");
        assert_eq!(v.params(), &before, "{name}");
        assert!(v.take_effects().is_empty(), "{name}: nothing saved");
    }
}

#[test]
fn given_positions_beyond_the_hard_limit_from_home_then_offboard_and_reposition_refuse_them_with_a_reason() {
    use ::mavlink::dialects::common::{PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA};
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 1.0);
    assert!(v.home().is_some(), "home set at the first converged fix");
    let target = |x: f32, y: f32, z: f32| {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            x,
            y,
            z,
            target_system: 1,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            type_mask: PositionTargetTypemask::from_bits_truncate(2552),
            ..Default::default()
        })
    };
    // GIVEN a finite but absurd offboard position (1e30 m) THEN refused in words, once.
    let replies = v.handle_message(t, &GCS, &target(1e30, -1e30, -1e30));
    let text = replies.iter().find_map(|m| match m {
        MavMessage::STATUSTEXT(s) => s.text.to_str().ok().map(str::to_owned),
        _ => None,
    });
    assert_eq!(text.as_deref(), Some("Offboard: setpoint over 10 km from home"));
    assert!(v.handle_message(t, &GCS, &target(1e30, -1e30, -1e30)).is_empty(), "said once");
    // A setpoint 9.9 km away is a position like any other.
    assert!(v.handle_message(t, &GCS, &target(9_900.0, 0.0, -5.0)).is_empty());
    // GIVEN a DO_REPOSITION 20 km north, in the air THEN refused with the reason.
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    let far = int(
        MavCmd::MAV_CMD_DO_REPOSITION,
        [-1.0, 1.0, 0.0, f32::NAN, 0.0, 0.0, 5.0],
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
    );
    let far = match far {
        MavMessage::COMMAND_INT(mut c) => {
            c.x = ((ORIGIN.lat_deg + 0.18) * 1e7) as i32;
            c.y = (ORIGIN.lon_deg * 1e7) as i32;
            MavMessage::COMMAND_INT(c)
        }
        other => other,
    };
    let replies = v.handle_message(t, &GCS, &far);
    assert_eq!(ack_of(&replies).map(|a| a.1), Some(MavResult::MAV_RESULT_DENIED), "{replies:?}");
    let said = replies.iter().any(|m| {
        matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == "Reposition: over 10 km from home"))
    });
    assert!(said, "{replies:?}");
}

#[test]
fn given_a_reboot_when_disarmed_then_the_shell_is_asked_and_when_armed_refused() {
    let (mut v, mut t) = (truth_vehicle(), 0);
    run(&mut v, &mut t, 0.1);
    let reboot = long(MavCmd::MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &reboot));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_ACCEPTED));
    assert_eq!(v.take_effects(), vec![ShellEffect::Reboot]);
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    let (ack, _) = ack_and_rest(&v.handle_message(t, &GCS, &reboot));
    assert_eq!(ack, Some(MavResult::MAV_RESULT_DENIED));
    assert!(v.take_effects().is_empty());
}

fn sys_status_of(messages: &[MavMessage]) -> Option<&::mavlink::dialects::common::SYS_STATUS_DATA> {
    messages.iter().rev().find_map(|m| match m {
        MavMessage::SYS_STATUS(s) => Some(s),
        _ => None,
    })
}

#[test]
fn given_a_lost_plant_then_the_fallback_says_critical_disarmed_emergency_armed_and_every_sensor_unhealthy() {
    use ::mavlink::dialects::common::{MavAutopilot, MavState, MavSysStatusSensor as S, MavType};
    let sensors = S::MAV_SYS_STATUS_SENSOR_3D_GYRO
        | S::MAV_SYS_STATUS_SENSOR_3D_ACCEL
        | S::MAV_SYS_STATUS_SENSOR_3D_MAG
        | S::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
        | S::MAV_SYS_STATUS_SENSOR_GPS
        | S::MAV_SYS_STATUS_PREARM_CHECK;
    // GIVEN a converged vehicle with a pack reading, whose own SYS_STATUS says the IMU, GPS and
    // pre-arm checks are healthy and reports the pack.
    let (mut v, mut t) = (truth_vehicle(), 0);
    let battery = BatterySample { voltage_v: 16.2, remaining: Some(0.9), ..BatterySample::default() };
    let mut stepped = Vec::new();
    while t < 2_000_000 {
        let inputs = VehicleInputs { battery: Some(battery), ..at_rest(t) };
        stepped.extend(v.step(t, &inputs).messages);
        t += DT_US;
    }
    let healthy = sys_status_of(&stepped).expect("SYS_STATUS at 1 Hz").clone();
    let checked = S::MAV_SYS_STATUS_SENSOR_3D_GYRO | S::MAV_SYS_STATUS_SENSOR_GPS | S::MAV_SYS_STATUS_PREARM_CHECK;
    assert!(healthy.onboard_control_sensors_health.contains(checked), "{healthy:?}");
    assert_eq!(healthy.voltage_battery, 16_200);
    v.set_link_errors(LinkErrors { malformed: 3, signing_rejected: 5 });
    // WHEN the plant is lost (no step comes) and the shell asks for the fallback.
    let lost = v.plant_lost_telemetry();
    // THEN a HEARTBEAT as usual but CRITICAL (disarmed), and a SYS_STATUS with every sensor present
    // and enabled but none healthy, the pack unknown.
    assert_eq!(lost.len(), 2, "{lost:?}");
    let MavMessage::HEARTBEAT(hb) = &lost[0] else { panic!("{lost:?}") };
    assert_eq!(
        (hb.mavtype, hb.autopilot, hb.mavlink_version),
        (MavType::MAV_TYPE_QUADROTOR, MavAutopilot::MAV_AUTOPILOT_PX4, 3)
    );
    assert_eq!(hb.custom_mode, HOLD);
    assert!(!hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    assert_eq!(hb.system_status, MavState::MAV_STATE_CRITICAL);
    let status = sys_status_of(&lost).expect("SYS_STATUS");
    assert!(status.onboard_control_sensors_present.contains(sensors));
    assert!(status.onboard_control_sensors_enabled.contains(sensors));
    assert!((status.onboard_control_sensors_health & sensors).is_empty(), "{status:?}");
    assert!(!status.onboard_control_sensors_present.contains(S::MAV_SYS_STATUS_SENSOR_BATTERY));
    assert_eq!((status.voltage_battery, status.current_battery, status.battery_remaining), (u16::MAX, -1, -1));
    assert_eq!((status.errors_comm, status.errors_count1), (3, 5));
    // No sample for the last second: the plant link's drop rate is 100 % (it read 0 while stepping).
    assert_eq!((healthy.drop_rate_comm, status.drop_rate_comm), (0, 10_000));
    // Asked again (the next wall second): the same.
    assert_eq!(v.plant_lost_telemetry(), lost);
    // WHEN armed and taking off, then the plant lost THEN EMERGENCY, armed, in TAKEOFF.
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, ARM, 1));
    v.handle_message(t, &GCS, &long(MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7], 1));
    run(&mut v, &mut t, 0.5);
    assert!(v.commander_output().armed);
    let lost = v.plant_lost_telemetry();
    let MavMessage::HEARTBEAT(hb) = &lost[0] else { panic!("{lost:?}") };
    assert_eq!(hb.system_status, MavState::MAV_STATE_EMERGENCY);
    assert!(hb.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED));
    assert_eq!(hb.custom_mode, TAKEOFF);
}

#[test]
fn given_sys_failure_en_1_when_a_gps_failure_is_injected_then_it_goes_to_the_plant_with_the_next_step_and_the_plants_ack_is_relayed()
 {
    // GIVEN SYS_FAILURE_EN = 0: DENIED at once, nothing for the plant.
    let mut v = truth_vehicle();
    let mut t = 0;
    run(&mut v, &mut t, 0.1);
    let inject = long(MavCmd::MAV_CMD_INJECT_FAILURE, [4.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    assert_eq!(
        ack_of(&v.handle_message(t, &GCS, &inject)),
        Some((MavCmd::MAV_CMD_INJECT_FAILURE, MavResult::MAV_RESULT_DENIED))
    );
    t += DT_US;
    assert!(v.step(t, &at_rest(t)).plant_messages.is_empty());
    // WHEN it is enabled and the injection comes again.
    let set = MavMessage::PARAM_SET(::mavlink::dialects::common::PARAM_SET_DATA {
        param_value: f32::from_bits(1),
        target_system: 1,
        target_component: 1,
        param_id: ::mavlink::types::CharArray::from("SYS_FAILURE_EN"),
        param_type: ::mavlink::dialects::common::MavParamType::MAV_PARAM_TYPE_INT32,
    });
    v.handle_message(t, &GCS, &set);
    assert!(v.params().failure_injection_enabled());
    assert!(ack_of(&v.handle_message(t, &GCS, &inject)).is_none(), "the answer is the plant's");
    // THEN the next step carries it to the plant, and the plant's ACK comes back as the vehicle's answer.
    t += DT_US;
    let out = v.step(t, &at_rest(t));
    assert!(
        matches!(out.plant_messages.as_slice(), [MavMessage::COMMAND_LONG(c)] if c.command == MavCmd::MAV_CMD_INJECT_FAILURE && c.param1 == 4.0 && c.param2 == 1.0)
    );
    t += DT_US;
    let ack = crate::core::plant_link::PlantCommandAck { command_id: 420, result: MavResult::MAV_RESULT_ACCEPTED };
    let out = v.step(t, &VehicleInputs { plant_ack: Some(ack), ..at_rest(t) });
    assert_eq!(ack_of(&out.messages), Some((MavCmd::MAV_CMD_INJECT_FAILURE, MavResult::MAV_RESULT_ACCEPTED)));
    assert!(out.plant_messages.is_empty());
}

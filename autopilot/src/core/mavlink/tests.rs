//! Unit tests of the pure MAVLink pieces: scheduling, addressing, command decoding and units.

use ::mavlink::dialects::common::{MavCmd, MavModeFlag};

use super::command::{px4_main_sub, takeoff_alt_rel_m};
use super::*;
use crate::core::commander::{FlightMode, Request};

const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

fn long(command: MavCmd, p: [f32; 7], target_system: u8, target_component: u8) -> MavMessage {
    command_long(target_system, target_component, command, p)
}

#[test]
fn given_a_10hz_stream_when_stepped_at_500hz_for_10s_then_100_emissions_without_drift() {
    let mut s = StreamScheduler::default();
    let times: Vec<u64> =
        (0..5000_u64).map(|i| i * 2000).filter(|&t| s.due(t).contains(&Stream::LocalPositionNed)).collect();
    assert_eq!(times.len(), 100);
    assert!(times.windows(2).all(|w| w[1] - w[0] == 100_000), "{times:?}");
}

#[test]
fn given_steps_that_fall_far_behind_when_due_then_one_emission_and_cadence_restarts() {
    assert_eq!(next_due_us(Some(1_000_000), 1_000_500, 1_000_000, false), 2_000_000);
    assert_eq!(next_due_us(Some(1_000_000), 5_000_000, 1_000_000, false), 6_000_000);
    assert_eq!(next_due_us(Some(1_000_000), 700_000, 1_000_000, true), 1_700_000);
    assert_eq!(next_due_us(None, 42, 1_000_000, false), 1_000_042);
}

#[test]
fn given_a_stream_turned_off_when_stepped_then_never_due() {
    let mut s = StreamScheduler::default();
    s.set_interval_us(Stream::VfrHud, 0);
    assert!((0..1000_u64).all(|i| !s.due(i * 2000).contains(&Stream::VfrHud)));
    assert_eq!(s.interval_us(Stream::Attitude), 50_000);
}

#[test]
fn given_targets_when_addressed_then_own_or_broadcast_system_and_component_0_or_1_accepted() {
    assert!(addressed_to_us(1, 1, 1));
    assert!(addressed_to_us(1, 1, 0));
    assert!(addressed_to_us(1, 0, 0));
    assert!(!addressed_to_us(1, 2, 1));
    assert!(!addressed_to_us(1, 1, 100));
}

#[test]
fn given_takeoff_altitudes_when_converted_then_nan_default_amsl_made_relative_low_values_relative() {
    let home = Some(488.0);
    assert_eq!(takeoff_alt_rel_m(f32::NAN, false, home), None);
    assert_eq!(takeoff_alt_rel_m(490.5, false, home), Some(2.5));
    assert_eq!(takeoff_alt_rel_m(1.5, false, home), Some(1.5));
    assert_eq!(takeoff_alt_rel_m(490.5, true, home), Some(490.5), "relative frame taken as given");
    assert_eq!(takeoff_alt_rel_m(3.0, false, None), Some(3.0), "no home: relative");
}

#[test]
fn given_custom_modes_when_split_then_px4_main_and_sub() {
    assert_eq!(px4_main_sub((4 << 16) | (3 << 24)), (4, 3));
    assert_eq!(px4_main_sub(3 << 16), (3, 0));
}

#[test]
fn given_do_set_mode_with_the_armed_bit_when_decoded_then_only_a_mode_request() {
    let ctx = CommandContext::default();
    let base =
        f32::from((MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED).bits());
    let msg = long(MavCmd::MAV_CMD_DO_SET_MODE, [base, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0], 1, 0);
    let cmd = decode_command(1, &GCS, &msg, &ctx).expect("for us");
    assert_eq!(cmd.effect, CommandEffect::Request(Request::SetMode(FlightMode::Hold)));
    assert_eq!((cmd.sender_system, cmd.sender_component), (255, 190));
    let no_custom = long(MavCmd::MAV_CMD_DO_SET_MODE, [128.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0], 1, 1);
    assert!(matches!(decode_command(1, &GCS, &no_custom, &ctx).map(|c| c.effect), Some(CommandEffect::Deny(_))));
}

#[test]
fn given_px4_modes_this_vehicle_does_not_fly_when_asked_then_refused_in_words() {
    let ctx = CommandContext::default();
    let base = f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits());
    for (main, sub, text) in
        [(9.0, 9.0, "Mode not supported: main 9 sub 9"), (4.0, 1.0, "Mode not supported: AUTO READY use Hold")]
    {
        let msg = long(MavCmd::MAV_CMD_DO_SET_MODE, [base, main, sub, 0.0, 0.0, 0.0, 0.0], 1, 0);
        let cmd = decode_command(1, &GCS, &msg, &ctx).expect("for us");
        assert_eq!(cmd.effect, CommandEffect::Deny(text.to_owned()));
        assert!(text.len() <= 50);
    }
}

#[test]
#[allow(deprecated)]
fn given_set_mode_message_when_decoded_then_same_request_as_do_set_mode() {
    let msg = MavMessage::SET_MODE(::mavlink::dialects::common::SET_MODE_DATA {
        custom_mode: (4 << 16) | (6 << 24),
        target_system: 1,
        base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
    });
    let cmd = decode_command(1, &GCS, &msg, &CommandContext::default()).expect("for us");
    assert_eq!(cmd.command, MavCmd::MAV_CMD_DO_SET_MODE);
    assert_eq!(cmd.effect, CommandEffect::Request(Request::SetMode(FlightMode::Land)));
}

#[test]
fn given_arm_disarm_params_when_decoded_then_arm_force_disarm_and_kill() {
    let ctx = CommandContext::default();
    let effect = |p1: f32, p2: f32| {
        let msg = long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [p1, p2, 0.0, 0.0, 0.0, 0.0, 0.0], 1, 1);
        decode_command(1, &GCS, &msg, &ctx).map(|c| c.effect)
    };
    assert_eq!(effect(1.0, 0.0), Some(CommandEffect::Request(Request::Arm { force: false })));
    assert_eq!(effect(1.0, 21196.0), Some(CommandEffect::Request(Request::Arm { force: true })));
    assert_eq!(effect(0.0, 0.0), Some(CommandEffect::Request(Request::Disarm { force: false })));
    assert_eq!(effect(0.0, 21196.0), Some(CommandEffect::Request(Request::Kill)));
    assert!(matches!(effect(0.5, 0.0), Some(CommandEffect::Deny(_))));
}

#[test]
fn given_a_long_refusal_when_sent_as_statustext_then_cut_to_50_bytes() {
    let MavMessage::STATUSTEXT(s) =
        statustext(::mavlink::dialects::common::MavSeverity::MAV_SEVERITY_INFO, &"é".repeat(40))
    else {
        panic!("not a STATUSTEXT");
    };
    assert_eq!(s.text.to_str().expect("utf-8").len(), 50);
}

/// The effect of a COMMAND_LONG `command` with params 1-7 sent to us.
fn effect_of(command: MavCmd, p: [f32; 7]) -> CommandEffect {
    decode_command(1, &GCS, &long(command, p, 1, 1), &CommandContext::default()).expect("for us").effect
}

fn run(motor: u8, thrust: f64, timeout_us: u64) -> CommandEffect {
    CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Run { motor, thrust, timeout_us }))
}

fn stop(motor: u8) -> CommandEffect {
    CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Stop { motor }))
}

#[test]
fn given_actuator_test_when_decoded_then_motor_value_and_timeout_as_px4_reads_them_capped_at_3_s() {
    let at = |value: f32, timeout_s: f32, function: f32| {
        effect_of(MavCmd::MAV_CMD_ACTUATOR_TEST, [value, timeout_s, 0.0, 0.0, function, 0.0, 0.0])
    };
    // ACTUATOR_OUTPUT_FUNCTION_MOTOR3 = 3 at 0.2 for 2 s.
    assert_eq!(at(0.2, 2.0, 3.0), run(3, f64::from(0.2_f32), 2_000_000));
    // The timeout is capped at PX4's 3 s; the value clamped to the output range.
    assert_eq!(at(1.5, 10.0, 1.0), run(1, 1.0, MOTOR_TEST_MAX_US));
    assert_eq!(at(0.0, 0.5, 4.0), run(4, 0.0, 500_000), "0: the output's minimum, running");
    // Stops: timeout 0 (PX4's release), value NaN or below 0 (a non-reversible motor's "off").
    assert_eq!(at(0.5, 0.0, 2.0), stop(2));
    assert_eq!(at(f32::NAN, 1.0, 2.0), stop(2));
    assert_eq!(at(-1.0, 1.0, 2.0), stop(2));
    // Motors 5-16 and servos: this vehicle has none (DENIED with a reason); anything else UNSUPPORTED.
    assert!(matches!(at(0.2, 1.0, 5.0), CommandEffect::Deny(t) if t.contains("no output function 5")));
    assert!(matches!(at(0.2, 1.0, 33.0), CommandEffect::Deny(_)));
    assert_eq!(at(0.2, 1.0, 0.0), CommandEffect::Unsupported);
    assert_eq!(at(0.2, 1.0, f32::NAN), CommandEffect::Unsupported);
}

#[test]
fn given_do_motor_test_when_decoded_then_percent_only_one_motor_and_0_percent_stops() {
    let mt = |motor: f32, kind: f32, pct: f32, timeout_s: f32, count: f32| {
        effect_of(MavCmd::MAV_CMD_DO_MOTOR_TEST, [motor, kind, pct, timeout_s, count, 0.0, 0.0])
    };
    assert_eq!(mt(3.0, 0.0, 20.0, 2.0, 0.0), run(3, 0.2, 2_000_000));
    assert_eq!(mt(1.0, 0.0, 150.0, 0.0, 1.0), run(1, 1.0, MOTOR_TEST_MAX_US), "timeout 0: PX4's 3 s");
    assert_eq!(mt(2.0, 0.0, 0.0, 2.0, 0.0), stop(2), "0 %: stop");
    assert_eq!(mt(2.0, 1.0, 1500.0, 2.0, 0.0), CommandEffect::Unsupported, "PWM throttle");
    assert_eq!(mt(2.0, 2.0, 50.0, 2.0, 0.0), CommandEffect::Unsupported, "pilot passthrough");
    assert_eq!(mt(2.0, 0.0, 50.0, 2.0, 4.0), CommandEffect::Unsupported, "a sequence of motors");
    assert!(matches!(mt(5.0, 0.0, 20.0, 2.0, 0.0), CommandEffect::Deny(t) if t.contains("no motor 5")));
    assert!(matches!(mt(0.0, 0.0, 20.0, 2.0, 0.0), CommandEffect::Deny(_)));
}

proptest::proptest! {
    /// Any parameters decode, without a panic, into a refusal or a test within limits: motor 1-4, thrust
    /// in [0, 1] (so PWM 1000-2000 µs, never NaN), timeout 1 ms-3 s.
    #[test]
    fn any_motor_test_params_decode_to_a_refusal_or_a_test_within_limits(
        actuator in proptest::bool::ANY,
        p in proptest::array::uniform7(proptest::num::f32::ANY),
    ) {
        let command = if actuator { MavCmd::MAV_CMD_ACTUATOR_TEST } else { MavCmd::MAV_CMD_DO_MOTOR_TEST };
        match effect_of(command, p) {
            CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Run { motor, thrust, timeout_us })) => {
                proptest::prop_assert!((1..=MOTOR_COUNT).contains(&motor));
                proptest::prop_assert!((0.0..=1.0).contains(&thrust), "{}", thrust);
                proptest::prop_assert!((1_000..=MOTOR_TEST_MAX_US).contains(&timeout_us), "{}", timeout_us);
            }
            CommandEffect::Vehicle(VehicleCommand::MotorTest(MotorTestRequest::Stop { motor })) => {
                proptest::prop_assert!((1..=MOTOR_COUNT).contains(&motor));
            }
            CommandEffect::Deny(text) => proptest::prop_assert!(!text.is_empty()),
            CommandEffect::Unsupported => {}
            other => proptest::prop_assert!(false, "{:?}", other),
        }
    }
}

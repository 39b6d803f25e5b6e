//! The motor test (MAV_CMD_DO_MOTOR_TEST, MAV_CMD_ACTUATOR_TEST) flown in lockstep with the real plant
//! (`sitl::plant`) at 500 Hz, as a ground station sends it: one motor spins on the disarmed vehicle for its
//! time and stops, and the refusals (armed, COM_MOT_TEST_EN 0) are said in STATUSTEXT. The plant's rotors
//! follow the paper's Eq 10, which has lift even at 1000 µs (11.28 N): a rotor "spins" on the truth when its
//! lift rises to that of the test's PWM. Pure simulated time: no sleeps.

use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::{MavCmd, MavMessage, MavResult};
use sitl::plant::rotor::lift_from_pwm_n;
use tests::rig::{DT_US, Rig};

/// The steady lift (N) of rotor `i` of the rig's plant at `pwm_us`.
fn steady_lift_n(rig: &Rig, i: usize, pwm_us: f64) -> f64 {
    let a = &rig.plant.config().airframe;
    a.thrust_scale * a.rotor_health[i] * lift_from_pwm_n(pwm_us)
}

/// The ACK result and the STATUSTEXTs of the replies to a COMMAND_LONG.
fn command(rig: &mut Rig, command: MavCmd, params: [f32; 7]) -> (MavResult, Vec<String>) {
    let replies = rig.send(&autopilot::core::mavlink::command_long(1, 1, command, params));
    let result = match replies.first() {
        Some(MavMessage::COMMAND_ACK(a)) if a.command == command => a.result,
        other => panic!("no ACK for {command:?}: {other:?}"),
    };
    let texts = replies
        .iter()
        .filter_map(|m| match m {
            MavMessage::STATUSTEXT(s) => Some(s.text.to_str().unwrap_or("").to_owned()),
            _ => None,
        })
        .collect();
    (result, texts)
}

/// DO_MOTOR_TEST: motor (1-based), throttle type 0 (percent), `pct` %, `timeout_s`, one motor.
fn do_motor_test(rig: &mut Rig, motor: f32, pct: f32, timeout_s: f32) -> (MavResult, Vec<String>) {
    command(rig, MavCmd::MAV_CMD_DO_MOTOR_TEST, [motor, 0.0, pct, timeout_s, 0.0, 0.0, 0.0])
}

/// A disarmed vehicle on the ground whose rotors have settled at 1000 µs.
fn settled() -> Rig {
    let mut rig = Rig::new(EstimatorSource::Truth);
    rig.run_s(1.0, |_| {});
    rig
}

#[test]
fn given_disarmed_when_motor_3_tested_at_20_percent_for_2_s_then_only_rotor_3_lifts_within_0_1_percent_and_stops_within_one_tick()
 {
    let mut rig = settled();
    let idle_n: Vec<f64> = (0..4).map(|i| steady_lift_n(&rig, i, 1000.0)).collect();
    let test_n = steady_lift_n(&rig, 2, 1200.0);
    // WHEN the ground station tests motor 3 (the paper's front rotor) at 20 % for 2 s.
    let start_us = rig.now_us;
    assert_eq!(do_motor_test(&mut rig, 3.0, 20.0, 2.0), (MavResult::MAV_RESULT_ACCEPTED, Vec::new()));
    // THEN the plant is told 1200 µs on output 3 only, for 2 s of vehicle time (to the tick), and 1000 µs
    // on the others throughout.
    let (mut first_us, mut last_us, mut peak_n) = (None, None, [0.0_f64; 4]);
    rig.run_s(3.0, |r| {
        let pwm = r.plant.last_pwm_us();
        if pwm[2] > 1000.0 {
            assert!((pwm[2] - 1200.0).abs() < 1e-9, "{pwm:?}");
            first_us.get_or_insert(r.now_us);
            last_us = Some(r.now_us);
        }
        assert!(pwm[0] == 1000.0 && pwm[1] == 1000.0 && pwm[3] == 1000.0, "{pwm:?}");
        for (p, f) in peak_n.iter_mut().zip(r.plant.truth().rotor_lift_n) {
            *p = p.max(f);
        }
    });
    let (first_us, last_us) = (first_us.expect("motor 3 ran"), last_us.expect("motor 3 ran"));
    let ran_us = last_us + DT_US - first_us;
    eprintln!(
        "motor 3 at 1200 µs for {ran_us} µs from {} µs after the command; peak lifts {peak_n:?} N (1200 µs: \
         {test_n} N, 1000 µs: {idle_n:?} N)",
        first_us - start_us
    );
    assert!(ran_us.abs_diff(2_000_000) <= DT_US, "ran {ran_us} µs");
    assert!(first_us - start_us <= DT_US, "started {} µs after the command", first_us - start_us);
    // AND on the truth rotor 3 reached the lift of 1200 µs (its lag settled in 2 s) while the others
    // stayed at the lift of 1000 µs.
    assert!((peak_n[2] - test_n).abs() <= 1e-3 * test_n, "rotor 3 peak {} N vs {test_n} N", peak_n[2]);
    for i in [0, 1, 3] {
        assert!((peak_n[i] - idle_n[i]).abs() <= 1e-3 * idle_n[i], "rotor {} peak {} N", i + 1, peak_n[i]);
    }
    // AND a second later it is back at the idle lift, the vehicle still disarmed on the ground.
    let lift_3 = rig.plant.truth().rotor_lift_n[2];
    assert!((lift_3 - idle_n[2]).abs() <= 1e-3 * idle_n[2], "rotor 3 after the test {lift_3} N");
    assert!(!rig.armed() && !rig.vehicle.motor_test_running());
}

#[test]
fn given_a_motor_test_running_when_armed_then_the_test_ends_on_the_next_tick() {
    let mut rig = settled();
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    assert_eq!(do_motor_test(&mut rig, 1.0, 50.0, 3.0).0, MavResult::MAV_RESULT_ACCEPTED);
    rig.run_s(0.2, |_| {});
    assert!(rig.vehicle.motor_test_running());
    assert_eq!(
        command(&mut rig, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).0,
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.tick();
    assert!(!rig.vehicle.motor_test_running());
    assert_ne!(rig.plant.last_pwm_us()[0], 1500.0, "the controller's PWM, not the test's");
}

#[test]
fn given_a_motor_test_running_when_a_disarm_kill_or_termination_is_sent_then_every_motor_is_at_1000_us_on_the_next_tick_and_killed_refuses_more()
 {
    for (stop, params) in [
        (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]),
        (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (MavCmd::MAV_CMD_DO_FLIGHTTERMINATION, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
    ] {
        let mut rig = settled();
        assert_eq!(do_motor_test(&mut rig, 2.0, 60.0, 3.0).0, MavResult::MAV_RESULT_ACCEPTED);
        rig.run_s(0.2, |_| {});
        assert!(rig.plant.last_pwm_us()[1] > 1500.0);
        let _ = command(&mut rig, stop, params);
        rig.tick();
        assert_eq!(rig.plant.last_pwm_us(), [1000.0; 4], "{stop:?} {params:?}");
        assert!(!rig.vehicle.motor_test_running());
        // AND after a kill or termination no new test is accepted; after a disarm one is.
        let killed = rig.vehicle.commander().state() == autopilot::core::commander::State::Killed;
        assert_eq!(killed, params != [0.0; 7], "{stop:?} {params:?}");
        let again = do_motor_test(&mut rig, 2.0, 60.0, 3.0);
        if killed {
            assert_eq!(again, (MavResult::MAV_RESULT_DENIED, vec!["Motor test denied: killed".to_owned()]));
        } else {
            assert_eq!(again.0, MavResult::MAV_RESULT_ACCEPTED);
        }
    }
}

#[test]
fn given_armed_when_a_motor_test_is_sent_then_denied_with_the_statustext_and_no_rotor_changes() {
    let mut rig = settled();
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    assert_eq!(
        command(&mut rig, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).0,
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.run_s(0.1, |_| {});
    for cmd in [
        (MavCmd::MAV_CMD_DO_MOTOR_TEST, [3.0, 0.0, 20.0, 2.0, 0.0, 0.0, 0.0]),
        (MavCmd::MAV_CMD_ACTUATOR_TEST, [0.2, 2.0, 0.0, 0.0, 3.0, 0.0, 0.0]),
    ] {
        let (result, texts) = command(&mut rig, cmd.0, cmd.1);
        assert_eq!(result, MavResult::MAV_RESULT_DENIED);
        assert_eq!(texts, ["Motor test denied: armed"]);
    }
    rig.tick();
    assert!(!rig.vehicle.motor_test_running());
}

#[test]
fn given_com_mot_test_en_0_when_a_motor_test_is_sent_then_denied_with_the_statustext_and_every_rotor_stays_at_1000_us()
{
    let mut rig = settled();
    rig.set_param("COM_MOT_TEST_EN", 0.0);
    let (result, texts) = command(&mut rig, MavCmd::MAV_CMD_ACTUATOR_TEST, [0.2, 2.0, 0.0, 0.0, 3.0, 0.0, 0.0]);
    assert_eq!(result, MavResult::MAV_RESULT_DENIED);
    assert_eq!(texts, ["Motor test denied: disabled"]);
    rig.run_s(1.0, |r| assert_eq!(r.plant.last_pwm_us(), [1000.0; 4]));
}

//! The whole vehicle core in flight, in lockstep with the real plant (the test rig, `tests::rig`), fed
//! any sequence of ground-station messages (commands with any parameters, modes, offboard setpoints,
//! parameter and mission traffic, any message of the dialect) with time passing between them. Each
//! input starts from the same hover 3 m over home. Nothing panics; after every tick the motor commands
//! are finite and in range and the estimate and reference finite; and the vehicle never arms without an
//! ARM command.
#![no_main]

use aco_fuzz::{GcsMessage, check_vehicle};
use arbitrary::Arbitrary;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::mavlink::common::MavCmd;
use libfuzzer_sys::fuzz_target;
use tests::rig::Rig;

/// A rig hovering 3 m over home: estimator up, a takeoff to 3 m, 4 s to climb.
fn hover() -> Rig {
    let mut rig = Rig::new(EstimatorSource::Truth);
    rig.wait_until(10.0, "estimator", |r| r.vehicle.estimate().flags.converged && r.vehicle.home().is_some());
    let nan = f32::NAN;
    rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 3.0]);
    rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    rig.run_s(4.0, |_| {});
    assert!(rig.armed(), "the hover every input starts from is armed");
    rig
}

#[derive(Debug, Arbitrary)]
struct Step {
    /// Ticks (2 ms) after the message.
    ticks: u8,
    message: GcsMessage,
}

fuzz_target!(|steps: Vec<Step>| {
    let mut rig = hover();
    let mut arm_allowed = false;
    for step in steps.iter().take(48) {
        arm_allowed |= step.message.is_arm();
        let _replies = rig.send(&step.message.to_message());
        for _ in 0..step.ticks {
            let was_armed = rig.vehicle.commander().armed();
            rig.tick();
            let armed = rig.vehicle.commander().armed();
            assert!(was_armed || !armed || arm_allowed, "armed without an ARM command");
            check_vehicle(&rig.vehicle);
            if !armed {
                arm_allowed = false;
            }
        }
        rig.messages.clear();
    }
});

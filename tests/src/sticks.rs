//! Flying by hand in lockstep tests: MANUAL_CONTROL streamed at 50 Hz as QGroundControl's joystick, the
//! mode and arming commands, the truth's attitude, and a vehicle armed and climbed by the sticks.

use autopilot::core::control::ControllerKind;
use autopilot::core::estimator::EstimatorSource;
use autopilot::core::manual::Sticks;
use autopilot::core::mavlink::common::{MANUAL_CONTROL_DATA, MavCmd, MavMessage, MavResult};
use nalgebra::Vector3;
use sitl::plant::{PlantConfig, SensorConfig};

use crate::rig::{DT_US, Rig};

/// MANUAL_CONTROL every 20 ms (50 Hz), as QGroundControl's joystick.
pub const STICK_PERIOD_US: u64 = 20_000;

pub fn manual_control(s: &Sticks) -> MavMessage {
    let (x, y, z, r) = s.to_manual_control();
    MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA { target: 1, x, y, z, r, ..MANUAL_CONTROL_DATA::default() })
}

/// Ticks for `seconds`, streaming `sticks` (None: silent) at 50 Hz, calling `each` after every tick.
pub fn fly(rig: &mut Rig, seconds: f64, sticks: Option<Sticks>, mut each: impl FnMut(&Rig)) {
    let end = rig.now_us + (seconds * 1e6) as u64;
    while rig.now_us < end {
        if let Some(s) = sticks
            && rig.now_us % STICK_PERIOD_US < DT_US
        {
            rig.send(&manual_control(&s));
        }
        rig.tick();
        each(rig);
    }
}

pub fn texts(rig: &mut Rig) -> Vec<(u64, String)> {
    rig.take_messages()
        .into_iter()
        .filter_map(|(t, m)| match m {
            MavMessage::STATUSTEXT(s) => Some((t, s.text.to_str().unwrap_or("").to_owned())),
            _ => None,
        })
        .collect()
}

pub fn said(rig: &mut Rig, text: &str) -> Vec<u64> {
    texts(rig).into_iter().filter(|(_, t)| t == text).map(|(t, _)| t).collect()
}

/// A command refused (not ACCEPTED), its reason said in a STATUSTEXT with the ACK.
pub fn refused_in_words(rig: &mut Rig, command: MavCmd, params: [f32; 7], text: &str) {
    let replies = rig.send(&autopilot::core::mavlink::command_long(1, 1, command, params));
    assert!(
        replies.iter().any(|m| matches!(m, MavMessage::COMMAND_ACK(a) if a.result != MavResult::MAV_RESULT_ACCEPTED)),
        "{replies:?}"
    );
    assert!(
        replies.iter().any(|m| matches!(m, MavMessage::STATUSTEXT(s) if s.text.to_str().is_ok_and(|t| t == text))),
        "{text}: {replies:?}"
    );
}

pub fn set_mode(rig: &mut Rig, main: f32) -> MavResult {
    rig.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, main, 0.0, 0.0, 0.0, 0.0, 0.0])
}

pub fn centre() -> Sticks {
    Sticks::default()
}

pub fn euler_truth(rig: &Rig) -> Vector3<f64> {
    let (r, p, y) = rig.plant.truth().q_ned_frd.euler_angles();
    Vector3::new(r, p, y)
}

pub fn converged_with(kind: ControllerKind) -> Rig {
    let plant = PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() };
    let mut rig = Rig::with(plant, EstimatorSource::Fused, |vc| vc.controller = kind);
    rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig
}

pub fn hovering_by_hand_with(kind: ControllerKind, main: f32) -> Rig {
    let mut rig = converged_with(kind);
    fly(&mut rig, 0.2, Some(centre()), |_| {});
    assert_eq!(set_mode(&mut rig, main), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let ground_d = rig.plant.truth().pos_ned_m.z;
    let up = Sticks { throttle: 1.0, ..centre() };
    let mut climbed = 0.0;
    let end = rig.now_us + 20_000_000;
    while climbed < 4.5 {
        assert!(rig.now_us < end, "did not climb with the throttle stick");
        fly(&mut rig, 0.1, Some(up), |_| {});
        climbed = ground_d - rig.plant.truth().pos_ned_m.z;
    }
    fly(&mut rig, 6.0, Some(centre()), |_| {});
    rig
}

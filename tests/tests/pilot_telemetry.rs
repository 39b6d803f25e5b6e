//! The pilot's input as a ground station sees it, flown in lockstep with the real plant at 500 Hz with the
//! rig's radio (RC_CHANNELS from the board every tick): the RC_CHANNELS stream (PX4's 5 Hz on a normal
//! link, none before the first frame), SYS_STATUS's RC receiver bits, and the stream's rate and one-shot
//! request by SET_MESSAGE_INTERVAL and REQUEST_MESSAGE. Pure simulated time: no sleeps.

use autopilot::core::estimator::EstimatorSource;
use autopilot::core::manual::RcFrame;
use autopilot::core::mavlink::common::{
    MavCmd, MavMessage, MavResult, MavSysStatusSensor, RC_CHANNELS_DATA, SYS_STATUS_DATA,
};
use tests::rig::Rig;

const RC_CHANNELS_ID: f32 = 65.0;

fn rc_channels(messages: &[(u64, MavMessage)]) -> Vec<RC_CHANNELS_DATA> {
    messages
        .iter()
        .filter_map(|(_, m)| match m {
            MavMessage::RC_CHANNELS(r) => Some(r.clone()),
            _ => None,
        })
        .collect()
}

fn last_sys_status(messages: &[(u64, MavMessage)]) -> SYS_STATUS_DATA {
    messages
        .iter()
        .rev()
        .find_map(|(_, m)| match m {
            MavMessage::SYS_STATUS(s) => Some(s.clone()),
            _ => None,
        })
        .expect("SYS_STATUS at 1 Hz")
}

#[test]
fn given_a_radio_when_streamed_then_rc_channels_at_5_hz_within_one_and_sys_status_shows_the_receiver_healthy_until_lost()
 {
    const RC: MavSysStatusSensor = MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_RC_RECEIVER;
    let mut rig = Rig::new(EstimatorSource::Truth);
    // GIVEN no radio ever: no RC_CHANNELS, the receiver not present, a request for it DENIED.
    rig.run_s(2.0, |_| {});
    let messages = rig.take_messages();
    assert!(rc_channels(&messages).is_empty());
    assert!(!last_sys_status(&messages).onboard_control_sensors_present.intersects(RC));
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_REQUEST_MESSAGE, [RC_CHANNELS_ID, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_DENIED
    );
    // WHEN the board's receiver sends 8 channels with RSSI 200 every tick for 2 s.
    let mut frame = RcFrame::of(&[1500, 1500, 1000, 1500, 1000, 2000, 1000, 1000]);
    frame.rssi = 200;
    rig.rc = Some(frame);
    rig.run_s(2.0, |_| {});
    let messages = rig.take_messages();
    // THEN RC_CHANNELS at 5 Hz (10 in 2 s, within one), as PX4 fills it: the frame's channels and count,
    // UINT16_MAX beyond it, its RSSI.
    let rc = rc_channels(&messages);
    eprintln!("{} RC_CHANNELS in 2 s at the default rate", rc.len());
    assert!(rc.len().abs_diff(10) <= 1, "{} RC_CHANNELS in 2 s", rc.len());
    let last = rc.last().expect("one");
    assert_eq!((last.chancount, last.rssi), (8, 200));
    assert_eq!(
        [last.chan1_raw, last.chan3_raw, last.chan6_raw, last.chan8_raw, last.chan9_raw, last.chan18_raw],
        [1500, 1000, 2000, 1000, u16::MAX, u16::MAX]
    );
    // AND SYS_STATUS shows the receiver present, enabled and healthy.
    let status = last_sys_status(&messages);
    assert!(status.onboard_control_sensors_present.contains(RC));
    assert!(status.onboard_control_sensors_enabled.contains(RC));
    assert!(status.onboard_control_sensors_health.contains(RC));
    // AND SET_MESSAGE_INTERVAL sets its rate (50 Hz: 50 in 1 s, within one); REQUEST_MESSAGE sends one now.
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, [RC_CHANNELS_ID, 20_000.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.run_s(1.0, |_| {});
    let n = rc_channels(&rig.take_messages()).len();
    eprintln!("{n} RC_CHANNELS in 1 s at 50 Hz");
    assert!(n.abs_diff(50) <= 1, "{n} RC_CHANNELS in 1 s at 50 Hz");
    let replies = rig.send(&autopilot::core::mavlink::command_long(
        1,
        1,
        MavCmd::MAV_CMD_REQUEST_MESSAGE,
        [RC_CHANNELS_ID, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ));
    assert!(matches!(replies.first(), Some(MavMessage::COMMAND_ACK(a)) if a.result == MavResult::MAV_RESULT_ACCEPTED));
    assert!(matches!(replies.get(1), Some(MavMessage::RC_CHANNELS(r)) if r.chancount == 8));
    // WHEN the radio goes silent for 1 s (COM_RC_LOSS_T 0.5 s).
    rig.rc = None;
    rig.run_s(1.0, |_| {});
    let messages = rig.take_messages();
    // THEN the receiver stays present but unhealthy, and RC_CHANNELS repeats the last frame with RSSI 0.
    let status = last_sys_status(&messages);
    assert!(status.onboard_control_sensors_present.contains(RC));
    assert!(!status.onboard_control_sensors_health.intersects(RC));
    assert_eq!(rc_channels(&messages).last().map(|r| r.rssi), Some(0));
}

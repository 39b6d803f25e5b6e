//! The pilot's input from ground stations: MANUAL_CONTROL (a joystick: QGroundControl's joystick and
//! virtual sticks, MAVSDK's ManualControl) and RC_CHANNELS_OVERRIDE (a radio: MAVProxy's `rc`), taken only
//! when addressed to this system. In: the message. Out: a [`ManualControlInput`] for the vehicle's manual
//! input, nothing to send back. RC_CHANNELS_OVERRIDE is cumulative, as the protocol defines it: channels
//! 1-8 at `u16::MAX` and 9-18 at 0 or `u16::MAX` keep their last override, 0 (1-8) or `u16::MAX - 1` (9-18)
//! release the channel.

use ::mavlink::dialects::common::{MANUAL_CONTROL_DATA, MavMessage, RC_CHANNELS_OVERRIDE_DATA};

use super::router::{MessageContext, Microservice, ServiceReply};
use crate::core::manual::{RC_CHANNELS_MAX, RcFrame, Sticks};

/// What a ground station's manual control gives the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ManualControlInput {
    /// MANUAL_CONTROL's sticks.
    Joystick(Sticks),
    /// The radio as overridden so far.
    Rc(RcFrame),
}

/// The manual-control service: the overridden channels so far.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ManualControlService {
    override_us: [u16; RC_CHANNELS_MAX],
}

impl ManualControlService {
    fn apply_override(&mut self, m: &RC_CHANNELS_OVERRIDE_DATA) -> RcFrame {
        let first8 =
            [m.chan1_raw, m.chan2_raw, m.chan3_raw, m.chan4_raw, m.chan5_raw, m.chan6_raw, m.chan7_raw, m.chan8_raw];
        let rest = [
            m.chan9_raw,
            m.chan10_raw,
            m.chan11_raw,
            m.chan12_raw,
            m.chan13_raw,
            m.chan14_raw,
            m.chan15_raw,
            m.chan16_raw,
            m.chan17_raw,
            m.chan18_raw,
        ];
        for (slot, v) in self.override_us.iter_mut().zip(first8) {
            match v {
                u16::MAX => {}
                v => *slot = v,
            }
        }
        for (slot, v) in self.override_us[8..].iter_mut().zip(rest) {
            match v {
                0 | u16::MAX => {}
                v if v == u16::MAX - 1 => *slot = 0,
                v => *slot = v,
            }
        }
        let count = self.override_us.iter().rposition(|&v| v != 0).map_or(0, |i| i + 1);
        RcFrame { channels_us: self.override_us, count: count as u8, rssi: u8::MAX }
    }
}

impl Microservice for ManualControlService {
    type State = ();
    type Effect = ManualControlInput;

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, (): &mut ()) -> ServiceReply<ManualControlInput> {
        let effect = match msg {
            MavMessage::MANUAL_CONTROL(m) if m.target == ctx.sysid => Some(joystick(m)),
            MavMessage::RC_CHANNELS_OVERRIDE(m) if m.target_system == ctx.sysid => {
                Some(ManualControlInput::Rc(self.apply_override(m)))
            }
            _ => None,
        };
        ServiceReply { messages: Vec::new(), effect }
    }
}

fn joystick(m: &MANUAL_CONTROL_DATA) -> ManualControlInput {
    ManualControlInput::Joystick(Sticks::from_manual_control(m.x, m.y, m.z, m.r))
}

#[cfg(test)]
mod tests {
    use ::mavlink::MavHeader;
    use proptest::prelude::*;

    use super::*;
    use crate::core::mavlink::command::CommandContext;
    use crate::core::mavlink::offboard::OffboardContext;

    fn handle(s: &mut ManualControlService, msg: &MavMessage) -> Option<ManualControlInput> {
        let header = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        let ctx = MessageContext {
            now_us: 0,
            sysid: 1,
            header: &header,
            command: CommandContext { home_alt_amsl_m: None },
            offboard: OffboardContext { origin: None, home_alt_amsl_m: None, yaw_rad: 0.0 },
        };
        s.handle(&ctx, msg, &mut ()).effect
    }

    fn manual(target: u8, x: i16, z: i16) -> MavMessage {
        MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA { target, x, z, ..MANUAL_CONTROL_DATA::default() })
    }

    #[test]
    fn manual_control_for_another_system_is_ignored() {
        let mut s = ManualControlService::default();
        assert_eq!(handle(&mut s, &manual(2, 1000, 500)), None);
        let Some(ManualControlInput::Joystick(sticks)) = handle(&mut s, &manual(1, 1000, 500)) else { panic!() };
        assert_eq!((sticks.pitch, sticks.throttle), (1.0, 0.5));
    }

    #[test]
    fn overrides_accumulate_and_release_as_the_protocol_says() {
        let mut s = ManualControlService::default();
        let mut m = RC_CHANNELS_OVERRIDE_DATA {
            target_system: 1,
            chan1_raw: 1500,
            chan2_raw: 1500,
            chan3_raw: 1000,
            chan4_raw: 1500,
            chan5_raw: u16::MAX,
            chan6_raw: u16::MAX,
            chan7_raw: u16::MAX,
            chan8_raw: u16::MAX,
            ..RC_CHANNELS_OVERRIDE_DATA::default()
        };
        let Some(ManualControlInput::Rc(f)) = handle(&mut s, &MavMessage::RC_CHANNELS_OVERRIDE(m.clone())) else {
            panic!()
        };
        assert_eq!((f.count, f.channels_us[2]), (4, 1000));
        // MAVProxy's `rc 3 1600`: one channel set, the others ignored (kept).
        m = RC_CHANNELS_OVERRIDE_DATA {
            target_system: 1,
            chan1_raw: u16::MAX,
            chan2_raw: u16::MAX,
            chan3_raw: 1600,
            chan4_raw: u16::MAX,
            chan5_raw: u16::MAX,
            chan6_raw: u16::MAX,
            chan7_raw: u16::MAX,
            chan8_raw: u16::MAX,
            chan12_raw: 1900,
            ..RC_CHANNELS_OVERRIDE_DATA::default()
        };
        let Some(ManualControlInput::Rc(f)) = handle(&mut s, &MavMessage::RC_CHANNELS_OVERRIDE(m.clone())) else {
            panic!()
        };
        assert_eq!(&f.channels_us[..4], &[1500, 1500, 1600, 1500]);
        assert_eq!((f.count, f.channels_us[11]), (12, 1900));
        m.chan3_raw = 0;
        m.chan12_raw = u16::MAX - 1;
        let Some(ManualControlInput::Rc(f)) = handle(&mut s, &MavMessage::RC_CHANNELS_OVERRIDE(m)) else { panic!() };
        assert_eq!((f.count, f.channels_us[2]), (4, 0));
    }

    proptest! {
        /// Any MANUAL_CONTROL gives sticks in range (never NaN, never out of [-1, 1] / [0, 1]).
        #[test]
        fn any_manual_control_gives_sticks_in_range(x in any::<i16>(), y in any::<i16>(), z in any::<i16>(), r in any::<i16>()) {
            let mut s = ManualControlService::default();
            let msg = MavMessage::MANUAL_CONTROL(MANUAL_CONTROL_DATA { target: 1, x, y, z, r, ..MANUAL_CONTROL_DATA::default() });
            let Some(ManualControlInput::Joystick(st)) = handle(&mut s, &msg) else { panic!() };
            for v in [st.roll, st.pitch, st.yaw] {
                prop_assert!((-1.0..=1.0).contains(&v));
            }
            prop_assert!((0.0..=1.0).contains(&st.throttle));
        }
    }
}

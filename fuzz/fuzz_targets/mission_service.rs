//! The mission protocol service (`core::mavlink::mission::MissionService`, transferring into the plan store
//! `core::plan::Plan`) on any sequence of mission messages (the three plans, uploads, downloads, acks,
//! clears, any counts and sequence numbers) from two ground stations, with time passing between them.
//! Nothing panics; no plan grows past the item cap (a bigger count gets MAV_MISSION_NO_SPACE); every reply
//! is addressed to a ground station that spoke; and once the sender falls silent, any upload under way
//! times out: the service never waits forever.
#![no_main]

use aco_fuzz::{MissionMessage, SYSID};
use arbitrary::Arbitrary;
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::common::{MavMessage, MavMissionResult};
use autopilot::core::mavlink::mission::{MissionService, MissionServiceConfig, PlanKind};
use autopilot::core::plan::Plan;
use libfuzzer_sys::fuzz_target;

/// A small cap, so that the fuzzer reaches it.
const MAX_ITEMS: u16 = 12;

#[derive(Debug, Arbitrary)]
struct Step {
    /// Vehicle time before the message, in ms.
    wait_ms: u16,
    /// Which of two ground stations sends it.
    second_gcs: bool,
    message: MissionMessage,
}

// MISSION_ITEM and MISSION_REQUEST are deprecated, but older ground stations send them: they are answered.
#[allow(deprecated)]
fn target_of(msg: &MavMessage) -> Option<(u8, u8)> {
    match msg {
        MavMessage::MISSION_REQUEST_INT(m) => Some((m.target_system, m.target_component)),
        MavMessage::MISSION_REQUEST(m) => Some((m.target_system, m.target_component)),
        MavMessage::MISSION_ITEM_INT(m) => Some((m.target_system, m.target_component)),
        MavMessage::MISSION_ITEM(m) => Some((m.target_system, m.target_component)),
        MavMessage::MISSION_COUNT(m) => Some((m.target_system, m.target_component)),
        MavMessage::MISSION_ACK(m) => Some((m.target_system, m.target_component)),
        _ => None,
    }
}

fuzz_target!(|steps: Vec<Step>| {
    let config = MissionServiceConfig { max_items: MAX_ITEMS, ..MissionServiceConfig::default() };
    let mut svc = MissionService::new(config);
    let mut plan = Plan::default();
    let gcs = [
        MavHeader { system_id: 255, component_id: 190, sequence: 0 },
        MavHeader { system_id: 254, component_id: 1, sequence: 0 },
    ];
    let mut now_us: u64 = 1_000_000;
    for step in steps.iter().take(256) {
        now_us += u64::from(step.wait_ms) * 1000;
        let mut replies = svc.poll(now_us).messages;
        let from = &gcs[usize::from(step.second_gcs)];
        let msg = step.message.to_message();
        let reply = svc.on_message(&mut plan, now_us, SYSID, from, &msg);
        replies.extend(reply.messages);
        for r in &replies {
            if let Some((system, component)) = target_of(r) {
                assert!(
                    gcs.iter().any(|g| u32::from(system) == g.system_id && component == g.component_id),
                    "reply to nobody: {r:?}"
                );
            }
        }
        // (A count for another plan type, MAV_MISSION_TYPE_ALL for one, is UNSUPPORTED instead.)
        if let MavMessage::MISSION_COUNT(c) = &msg
            && c.count > MAX_ITEMS
            && PlanKind::of(c.mission_type).is_some()
        {
            let no_space = replies.iter().any(
                |r| matches!(r, MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_NO_SPACE),
            );
            assert!(no_space, "a count of {} above the cap is not NO_SPACE: {replies:?}", c.count);
        }
        assert!(plan.mission().len() <= usize::from(MAX_ITEMS), "mission of {} items", plan.mission().len());
    }
    // Silence: retries run out and the upload ends.
    for _ in 0..100 {
        now_us += 1_000_000;
        let _ = svc.poll(now_us);
    }
    assert!(!svc.upload_in_progress(), "an upload still waits after 100 s of silence");
});

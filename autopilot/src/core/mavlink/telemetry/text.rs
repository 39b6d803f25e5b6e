//! What the ground station reads as text: STATUSTEXT (cut to 50 bytes, or in MAVLink 2 chunks) and the
//! messages of the navigator's, the estimator's, the plant link's and the commander's events.

use ::mavlink::dialects::common::{MISSION_ITEM_REACHED_DATA, MavMessage, MavSeverity, STATUSTEXT_DATA};

use super::mission_current;
use crate::core::commander::Event;
use crate::core::estimator::{EstimatorEvent, EventSeverity};
use crate::core::navigator::NavEvent;
use crate::core::plant_link::health::PlantLinkEvent;

/// What the ground station hears of a navigator event: MISSION_CURRENT, MISSION_ITEM_REACHED, or an INFO
/// STATUSTEXT.
#[must_use]
pub fn nav_event_message(event: &NavEvent) -> MavMessage {
    match event {
        NavEvent::Current(seq) => mission_current(*seq),
        NavEvent::Reached(seq) => MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA { seq: *seq }),
        NavEvent::Text(text) => statustext(MavSeverity::MAV_SEVERITY_INFO, text),
    }
}

/// What the ground station hears of an estimator event (a source lost, stuck, rejected or regained): a
/// STATUSTEXT, WARNING for a lost aiding source, CRITICAL for the IMU, INFO when a source is back.
#[must_use]
pub fn estimator_event_message(event: &EstimatorEvent) -> MavMessage {
    let severity = match event.severity() {
        EventSeverity::Info => MavSeverity::MAV_SEVERITY_INFO,
        EventSeverity::Warning => MavSeverity::MAV_SEVERITY_WARNING,
        EventSeverity::Critical => MavSeverity::MAV_SEVERITY_CRITICAL,
    };
    statustext(severity, &event.text())
}

/// What the ground station hears of the plant link's health (`core::plant_link::health`): a STATUSTEXT,
/// WARNING while samples go missing ("Plant link: 100 of 500 samples missing"), INFO when they are
/// complete again.
#[must_use]
pub fn plant_link_event_message(event: &PlantLinkEvent) -> MavMessage {
    let severity = match event {
        PlantLinkEvent::Missing { .. } => MavSeverity::MAV_SEVERITY_WARNING,
        PlantLinkEvent::Complete => MavSeverity::MAV_SEVERITY_INFO,
    };
    statustext(severity, &event.text())
}

/// A STATUSTEXT (text cut to MAVLink's 50 bytes at a character boundary).
#[must_use]
pub fn statustext(severity: MavSeverity, text: &str) -> MavMessage {
    let mut end = text.len().min(50);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    MavMessage::STATUSTEXT(STATUSTEXT_DATA { severity, text: text[..end].into(), ..Default::default() })
}

/// `text` as STATUSTEXTs: one when it fits (50 bytes), else MAVLink 2 chunks that ground stations
/// reassemble (QGroundControl, MAVProxy): every chunk carries the non-zero `id`, `chunk_seq` counts from
/// 0, and the last chunk is shorter than 50 bytes (an empty one follows a text that fills its last chunk).
#[must_use]
pub fn statustext_chunks(severity: MavSeverity, text: &str, id: u16) -> Vec<MavMessage> {
    if text.len() <= 50 {
        return vec![statustext(severity, text)];
    }
    let id = id.max(1);
    let mut chunks = Vec::new();
    let mut rest = text;
    loop {
        let mut end = rest.len().min(50);
        while !rest.is_char_boundary(end) {
            end -= 1;
        }
        let chunk_seq = u8::try_from(chunks.len()).unwrap_or(u8::MAX);
        chunks.push(MavMessage::STATUSTEXT(STATUSTEXT_DATA { severity, text: rest[..end].into(), id, chunk_seq }));
        if end < 50 || chunk_seq == u8::MAX {
            break;
        }
        rest = &rest[end..];
    }
    chunks
}

/// The severity of an event's STATUSTEXT: a kill or failsafe is critical, a low battery a warning, a
/// disarm a notice, the rest info.
#[must_use]
pub fn event_severity(event: &Event) -> MavSeverity {
    match event {
        Event::Killed | Event::Failsafe { .. } => MavSeverity::MAV_SEVERITY_CRITICAL,
        Event::BatteryLow { .. } => MavSeverity::MAV_SEVERITY_WARNING,
        Event::Disarmed { .. } => MavSeverity::MAV_SEVERITY_NOTICE,
        _ => MavSeverity::MAV_SEVERITY_INFO,
    }
}

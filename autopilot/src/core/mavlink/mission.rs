//! The mission microservice (MAVLink mission protocol), sans-I/O. In: each received message with its
//! [`MavHeader`] and our system id ([`MissionService::on_message`]), and the vehicle time `now_us` (µs of
//! vehicle time) on every step ([`MissionService::poll`], for re-requests and time-outs). Out: a
//! [`MissionReply`]: the messages to send (every one carries target_system/target_component = the client
//! it answers, so the vehicle routes by those) and at most one [`MissionEvent`] for the vehicle to apply:
//! a new mission to store and persist, a clear, or a new current item. MISSION_CURRENT and
//! MISSION_ITEM_REACHED are the mission executor's, not this service's.
//!
//! - Upload: MISSION_COUNT n -> MISSION_REQUEST_INT 0, item 0 -> request 1, ... -> item n-1 -> MISSION_ACK
//!   ACCEPTED and [`MissionEvent::Replaced`]. Requests are MISSION_REQUEST_INT until the client sends a
//!   legacy MISSION_ITEM, then MISSION_REQUEST (the flavour of the client's last item); a client MISSION_ACK
//!   UNSUPPORTED (MAVSDK's answer to the flavour it does not speak) switches the flavour, as PX4 does, and
//!   while no item has arrived yet the re-requests alternate flavours. Each item is validated on arrival
//!   (see [`crate::core::mission`]): the first bad one ends the upload with its MISSION_ACK error and a
//!   STATUSTEXT with the reason. COUNT 0 clears (ACK ACCEPTED, [`MissionEvent::Cleared`]); a COUNT above
//!   [`MissionServiceConfig::max_items`] gets MAV_MISSION_NO_SPACE.
//! - Atomic: the stored mission changes only when an upload completes valid. A refused, timed-out or
//!   abandoned upload leaves it as it was. Abandoned: a new MISSION_COUNT (from anyone) restarts the
//!   upload with the new count; MISSION_CLEAR_ALL clears; MISSION_REQUEST_LIST or a MISSION_ACK
//!   OPERATION_CANCELLED from the uploading client ends it without a reply. (PX4 instead refuses a second
//!   COUNT with "Busy" unless nothing was received yet; clients time out on the wall clock while this
//!   vehicle's clock may run slower or faster, so a client's restart must win.)
//! - Re-requests on vehicle time: an item not received [`MissionServiceConfig::item_timeout_us`] (1.5 s)
//!   after its request is requested again, up to [`MissionServiceConfig::max_retries`] (5) times; then
//!   MISSION_ACK OPERATION_CANCELLED and a STATUSTEXT. Generous, because SITL may run 100x the wall clock
//!   and clients (MAVSDK 0.5 s x 5, QGC 1.5 s) retry on the wall clock themselves.
//! - Out of order: an item other than the expected one (a duplicate, or one ahead) is ignored and the
//!   expected seq requested again at once. Such re-requests do not restart the time-out, so a client that
//!   never sends the expected item still times out. (Current PX4 ignores them silently and re-requests on
//!   its time-out; older PX4 re-requested at once, as here.)
//! - An item while no upload is in progress, as PX4: the last item of the upload just completed, from the
//!   same client, is answered with that upload's ACK again (the client missed it); any other gets
//!   MISSION_ACK MAV_MISSION_ERROR and the STATUSTEXT "Mission item ignored: no upload". An item from
//!   another client while an upload is in progress gets MAV_MISSION_ERROR ("busy") and the upload goes on.
//! - Download, stateless: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT / MISSION_REQUEST seq
//!   -> MISSION_ITEM_INT / MISSION_ITEM with `current` on [`MissionService::current_seq`]; a seq beyond the
//!   mission -> MISSION_ACK MAV_MISSION_INVALID_SEQUENCE; the client's closing MISSION_ACK needs no answer.
//! - MISSION_CLEAR_ALL -> MISSION_ACK ACCEPTED and [`MissionEvent::Cleared`]. MISSION_SET_CURRENT seq in
//!   the mission -> [`MissionEvent::SetCurrent`] (the vehicle answers with MISSION_CURRENT); beyond it -> a
//!   STATUSTEXT only (as PX4: a MISSION_ACK here could end an unrelated transfer of the client's).
//! - The `current` flag of uploaded items is ignored: a new mission starts at item 0.
//! - Mission types: `mission_type` (a MAVLink 2 extension field) tells the transfers apart: MISSION (0),
//!   FENCE (1) and RALLY (2) each have their own stored plan, uploaded, downloaded and cleared by the same
//!   protocol; every reply carries the transfer's type. Fence and rally items are validated as
//!   `core::plan::geofence` says ([`Fence::new`], [`Rally::new`]): a completed upload gives
//!   [`MissionEvent::FenceReplaced`] / [`MissionEvent::RallyReplaced`], a clear the same with an empty
//!   plan. MISSION_CLEAR_ALL of type ALL (255) clears all three ([`MissionEvent::ClearedAll`]); ALL in any
//!   other message is answered MAV_MISSION_UNSUPPORTED. MISSION_SET_CURRENT and the `current` flag are the
//!   mission's only.
//! - Only messages for our system (or broadcast) and component 1 (or 0) are handled ([`addressed_to_us`]).

// MISSION_ITEM, MISSION_REQUEST and MISSION_SET_CURRENT are deprecated in the dialect, but QGroundControl,
// MAVProxy and pymavlink scripts still send them: this service answers them.
#![allow(deprecated)]

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA,
    MISSION_REQUEST_INT_DATA, MavMessage, MavMissionResult, MavMissionType, MavSeverity,
};

use super::addressed_to_us;
use super::telemetry::statustext;
use crate::core::mission::{Mission, MissionError, MissionItem, validate_item};
use crate::core::plan::Plan;
use crate::core::plan::geofence::{Fence, Rally, validate_fence_item, validate_rally_item};

/// The service's tunables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MissionServiceConfig {
    /// Vehicle time (µs) to wait for a requested item before requesting it again.
    pub item_timeout_us: u64,
    /// Re-requests of one item before the upload is given up.
    pub max_retries: u8,
    /// The largest mission accepted (items); a larger MISSION_COUNT gets MAV_MISSION_NO_SPACE.
    pub max_items: u16,
}

impl Default for MissionServiceConfig {
    fn default() -> Self {
        Self { item_timeout_us: 1_500_000, max_retries: 5, max_items: 1000 }
    }
}

/// Which plan a transfer carries (MAVLink's `mission_type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanKind {
    Mission,
    Fence,
    Rally,
}

impl PlanKind {
    /// The plan of a `mission_type` (None for ALL, which only a clear may name).
    #[must_use]
    pub fn of(mission_type: MavMissionType) -> Option<Self> {
        match mission_type {
            MavMissionType::MAV_MISSION_TYPE_MISSION => Some(Self::Mission),
            MavMissionType::MAV_MISSION_TYPE_FENCE => Some(Self::Fence),
            MavMissionType::MAV_MISSION_TYPE_RALLY => Some(Self::Rally),
            _ => None,
        }
    }

    /// The `mission_type` on the wire.
    #[must_use]
    pub fn wire(self) -> MavMissionType {
        match self {
            Self::Mission => MavMissionType::MAV_MISSION_TYPE_MISSION,
            Self::Fence => MavMissionType::MAV_MISSION_TYPE_FENCE,
            Self::Rally => MavMissionType::MAV_MISSION_TYPE_RALLY,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Mission => "Mission",
            Self::Fence => "Fence",
            Self::Rally => "Rally",
        }
    }
}

/// What the vehicle must apply after a message.
#[derive(Debug, Clone, PartialEq)]
pub enum MissionEvent {
    /// An upload completed valid: store this mission (already held by the service), persist it, restart
    /// the executor at item 0.
    Replaced(Mission),
    /// The mission was cleared (MISSION_CLEAR_ALL or an upload of 0 items).
    Cleared,
    /// The client asked to continue from this item (within the mission); answer with MISSION_CURRENT.
    SetCurrent(u16),
    /// A fence upload completed valid, or the fence was cleared (empty): store and persist it.
    FenceReplaced(Fence),
    /// A rally upload completed valid, or the rally points were cleared (empty): store and persist them.
    RallyReplaced(Rally),
    /// MISSION_CLEAR_ALL of type ALL: the mission, the fence and the rally points are cleared.
    ClearedAll,
}

/// The result of one message or poll.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MissionReply {
    /// To send; each carries the target client in target_system/target_component.
    pub messages: Vec<MavMessage>,
    pub event: Option<MissionEvent>,
}

impl MissionReply {
    fn send(messages: Vec<MavMessage>) -> Self {
        Self { messages, event: None }
    }
}

/// A client: (system id, component id).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Peer {
    system: u8,
    component: u8,
}

impl Peer {
    fn of(header: &MavHeader) -> Self {
        Self { system: u8::try_from(header.system_id).unwrap_or(u8::MAX), component: header.component_id }
    }
}

/// The message family a client uses for items.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flavour {
    /// MISSION_REQUEST_INT / MISSION_ITEM_INT.
    Int,
    /// MISSION_REQUEST / MISSION_ITEM.
    Legacy,
}

impl Flavour {
    fn other(self) -> Self {
        match self {
            Self::Int => Self::Legacy,
            Self::Legacy => Self::Int,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
struct Upload {
    kind: PlanKind,
    peer: Peer,
    count: u16,
    /// Items 0..received, validated.
    items: Vec<MissionItem>,
    flavour: Flavour,
    /// When the expected item was last requested on progress or time-out (µs of vehicle time).
    requested_at_us: u64,
    retries: u8,
}

impl Upload {
    fn expected_seq(&self) -> u16 {
        u16::try_from(self.items.len()).unwrap_or(u16::MAX)
    }
}

/// The end of the last completed upload, to repeat its ACK to a client that resends its last item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Finished {
    kind: PlanKind,
    peer: Peer,
    last_seq: u16,
}

/// The mission microservice: the transfer protocol over the plan store ([`Plan`]), which it is handed
/// with every message.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MissionService {
    config: MissionServiceConfig,
    upload: Option<Upload>,
    finished: Option<Finished>,
}

fn ack(peer: Peer, result: MavMissionResult, kind: PlanKind) -> MavMessage {
    ack_typed(peer, result, kind.wire())
}

fn ack_typed(peer: Peer, result: MavMissionResult, mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: peer.system,
        target_component: peer.component,
        mavtype: result,
        mission_type,
        ..Default::default()
    })
}

fn request(peer: Peer, seq: u16, flavour: Flavour, kind: PlanKind) -> MavMessage {
    let (target_system, target_component, mission_type) = (peer.system, peer.component, kind.wire());
    match flavour {
        Flavour::Int => MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system,
            target_component,
            mission_type,
        }),
        Flavour::Legacy => {
            MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA { seq, target_system, target_component, mission_type })
        }
    }
}

fn warning(text: &str) -> MavMessage {
    statustext(MavSeverity::MAV_SEVERITY_WARNING, text)
}

/// An upload refused: the MISSION_ACK with the error's result and a STATUSTEXT with the reason.
fn refusal(peer: Peer, error: &MissionError, kind: PlanKind) -> MissionReply {
    MissionReply::send(vec![ack(peer, error.result(), kind), warning(&format!("{}: {error}", kind.name()))])
}

impl MissionService {
    /// A service with an empty mission.
    #[must_use]
    pub fn new(config: MissionServiceConfig) -> Self {
        Self { config, ..Self::default() }
    }

    #[must_use]
    pub fn config(&self) -> &MissionServiceConfig {
        &self.config
    }

    /// Whether an upload is in progress.
    #[must_use]
    pub fn upload_in_progress(&self) -> bool {
        self.upload.is_some()
    }

    /// A received message, from the client `header` names, to system `sysid`. Messages that are not
    /// mission messages for us give an empty reply.
    pub fn on_message(
        &mut self,
        plan: &mut Plan,
        now_us: u64,
        sysid: u8,
        header: &MavHeader,
        msg: &MavMessage,
    ) -> MissionReply {
        let ours = |target_system, target_component| addressed_to_us(sysid, target_system, target_component);
        let peer = Peer::of(header);
        // The plan a message is about; ALL (or an unknown type) is answered UNSUPPORTED except by a clear.
        let kind = |t: MavMissionType| PlanKind::of(t).ok_or(t);
        let unsupported = |t| MissionReply::send(vec![ack_typed(peer, MavMissionResult::MAV_MISSION_UNSUPPORTED, t)]);
        match msg {
            MavMessage::MISSION_COUNT(m) if ours(m.target_system, m.target_component) => match kind(m.mission_type) {
                Ok(k) => self.on_count(plan, now_us, peer, m.count, k),
                Err(t) => unsupported(t),
            },
            MavMessage::MISSION_ITEM_INT(m) if ours(m.target_system, m.target_component) => {
                match kind(m.mission_type) {
                    Ok(k) => {
                        self.on_item(plan, now_us, peer, Flavour::Int, m.seq, k, Ok(MissionItem::from_item_int(m)))
                    }
                    Err(t) => unsupported(t),
                }
            }
            MavMessage::MISSION_ITEM(m) if ours(m.target_system, m.target_component) => match kind(m.mission_type) {
                Ok(k) => self.on_item(plan, now_us, peer, Flavour::Legacy, m.seq, k, MissionItem::from_item(m)),
                Err(t) => unsupported(t),
            },
            MavMessage::MISSION_REQUEST_LIST(m) if ours(m.target_system, m.target_component) => {
                match kind(m.mission_type) {
                    Ok(k) => self.on_request_list(plan, peer, k),
                    Err(t) => unsupported(t),
                }
            }
            MavMessage::MISSION_REQUEST_INT(m) if ours(m.target_system, m.target_component) => {
                match kind(m.mission_type) {
                    Ok(k) => self.on_request(plan, peer, m.seq, Flavour::Int, k),
                    Err(t) => unsupported(t),
                }
            }
            MavMessage::MISSION_REQUEST(m) if ours(m.target_system, m.target_component) => match kind(m.mission_type) {
                Ok(k) => self.on_request(plan, peer, m.seq, Flavour::Legacy, k),
                Err(t) => unsupported(t),
            },
            MavMessage::MISSION_CLEAR_ALL(m) if ours(m.target_system, m.target_component) => {
                self.on_clear(plan, peer, PlanKind::of(m.mission_type), m.mission_type)
            }
            MavMessage::MISSION_SET_CURRENT(m) if ours(m.target_system, m.target_component) => {
                Self::on_set_current(plan, m.seq)
            }
            MavMessage::MISSION_ACK(m) if ours(m.target_system, m.target_component) => {
                self.on_ack(now_us, peer, m.mavtype, PlanKind::of(m.mission_type))
            }
            _ => MissionReply::default(),
        }
    }

    /// Re-requests and time-outs due at `now_us` (µs of vehicle time); call on every vehicle step.
    pub fn poll(&mut self, now_us: u64) -> MissionReply {
        let Some(upload) = &mut self.upload else {
            return MissionReply::default();
        };
        if now_us < upload.requested_at_us.saturating_add(self.config.item_timeout_us) {
            return MissionReply::default();
        }
        if upload.retries < self.config.max_retries {
            upload.retries += 1;
            upload.requested_at_us = now_us;
            if upload.items.is_empty() {
                upload.flavour = upload.flavour.other();
            }
            return MissionReply::send(vec![request(upload.peer, upload.expected_seq(), upload.flavour, upload.kind)]);
        }
        let (peer, kind) = (upload.peer, upload.kind);
        self.upload = None;
        MissionReply::send(vec![
            ack(peer, MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, kind),
            warning(&format!("{} upload timed out", kind.name())),
        ])
    }

    fn on_count(&mut self, plan: &mut Plan, now_us: u64, peer: Peer, count: u16, kind: PlanKind) -> MissionReply {
        self.upload = None;
        self.finished = None;
        if count == 0 {
            return Self::clear(plan, peer, kind);
        }
        if count > self.config.max_items {
            let error =
                MissionError::TooManyItems { count: usize::from(count), max: usize::from(self.config.max_items) };
            return refusal(peer, &error, kind);
        }
        let upload = Upload {
            kind,
            peer,
            count,
            items: Vec::with_capacity(usize::from(count)),
            flavour: Flavour::Int,
            requested_at_us: now_us,
            retries: 0,
        };
        let first = request(peer, 0, upload.flavour, kind);
        self.upload = Some(upload);
        MissionReply::send(vec![first])
    }

    #[allow(clippy::too_many_arguments)]
    fn on_item(
        &mut self,
        plan: &mut Plan,
        now_us: u64,
        peer: Peer,
        flavour: Flavour,
        seq: u16,
        kind: PlanKind,
        item: Result<MissionItem, MissionError>,
    ) -> MissionReply {
        let Some(upload) = self.upload.as_mut().filter(|u| u.peer == peer && u.kind == kind) else {
            return self.on_stray_item(peer, seq, kind);
        };
        upload.flavour = flavour;
        let expected = upload.expected_seq();
        if seq != expected {
            return MissionReply::send(vec![request(peer, expected, flavour, kind)]);
        }
        let count = usize::from(upload.count);
        let valid = |item: &MissionItem| match kind {
            PlanKind::Mission => validate_item(item, count),
            PlanKind::Fence => validate_fence_item(item),
            PlanKind::Rally => validate_rally_item(item),
        };
        let item = match item.and_then(|item| valid(&item).map(|()| item)) {
            Ok(item) => item,
            Err(error) => {
                self.upload = None;
                return refusal(peer, &error, kind);
            }
        };
        upload.items.push(item);
        upload.retries = 0;
        upload.requested_at_us = now_us;
        if upload.items.len() < count {
            return MissionReply::send(vec![request(peer, upload.expected_seq(), flavour, kind)]);
        }
        let items = std::mem::take(&mut upload.items);
        self.upload = None;
        let event = match kind {
            PlanKind::Mission => Mission::new(items).and_then(|mission| {
                plan.set_mission(mission.clone())?;
                Ok(MissionEvent::Replaced(mission))
            }),
            PlanKind::Fence => Fence::new(items).map(|fence| {
                plan.set_fence(fence.clone());
                MissionEvent::FenceReplaced(fence)
            }),
            PlanKind::Rally => Rally::new(items).map(|rally| {
                plan.set_rally(rally.clone());
                MissionEvent::RallyReplaced(rally)
            }),
        };
        match event {
            Ok(event) => {
                self.finished = Some(Finished { kind, peer, last_seq: seq });
                MissionReply {
                    messages: vec![ack(peer, MavMissionResult::MAV_MISSION_ACCEPTED, kind)],
                    event: Some(event),
                }
            }
            Err(error) => refusal(peer, &error, kind),
        }
    }

    /// An item outside an upload of the sender's.
    fn on_stray_item(&self, peer: Peer, seq: u16, kind: PlanKind) -> MissionReply {
        if self.upload.is_some() {
            return MissionReply::send(vec![
                ack(peer, MavMissionResult::MAV_MISSION_ERROR, kind),
                warning(&format!("{} item ignored: busy", kind.name())),
            ]);
        }
        if self.finished == Some(Finished { kind, peer, last_seq: seq }) {
            return MissionReply::send(vec![ack(peer, MavMissionResult::MAV_MISSION_ACCEPTED, kind)]);
        }
        MissionReply::send(vec![
            ack(peer, MavMissionResult::MAV_MISSION_ERROR, kind),
            warning(&format!("{} item ignored: no upload", kind.name())),
        ])
    }

    /// The stored items of a plan.
    fn items(plan: &Plan, kind: PlanKind) -> &[MissionItem] {
        match kind {
            PlanKind::Mission => &plan.mission().items,
            PlanKind::Fence => plan.fence().items(),
            PlanKind::Rally => plan.rally().items(),
        }
    }

    fn on_request_list(&mut self, plan: &Plan, peer: Peer, kind: PlanKind) -> MissionReply {
        if self.upload.as_ref().is_some_and(|u| u.peer == peer) {
            self.upload = None;
        }
        let count = u16::try_from(Self::items(plan, kind).len()).unwrap_or(u16::MAX);
        MissionReply::send(vec![MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count,
            target_system: peer.system,
            target_component: peer.component,
            mission_type: kind.wire(),
            ..Default::default()
        })])
    }

    fn on_request(&self, plan: &Plan, peer: Peer, seq: u16, flavour: Flavour, kind: PlanKind) -> MissionReply {
        let Some(item) = Self::items(plan, kind).get(usize::from(seq)) else {
            return MissionReply::send(vec![ack(peer, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, kind)]);
        };
        let current = kind == PlanKind::Mission && seq == plan.current_seq();
        MissionReply::send(vec![match flavour {
            Flavour::Int => MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                mission_type: kind.wire(),
                ..item.to_item_int(peer.system, peer.component, current)
            }),
            Flavour::Legacy => MavMessage::MISSION_ITEM(MISSION_ITEM_DATA {
                mission_type: kind.wire(),
                ..item.to_item(peer.system, peer.component, current)
            }),
        }])
    }

    fn on_clear(
        &mut self,
        plan: &mut Plan,
        peer: Peer,
        kind: Option<PlanKind>,
        mission_type: MavMissionType,
    ) -> MissionReply {
        self.upload = None;
        self.finished = None;
        if let Some(kind) = kind {
            return Self::clear(plan, peer, kind);
        }
        if mission_type != MavMissionType::MAV_MISSION_TYPE_ALL {
            return MissionReply::send(vec![ack_typed(peer, MavMissionResult::MAV_MISSION_UNSUPPORTED, mission_type)]);
        }
        plan.clear_mission();
        plan.set_fence(Fence::default());
        plan.set_rally(Rally::default());
        MissionReply {
            messages: vec![ack_typed(peer, MavMissionResult::MAV_MISSION_ACCEPTED, mission_type)],
            event: Some(MissionEvent::ClearedAll),
        }
    }

    fn clear(plan: &mut Plan, peer: Peer, kind: PlanKind) -> MissionReply {
        let event = match kind {
            PlanKind::Mission => {
                plan.clear_mission();
                MissionEvent::Cleared
            }
            PlanKind::Fence => {
                plan.set_fence(Fence::default());
                MissionEvent::FenceReplaced(Fence::default())
            }
            PlanKind::Rally => {
                plan.set_rally(Rally::default());
                MissionEvent::RallyReplaced(Rally::default())
            }
        };
        MissionReply { messages: vec![ack(peer, MavMissionResult::MAV_MISSION_ACCEPTED, kind)], event: Some(event) }
    }

    fn on_set_current(plan: &mut Plan, seq: u16) -> MissionReply {
        if usize::from(seq) < plan.mission().len() {
            plan.set_current_seq(seq);
            return MissionReply { messages: Vec::new(), event: Some(MissionEvent::SetCurrent(seq)) };
        }
        let text = format!("Mission: set current {seq}: not in 0..{}", plan.mission().len());
        MissionReply::send(vec![warning(&text)])
    }

    fn on_ack(&mut self, now_us: u64, peer: Peer, result: MavMissionResult, kind: Option<PlanKind>) -> MissionReply {
        let Some(upload) = self.upload.as_mut().filter(|u| u.peer == peer && Some(u.kind) == kind) else {
            return MissionReply::default();
        };
        match result {
            MavMissionResult::MAV_MISSION_OPERATION_CANCELLED => {
                self.upload = None;
                MissionReply::default()
            }
            MavMissionResult::MAV_MISSION_UNSUPPORTED if upload.retries < self.config.max_retries => {
                upload.retries += 1;
                upload.requested_at_us = now_us;
                upload.flavour = upload.flavour.other();
                MissionReply::send(vec![request(peer, upload.expected_seq(), upload.flavour, upload.kind)])
            }
            _ => MissionReply::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::{
        MISSION_CLEAR_ALL_DATA, MISSION_ITEM_DATA, MISSION_REQUEST_LIST_DATA, MISSION_SET_CURRENT_DATA, MavCmd,
        MavFrame,
    };

    use super::*;

    /// The service with the plan store it transfers into (the vehicle holds both), for the tests.
    #[derive(Debug, Default)]
    struct Svc {
        service: MissionService,
        plan: Plan,
    }

    impl Svc {
        fn new(config: MissionServiceConfig) -> Self {
            Self { service: MissionService::new(config), plan: Plan::default() }
        }

        fn on_message(&mut self, now_us: u64, sysid: u8, header: &MavHeader, msg: &MavMessage) -> MissionReply {
            self.service.on_message(&mut self.plan, now_us, sysid, header, msg)
        }

        fn poll(&mut self, now_us: u64) -> MissionReply {
            self.service.poll(now_us)
        }

        fn upload_in_progress(&self) -> bool {
            self.service.upload_in_progress()
        }

        fn mission(&self) -> &Mission {
            self.plan.mission()
        }

        fn current_seq(&self) -> u16 {
            self.plan.current_seq()
        }

        fn set_mission(&mut self, mission: Mission) -> Result<(), MissionError> {
            self.plan.set_mission(mission)
        }
    }
    use crate::core::mission::XY_UNSET;

    const SYSID: u8 = 1;
    const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
    const OTHER_GCS: MavHeader = MavHeader { system_id: 245, component_id: 190, sequence: 0 };
    const MS: u64 = 1000;
    const S: u64 = 1_000_000;

    fn wp(seq: u16, lat_dege7: i32, lon_dege7: i32, alt_m: f32) -> MissionItem {
        MissionItem {
            seq,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            param1: 0.0,
            param2: 2.0,
            param3: 0.0,
            param4: 90.0,
            x: lat_dege7,
            y: lon_dege7,
            z: alt_m,
            autocontinue: true,
        }
    }

    fn with(seq: u16, command: MavCmd, frame: MavFrame, param1: f32, param2: f32) -> MissionItem {
        MissionItem { command, frame, param1, param2, param4: 0.0, ..wp(seq, 0, 0, 0.0) }
    }

    /// Takeoff, waypoints, a speed change, a jump back, RTL: every supported command once in `n` >= 9 items.
    fn mission_items(n: u16) -> Vec<MissionItem> {
        (0..n)
            .map(|seq| match seq {
                0 => MissionItem { command: MavCmd::MAV_CMD_NAV_TAKEOFF, x: XY_UNSET, y: XY_UNSET, ..wp(0, 0, 0, 5.0) },
                2 => with(2, MavCmd::MAV_CMD_DO_CHANGE_SPEED, MavFrame::MAV_FRAME_MISSION, 1.0, 4.5),
                3 => MissionItem {
                    command: MavCmd::MAV_CMD_NAV_LOITER_TIME,
                    param1: 3.0,
                    ..wp(3, 473_977_500, 85_456_000, 12.0)
                },
                4 => with(4, MavCmd::MAV_CMD_NAV_DELAY, MavFrame::MAV_FRAME_MISSION, 1.5, 0.0),
                5 => with(5, MavCmd::MAV_CMD_DO_JUMP, MavFrame::MAV_FRAME_MISSION, 1.0, 2.0),
                6 => MissionItem {
                    command: MavCmd::MAV_CMD_NAV_LOITER_UNLIM,
                    ..wp(6, -353_632_621, 1_491_652_374, 30.0)
                },
                s if s + 2 == n => with(s, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, MavFrame::MAV_FRAME_MISSION, 0.0, 0.0),
                s if s + 1 == n => {
                    MissionItem { command: MavCmd::MAV_CMD_NAV_LAND, ..wp(s, 473_977_419, 85_455_939, 0.0) }
                }
                s => wp(s, 473_977_419 + i32::from(s) * 100, 85_455_939 - i32::from(s) * 70, 10.0 + f32::from(s)),
            })
            .collect()
    }

    fn waypoints(n: u16, alt_m: f32) -> Vec<MissionItem> {
        (0..n).map(|s| wp(s, 470_000_000 + i32::from(s) * 1000, 80_000_000, alt_m)).collect()
    }

    fn count(n: u16) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            target_system: SYSID,
            target_component: 1,
            ..Default::default()
        })
    }

    fn item_int(item: &MissionItem) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(item.to_item_int(SYSID, 1, false))
    }

    fn item_legacy(item: &MissionItem) -> MavMessage {
        MavMessage::MISSION_ITEM(item.to_item(SYSID, 1, false))
    }

    fn request_list() -> MavMessage {
        MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: SYSID,
            target_component: 1,
            ..Default::default()
        })
    }

    fn client_ack(result: MavMissionResult) -> MavMessage {
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: SYSID,
            target_component: 1,
            mavtype: result,
            ..Default::default()
        })
    }

    fn clear_all() -> MavMessage {
        MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: SYSID,
            target_component: 1,
            ..Default::default()
        })
    }

    fn set_current(seq: u16) -> MavMessage {
        MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA { seq, target_system: SYSID, target_component: 1 })
    }

    /// The (seq, flavour) of every request in `reply`.
    fn requests(reply: &MissionReply) -> Vec<(u16, Flavour)> {
        reply
            .messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_REQUEST_INT(r) => Some((r.seq, Flavour::Int)),
                MavMessage::MISSION_REQUEST(r) => Some((r.seq, Flavour::Legacy)),
                _ => None,
            })
            .collect()
    }

    fn acks(reply: &MissionReply) -> Vec<MavMissionResult> {
        reply
            .messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_ACK(a) => Some(a.mavtype),
                _ => None,
            })
            .collect()
    }

    fn texts(reply: &MissionReply) -> Vec<String> {
        reply
            .messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::STATUSTEXT(t) => Some(t.text.to_str().unwrap_or_default().to_owned()),
                _ => None,
            })
            .collect()
    }

    /// The target of a mission message (None for STATUSTEXT, which has none).
    fn target(m: &MavMessage) -> Option<(u8, u8)> {
        match m {
            MavMessage::MISSION_ACK(x) => Some((x.target_system, x.target_component)),
            MavMessage::MISSION_COUNT(x) => Some((x.target_system, x.target_component)),
            MavMessage::MISSION_REQUEST_INT(x) => Some((x.target_system, x.target_component)),
            MavMessage::MISSION_REQUEST(x) => Some((x.target_system, x.target_component)),
            MavMessage::MISSION_ITEM_INT(x) => Some((x.target_system, x.target_component)),
            MavMessage::MISSION_ITEM(x) => Some((x.target_system, x.target_component)),
            _ => None,
        }
    }

    fn assert_to(reply: &MissionReply, header: &MavHeader) {
        let peer = (u8::try_from(header.system_id).unwrap_or(0), header.component_id);
        for m in &reply.messages {
            if let Some(t) = target(m) {
                assert_eq!(t, peer, "{m:?}");
            }
        }
    }

    /// A client that answers each request with the item asked for, INT or `legacy`, from `now_us` on at
    /// 1 ms per message; returns the last reply (the ACK) and the number of requests answered.
    fn upload(svc: &mut Svc, now_us: u64, items: &[MissionItem], legacy: bool) -> (MissionReply, usize) {
        let n = u16::try_from(items.len()).expect("small");
        let mut t = now_us;
        let mut reply = svc.on_message(t, SYSID, &GCS, &count(n));
        let mut answered = 0;
        while let Some(&(seq, _)) = requests(&reply).first() {
            assert_to(&reply, &GCS);
            assert!(answered <= items.len() * 2, "runaway upload");
            t += MS;
            let item = &items[usize::from(seq)];
            let msg = if legacy { item_legacy(item) } else { item_int(item) };
            reply = svc.on_message(t, SYSID, &GCS, &msg);
            answered += 1;
        }
        assert_to(&reply, &GCS);
        (reply, answered)
    }

    /// A client that downloads the mission (INT or legacy): the items and the seq flagged current.
    fn download(svc: &mut Svc, legacy: bool) -> (Vec<MissionItem>, Vec<u16>) {
        let reply = svc.on_message(0, SYSID, &GCS, &request_list());
        assert_to(&reply, &GCS);
        let [MavMessage::MISSION_COUNT(c)] = reply.messages.as_slice() else { panic!("{reply:?}") };
        let mut items = Vec::new();
        let mut current = Vec::new();
        for seq in 0..c.count {
            let req = if legacy {
                MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                    seq,
                    target_system: SYSID,
                    target_component: 1,
                    ..Default::default()
                })
            } else {
                MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                    seq,
                    target_system: SYSID,
                    target_component: 1,
                    ..Default::default()
                })
            };
            let reply = svc.on_message(0, SYSID, &GCS, &req);
            assert_to(&reply, &GCS);
            match reply.messages.as_slice() {
                [MavMessage::MISSION_ITEM_INT(m)] if !legacy => {
                    items.push(MissionItem::from_item_int(m));
                    if m.current == 1 {
                        current.push(seq);
                    }
                }
                [MavMessage::MISSION_ITEM(m)] if legacy => {
                    items.push(MissionItem::from_item(m).expect("finite"));
                    if m.current == 1 {
                        current.push(seq);
                    }
                }
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(
            svc.on_message(0, SYSID, &GCS, &client_ack(MavMissionResult::MAV_MISSION_ACCEPTED)),
            MissionReply::default()
        );
        (items, current)
    }

    fn with_mission(items: Vec<MissionItem>) -> Svc {
        let mut svc = Svc::default();
        svc.set_mission(Mission::new(items).expect("valid")).expect("valid");
        svc
    }

    #[test]
    fn given_an_int_client_when_it_uploads_a_mission_then_accepted_replaced_and_downloaded_identically() {
        let mut svc = Svc::default();
        let items = mission_items(9);
        let (reply, answered) = upload(&mut svc, 0, &items, false);
        assert_eq!(answered, 9);
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(reply.event, Some(MissionEvent::Replaced(Mission { items: items.clone() })));
        assert_eq!(svc.mission().items, items);
        assert!(!svc.upload_in_progress());
        let (down, current) = download(&mut svc, false);
        assert_eq!(down, items);
        assert_eq!(current, vec![0]);
    }

    #[test]
    fn given_a_legacy_client_when_it_answers_with_mission_item_then_requests_turn_legacy_and_the_round_trip_holds() {
        let mut svc = Svc::default();
        let items = mission_items(9);
        let mut reply = svc.on_message(0, SYSID, &GCS, &count(9));
        assert_eq!(requests(&reply), vec![(0, Flavour::Int)], "INT by default");
        let mut flavours = Vec::new();
        while let Some(&(seq, flavour)) = requests(&reply).first() {
            flavours.push(flavour);
            reply = svc.on_message(0, SYSID, &GCS, &item_legacy(&items[usize::from(seq)]));
        }
        assert_eq!(flavours[1..], [Flavour::Legacy; 8], "answered in the client's flavour");
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        // What the legacy wire carries: f32 deg (about 4e-6 deg at 47 deg), rounded to degE7.
        let sent: Vec<MISSION_ITEM_DATA> = items.iter().map(|i| i.to_item(SYSID, 1, false)).collect();
        let carried: Vec<MissionItem> = sent.iter().map(|m| MissionItem::from_item(m).expect("finite")).collect();
        assert_eq!(svc.mission().items, carried);
        let (down, current) = download(&mut svc, true);
        assert_eq!(down, carried);
        assert_eq!(current, vec![0]);
        for (seq, sent) in (0..).zip(&sent) {
            let req = MISSION_REQUEST_DATA { seq, target_system: SYSID, target_component: 1, ..Default::default() };
            let reply = svc.on_message(0, SYSID, &GCS, &MavMessage::MISSION_REQUEST(req));
            let [MavMessage::MISSION_ITEM(got)] = reply.messages.as_slice() else { panic!("{reply:?}") };
            let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
            assert!(same(got.x, sent.x) && same(got.y, sent.y) && got.z == sent.z, "the floats sent: {got:?}");
        }
    }

    #[test]
    fn given_a_stored_mission_when_the_client_stops_after_2_of_5_then_5_re_requests_on_vehicle_time_and_the_old_mission_stays()
     {
        let old = waypoints(3, 50.0);
        let mut svc = with_mission(old.clone());
        let new = waypoints(5, 10.0);
        assert_eq!(requests(&svc.on_message(0, SYSID, &GCS, &count(5))), vec![(0, Flavour::Int)]);
        svc.on_message(10 * MS, SYSID, &GCS, &item_int(&new[0]));
        assert_eq!(requests(&svc.on_message(20 * MS, SYSID, &GCS, &item_int(&new[1]))), vec![(2, Flavour::Int)]);
        let mut re_requests = Vec::new();
        let mut end = None;
        for step in 1..=200_u64 {
            let now_us = 20 * MS + step * 100 * MS;
            let reply = svc.poll(now_us);
            assert_eq!(reply.event, None);
            assert_to(&reply, &GCS);
            re_requests.extend(requests(&reply).into_iter().map(|r| (now_us, r)));
            if !acks(&reply).is_empty() {
                assert!(end.is_none(), "one end");
                end = Some((now_us, acks(&reply), texts(&reply)));
            }
        }
        let times: Vec<u64> = re_requests.iter().map(|&(t, _)| t).collect();
        assert_eq!(times, [1520, 3020, 4520, 6020, 7520].map(|ms| ms * MS), "every 1.5 s of vehicle time");
        assert!(re_requests.iter().all(|&(_, r)| r == (2, Flavour::Int)));
        let (t_end, end_acks, end_texts) = end.expect("gave up");
        assert_eq!(t_end, 9020 * MS);
        assert_eq!(end_acks, vec![MavMissionResult::MAV_MISSION_OPERATION_CANCELLED]);
        assert_eq!(end_texts, vec!["Mission upload timed out".to_owned()]);
        assert!(!svc.upload_in_progress());
        assert_eq!(svc.mission().items, old);
        let late = svc.on_message(9100 * MS, SYSID, &GCS, &item_int(&new[2]));
        assert_eq!(acks(&late), vec![MavMissionResult::MAV_MISSION_ERROR], "too late: no upload");
        assert_eq!(svc.mission().items, old);
    }

    #[test]
    fn given_an_upload_in_progress_when_a_new_count_arrives_then_it_restarts_and_the_old_mission_stays_until_complete()
    {
        let old = waypoints(3, 50.0);
        let mut svc = with_mission(old.clone());
        let first = waypoints(5, 10.0);
        svc.on_message(0, SYSID, &GCS, &count(5));
        svc.on_message(MS, SYSID, &GCS, &item_int(&first[0]));
        svc.on_message(2 * MS, SYSID, &GCS, &item_int(&first[1]));
        let restart = svc.on_message(3 * MS, SYSID, &GCS, &count(4));
        assert_eq!(requests(&restart), vec![(0, Flavour::Int)]);
        assert!(acks(&restart).is_empty(), "no ACK for the abandoned upload");
        assert_eq!(svc.mission().items, old);
        let stale = svc.on_message(4 * MS, SYSID, &GCS, &item_int(&first[2]));
        assert_eq!(requests(&stale), vec![(0, Flavour::Int)], "an item of the old upload is ahead: re-request");
        let second = waypoints(4, 20.0);
        let (reply, _) = upload(&mut svc, 5 * MS, &second, false);
        assert_eq!(reply.event, Some(MissionEvent::Replaced(Mission { items: second.clone() })));
        assert_eq!(svc.mission().items, second);
    }

    #[test]
    fn given_an_upload_in_progress_when_request_list_clear_or_a_cancel_arrives_then_it_is_abandoned() {
        let old = waypoints(3, 50.0);
        let new = waypoints(5, 10.0);
        let mut svc = with_mission(old.clone());
        svc.on_message(0, SYSID, &GCS, &count(5));
        svc.on_message(MS, SYSID, &GCS, &item_int(&new[0]));
        let list = svc.on_message(2 * MS, SYSID, &GCS, &request_list());
        assert!(matches!(list.messages.as_slice(), [MavMessage::MISSION_COUNT(c)] if c.count == 3));
        assert!(!svc.upload_in_progress());
        assert_eq!(
            acks(&svc.on_message(3 * MS, SYSID, &GCS, &item_int(&new[1]))),
            vec![MavMissionResult::MAV_MISSION_ERROR]
        );
        assert_eq!(svc.mission().items, old);

        svc.on_message(4 * MS, SYSID, &GCS, &count(5));
        let cancel =
            svc.on_message(5 * MS, SYSID, &GCS, &client_ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
        assert_eq!(cancel, MissionReply::default());
        assert!(!svc.upload_in_progress());
        assert_eq!(svc.mission().items, old);

        svc.on_message(6 * MS, SYSID, &GCS, &count(5));
        svc.on_message(7 * MS, SYSID, &GCS, &item_int(&new[0]));
        let clear = svc.on_message(8 * MS, SYSID, &GCS, &clear_all());
        assert_eq!(acks(&clear), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(clear.event, Some(MissionEvent::Cleared));
        assert!(!svc.upload_in_progress());
        assert!(svc.mission().is_empty());
        assert_eq!(svc.poll(60 * S), MissionReply::default(), "nothing left to time out");
    }

    #[test]
    fn given_an_upload_when_items_are_duplicated_or_ahead_then_ignored_and_the_expected_seq_re_requested() {
        let mut svc = Svc::default();
        let items = waypoints(4, 10.0);
        svc.on_message(0, SYSID, &GCS, &count(4));
        assert_eq!(requests(&svc.on_message(100 * MS, SYSID, &GCS, &item_int(&items[0]))), vec![(1, Flavour::Int)]);
        let dup = svc.on_message(1000 * MS, SYSID, &GCS, &item_int(&items[0]));
        assert_eq!((requests(&dup), acks(&dup)), (vec![(1, Flavour::Int)], vec![]));
        let ahead = svc.on_message(1100 * MS, SYSID, &GCS, &item_int(&items[3]));
        assert_eq!((requests(&ahead), acks(&ahead)), (vec![(1, Flavour::Int)], vec![]));
        assert_eq!(requests(&svc.poll(1599 * MS)), vec![], "time-out runs from the last progress (0.1 s)");
        assert_eq!(requests(&svc.poll(1600 * MS)), vec![(1, Flavour::Int)]);
        svc.on_message(1700 * MS, SYSID, &GCS, &item_int(&items[1]));
        svc.on_message(1701 * MS, SYSID, &GCS, &item_int(&items[1]));
        svc.on_message(1702 * MS, SYSID, &GCS, &item_int(&items[2]));
        let done = svc.on_message(1703 * MS, SYSID, &GCS, &item_int(&items[3]));
        assert_eq!(acks(&done), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(svc.mission().items, items, "duplicates did not corrupt the mission");
        let again = svc.on_message(1800 * MS, SYSID, &GCS, &item_int(&items[3]));
        assert_eq!(acks(&again), vec![MavMissionResult::MAV_MISSION_ACCEPTED], "last item again: the ACK again");
        assert_eq!(again.event, None);
    }

    #[test]
    fn given_a_stored_mission_when_an_upload_holds_a_bad_item_then_refused_with_its_result_and_the_mission_unchanged() {
        let old = waypoints(3, 50.0);
        let mut nan_lat = item_legacy(&wp(2, 1, 1, 10.0));
        if let MavMessage::MISSION_ITEM(m) = &mut nan_lat {
            m.x = f32::NAN;
        }
        let cases = [
            (
                item_int(&with(2, MavCmd::MAV_CMD_DO_SET_SERVO, MavFrame::MAV_FRAME_MISSION, 1.0, 1500.0)),
                MavMissionResult::MAV_MISSION_UNSUPPORTED,
                "Mission: item 2: command 183 unsupported",
            ),
            (
                item_int(&MissionItem { frame: MavFrame::MAV_FRAME_LOCAL_NED, ..wp(2, 1, 1, 1.0) }),
                MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME,
                "Mission: item 2: frame 1 unsupported for cmd 16",
            ),
            (
                item_int(&with(2, MavCmd::MAV_CMD_DO_JUMP, MavFrame::MAV_FRAME_MISSION, 5.0, 1.0)),
                MavMissionResult::MAV_MISSION_INVALID_PARAM1,
                "Mission: item 2: jump target 5 not in 0..5",
            ),
            (nan_lat, MavMissionResult::MAV_MISSION_INVALID_PARAM5_X, "Mission: item 2: latitude not set"),
        ];
        for (bad, result, text) in cases {
            let mut svc = with_mission(old.clone());
            let new = waypoints(5, 10.0);
            svc.on_message(0, SYSID, &GCS, &count(5));
            svc.on_message(MS, SYSID, &GCS, &item_int(&new[0]));
            svc.on_message(2 * MS, SYSID, &GCS, &item_int(&new[1]));
            let reply = svc.on_message(3 * MS, SYSID, &GCS, &bad);
            assert_to(&reply, &GCS);
            assert_eq!(acks(&reply), vec![result]);
            assert_eq!(texts(&reply), vec![text.to_owned()]);
            assert_eq!((reply.event.clone(), requests(&reply).len()), (None, 0));
            assert!(!svc.upload_in_progress());
            assert_eq!(svc.mission().items, old);
            let more = svc.on_message(4 * MS, SYSID, &GCS, &item_int(&new[3]));
            assert_eq!(acks(&more), vec![MavMissionResult::MAV_MISSION_ERROR], "the upload is over");
            assert_eq!(svc.mission().items, old);
        }
    }

    #[test]
    fn given_a_mission_when_cleared_or_uploaded_with_count_0_then_accepted_cleared_and_empty() {
        let mut svc = with_mission(waypoints(3, 50.0));
        let reply = svc.on_message(0, SYSID, &GCS, &clear_all());
        assert_to(&reply, &GCS);
        assert_eq!(
            (acks(&reply), reply.event),
            (vec![MavMissionResult::MAV_MISSION_ACCEPTED], Some(MissionEvent::Cleared))
        );
        assert!(svc.mission().is_empty());
        assert_eq!(download(&mut svc, false).0, vec![]);

        let mut svc = with_mission(waypoints(3, 50.0));
        let reply = svc.on_message(0, SYSID, &GCS, &count(0));
        assert_eq!(
            (acks(&reply), reply.event),
            (vec![MavMissionResult::MAV_MISSION_ACCEPTED], Some(MissionEvent::Cleared))
        );
        assert!(svc.mission().is_empty() && !svc.upload_in_progress());
    }

    #[test]
    fn given_a_mission_when_set_current_in_and_out_of_range_then_set_current_or_a_statustext_only() {
        let mut svc = with_mission(waypoints(3, 50.0));
        let reply = svc.on_message(0, SYSID, &GCS, &set_current(2));
        assert_eq!(reply, MissionReply { messages: vec![], event: Some(MissionEvent::SetCurrent(2)) });
        assert_eq!(svc.current_seq(), 2);
        assert_eq!(download(&mut svc, false).1, vec![2], "downloads flag the current item");
        let reply = svc.on_message(0, SYSID, &GCS, &set_current(3));
        assert_eq!(reply.event, None);
        assert_eq!(acks(&reply), vec![]);
        assert_eq!(texts(&reply), vec!["Mission: set current 3: not in 0..3".to_owned()]);
        assert_eq!(svc.current_seq(), 2);
        let empty = Svc::default().on_message(0, SYSID, &GCS, &set_current(0));
        assert_eq!((empty.event.clone(), texts(&empty).len()), (None, 1));
    }

    #[test]
    fn given_no_mission_type_on_the_wire_when_a_client_lists_or_uploads_an_empty_set_then_count_0_and_accepted() {
        // The fence (1) and rally (2) transfers of clients are read as type 0: with nothing stored, a list
        // gets COUNT 0 and an empty upload is accepted, which is what those transfers expect.
        let mut svc = Svc::default();
        let reply = svc.on_message(0, SYSID, &GCS, &request_list());
        assert!(matches!(reply.messages.as_slice(), [MavMessage::MISSION_COUNT(c)] if c.count == 0));
        assert_eq!(acks(&svc.on_message(0, SYSID, &GCS, &count(0))), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        let reply = svc.on_message(
            0,
            SYSID,
            &GCS,
            &MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq: 0,
                target_system: SYSID,
                target_component: 1,
                ..Default::default()
            }),
        );
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_INVALID_SEQUENCE], "out of range");
    }

    #[test]
    fn given_messages_for_another_system_or_component_when_received_then_ignored() {
        let old = waypoints(3, 50.0);
        let mut svc = with_mission(old.clone());
        let retarget = |msg: MavMessage, ts: u8, tc: u8| match msg {
            MavMessage::MISSION_COUNT(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_COUNT(m)
            }
            MavMessage::MISSION_ITEM_INT(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_ITEM_INT(m)
            }
            MavMessage::MISSION_ITEM(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_ITEM(m)
            }
            MavMessage::MISSION_REQUEST_LIST(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_REQUEST_LIST(m)
            }
            MavMessage::MISSION_CLEAR_ALL(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_CLEAR_ALL(m)
            }
            MavMessage::MISSION_SET_CURRENT(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_SET_CURRENT(m)
            }
            MavMessage::MISSION_ACK(mut m) => {
                (m.target_system, m.target_component) = (ts, tc);
                MavMessage::MISSION_ACK(m)
            }
            other => other,
        };
        let all = || {
            vec![
                count(2),
                item_int(&old[0]),
                item_legacy(&old[0]),
                request_list(),
                clear_all(),
                set_current(1),
                client_ack(MavMissionResult::MAV_MISSION_ACCEPTED),
            ]
        };
        for (ts, tc) in [(2, 1), (2, 0), (1, 100)] {
            for msg in all() {
                let msg = retarget(msg, ts, tc);
                assert_eq!(svc.on_message(0, SYSID, &GCS, &msg), MissionReply::default(), "{msg:?}");
            }
        }
        assert_eq!(svc.mission().items, old);
        assert!(!svc.upload_in_progress());
        let broadcast = svc.on_message(0, SYSID, &GCS, &retarget(request_list(), 0, 0));
        assert_eq!(broadcast.messages.len(), 1, "broadcast is ours");
    }

    #[test]
    fn given_a_40_item_mission_when_uploaded_then_40_requests_and_an_identical_download() {
        let mut svc = Svc::default();
        let items = mission_items(40);
        let (reply, answered) = upload(&mut svc, 0, &items, false);
        assert_eq!(answered, 40);
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(svc.mission().len(), 40);
        assert_eq!(download(&mut svc, false).0, items);
    }

    #[test]
    fn given_no_upload_when_an_item_arrives_then_mission_error_and_a_statustext_as_px4() {
        let mut svc = Svc::default();
        let reply = svc.on_message(0, SYSID, &GCS, &item_int(&wp(0, 1, 1, 1.0)));
        assert_to(&reply, &GCS);
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_ERROR]);
        assert_eq!(texts(&reply), vec!["Mission item ignored: no upload".to_owned()]);
    }

    #[test]
    fn given_a_count_above_max_items_when_received_then_no_space_and_no_upload() {
        let mut svc = Svc::new(MissionServiceConfig { max_items: 10, ..MissionServiceConfig::default() });
        let reply = svc.on_message(0, SYSID, &GCS, &count(11));
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_NO_SPACE]);
        assert_eq!(texts(&reply), vec!["Mission: 11 items, at most 10".to_owned()]);
        assert!(!svc.upload_in_progress());
    }

    #[test]
    fn given_a_client_that_refuses_a_flavour_when_it_acks_unsupported_then_the_other_flavour_is_requested() {
        let mut svc = Svc::default();
        let items = waypoints(2, 10.0);
        svc.on_message(0, SYSID, &GCS, &count(2));
        svc.on_message(MS, SYSID, &GCS, &item_legacy(&items[0]));
        let nack = svc.on_message(2 * MS, SYSID, &GCS, &client_ack(MavMissionResult::MAV_MISSION_UNSUPPORTED));
        assert_eq!(requests(&nack), vec![(1, Flavour::Int)], "MAVSDK answers MISSION_REQUEST with UNSUPPORTED");
        let done = svc.on_message(3 * MS, SYSID, &GCS, &item_int(&items[1]));
        assert_eq!(acks(&done), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert_eq!(svc.mission().items, items);
    }

    #[test]
    fn given_a_legacy_only_client_when_it_ignores_request_int_then_the_retry_asks_with_mission_request() {
        let mut svc = Svc::new(MissionServiceConfig { item_timeout_us: 100 * MS, ..MissionServiceConfig::default() });
        svc.on_message(0, SYSID, &GCS, &count(1));
        assert_eq!(requests(&svc.poll(100 * MS)), vec![(0, Flavour::Legacy)]);
        assert_eq!(requests(&svc.poll(200 * MS)), vec![(0, Flavour::Int)], "alternating until an item arrives");
        let done = svc.on_message(250 * MS, SYSID, &GCS, &item_legacy(&wp(0, 1, 1, 1.0)));
        assert_eq!(acks(&done), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
    }

    #[test]
    fn given_an_upload_from_one_gcs_when_another_sends_an_item_then_it_gets_an_error_and_the_upload_goes_on() {
        let mut svc = Svc::default();
        let items = waypoints(2, 10.0);
        svc.on_message(0, SYSID, &GCS, &count(2));
        let intruder = svc.on_message(MS, SYSID, &OTHER_GCS, &item_int(&items[0]));
        assert_to(&intruder, &OTHER_GCS);
        assert_eq!(acks(&intruder), vec![MavMissionResult::MAV_MISSION_ERROR]);
        assert!(svc.upload_in_progress());
        svc.on_message(2 * MS, SYSID, &GCS, &item_int(&items[0]));
        let done = svc.on_message(3 * MS, SYSID, &GCS, &item_int(&items[1]));
        assert_eq!(acks(&done), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
    }

    #[test]
    fn given_an_invalid_mission_when_set_then_refused_and_the_stored_one_kept() {
        let mut svc = with_mission(waypoints(2, 10.0));
        let bad = Mission { items: vec![wp(0, XY_UNSET, 1, 1.0)] };
        assert_eq!(svc.set_mission(bad).map_err(|e| e.result()), Err(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X));
        assert_eq!(svc.mission().items, waypoints(2, 10.0));
    }

    /// A client's fence or rally transfer as QGroundControl runs it: every message carries the type.
    fn typed_upload(svc: &mut Svc, kind: PlanKind, items: &[MissionItem]) -> MissionReply {
        let t = kind.wire();
        let n = u16::try_from(items.len()).expect("small");
        let mut reply = svc.on_message(
            0,
            SYSID,
            &GCS,
            &MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count: n,
                target_system: SYSID,
                target_component: 1,
                mission_type: t,
                ..Default::default()
            }),
        );
        loop {
            let seq = match reply.messages.first() {
                Some(MavMessage::MISSION_REQUEST_INT(r)) => {
                    assert_eq!(r.mission_type, t, "requests carry the transfer's type");
                    r.seq
                }
                _ => return reply,
            };
            let item =
                MISSION_ITEM_INT_DATA { mission_type: t, ..items[usize::from(seq)].to_item_int(SYSID, 1, false) };
            reply = svc.on_message(0, SYSID, &GCS, &MavMessage::MISSION_ITEM_INT(item));
        }
    }

    fn typed_download(svc: &mut Svc, kind: PlanKind) -> Vec<MissionItem> {
        let t = kind.wire();
        let list = MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: SYSID,
            target_component: 1,
            mission_type: t,
        });
        let reply = svc.on_message(0, SYSID, &GCS, &list);
        let [MavMessage::MISSION_COUNT(c)] = reply.messages.as_slice() else { panic!("{reply:?}") };
        assert_eq!(c.mission_type, t);
        (0..c.count)
            .map(|seq| {
                let req = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                    seq,
                    target_system: SYSID,
                    target_component: 1,
                    mission_type: t,
                });
                match svc.on_message(0, SYSID, &GCS, &req).messages.as_slice() {
                    [MavMessage::MISSION_ITEM_INT(m)] if m.mission_type == t => MissionItem::from_item_int(m),
                    other => panic!("{other:?}"),
                }
            })
            .collect()
    }

    fn fence_vertex(seq: u16, n: u16, lat_dege7: i32, lon_dege7: i32) -> MissionItem {
        MissionItem {
            command: MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            param1: f32::from(n),
            param2: 0.0,
            param4: 0.0,
            z: 0.0,
            ..wp(seq, lat_dege7, lon_dege7, 0.0)
        }
    }

    #[test]
    fn given_fence_and_rally_uploads_then_each_is_stored_apart_from_the_mission_and_downloaded_identically() {
        let mut svc = with_mission(waypoints(3, 10.0));
        let fence: Vec<MissionItem> = (0..4)
            .map(|s| fence_vertex(s, 4, 473_970_000 + i32::from(s % 2) * 1000, 85_450_000 + i32::from(s / 2) * 1000))
            .collect();
        let reply = typed_upload(&mut svc, PlanKind::Fence, &fence);
        assert!(matches!(reply.messages.as_slice(), [MavMessage::MISSION_ACK(a)]
            if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED && a.mission_type == MavMissionType::MAV_MISSION_TYPE_FENCE));
        assert!(matches!(reply.event, Some(MissionEvent::FenceReplaced(ref f)) if f.zones().len() == 1));
        let rally = [MissionItem { command: MavCmd::MAV_CMD_NAV_RALLY_POINT, ..wp(0, 473_971_000, 85_451_000, 15.0) }];
        assert!(matches!(typed_upload(&mut svc, PlanKind::Rally, &rally).event, Some(MissionEvent::RallyReplaced(_))));
        assert_eq!(typed_download(&mut svc, PlanKind::Fence), fence);
        assert_eq!(typed_download(&mut svc, PlanKind::Rally), rally);
        assert_eq!(svc.mission().len(), 3, "the mission is untouched");
        // A waypoint in a fence upload, and a 2-vertex polygon, are refused with their reasons.
        let reply = typed_upload(&mut svc, PlanKind::Fence, &waypoints(1, 10.0));
        assert_eq!(acks(&reply), vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]);
        let short = [fence_vertex(0, 4, 473_970_000, 85_450_000), fence_vertex(1, 4, 473_971_000, 85_450_000)];
        let reply = typed_upload(&mut svc, PlanKind::Fence, &short);
        assert_eq!(texts(&reply), vec!["Fence: item 0: polygon vertex count mismatch".to_owned()]);
        assert_eq!(typed_download(&mut svc, PlanKind::Fence), fence, "a refused upload changes nothing");
        // Clear ALL clears the three.
        let clear = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            target_system: SYSID,
            target_component: 1,
            mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
        });
        assert_eq!(svc.on_message(0, SYSID, &GCS, &clear).event, Some(MissionEvent::ClearedAll));
        assert!(typed_download(&mut svc, PlanKind::Fence).is_empty() && svc.mission().is_empty());
    }
}

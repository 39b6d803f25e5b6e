//! The one router and the one shape of a MAVLink microservice. In: a message from a ground station with
//! its header, the vehicle time (µs) and what the services need to know of the vehicle
//! ([`MessageContext`]). Out: which service the message belongs to ([`route`]: one match, so no message
//! reaches two services and none is claimed by a hand-kept predicate), and that service's
//! [`ServiceReply`]: the messages to send back, and what it asks of the vehicle (an effect the vehicle
//! applies: a parameter change, a mission event, a command, an offboard setpoint, a ground station's
//! HEARTBEAT for the datalink failsafe, the pilot's sticks).

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{MavMessage, MavSeverity, MavType};

use super::command::{CommandContext, InboundCommand, decode_command};
use super::housekeeping;
use super::mission::{MissionEvent, MissionService};
use super::offboard::{self, OffboardContext};
use super::params::{ParamChange, ParamService};
use super::statustext;
use crate::core::navigator::OffboardSetpoint;
use crate::core::params::ParamStore;
use crate::core::plan::Plan;

/// The microservices a ground station's message can belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Service {
    /// PING and FTP (answered NAK): replies only.
    Housekeeping,
    /// SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT, SET_ATTITUDE_TARGET.
    Offboard,
    /// PARAM_REQUEST_LIST / _READ, PARAM_SET.
    Params,
    /// The mission protocol (every mission_type).
    Mission,
    /// COMMAND_LONG, COMMAND_INT, SET_MODE.
    Command,
    /// HEARTBEAT: a ground station's keeps the datalink alive.
    Heartbeat,
    /// MANUAL_CONTROL, RC_CHANNELS_OVERRIDE: the pilot's sticks.
    Manual,
}

/// The service `msg` belongs to (None: nothing of ours, such as a ground station's HEARTBEAT).
// The legacy float items and MISSION_SET_CURRENT are deprecated, but older clients still send them.
#[allow(deprecated)]
#[must_use]
pub fn route(msg: &MavMessage) -> Option<Service> {
    use MavMessage as M;
    Some(match msg {
        M::PING(_) | M::FILE_TRANSFER_PROTOCOL(_) => Service::Housekeeping,
        M::SET_POSITION_TARGET_LOCAL_NED(_) | M::SET_POSITION_TARGET_GLOBAL_INT(_) | M::SET_ATTITUDE_TARGET(_) => {
            Service::Offboard
        }
        M::PARAM_REQUEST_LIST(_) | M::PARAM_REQUEST_READ(_) | M::PARAM_SET(_) => Service::Params,
        M::MISSION_COUNT(_)
        | M::MISSION_ITEM(_)
        | M::MISSION_ITEM_INT(_)
        | M::MISSION_REQUEST(_)
        | M::MISSION_REQUEST_INT(_)
        | M::MISSION_REQUEST_LIST(_)
        | M::MISSION_ACK(_)
        | M::MISSION_CLEAR_ALL(_)
        | M::MISSION_SET_CURRENT(_) => Service::Mission,
        M::COMMAND_LONG(_) | M::COMMAND_INT(_) | M::SET_MODE(_) => Service::Command,
        M::HEARTBEAT(_) => Service::Heartbeat,
        M::MANUAL_CONTROL(_) | M::RC_CHANNELS_OVERRIDE(_) => Service::Manual,
        _ => return None,
    })
}

/// What a service knows of the message and the vehicle.
#[derive(Debug, Clone, Copy)]
pub struct MessageContext<'a> {
    /// Vehicle time (µs).
    pub now_us: u64,
    /// Our system id.
    pub sysid: u8,
    /// The sender's header.
    pub header: &'a MavHeader,
    pub command: CommandContext,
    pub offboard: OffboardContext,
}

/// A service's answer to one message.
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceReply<E> {
    /// To send (to the sender, or to every ground station for broadcasts such as PARAM_VALUE).
    pub messages: Vec<MavMessage>,
    /// What the vehicle is asked to do.
    pub effect: Option<E>,
}

impl<E> ServiceReply<E> {
    fn of(messages: Vec<MavMessage>, effect: Option<E>) -> Self {
        Self { messages, effect }
    }
}

/// A MAVLink microservice: one message in, its reply out. `State` is the part of the vehicle the service
/// works on (the parameter store), `()` for the rest.
pub trait Microservice {
    type State;
    type Effect;
    fn handle(
        &mut self,
        ctx: &MessageContext<'_>,
        msg: &MavMessage,
        state: &mut Self::State,
    ) -> ServiceReply<Self::Effect>;
}

/// PING and FTP.
#[derive(Debug, Clone, Copy, Default)]
pub struct Housekeeping;

impl Microservice for Housekeeping {
    type State = ();
    type Effect = ();

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, (): &mut ()) -> ServiceReply<()> {
        ServiceReply::of(housekeeping::reply(ctx.sysid, ctx.header, msg).into_iter().collect(), None)
    }
}

/// Offboard setpoints: decoded into local NED; a refused stream says why once, not 20 times a second.
/// A setpoint that decodes is the vehicle's to take ([`OffboardReceiver::taken`]) or refuse
/// ([`OffboardReceiver::refuse`]: outside the geofence, too far from home).
#[derive(Debug, Clone, Default)]
pub struct OffboardReceiver {
    last_refusal: Option<String>,
    /// When the vehicle last took a setpoint (µs of vehicle time).
    taken_us: Option<u64>,
}

impl OffboardReceiver {
    /// The vehicle flies the setpoint received at `now_us`: the next refusal is said again.
    pub fn taken(&mut self, now_us: u64) {
        self.last_refusal = None;
        self.taken_us = Some(now_us);
    }

    /// Whether setpoints flow: the last one taken is younger than `timeout_s` (COM_OF_LOSS_T) at `now_us`.
    #[must_use]
    pub fn fresh(&self, now_us: u64, timeout_s: f64) -> bool {
        self.taken_us.is_some_and(|t| now_us.saturating_sub(t) <= crate::core::seconds_to_us(timeout_s))
    }

    /// A refused setpoint's STATUSTEXT, once per run of the same refusal.
    pub fn refuse(&mut self, text: String) -> Vec<MavMessage> {
        if self.last_refusal.as_deref() == Some(text.as_str()) {
            return Vec::new();
        }
        let reply = statustext(MavSeverity::MAV_SEVERITY_WARNING, &text);
        self.last_refusal = Some(text);
        vec![reply]
    }
}

impl Microservice for OffboardReceiver {
    type State = ();
    type Effect = OffboardSetpoint;

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, (): &mut ()) -> ServiceReply<OffboardSetpoint> {
        match offboard::decode(ctx.sysid, msg, &ctx.offboard) {
            Some(Ok(sp)) => ServiceReply::of(Vec::new(), Some(sp)),
            Some(Err(text)) => ServiceReply::of(self.refuse(text), None),
            None => ServiceReply::of(Vec::new(), None),
        }
    }
}

impl Microservice for ParamService {
    type State = ParamStore;
    type Effect = ParamChange;

    fn handle(
        &mut self,
        ctx: &MessageContext<'_>,
        msg: &MavMessage,
        store: &mut ParamStore,
    ) -> ServiceReply<ParamChange> {
        let reply = ParamService::on_message(self, ctx.sysid, ctx.header, msg, store);
        ServiceReply::of(reply.messages, reply.changed)
    }
}

impl Microservice for MissionService {
    type State = Plan;
    type Effect = MissionEvent;

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, plan: &mut Plan) -> ServiceReply<MissionEvent> {
        let reply = MissionService::on_message(self, plan, ctx.now_us, ctx.sysid, ctx.header, msg);
        ServiceReply::of(reply.messages, reply.event)
    }
}

/// COMMAND_LONG / COMMAND_INT / SET_MODE: decoded into the command to apply (the vehicle answers it with
/// its ACK once applied).
#[derive(Debug, Clone, Copy, Default)]
pub struct Commands;

impl Microservice for Commands {
    type State = ();
    type Effect = InboundCommand;

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, (): &mut ()) -> ServiceReply<InboundCommand> {
        ServiceReply::of(Vec::new(), decode_command(ctx.sysid, ctx.header, msg, &ctx.command))
    }
}

/// Ground-station HEARTBEATs (MAV_TYPE_GCS, from another system): each is the vehicle time it came at, the
/// datalink failsafe's clock. Other components' heartbeats (a companion, the plant) do not count.
#[derive(Debug, Clone, Copy, Default)]
pub struct GcsHeartbeats;

impl Microservice for GcsHeartbeats {
    type State = ();
    type Effect = u64;

    fn handle(&mut self, ctx: &MessageContext<'_>, msg: &MavMessage, (): &mut ()) -> ServiceReply<u64> {
        let from_gcs = matches!(msg, MavMessage::HEARTBEAT(h) if h.mavtype == MavType::MAV_TYPE_GCS)
            && ctx.header.system_id != u32::from(ctx.sysid);
        ServiceReply::of(Vec::new(), from_gcs.then_some(ctx.now_us))
    }
}

#[cfg(test)]
mod tests {
    #[allow(deprecated)]
    use ::mavlink::dialects::common::{HEARTBEAT_DATA, PARAM_SET_DATA, PING_DATA};

    use super::*;

    #[test]
    #[allow(deprecated)]
    fn given_messages_of_each_protocol_then_exactly_one_service_claims_each_and_heartbeats_none() {
        assert_eq!(route(&MavMessage::PING(PING_DATA::default())), Some(Service::Housekeeping));
        assert_eq!(route(&MavMessage::PARAM_SET(PARAM_SET_DATA::default())), Some(Service::Params));
        assert_eq!(route(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())), Some(Service::Heartbeat));
        assert_eq!(route(&MavMessage::ATTITUDE(Default::default())), None);
        let mission = MavMessage::MISSION_REQUEST_LIST(Default::default());
        assert_eq!(route(&mission), Some(Service::Mission));
        assert_eq!(route(&MavMessage::COMMAND_LONG(Default::default())), Some(Service::Command));
        assert_eq!(route(&MavMessage::SET_ATTITUDE_TARGET(Default::default())), Some(Service::Offboard));
    }

    #[test]
    fn given_setpoints_taken_then_they_are_fresh_for_com_of_loss_t_of_vehicle_time_and_stale_after() {
        let mut rx = OffboardReceiver::default();
        assert!(!rx.fresh(0, 0.5), "none taken yet");
        rx.taken(1_000_000);
        assert!(rx.fresh(1_000_000, 0.5));
        assert!(rx.fresh(1_500_000, 0.5), "fresh at exactly COM_OF_LOSS_T");
        assert!(!rx.fresh(1_500_001, 0.5), "stale 1 µs after it");
        rx.taken(1_600_000);
        assert!(rx.fresh(2_000_000, 0.5), "a new setpoint is fresh again");
    }
}

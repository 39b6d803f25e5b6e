//! The vehicle's side of the ground-station conversation: a message in, applied at once (a command, a
//! parameter, a mission transfer, an offboard setpoint, a HEARTBEAT) and answered to its sender; the
//! plans loaded at start; the checks of commanded targets (through the one resolver and the setpoint
//! guard). The vehicle's step is in `mod.rs`.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{MavMessage, MavSeverity};
use nalgebra::Vector3;

use super::{ShellEffect, Vehicle, weights_interval_us};
use crate::core::commander::{Facts, FlightMode, Request};
use crate::core::control::ControllerKind;
use crate::core::estimator::EstimatorState;
use crate::core::manual::PilotAction;
use crate::core::manual::input::fltmode_flight_mode;
use crate::core::mavlink::command::{AUTOPILOT_VERSION_ID, InboundCommand};
use crate::core::mavlink::failure::Requester;
use crate::core::mavlink::manual::ManualControlInput;
use crate::core::mavlink::mission::MissionEvent;
use crate::core::mavlink::offboard::OffboardContext;
use crate::core::mavlink::params::{ParamChange, param_value};
use crate::core::mavlink::router::{
    self, Commands, GcsHeartbeats, Housekeeping, MessageContext, Microservice, Service,
};
use crate::core::mavlink::{
    CommandContext, CommandEffect, CommandPoint, Stream, VehicleCommand, command_replies, housekeeping,
    mission_current, statustext, statustext_chunks,
};
use crate::core::mission::{Mission, MissionError, NavTarget, items_to_wpl};
use crate::core::navigator::OffboardSetpoint;
use crate::core::params::ParamStore;
use crate::core::plan::geofence::{Fence, Rally, Violation};
use crate::core::plan::{self, Unresolved};

/// What a ground station's message asks of the vehicle, once its service has decoded it.
enum Effect {
    Offboard(OffboardSetpoint),
    /// A parameter set (the store as it was before, to undo a value that makes the vehicle unflyable).
    Param {
        change: ParamChange,
        before: ParamStore,
    },
    Mission(MissionEvent),
    /// A ground station's HEARTBEAT at this vehicle time (µs), the datalink failsafe's clock.
    GcsHeartbeat(u64),
    Command(InboundCommand),
    /// The pilot's sticks (MANUAL_CONTROL) or radio (RC_CHANNELS_OVERRIDE).
    Manual(ManualControlInput),
}

impl Vehicle {
    /// A message from a ground station at `now_us`: commands are applied at once and answered (ACK, and
    /// STATUSTEXT on refusal, then any message the command asked for) to the sender; PING and FTP get
    /// their replies; offboard setpoints are taken; anything else, or anything for another system, gets
    /// nothing.
    pub fn handle_message(&mut self, now_us: u64, header: &MavHeader, msg: &MavMessage) -> Vec<MavMessage> {
        // An injected link or manual-control failure: the vehicle does not hear it (`mavlink::failure`).
        if !self.failures.hears(msg) {
            return Vec::new();
        }
        let Some(service) = router::route(msg) else {
            return Vec::new();
        };
        let est = *self.estimator.state();
        let home_alt_amsl_m = self.home_alt_amsl_m();
        let ctx = MessageContext {
            now_us,
            sysid: self.config.sysid,
            header,
            command: CommandContext { home_alt_amsl_m },
            offboard: OffboardContext { origin: est.origin, home_alt_amsl_m, yaw_rad: est.euler_rad.z },
        };
        let (messages, effect) = match service {
            Service::Housekeeping => (Housekeeping.handle(&ctx, msg, &mut ()).messages, None),
            Service::Offboard => {
                let reply = self.offboard.handle(&ctx, msg, &mut ());
                (reply.messages, reply.effect.map(Effect::Offboard))
            }
            Service::Params => {
                let before = self.params.clone();
                let reply = self.param_service.handle(&ctx, msg, &mut self.params);
                (reply.messages, reply.effect.map(|change| Effect::Param { change, before }))
            }
            Service::Mission => {
                let reply = self.missions.handle(&ctx, msg, &mut self.plan);
                (reply.messages, reply.effect.map(Effect::Mission))
            }
            Service::Heartbeat => {
                (Vec::new(), GcsHeartbeats.handle(&ctx, msg, &mut ()).effect.map(Effect::GcsHeartbeat))
            }
            Service::Command => (Vec::new(), Commands.handle(&ctx, msg, &mut ()).effect.map(Effect::Command)),
            Service::Manual => (Vec::new(), self.manual_service.handle(&ctx, msg, &mut ()).effect.map(Effect::Manual)),
        };
        match effect {
            Some(effect) => self.apply(now_us, messages, effect),
            None => messages,
        }
    }

    /// Applies what a service decoded, after its own `replies`; returns every message to send the peer.
    fn apply(&mut self, now_us: u64, mut replies: Vec<MavMessage>, effect: Effect) -> Vec<MavMessage> {
        match effect {
            Effect::Offboard(sp) => {
                if sp.rate_frd_radps.is_some() && !self.config.controller.flies_rates() {
                    replies.extend(self.offboard.refuse(no_rate_loop("Offboard rates", self.config.controller)));
                    return replies;
                }
                match sp.pos_ned_m.map(|p| self.check_setpoint(&p)) {
                    Some(Err(why)) => replies.extend(self.offboard.refuse(format!("Offboard: setpoint {why}"))),
                    _ => {
                        self.offboard.taken(now_us);
                        self.navigator.set_offboard(sp);
                    }
                }
                replies
            }
            Effect::Param { change, before } => match self.on_param_change(&change) {
                Ok(extra) => replies.into_iter().chain(extra).collect(),
                Err(text) => {
                    // In range, but the configuration it makes is not flyable: undo it, in words (in chunks
                    // when it is longer than one STATUSTEXT), and say the value it still has.
                    self.params = before;
                    self.text_id = self.text_id.wrapping_add(1).max(1);
                    let mut messages = statustext_chunks(MavSeverity::MAV_SEVERITY_WARNING, &text, self.text_id);
                    messages.extend(param_value(&self.params, change.index));
                    messages
                }
            },
            Effect::Mission(event) => {
                replies.extend(self.on_mission_event(event));
                replies
            }
            Effect::GcsHeartbeat(t) => {
                self.gcs_heartbeat_us = Some(t);
                replies
            }
            Effect::Command(cmd) => {
                replies.extend(self.apply_command(now_us, &cmd));
                replies
            }
            Effect::Manual(ManualControlInput::Joystick(sticks)) => {
                self.manual.on_joystick(now_us, sticks);
                replies
            }
            Effect::Manual(ManualControlInput::Rc(frame)) => {
                self.manual.on_rc(now_us, frame, &self.config.manual);
                replies
            }
        }
    }

    /// A request of the commander with the vehicle's facts, a mission checked against the fence first.
    fn request(&mut self, now_us: u64, facts: Facts, req: Request) -> Result<(), String> {
        if matches!(req, Request::Mission | Request::SetMode(FlightMode::Mission)) {
            self.check_mission()?;
        }
        if req == Request::SetMode(FlightMode::Acro) && !self.config.controller.flies_rates() {
            return Err(no_rate_loop("ACRO", self.config.controller));
        }
        self.commander.request(now_us, facts, req).map_err(|r| r.to_string())
    }

    /// What the pilot did with a switch or the sticks (see [`PilotAction`]), as a request of the
    /// commander; the refusal's words when it is refused (the pilot has no ACK: a STATUSTEXT says it).
    pub(super) fn pilot_action(&mut self, now_us: u64, action: PilotAction) -> Result<(), String> {
        let facts = self.facts(now_us);
        let req = match action {
            PilotAction::ModeSwitch { mode, .. } => Request::SetMode(fltmode_flight_mode(mode)?),
            PilotAction::KillSwitch(on) => Request::KillSwitch(on),
            PilotAction::ArmGesture if !self.commander.mode().is_manual() => {
                return Err("Arming denied: switch to a manual mode".to_owned());
            }
            PilotAction::ArmSwitch(true) | PilotAction::ArmGesture => Request::Arm { force: false },
            PilotAction::ArmSwitch(false) | PilotAction::DisarmGesture => Request::Disarm { force: false },
        };
        self.request(now_us, facts, req)
    }

    /// Applies a command and answers it: its ACK (and STATUSTEXT on refusal), then any message it asked
    /// for.
    fn apply_command(&mut self, now_us: u64, cmd: &InboundCommand) -> Vec<MavMessage> {
        let mut extra = Vec::new();
        let facts = self.facts(now_us);
        if matches!(cmd.effect, CommandEffect::Request(Request::Disarm { .. } | Request::Kill)) {
            // A disarm, kill or termination stops a motor test too, whatever the commander answers.
            self.motor_test.stop();
        }
        let outcome = match cmd.effect.clone() {
            CommandEffect::InjectFailure(request) => {
                // Answered by the failure-injection service: now, or when the plant has answered.
                let from = Requester { system: cmd.sender_system, component: cmd.sender_component };
                return self.failures.inject(now_us, from, request, self.params.failure_injection_enabled());
            }
            CommandEffect::Request(req) => self.request(now_us, facts, req).map_err(Some),
            CommandEffect::Vehicle(command) => self.vehicle_command(now_us, facts, command, &mut extra),
            CommandEffect::Deny(text) => Err(Some(text)),
            CommandEffect::Unsupported => Err(None),
        };
        let accepted = outcome.is_ok();
        let mut replies = command_replies(cmd, outcome);
        if accepted {
            replies.extend(extra);
        }
        replies
    }

    /// A geodetic point of a command in local NED (altitude NaN: the vehicle's), by the one resolver.
    fn local_point(&self, point: &CommandPoint) -> Result<Vector3<f64>, Option<String>> {
        let target = NavTarget::Global {
            lat_deg: point.lat_deg,
            lon_deg: point.lon_deg,
            alt_m: point.alt_m,
            relative: point.relative_alt,
        };
        plan::resolve(&target, &self.frame(), self.estimator.state().pos_ned_m).map_err(|why| {
            Some(
                match why {
                    Unresolved::NoOrigin => "No global position yet",
                    Unresolved::NoHomeAltitude => "No home altitude yet",
                    Unresolved::Invalid => "Invalid position",
                }
                .to_owned(),
            )
        })
    }

    /// A command the vehicle answers itself; `extra` gets the messages it asked for (sent after the ACK).
    fn vehicle_command(
        &mut self,
        now_us: u64,
        facts: Facts,
        command: VehicleCommand,
        extra: &mut Vec<MavMessage>,
    ) -> Result<(), Option<String>> {
        match command {
            VehicleCommand::RequestMessage { message_id } => {
                if message_id == AUTOPILOT_VERSION_ID {
                    extra.push(housekeeping::autopilot_version(self.config.sysid));
                    return Ok(());
                }
                let stream = Stream::of_message(message_id).ok_or(None)?;
                let home = self.home();
                let messages = stream.messages(&self.snapshot(now_us, home.as_ref()));
                if messages.is_empty() {
                    // Not yet (no home, no fix): DENIED, quietly (MAVSDK asks three times a second).
                    return Err(Some(String::new()));
                }
                extra.extend(messages);
                Ok(())
            }
            VehicleCommand::SetMessageInterval { message_id, interval_us } => {
                let stream = Stream::of_message(message_id).ok_or(None)?;
                let us = if interval_us < 0.0 {
                    0
                } else if interval_us == 0.0 {
                    stream.default_interval_us()
                } else {
                    interval_us.round() as u64
                };
                self.mavlink.streams_mut().set_interval_us(stream, us);
                Ok(())
            }
            VehicleCommand::GetMessageInterval { message_id } => {
                let stream = Stream::of_message(message_id).ok_or(None)?;
                extra
                    .push(housekeeping::message_interval(message_id, Some(self.mavlink.streams().interval_us(stream))));
                Ok(())
            }
            VehicleCommand::ChangeSpeed { speed_mps } => {
                self.navigator.set_speed(speed_mps);
                Ok(())
            }
            VehicleCommand::SetHome { point } => {
                let pos_ned_m = point.map(|p| self.local_point(&p)).transpose()?;
                self.commander.request(now_us, facts, Request::SetHome { pos_ned_m }).map_err(|r| Some(r.to_string()))
            }
            VehicleCommand::Reposition { point, yaw_rad } => {
                let pos_ned_m = point.map(|p| self.local_point(&p)).transpose()?;
                if let Some(p) = pos_ned_m {
                    self.check_setpoint(&p).map_err(|why| Some(format!("Reposition: {why}")))?;
                }
                self.commander
                    .request(now_us, facts, Request::Goto { pos_ned_m, yaw_rad })
                    .map_err(|r| Some(r.to_string()))
            }
            VehicleCommand::MissionStart { first } => {
                if self.navigator.mission_len() == 0 {
                    return Err(Some("Mission start: no mission".to_owned()));
                }
                self.check_mission().map_err(Some)?;
                self.navigator.set_current(first);
                self.commander.request(now_us, facts, Request::Mission).map_err(|r| Some(r.to_string()))
            }
            VehicleCommand::Reboot => {
                if self.commander.armed() {
                    return Err(Some("Reboot denied: armed".to_owned()));
                }
                self.effects.push(ShellEffect::Reboot);
                Ok(())
            }
            VehicleCommand::NoOp => Ok(()),
            VehicleCommand::MotorTest(request) => {
                // PX4's order: armed first, then the enable parameter.
                if self.commander.armed() {
                    return Err(Some("Motor test denied: armed".to_owned()));
                }
                if !self.params.motor_test_enabled() {
                    return Err(Some("Motor test denied: disabled".to_owned()));
                }
                // Killed (a kill or flight termination): the motors stay stopped until the pilot rearms.
                if self.commander.state() == crate::core::commander::State::Killed {
                    return Err(Some("Motor test denied: killed".to_owned()));
                }
                self.motor_test.request(now_us, request);
                Ok(())
            }
        }
    }

    /// Applies a changed parameter from the next step (gains, rates, limits, timers, speeds; the loop
    /// rates only after a restart), and asks for the parameters to be persisted. Returns the messages to
    /// send (a STATUSTEXT when the change needs a restart).
    ///
    /// # Errors
    /// The reason, when the configuration the parameter makes is not flyable; nothing changed then.
    fn on_param_change(&mut self, change: &ParamChange) -> Result<Vec<MavMessage>, String> {
        let mut next = self.config.clone();
        self.params.apply(&mut next);
        // Everything is checked now, the values that apply only after a restart (the loop rates) too:
        // a value that would stop the next start is refused when it is set.
        next.validate().map_err(|e| format!("{}: {e}", change.name))?;
        // The loop rates apply only when the vehicle is rebuilt with the stored parameters (a restart).
        next.control.rates = self.config.control.rates;
        self.commander.set_config(next.commander).map_err(|e| format!("{}: {e}", change.name))?;
        self.control.reconfigure(&next.control);
        self.navigator.set_config(next.navigator);
        self.mavlink
            .streams_mut()
            .set_interval_us(Stream::AdaptiveWeights, weights_interval_us(self.params.aco_weights_hz()));
        self.config = next;
        self.effects.push(ShellEffect::SaveParams(self.params.to_text()));
        Ok(if change.restart_required {
            vec![statustext(MavSeverity::MAV_SEVERITY_NOTICE, &format!("{} applies after a restart", change.name))]
        } else {
            Vec::new()
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &ParamStore {
        &self.params
    }

    /// Applies a mission upload, clear or set-current; returns the messages to send (MISSION_CURRENT).
    fn on_mission_event(&mut self, event: MissionEvent) -> Vec<MavMessage> {
        match event {
            MissionEvent::Replaced(mission) => {
                self.navigator.set_mission(self.plan.items());
                self.effects.push(ShellEffect::SaveMission(mission.to_wpl()));
                // Accepted (it is a valid mission), but said now: it will not start while it leaves the fence.
                self.check_mission()
                    .err()
                    .map(|why| statustext(MavSeverity::MAV_SEVERITY_WARNING, &why))
                    .into_iter()
                    .collect()
            }
            MissionEvent::Cleared => {
                self.navigator.set_mission(self.plan.items());
                self.effects.push(ShellEffect::SaveMission(self.plan.mission().to_wpl()));
                Vec::new()
            }
            MissionEvent::FenceReplaced(fence) => {
                self.effects.push(ShellEffect::SaveFence(items_to_wpl(fence.items())));
                let mut out = Vec::new();
                if let Err(why) = self.check_mission() {
                    out.push(statustext(MavSeverity::MAV_SEVERITY_WARNING, &why));
                }
                out
            }
            MissionEvent::RallyReplaced(rally) => {
                self.effects.push(ShellEffect::SaveRally(items_to_wpl(rally.items())));
                Vec::new()
            }
            MissionEvent::ClearedAll => {
                self.navigator.set_mission(self.plan.items());
                self.effects.push(ShellEffect::SaveMission(self.plan.mission().to_wpl()));
                self.effects.push(ShellEffect::SaveFence(items_to_wpl(&[])));
                self.effects.push(ShellEffect::SaveRally(items_to_wpl(&[])));
                Vec::new()
            }
            MissionEvent::SetCurrent(seq) => {
                self.navigator.set_current(seq);
                vec![mission_current(seq)]
            }
        }
    }

    /// A mission loaded at start (persisted by an earlier run).
    ///
    /// # Errors
    /// The mission's first invalid item; the vehicle then has no mission.
    pub fn load_mission(&mut self, mission: Mission) -> Result<(), MissionError> {
        self.plan.set_mission(mission)?;
        self.navigator.set_mission(self.plan.items());
        Ok(())
    }

    /// A geofence loaded at start (persisted by an earlier run).
    pub fn load_fence(&mut self, fence: Fence) {
        self.plan.set_fence(fence);
    }

    /// Rally points loaded at start (persisted by an earlier run).
    pub fn load_rally(&mut self, rally: Rally) {
        self.plan.set_rally(rally);
    }

    /// The geofence and the rally points as uploaded.
    #[must_use]
    pub fn fence_and_rally(&self) -> (&Fence, &Rally) {
        (self.plan.fence(), self.plan.rally())
    }

    /// Why the vehicle will not fly to `pos_ned_m` (NED m): see [`SetpointGuard::check`].
    fn check_setpoint(&self, pos_ned_m: &Vector3<f64>) -> Result<(), String> {
        self.guard().check(pos_ned_m)
    }

    /// The geofence breach predicted from the estimate, braking as the navigator brakes (MPC_ACC_HOR,
    /// MPC_JERK_AUTO).
    pub(super) fn fence_breach(&self, state: &EstimatorState) -> Option<Violation> {
        if !state.flags.position_valid {
            return None;
        }
        let nav = &self.config.navigator;
        self.guard().predicted_breach(&state.pos_ned_m, &state.vel_ned_mps, nav.acc_hor_mps2, nav.jerk_mps3)
    }

    /// Why the mission cannot be flown: an item, resolved as the navigator flies it, outside the geofence
    /// or too far.
    /// Items the frame cannot place yet (no origin) have nothing to check.
    fn check_mission(&self) -> Result<(), String> {
        self.guard().check_mission(&self.plan.items(), &self.frame())
    }

    /// The mission as uploaded.
    #[must_use]
    pub fn mission(&self) -> &Mission {
        self.plan.mission()
    }

    /// What the vehicle asks of the shell (restart, save parameters or the mission), since the last call.
    pub fn take_effects(&mut self) -> Vec<ShellEffect> {
        std::mem::take(&mut self.effects)
    }
}

/// The refusal of a rate-level request (`what`: Acro, offboard body rates) for a controller without a
/// rate loop.
fn no_rate_loop(what: &str, controller: ControllerKind) -> String {
    format!("{what} refused: {controller} has no rate loop")
}

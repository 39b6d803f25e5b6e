//! The plant server's SIM_ side: the hook polled between steps ([`PlantHook`], the SIM_ port), the
//! plant's one SIM_ parameter service the server holds (failure injections forwarded by the autopilot and
//! a scenario's timed sets go through it, the SIM_ port answers from it) and the step that fires the
//! timed sets due before the plant steps.

use std::io;
use std::time::Instant;

use mavlink::MavHeader;
use mavlink::dialects::common::{COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavMessage};

use super::{HOOK_WAIT_INTERVAL, LinkError, PlantServer, Transport};
use crate::plant::Plant;
use crate::sim_params::{SimEvent, SimEvents, SimParamLink, SimParamService};

/// Something polled between plant steps that may change the plant (its wind) before the next step, such
/// as the SIM_ port. A poll must not block.
pub trait PlantHook: Send + std::fmt::Debug {
    /// Called with the plant and the server's SIM_ parameter service between two steps: every
    /// [`super::HOOK_EVERY_STEPS`] steps and at least every [`HOOK_WAIT_INTERVAL`] while the server waits.
    ///
    /// # Errors
    /// An I/O error that is not transient; it ends the server's run as [`LinkError::Hook`].
    fn poll(&mut self, plant: &mut Plant, sim: &mut SimParamService) -> io::Result<()>;

    /// Called after every plant step with the plant as it now is, to take samples on plant time (the
    /// SIM_ port's truth stream). It must be cheap and make no system call: what it takes goes out at
    /// the next [`PlantHook::poll`].
    fn stepped(&mut self, _plant: &Plant) {}
}

/// The SIM_ port as the server's hook: it answers from the server's service.
impl PlantHook for SimParamLink {
    fn poll(&mut self, plant: &mut Plant, sim: &mut SimParamService) -> io::Result<()> {
        SimParamLink::poll(self, sim, plant)
    }

    fn stepped(&mut self, plant: &Plant) {
        SimParamLink::stepped(self, plant);
    }
}

impl<T: Transport> PlantServer<T> {
    /// Poll `hook` between steps from now on (replacing any earlier one).
    pub fn set_hook(&mut self, hook: Box<dyn PlantHook>) {
        self.hook = Some((hook, Instant::now()));
    }

    /// Serve the plant's SIM_ parameters on `port` from now on: the server's service answers for the
    /// port's system, and the port is the server's hook (replacing any earlier one).
    pub fn set_sim_port(&mut self, port: SimParamLink) {
        self.sim.set_system_id(port.system_id());
        self.set_hook(Box::new(port));
    }

    /// Fire `schedule` (a scenario's `[[event]]`, from `crate::sim_params::events::resolve`) through the
    /// server's SIM_ parameter service, each event just before the first step at or after its time.
    pub fn set_sim_events(&mut self, schedule: Vec<SimEvent>) {
        self.events = SimEvents::new(schedule);
    }

    /// The plant's SIM_ parameter service (its values).
    #[must_use]
    pub fn sim_params(&self) -> &SimParamService {
        &self.sim
    }

    /// The timed SIM_ sets: how many fired, and what the plant refused.
    #[must_use]
    pub fn sim_events(&self) -> &SimEvents {
        &self.events
    }

    /// Step the plant by the link's `dt_us` with `pwm_us` held, the timed sets due firing first.
    pub(super) fn step_plant(&mut self, pwm_us: [f64; 4]) {
        self.events.step(&mut self.sim, &mut self.plant, pwm_us, self.config.dt_us);
    }

    /// Poll the hook now, if there is one.
    pub(super) fn poll_hook(&mut self, now: Instant) -> Result<(), LinkError> {
        if let Some((hook, polled_at)) = &mut self.hook {
            *polled_at = now;
            hook.poll(&mut self.plant, &mut self.sim).map_err(LinkError::Hook)?;
        }
        Ok(())
    }

    /// Poll the hook if it has not been polled for [`HOOK_WAIT_INTERVAL`] (the server is waiting).
    pub(super) fn poll_hook_if_due(&mut self, now: Instant) -> Result<(), LinkError> {
        match &self.hook {
            Some((_, polled_at)) if now.saturating_duration_since(*polled_at) >= HOOK_WAIT_INTERVAL => {
                self.poll_hook(now)
            }
            _ => Ok(()),
        }
    }

    /// Apply a `MAV_CMD_INJECT_FAILURE` the autopilot forwarded through the server's SIM_ parameter
    /// service (what it changed goes to the SIM_ port's clients at its next poll) and owe `sender` its
    /// `COMMAND_ACK`.
    pub(super) fn inject_failure(&mut self, command: &COMMAND_LONG_DATA, sender: &MavHeader) {
        let injection = self.sim.inject_forwarded([command.param1, command.param2, command.param3], &mut self.plant);
        if self.hook.is_some() {
            self.sim.tell_peers(&injection.messages);
        }
        tracing::info!(t_us = self.plant.time_us(), "plant: {} ({:?})", injection.text, injection.result);
        self.stats.injections += 1;
        self.acks.push(MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_INJECT_FAILURE,
            result: injection.result,
            target_system: u8::try_from(sender.system_id).unwrap_or(0),
            target_component: sender.component_id,
            ..COMMAND_ACK_DATA::default()
        }));
    }
}

//! The plant's end of the plant protocol (MAVLink 2 HIL messages, see `autopilot::core::plant_link`), over UDP
//! or serial. Out, once per plant step (`dt_us`, default 2 ms = 500 Hz) for plant time `t`: one datagram
//! holding `HIL_GPS` (when the plant releases a fix, 10 Hz by default), `HIL_STATE_QUATERNION` (truth,
//! optionally with the paper's state noise), optionally `ODOMETRY` (the same truth at float precision),
//! `BATTERY_STATUS` (the pack, every [`BATTERY_PERIOD_US`] = 0.1 s, when the plant has one),
//! `RC_CHANNELS` (the airframe's radio receiver, every [`rc::RC_PERIOD_US`] = 20 ms, while it has output:
//! see [`crate::plant::Radio`] and the RC input port [`rc::RcInPort`]; `time_boot_ms` = plant time in ms)
//! and `HIL_SENSOR` last (the autopilot ticks on it). In: `HIL_ACTUATOR_CONTROLS` with `time_usec == t`, whose
//! four controls are the PWM (µs) of the paper's rotors 1..4 held over the step (1000 µs each when
//! disarmed; stopped motors draw nothing from the pack).
//!
//! Failure injection: a `COMMAND_LONG` `MAV_CMD_INJECT_FAILURE` (420) the autopilot forwards (before its
//! `HIL_ACTUATOR_CONTROLS`, in the same datagram or write) is applied before the step, through the
//! server's SIM_ parameter service ([`SimParamService::inject_failure`], the one its SIM_ port answers
//! from), and answered by exactly one `COMMAND_ACK` first in the next sensor datagram sent, before its
//! `HIL_SENSOR` (a resend of that datagram repeats it, as it repeats everything).
//!
//! Delay and loss (SIM_LINK_DELAY, SIM_LINK_LOSS, `crate::plant::LinkFaults`): every step's sample goes
//! into a delay line and a step sends the newest sample at least the delay old; the reply must echo that
//! sample's time. When there is none (the delay just grew, or the sample was lost: one draw per step from
//! the plant seed's own stream while the loss is above 0) the step sends nothing and the plant steps on
//! the last command, as ESCs hold theirs; samples a falling delay overtakes are dropped. So a loss never
//! waits for a resend and never deadlocks the lockstep, the autopilot's clock never goes back, and until
//! the autopilot has first answered every sample goes at once. Without delay and loss nothing is drawn
//! and every step's datagram goes out at once, as before.
//!
//! Lockstep: the plant steps only when it has the reply for `t`; replies for other times are stale and
//! counted. No reply within `resend_timeout` (wall clock, default 1 s): the same datagram is resent and
//! counted. No reply within `link_lost_timeout` (default 5 s): [`LinkError::LinkLost`]; the autopilot
//! does the same on its side and commands the motors to minimum. [`Pacing::RealTime`] keeps the
//! handshake and also holds plant time at or below `speed` times wall time, on absolute deadlines from
//! the first step, in batches of 20 ms of wall time, catching up after a stall at most 10x `speed` and
//! never dropping a step ([`crate::pacer`]).
//!
//! Who binds (as PX4's simulator interface): the plant LISTENS on UDP 127.0.0.1:4560
//! ([`autopilot::core::plant_link::DEFAULT_PLANT_PORT`]); the autopilot binds any port and announces itself by
//! sending any MAVLink message (e.g. `HEARTBEAT`) to 4560. Until then the plant waits (`connect_timeout`,
//! default forever). Afterwards the plant answers the sender of the last matching actuator message, so an
//! autopilot restarted on another port is followed. Serial ([`SerialTransport`]) is point to point.
//!
//! The server always holds the plant's SIM_ parameter service ([`SimParamService`]): failure injections
//! and a scenario's timed SIM_ sets ([`SimEvents`], fired just before the step they are due at) go
//! through it, and a SIM_ port attached to the server ([`PlantServer::set_sim_port`]) answers from it.
//!
//! A [`PlantHook`] (the SIM_ port, [`SimParamLink`]) may change the plant between
//! steps. It is polled every [`HOOK_EVERY_STEPS`] plant steps (0.1 s of plant time at 2 ms), and at
//! least every [`HOOK_WAIT_INTERVAL`] of wall time while the server waits (for the autopilot's reply, its
//! first datagram, or the real-time pacing): never once per step, which would cost the lockstep loop a
//! system call per step. After every step it is told the step happened ([`PlantHook::stepped`], no system
//! call), so that it can sample the plant on plant time (the SIM_ port's truth stream). With a
//! [`hawkeye::HawkeyeSender`] ([`PlantServer::set_hawkeye`]) the server also sends the truth to PX4's
//! Hawkeye viewer after the step that enters each 20 ms period of plant time, the SIM_ port's samples.

use std::collections::VecDeque;
use std::io;
use std::net::ToSocketAddrs;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use autopilot::core::estimator::GeoOrigin;
use autopilot::core::plant_link::{
    ActuatorCommand, FrameDecoder, HilInput, decode_hil_message, encode_battery_status, encode_frame_v2,
    encode_hil_gps, encode_hil_sensor, encode_hil_state_quaternion, encode_odometry, encode_rc_channels,
};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavBatteryChargeState, MavCmd, MavMessage};

mod config;
mod fields;
pub mod free_run;
pub mod hawkeye;
pub mod rc;
mod sim;
mod udp;

#[cfg(test)]
mod fault_tests;

pub use config::{LinkConfig, LinkError, LinkStats, Pacing};
pub use fields::{
    BATTERY_PERIOD_US, battery_due, battery_fields, home_origin, noisy_truth_fields, sensor_fields, truth_fields,
};

use crate::pacer::Pacer;
use crate::plant::Plant;
pub use crate::sim_params::PLANT_COMPONENT_ID;
use crate::sim_params::{SimEvents, SimParamService};
pub use sim::PlantHook;
pub use udp::UdpTransport;

/// MAVLink system id the plant sends with.
pub const PLANT_SYSTEM_ID: u8 = 1;

pub use autopilot::runtime::transport::{SerialTransport, Transport};

/// Plant steps between two polls of the [`PlantHook`] (50 steps = 0.1 s of plant time at 2 ms).
pub const HOOK_EVERY_STEPS: u64 = 50;
/// Longest wall time between two polls of the [`PlantHook`] while the server waits.
pub const HOOK_WAIT_INTERVAL: Duration = Duration::from_millis(20);

/// What one read of the transport brought (see `PlantServer::receive`).
#[derive(Debug)]
struct Received {
    /// The first frames from a peer: the transport has just adopted it.
    first_contact: bool,
    actuators: Vec<ActuatorCommand>,
}

/// One plant step's sensor datagram, kept until the plant steps.
#[derive(Debug)]
struct Pending {
    /// Plant time of the step (µs).
    time_us: u64,
    /// The time of the `HIL_SENSOR` sent (the reply echoes it) and the datagram; `None` when nothing was
    /// sent this step (lost or delayed: the plant steps on the last command).
    sent: Option<(u64, Vec<u8>)>,
}

/// The plant behind a [`Transport`], in lockstep with the autopilot.
#[derive(Debug)]
pub struct PlantServer<T: Transport> {
    plant: Plant,
    transport: T,
    config: LinkConfig,
    home: GeoOrigin,
    decoder: FrameDecoder,
    stats: LinkStats,
    sequence: u8,
    last_command: Option<ActuatorCommand>,
    /// The sensor datagram of the current plant time, kept until the plant steps (a `step` retried after
    /// an error resends it rather than sampling the sensors twice).
    pending: Option<Pending>,
    /// Samples delayed by SIM_LINK_DELAY: (plant time, messages), oldest first.
    delay_line: VecDeque<(u64, Vec<MavMessage>)>,
    /// `COMMAND_ACK`s owed to the autopilot, sent before the next `HIL_SENSOR`.
    acks: Vec<MavMessage>,
    /// The plant's SIM_ parameter service: failure injections and the timed sets go through it, and the
    /// SIM_ port (the hook) answers from it.
    sim: SimParamService,
    /// A scenario's timed SIM_ parameter sets (none by default), fired through `sim` before a step.
    events: SimEvents,
    /// The real-time pacer, from the first paced step.
    pacer: Option<Pacer>,
    /// Polled between steps (see [`PlantHook`]), with the wall time of its last poll.
    hook: Option<(Box<dyn PlantHook>, Instant)>,
    /// The RC input port, read whenever `RC_CHANNELS` is due.
    rc_in: Option<rc::RcInPort>,
    /// The board's watchdog when running free (see [`free_run`]).
    watchdog: free_run::Watchdog,
    /// The truth for PX4's Hawkeye viewer, when asked for (see [`hawkeye`]).
    hawkeye: Option<hawkeye::HawkeyeSender>,
}

impl PlantServer<UdpTransport> {
    /// A server listening on UDP `addr` (default plant address `127.0.0.1:4560`).
    ///
    /// # Errors
    /// The bind error.
    pub fn bind_udp(plant: Plant, addr: impl ToSocketAddrs, config: LinkConfig) -> io::Result<Self> {
        Ok(Self::new(plant, UdpTransport::bind(addr)?, config))
    }
}

impl<T: Transport> PlantServer<T> {
    #[must_use]
    pub fn new(plant: Plant, transport: T, config: LinkConfig) -> Self {
        let home = home_origin(&plant.config().sensors.home);
        let sim = SimParamService::new(PLANT_SYSTEM_ID, &plant);
        Self {
            plant,
            transport,
            config,
            home,
            decoder: FrameDecoder::new(),
            stats: LinkStats::default(),
            sequence: 0,
            last_command: None,
            pending: None,
            delay_line: VecDeque::new(),
            acks: Vec::new(),
            sim,
            events: SimEvents::default(),
            pacer: None,
            hook: None,
            rc_in: None,
            watchdog: free_run::Watchdog::default(),
            hawkeye: None,
        }
    }

    /// The plant step (µs).
    #[must_use]
    pub fn dt_us(&self) -> u64 {
        self.config.dt_us
    }

    /// How plant time relates to wall time.
    #[must_use]
    pub fn pacing(&self) -> Pacing {
        self.config.pacing
    }

    /// Pace by `pacing` from the next step on (a swarm paces its plants on one clock of its own and runs
    /// each server in lockstep).
    pub fn set_pacing(&mut self, pacing: Pacing) {
        self.config.pacing = pacing;
        self.pacer = None;
    }

    /// Read the pilot's radio from `port` from now on (its last good frame is the receiver's until a
    /// schedule begins), whenever `RC_CHANNELS` is due.
    pub fn set_rc_in(&mut self, port: rc::RcInPort) {
        self.rc_in = Some(port);
    }

    /// The RC input port, if there is one.
    #[must_use]
    pub fn rc_in(&self) -> Option<&rc::RcInPort> {
        self.rc_in.as_ref()
    }

    #[must_use]
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, for fault injection between steps.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    #[must_use]
    pub fn transport(&self) -> &T {
        &self.transport
    }

    #[must_use]
    pub fn stats(&self) -> LinkStats {
        LinkStats { decoder: self.decoder.stats(), ..self.stats }
    }

    /// The last accepted actuator command.
    #[must_use]
    pub fn last_command(&self) -> Option<ActuatorCommand> {
        self.last_command
    }

    /// Stop and hand back the plant.
    #[must_use]
    pub fn into_plant(self) -> Plant {
        self.plant
    }

    fn frame(&mut self, msg: &MavMessage) -> Vec<u8> {
        let header = MavHeader {
            system_id: u32::from(PLANT_SYSTEM_ID),
            component_id: PLANT_COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        encode_frame_v2(header, msg)
    }

    /// Sample the plant now (once per step: sampling advances the sensor noise and GPS schedule) and
    /// build the step's messages: `HIL_GPS` if a fix is released, `HIL_STATE_QUATERNION` (truth, with
    /// [`LinkConfig::truth_noise`] added), `ODOMETRY`, `BATTERY_STATUS`, `RC_CHANNELS` when due, `HIL_SENSOR`.
    fn sensor_messages(&mut self) -> Result<Vec<MavMessage>, LinkError> {
        let truth = self.plant.truth();
        let sample = self.plant.sample_sensors();
        let mut messages = Vec::with_capacity(6);
        if let Some(gps) = &sample.gps {
            messages.push(MavMessage::HIL_GPS(encode_hil_gps(gps)));
        }
        let airspeed_mps = (truth.vel_ned_mps - truth.wind_ned_mps).norm();
        let reported = match self.config.truth_noise {
            Some(noise) => noisy_truth_fields(&self.plant.sample_state_of(&truth, &noise)),
            None => truth_fields(&truth),
        };
        if self.config.send_truth {
            messages.push(MavMessage::HIL_STATE_QUATERNION(encode_hil_state_quaternion(
                &reported,
                &self.home,
                airspeed_mps,
            )));
        }
        if self.config.send_truth && self.config.truth_odometry {
            messages.push(MavMessage::ODOMETRY(encode_odometry(&reported)));
        }
        if let Some(battery) = self.plant.battery()
            && battery_due(truth.time_us, self.config.dt_us)
        {
            messages.push(MavMessage::BATTERY_STATUS(encode_battery_status(
                &battery_fields(&battery.reading()),
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED,
            )));
        }
        if rc::rc_due(truth.time_us, self.config.dt_us) {
            if let Some(port) = &mut self.rc_in
                && let Some(frame) = port.poll().map_err(LinkError::RcIn)?
            {
                self.plant.radio_mut().set_port_frame(frame);
            }
            if let Some(frame) = self.plant.radio().output(truth.time_us) {
                let time_boot_ms = u32::try_from(truth.time_us / 1000).unwrap_or(u32::MAX);
                messages.push(MavMessage::RC_CHANNELS(encode_rc_channels(&frame, time_boot_ms)));
            }
        }
        messages.push(MavMessage::HIL_SENSOR(encode_hil_sensor(&sensor_fields(&sample))));
        Ok(messages)
    }

    /// The datagram that carries `messages` (a step's, `HIL_SENSOR` last), after the `COMMAND_ACK`s owed
    /// to the autopilot; counts what it sends.
    fn datagram(&mut self, messages: &[MavMessage]) -> Vec<u8> {
        let mut datagram = Vec::with_capacity(256);
        for ack in std::mem::take(&mut self.acks) {
            datagram.extend(self.frame(&ack));
        }
        for msg in messages {
            match msg {
                MavMessage::HIL_GPS(_) => self.stats.gps_sent += 1,
                MavMessage::RC_CHANNELS(_) => self.stats.rc_sent += 1,
                _ => {}
            }
            datagram.extend(self.frame(msg));
        }
        datagram
    }

    /// What the link delivers this step of plant time `t`, whose messages are `messages`: the newest
    /// sample whose delay has passed (its `HIL_SENSOR` time and messages), or `None` (lost, or still on
    /// its way) when the plant steps on the last actuators. See the module docs.
    fn deliver(&mut self, t: u64, messages: Vec<MavMessage>) -> Option<(u64, Vec<MavMessage>)> {
        let faults = self.plant.link_faults_mut();
        if self.last_command.is_none() {
            // Until the autopilot first answers there are no actuators to hold: every sample goes at once.
            self.delay_line.clear();
            return Some((t, messages));
        }
        if faults.is_clear() && self.delay_line.is_empty() {
            return Some((t, messages));
        }
        if faults.draw_lost() {
            self.stats.lost += 1;
        } else {
            self.delay_line.push_back((t, messages));
        }
        let delay_us = faults.delay_us();
        let mut delivered = None;
        while self.delay_line.front().is_some_and(|(s, _)| s + delay_us <= t) {
            if delivered.replace(self.delay_line.pop_front()).flatten().is_some() {
                // A newer sample is due too (the delay fell): the older one is dropped.
                self.stats.lost += 1;
            }
        }
        delivered.flatten()
    }

    /// One lockstep cycle: send the sensors for the current plant time `t`, wait for the reply for `t`,
    /// (pace,) step the plant by `dt_us` with its PWM. Returns the command applied. With the link's delay
    /// or loss (SIM_LINK_DELAY, SIM_LINK_LOSS) the datagram sent may be an older sample (the reply
    /// must echo its time) or none, when the plant steps on the last command.
    ///
    /// # Errors
    /// [`LinkError::Io`] from the transport, [`LinkError::NoPeer`] / [`LinkError::LinkLost`] on timeouts,
    /// [`LinkError::Stopped`] once `stop` is set; the plant has not stepped then (call again to keep
    /// waiting).
    pub fn step(&mut self, stop: &AtomicBool) -> Result<ActuatorCommand, LinkError> {
        self.begin_step()?;
        self.end_step(stop)
    }

    /// The first half of [`PlantServer::step`]: send the sensors for the current plant time (again, if
    /// they were sent and not yet answered). A swarm sends every plant's sensors first and then collects
    /// the replies, so its autopilots compute at the same time rather than one after another.
    ///
    /// # Errors
    /// [`LinkError::Io`] from the transport.
    pub fn begin_step(&mut self) -> Result<(), LinkError> {
        let t = self.plant.time_us();
        let pending = match self.pending.take() {
            Some(pending) if pending.time_us == t => pending,
            _ => {
                let messages = self.sensor_messages()?;
                let sent = self.deliver(t, messages).map(|(sensor_us, messages)| {
                    self.stats.sensor_sent += 1;
                    (sensor_us, self.datagram(&messages))
                });
                Pending { time_us: t, sent }
            }
        };
        let sent = match &pending.sent {
            Some((_, datagram)) => self.transport.send(datagram),
            None => Ok(()),
        };
        self.pending = Some(pending);
        Ok(sent?)
    }

    /// The second half of [`PlantServer::step`]: wait for the reply to the sensors [`PlantServer::begin_step`]
    /// sent (sending them first if it did not), (pace,) step the plant.
    ///
    /// # Errors
    /// As [`PlantServer::step`].
    pub fn end_step(&mut self, stop: &AtomicBool) -> Result<ActuatorCommand, LinkError> {
        let t = self.plant.time_us();
        if self.pending.as_ref().is_none_or(|p| p.time_us != t) {
            self.begin_step()?;
        }
        let Some(pending) = self.pending.take() else { return Err(LinkError::Stopped) };
        let command = match &pending.sent {
            Some((sensor_us, datagram)) => {
                let reply = self.wait_for_reply(*sensor_us, datagram, stop);
                if reply.is_err() {
                    self.pending = Some(pending);
                }
                reply?
            }
            None => {
                // Nothing reached the autopilot this step: the board holds its last command (a step is
                // only held once the autopilot has answered, see `deliver`).
                self.stats.held_steps += 1;
                self.last_command.ok_or(LinkError::Stopped)?
            }
        };
        self.pace(t)?;
        self.plant.set_motors_running(command.motors_running());
        self.step_plant(command.effective_pwm_us());
        self.stats.steps += 1;
        self.last_command = Some(command);
        if let Some((hook, _)) = &mut self.hook {
            hook.stepped(&self.plant);
        }
        self.send_hawkeye();
        if self.hook.is_some() && self.stats.steps.is_multiple_of(HOOK_EVERY_STEPS) {
            self.poll_hook(Instant::now())?;
        }
        Ok(command)
    }

    /// Run until `max_steps` steps (`None`: no limit) or `stop` is set; returns the steps taken.
    ///
    /// # Errors
    /// As [`PlantServer::step`], except that a stop is not an error.
    pub fn run(&mut self, max_steps: Option<u64>, stop: &AtomicBool) -> Result<u64, LinkError> {
        let mut steps = 0;
        while max_steps.is_none_or(|n| steps < n) {
            match self.step(stop) {
                Ok(_) => steps += 1,
                Err(LinkError::Stopped) => break,
                Err(e) => return Err(e),
            }
        }
        Ok(steps)
    }

    fn wait_for_reply(&mut self, t: u64, datagram: &[u8], stop: &AtomicBool) -> Result<ActuatorCommand, LinkError> {
        let start = Instant::now();
        let mut last_send = start;
        loop {
            if stop.load(Ordering::Relaxed) {
                return Err(LinkError::Stopped);
            }
            let now = Instant::now();
            let waited = now - start;
            let has_peer = self.transport.has_peer();
            let limit = if has_peer { Some(self.config.link_lost_timeout) } else { self.config.connect_timeout };
            if let Some(limit) = limit
                && waited >= limit
            {
                return Err(if has_peer {
                    LinkError::LinkLost { time_us: t, waited }
                } else {
                    LinkError::NoPeer { waited }
                });
            }
            self.poll_hook_if_due(now)?;
            if now - last_send >= self.config.resend_timeout {
                if has_peer {
                    self.transport.send(datagram)?;
                    self.stats.resends += 1;
                }
                last_send = now;
            }
            let Some(received) = self.receive()? else { continue };
            if received.first_contact {
                // First contact: answer whoever spoke, at once.
                self.transport.send(datagram)?;
                last_send = Instant::now();
            }
            let mut reply = None;
            for cmd in received.actuators {
                if cmd.time_us == t && reply.is_none() {
                    reply = Some(cmd);
                } else {
                    self.stats.stale_actuators += 1;
                }
            }
            if let Some(cmd) = reply {
                self.transport.adopt_last_sender();
                return Ok(cmd);
            }
        }
    }

    /// One read from the transport: its frames decoded (junk datagrams counted), a forwarded
    /// `MAV_CMD_INJECT_FAILURE` applied, other messages counted; the actuator commands in arrival order.
    /// On the first frames from a peer the transport adopts it (`first_contact`). `None` when nothing
    /// came within the transport's poll interval.
    fn receive(&mut self) -> Result<Option<Received>, LinkError> {
        let datagrams = self.transport.is_datagram();
        let Some(bytes) = self.transport.recv()? else { return Ok(None) };
        let frames = if datagrams { self.decoder.decode_datagram(bytes) } else { self.decoder.push(bytes) };
        if frames.is_empty() && datagrams {
            self.stats.junk_datagrams += 1;
        }
        let first_contact = !frames.is_empty() && !self.transport.has_peer();
        if first_contact {
            self.transport.adopt_last_sender();
        }
        let mut actuators = Vec::new();
        for frame in &frames {
            if let MavMessage::COMMAND_LONG(command) = &frame.message
                && command.command == MavCmd::MAV_CMD_INJECT_FAILURE
            {
                self.inject_failure(command, &frame.header);
                continue;
            }
            match decode_hil_message(&frame.message, &self.home) {
                Some(HilInput::Actuators(cmd)) => actuators.push(cmd),
                _ => self.stats.other_messages += 1,
            }
        }
        Ok(Some(Received { first_contact, actuators }))
    }

    /// Real-time pacing: sleep until the step from plant time `t` to `t + dt` is due at `speed` times wall
    /// time, by the [`Pacer`]'s rules (absolute deadlines, batches, bounded catch-up), polling the hook
    /// through a long sleep.
    fn pace(&mut self, t: u64) -> Result<(), LinkError> {
        let Pacing::RealTime { speed } = self.config.pacing else { return Ok(()) };
        let to = t + self.config.dt_us;
        loop {
            let now = Instant::now();
            let Some(wake) = self.pacer.get_or_insert_with(|| Pacer::new(speed)).wait(t, to, now) else {
                return Ok(());
            };
            let sleep = wake.saturating_duration_since(now);
            std::thread::sleep(if self.hook.is_some() { sleep.min(HOOK_WAIT_INTERVAL) } else { sleep });
            self.poll_hook_if_due(Instant::now())?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{InitialState, PlantConfig};
    use autopilot::core::manual::RcFrame;
    use autopilot::core::plant_link::{encode_actuator_controls, encode_frame_v2};
    use mavlink::dialects::common::HEARTBEAT_DATA;
    use nalgebra::Vector3;
    use std::net::{SocketAddr, UdpSocket};
    use std::sync::Arc;
    use std::thread;

    const HOVER_ALT_M: f64 = 10.0;

    fn hover_plant() -> Plant {
        let initial = InitialState { pos_ned_m: Vector3::new(0.0, 0.0, -HOVER_ALT_M), ..InitialState::default() };
        Plant::new(PlantConfig::default(), &initial, 7).expect("nominal plant")
    }

    fn ap_header() -> MavHeader {
        MavHeader { system_id: 1, component_id: 1, sequence: 0 }
    }

    fn heartbeat() -> Vec<u8> {
        encode_frame_v2(ap_header(), &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
    }

    fn reply(t: u64, pwm_us: f64) -> Vec<u8> {
        let cmd = ActuatorCommand { time_us: t, pwm_us: [pwm_us; 4], armed: true, motor_test: false };
        encode_frame_v2(ap_header(), &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)))
    }

    /// What the test autopilot saw.
    #[derive(Debug, Default)]
    struct Seen {
        sensor_times_us: Vec<u64>,
        gps: usize,
        truth: usize,
        /// Each `RC_CHANNELS`: its `time_boot_ms`, its frame (as the autopilot decodes it) and the time of
        /// the `HIL_SENSOR` that closed its datagram.
        rc: Vec<(u32, RcFrame, Option<u64>)>,
    }

    /// A test autopilot: announce, then answer every new HIL_SENSOR with `pwm_us` until `n` sensor
    /// times were answered; `before_reply(k, socket)` runs before the k-th reply, `skip(k)` leaves the
    /// k-th first delivery unanswered.
    fn autopilot(
        plant_addr: SocketAddr,
        n: usize,
        pwm_us: f64,
        before_reply: impl Fn(usize, &UdpSocket) + Send + 'static,
        skip: impl Fn(usize) -> bool + Send + 'static,
    ) -> thread::JoinHandle<Seen> {
        let socket = UdpSocket::bind("127.0.0.1:0").expect("bind autopilot");
        socket.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
        thread::spawn(move || {
            socket.send_to(&heartbeat(), plant_addr).expect("announce");
            let mut decoder = FrameDecoder::new();
            let mut seen = Seen::default();
            let mut buf = vec![0; 65_536];
            let mut skipped = std::collections::HashSet::new();
            while seen.sensor_times_us.len() < n {
                let Ok((len, _)) = socket.recv_from(&mut buf) else { break };
                let frames = decoder.decode_datagram(&buf[..len]);
                let closing_sensor = match frames.last().map(|f| &f.message) {
                    Some(MavMessage::HIL_SENSOR(m)) => Some(m.time_usec),
                    _ => None,
                };
                for frame in frames {
                    match frame.message {
                        MavMessage::RC_CHANNELS(m) => {
                            let home = GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 };
                            let Some(HilInput::Rc(rc)) = decode_hil_message(&MavMessage::RC_CHANNELS(m.clone()), &home)
                            else {
                                panic!("RC_CHANNELS is the autopilot's radio input")
                            };
                            seen.rc.push((m.time_boot_ms, rc, closing_sensor));
                        }
                        MavMessage::HIL_GPS(_) => seen.gps += 1,
                        MavMessage::HIL_STATE_QUATERNION(_) => seen.truth += 1,
                        MavMessage::HIL_SENSOR(m) => {
                            let k = seen.sensor_times_us.len();
                            if skip(k) && skipped.insert(k) {
                                continue;
                            }
                            if seen.sensor_times_us.last() != Some(&m.time_usec) {
                                seen.sensor_times_us.push(m.time_usec);
                            }
                            before_reply(k, &socket);
                            socket.send_to(&reply(m.time_usec, pwm_us), plant_addr).expect("reply");
                        }
                        _ => {}
                    }
                }
            }
            seen
        })
    }

    #[test]
    fn link_lockstep_over_udp_holds_hover_and_counts_garbage() {
        const N: usize = 2000;
        let plant = hover_plant();
        let hover_pwm_us = plant.config().airframe.hover_pwm_us();
        let p0 = plant.truth().pos_ned_m;
        let config = LinkConfig::default();
        let mut server = PlantServer::bind_udp(plant, "127.0.0.1:0", config).expect("bind plant");
        let plant_addr = server.transport().local_addr().expect("addr");
        let ap = autopilot(
            plant_addr,
            N,
            hover_pwm_us,
            move |k, socket| {
                if k == N / 2 {
                    socket.send_to(b"\xfd\x09garbage\xfe\x03xyz and more junk", plant_addr).expect("inject");
                }
            },
            |_| false,
        );
        let stop = Arc::new(AtomicBool::new(false));
        let started = Instant::now();
        let steps = server.run(Some(N as u64), &stop).expect("lockstep run");
        let elapsed = started.elapsed();
        let seen = ap.join().expect("autopilot thread");
        println!(
            "lockstep UDP: {N} steps in {elapsed:?} = {:.0} steps/s; {:?}",
            N as f64 / elapsed.as_secs_f64(),
            server.stats()
        );

        assert_eq!(steps, N as u64);
        let dt = config.dt_us;
        assert_eq!(server.plant().time_us(), N as u64 * dt, "plant time = N·dt");
        let expected: Vec<u64> = (0..N as u64).map(|k| k * dt).collect();
        assert_eq!(seen.sensor_times_us, expected, "one sensor sample per dt, none skipped");
        assert_eq!(seen.truth, N);
        assert_eq!(seen.gps, N * 2 / 100, "10 Hz GPS at 500 Hz steps");
        let dp = (server.plant().truth().pos_ned_m - p0).norm();
        assert!(dp < 1e-3, "hover drifted {dp} m");
        let stats = server.stats();
        assert_eq!(stats.steps, N as u64);
        assert_eq!(stats.junk_datagrams, 1, "{stats:?}");
        assert!(stats.decoder.malformed() >= 1 && stats.decoder.garbage_bytes > 0, "{stats:?}");
        assert_eq!(stats.resends, 0);
        let cmd = server.last_command().expect("a command");
        assert!((cmd.pwm_us[0] - hover_pwm_us).abs() < 1e-3);
    }

    #[test]
    fn link_resends_after_timeout_and_counts_stale_replies() {
        let config = LinkConfig { resend_timeout: Duration::from_millis(50), ..LinkConfig::default() };
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", config).expect("bind plant");
        let plant_addr = server.transport().local_addr().expect("addr");
        let pwm = server.plant().config().airframe.hover_pwm_us();
        // Ignore the first delivery of sample 3; before replying to sample 5, send a stale reply.
        let ap = autopilot(
            plant_addr,
            8,
            pwm,
            move |k, socket| {
                if k == 5 {
                    socket.send_to(&reply(123, 1500.0), plant_addr).expect("stale");
                }
            },
            |k| k == 3,
        );
        let steps = server.run(Some(8), &AtomicBool::new(false)).expect("run");
        let seen = ap.join().expect("autopilot");
        assert_eq!(steps, 8);
        assert_eq!(seen.sensor_times_us, (0..8).map(|k| k * 2000).collect::<Vec<_>>());
        let stats = server.stats();
        assert_eq!(stats.resends, 1, "{stats:?}");
        assert_eq!(stats.stale_actuators, 1, "{stats:?}");
        assert_eq!(stats.other_messages, 1, "the announcing HEARTBEAT: {stats:?}");
    }

    #[test]
    fn link_reports_loss_and_no_peer() {
        let config = LinkConfig {
            resend_timeout: Duration::from_millis(20),
            link_lost_timeout: Duration::from_millis(150),
            connect_timeout: Some(Duration::from_millis(100)),
            ..LinkConfig::default()
        };
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", config).expect("bind plant");
        assert!(matches!(server.step(&AtomicBool::new(false)), Err(LinkError::NoPeer { .. })));
        assert_eq!(server.plant().time_us(), 0);

        // A peer that announces itself and then never answers.
        let silent = UdpSocket::bind("127.0.0.1:0").expect("bind");
        silent.send_to(&heartbeat(), server.transport().local_addr().expect("addr")).expect("announce");
        let started = Instant::now();
        let err = server.step(&AtomicBool::new(false)).expect_err("no reply");
        assert!(matches!(err, LinkError::LinkLost { time_us: 0, .. }), "{err}");
        assert!(started.elapsed() >= Duration::from_millis(150));
        assert_eq!(server.plant().time_us(), 0, "no step without a reply");
        assert!(server.stats().resends >= 3, "{:?}", server.stats());
    }

    /// A hook that counts its polls and sets a steady wind at its first, and counts the steps it is told
    /// of with the plant time after the last.
    #[derive(Debug)]
    struct CountingHook {
        polls: Arc<std::sync::atomic::AtomicU64>,
        steps: Arc<std::sync::atomic::AtomicU64>,
        last_step_us: Arc<std::sync::atomic::AtomicU64>,
    }

    impl PlantHook for CountingHook {
        fn poll(&mut self, plant: &mut Plant, _sim: &mut SimParamService) -> io::Result<()> {
            if self.polls.fetch_add(1, Ordering::Relaxed) == 0 {
                plant.wind_mut().set_steady_ned_mps(Vector3::new(0.0, 3.0, 0.0));
            }
            Ok(())
        }

        fn stepped(&mut self, plant: &Plant) {
            self.steps.fetch_add(1, Ordering::Relaxed);
            self.last_step_us.store(plant.time_us(), Ordering::Relaxed);
        }
    }

    #[test]
    fn link_polls_its_hook_every_50_steps_and_while_waiting_and_tells_it_of_every_step() {
        let polls = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let steps = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let last_step_us = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let config = LinkConfig { connect_timeout: Some(Duration::from_millis(100)), ..LinkConfig::default() };
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", config).expect("bind plant");
        server.set_hook(Box::new(CountingHook {
            polls: polls.clone(),
            steps: steps.clone(),
            last_step_us: last_step_us.clone(),
        }));
        // No autopilot yet: polled every 20 ms of the 100 ms wait.
        assert!(matches!(server.step(&AtomicBool::new(false)), Err(LinkError::NoPeer { .. })));
        let waiting = polls.load(Ordering::Relaxed);
        assert!((3..=6).contains(&waiting), "{waiting} polls in 100 ms");
        assert_eq!(server.plant().truth().wind_ned_mps, Vector3::zeros(), "acts from the next step");

        let plant_addr = server.transport().local_addr().expect("addr");
        let pwm = server.plant().config().airframe.hover_pwm_us();
        let ap = autopilot(plant_addr, 200, pwm, |_, _| {}, |_| false);
        let started = Instant::now();
        assert_eq!(server.run(Some(200), &AtomicBool::new(false)).expect("run"), 200);
        let elapsed = started.elapsed();
        ap.join().expect("autopilot");
        let stepping = polls.load(Ordering::Relaxed) - waiting;
        let waits = (elapsed.as_secs_f64() / HOOK_WAIT_INTERVAL.as_secs_f64()).ceil() as u64;
        assert!(stepping >= 4 && stepping <= 4 + waits, "{stepping} polls in 200 steps ({elapsed:?})");
        assert_eq!(server.plant().truth().wind_ned_mps, Vector3::new(0.0, 3.0, 0.0));
        // Told of each step once, after it: the last at the plant's time after 200 steps of 2 ms.
        assert_eq!(steps.load(Ordering::Relaxed), 200);
        assert_eq!(last_step_us.load(Ordering::Relaxed), 400_000);
    }

    #[test]
    fn given_hawkeye_then_the_server_sends_the_truth_every_20_ms_of_plant_time_and_counts_what_was_refused() {
        // GIVEN a server with a Hawkeye viewer listening.
        let viewer = UdpSocket::bind("127.0.0.1:0").expect("bind viewer");
        viewer.set_read_timeout(Some(Duration::from_millis(200))).expect("timeout");
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", LinkConfig::default()).expect("bind");
        let to = viewer.local_addr().expect("addr");
        server.set_hawkeye(hawkeye::HawkeyeSender::new(to, 1, 0).expect("sender"));
        assert_eq!(server.hawkeye().map(hawkeye::HawkeyeSender::destination), Some(to));
        let plant_addr = server.transport().local_addr().expect("addr");
        let pwm = server.plant().config().airframe.hover_pwm_us();
        // WHEN it runs 200 steps of 2 ms (of an autopilot's 400).
        let ap = autopilot(plant_addr, 400, pwm, |_, _| {}, |_| false);
        assert_eq!(server.run(Some(200), &AtomicBool::new(false)).expect("run"), 200);
        // THEN the viewer got 20 HIL_STATE_QUATERNION at 20, 40, .. 400 ms, each the truth of its time.
        let mut buf = [0_u8; 512];
        let mut times = Vec::new();
        while let Ok(n) = viewer.recv(&mut buf) {
            for frame in FrameDecoder::new().decode_datagram(&buf[..n]) {
                let MavMessage::HIL_STATE_QUATERNION(m) = frame.message else { panic!("{:?}", frame.message) };
                times.push(m.time_usec);
            }
        }
        assert_eq!(times, (1..=20).map(|k| k * 20_000).collect::<Vec<u64>>());
        assert_eq!((server.stats().hawkeye_sent, server.stats().hawkeye_failed), (20, 0));

        // AND with nobody listening the plant steps on; every sample is either sent or counted refused.
        drop(viewer);
        assert_eq!(server.run(Some(200), &AtomicBool::new(false)).expect("run with nobody listening"), 200);
        ap.join().expect("autopilot");
        let stats = server.stats();
        assert_eq!(stats.hawkeye_sent + stats.hawkeye_failed, 40, "{stats:?}");
        assert!(stats.hawkeye_failed >= 5, "ECONNREFUSED counted: {stats:?}");
    }

    #[test]
    fn link_real_time_pacing_holds_plant_time_to_wall_time() {
        let config = LinkConfig { pacing: Pacing::RealTime { speed: 2.0 }, ..LinkConfig::default() };
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", config).expect("bind plant");
        let plant_addr = server.transport().local_addr().expect("addr");
        let pwm = server.plant().config().airframe.hover_pwm_us();
        let ap = autopilot(plant_addr, 100, pwm, |_, _| {}, |_| false);
        let started = Instant::now();
        server.run(Some(100), &AtomicBool::new(false)).expect("run");
        let elapsed = started.elapsed();
        ap.join().expect("autopilot");
        // 100 steps of 2 ms = 0.2 s plant time at 2x: at least 0.1 s wall.
        assert!(elapsed >= Duration::from_millis(99), "{elapsed:?}");
        assert!(elapsed < Duration::from_secs(2), "{elapsed:?}");
    }

    #[test]
    fn link_plant_samples_map_to_hil_fields() {
        let mut plant = hover_plant();
        let sample = plant.sample_sensors();
        let fields = sensor_fields(&sample);
        assert_eq!(fields.time_us, 0);
        assert_eq!(fields.accel_frd_mps2, sample.accel_frd_mps2);
        assert_eq!(fields.baro.map(|b| b.pressure_alt_m), sample.baro.map(|b| b.pressure_alt_m));
        assert!(fields.baro.is_some() && fields.mag_frd_gauss.is_some());
        // The plant's GPS sample is the protocol's (`autopilot::core::estimator::GpsSample`): no mapping.
        let gps = sample.gps.expect("GPS at t = 0");
        assert_eq!(gps.satellites, plant.config().sensors.gps.satellites_visible);
        let home = home_origin(&plant.config().sensors.home);
        let truth = truth_fields(&plant.truth());
        let msg = encode_hil_state_quaternion(&truth, &home, 0.0);
        assert_eq!(msg.alt, ((home.alt_amsl_m + HOVER_ALT_M) * 1000.0).round() as i32);
    }

    /// A change to a test server between two runs of steps.
    type Between<'a> = &'a dyn Fn(&mut PlantServer<UdpTransport>);

    /// One test autopilot answering `total` steps of `server`, run in `parts` (steps, then a change to the
    /// server before the next part); the `RC_CHANNELS` it saw.
    fn rc_seen(
        server: &mut PlantServer<UdpTransport>,
        parts: &[(u64, Between<'_>)],
    ) -> Vec<(u32, RcFrame, Option<u64>)> {
        let plant_addr = server.transport().local_addr().expect("addr");
        let pwm = server.plant().config().airframe.hover_pwm_us();
        let total: u64 = parts.iter().map(|p| p.0).sum();
        let ap = autopilot(plant_addr, total as usize, pwm, |_, _| {}, |_| false);
        for (steps, then) in parts {
            assert_eq!(server.run(Some(*steps), &AtomicBool::new(false)).expect("run"), *steps);
            then(server);
        }
        ap.join().expect("autopilot").rc
    }

    #[test]
    fn given_a_radio_frame_then_rc_channels_go_every_20_ms_of_plant_time_before_the_sensor_and_sim_rc_fail_stops_them()
    {
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", LinkConfig::default()).expect("bind");
        let frame = RcFrame::of(&[1100, 1200, 1000, 2000, 1500, 1600, 1700, 1800, 1900, 2100]);
        server.plant_mut().radio_mut().set_port_frame(frame);
        // 100 steps of 2 ms (plant times 0..198 ms, RC at 0, 20, .., 180 ms), SIM_RC_FAIL for 100 steps,
        // cleared for 20.
        let fail = |s: &mut PlantServer<UdpTransport>| s.plant_mut().radio_mut().set_failed(true);
        let clear = |s: &mut PlantServer<UdpTransport>| s.plant_mut().radio_mut().set_failed(false);
        let rc = rc_seen(&mut server, &[(100, &fail), (100, &clear), (20, &|_| {})]);
        let times: Vec<u32> = rc.iter().map(|r| r.0).collect();
        let mut expected: Vec<u32> = (0..10).map(|k| k * 20).collect();
        expected.extend([400, 420]);
        assert_eq!(times, expected, "50 Hz of plant time (time_boot_ms = plant ms), none while SIM_RC_FAIL = 1");
        for (ms, got, sensor_us) in &rc {
            assert_eq!(got, &frame, "at {ms} ms: the frame's values exactly");
            assert_eq!(*sensor_us, Some(u64::from(*ms) * 1000), "in the datagram of the HIL_SENSOR of its time");
        }
        assert_eq!(server.stats().rc_sent, 12);
    }

    #[test]
    fn given_no_radio_then_the_link_sends_no_rc_channels() {
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", LinkConfig::default()).expect("bind");
        assert!(rc_seen(&mut server, &[(50, &|_| {})]).is_empty());
        assert_eq!(server.stats().rc_sent, 0);
    }

    #[test]
    fn given_a_datagram_on_the_rc_input_port_then_its_channels_go_out_as_rc_channels_and_are_held() {
        let mut server = PlantServer::bind_udp(hover_plant(), "127.0.0.1:0", LinkConfig::default()).expect("bind");
        let port = rc::RcInPort::bind("127.0.0.1:0").expect("bind rc in");
        let rc_addr = port.local_addr().expect("addr");
        server.set_rc_in(port);
        let values = [1000_u16, 1500, 1000, 2000, 1500, 1500, 1500, 1500];
        let send = move |_: &mut PlantServer<UdpTransport>| {
            let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            let tx = UdpSocket::bind("127.0.0.1:0").expect("bind sender");
            tx.send_to(&bytes, rc_addr).expect("send");
            tx.send_to(&[1, 2, 3], rc_addr).expect("send junk");
        };
        // Sent after 20 steps (plant time 40 ms); loopback UDP is queued at the receiver by the send.
        let rc = rc_seen(&mut server, &[(20, &send), (100, &|_| {})]);
        let times: Vec<u32> = rc.iter().map(|r| r.0).collect();
        assert_eq!(
            times,
            (2..12).map(|k| k * 20).collect::<Vec<_>>(),
            "from the first RC time after the datagram, held"
        );
        assert!(rc.iter().all(|r| r.1 == RcFrame::of(&values)));
        let stats = server.rc_in().expect("port").stats();
        assert_eq!((stats.accepted, stats.dropped), (1, 1), "{stats:?}");
    }
}

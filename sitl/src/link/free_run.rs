//! The plant timed as the airframe's board times its link (free-running): a sensor sample every period
//! of wall time whether or not the autopilot has answered, each step flown on the newest actuator
//! command received, and the board's watchdog: with no command for [`BOARD_WATCHDOG_US`] every motor
//! goes to minimum until commands come back. In: the server's transport and plant; out: the same
//! messages as the lockstep link, on a wall-clock schedule (`sitl serve --free-run`, docs/board.md).
//!
//! Unlike lockstep, a run is not reproducible (what the autopilot answered in time depends on the
//! machine), and a line too slow for the stream shows as late answers rather than a slower simulation:
//! what a board sees.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use autopilot::core::plant_link::ActuatorCommand;

use super::{HOOK_EVERY_STEPS, LinkError, PlantServer, Transport};

/// Plant time without a new actuator command after which the board puts every motor at minimum (100 ms:
/// 25 samples at 250 Hz); the motors follow the commands again from the next one received.
pub const BOARD_WATCHDOG_US: u64 = 100_000;

/// The board's watchdog: when the newest command came, and whether it has tripped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Watchdog {
    /// Plant time of the step that received the newest command.
    last_command_at_us: Option<u64>,
    tripped: bool,
}

impl<T: Transport> PlantServer<T> {
    /// Run free (see the module documentation) at `speed` times real time until `max_steps` steps
    /// (`None`: no limit) or `stop` is set; returns the steps taken. The transport's poll interval bounds
    /// how late a step can be: open it with a short one (1 ms).
    ///
    /// # Errors
    /// [`LinkError::Io`] from the transport, a hook's or the RC input's error.
    pub fn run_free(&mut self, speed: f64, max_steps: Option<u64>, stop: &AtomicBool) -> Result<u64, LinkError> {
        let speed = if speed.is_finite() && speed > 0.0 { speed } else { 1.0 };
        let wall0 = Instant::now();
        let t0 = self.plant.time_us();
        let mut steps = 0;
        while max_steps.is_none_or(|n| steps < n) && !stop.load(Ordering::Relaxed) {
            let t = self.plant.time_us();
            let messages = self.sensor_messages()?;
            if let Some((_, messages)) = self.deliver(t, messages) {
                let datagram = self.datagram(&messages);
                self.stats.sensor_sent += 1;
                match self.transport.send(&datagram) {
                    Ok(()) => {}
                    // The line is full (nobody reads the other end, or the stream outruns it): a board's
                    // UART drops what it cannot send and the next sample goes on time.
                    Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => {
                        self.stats.send_timeouts += 1;
                    }
                    Err(e) => return Err(e.into()),
                }
            } else {
                self.stats.held_steps += 1;
            }
            let due = wall0 + Duration::from_secs_f64((t + self.config.dt_us - t0) as f64 * 1e-6 / speed);
            while Instant::now() < due {
                self.poll_hook_if_due(Instant::now())?;
                let Some(received) = self.receive()? else { continue };
                for cmd in received.actuators {
                    self.take_free_command(cmd, t);
                }
            }
            let fresh = self.watchdog.last_command_at_us.is_some_and(|at| t.saturating_sub(at) <= BOARD_WATCHDOG_US);
            let idle = ActuatorCommand { time_us: t, pwm_us: [1000.0; 4], armed: false, motor_test: false };
            let command = match self.last_command {
                Some(cmd) if fresh => {
                    if self.watchdog.tripped {
                        tracing::info!(t_us = t, "board watchdog: actuator commands again");
                        self.watchdog.tripped = false;
                    }
                    cmd
                }
                Some(_) => {
                    if !self.watchdog.tripped {
                        tracing::warn!(t_us = t, "board watchdog: no actuator command for 100 ms, motors to minimum");
                        self.stats.watchdog_trips += 1;
                        self.watchdog.tripped = true;
                    }
                    idle
                }
                None => idle,
            };
            self.plant.set_motors_running(command.motors_running());
            self.step_plant(command.effective_pwm_us());
            self.stats.steps += 1;
            steps += 1;
            if let Some((hook, _)) = &mut self.hook {
                hook.stepped(&self.plant);
            }
            self.send_hawkeye();
            if self.hook.is_some() && self.stats.steps.is_multiple_of(HOOK_EVERY_STEPS) {
                self.poll_hook(Instant::now())?;
            }
        }
        Ok(steps)
    }

    /// An actuator command received while the step at plant time `t` waits: the newest sample's answer is
    /// taken (one for an older sample than the step's is late, one older than the command held is stale).
    fn take_free_command(&mut self, cmd: ActuatorCommand, t: u64) {
        if self.last_command.is_some_and(|held| cmd.time_us < held.time_us) || cmd.time_us > t {
            self.stats.stale_actuators += 1;
            return;
        }
        if cmd.time_us < t {
            self.stats.late_actuators += 1;
        }
        self.last_command = Some(cmd);
        self.watchdog.last_command_at_us = Some(t);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::{LinkConfig, UdpTransport};
    use crate::plant::{InitialState, Plant, PlantConfig};
    use autopilot::core::plant_link::{FrameDecoder, encode_actuator_controls, encode_frame_v2};
    use mavlink::MavHeader;
    use mavlink::dialects::common::MavMessage;
    use std::net::UdpSocket;
    use std::sync::Arc;

    /// A test autopilot that answers every HIL_SENSOR (armed, 1500 µs) until `stop_after` answers, then
    /// falls silent; it counts the samples it saw.
    fn autopilot(
        plant: std::net::SocketAddr,
        stop_after: usize,
        done: Arc<AtomicBool>,
    ) -> std::thread::JoinHandle<usize> {
        let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
        socket.set_read_timeout(Some(Duration::from_millis(50))).expect("timeout");
        std::thread::spawn(move || {
            let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
            let hello = encode_frame_v2(header, &autopilot::core::mavlink::gcs_heartbeat());
            socket.send_to(&hello, plant).expect("hello");
            let (mut decoder, mut buf, mut seen) = (FrameDecoder::new(), [0_u8; 4096], 0);
            while !done.load(Ordering::Relaxed) {
                let Ok(n) = socket.recv(&mut buf) else { continue };
                for frame in decoder.decode_datagram(&buf[..n]) {
                    let MavMessage::HIL_SENSOR(s) = frame.message else { continue };
                    seen += 1;
                    if seen <= stop_after {
                        let cmd = ActuatorCommand {
                            time_us: s.time_usec,
                            pwm_us: [1500.0; 4],
                            armed: true,
                            motor_test: false,
                        };
                        let reply =
                            encode_frame_v2(header, &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)));
                        socket.send_to(&reply, plant).expect("reply");
                    }
                }
            }
            seen
        })
    }

    #[test]
    fn a_free_running_board_steps_on_its_clock_and_its_watchdog_stops_the_motors_100_ms_after_the_last_command() {
        let plant = Plant::new(PlantConfig::default(), &InitialState::default(), 1).expect("plant");
        let transport =
            UdpTransport::bind("127.0.0.1:0").expect("bind").with_poll(Duration::from_millis(1)).expect("poll");
        let addr = transport.local_addr().expect("addr");
        let config = LinkConfig { dt_us: 4000, ..LinkConfig::default() };
        let mut server = crate::link::PlantServer::new(plant, transport, config);
        let done = Arc::new(AtomicBool::new(false));
        // The autopilot answers 100 samples (0.4 s) and then falls silent.
        let ap = autopilot(addr, 100, done.clone());
        let mut running_at = Vec::new();
        let stop = AtomicBool::new(false);
        for _ in 0..200 {
            server.run_free(1.0, Some(1), &stop).expect("one step");
            running_at.push((server.plant().time_us(), server.plant().motors_running()));
        }
        done.store(true, Ordering::Relaxed);
        let seen = ap.join().expect("autopilot");
        let stats = server.stats();
        // Every step sent its sample, answered or not: the board never waits.
        assert_eq!(stats.steps, 200);
        assert_eq!(stats.sensor_sent, 200);
        assert!(seen >= 190, "the autopilot saw {seen} of 200 samples");
        // The motors ran on the answers, and stopped once 100 ms passed without one.
        let last_on = running_at.iter().rposition(|(_, on)| *on).expect("the motors ran");
        let first_on = running_at.iter().position(|(_, on)| *on).expect("the motors ran");
        let silent_from_us = 100 * 4000;
        let off_at_us = running_at[last_on + 1].0;
        assert!(
            (silent_from_us + BOARD_WATCHDOG_US..=silent_from_us + BOARD_WATCHDOG_US + 3 * 4000).contains(&off_at_us),
            "motors off at {off_at_us} µs; last answer for {silent_from_us} µs (first on at step {first_on})"
        );
        assert_eq!(stats.watchdog_trips, 1);
        assert!(running_at[last_on + 1..].iter().all(|(_, on)| !on), "they stay off while the autopilot is silent");
    }
}

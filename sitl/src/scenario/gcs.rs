//! A small ground station that `sitl run --scenario` flies track scenarios with, over the autopilot's
//! UDP ground-station port, as a user's script would: in, the autopilot's telemetry (every wait is on the
//! vehicle's clock, `time_boot_ms`); out, COMMAND_LONGs and the mission protocol. Blocking, for a thread
//! of its own; a wall-clock deadline only guards against a hang.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::common::{
    MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MavCmd, MavMessage, MavMissionResult, MavModeFlag, MavResult,
    MavSysStatusSensor,
};
use autopilot::core::mavlink::{command_long, gcs_heartbeat};
use autopilot::core::plant_link::{FrameDecoder, encode_frame_v2};

/// The ground station's identity (QGroundControl's).
const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

/// Why the ground station gave up.
#[derive(Debug, thiserror::Error)]
pub enum GcsError {
    #[error("ground station socket: {0}")]
    Io(#[from] std::io::Error),
    #[error("{0}: not within {1} s of vehicle time")]
    Timeout(String, f64),
    #[error("the vehicle stopped talking (no telemetry for {0:?} of wall time)")]
    Silent(Duration),
    #[error("{command:?} answered {result:?}")]
    Refused { command: MavCmd, result: MavResult },
    #[error("mission upload answered {0:?}")]
    Mission(MavMissionResult),
}

/// What the ground station has heard.
#[derive(Debug, Clone, Default)]
pub struct Seen {
    pub time_ms: u32,
    pub armed: bool,
    pub converged: bool,
    pub reached: Vec<u16>,
    acks: Vec<(MavCmd, MavResult)>,
}

/// The ground station.
#[derive(Debug)]
pub struct Gcs {
    socket: UdpSocket,
    autopilot: SocketAddr,
    sysid: u8,
    decoder: FrameDecoder,
    pub seen: Seen,
    last_heard: Instant,
    pending: Vec<MavMessage>,
}

/// Wall time without a message after which the vehicle counts as gone.
const SILENCE: Duration = Duration::from_secs(20);

impl Gcs {
    /// A ground station talking to the autopilot at `autopilot` (system `sysid`).
    ///
    /// # Errors
    /// The socket's error.
    pub fn new(autopilot: SocketAddr, sysid: u8) -> Result<Self, GcsError> {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        socket.set_read_timeout(Some(Duration::from_millis(50)))?;
        Ok(Self {
            socket,
            autopilot,
            sysid,
            decoder: FrameDecoder::new(),
            seen: Seen::default(),
            last_heard: Instant::now(),
            pending: Vec::new(),
        })
    }

    fn send(&self, msg: &MavMessage) -> Result<(), GcsError> {
        self.socket.send_to(&encode_frame_v2(GCS, msg), self.autopilot)?;
        Ok(())
    }

    /// Reads what arrived (up to 50 ms of wall time) and updates what is known.
    fn pump(&mut self) -> Result<(), GcsError> {
        let mut buf = [0u8; 65_536];
        let len = match self.socket.recv(&mut buf) {
            Ok(len) => len,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                if self.last_heard.elapsed() > SILENCE {
                    return Err(GcsError::Silent(SILENCE));
                }
                // Say hello again: the vehicle answers peers that speak.
                self.send(&gcs_heartbeat())?;
                return Ok(());
            }
            Err(e) => return Err(e.into()),
        };
        self.last_heard = Instant::now();
        for frame in self.decoder.decode_datagram(&buf[..len]) {
            if frame.header.system_id != u32::from(self.sysid) {
                continue;
            }
            let s = &mut self.seen;
            match &frame.message {
                MavMessage::HEARTBEAT(h) => s.armed = h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
                MavMessage::SYS_STATUS(st) => {
                    s.converged =
                        st.onboard_control_sensors_health.contains(MavSysStatusSensor::MAV_SYS_STATUS_PREARM_CHECK);
                }
                MavMessage::ATTITUDE(a) => s.time_ms = s.time_ms.max(a.time_boot_ms),
                MavMessage::MISSION_ITEM_REACHED(r) => s.reached.push(r.seq),
                MavMessage::COMMAND_ACK(a) => s.acks.push((a.command, a.result)),
                MavMessage::MISSION_REQUEST_INT(_) | MavMessage::MISSION_ACK(_) => {
                    self.pending.push(frame.message.clone())
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Pumps until `cond` holds, at most `timeout_s` of vehicle time.
    ///
    /// # Errors
    /// [`GcsError::Timeout`] naming `what`, or the link's error.
    pub fn wait_until(&mut self, timeout_s: f64, what: &str, cond: impl Fn(&Seen) -> bool) -> Result<(), GcsError> {
        let start_ms = self.seen.time_ms;
        while !cond(&self.seen) {
            if f64::from(self.seen.time_ms.saturating_sub(start_ms)) > timeout_s * 1e3 {
                return Err(GcsError::Timeout(what.to_owned(), timeout_s));
            }
            self.pump()?;
        }
        Ok(())
    }

    /// A COMMAND_LONG, waiting for its ACK (resent every 2 s of vehicle time); Ok when accepted.
    ///
    /// # Errors
    /// [`GcsError::Refused`] with the result, or a timeout.
    pub fn command(&mut self, command: MavCmd, params: [f32; 7]) -> Result<(), GcsError> {
        self.seen.acks.clear();
        for _ in 0..3 {
            self.send(&command_long(self.sysid, 1, command, params))?;
            let acked = |s: &Seen| s.acks.iter().any(|a| a.0 == command);
            if self.wait_until(2.0, &format!("ACK of {command:?}"), acked).is_ok() {
                let result = self.seen.acks.iter().find(|a| a.0 == command).map(|a| a.1);
                return match result {
                    Some(MavResult::MAV_RESULT_ACCEPTED) => Ok(()),
                    Some(result) => Err(GcsError::Refused { command, result }),
                    None => Err(GcsError::Timeout(format!("ACK of {command:?}"), 6.0)),
                };
            }
        }
        Err(GcsError::Timeout(format!("ACK of {command:?}"), 6.0))
    }

    /// Uploads `items` with the mission protocol.
    ///
    /// # Errors
    /// [`GcsError::Mission`] when the vehicle's ACK is not ACCEPTED, or a timeout.
    pub fn upload(&mut self, items: &[MISSION_ITEM_INT_DATA]) -> Result<(), GcsError> {
        let count = u16::try_from(items.len()).unwrap_or(u16::MAX);
        self.pending.clear();
        self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count,
            target_system: self.sysid,
            target_component: 1,
            ..Default::default()
        }))?;
        let start_ms = self.seen.time_ms;
        loop {
            for msg in std::mem::take(&mut self.pending) {
                match msg {
                    MavMessage::MISSION_REQUEST_INT(r) => {
                        let item = items
                            .get(usize::from(r.seq))
                            .ok_or(GcsError::Mission(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE))?;
                        self.send(&MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
                            target_system: self.sysid,
                            ..item.clone()
                        }))?;
                    }
                    MavMessage::MISSION_ACK(a) if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED => return Ok(()),
                    MavMessage::MISSION_ACK(a) => return Err(GcsError::Mission(a.mavtype)),
                    _ => {}
                }
            }
            if self.seen.time_ms.saturating_sub(start_ms) > 20_000 {
                return Err(GcsError::Timeout("mission upload".into(), 20.0));
            }
            self.pump()?;
        }
    }
}

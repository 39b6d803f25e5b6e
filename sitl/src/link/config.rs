//! The plant link's settings (pacing, step, timeouts, what truth it sends), its errors and its counts.

use std::io;
use std::time::Duration;

use autopilot::core::plant_link::DecoderStats;

use crate::plant::StateNoise;

/// How plant time relates to wall time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// As fast as the autopilot answers ([`LinkConfig`]'s default, for tests and scenarios; `sitl run` and
    /// `sitl serve` run at real time unless given `--speed max`).
    Lockstep,
    /// Lockstep, and plant time never ahead of `speed` times wall time (1.0 = real time).
    RealTime { speed: f64 },
}

/// Timing of the link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkConfig {
    /// Plant step per sensor sample (µs); default 2000 (500 Hz).
    pub dt_us: u64,
    pub pacing: Pacing,
    /// Wall time without a reply before the sensor datagram is resent; default 1 s.
    pub resend_timeout: Duration,
    /// Wall time without a reply before [`LinkError::LinkLost`]; default 5 s.
    pub link_lost_timeout: Duration,
    /// Wall time to wait for the autopilot's first datagram; `None` (default) = forever.
    pub connect_timeout: Option<Duration>,
    /// White noise added to the truth in `HIL_STATE_QUATERNION` (the paper's truth-fed "hardware" runs);
    /// `None` (default): exact truth.
    pub truth_noise: Option<StateNoise>,
    /// Send the simulator's ground truth (`HIL_STATE_QUATERNION` with every sample); default on. A real
    /// board never sends it, so `sitl serve --serial` leaves it off unless asked (`--truth`).
    pub send_truth: bool,
    /// Also send the truth as `ODOMETRY` at float precision (see `autopilot::core::plant_link::LocalTruth`), for
    /// truth-fed runs; default off (HIL_STATE_QUATERNION's degE7 position is quantised to ±5.6 mm).
    pub truth_odometry: bool,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            dt_us: 2000,
            pacing: Pacing::Lockstep,
            resend_timeout: Duration::from_secs(1),
            link_lost_timeout: Duration::from_secs(5),
            connect_timeout: None,
            truth_noise: None,
            send_truth: true,
            truth_odometry: false,
        }
    }
}

/// Link errors.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("plant link I/O: {0}")]
    Io(#[from] io::Error),
    #[error("link lost: no actuator reply for plant time {time_us} µs within {waited:?}")]
    LinkLost { time_us: u64, waited: Duration },
    #[error("no autopilot connected within {waited:?}")]
    NoPeer { waited: Duration },
    #[error("stopped")]
    Stopped,
    #[error("plant hook: {0}")]
    Hook(#[source] io::Error),
    #[error("RC input port: {0}")]
    RcIn(#[source] io::Error),
}

/// What the link saw; every field only grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Plant steps taken.
    pub steps: u64,
    /// Sensor datagrams sent (first sends, not resends).
    pub sensor_sent: u64,
    /// `HIL_GPS` messages sent.
    pub gps_sent: u64,
    /// `RC_CHANNELS` messages sent (the radio receiver's output).
    pub rc_sent: u64,
    /// Sensor datagrams resent after `resend_timeout`.
    pub resends: u64,
    /// Actuator replies for another time than the one awaited (free-running: for a sample older than the
    /// command held, or not yet sent).
    pub stale_actuators: u64,
    /// Free-running: actuator replies taken a step or more after their sample's own step (the line or the
    /// autopilot took longer than a period).
    pub late_actuators: u64,
    /// Free-running: sensor datagrams the line would not take within the poll interval (dropped).
    pub send_timeouts: u64,
    /// Free-running: times the board's watchdog put the motors at minimum (no command for 100 ms).
    pub watchdog_trips: u64,
    /// Well-formed messages other than `HIL_ACTUATOR_CONTROLS` and `MAV_CMD_INJECT_FAILURE` (ignored).
    pub other_messages: u64,
    /// Datagrams without a single good frame.
    pub junk_datagrams: u64,
    /// Sensor datagrams the link lost (SIM_LINK_LOSS) or dropped for a newer one when the delay fell.
    pub lost: u64,
    /// Plant steps taken on the last command because no sensor datagram went out (lost or delayed).
    pub held_steps: u64,
    /// `MAV_CMD_INJECT_FAILURE` commands received (each answered by one `COMMAND_ACK`).
    pub injections: u64,
    /// `HIL_STATE_QUATERNION` datagrams the kernel took for the Hawkeye viewer (`--hawkeye`).
    pub hawkeye_sent: u64,
    /// Hawkeye datagrams the kernel refused (no viewer listening: ECONNREFUSED; a full buffer), dropped.
    pub hawkeye_failed: u64,
    /// The frame decoder's counts (garbage, bad CRC, truncated, ...).
    pub decoder: DecoderStats,
}

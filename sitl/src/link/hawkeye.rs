//! The plant's truth for PX4's Hawkeye viewer: with `--hawkeye`, one MAVLink 2 HIL_STATE_QUATERNION per
//! datagram to UDP 127.0.0.1:19410 + N (instance N; `autopilot::runtime::ports`), every 20 ms of plant
//! time.
//!
//! Each sample is [`crate::sim_params::hil_state_quaternion`] of the plant's truth, taken after the plant
//! step that enters a new [`TRUTH_PERIOD_US`] period ([`TruthPeriods`], the SIM_ port's rule, from the
//! same start), so at equal times it carries the same sample as the SIM_ port's SIM_STATE. It is sent at
//! once, from the plant's thread: the rate is 50 Hz of plant (vehicle) time at any `--speed` and in
//! lockstep. The header is the SIM_ port's: system N + 1, component
//! [`crate::sim_params::PLANT_COMPONENT_ID`].
//!
//! The socket is non-blocking and connected to the viewer's port: a send the kernel refuses (no viewer
//! listening: ECONNREFUSED, reported on the send after an unanswered one; a full buffer: EWOULDBLOCK) is
//! counted ([`super::LinkStats::hawkeye_failed`]) and dropped, never retried, never waited for, never an
//! error of the plant.

use std::io;
use std::net::{SocketAddr, UdpSocket};

use autopilot::core::plant_link::encode_frame_v2;
use autopilot::runtime::view::viewer_socket;
use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;

use crate::plant::Plant;
use crate::sim_params::{PLANT_COMPONENT_ID, TRUTH_PERIOD_US, TruthPeriods, hil_state_quaternion};

/// The Hawkeye period (µs of plant time): the SIM_ port's truth period.
pub const HAWKEYE_PERIOD_US: u64 = TRUTH_PERIOD_US;

/// Sends the plant's truth to a Hawkeye viewer on plant time.
#[derive(Debug)]
pub struct HawkeyeSender {
    socket: UdpSocket,
    to: SocketAddr,
    system_id: u8,
    periods: TruthPeriods,
    sequence: u8,
}

impl HawkeyeSender {
    /// A sender to `to` (the viewer's `127.0.0.1:19410 + N`) for system `system_id`, its first sample
    /// at the first multiple of [`TRUTH_PERIOD_US`] after plant time `now_us`, from a [`viewer_socket`]
    /// connected to `to`.
    ///
    /// # Errors
    /// The bind, socket-option or connect error.
    pub fn new(to: SocketAddr, system_id: u8, now_us: u64) -> io::Result<Self> {
        let socket = viewer_socket(to)?;
        socket.connect(to)?;
        Ok(Self { socket, to, system_id, periods: TruthPeriods::new(now_us), sequence: 0 })
    }

    /// Where it sends.
    #[must_use]
    pub fn destination(&self) -> SocketAddr {
        self.to
    }

    /// After every plant step: when a sample is due, send it. `None` when none was due, else whether the
    /// kernel took the datagram (a refusal is only counted by the caller).
    pub fn stepped(&mut self, plant: &Plant) -> Option<bool> {
        if !self.periods.due(plant.time_us()) {
            return None;
        }
        let msg = MavMessage::HIL_STATE_QUATERNION(hil_state_quaternion(&plant.truth(), &plant.config().sensors.home));
        let header =
            MavHeader { system_id: self.system_id.into(), component_id: PLANT_COMPONENT_ID, sequence: self.sequence };
        self.sequence = self.sequence.wrapping_add(1);
        Some(self.socket.send(&encode_frame_v2(header, &msg)).is_ok())
    }
}

impl<T: super::Transport> super::PlantServer<T> {
    /// Send the plant's truth to a Hawkeye viewer through `sender` from the next step on (replacing any
    /// earlier one).
    pub fn set_hawkeye(&mut self, sender: HawkeyeSender) {
        self.hawkeye = Some(sender);
    }

    /// Where the truth goes for Hawkeye, if it does.
    #[must_use]
    pub fn hawkeye(&self) -> Option<&HawkeyeSender> {
        self.hawkeye.as_ref()
    }

    /// After every plant step: the Hawkeye sample, if one is due, sent and counted.
    pub(super) fn send_hawkeye(&mut self) {
        match self.hawkeye.as_mut().and_then(|h| h.stepped(&self.plant)) {
            Some(true) => self.stats.hawkeye_sent += 1,
            Some(false) => self.stats.hawkeye_failed += 1,
            None => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{InitialState, PlantConfig};
    use crate::sim_params::{TruthStream, sim_state};
    use autopilot::core::plant_link::FrameDecoder;
    use mavlink::MavlinkVersion;
    use mavlink::dialects::common::HIL_STATE_QUATERNION_DATA;
    use nalgebra::Vector3;
    use std::time::{Duration, Instant};

    fn flying_plant() -> Plant {
        let start = InitialState {
            pos_ned_m: Vector3::new(40.0, -25.0, -12.0),
            vel_ned_mps: Vector3::new(2.0, 1.0, -0.5),
            euler_rad: Vector3::new(0.15, -0.1, 0.8),
            rate_frd_radps: Vector3::new(0.3, -0.2, 0.1),
            ..InitialState::default()
        };
        let mut plant = Plant::new(PlantConfig::default(), &start, 3).expect("plant");
        plant.set_motors_running(true);
        plant
    }

    /// Every HIL_STATE_QUATERNION waiting on `listener`, one frame per datagram, with its header.
    fn received(listener: &UdpSocket) -> Vec<(MavHeader, HIL_STATE_QUATERNION_DATA)> {
        listener.set_read_timeout(Some(Duration::from_millis(200))).expect("timeout");
        let mut buf = [0_u8; 512];
        let mut got = Vec::new();
        while let Ok(n) = listener.recv(&mut buf) {
            let frames = FrameDecoder::new().decode_datagram(&buf[..n]);
            assert_eq!(frames.len(), 1, "one frame per datagram");
            assert_eq!(frames[0].version, MavlinkVersion::V2);
            match &frames[0].message {
                MavMessage::HIL_STATE_QUATERNION(m) => got.push((frames[0].header, m.clone())),
                other => panic!("not HIL_STATE_QUATERNION: {other:?}"),
            }
        }
        got
    }

    #[test]
    fn given_a_listener_then_it_gets_the_sim_state_samples_as_hil_state_quaternion_every_20_ms_of_plant_time() {
        // GIVEN a viewer listening, the sender and the SIM_ port's stream of a plant at t = 0.
        let listener = UdpSocket::bind("127.0.0.1:0").expect("bind viewer");
        let mut plant = flying_plant();
        let home = plant.config().sensors.home;
        let mut sender = HawkeyeSender::new(listener.local_addr().expect("addr"), 5, plant.time_us()).expect("sender");
        let mut sim = TruthStream::new(plant.time_us());
        // WHEN the plant steps 1 s at 2 ms.
        let mut outcomes = Vec::new();
        while plant.time_us() < 1_000_000 {
            plant.step([1560.0, 1540.0, 1550.0, 1530.0], 2000);
            sim.stepped(&plant, true);
            outcomes.extend(sender.stepped(&plant));
        }
        // THEN 50 datagrams went, at 20, 40, .. 1000 ms, from system 5, component 51, in sequence.
        assert_eq!(outcomes, vec![true; 50]);
        let got = received(&listener);
        let times: Vec<u64> = got.iter().map(|(_, m)| m.time_usec).collect();
        assert_eq!(times, (1..=50).map(|k| k * HAWKEYE_PERIOD_US).collect::<Vec<_>>());
        for (k, (header, _)) in got.iter().enumerate() {
            assert_eq!((header.system_id, header.component_id, usize::from(header.sequence)), (5, 51, k));
        }
        // AND each is the SIM_ port's sample of the same time: the quaternion bit for bit, lat/lon equal.
        let sims = sim.take();
        assert_eq!(sims.len(), 50);
        for ((_, h), pair) in got.iter().zip(&sims) {
            let [MavMessage::SYSTEM_TIME(t), MavMessage::SIM_STATE(s)] = pair else { panic!("{pair:?}") };
            assert_eq!(u64::from(t.time_boot_ms) * 1000, h.time_usec);
            assert_eq!(h.attitude_quaternion.map(f32::to_bits), [s.q1, s.q2, s.q3, s.q4].map(f32::to_bits));
            assert_eq!((h.lat, h.lon), (s.lat_int, s.lon_int));
            assert!((f64::from(h.alt) - f64::from(s.alt) * 1e3).abs() <= 1.0);
        }
        let last = plant.truth();
        assert_eq!(got.last().map(|(_, m)| m.clone()), Some(hil_state_quaternion(&last, &home)));
        assert_ne!(sim_state(&last, &home).q1, 1.0, "a moving attitude");
    }

    #[test]
    fn given_nobody_listening_then_the_refused_sends_are_reported_and_the_plant_goes_on_at_full_speed() {
        // GIVEN a port nobody listens on (bound, then released).
        let to = UdpSocket::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr");
        let mut plant = flying_plant();
        let mut sender = HawkeyeSender::new(to, 1, plant.time_us()).expect("sender");
        // WHEN the plant steps 4 s of plant time.
        let started = Instant::now();
        let mut outcomes = Vec::new();
        while plant.time_us() < 4_000_000 {
            plant.step([1550.0; 4], 2000);
            outcomes.extend(sender.stepped(&plant));
        }
        // THEN every sample was tried once, the kernel refused some (ECONNREFUSED), nothing failed or waited.
        assert_eq!(outcomes.len(), 200);
        let refused = outcomes.iter().filter(|ok| !**ok).count();
        assert!(refused >= 50, "{refused} of 200 refused");
        assert!(started.elapsed() < Duration::from_secs(20), "{:?}", started.elapsed());
    }
}

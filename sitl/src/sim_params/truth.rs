//! The plant's true state as it goes out on the SIM_ port: SIM_STATE (with SYSTEM_TIME) built from the
//! plant's truth, and the stream that samples it at [`TRUTH_RATE_HZ`] of plant time.

use autopilot::core::mavlink::units::deg_to_dege7;
use mavlink::dialects::common::{MavMessage, SIM_STATE_DATA, SYSTEM_TIME_DATA};

use crate::plant::sensors::{HomeConfig, geodetic_from_ned};
use crate::plant::{Plant, Truth};

/// Rate of the truth stream (SIM_STATE), in plant time.
pub const TRUTH_RATE_HZ: u64 = 50;

/// Plant time between two SIM_STATE (µs).
pub const TRUTH_PERIOD_US: u64 = 1_000_000 / TRUTH_RATE_HZ;

/// The plant's truth as SIM_STATE (see the module documentation for the fields, frames and units): the
/// position mapped to WGS-84 about `home` by the map the plant's GPS uses.
#[must_use]
pub fn sim_state(truth: &Truth, home: &HomeConfig) -> SIM_STATE_DATA {
    let q = truth.q_ned_frd.quaternion();
    let geo = geodetic_from_ned(home, &truth.pos_ned_m);
    let (euler, acc, rate, vel) =
        (truth.euler_rad, truth.specific_force_frd_mps2, truth.rate_frd_radps, truth.vel_ned_mps);
    SIM_STATE_DATA {
        q1: q.w as f32,
        q2: q.i as f32,
        q3: q.j as f32,
        q4: q.k as f32,
        roll: euler.x as f32,
        pitch: euler.y as f32,
        yaw: euler.z as f32,
        xacc: acc.x as f32,
        yacc: acc.y as f32,
        zacc: acc.z as f32,
        xgyro: rate.x as f32,
        ygyro: rate.y as f32,
        zgyro: rate.z as f32,
        lat: geo.lat_deg as f32,
        lon: geo.lon_deg as f32,
        alt: geo.alt_amsl_m as f32,
        std_dev_horz: 0.0,
        std_dev_vert: 0.0,
        vn: vel.x as f32,
        ve: vel.y as f32,
        vd: vel.z as f32,
        lat_int: deg_to_dege7(geo.lat_deg),
        lon_int: deg_to_dege7(geo.lon_deg),
    }
}

/// One truth sample as it goes out, in this order in one datagram: SYSTEM_TIME (`time_boot_ms` = the
/// plant time in ms) and SIM_STATE ([`sim_state`]).
#[must_use]
pub fn truth_messages(truth: &Truth, home: &HomeConfig) -> [MavMessage; 2] {
    let time = SYSTEM_TIME_DATA { time_unix_usec: 0, time_boot_ms: (truth.time_us / 1000) as u32 };
    [MavMessage::SYSTEM_TIME(time), MavMessage::SIM_STATE(sim_state(truth, home))]
}

/// The truth samples due on plant time: [`TruthStream::stepped`], after each plant step, takes one when
/// the step crossed into a new [`TRUTH_PERIOD_US`] period (at most one per step); [`TruthStream::take`]
/// hands over those taken since the last call, oldest first.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthStream {
    /// The period (plant time / [`TRUTH_PERIOD_US`]) of the last step seen.
    period: u64,
    pending: Vec<[MavMessage; 2]>,
}

impl TruthStream {
    /// A stream for a plant at plant time `now_us`: the first sample is at the next multiple of
    /// [`TRUTH_PERIOD_US`].
    #[must_use]
    pub fn new(now_us: u64) -> Self {
        Self { period: now_us / TRUTH_PERIOD_US, pending: Vec::new() }
    }

    /// After a plant step: take a sample of `plant` if the step entered a new period and someone is
    /// `listening` (a sample nobody would receive is not built).
    pub fn stepped(&mut self, plant: &Plant, listening: bool) {
        let period = plant.time_us() / TRUTH_PERIOD_US;
        if period == self.period {
            return;
        }
        self.period = period;
        if listening {
            self.pending.push(truth_messages(&plant.truth(), &plant.config().sensors.home));
        }
    }

    /// The samples taken since the last call, oldest first.
    pub fn take(&mut self) -> Vec<[MavMessage; 2]> {
        std::mem::take(&mut self.pending)
    }
}

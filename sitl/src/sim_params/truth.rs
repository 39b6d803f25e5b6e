//! The plant's true state as it goes out on the SIM_ port: SIM_STATE (with SYSTEM_TIME) built from the
//! plant's truth, and the stream that samples it at [`TRUTH_RATE_HZ`] of plant time; and the same truth
//! as HIL_STATE_QUATERNION for PX4's Hawkeye viewer ([`hil_state_quaternion`]), sampled on the same
//! plant-time periods ([`TruthPeriods`]), so at equal times the two carry the same sample.

use autopilot::core::mavlink::units::{deg_to_dege7, m_to_mm, mps_to_cmps_i16, mps2_to_mg, to_centi_u16};
use mavlink::dialects::common::{HIL_STATE_QUATERNION_DATA, MavMessage, SIM_STATE_DATA, SYSTEM_TIME_DATA};

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

/// The plant's truth as HIL_STATE_QUATERNION, as PX4's Hawkeye viewer draws it, with SIM_STATE's
/// conventions ([`sim_state`]) so the two agree at the same truth: `time_usec` the plant time (µs);
/// `attitude_quaternion` the same f32 quaternion as SIM_STATE's `q1..q4` (w x y z, NED <- FRD);
/// `rollspeed/pitchspeed/yawspeed` the body rates FRD (rad/s); `lat/lon` (degE7) and `alt` (mm AMSL) from
/// the same GPS map of the NED position ([`geodetic_from_ned`] about `home`), so `lat/lon` equal SIM_STATE's
/// `lat_int/lon_int`; `vx/vy/vz` the velocity NED (cm/s, saturated to i16: ±327 m/s);
/// `ind_airspeed = true_airspeed` the speed relative to the air (|velocity - wind|, cm/s; the truth always
/// carries the wind, zero in calm air, so in calm air this is the ground speed); `xacc/yacc/zacc` the
/// specific force FRD (mG, saturated to i16: what an ideal accelerometer reads, -1000 on `zacc` at rest).
#[must_use]
pub fn hil_state_quaternion(truth: &Truth, home: &HomeConfig) -> HIL_STATE_QUATERNION_DATA {
    let q = truth.q_ned_frd.quaternion();
    let geo = geodetic_from_ned(home, &truth.pos_ned_m);
    let (acc, rate, vel) = (truth.specific_force_frd_mps2, truth.rate_frd_radps, truth.vel_ned_mps);
    let airspeed_cmps = to_centi_u16((vel - truth.wind_ned_mps).norm());
    HIL_STATE_QUATERNION_DATA {
        time_usec: truth.time_us,
        attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        rollspeed: rate.x as f32,
        pitchspeed: rate.y as f32,
        yawspeed: rate.z as f32,
        lat: deg_to_dege7(geo.lat_deg),
        lon: deg_to_dege7(geo.lon_deg),
        alt: m_to_mm(geo.alt_amsl_m),
        vx: mps_to_cmps_i16(vel.x),
        vy: mps_to_cmps_i16(vel.y),
        vz: mps_to_cmps_i16(vel.z),
        ind_airspeed: airspeed_cmps,
        true_airspeed: airspeed_cmps,
        xacc: mps2_to_mg(acc.x),
        yacc: mps2_to_mg(acc.y),
        zacc: mps2_to_mg(acc.z),
    }
}

/// When a truth sample is due on plant time: after a plant step that entered a new [`TRUTH_PERIOD_US`]
/// period (at most one per step). The SIM_ port's [`TruthStream`] and the Hawkeye stream both sample by it,
/// from the same start, so they take the same steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TruthPeriods {
    /// The period (plant time / [`TRUTH_PERIOD_US`]) of the last step seen.
    period: u64,
}

impl TruthPeriods {
    /// For a plant at plant time `now_us`: the first sample is due at the next multiple of
    /// [`TRUTH_PERIOD_US`].
    #[must_use]
    pub fn new(now_us: u64) -> Self {
        Self { period: now_us / TRUTH_PERIOD_US }
    }

    /// After a plant step to plant time `time_us`: whether a sample is due now.
    pub fn due(&mut self, time_us: u64) -> bool {
        let period = time_us / TRUTH_PERIOD_US;
        let due = period != self.period;
        self.period = period;
        due
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
    periods: TruthPeriods,
    pending: Vec<[MavMessage; 2]>,
}

impl TruthStream {
    /// A stream for a plant at plant time `now_us`: the first sample is at the next multiple of
    /// [`TRUTH_PERIOD_US`].
    #[must_use]
    pub fn new(now_us: u64) -> Self {
        Self { periods: TruthPeriods::new(now_us), pending: Vec::new() }
    }

    /// After a plant step: take a sample of `plant` if the step entered a new period and someone is
    /// `listening` (a sample nobody would receive is not built).
    pub fn stepped(&mut self, plant: &Plant, listening: bool) {
        if self.periods.due(plant.time_us()) && listening {
            self.pending.push(truth_messages(&plant.truth(), &plant.config().sensors.home));
        }
    }

    /// The samples taken since the last call, oldest first.
    pub fn take(&mut self) -> Vec<[MavMessage; 2]> {
        std::mem::take(&mut self.pending)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use autopilot::core::plant_link::{FrameDecoder, encode_frame_v2};
    use mavlink::{MavHeader, MavlinkVersion};
    use nalgebra::Vector3;

    /// A plant flying 0.5 s after a tumbling start far from home, in a steady 4 m/s east wind.
    fn flown_plant() -> Plant {
        let mut plant = super::super::tests::flying_plant();
        plant.wind_mut().set_steady_ned_mps(Vector3::new(0.0, 4.0, 0.0));
        for _ in 0..250 {
            plant.step([1600.0, 1550.0, 1500.0, 1450.0], 2000);
        }
        plant
    }

    #[test]
    fn given_a_flying_plant_then_hil_state_quaternion_agrees_with_sim_state_field_by_field() {
        let plant = flown_plant();
        let (truth, home) = (plant.truth(), plant.config().sensors.home);
        let (h, s) = (hil_state_quaternion(&truth, &home), sim_state(&truth, &home));
        assert_eq!(h.time_usec, truth.time_us);
        assert_eq!(h.time_usec, 500_000);
        // The quaternion bit for bit, the rates as SIM_STATE's gyro.
        assert_eq!(h.attitude_quaternion.map(f32::to_bits), [s.q1, s.q2, s.q3, s.q4].map(f32::to_bits));
        assert_eq!((h.rollspeed, h.pitchspeed, h.yawspeed), (s.xgyro, s.ygyro, s.zgyro));
        // The position: lat/lon equal SIM_STATE's degE7 (and its f32 degrees to their precision), alt its
        // metres within a millimetre.
        assert_eq!((h.lat, h.lon), (s.lat_int, s.lon_int));
        assert!((f64::from(h.lat) * 1e-7 - f64::from(s.lat)).abs() < 1e-5);
        assert!((f64::from(h.alt) - f64::from(s.alt) * 1e3).abs() <= 1.0, "{} mm vs {} m", h.alt, s.alt);
        // The velocity in cm/s, the specific force in mG, both FRD/NED as SIM_STATE's.
        for (got, want) in [(h.vx, s.vn), (h.vy, s.ve), (h.vz, s.vd)] {
            assert!((f64::from(got) - f64::from(want) * 100.0).abs() <= 0.5 + 1e-3, "{got} cm/s vs {want} m/s");
        }
        for (got, want) in [(h.xacc, s.xacc), (h.yacc, s.yacc), (h.zacc, s.zacc)] {
            let want_mg = f64::from(want) / autopilot::core::mavlink::units::MPS2_PER_G * 1e3;
            assert!((f64::from(got) - want_mg).abs() <= 0.5 + 1e-3, "{got} mG vs {want} m/s²");
        }
        // The airspeed is relative to the air: the 4 m/s east wind taken off the ground velocity.
        let air = (truth.vel_ned_mps - Vector3::new(0.0, 4.0, 0.0)).norm();
        assert!((air - truth.vel_ned_mps.norm()).abs() > 1.0, "the wind matters here");
        assert_eq!((h.ind_airspeed, h.true_airspeed), (to_centi_u16(air), to_centi_u16(air)));
        // Something moved, so none of this compares zeros.
        assert!(truth.rate_frd_radps.norm() > 0.05 && truth.vel_ned_mps.norm() > 0.5, "{truth:?}");
    }

    #[test]
    fn given_speeds_past_the_fields_then_they_saturate_rather_than_wrap() {
        let plant = flown_plant();
        let (mut truth, home) = (plant.truth(), plant.config().sensors.home);
        truth.vel_ned_mps = Vector3::new(400.0, -400.0, 327.0);
        truth.wind_ned_mps = Vector3::new(-400.0, 400.0, 0.0);
        truth.specific_force_frd_mps2 = Vector3::new(1e4, -1e4, 0.0);
        let h = hil_state_quaternion(&truth, &home);
        assert_eq!((h.vx, h.vy, h.vz), (i16::MAX, i16::MIN, 32_700));
        assert_eq!((h.ind_airspeed, h.true_airspeed), (u16::MAX - 1, u16::MAX - 1), "65535 means unknown");
        assert_eq!((h.xacc, h.yacc, h.zacc), (i16::MAX, i16::MIN, 0));
    }

    #[test]
    fn given_a_hil_state_quaternion_then_a_mavlink_2_frame_of_it_parses_back_to_the_same_message() {
        let plant = flown_plant();
        let h = hil_state_quaternion(&plant.truth(), &plant.config().sensors.home);
        let header = MavHeader { system_id: 7, component_id: crate::sim_params::PLANT_COMPONENT_ID, sequence: 42 };
        let bytes = encode_frame_v2(header, &MavMessage::HIL_STATE_QUATERNION(h.clone()));
        assert_eq!(bytes[0], 0xFD, "a MAVLink 2 frame");
        let frames = FrameDecoder::new().decode_datagram(&bytes);
        assert_eq!(frames.len(), 1);
        assert_eq!(frames[0].version, MavlinkVersion::V2);
        assert_eq!(frames[0].header, header);
        assert_eq!(frames[0].message, MavMessage::HIL_STATE_QUATERNION(h));
    }

    #[test]
    fn truth_periods_are_due_once_per_20_ms_of_plant_time_whatever_the_step() {
        let mut periods = TruthPeriods::new(0);
        let due: Vec<u64> = (1..=30).map(|k| k * 2000).filter(|&t| periods.due(t)).collect();
        assert_eq!(due, [20_000, 40_000, 60_000]);
        let mut periods = TruthPeriods::new(0);
        let due: Vec<u64> = (1..=20).map(|k| k * 3000).filter(|&t| periods.due(t)).collect();
        assert_eq!(due, [21_000, 42_000, 60_000]);
    }
}

//! The rate level's setpoint shaping, shared by the controllers that fly it: a lead-lag that cancels a
//! proportional rate loop's lag. In: the body rates asked for (FRD rad/s) each inner tick, the rate
//! loop's gains (1/s) and the tick (s). Out: the rate setpoint for that loop.
//!
//! A rate loop `ω̇ = Kω (ω_sp - ω)` follows a step a time constant 1/Kω behind, so a vehicle asked for
//! 0.5 rad/s for 0.6 s turns 0.5/Kω rad short (55 mrad at Kω = 9/s) and is still turning when asked to
//! stop. Fed through `(1 + s/Kω) / (1 + τ s)` the setpoint cancels that pole and leaves the faster
//! `τ` ([`LAG_S`]): the vehicle turns by the integral of the rates asked for, `τ` late. A constant
//! request passes unchanged (centred sticks hold the attitude where it is). Only the rate level is
//! shaped; an attitude loop's setpoint is not.
//!
//! A rate loop without integral action (ACO's) is also given the integral of what it missed: the angle by
//! which the vehicle has turned less than the low-passed request, fed back at `angle_gain_per_s`, so a
//! roll there and back ends where it began. A loop with its own integrator (PID's) takes gain 0 and
//! integrates its error against the low-passed request ([`Shaped::lowpassed_frd_radps`]), not the lead,
//! so the lead does not wind it up.

use nalgebra::Vector3;

/// The shaped setpoint's time constant τ (s): 20 ticks at 500 Hz, about a third of the lag of a rate
/// loop at Kω = 9/s, and long enough that reversing 0.5 rad/s (a lead of 1/(Kω τ) = 2.8 times the 1 rad/s
/// step) stays inside the controllers' 3.5 rad/s rate limit, unclipped.
pub const LAG_S: f64 = 0.04;

/// The lead-lag's state: the asked rates low-passed at τ (None: not at the rate level), and the angle
/// (FRD rad) the vehicle has turned short of them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RateShaper {
    lowpassed_frd_radps: Option<Vector3<f64>>,
    missed_frd_rad: Vector3<f64>,
}

/// A shaped rate request (FRD rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shaped {
    /// The rate loop's setpoint.
    pub setpoint_frd_radps: Vector3<f64>,
    /// The request low-passed at τ: what the vehicle should turn at, for an integrator's error.
    pub lowpassed_frd_radps: Vector3<f64>,
}

impl RateShaper {
    /// Not at the rate level: the next request starts the filter afresh.
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The setpoint for rates `asked_frd_radps` through `(1 + s/Kω)/(1 + τ s)`, with the rate loop's
    /// gains `k_rate_per_s`, the vehicle's rates `rate_frd_radps` and the tick `dt_s`, plus the missed
    /// angle times `angle_gain_per_s`. The first call after a reset starts from the vehicle's rates, so
    /// entering the rate level at speed is a step like any other.
    pub fn shape(
        &mut self,
        asked_frd_radps: &Vector3<f64>,
        rate_frd_radps: &Vector3<f64>,
        k_rate_per_s: &[f64; 3],
        angle_gain_per_s: f64,
        dt_s: f64,
    ) -> Shaped {
        let x = self.lowpassed_frd_radps.get_or_insert(*rate_frd_radps);
        *x += (asked_frd_radps - *x) * (dt_s / LAG_S).min(1.0);
        let x = *x;
        self.missed_frd_rad += (x - rate_frd_radps) * dt_s;
        let mut out = x + self.missed_frd_rad * angle_gain_per_s;
        for j in 0..3 {
            let lead_s = if k_rate_per_s[j] > 0.0 { 1.0 / k_rate_per_s[j] } else { 0.0 };
            out[j] += (lead_s / LAG_S) * (asked_frd_radps[j] - x[j]);
        }
        Shaped { setpoint_frd_radps: out, lowpassed_frd_radps: x }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first-order rate loop of gain Kω under the shaped setpoint turns by the integral of the rates
    /// asked for, about τ late; the same loop under the raw step is 1/Kω late.
    #[test]
    fn given_a_p_rate_loop_when_a_step_is_shaped_then_the_angle_follows_the_asked_integral() {
        let (k, dt) = (9.0, 0.002);
        let fly = |shaped: bool| {
            let mut shaper = RateShaper::default();
            let (mut w, mut angle) = (0.0_f64, 0.0_f64);
            for _ in 0..300 {
                let asked = Vector3::new(0.5, 0.0, 0.0);
                let w_frd = Vector3::new(w, 0.0, 0.0);
                let sp = if shaped { shaper.shape(&asked, &w_frd, &[k; 3], 0.0, dt).setpoint_frd_radps.x } else { 0.5 };
                w += k * (sp - w) * dt;
                angle += w * dt;
            }
            angle
        };
        let (raw, shaped) = (fly(false), fly(true));
        assert!((0.3 - raw - 0.5 / k).abs() < 0.01, "raw: {raw}");
        assert!((0.3 - shaped - 0.5 * LAG_S).abs() < 0.005, "shaped: {shaped}");
        // A loop that turns 10 % slow is brought back onto the request's integral by the missed angle.
        let mut shaper = RateShaper::default();
        let (mut w, mut angle) = (0.0_f64, 0.0_f64);
        for i in 0..2000 {
            let asked = Vector3::new(if i < 300 { 0.5 } else { 0.0 }, 0.0, 0.0);
            let sp = shaper.shape(&asked, &Vector3::new(w, 0.0, 0.0), &[k; 3], 3.0, dt).setpoint_frd_radps.x;
            w += k * (0.9 * sp - w) * dt;
            angle += w * dt;
        }
        assert!((angle - 0.3).abs() < 0.005, "ends at {angle} rad, asked 0.3 rad");
        // A constant request passes unchanged.
        let mut s = RateShaper::default();
        let c = Vector3::new(0.1, -0.2, 0.3);
        for _ in 0..100 {
            s.shape(&c, &c, &[9.0; 3], 3.0, dt);
        }
        assert!((s.shape(&c, &c, &[9.0; 3], 3.0, dt).setpoint_frd_radps - c).norm() < 1e-12);
    }
}

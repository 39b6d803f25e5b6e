//! A train of crosswind pulses (`[wind.pulses]`): the paper's "wind pulsed on the quadrotor all the time".
//! In: the train's ranges (amplitude m/s, width s, gap s), direction, start and end (s of plant time), and a
//! random stream of its own (the plant seed's `stream::WIND_PULSES`). Out: the pulses, drawn once when the
//! plant is built, and their wind (m/s NED, toward) at a plant time.
//!
//! Pulse k starts at `t_k` and lasts `W_k`: `w(t) = A_k · ½(1 - cos(2π (t - t_k)/W_k)) · dir` on
//! `[t_k, t_k + W_k)`, zero outside (a 1-cos pulse: it rises from and returns to zero, peaking at `A_k` in
//! its middle). `t_0 = start_s`, `t_{k+1} = t_k + W_k + G_k`; each pulse draws, in this order, its amplitude
//! `A_k`, width `W_k` and the gap `G_k` after it, each uniform over its range; pulses are drawn while
//! `t_k < end_s`. The defaults are Beaufort 4's range (5.5-7.9 m/s) toward +E.
//!
//! The train draws from its own stream only, so adding one changes no other draw (turbulence, sensor
//! noise), and a wind without `[wind.pulses]` is the same, bit for bit, as before the train existed.

use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use super::PlantError;
use super::airframe::{finite, non_negative, positive};

/// The most pulses a train may hold (a guard against a train of tiny pulses over an hour).
pub const MAX_PULSES: usize = 10_000;

/// The `[wind.pulses]` table.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PulseTrainConfig {
    /// The range each pulse's peak speed is drawn from, `[least, greatest]` (m/s).
    pub amplitude_mps: [f64; 2],
    /// The range each pulse's duration is drawn from (s, > 0).
    pub width_s: [f64; 2],
    /// The range of the calm between a pulse's end and the next pulse's start (s, >= 0).
    pub gap_s: [f64; 2],
    /// The direction every pulse blows toward, NED (normalised; default +E).
    pub direction_ned: [f64; 3],
    /// The first pulse's start (s of plant time).
    pub start_s: f64,
    /// No pulse starts at or after this time (s of plant time).
    pub end_s: f64,
}

impl Default for PulseTrainConfig {
    fn default() -> Self {
        Self {
            amplitude_mps: [5.5, 7.9],
            width_s: [1.0, 3.0],
            gap_s: [8.0, 14.0],
            direction_ned: [0.0, 1.0, 0.0],
            start_s: 10.0,
            end_s: 100.0,
        }
    }
}

/// One drawn pulse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pulse {
    /// Start (s of plant time).
    pub start_s: f64,
    /// Duration (s).
    pub width_s: f64,
    /// Peak speed (m/s).
    pub amplitude_mps: f64,
}

impl Pulse {
    /// The end of the pulse (s of plant time).
    #[must_use]
    pub fn end_s(&self) -> f64 {
        self.start_s + self.width_s
    }

    /// The pulse's speed (m/s) at plant time `t_s`: `A · ½(1 - cos(2π (t - start)/W))` within it, else 0.
    #[must_use]
    pub fn speed_mps(&self, t_s: f64) -> f64 {
        if t_s < self.start_s || t_s >= self.end_s() {
            return 0.0;
        }
        let phase = std::f64::consts::TAU * (t_s - self.start_s) / self.width_s;
        self.amplitude_mps * 0.5 * (1.0 - phase.cos())
    }
}

/// A resolved pulse train: its direction and its pulses in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct PulseTrain {
    direction_ned: Vector3<f64>,
    pulses: Vec<Pulse>,
}

fn range(
    name: &'static str,
    r: [f64; 2],
    least: fn(&'static str, f64) -> Result<(), PlantError>,
) -> Result<(), PlantError> {
    least(name, r[0])?;
    least(name, r[1])?;
    if r[0] > r[1] {
        return Err(PlantError::InvalidValue {
            name,
            value: format!("{r:?}"),
            reason: "must be [least, greatest] with least <= greatest",
        });
    }
    Ok(())
}

fn draw(rng: &mut ChaCha8Rng, r: [f64; 2]) -> f64 {
    let u: f64 = rng.random();
    r[0] + (r[1] - r[0]) * u
}

impl PulseTrain {
    /// The train of `config`, its pulses drawn from `rng` (the plant's pulse stream).
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] for a range that is not finite `[least, greatest]` (amplitudes and
    /// gaps >= 0, widths > 0), a zero or non-finite direction, a non-finite start or end, or a train of
    /// more than [`MAX_PULSES`] pulses.
    pub fn new(config: &PulseTrainConfig, mut rng: ChaCha8Rng) -> Result<Self, PlantError> {
        range("wind.pulses.amplitude_mps", config.amplitude_mps, non_negative)?;
        range("wind.pulses.width_s", config.width_s, positive)?;
        range("wind.pulses.gap_s", config.gap_s, non_negative)?;
        finite("wind.pulses.start_s", config.start_s)?;
        finite("wind.pulses.end_s", config.end_s)?;
        let direction = Vector3::from(config.direction_ned);
        let norm = direction.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(PlantError::InvalidValue {
                name: "wind.pulses.direction_ned",
                value: format!("{:?}", config.direction_ned),
                reason: "must be a finite non-zero vector",
            });
        }
        let mut pulses = Vec::new();
        let mut t_s = config.start_s;
        while t_s < config.end_s {
            if pulses.len() == MAX_PULSES {
                return Err(PlantError::InvalidValue {
                    name: "wind.pulses.end_s",
                    value: config.end_s.to_string(),
                    reason: "the train would hold more than 10000 pulses",
                });
            }
            let amplitude_mps = draw(&mut rng, config.amplitude_mps);
            let width_s = draw(&mut rng, config.width_s);
            let gap_s = draw(&mut rng, config.gap_s);
            pulses.push(Pulse { start_s: t_s, width_s, amplitude_mps });
            t_s += width_s + gap_s;
        }
        Ok(Self { direction_ned: direction / norm, pulses })
    }

    /// The pulses, in time order.
    #[must_use]
    pub fn pulses(&self) -> &[Pulse] {
        &self.pulses
    }

    /// The train's wind at plant time `t_s` (m/s NED).
    #[must_use]
    pub fn velocity_ned_mps(&self, t_s: f64) -> Vector3<f64> {
        let k = self.pulses.partition_point(|p| p.start_s <= t_s);
        let speed = k.checked_sub(1).map_or(0.0, |k| self.pulses[k].speed_mps(t_s));
        self.direction_ned * speed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{stream, stream_rng};

    #[test]
    fn given_a_seed_then_the_train_is_reproducible_within_its_ranges_and_another_seed_differs() {
        let config = PulseTrainConfig::default();
        let a = PulseTrain::new(&config, stream_rng(3, stream::WIND_PULSES)).unwrap();
        let b = PulseTrain::new(&config, stream_rng(3, stream::WIND_PULSES)).unwrap();
        let c = PulseTrain::new(&config, stream_rng(4, stream::WIND_PULSES)).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_eq!(a.pulses()[0].start_s, 10.0);
        for w in a.pulses().windows(2) {
            let gap = w[1].start_s - w[0].end_s();
            assert!((8.0..=14.0).contains(&gap), "{gap}");
        }
        for p in a.pulses() {
            assert!((5.5..=7.9).contains(&p.amplitude_mps) && (1.0..=3.0).contains(&p.width_s), "{p:?}");
            assert!(p.start_s < 100.0);
        }
        assert!(a.pulses().len() >= 6, "{}", a.pulses().len());
    }

    #[test]
    fn given_a_pulse_then_its_wind_is_1_minus_cos_peaking_in_the_middle() {
        let config = PulseTrainConfig {
            amplitude_mps: [6.0, 6.0],
            width_s: [2.0, 2.0],
            gap_s: [5.0, 5.0],
            ..Default::default()
        };
        let train = PulseTrain::new(&config, stream_rng(1, stream::WIND_PULSES)).unwrap();
        assert_eq!(train.velocity_ned_mps(9.99), Vector3::zeros());
        assert!((train.velocity_ned_mps(11.0) - Vector3::new(0.0, 6.0, 0.0)).norm() < 1e-12);
        assert!((train.velocity_ned_mps(10.5).y - 3.0).abs() < 1e-12);
        assert_eq!(train.velocity_ned_mps(12.0), Vector3::zeros());
        // The second pulse starts 7 s after the first.
        assert!((train.velocity_ned_mps(18.0).y - 6.0).abs() < 1e-12);
    }

    #[test]
    fn given_bad_ranges_then_the_error_names_the_key() {
        let bad = |c: PulseTrainConfig, key: &str| {
            let e = PulseTrain::new(&c, stream_rng(1, 18)).unwrap_err().to_string();
            assert!(e.contains(key), "{e}");
        };
        bad(PulseTrainConfig { amplitude_mps: [7.0, 6.0], ..Default::default() }, "wind.pulses.amplitude_mps");
        bad(PulseTrainConfig { width_s: [0.0, 1.0], ..Default::default() }, "wind.pulses.width_s");
        bad(PulseTrainConfig { gap_s: [-1.0, 1.0], ..Default::default() }, "wind.pulses.gap_s");
        bad(PulseTrainConfig { direction_ned: [0.0; 3], ..Default::default() }, "wind.pulses.direction_ned");
        bad(
            PulseTrainConfig { width_s: [1e-3, 1e-3], gap_s: [0.0, 0.0], end_s: 3600.0, ..Default::default() },
            "wind.pulses.end_s",
        );
    }
}

#[cfg(test)]
mod wind_tests {
    use nalgebra::Vector3;

    use crate::plant::wind::{GaussMarkovConfig, TurbulenceConfig, Wind, WindConfig};
    use crate::plant::{PulseTrainConfig, stream, stream_rng};

    /// The turbulence and the whole wind over 20 s at 1 kHz.
    fn record(config: &WindConfig, seed: u64) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let mut wind = Wind::new(config, stream_rng(seed, stream::WIND)).unwrap();
        (0..20_000u64)
            .map(|k| {
                let w = wind.update(k * 1000, 1.5, &Vector3::zeros());
                (wind.turbulence_ned_mps(), w)
            })
            .unzip()
    }

    #[test]
    fn given_a_pulse_train_then_it_draws_its_own_stream_and_leaves_the_turbulence_bit_identical() {
        let plain = WindConfig {
            turbulence: Some(TurbulenceConfig::GaussMarkov(GaussMarkovConfig::default())),
            ..WindConfig::default()
        };
        let pulsed = WindConfig {
            pulses: Some(PulseTrainConfig { start_s: 2.0, end_s: 20.0, gap_s: [1.0, 2.0], ..Default::default() }),
            ..plain.clone()
        };
        let (turb_plain, wind_plain) = record(&plain, 9);
        let (turb_pulsed, wind_pulsed) = record(&pulsed, 9);
        assert_eq!(turb_plain, turb_pulsed, "the turbulence does not see the train");
        assert_ne!(wind_plain, wind_pulsed);
        // The pulses are those of the seed's pulse stream, and the same again for the same seed.
        let wind = Wind::new(&pulsed, stream_rng(9, stream::WIND)).unwrap();
        let train =
            super::PulseTrain::new(pulsed.pulses.as_ref().unwrap(), stream_rng(9, stream::WIND_PULSES)).unwrap();
        assert_eq!(wind.pulses(), train.pulses());
        assert_eq!(record(&pulsed, 9), (turb_pulsed, wind_pulsed.clone()));
        // The difference is exactly the train's wind, steady + gust + turbulence unchanged.
        for k in [2500u64, 3100, 7000] {
            let t_s = k as f64 * 1e-3;
            let d = wind_pulsed[k as usize] - wind_plain[k as usize];
            assert!((d - train.velocity_ned_mps(t_s)).norm() < 1e-12, "{t_s}: {d:?}");
        }
        assert!(Wind::new(&plain, stream_rng(9, stream::WIND)).unwrap().pulses().is_empty());
    }
}

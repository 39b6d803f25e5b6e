//! A small CMA-ES (covariance matrix adaptation evolution strategy) over the unit box `[0, 1]^n`, written
//! for `sitl tune` from the algorithm's standard equations (Hansen, "The CMA Evolution Strategy: A
//! Tutorial", 2016, with its default strategy parameters), with reflection at the box's faces.
//!
//! Each generation samples `lambda` candidates `x_k = m + sigma * B D z_k` (`z_k` standard normal), reflects
//! them into the box, and hands the whole generation to the caller's evaluator at once (so the caller may
//! evaluate the candidates in parallel); the `mu` best (by cost, ties by index) move the mean, the
//! evolution paths, the covariance `C = B D^2 B^T` and the step size `sigma`. All randomness comes from
//! ChaCha8 seeded with the caller's seed, so the same seed and the same costs give the same candidates bit
//! for bit.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// One evaluated candidate.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// 0-based, in the order the candidates were made.
    pub index: usize,
    /// 0 for the start point, then 1, 2, ... per generation.
    pub generation: usize,
    /// The point in the unit box.
    pub x: Vec<f64>,
    pub cost: f64,
}

/// The settings of one minimisation.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The start point (the mean of the first generation), in the unit box.
    pub x0: Vec<f64>,
    /// The initial step size, as a fraction of the box's side.
    pub sigma0: f64,
    /// Candidates per generation; `None`: the default `4 + floor(3 ln n)`.
    pub population: Option<usize>,
    /// Evaluations in all, the start point's included.
    pub budget: usize,
    pub seed: u64,
}

/// The default population of an `n`-dimensional problem: `4 + floor(3 ln n)`.
#[must_use]
pub fn default_population(n: usize) -> usize {
    4 + (3.0 * (n.max(1) as f64).ln()).floor() as usize
}

/// Folds `v` into `[0, 1]` by reflection at the faces (a triangle wave of period 2).
#[must_use]
pub fn reflect(v: f64) -> f64 {
    if !v.is_finite() {
        return 0.5;
    }
    let r = v.rem_euclid(2.0);
    if r > 1.0 { 2.0 - r } else { r }
}

/// Minimises a cost over `[0, 1]^n`: the start point alone first (generation 0), then generations of
/// `population` candidates until `budget` evaluations are spent (the last generation cut short if the
/// budget ends inside it). `evaluate` gets a generation's points and returns their costs in the same
/// order (a NaN ranks last). Returns every evaluation in order.
///
/// # Panics
/// If `evaluate` returns a different number of costs than it was given points.
pub fn minimize(settings: &Settings, mut evaluate: impl FnMut(&[Vec<f64>]) -> Vec<f64>) -> Vec<Evaluation> {
    let n = settings.x0.len();
    let mut trace = Vec::with_capacity(settings.budget);
    if settings.budget == 0 {
        return trace;
    }
    let x0: Vec<f64> = settings.x0.iter().map(|&v| reflect(v)).collect();
    let cost0 = evaluate(std::slice::from_ref(&x0));
    assert_eq!(cost0.len(), 1, "one cost per point");
    trace.push(Evaluation { index: 0, generation: 0, x: x0.clone(), cost: cost0[0] });
    if n == 0 {
        return trace;
    }

    let lambda = settings.population.unwrap_or_else(|| default_population(n)).max(2);
    let mu = lambda / 2;
    let nf = n as f64;
    // Recombination weights: log-decreasing over the mu best, summing to 1.
    let raw: Vec<f64> = (1..=mu).map(|i| ((mu as f64) + 0.5).ln() - (i as f64).ln()).collect();
    let total: f64 = raw.iter().sum();
    let w: Vec<f64> = raw.iter().map(|r| r / total).collect();
    let mu_eff = 1.0 / w.iter().map(|x| x * x).sum::<f64>();
    let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
    let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
    let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
    let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
    let c_mu = (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff));
    // E||N(0, I)||.
    let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));

    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
    let mut mean = DVector::from_vec(x0);
    let mut sigma = settings.sigma0;
    let mut c = DMatrix::<f64>::identity(n, n);
    let mut b = DMatrix::<f64>::identity(n, n);
    let mut d = DVector::<f64>::from_element(n, 1.0);
    let mut p_sigma = DVector::<f64>::zeros(n);
    let mut p_c = DVector::<f64>::zeros(n);
    let mut generation = 0;

    while trace.len() < settings.budget {
        generation += 1;
        let count = lambda.min(settings.budget - trace.len());
        // y_k = B D z_k; the candidate is m + sigma y_k, reflected into the box for evaluation.
        let ys: Vec<DVector<f64>> = (0..lambda)
            .map(|_| {
                let z = DVector::from_iterator(n, (0..n).map(|_| StandardNormal.sample(&mut rng)));
                &b * d.component_mul(&z)
            })
            .collect();
        let points: Vec<Vec<f64>> =
            ys[..count].iter().map(|y| (&mean + y * sigma).iter().map(|&v| reflect(v)).collect()).collect();
        let costs = evaluate(&points);
        assert_eq!(costs.len(), points.len(), "one cost per point");
        for (point, cost) in points.into_iter().zip(&costs) {
            trace.push(Evaluation { index: trace.len(), generation, x: point, cost: *cost });
        }
        if count < lambda {
            break;
        }
        // Rank: lower cost first, NaN last, ties by index (a stable sort).
        let mut order: Vec<usize> = (0..lambda).collect();
        order.sort_by(|&i, &j| rank_key(costs[i]).total_cmp(&rank_key(costs[j])));
        let y_w: DVector<f64> =
            order.iter().take(mu).zip(&w).fold(DVector::zeros(n), |acc, (&i, wi)| acc + &ys[i] * *wi);
        mean += &y_w * sigma;

        // C^(-1/2) y_w = B D^-1 B^T y_w.
        let c_inv_sqrt_y = &b * (b.transpose() * &y_w).component_div(&d);
        p_sigma = &p_sigma * (1.0 - c_sigma) + c_inv_sqrt_y * (c_sigma * (2.0 - c_sigma) * mu_eff).sqrt();
        let norm_ps = p_sigma.norm();
        let g = generation as f64;
        let h_sigma = norm_ps / (1.0 - (1.0 - c_sigma).powf(2.0 * g)).sqrt() < (1.4 + 2.0 / (nf + 1.0)) * chi_n;
        let h = if h_sigma { 1.0 } else { 0.0 };
        p_c = &p_c * (1.0 - c_c) + &y_w * (h * (c_c * (2.0 - c_c) * mu_eff).sqrt());
        let rank_mu = order
            .iter()
            .take(mu)
            .zip(&w)
            .fold(DMatrix::zeros(n, n), |acc, (&i, wi)| acc + &ys[i] * ys[i].transpose() * *wi);
        let delta_h = (1.0 - h) * c_c * (2.0 - c_c);
        c = &c * (1.0 - c_1 - c_mu) + (&p_c * p_c.transpose() + &c * delta_h) * c_1 + rank_mu * c_mu;
        sigma *= ((c_sigma / d_sigma) * (norm_ps / chi_n - 1.0)).exp();
        // A step far beyond the box searches nothing: cap it at the box's side.
        sigma = sigma.min(1.0);

        // Keep C symmetric against rounding, then B and D from its eigen-decomposition.
        c = (&c + c.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(c.clone());
        b = eigen.eigenvectors;
        d = eigen.eigenvalues.map(|e| e.max(1e-20).sqrt());
    }
    trace
}

/// A cost as a ranking key: NaN ranks after every number.
fn rank_key(cost: f64) -> f64 {
    if cost.is_nan() { f64::INFINITY } else { cost }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn best(trace: &[Evaluation]) -> &Evaluation {
        trace.iter().min_by(|a, b| a.cost.total_cmp(&b.cost)).unwrap()
    }

    #[test]
    fn reflection_folds_every_value_into_the_box() {
        for (v, r) in [(0.3, 0.3), (1.2, 0.8), (-0.25, 0.25), (2.5, 0.5), (-1.75, 0.25), (1.0, 1.0), (0.0, 0.0)] {
            assert!((reflect(v) - r).abs() < 1e-12, "{v}: {}", reflect(v));
        }
        assert_eq!(reflect(f64::NAN), 0.5);
    }

    #[test]
    fn it_finds_the_minimum_of_a_shifted_ellipsoid_within_the_budget() {
        // Minimum 0 at (0.7, 0.2, 0.55, 0.35), axes scaled 1 to 1000.
        let target = [0.7, 0.2, 0.55, 0.35];
        let cost = |x: &[f64]| {
            x.iter().zip(target).enumerate().map(|(i, (v, t))| 10f64.powi(i as i32) * (v - t).powi(2)).sum()
        };
        let settings = Settings { x0: vec![0.5; 4], sigma0: 0.3, population: None, budget: 600, seed: 3 };
        let trace = minimize(&settings, |points| points.iter().map(|p| cost(p)).collect());
        assert_eq!(trace.len(), 600);
        let b = best(&trace);
        assert!(b.cost < 1e-5, "best {} at {:?}", b.cost, b.x);
        for (v, t) in b.x.iter().zip(target) {
            assert!((v - t).abs() < 1e-2, "{:?}", b.x);
        }
    }

    #[test]
    fn it_finds_the_minimum_of_rosenbrock_in_the_box() {
        // Rosenbrock's valley mapped to the box: minimum 0 at u = (1, 1), u = 4 x - 2.
        let cost = |x: &[f64]| {
            let (u, v) = (4.0 * x[0] - 2.0, 4.0 * x[1] - 2.0);
            100.0 * (v - u * u).powi(2) + (1.0 - u).powi(2)
        };
        let settings = Settings { x0: vec![0.2, 0.8], sigma0: 0.2, population: None, budget: 800, seed: 11 };
        let trace = minimize(&settings, |points| points.iter().map(|p| cost(p)).collect());
        let b = best(&trace);
        assert!(b.cost < 1e-4, "best {} at {:?}", b.cost, b.x);
    }

    #[test]
    fn a_minimum_on_the_box_face_is_reached_through_reflection() {
        let cost = |x: &[f64]| (x[0] - 1.0).powi(2) + (x[1] - 0.0).powi(2);
        let settings = Settings { x0: vec![0.5, 0.5], sigma0: 0.3, population: Some(6), budget: 200, seed: 1 };
        let trace = minimize(&settings, |points| points.iter().map(|p| cost(p)).collect());
        assert!(trace.iter().all(|e| e.x.iter().all(|v| (0.0..=1.0).contains(v))));
        assert!(best(&trace).cost < 1e-4, "{:?}", best(&trace));
    }

    #[test]
    fn the_same_seed_gives_the_same_trace_and_another_seed_another() {
        let cost = |x: &[f64]| x.iter().map(|v| (v - 0.3).powi(2)).sum::<f64>();
        let run = |seed| {
            let settings = Settings { x0: vec![0.5; 3], sigma0: 0.3, population: None, budget: 47, seed };
            minimize(&settings, |points| points.iter().map(|p| cost(p)).collect())
        };
        let (a, b, c) = (run(5), run(5), run(6));
        let bits = |t: &[Evaluation]| t.iter().flat_map(|e| e.x.iter().map(|v| v.to_bits())).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b));
        assert_ne!(bits(&a), bits(&c));
        // The budget is exact, the last generation cut short; generation 0 is the start point alone.
        assert_eq!(a.len(), 47);
        assert_eq!((a[0].generation, a[0].x.clone(), a[1].generation), (0, vec![0.5; 3], 1));
        assert!(a.windows(2).all(|w| w[1].index == w[0].index + 1));
    }

    #[test]
    fn a_nan_cost_ranks_last() {
        // The half of the box where x > 0.5 is NaN: the search must still find the minimum at 0.2.
        let cost = |x: &[f64]| if x[0] > 0.5 { f64::NAN } else { (x[0] - 0.2).powi(2) + (x[1] - 0.4).powi(2) };
        let settings = Settings { x0: vec![0.45, 0.5], sigma0: 0.2, population: None, budget: 200, seed: 2 };
        let trace = minimize(&settings, |points| points.iter().map(|p| cost(p)).collect());
        let b = trace.iter().filter(|e| !e.cost.is_nan()).min_by(|a, b| a.cost.total_cmp(&b.cost)).unwrap();
        assert!(b.cost < 1e-4, "{b:?}");
    }
}

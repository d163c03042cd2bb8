//! Generalised least squares on block means, with the covariance of the noise model computed
//! exactly: the regressor tests' estimator ([`super::regression`]).
//!
//! **Why GLS.** A rate ramp, a temperature warm-up and a temperature cycle are slow, where
//! rate random walk and flicker put most of their power. Ordinary least squares weighs every
//! sample alike and so takes most of its variance from the random walk; GLS weighs each
//! frequency by the noise there (`beta = (X^T S^-1 X)^-1 X^T S^-1 y`, the best linear
//! unbiased estimator; Aitken, 1935). On the temperature family of [`super::families`]
//! (3 h at 50 Hz, random walk crossing white noise at a tenth to a third of the record) the
//! Wald statistic of a coupling grows 1.2 to 2.3 times over least squares' for the same
//! coupling (a ramp's: 1.06 to 1.10 times). Because the covariance is known, the statistic
//! follows chi-square exactly under the model, with no penalty for estimating a covariance
//! from a few realisations.
//!
//! **Block means.** The regressors change over minutes, so the series is averaged over
//! blocks of `len` samples (at most [`MAX_BLOCKS`] blocks; the samples after the last whole
//! block are left out) and the dense covariance of the block means is factored once per
//! noise model (Cholesky, `count^3 / 3` flops). Averaging is linear, so block means of the
//! series are block means of the regressors times the coefficients plus block means of the
//! noise: the estimator stays unbiased and its covariance exact; it only gives up the
//! regressors' content faster than a block, which slow regressors do not have.
//!
//! **The covariance of block means** (m samples of `tau0` per block, u the series' unit),
//! term by term as [`crate::sim::noise::AxisNoise`] synthesises them:
//! - white rate noise of density N (u/sqrt(Hz)), with the flicker band faster than a sample
//!   ([`flicker_white_density`]): `N^2 / (m tau0)` on the diagonal;
//! - quantization, the rate `(e_k - e_(k-1)) / tau0` with `e` white of variance Q^2: a block
//!   mean is `(e_last - e_before) / (m tau0)`, so `2 Q^2 / (m tau0)^2` on the diagonal and
//!   `-Q^2 / (m tau0)^2` beside it;
//! - each first-order process (a flicker pole of [`flicker_poles`], or the Gauss-Markov term)
//!   of variance s^2 and `phi = exp(-tau0 / tau_c)`: `s^2 / m^2` times
//!   `m + 2 phi (m (1 - phi) - (1 - phi^m)) / (1 - phi)^2` at lag 0 and
//!   `phi^((d - 1) m + 1) ((1 - phi^m) / (1 - phi))^2` at lag d >= 1 blocks (sums of
//!   `phi^|a - b|` over the two blocks' samples);
//! - rate random walk, `Cov(y_a, y_b) = K^2 tau0 min(a, b)` for samples a, b: between blocks
//!   i < j, `K^2 tau0 (i m + (m - 1) / 2)`; within block i, `K^2 tau0 (i m + (m - 1) (2 m -
//!   1) / (6 m))` (the mean of `min` over a block's pairs).
//!
//! The sensor's low-pass filter has unit gain at the regressors' frequencies and is left out.

use crate::analysis::fit::invert_spd;
use crate::sim::noise::{NoiseTerms, flicker_poles, flicker_tau_max, flicker_white_density};

/// Most blocks: the factorisation costs `MAX_BLOCKS^3 / 3` flops, and a 3 h record's blocks
/// are then about 10 s long, far shorter than a warm-up or a cycle.
pub const MAX_BLOCKS: usize = 1024;

/// How a series is cut into blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Blocks {
    /// Samples per block.
    pub len: usize,
    /// Whole blocks.
    pub count: usize,
}

impl Blocks {
    /// At most [`MAX_BLOCKS`] whole blocks of a series of `n` samples.
    pub fn of(n: usize) -> Blocks {
        let len = n.div_ceil(MAX_BLOCKS).max(1);
        Blocks {
            len,
            count: n / len,
        }
    }

    /// The block means of `x`.
    pub fn means(&self, x: &[f64]) -> Vec<f64> {
        x.chunks_exact(self.len)
            .take(self.count)
            .map(|c| c.iter().sum::<f64>() / self.len as f64)
            .collect()
    }
}

/// The covariance of the block means of `terms`' noise sampled at `rate_hz` (see the module
/// documentation), row-major `count x count`, u^2.
pub fn covariance(terms: &NoiseTerms, rate_hz: f64, blocks: Blocks) -> Vec<f64> {
    let tau0 = 1.0 / rate_hz;
    let (m, count) = (blocks.len as f64, blocks.count);
    let block_s = m * tau0;
    // The stationary terms by lag, in blocks.
    let mut by_lag = vec![0.0; count];
    if let Some(first) = by_lag.first_mut() {
        let white = terms.n * terms.n + flicker_white_density(terms.b, tau0).powi(2);
        *first += white / block_s + 2.0 * terms.q * terms.q / (block_s * block_s);
    }
    if let Some(second) = by_lag.get_mut(1) {
        *second -= terms.q * terms.q / (block_s * block_s);
    }
    let duration = count as f64 * block_s;
    let mut processes: Vec<(f64, f64)> = if terms.b > 0.0 {
        flicker_poles(terms.b, tau0, flicker_tau_max(duration, tau0)).collect()
    } else {
        Vec::new()
    };
    if let Some(g) = terms
        .gauss_markov
        .filter(|g| g.sigma > 0.0 && g.tau_c > 0.0)
    {
        processes.push((g.sigma, g.tau_c));
    }
    for (sigma, tau_c) in processes {
        let x = tau0 / tau_c;
        let phi = (-x).exp();
        let one_minus_phi = -(-x).exp_m1();
        let one_minus_phi_m = -(-m * x).exp_m1();
        let s2 = sigma * sigma / (m * m);
        let within = m + 2.0 * phi * (m * one_minus_phi - one_minus_phi_m) / one_minus_phi.powi(2);
        let sum_m = one_minus_phi_m / one_minus_phi;
        by_lag[0] += s2 * within;
        for (d, v) in by_lag.iter_mut().enumerate().skip(1) {
            let decay = (-(((d - 1) as f64) * m + 1.0) * x).exp();
            if decay < 1e-300 {
                break;
            }
            *v += s2 * decay * sum_m * sum_m;
        }
    }
    let walk = terms.k * terms.k * tau0;
    let mut cov = vec![0.0; count * count];
    for i in 0..count {
        for j in 0..count {
            let lo = i.min(j) as f64 * m;
            let within_walk = if i == j {
                (m - 1.0) * (2.0 * m - 1.0) / (6.0 * m)
            } else {
                (m - 1.0) / 2.0
            };
            cov[i * count + j] = by_lag[i.abs_diff(j)] + walk * (lo + within_walk);
        }
    }
    cov
}

/// The lower Cholesky factor `L` of a covariance (`S = L L^T`), by which series are whitened.
#[derive(Debug, Clone)]
pub struct Whitener {
    n: usize,
    /// Row-major, lower triangle used.
    l: Vec<f64>,
}

impl Whitener {
    /// The factor of the row-major `n x n` symmetric matrix `s`; None unless positive
    /// definite.
    pub fn new(s: &[f64], n: usize) -> Option<Whitener> {
        let mut l = s.to_vec();
        for j in 0..n {
            let prefix: Vec<f64> = l[j * n..j * n + j].to_vec();
            let d = l[j * n + j] - prefix.iter().map(|v| v * v).sum::<f64>();
            if d.is_nan() || d <= 0.0 {
                return None;
            }
            let pivot = d.sqrt();
            l[j * n + j] = pivot;
            for i in j + 1..n {
                let row = &mut l[i * n..i * n + j + 1];
                let dot: f64 = row[..j].iter().zip(&prefix).map(|(a, b)| a * b).sum();
                row[j] = (row[j] - dot) / pivot;
            }
        }
        Some(Whitener { n, l })
    }

    /// `L^-1 v` (forward substitution): white, unit-variance noise when `v` is noise of the
    /// factored covariance.
    pub fn whiten(&self, v: &[f64]) -> Vec<f64> {
        let n = self.n;
        let mut out = vec![0.0; n];
        for i in 0..n.min(v.len()) {
            let row = &self.l[i * n..i * n + i];
            let dot: f64 = row.iter().zip(&out).map(|(a, b)| a * b).sum();
            out[i] = (v[i] - dot) / self.l[i * n + i];
        }
        out
    }
}

/// GLS under one noise model for series of one length: the blocks and the factored
/// covariance of their means.
#[derive(Debug, Clone)]
pub struct Estimator {
    blocks: Blocks,
    whitener: Whitener,
}

impl Estimator {
    /// For series of `n` samples at `rate_hz` whose noise is `terms`; None when the
    /// covariance is not positive definite (no noise at all).
    pub fn new(terms: &NoiseTerms, rate_hz: f64, n: usize) -> Option<Estimator> {
        let blocks = Blocks::of(n);
        let whitener = Whitener::new(&covariance(terms, rate_hz, blocks), blocks.count)?;
        Some(Estimator { blocks, whitener })
    }

    /// GLS of the series `y` on the full-length `columns` (see [`fit`]).
    pub fn fit(&self, columns: &[Vec<f64>], y: &[f64]) -> Option<Fit> {
        let means: Vec<Vec<f64>> = columns.iter().map(|c| self.blocks.means(c)).collect();
        fit(&self.whitener, &means, &self.blocks.means(y))
    }
}

/// A GLS fit: the coefficients and their covariance, in the columns' order.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub beta: Vec<f64>,
    pub cov: Vec<Vec<f64>>,
}

/// GLS of the block means `y` on the block-mean `columns` under the factored covariance:
/// `beta = (X^T S^-1 X)^-1 X^T S^-1 y`, `Cov(beta) = (X^T S^-1 X)^-1`. None when the columns
/// are collinear.
pub fn fit(whitener: &Whitener, columns: &[Vec<f64>], y: &[f64]) -> Option<Fit> {
    let white: Vec<Vec<f64>> = columns.iter().map(|c| whitener.whiten(c)).collect();
    // Unit-norm whitened columns keep the normal equations conditioned whatever the units.
    let norms: Vec<f64> = white
        .iter()
        .map(|c| c.iter().map(|v| v * v).sum::<f64>().sqrt())
        .collect();
    if norms.iter().any(|n| n.is_nan() || *n <= 0.0) {
        return None;
    }
    let yw = whitener.whiten(y);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let p = columns.len();
    let normal: Vec<Vec<f64>> = (0..p)
        .map(|j| {
            (0..p)
                .map(|k| dot(&white[j], &white[k]) / (norms[j] * norms[k]))
                .collect()
        })
        .collect();
    let inv = invert_spd(&normal)?;
    let rhs: Vec<f64> = (0..p).map(|j| dot(&white[j], &yw) / norms[j]).collect();
    let beta = (0..p)
        .map(|j| (0..p).map(|k| inv[j][k] * rhs[k]).sum::<f64>() / norms[j])
        .collect();
    let cov = (0..p)
        .map(|j| (0..p).map(|k| inv[j][k] / (norms[j] * norms[k])).collect())
        .collect();
    Some(Fit { beta, cov })
}

/// The Wald statistic `b^T C^-1 b` of the coefficients at `indices` of a fit: chi-square
/// with `indices.len()` degrees of freedom when those coefficients are 0 and the covariance
/// is the noise's. None when their covariance is singular.
pub fn wald(fit: &Fit, indices: &[usize]) -> Option<f64> {
    let b: Vec<f64> = indices.iter().map(|&i| fit.beta[i]).collect();
    let c: Vec<Vec<f64>> = indices
        .iter()
        .map(|&i| indices.iter().map(|&j| fit.cov[i][j]).collect())
        .collect();
    let inv = invert_spd(&c)?;
    Some(
        (0..b.len())
            .map(|i| b[i] * (0..b.len()).map(|j| inv[i][j] * b[j]).sum::<f64>())
            .sum(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::noise::{AxisNoise, GaussMarkov};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// `n` samples of `terms` at `rate` Hz, seed `seed`.
    fn series(terms: NoiseTerms, rate: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        AxisNoise::new(terms, rate, n as f64 / rate, &mut rng).take(n, &mut rng)
    }

    /// The computed covariance of block means against the sample covariance of many
    /// simulated series, every term at once: each entry within 4 standard errors (the
    /// sample covariance of R draws has standard error `sqrt((S_ii S_jj + S_ij^2) / R)`).
    #[test]
    fn block_covariance_matches_simulation() {
        let rate = 10.0;
        let terms = NoiseTerms {
            q: 2e-3,
            n: 1e-2,
            b: 3e-3,
            k: 2e-3,
            gauss_markov: Some(GaussMarkov {
                sigma: 5e-3,
                tau_c: 3.0,
            }),
            ..NoiseTerms::default()
        };
        let n = 200;
        let blocks = Blocks { len: 25, count: 8 };
        let exact = covariance(&terms, rate, blocks);
        let r = 20_000;
        let mut sum = vec![0.0; 64];
        for seed in 0..r {
            let means = blocks.means(&series(terms, rate, n, seed));
            for i in 0..8 {
                for j in 0..8 {
                    sum[i * 8 + j] += means[i] * means[j] / r as f64;
                }
            }
        }
        let mut worst: f64 = 0.0;
        for i in 0..8 {
            for j in 0..8 {
                let s = exact[i * 8 + j];
                let se = ((exact[i * 8 + i] * exact[j * 8 + j] + s * s) / r as f64).sqrt();
                worst = worst.max((sum[i * 8 + j] - s).abs() / se);
            }
        }
        assert!(worst < 4.0, "worst entry {worst:.2} standard errors off");
    }

    /// GLS of a ramp in white noise plus a random walk: the coefficient's covariance is the
    /// spread of the estimates over many series, and the Wald statistic is chi-square(1).
    #[test]
    fn gls_covariance_is_the_spread_of_its_estimates() {
        let rate = 5.0;
        let terms = NoiseTerms {
            n: 1e-2,
            k: 1e-3,
            ..NoiseTerms::default()
        };
        let n = 2000;
        let blocks = Blocks::of(n);
        let whitener = Whitener::new(&covariance(&terms, rate, blocks), blocks.count).unwrap();
        let time: Vec<f64> = (0..n).map(|i| i as f64 / rate).collect();
        let columns = vec![vec![1.0; blocks.count], blocks.means(&time)];
        let r = 2000;
        let mut slopes = Vec::with_capacity(r);
        let mut walds = Vec::with_capacity(r);
        let mut stated = 0.0;
        for seed in 0..r as u64 {
            let f = fit(
                &whitener,
                &columns,
                &blocks.means(&series(terms, rate, n, seed)),
            )
            .unwrap();
            slopes.push(f.beta[1]);
            walds.push(wald(&f, &[1]).unwrap());
            stated = f.cov[1][1];
        }
        let var = slopes.iter().map(|s| s * s).sum::<f64>() / r as f64;
        // The sample variance of r normal draws has relative sd sqrt(2 / r) = 3.2 %.
        assert!(
            (var / stated - 1.0).abs() < 4.0 * (2.0 / r as f64).sqrt(),
            "{var} vs {stated}"
        );
        // P(chi2_1 > 6.63) = 1 %: binomial(2000, 0.01) has mean 20, sd 4.5.
        let above = walds.iter().filter(|w| **w > 6.635).count();
        assert!(
            (6..=34).contains(&above),
            "{above} of {r} above the 1 % point"
        );
    }

    #[test]
    fn blocks_cover_the_series() {
        assert_eq!(
            Blocks::of(1000),
            Blocks {
                len: 1,
                count: 1000
            }
        );
        assert_eq!(
            Blocks::of(540_000),
            Blocks {
                len: 528,
                count: 1022
            }
        );
        let b = Blocks { len: 3, count: 2 };
        assert_eq!(
            b.means(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]),
            vec![2.0, 5.0]
        );
    }
}

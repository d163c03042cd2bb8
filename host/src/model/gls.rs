//! The regressor tests' statistic ([`super::regression`]): a likelihood ratio of the
//! record's block means with and without the regressors, under Gaussian noise of the
//! IEEE-952 kinds whose covariance is computed exactly, calibrated by a parametric
//! bootstrap.
//!
//! **Why a likelihood.** A rate ramp, a temperature warm-up and a temperature cycle are
//! slow, where rate random walk and flicker put most of their power. The likelihood weighs
//! each frequency by the noise there (generalised least squares, `beta = (X^T S^-1 X)^-1 X^T
//! S^-1 y`; Aitken, 1935) and sees what an Allan curve cannot: that a ramp is one straight
//! line, while a random walk whose level explains the record's slow power also wanders at
//! minutes. On the temperature family of `model::families` a least-squares estimate left
//! 1.2 to 2.3 times the Wald statistic on the table.
//!
//! **Why levels are estimated, and how the test stays calibrated.** K (and B) are what
//! decide whether a slow regressor stands out, and a single record gives K only roughly: in
//! 64 block means of a record whose random walk crosses the white noise at a fifth of it,
//! the restricted-likelihood K has quartiles 0.01, 0.43 and 1.7 times the truth. A test that
//! takes the levels as known is then far from its law (the Wald statistic under levels
//! fitted with the regressor in: 43 of 300 noise records below p = 0.05, 10 below 1e-3; the
//! plain likelihood ratio against chi-square: 27 of 80 below 0.1), and a refit that left K
//! at 0 showed a ramp with T^2 = 20 on pure noise. So the statistic is the likelihood ratio
//! `2 (min nll_without - min nll_with)`, each side with its own levels (maximum likelihood),
//! and its law under the null comes from series drawn from the noise the record shows
//! without the regressors (levels by restricted maximum likelihood: Patterson & Thompson,
//! Biometrika 58, 1971; Harville, JASA 72, 1977), each put through the same two fits — a
//! parametric bootstrap. A draw is a vector of block means `L z` (L the covariance's
//! Cholesky factor, z standard normal), not a synthesis of the record. Measured on that
//! configuration (`the_bootstrap_ramp_test_is_calibrated_and_finds_ramps`): 11 of 80 noise
//! records below p = 0.1 and none below 0.01; ramps raising the Allan deviation at a quarter
//! of the record 6 times found below 1e-3 in 19 of 20, 4.5 times in 7, 3 times in 5. The
//! price of honesty is there: with the ramp in the record the null's levels include the
//! power the ramp lends the random walk, so a weak ramp cannot be told from a random walk's
//! own trend.
//!
//! **Block means.** The regressors change over minutes, so the series is averaged over
//! blocks of `len` samples (at most [`MAX_BLOCKS`] blocks; the samples after the last whole
//! block are left out). Averaging is linear, so block means of the series are block means of
//! the regressors times the coefficients plus block means of the noise: nothing is biased;
//! only the regressors' content faster than a block, which slow regressors do not have, is
//! given up.
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
//! The white noise, quantization and Gauss-Markov terms are taken from the noise model (the
//! shortest taus fix them far better than block means can); B and K are searched. The
//! sensor's low-pass filter has unit gain at the regressors' frequencies and is left out.

use crate::analysis::numerics::dot;
use crate::sim::noise::{NoiseTerms, flicker_poles, flicker_tau_max, flicker_white_density};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

/// Most blocks: each evaluation of the restricted likelihood factors a covariance
/// (`MAX_BLOCKS^3 / 3` flops), and a test takes about 50 fits of 50 evaluations each. A
/// 3 h record's blocks are then 170 s long, shorter than a warm-up or a cycle.
pub const MAX_BLOCKS: usize = 64;

/// Draws between the looks of [`Estimator::test_designs_until`].
const SEQUENTIAL_CHUNK: usize = 128;

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

    /// The means of `x`'s first [`Blocks::count`] blocks.
    pub fn means(&self, x: &[f64]) -> Vec<f64> {
        let mut means = super::clean::block_means(x, self.len);
        means.truncate(self.count);
        means
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
            // Rows above j are final; row j's first j entries are L's.
            let (done, below) = l.split_at_mut((j + 1) * n);
            let (prefix, diagonal) = done[j * n..j * n + j + 1].split_at_mut(j);
            let d = diagonal[0] - dot(prefix, prefix);
            if d.is_nan() || d <= 0.0 {
                return None;
            }
            let pivot = d.sqrt();
            diagonal[0] = pivot;
            for row in below.chunks_exact_mut(n) {
                row[j] = (row[j] - dot(&row[..j], prefix)) / pivot;
            }
        }
        Some(Whitener { n, l })
    }

    /// `L z`: a draw of the factored covariance's noise when `z` is standard normal.
    pub fn colour(&self, z: &[f64]) -> Vec<f64> {
        let n = self.n;
        (0..n)
            .map(|i| dot(&self.l[i * n..i * n + i + 1], z))
            .collect()
    }

    /// `L^-1 v` (forward substitution): white, unit-variance noise when `v` is noise of the
    /// factored covariance.
    pub fn whiten(&self, v: &[f64]) -> Vec<f64> {
        let n = self.n;
        let mut out = vec![0.0; n];
        for i in 0..n.min(v.len()) {
            out[i] = (v[i] - dot(&self.l[i * n..i * n + i], &out)) / self.l[i * n + i];
        }
        out
    }

    /// The log-determinant of the factored matrix, `2 sum ln L_ii`.
    pub fn log_det(&self) -> f64 {
        (0..self.n).map(|i| 2.0 * self.l[i * self.n + i].ln()).sum()
    }
}

/// Least plausible and most plausible flicker and random-walk levels the restricted
/// likelihood is searched over, as the natural log of their block variance relative to the
/// white noise's: from a millionth of it (absent) to a few thousand times.
const LOG_LEVEL_RANGE: (f64, f64) = (-14.0, 8.0);

/// Likelihoods of the block means of series of one length, with the flicker and random-walk
/// levels searched and the other terms of the noise model fixed (see the module
/// documentation).
#[derive(Debug, Clone)]
pub struct Estimator {
    blocks: Blocks,
    /// Block covariance of the fixed terms (white, quantization, Gauss-Markov).
    fixed: Vec<f64>,
    /// Per unit B^2 and per unit K^2.
    flicker: Vec<f64>,
    walk: Vec<f64>,
    /// B^2 and K^2 of the model, where the search starts.
    start: [f64; 2],
    /// The unit levels' block variance relative to the white noise's: `level = scale * e^u`.
    scale: [f64; 2],
}

impl Estimator {
    /// For series of `n` samples at `rate_hz` whose noise has `terms`' white noise,
    /// quantization and Gauss-Markov terms, cut into at most [`MAX_BLOCKS`] blocks.
    pub fn new(terms: &NoiseTerms, rate_hz: f64, n: usize) -> Estimator {
        Estimator::with_blocks(terms, rate_hz, Blocks::of(n))
    }

    /// As [`Estimator::new`] with the given blocks.
    pub fn with_blocks(terms: &NoiseTerms, rate_hz: f64, blocks: Blocks) -> Estimator {
        let only = |f: &dyn Fn(&mut NoiseTerms)| {
            let mut t = NoiseTerms::default();
            f(&mut t);
            covariance(&t, rate_hz, blocks)
        };
        let fixed = only(&|t| {
            t.n = terms.n;
            t.q = terms.q;
            t.gauss_markov = terms.gauss_markov;
        });
        let flicker = only(&|t| t.b = 1.0);
        let walk = only(&|t| t.k = 1.0);
        let count = blocks.count.max(1);
        let white = if fixed[0] > 0.0 { fixed[0] } else { 1.0 };
        let walk_mean = (0..count).map(|i| walk[i * count + i]).sum::<f64>() / count as f64;
        Estimator {
            blocks,
            scale: [white / flicker[0], white / walk_mean],
            start: [terms.b * terms.b, terms.k * terms.k],
            fixed,
            flicker,
            walk,
        }
    }

    fn covariance(&self, levels: [f64; 2]) -> Vec<f64> {
        self.fixed
            .iter()
            .zip(&self.flicker)
            .zip(&self.walk)
            .map(|((f, b), k)| f + levels[0] * b + levels[1] * k)
            .collect()
    }

    fn levels(&self, u: [f64; 2]) -> [f64; 2] {
        [self.scale[0] * u[0].exp(), self.scale[1] * u[1].exp()]
    }

    /// The negative log-likelihood of the block means `y` with the block-mean `columns` as
    /// fixed effects at the log levels `u` (infinite outside [`LOG_LEVEL_RANGE`] or where
    /// the columns are collinear).
    fn nll(&self, columns: &[Vec<f64>], y: &[f64], u: [f64; 2], likelihood: Likelihood) -> f64 {
        let inside = |v: f64| (LOG_LEVEL_RANGE.0..=LOG_LEVEL_RANGE.1).contains(&v);
        if !inside(u[0]) || !inside(u[1]) {
            return f64::INFINITY;
        }
        Whitener::new(&self.covariance(self.levels(u)), self.blocks.count)
            .and_then(|w| {
                let parts = solve(&w, columns, y)?;
                let contrasts = if likelihood == Likelihood::Restricted {
                    parts.log_det_normal
                } else {
                    0.0
                };
                Some(0.5 * (w.log_det() + contrasts + parts.residual))
            })
            .unwrap_or(f64::INFINITY)
    }

    /// The flicker and random-walk levels (B^2, K^2) that maximise the `likelihood` of the
    /// block means `y` with the block-mean `columns` as fixed effects, searched from `start`,
    /// and the minimised negative log-likelihood. None when the columns are collinear.
    pub fn likeliest(
        &self,
        columns: &[Vec<f64>],
        y: &[f64],
        start: [f64; 2],
        likelihood: Likelihood,
    ) -> Option<([f64; 2], f64)> {
        let negative_log_likelihood = |u: [f64; 2]| self.nll(columns, y, u, likelihood);
        let from = |level: f64, scale: f64| {
            if level > 0.0 {
                (level / scale)
                    .ln()
                    .clamp(LOG_LEVEL_RANGE.0 + 2.0, LOG_LEVEL_RANGE.1 - 2.0)
            } else {
                LOG_LEVEL_RANGE.0 + 4.0
            }
        };
        let u0 = [from(start[0], self.scale[0]), from(start[1], self.scale[1])];
        let best = nelder_mead(&negative_log_likelihood, u0, 2.0);
        let nll = negative_log_likelihood(best);
        nll.is_finite().then(|| (self.levels(best), nll))
    }

    /// The test of whether the columns at `tested` play a part in the series `y`, beside the
    /// others (a constant among them): the likelihood-ratio statistic, and that statistic on
    /// `draws` series drawn from the noise without them (see the module documentation).
    /// None when the columns are collinear.
    pub fn test(
        &self,
        columns: &[Vec<f64>],
        tested: &[usize],
        y: &[f64],
        draws: usize,
        seed: u64,
    ) -> Option<Bootstrap> {
        self.test_designs(&[Design { columns, tested }], y, draws, seed)
    }

    /// [`Estimator::test`] of one set of regressors in several designs at once — beside
    /// fewer or more of the other regressors — with the largest of the designs' likelihood
    /// ratios as the statistic, on the record and on every draw alike, so its null holds the
    /// maximum's own spread. The draws come from the levels the record shows without the
    /// tested columns in the first design. None when any design is collinear.
    pub fn test_designs(
        &self,
        designs: &[Design],
        y: &[f64],
        draws: usize,
        seed: u64,
    ) -> Option<Bootstrap> {
        self.test_designs_until(designs, y, draws, seed, usize::MAX)
    }

    /// [`Estimator::test_designs`], drawing no further once `enough` draws reach the
    /// record's statistic: the sequential Monte Carlo test of Besag & Clifford (Biometrika
    /// 78, 1991), which stops where its p-value can no longer fall below `enough / draws`.
    pub fn test_designs_until(
        &self,
        designs: &[Design],
        y: &[f64],
        draws: usize,
        seed: u64,
        enough: usize,
    ) -> Option<Bootstrap> {
        struct Means {
            with: Vec<Vec<f64>>,
            without: Vec<Vec<f64>>,
        }
        let means: Vec<Means> = designs
            .iter()
            .map(|d| {
                let with: Vec<Vec<f64>> = d.columns.iter().map(|c| self.blocks.means(c)).collect();
                let without = with
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !d.tested.contains(i))
                    .map(|(_, c)| c.clone())
                    .collect();
                Means { with, without }
            })
            .collect();
        let y = self.blocks.means(y);
        // Twice the drop of the plain likelihood's minimum when the tested columns join,
        // the largest over the designs. The first design must be testable; a later one whose
        // columns are degenerate (a temperature channel that never changed, or that moved
        // only as a straight line in time) is passed over rather than voiding the test.
        let ratio = |y: &[f64], start: [f64; 2]| -> Option<f64> {
            let drop = |m: &Means| -> Option<f64> {
                let (_, without) = self.likeliest(&m.without, y, start, Likelihood::Plain)?;
                let (_, with) = self.likeliest(&m.with, y, start, Likelihood::Plain)?;
                Some(2.0 * (without - with))
            };
            let first = drop(means.first()?)?;
            Some(means[1..].iter().filter_map(drop).fold(first, f64::max))
        };
        let statistic = ratio(&y, self.start)?;
        let (levels, _) = self.likeliest(
            &means.first()?.without,
            &y,
            self.start,
            Likelihood::Restricted,
        )?;
        let w = Whitener::new(&self.covariance(levels), self.blocks.count)?;
        let draw = |i: usize| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(i as u64));
            let z: Vec<f64> = (0..self.blocks.count)
                .map(|_| rng.sample::<f64, _>(StandardNormal))
                .collect();
            ratio(&w.colour(&z), levels)
        };
        // Drawn in chunks, so the stop is looked at between them; draw i has seed + i
        // whatever the chunks.
        let mut null: Vec<f64> = Vec::with_capacity(draws);
        let mut beyond = 0;
        for start in (0..draws).step_by(SEQUENTIAL_CHUNK) {
            if beyond >= enough {
                break;
            }
            let end = (start + SEQUENTIAL_CHUNK).min(draws);
            let chunk: Vec<f64> = (start..end).into_par_iter().filter_map(draw).collect();
            beyond += chunk.iter().filter(|&&v| v >= statistic).count();
            null.extend(chunk);
        }
        Some(Bootstrap { statistic, null })
    }
}

impl Estimator {
    /// The standard deviation of each column's ordinary least-squares coefficient on the
    /// block means of `y` (least squares is what removes a named regressor, so this is the
    /// spread of the coefficient shown). For given levels it is the sandwich `A S A^T`, `A =
    /// (X^T X)^-1 X^T`, S the block covariance (White, Econometrica 48, 1980, with S
    /// modelled rather than taken from the residuals). A record gives the random walk's
    /// level only roughly, and the slope's error is the random walk's own trend, so the
    /// variance is averaged over the flicker and random-walk levels, weighted by the
    /// restricted likelihood of the record with every column in: a flat prior on the log
    /// levels over the whole searched range, on a grid of `LEVEL_GRID_STEP` (the levels
    /// integrated out rather than fixed at the likeliest). Measured on a ramp beside white
    /// noise, flicker and a random walk that crosses the white noise at a fifth of the record
    /// (`a_ramps_standard_error_is_calibrated`, 100 records): the errors over their standard
    /// errors have a mean square of 1.8 and 88 lie within 2, where the likeliest levels alone
    /// gave 2.9. Levels fitted without the regressor gave 1.2, but they carry the
    /// regressor's power, so the error grows with the ramp (half the slope on a record whose
    /// ramp the test named), and the errors were skewed (a noise trend running against the
    /// ramp shrank the error). For regressors
    /// as slow as a ramp or a warm-up, least squares on the samples and on their block means
    /// agree. None when the columns are collinear.
    pub fn coefficient_sd(&self, columns: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
        let x: Vec<Vec<f64>> = columns.iter().map(|c| self.blocks.means(c)).collect();
        let y = self.blocks.means(y);
        let count = self.blocks.count;
        let gram: Vec<Vec<f64>> = x
            .iter()
            .map(|a| x.iter().map(|b| dot(a, b)).collect())
            .collect();
        let inverse = crate::analysis::numerics::invert_spd(&gram)?;
        // Rows of A = (X^T X)^-1 X^T, one per column.
        let a: Vec<Vec<f64>> = inverse
            .iter()
            .map(|row| {
                (0..count)
                    .map(|t| row.iter().zip(&x).map(|(g, c)| g * c[t]).sum())
                    .collect()
            })
            .collect();
        let variances = |u: [f64; 2]| -> Vec<f64> {
            let s = self.covariance(self.levels(u));
            a.iter()
                .map(|r| {
                    (0..count)
                        .map(|i| r[i] * (0..count).map(|j| s[i * count + j] * r[j]).sum::<f64>())
                        .sum::<f64>()
                        .max(0.0)
                })
                .collect()
        };
        let points = ((LOG_LEVEL_RANGE.1 - LOG_LEVEL_RANGE.0) / LEVEL_GRID_STEP) as i32;
        let steps = (0..=points).map(|k| LOG_LEVEL_RANGE.0 + k as f64 * LEVEL_GRID_STEP);
        let grid: Vec<[f64; 2]> = steps
            .clone()
            .flat_map(|b| steps.clone().map(move |k| [b, k]))
            .collect();
        let weighed: Vec<(f64, [f64; 2])> = grid
            .into_par_iter()
            .map(|u| (self.nll(&x, &y, u, Likelihood::Restricted), u))
            .filter(|(nll, _)| nll.is_finite())
            .collect();
        let least = weighed.iter().map(|w| w.0).fold(f64::INFINITY, f64::min);
        let mut total = vec![0.0; x.len()];
        let mut weight = 0.0;
        for (nll, u) in weighed {
            let w = (least - nll).exp();
            if w < 1e-12 {
                continue;
            }
            weight += w;
            total
                .iter_mut()
                .zip(variances(u))
                .for_each(|(t, v)| *t += w * v);
        }
        (weight > 0.0).then(|| total.iter().map(|t| (t / weight).sqrt()).collect())
    }
}

/// Spacing of the log-level grid, over the whole [`LOG_LEVEL_RANGE`], that the coefficients'
/// variance is averaged over ([`Estimator::coefficient_sd`]).
const LEVEL_GRID_STEP: f64 = 1.0;

/// One design of a regressor test: the columns (a constant among them) and the positions
/// of the tested ones.
#[derive(Debug, Clone, Copy)]
pub struct Design<'a> {
    pub columns: &'a [Vec<f64>],
    pub tested: &'a [usize],
}

/// A parametric-bootstrap test: the measured statistic and its values on series drawn
/// under the null.
#[derive(Debug, Clone)]
pub struct Bootstrap {
    pub statistic: f64,
    pub null: Vec<f64>,
}

/// Which likelihood of the block means a search maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Likelihood {
    /// `-1/2 (ln |S| + r^T S^-1 r)`: comparable between designs, so it gives the ratio.
    Plain,
    /// `-1/2 (ln |S| + ln |X^T S^-1 X| + r^T S^-1 r)`: the contrasts free of the columns,
    /// whose levels are not biased low by what the columns take.
    Restricted,
}

/// Minimise `f` over two variables from `start` with a simplex of side `step` (Nelder &
/// Mead, "A simplex method for function minimization", Computer Journal 7, 1965; standard
/// coefficients), until the simplex's values agree within 1e-4 or 200 evaluations.
pub(super) fn nelder_mead(f: &dyn Fn([f64; 2]) -> f64, start: [f64; 2], step: f64) -> [f64; 2] {
    let best = nelder_mead_n(&|u: &[f64]| f([u[0], u[1]]), &start, step);
    [best[0], best[1]]
}

/// Minimise `f` over the `d = start.len()` variables from `start` with a simplex of side
/// `step` (Nelder & Mead, 1965; reflection 1, expansion 2, contraction and shrinkage 1/2),
/// until the simplex's values agree within 1e-4 or `100 d` evaluations.
pub(super) fn nelder_mead_n(f: &dyn Fn(&[f64]) -> f64, start: &[f64], step: f64) -> Vec<f64> {
    let d = start.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = (0..=d)
        .map(|i| {
            let mut p = start.to_vec();
            if i > 0 {
                p[i - 1] += step;
            }
            let v = f(&p);
            (p, v)
        })
        .collect();
    let at = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect()
    };
    let mut evaluations = d + 1;
    while evaluations < 100 * d {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (best, worst) = (simplex[0].1, simplex[d].1);
        if worst.is_finite() && worst - best < 1e-4 {
            break;
        }
        // The centroid of all but the worst vertex, as offsets from the best.
        let centroid: Vec<f64> = (0..d)
            .map(|k| {
                let first = simplex[0].0[k];
                first
                    + simplex[1..d]
                        .iter()
                        .map(|p| (p.0[k] - first) / d as f64)
                        .sum::<f64>()
            })
            .collect();
        let reflected = at(&centroid, &simplex[d].0, -1.0);
        let fr = f(&reflected);
        evaluations += 1;
        if fr < simplex[0].1 {
            let expanded = at(&centroid, &simplex[d].0, -2.0);
            let fe = f(&expanded);
            evaluations += 1;
            simplex[d] = if fe < fr {
                (expanded, fe)
            } else {
                (reflected, fr)
            };
        } else if fr < simplex[d - 1].1 {
            simplex[d] = (reflected, fr);
        } else {
            let contracted = if fr < simplex[d].1 {
                at(&centroid, &reflected, 0.5)
            } else {
                at(&centroid, &simplex[d].0, 0.5)
            };
            let fc = f(&contracted);
            evaluations += 1;
            if fc < fr.min(simplex[d].1) {
                simplex[d] = (contracted, fc);
            } else {
                let anchor = simplex[0].0.clone();
                for v in simplex.iter_mut().skip(1) {
                    v.0 = at(&anchor, &v.0, 0.5);
                    v.1 = f(&v.0);
                }
                evaluations += d;
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex.swap_remove(0).0
}

/// The parts of the likelihoods a GLS solution gives.
pub(super) struct Solution {
    /// `r^T S^-1 r`, r the GLS residual.
    pub(super) residual: f64,
    /// `ln |X^T S^-1 X|`.
    pub(super) log_det_normal: f64,
}

/// Design columns whitened and scaled to unit norm (the normal equations then stay
/// conditioned whatever the units).
struct Whitened {
    columns: Vec<Vec<f64>>,
    /// Each whitened column's norm before scaling.
    norms: Vec<f64>,
    /// `X^T S^-1 X` of the scaled columns.
    normal: Vec<Vec<f64>>,
}

/// The whitened design; None when a column vanishes.
fn whitened(whitener: &Whitener, columns: &[Vec<f64>]) -> Option<Whitened> {
    let white: Vec<Vec<f64>> = columns.iter().map(|c| whitener.whiten(c)).collect();
    let norms: Vec<f64> = white.iter().map(|c| dot(c, c).sqrt()).collect();
    if norms.iter().any(|n| n.is_nan() || *n <= 0.0) {
        return None;
    }
    let white: Vec<Vec<f64>> = white
        .into_iter()
        .zip(&norms)
        .map(|(c, n)| c.iter().map(|v| v / n).collect())
        .collect();
    let normal = white
        .iter()
        .map(|a| white.iter().map(|b| dot(a, b)).collect())
        .collect();
    Some(Whitened {
        columns: white,
        norms,
        normal,
    })
}

/// GLS of the block means `y` on the block-mean `columns` under the factored covariance
/// `S`: the residual `|y_w|^2 - |L_n^-1 X_w^T y_w|^2` (w whitened, `L_n` the Cholesky factor
/// of the normal matrix) and `ln |X^T S^-1 X|`. None when the columns are collinear.
pub(super) fn solve(whitener: &Whitener, columns: &[Vec<f64>], y: &[f64]) -> Option<Solution> {
    let w = whitened(whitener, columns)?;
    let flat: Vec<f64> = w.normal.iter().flatten().copied().collect();
    let factor = Whitener::new(&flat, columns.len())?;
    let yw = whitener.whiten(y);
    let rhs: Vec<f64> = w.columns.iter().map(|c| dot(c, &yw)).collect();
    let explained = factor.whiten(&rhs).iter().map(|v| v * v).sum::<f64>();
    Some(Solution {
        residual: (dot(&yw, &yw) - explained).max(0.0),
        log_det_normal: factor.log_det() + 2.0 * w.norms.iter().map(|n| n.ln()).sum::<f64>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::numerics::invert_spd;
    use crate::model::evidence::scaled_chi_square_p;
    use crate::sim::noise::{AxisNoise, GaussMarkov};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// GLS coefficients and their covariance `(X^T S^-1 X)^-1`.
    fn fit(whitener: &Whitener, columns: &[Vec<f64>], y: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
        let Whitened {
            columns: white,
            norms,
            normal,
        } = whitened(whitener, columns).unwrap();
        let inv = invert_spd(&normal).unwrap();
        let yw = whitener.whiten(y);
        let rhs: Vec<f64> = white.iter().map(|c| dot(c, &yw)).collect();
        let p = columns.len();
        let beta = (0..p).map(|j| dot(&inv[j], &rhs) / norms[j]).collect();
        let cov = (0..p)
            .map(|j| (0..p).map(|k| inv[j][k] / (norms[j] * norms[k])).collect())
            .collect();
        (beta, cov)
    }

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
            let (beta, cov) = fit(
                &whitener,
                &columns,
                &blocks.means(&series(terms, rate, n, seed)),
            );
            slopes.push(beta[1]);
            // The Wald statistic of one coefficient: b^2 / Var(b).
            walds.push(beta[1] * beta[1] / cov[1][1]);
            stated = cov[1][1];
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

    /// The ramp tests' record: 2048 samples at 5 Hz in 64 blocks, white noise, flicker and
    /// a random walk crossing the white noise at a fifth of the record; the estimator knows
    /// every level but K.
    struct RampCase {
        rate: f64,
        n: usize,
        duration: f64,
        truth: NoiseTerms,
        estimator: Estimator,
        time: Vec<f64>,
    }

    fn ramp_case() -> RampCase {
        let rate = 5.0;
        let blocks = Blocks { len: 32, count: 64 };
        let n = blocks.len * blocks.count;
        let duration = n as f64 / rate;
        let truth = NoiseTerms {
            n: 1e-2,
            b: 2e-3,
            k: 3f64.sqrt() * 1e-2 / (duration / 5.0),
            ..NoiseTerms::default()
        };
        RampCase {
            rate,
            n,
            duration,
            truth,
            estimator: Estimator::with_blocks(&NoiseTerms { k: 0.0, ..truth }, rate, blocks),
            time: (0..n).map(|i| i as f64 / rate).collect(),
        }
    }

    /// The standard error of a ramp's least-squares slope, under white noise, flicker and a
    /// random walk whose levels the record gives only roughly: over 100 records the errors
    /// divided by their standard errors have a mean square near 1 and the 2-sigma intervals
    /// hold the truth about as often as they should. With exact levels the mean square of
    /// 100 would lie in [0.64, 1.43] (chi-square, 99.9 %); estimated levels widen that, and
    /// 2-sigma coverage of 95 % on 100 records is below 88 with probability 0.1 %. Measured:
    /// 1.80 and 88; the bounds catch the levels taken as known (2.9).
    #[test]
    fn a_ramps_standard_error_is_calibrated() {
        let RampCase {
            rate,
            n,
            truth,
            estimator,
            time,
            ..
        } = ramp_case();
        let columns = vec![vec![1.0; n], time.clone()];
        let slope = 2e-5;
        let mean_t = time.iter().sum::<f64>() / n as f64;
        let sxx: f64 = time.iter().map(|t| (t - mean_t).powi(2)).sum();
        let z: Vec<f64> = (0..100u64)
            .map(|seed| {
                let mut y = series(truth, rate, n, 500 + seed);
                y.iter_mut().zip(&time).for_each(|(v, t)| *v += slope * t);
                let sxy: f64 = time.iter().zip(&y).map(|(t, v)| (t - mean_t) * v).sum();
                let sd = estimator.coefficient_sd(&columns, &y).unwrap()[1];
                (sxy / sxx - slope) / sd
            })
            .collect();
        let mean_square = z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64;
        let covered = z.iter().filter(|v| v.abs() < 2.0).count();
        eprintln!("ramp slope z: mean square {mean_square:.3}, {covered} of 100 within 2");
        assert!((0.6..=2.3).contains(&mean_square), "{mean_square}");
        assert!(covered >= 85, "{covered}");
    }

    /// White noise, flicker and a random walk; a ramp column, and no ramp or one raising the
    /// Allan deviation at a quarter of the record six times; the model's K set to 0 (as a
    /// refit after a removal can leave it). The bootstrap test's p-values are calibrated
    /// without the ramp and small with it.
    #[test]
    fn the_bootstrap_ramp_test_is_calibrated_and_finds_ramps() {
        let RampCase {
            rate,
            n,
            duration,
            truth,
            estimator,
            time,
        } = ramp_case();
        let columns = vec![vec![1.0; n], time.clone()];
        let tau = duration / 4.0;
        let base = truth.n * truth.n / tau
            + 2.0 * 2f64.ln() / std::f64::consts::PI * truth.b * truth.b
            + truth.k * truth.k * tau / 3.0;
        let p_values = |raise: f64, seeds: std::ops::Range<u64>| -> Vec<f64> {
            let slope = ((raise * raise - 1.0).max(0.0) * base * 2.0 / (tau * tau)).sqrt();
            seeds
                .map(|seed| {
                    let mut y = series(truth, rate, n, seed);
                    y.iter_mut().zip(&time).for_each(|(v, t)| *v += slope * t);
                    let t = estimator.test(&columns, &[1], &y, 24, 1000 * seed).unwrap();
                    scaled_chi_square_p(t.statistic, &t.null)
                })
                .collect()
        };
        let null = p_values(0.0, 0..80);
        let below = |p: &[f64], level: f64| p.iter().filter(|v| **v < level).count();
        // Binomial(80, 0.1): mean 8, sd 2.7; binomial(80, 0.5): mean 40, sd 4.5.
        assert!(
            below(&null, 0.1) <= 16,
            "{} of 80 below 0.1",
            below(&null, 0.1)
        );
        assert!(
            (24..=56).contains(&below(&null, 0.5)),
            "{} of 80 below 0.5",
            below(&null, 0.5)
        );
        // Measured 81 (88 on another stream of the same noise) of 100 below 1e-3 at a raise
        // of 6, and a quarter at a raise of 3, where the random walk's own trend, whose level
        // the record gives only roughly, can make the ramp. At a rate of 0.8 the count of 100
        // has a standard deviation of 4: the bound is 2.5 of those below.
        let ramps = p_values(6.0, 100..200);
        assert!(
            below(&ramps, 1e-3) >= 70,
            "{} of 100 ramps below 1e-3",
            below(&ramps, 1e-3)
        );
    }

    /// The several-design test: with one design it is [`Estimator::test`]; with a second
    /// (the tested ramp beside a warm-up column) its statistic is the larger of the two
    /// designs' on the record and on every draw, the draws coming from the first design's
    /// null levels and seeds.
    #[test]
    fn a_test_over_designs_takes_the_larger_ratio_everywhere() {
        let case = ramp_case();
        let (n, time, estimator) = (case.n, &case.time, &case.estimator);
        let warm: Vec<f64> = time
            .iter()
            .map(|t| 1.0 - (-t / (case.duration / 8.0)).exp())
            .collect();
        let alone = vec![vec![1.0; n], time.clone()];
        let beside = vec![vec![1.0; n], time.clone(), warm.clone()];
        // A ramp and a warm-up of opposite signs, the warm-up's coefficient chosen so that
        // the two leave no least-squares slope on time: alone, the ramp is hidden.
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (t_mean, w_mean) = (mean(time), mean(&warm));
        let (tw, tt) = time.iter().zip(&warm).fold((0.0, 0.0), |(tw, tt), (t, w)| {
            (
                tw + (t - t_mean) * (w - w_mean),
                tt + (t - t_mean) * (t - t_mean),
            )
        });
        let slope = 1e-4;
        let coeff = -slope * tt / tw;
        let mut y = series(case.truth, case.rate, n, 7);
        y.iter_mut()
            .zip(time.iter().zip(&warm))
            .for_each(|(v, (t, w))| *v += slope * t + coeff * w);
        let single = estimator.test(&alone, &[1], &y, 16, 5).unwrap();
        let one = Design {
            columns: &alone,
            tested: &[1],
        };
        let same = estimator.test_designs(&[one], &y, 16, 5).unwrap();
        assert_eq!(single.statistic, same.statistic);
        assert_eq!(single.null, same.null);
        let two = Design {
            columns: &beside,
            tested: &[1],
        };
        let both = estimator.test_designs(&[one, two], &y, 16, 5).unwrap();
        let other = estimator.test(&beside, &[1], &y, 1, 5).unwrap();
        assert_eq!(both.statistic, single.statistic.max(other.statistic));
        assert!(
            other.statistic > 10.0 * single.statistic.max(1.0),
            "{other:?} {single:?}"
        );
        assert_eq!(both.null.len(), single.null.len());
        for (b, s) in both.null.iter().zip(&single.null) {
            assert!(b >= s, "{both:?} {single:?}");
        }
        assert!(both.null.iter().zip(&single.null).any(|(b, s)| b > s));
    }

    /// A later design whose columns are degenerate (a temperature channel that never changed
    /// is a column of zeros once centred) is passed over: the test is the first design's,
    /// on the record and on every draw, instead of no test at all.
    #[test]
    fn a_degenerate_design_beside_a_testable_one_is_passed_over() {
        let case = ramp_case();
        let (n, time, estimator) = (case.n, &case.time, &case.estimator);
        let alone = vec![vec![1.0; n], time.clone()];
        let flat = vec![vec![1.0; n], time.clone(), vec![0.0; n]];
        let mut y = series(case.truth, case.rate, n, 7);
        y.iter_mut().zip(time).for_each(|(v, t)| *v += 1e-4 * t);
        let one = Design {
            columns: &alone,
            tested: &[1],
        };
        let degenerate = Design {
            columns: &flat,
            tested: &[1],
        };
        assert!(estimator.test_designs(&[degenerate], &y, 4, 5).is_none());
        let single = estimator.test_designs(&[one], &y, 16, 5).unwrap();
        let both = estimator
            .test_designs(&[one, degenerate], &y, 16, 5)
            .expect("the first design is testable");
        assert_eq!(both.statistic, single.statistic);
        assert_eq!(both.null, single.null);
    }

    #[test]
    fn blocks_cover_the_series() {
        assert_eq!(Blocks::of(60), Blocks { len: 1, count: 60 });
        assert_eq!(
            Blocks::of(540_000),
            Blocks {
                len: 8438,
                count: 63
            }
        );
        let b = Blocks { len: 3, count: 2 };
        assert_eq!(
            b.means(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]),
            vec![2.0, 5.0]
        );
    }
}

//! The Gauss-Markov candidate's second view: the exact likelihood of the record's cosine
//! transform, where a process of minutes leaves its evidence.
//!
//! **Why.** The Allan curve's misfit drop judges a Gauss-Markov term against realisations
//! of the current model, whose B and K absorbed the process's bump; such noise shows bumps
//! of its own, and the drop's null spreads wide (on one 4 h record, 7.8 +- 21). Measured on
//! the family's records (`model::gauss_markov_power`), flicker at a free level bends to a
//! process of minutes everywhere but in the few lowest bins below its corner, where the
//! process is flat and flicker still rises as 1/f; a likelihood that weighs each frequency
//! by the noise there sees that, and its ratio is nearly pivotal (a null of mean about 1).
//!
//! **The transform.** The orthonormal DCT-II makes every term of the noise model diagonal:
//! a rate random walk's increments are white, and the path graph's Laplacian `D^T D` (D the
//! first difference) is diagonalised exactly by the DCT-II with eigenvalues `2 - 2 cos(pi k
//! / n)` (Strang, "The discrete cosine transform", SIAM Review 41, 1999), so coefficient k
//! of a walk with increments of variance `K^2 tau0` has variance `K^2 tau0 / (2 - 2 cos(pi
//! k / n))`, independent of the others once the mean (k = 0) is left out. White noise is
//! diagonal in any orthonormal basis (times the sensor filter's power gain at the
//! coefficient's frequency `k f_s / (2 n)`); a first-order process of variance s^2 and `phi
//! = exp(-tau0 / tau_c)` (each pole of the flicker bank, and the Gauss-Markov term) is
//! diagonal up to edge terms, with its discrete spectrum `s^2 (1 - phi^2) / (1 - 2 phi cos w
//! + phi^2)` at `w = pi k / n`.
//!
//! **The likelihood.** Coefficients up to [`HIGHEST_HZ`]: the first [`SINGLE_COEFFICIENTS`]
//! one by one (the process's corner and the slow regressors live there), the rest summed in
//! bands [`BANDS_PER_OCTAVE`] to the octave, within which the model's variance changes by a
//! few percent: `-2 ln L = sum_k (ln v_k + c_k^2 / v_k) + sum_j (m_j ln v_j + P_j / v_j)`,
//! P_j the band's sum of squares over m_j coefficients (Whittle, "Curve and periodogram
//! smoothing", JRSS B 19, 1957). The regressors the model has named (a ramp, the
//! temperature and its rate, slow tones) are fixed effects profiled out of the single
//! coefficients by weighted least squares, so removing them takes from neither side of the
//! ratio what the other keeps. White noise and quantization are the model's; flicker and
//! random walk are searched on both sides, the Gauss-Markov term's level beside them at
//! each correlation time of a grid from [`GRID_FRACTIONS`] of the record.
//!
//! **The test.** The statistic is `2 (min nll without - min nll with)`; its null comes from
//! coefficient vectors drawn from the levels the record shows without the term (single
//! coefficients normal, band sums `v_j chi2_(m_j)`), each put through the same two searches
//! (a parametric bootstrap). On the family's 3 h records it names 8 of 10 processes of
//! minutes, a different 8 from the Allan view's, and gives p of 0.16 to 1.0 on the same
//! records without the process (`model::gauss_markov_power`).

use super::gls::nelder_mead_n;
use crate::analysis::low_pass::LowPass;
use crate::analysis::numerics::{dot, invert_spd};
use crate::analysis::shared_plans;
use crate::sim::noise::{NoiseTerms, flicker_poles, flicker_tau_max, flicker_white_density};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, StandardNormal};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Highest frequency whose coefficients the view reads, Hz: a process of minutes and the
/// flicker and random walk it competes with are decided far below it, and the sensor's
/// filter and its lines lie far above it.
pub const HIGHEST_HZ: f64 = 1.0;
/// Coefficients taken one by one: 128 cycles per record.
pub const SINGLE_COEFFICIENTS: usize = 256;
/// Bands per octave above the single coefficients: a 1/f^2 variance changes by 9 % across
/// one.
pub const BANDS_PER_OCTAVE: f64 = 16.0;
/// Correlation times tried, as fractions of the record: from a third of a percent (a
/// corner at 53 cycles per record) to a tenth (a corner at 1.6 cycles per record: a longer
/// process shows no plateau the record can tell from a random walk).
pub const GRID_FRACTIONS: (f64, f64) = (0.003, 0.1);
/// Correlation times on the grid, log-spaced (0.15 decades apart).
pub const GRID_POINTS: usize = 10;
/// Log-levels searched, relative to the white variance at the first coefficient.
const LOG_LEVEL_RANGE: (f64, f64) = (-30.0, 30.0);

/// The orthonormal DCT-II coefficients 1..=kmax of `x` (Makhoul's even-odd reordering and
/// one real FFT of the same length: IEEE Trans. ASSP 28, 1980).
pub fn dct2(x: &[f64], kmax: usize) -> Vec<f64> {
    let n = x.len();
    let half = n.div_ceil(2);
    let mut v: Vec<f64> = (0..n)
        .map(|i| {
            if i < half {
                x[2 * i]
            } else {
                x[2 * (n - i) - 1]
            }
        })
        .collect();
    let r2c = shared_plans::forward(n);
    let mut out = r2c.make_output_vec();
    r2c.process(&mut v, &mut out)
        .expect("buffers of the plan's sizes");
    let scale = (2.0 / n as f64).sqrt();
    out[1..=kmax]
        .iter()
        .enumerate()
        .map(|(i, z)| {
            let a = -PI * (i + 1) as f64 / (2.0 * n as f64);
            (z.re * a.cos() - z.im * a.sin()) * scale
        })
        .collect()
}

/// Variances of DCT coefficients 1..=kmax for `n` samples at `rate_hz`: the fixed part (white
/// and quantization of `terms`), and per unit B^2 and per unit K^2.
pub fn coefficient_variances(
    terms: &NoiseTerms,
    rate_hz: f64,
    n: usize,
    kmax: usize,
) -> [Vec<f64>; 3] {
    let tau0 = 1.0 / rate_hz;
    let w = |k: usize| PI * k as f64 / n as f64;
    let poles: Vec<(f64, f64)> =
        flicker_poles(1.0, tau0, flicker_tau_max(n as f64 * tau0, tau0)).collect();
    let ar1 = |sigma: f64, tau_c: f64, w: f64| {
        let phi = (-tau0 / tau_c).exp();
        sigma * sigma * (1.0 - phi * phi) / (1.0 - 2.0 * phi * w.cos() + phi * phi)
    };
    let fixed = (1..=kmax)
        .map(|k| terms.n * terms.n / tau0 + (terms.q / tau0).powi(2) * (2.0 - 2.0 * w(k).cos()))
        .collect();
    let flicker = (1..=kmax)
        .map(|k| {
            flicker_white_density(1.0, tau0).powi(2) / tau0
                + poles.iter().map(|&(s, t)| ar1(s, t, w(k))).sum::<f64>()
        })
        .collect();
    let walk = (1..=kmax)
        .map(|k| tau0 / (2.0 - 2.0 * w(k).cos()))
        .collect();
    [fixed, flicker, walk]
}

/// The model's variance of DCT-II coefficients 1..=kmax of `n` samples at `rate_hz`: white
/// noise (through `low_pass`), quantization, flicker, random walk and a Gauss-Markov term.
pub fn model_variances(
    terms: &NoiseTerms,
    low_pass: Option<&LowPass>,
    rate_hz: f64,
    n: usize,
    kmax: usize,
) -> Vec<f64> {
    let tau0 = 1.0 / rate_hz;
    let unit = NoiseTerms {
        n: 1.0,
        ..NoiseTerms::default()
    };
    let [white, flicker, walk] = coefficient_variances(&unit, rate_hz, n, kmax);
    (1..=kmax)
        .map(|k| {
            let w = PI * k as f64 / n as f64;
            let gain = low_pass.map_or(1.0, |lp| {
                lp.power_gain(k as f64 * rate_hz / (2.0 * n as f64))
            });
            let gm = terms.gauss_markov.map_or(0.0, |g| {
                let phi = (-tau0 / g.tau_c).exp();
                g.sigma * g.sigma * (1.0 - phi * phi) / (1.0 - 2.0 * phi * w.cos() + phi * phi)
            });
            terms.n * terms.n * white[k - 1] * gain
                + (terms.q / tau0).powi(2) * (2.0 - 2.0 * w.cos())
                + terms.b * terms.b * flicker[k - 1]
                + terms.k * terms.k * walk[k - 1]
                + gm
        })
        .collect()
}

/// A record's cosine coefficients and the model's variance per unit level of each term, the
/// single coefficients first and then the bands.
#[derive(Debug, Clone)]
pub struct CosineLikelihood {
    /// The single coefficients.
    single: Vec<f64>,
    /// Each band's sum of squares and coefficient count.
    band_power: Vec<f64>,
    band_count: Vec<f64>,
    /// Per single coefficient then per band: the fixed variance (white, quantization), and
    /// per unit B^2, K^2.
    pub(super) fixed: Vec<f64>,
    pub(super) flicker: Vec<f64>,
    pub(super) walk: Vec<f64>,
    /// Correlation times, s, each with its unit-variance Gauss-Markov column.
    pub(super) grid: Vec<(f64, Vec<f64>)>,
    /// The regressors' single coefficients, one vector per regressor.
    regressors: Vec<Vec<f64>>,
    /// `cos(pi k / n)` of coefficients 1..=kmax, the bands' index ranges and the sample
    /// interval, s: what a Gauss-Markov column of any correlation time needs.
    cosines: Vec<f64>,
    ranges: Vec<(usize, usize)>,
    pub(super) tau0: f64,
    /// The record's length, s.
    pub(super) duration: f64,
}

/// Index ranges `[lo, hi)` of coefficients 1..=kmax (index k - 1): single ones, then bands.
fn bands(kmax: usize) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = (0..SINGLE_COEFFICIENTS.min(kmax))
        .map(|i| (i, i + 1))
        .collect();
    let ratio = 2f64.powf(1.0 / BANDS_PER_OCTAVE);
    let mut lo = SINGLE_COEFFICIENTS.min(kmax);
    while lo < kmax {
        let hi = (((lo as f64) * ratio).ceil() as usize)
            .max(lo + 1)
            .min(kmax);
        out.push((lo, hi));
        lo = hi;
    }
    out
}

/// The unit-variance first-order process of correlation time `tau_c` (s) per single
/// coefficient then per band, from the coefficients' `cosines` (`cos(pi k / n)`).
fn gauss_markov_column(
    cosines: &[f64],
    ranges: &[(usize, usize)],
    tau0: f64,
    tau_c: f64,
) -> Vec<f64> {
    let phi = (-tau0 / tau_c).exp();
    let v: Vec<f64> = cosines
        .iter()
        .map(|c| (1.0 - phi * phi) / (1.0 - 2.0 * phi * c + phi * phi))
        .collect();
    band_means(&v, ranges)
}

fn band_means(v: &[f64], ranges: &[(usize, usize)]) -> Vec<f64> {
    ranges
        .iter()
        .map(|&(lo, hi)| v[lo..hi].iter().sum::<f64>() / (hi - lo) as f64)
        .collect()
}

/// What the view concludes of a record.
#[derive(Debug, Clone)]
pub struct Verdict {
    /// The likelihood ratio of the Gauss-Markov term.
    pub statistic: f64,
    /// The statistic on the bootstrap's draws.
    pub null: Vec<f64>,
    /// The flicker and random-walk levels (B^2, K^2) the record shows without the term,
    /// from which the bootstrap draws.
    pub levels: Vec<f64>,
    /// The term's correlation time (s) and standard deviation (u) where the record is likeliest.
    pub tau_c: f64,
    pub sigma: f64,
}

impl CosineLikelihood {
    /// The view of `x` (a rate record at `rate_hz`, the named lines notched) under `terms`'
    /// white noise and quantization, the white noise through `low_pass` when there is one,
    /// with `regressors` (time-domain columns) as fixed effects.
    pub fn new(
        x: &[f64],
        rate_hz: f64,
        terms: &NoiseTerms,
        low_pass: Option<&LowPass>,
        regressors: &[Vec<f64>],
    ) -> Option<CosineLikelihood> {
        let n = x.len();
        let tau0 = 1.0 / rate_hz;
        let duration = n as f64 * tau0;
        let kmax = ((2.0 * duration * HIGHEST_HZ) as usize).min(n.saturating_sub(1) / 2);
        if kmax < 16 {
            return None;
        }
        let ranges = bands(kmax);
        let singles = SINGLE_COEFFICIENTS.min(kmax);
        let c = dct2(x, kmax);
        let [_, flicker, walk] = coefficient_variances(
            &NoiseTerms {
                n: 1.0,
                ..NoiseTerms::default()
            },
            rate_hz,
            n,
            kmax,
        );
        // White noise (through the filter) and quantization are the model's own.
        let fixed = model_variances(
            &NoiseTerms {
                n: terms.n,
                q: terms.q,
                ..NoiseTerms::default()
            },
            low_pass,
            rate_hz,
            n,
            kmax,
        );
        if !fixed.iter().all(|v| *v > 0.0) {
            return None;
        }
        let cosines: Vec<f64> = (1..=kmax)
            .map(|k| (PI * k as f64 / n as f64).cos())
            .collect();
        let (lo, hi) = GRID_FRACTIONS;
        let grid = (0..GRID_POINTS)
            .map(|i| {
                let tau_c = duration * lo * (hi / lo).powf(i as f64 / (GRID_POINTS - 1) as f64);
                (tau_c, gauss_markov_column(&cosines, &ranges, tau0, tau_c))
            })
            .collect();
        let band_power = ranges[singles..]
            .iter()
            .map(|&(lo, hi)| c[lo..hi].iter().map(|v| v * v).sum())
            .collect();
        let band_count = ranges[singles..]
            .iter()
            .map(|&(lo, hi)| (hi - lo) as f64)
            .collect();
        Some(CosineLikelihood {
            single: c[..singles].to_vec(),
            band_power,
            band_count,
            fixed: band_means(&fixed, &ranges),
            flicker: band_means(&flicker, &ranges),
            walk: band_means(&walk, &ranges),
            grid,
            regressors: regressors.iter().map(|r| dct2(r, singles)).collect(),
            cosines,
            ranges,
            tau0,
            duration,
        })
    }

    /// Twice the negative log-likelihood with `levels` of the unit `columns`, the regressors
    /// profiled out.
    pub(super) fn nll(&self, columns: &[&[f64]], levels: &[f64]) -> f64 {
        let variance = |j: usize| {
            self.fixed[j]
                + columns
                    .iter()
                    .zip(levels)
                    .map(|(col, l)| col[j] * l)
                    .sum::<f64>()
        };
        let singles = self.single.len();
        let v: Vec<f64> = (0..singles).map(variance).collect();
        let mut total: f64 = self
            .single
            .iter()
            .zip(&v)
            .map(|(c, v)| v.ln() + c * c / v)
            .sum();
        total += self
            .band_power
            .iter()
            .zip(&self.band_count)
            .enumerate()
            .map(|(j, (p, m))| {
                let v = variance(singles + j);
                m * v.ln() + p / v
            })
            .sum::<f64>();
        total - self.explained(&v)
    }

    /// What the regressors explain of the single coefficients' weighted sum of squares at
    /// variances `v`: `b^T A^-1 b`, `A = X^T V^-1 X`, `b = X^T V^-1 c`.
    fn explained(&self, v: &[f64]) -> f64 {
        if self.regressors.is_empty() {
            return 0.0;
        }
        // Each regressor weighted by 1 / v once (a division per coefficient, not one per
        // product), then its products with the others and with the coefficients.
        let weights: Vec<f64> = v.iter().map(|v| 1.0 / v).collect();
        let weighted: Vec<Vec<f64>> = self
            .regressors
            .iter()
            .map(|r| r.iter().zip(&weights).map(|(x, w)| x * w).collect())
            .collect();
        let a: Vec<Vec<f64>> = weighted
            .iter()
            .map(|r| self.regressors.iter().map(|s| dot(r, s)).collect())
            .collect();
        let b: Vec<f64> = weighted.iter().map(|r| dot(r, &self.single)).collect();
        match invert_spd(&a) {
            Some(inv) => inv
                .iter()
                .zip(&b)
                .map(|(row, bi)| bi * row.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>())
                .sum::<f64>()
                .max(0.0),
            None => 0.0,
        }
    }

    /// The least [`CosineLikelihood::nll`] over the columns' levels, searched in logs from
    /// `start`, from a thousandth of it, and from every term at the white variance of the
    /// first coefficient (a level of 0 in `start`, a term the model lacks, is searched from
    /// there: at a negligible level the likelihood is flat and a simplex would stay), with
    /// the levels that reach it; and from the log-levels `more`.
    pub(super) fn likeliest(
        &self,
        columns: &[&[f64]],
        start: &[f64],
        more: &[Vec<f64>],
    ) -> (f64, Vec<f64>) {
        // A unit log-level is the white variance at the first coefficient.
        let scale: Vec<f64> = columns.iter().map(|col| self.fixed[0] / col[0]).collect();
        let levels =
            |u: &[f64]| -> Vec<f64> { u.iter().zip(&scale).map(|(v, s)| s * v.exp()).collect() };
        let f = |u: &[f64]| {
            if u.iter()
                .any(|v| !(LOG_LEVEL_RANGE.0..=LOG_LEVEL_RANGE.1).contains(v))
            {
                return f64::INFINITY;
            }
            self.nll(columns, &levels(u))
        };
        let from = |shift: f64| -> Vec<f64> {
            start
                .iter()
                .zip(&scale)
                .map(|(l, s)| {
                    if *l > 0.0 {
                        ((l / s).ln() + shift).clamp(-25.0, 25.0)
                    } else {
                        shift
                    }
                })
                .collect()
        };
        let starts: Vec<Vec<f64>> = [from(0.0), from(-7.0), vec![0.0; columns.len()]]
            .into_iter()
            .chain(more.iter().cloned())
            .collect();
        // The searches run side by side; the least is taken in the starts' order, so a tie
        // goes to the earlier start as in a sequential search.
        let found: Vec<(f64, Vec<f64>)> = starts
            .par_iter()
            .map(|u0| {
                let coarse = nelder_mead_n(&f, u0, 2.0);
                let u = nelder_mead_n(&f, &coarse, 0.5);
                (f(&u), levels(&u))
            })
            .collect();
        found
            .into_iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((f64::INFINITY, Vec::new()))
    }

    /// Without the term: the least nll and the flicker and random-walk levels (B^2, K^2).
    /// Its search also starts from a grid of flicker and random-walk levels, a thousandth
    /// to a thousand times the white variance of the first coefficient: a ratio is only as
    /// good as the minimum without the term, and a search stuck at a flat stretch there (a
    /// level far too low) would make noise look like the term.
    pub(super) fn without(&self, start: [f64; 2]) -> (f64, Vec<f64>) {
        let grid: Vec<Vec<f64>> = [-7.0, 0.0, 7.0]
            .iter()
            .flat_map(|&b| [-7.0, 0.0, 7.0].map(|k| vec![b, k]))
            .collect();
        self.likeliest(&[&self.flicker, &self.walk], &start, &grid)
    }

    /// The unit-variance Gauss-Markov column of correlation time `tau_c`, s.
    pub(super) fn gauss_markov_column(&self, tau_c: f64) -> Vec<f64> {
        gauss_markov_column(&self.cosines, &self.ranges, self.tau0, tau_c)
    }

    /// With the term: the least nll over the grid, its correlation time and variance.
    fn with(&self, from: &[f64]) -> (f64, f64, f64) {
        let fits: Vec<(f64, f64, f64)> = self
            .grid
            .par_iter()
            .map(|(tau_c, gm)| {
                let start = [from[0], from[1], self.fixed[0] / gm[0]];
                let (nll, levels) = self.likeliest(&[&self.flicker, &self.walk, gm], &start, &[]);
                (nll, *tau_c, levels.get(2).copied().unwrap_or(0.0))
            })
            .collect();
        fits.into_iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((f64::INFINITY, 0.0, 0.0))
    }

    /// The likelihood ratio, and the term's correlation time and variance at the best fit.
    pub fn ratio(&self, start: [f64; 2]) -> (f64, f64, f64) {
        let (without, levels) = self.without(start);
        let (with, tau_c, variance) = self.with(&levels);
        ((without - with).max(0.0), tau_c, variance)
    }

    /// The likelihood ratio of the term with the flicker and random-walk levels `known` (B^2,
    /// K^2): the most any test could see.
    #[cfg(test)]
    pub fn ratio_known(&self, known: [f64; 2]) -> f64 {
        let base: [&[f64]; 2] = [&self.flicker, &self.walk];
        let without = self.nll(&base, &known);
        let fixed: Vec<f64> = (0..self.fixed.len())
            .map(|j| self.fixed[j] + known[0] * self.flicker[j] + known[1] * self.walk[j])
            .collect();
        let known_levels = CosineLikelihood {
            fixed,
            ..self.clone()
        };
        let with = self
            .grid
            .iter()
            .map(|(_, gm)| {
                known_levels
                    .likeliest(&[gm], &[1e-3 * known_levels.fixed[0] / gm[0]], &[])
                    .0
            })
            .fold(f64::INFINITY, f64::min);
        (without - with).max(0.0)
    }

    /// The same view of coefficients drawn from the model with flicker and random-walk
    /// `levels` and no regressors' signal (they are profiled out on both sides).
    fn drawn(&self, levels: &[f64], seed: u64) -> CosineLikelihood {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let variance =
            |j: usize| self.fixed[j] + levels[0] * self.flicker[j] + levels[1] * self.walk[j];
        let singles = self.single.len();
        let single = (0..singles)
            .map(|j| variance(j).sqrt() * rng.sample::<f64, _>(StandardNormal))
            .collect();
        let band_power = self
            .band_count
            .iter()
            .enumerate()
            .map(|(j, m)| {
                let chi = ChiSquared::new(*m).map_or(*m, |d| rng.sample(d));
                variance(singles + j) * chi
            })
            .collect();
        CosineLikelihood {
            single,
            band_power,
            ..self.clone()
        }
    }

    /// The test of a Gauss-Markov term (see the module documentation), `draws` bootstrap
    /// draws from seed `seed`, the searches started from `start` (B^2, K^2).
    pub fn test(&self, start: [f64; 2], draws: usize, seed: u64) -> Verdict {
        let (without, levels) = self.without(start);
        let (with, tau_c, variance) = self.with(&levels);
        Verdict {
            statistic: (without - with).max(0.0),
            null: self.null(&levels, 0..draws, seed),
            levels,
            tau_c,
            sigma: variance.max(0.0).sqrt(),
        }
    }

    /// `verdict` with its bootstrap carried on to `draws` draws: those it has are kept (draw
    /// i is the same whenever it is made), only the rest are drawn.
    pub fn extend(&self, verdict: Verdict, draws: usize, seed: u64) -> Verdict {
        let mut null = verdict.null;
        let more = self.null(&verdict.levels, null.len()..draws.max(null.len()), seed);
        null.extend(more);
        Verdict { null, ..verdict }
    }

    /// The statistic on bootstrap draws `draws` from `levels` (B^2, K^2), draw i from seed
    /// `seed + i`.
    fn null(&self, levels: &[f64], draws: std::ops::Range<usize>, seed: u64) -> Vec<f64> {
        draws
            .into_par_iter()
            .map(|i| {
                self.drawn(levels, seed.wrapping_add(i as u64))
                    .ratio([levels[0], levels[1]])
                    .0
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::noise::AxisNoise;

    /// A bootstrap carried on from fewer draws is the bootstrap made at once: the draws it
    /// had are kept and the rest come from the same seeds.
    #[test]
    fn an_extended_bootstrap_is_the_one_made_at_once() {
        let terms = NoiseTerms {
            n: 1e-3,
            k: 1e-5,
            ..NoiseTerms::default()
        };
        let (rate_hz, seconds) = (10.0, 1200.0);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let x = AxisNoise::new(terms, rate_hz, seconds, &mut rng).take(12_000, &mut rng);
        let view = CosineLikelihood::new(&x, rate_hz, &terms, None, &[]).expect("a view");
        let start = [0.0, terms.k * terms.k];
        let at_once = view.test(start, 6, 11);
        let extended = view.extend(view.test(start, 2, 11), 6, 11);
        assert_eq!(extended.null.len(), 6);
        assert_eq!(extended.null, at_once.null);
        assert_eq!(extended.statistic, at_once.statistic);
        assert_eq!(extended.levels, at_once.levels);
        // Fewer draws than it has: nothing is drawn or lost.
        assert_eq!(view.extend(at_once.clone(), 3, 11).null, at_once.null);
    }
}

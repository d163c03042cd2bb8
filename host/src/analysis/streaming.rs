//! Streaming Allan accumulators: the overlapping Allan (oadev) or overlapping Hadamard (ohdev)
//! variance of a rate series at a fixed ladder of averaging factors, fed sample by sample or
//! batch by batch, in memory that does not grow with the record.
//!
//! **What is exact.** Both estimators are sums of squared finite differences of the phase
//! `x` (NIST SP 1065 eqs. 11 and 18; [`super::allan`]): `D2(i) = x[i+2m] - 2 x[i+m] + x[i]`
//! and `D3(i) = x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i]`. A difference ending at the newest
//! phase point needs the `span m` points before it, so a ring buffer of the last
//! `span m_max + 1` points serves every factor up to `m_max`, and each new point adds one
//! term per factor. Factors up to [`Config::exact_up_to`] are served this way and are
//! **exact**: the same sums as the batch engine, up to rounding (the tests compare them).
//!
//! **What is approximated, and how.** A ring for a factor of hours at a kilohertz would hold
//! tens of millions of points. Larger factors m are served by a decimated phase, every d-th
//! point, d the smallest divisor of m with `m / d <= Config::strided_lag`: the sum runs over
//! starts `i = 0, d, 2d, ...` instead of every i. This is the overlapping estimator of the
//! phase sampled every `d tau0` at factor `m / d`, so it is unbiased for the same variance,
//! and its equivalent degrees of freedom are Greenhall's for that decimated series
//! ([`Curve::edf`]); with `m / d` in the hundreds they are within a few per cent of the fully
//! overlapping estimator's, since starts closer than m apart give nearly the same term.
//! Ladders of powers of two or of 1-2-5 steps keep `m / d` at the target; a prime factor
//! above the exact range falls back to d = m, the non-overlapping estimator, so a log-spaced
//! ladder is first put through [`snap_factors`], which moves each factor above the exact
//! range to the nearest multiple of a power of two (by at most `1 / strided_lag`, 0.1 % with
//! the defaults).
//!
//! **Memory.** One ring per distinct stride, each at most `span lag + 1` points rounded up
//! to a power of two (`lag` the largest `m / d` it serves): with the defaults, 512 KiB for the
//! exact range of an Allan ladder and 32 KiB per stride above it, whatever the record's
//! length.
//!
//! **Precision.** The phase is the running sum of `(y - y_first) tau0`, compensated
//! (Neumaier), so a bias does not grow the phase out of the digits the differences need.
//!
//! Estimators that weigh the whole record at once (totdev's reflection, mdev's moving
//! average over m differences) are not offered: mdev would need the ring plus a running sum
//! of `m` differences per factor, and is left to the batch engine.

use super::ci::{self, chi2_bounds};
use super::fit::NoiseFit;
use super::{Deviation, Estimator};

/// How factors are served (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// Factors up to this are exact (stride 1).
    pub exact_up_to: usize,
    /// Above the exact range, the largest `m / d` a stride d may leave.
    pub strided_lag: usize,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            exact_up_to: 1 << 14,
            strided_lag: 1 << 10,
        }
    }
}

/// Why an accumulator cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StreamingError {
    #[error("streaming accumulators serve oadev and ohdev only, not {0}")]
    Estimator(Estimator),
    #[error("the sample interval must be positive and finite (got {0} s)")]
    Interval(f64),
    #[error("the averaging factors must be at least 1")]
    ZeroFactor,
    #[error("streaming config: exact_up_to and strided_lag must be at least 1")]
    Config,
}

/// The sum of squared differences at one factor.
#[derive(Debug, Clone)]
struct Term {
    /// Averaging factor m, in samples.
    m: usize,
    /// m in decimated points (m / stride).
    lag: usize,
    sum: f64,
    count: u64,
}

/// Decimated phase points at one stride, and the factors they serve.
#[derive(Debug, Clone)]
struct Level {
    stride: usize,
    /// Phase points to skip before the next kept one.
    countdown: usize,
    ring: Vec<f64>,
    mask: usize,
    /// Points kept so far (the next one's index in the decimated series).
    kept: usize,
    terms: Vec<Term>,
}

impl Level {
    fn keep(&mut self, x: f64, span: usize) {
        let k = self.kept;
        self.ring[k & self.mask] = x;
        self.kept += 1;
        let at = |j: usize| self.ring[j & self.mask];
        for t in &mut self.terms {
            let l = t.lag;
            if k < span * l {
                // Terms are sorted by lag: the longer ones have no difference yet either.
                break;
            }
            let d = if span == 2 {
                x - 2.0 * at(k - l) + at(k - 2 * l)
            } else {
                x - 3.0 * (at(k - l) - at(k - 2 * l)) - at(k - 3 * l)
            };
            t.sum += d * d;
            t.count += 1;
        }
    }
}

/// The running accumulators of one channel.
#[derive(Debug, Clone)]
pub struct Streaming {
    estimator: Estimator,
    span: usize,
    tau0: f64,
    /// The first rate sample, subtracted before integrating.
    reference: Option<f64>,
    phase: f64,
    carry: f64,
    samples: u64,
    levels: Vec<Level>,
}

/// The smallest divisor d of m with `m / d <= lag` (d = m when m is prime and above `lag`).
fn stride_for(m: usize, lag: usize) -> usize {
    (m.div_ceil(lag).max(1)..=m)
        .find(|d| m.is_multiple_of(*d))
        .unwrap_or(m)
}

/// `factors` with each one above `config.exact_up_to` moved to the nearest multiple of the
/// power of two d that leaves `m / d` at most `config.strided_lag` (half of it at least), so
/// every factor is served at that lag rather than by whatever divisor it happens to have;
/// ascending, without duplicates.
pub fn snap_factors(factors: &[usize], config: Config) -> Vec<usize> {
    let mut out: Vec<usize> = factors
        .iter()
        .map(|&m| {
            if m <= config.exact_up_to {
                return m;
            }
            let d = m.div_ceil(config.strided_lag.max(1)).next_power_of_two();
            ((m + d / 2) / d).max(1) * d
        })
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

impl Streaming {
    /// Accumulators of `estimator` (oadev or ohdev) for rate samples every `tau0` seconds at
    /// the averaging `factors` (any order; duplicates ignored).
    pub fn new(
        estimator: Estimator,
        tau0: f64,
        factors: &[usize],
        config: Config,
    ) -> Result<Streaming, StreamingError> {
        let span = match estimator {
            Estimator::Oadev => 2,
            Estimator::Ohdev => 3,
            other => return Err(StreamingError::Estimator(other)),
        };
        if !(tau0 > 0.0 && tau0.is_finite()) {
            return Err(StreamingError::Interval(tau0));
        }
        if factors.contains(&0) {
            return Err(StreamingError::ZeroFactor);
        }
        if config.exact_up_to == 0 || config.strided_lag == 0 {
            return Err(StreamingError::Config);
        }
        let mut ms = factors.to_vec();
        ms.sort_unstable();
        ms.dedup();
        let mut levels: Vec<Level> = Vec::new();
        for m in ms {
            let stride = if m <= config.exact_up_to {
                1
            } else {
                stride_for(m, config.strided_lag)
            };
            let term = Term {
                m,
                lag: m / stride,
                sum: 0.0,
                count: 0,
            };
            match levels.iter_mut().find(|l| l.stride == stride) {
                Some(level) => level.terms.push(term),
                None => levels.push(Level {
                    stride,
                    countdown: 0,
                    ring: Vec::new(),
                    mask: 0,
                    kept: 0,
                    terms: vec![term],
                }),
            }
        }
        for level in &mut levels {
            level.terms.sort_by_key(|t| t.lag);
            let longest = level.terms.last().map_or(0, |t| t.lag);
            let capacity = (span * longest + 1).next_power_of_two();
            level.ring = vec![0.0; capacity];
            level.mask = capacity - 1;
        }
        Ok(Streaming {
            estimator,
            span,
            tau0,
            reference: None,
            phase: 0.0,
            carry: 0.0,
            samples: 0,
            levels,
        })
    }

    /// The estimator accumulated.
    pub fn estimator(&self) -> Estimator {
        self.estimator
    }

    /// The averaging factors served, ascending.
    pub fn factors(&self) -> Vec<usize> {
        let mut m: Vec<usize> = self
            .levels
            .iter()
            .flat_map(|l| l.terms.iter().map(|t| t.m))
            .collect();
        m.sort_unstable();
        m
    }

    /// Rate samples taken so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Memory held by the rings, bytes.
    pub fn ring_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.ring.len() * size_of::<f64>())
            .sum()
    }

    fn keep_phase(&mut self, x: f64) {
        let span = self.span;
        for level in &mut self.levels {
            if level.countdown == 0 {
                level.keep(x, span);
                level.countdown = level.stride;
            }
            level.countdown -= 1;
        }
    }

    /// Take one rate sample.
    pub fn push(&mut self, y: f64) {
        let reference = *self.reference.get_or_insert(y);
        if self.samples == 0 {
            // The phase point before the first sample.
            self.keep_phase(0.0);
        }
        let term = (y - reference) * self.tau0;
        let t = self.phase + term;
        self.carry += if self.phase.abs() >= term.abs() {
            (self.phase - t) + term
        } else {
            (term - t) + self.phase
        };
        self.phase = t;
        self.samples += 1;
        self.keep_phase(self.phase + self.carry);
    }

    /// Take a batch of rate samples.
    pub fn extend(&mut self, ys: &[f64]) {
        ys.iter().for_each(|&y| self.push(y));
    }

    /// The deviation so far at every factor that has at least one term.
    pub fn curve(&self) -> Curve {
        let mut rows: Vec<(usize, usize, f64, u64)> = self
            .levels
            .iter()
            .flat_map(|l| l.terms.iter().map(move |t| (t.m, l.stride, t.sum, t.count)))
            .filter(|r| r.3 > 0)
            .collect();
        rows.sort_unstable_by_key(|r| r.0);
        let divisor = if self.span == 2 { 2.0 } else { 6.0 };
        let dev = rows
            .iter()
            .map(|&(m, _, sum, count)| {
                let tau = m as f64 * self.tau0;
                (sum / (divisor * count as f64 * tau * tau)).sqrt()
            })
            .collect();
        Curve {
            deviation: Deviation {
                estimator: self.estimator,
                m: rows.iter().map(|r| r.0).collect(),
                tau: rows.iter().map(|r| r.0 as f64 * self.tau0).collect(),
                dev,
                n: rows.iter().map(|r| r.3 as usize).collect(),
            },
            stride: rows.iter().map(|r| r.1).collect(),
            phase_points: self.samples as usize + usize::from(self.samples > 0),
        }
    }
}

/// A streamed deviation curve and how each point was computed.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// The deviation at each factor with terms; `n` counts the terms summed.
    pub deviation: Deviation,
    /// The stride of the starts summed per factor: 1 exact, d > 1 decimated.
    pub stride: Vec<usize>,
    /// Phase points seen (rate samples + 1).
    pub phase_points: usize,
}

impl Curve {
    /// Equivalent degrees of freedom at point `k` for noise exponent `alpha`: Greenhall's
    /// EDF ([`ci::edf`]) of the overlapping estimator on the phase decimated by the point's
    /// stride d (factor `m / d` on `ceil(points / d)` points); d = 1 is the full series.
    pub fn edf(&self, k: usize, alpha: i32) -> f64 {
        let d = self.stride[k];
        let m = self.deviation.m[k] / d;
        ci::edf(
            self.deviation.estimator,
            alpha,
            m,
            self.phase_points.div_ceil(d),
        )
    }

    /// `confidence` intervals at every point. The noise type at each tau is taken from the
    /// fitted `model` (the power law of the term that dominates its AVAR there,
    /// [`NoiseFit::dominant_alpha`]): a stream has no record to identify noise on, and the
    /// fit rests on the whole curve. Without a model, from the curve's local slope
    /// (`alpha = -mu - 1` for the Allan variance's slope mu, between -2 and 1: SP 1065
    /// table 5).
    pub fn intervals(&self, model: Option<&NoiseFit>, confidence: f64) -> ci::Intervals {
        let (tau, dev) = (&self.deviation.tau, &self.deviation.dev);
        let alpha: Vec<i32> = (0..tau.len())
            .map(|k| match model {
                Some(m) => m.dominant_alpha(tau[k]),
                None => {
                    let (a, b) = (k.saturating_sub(1), (k + 1).min(tau.len() - 1));
                    if a == b {
                        return 0;
                    }
                    let mu = 2.0 * (dev[b] / dev[a]).ln() / (tau[b] / tau[a]).ln();
                    ((-mu - 1.0).round() as i32).clamp(-2, 1)
                }
            })
            .collect();
        let edf: Vec<f64> = alpha
            .iter()
            .enumerate()
            .map(|(k, &a)| self.edf(k, a))
            .collect();
        let (lo, hi) = dev
            .iter()
            .zip(&edf)
            .map(|(&d, &e)| chi2_bounds(d, e, confidence))
            .unzip();
        ci::Intervals { alpha, edf, lo, hi }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::analysis::taus::{self, TauGrid};
    use crate::analysis::{allan, phase_from_rate};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// White noise plus a random walk and a bias, so every tau has something to measure and
    /// the phase drifts far from zero.
    pub(crate) fn series(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut walk = 0.0;
        (0..n)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                let s: f64 = StandardNormal.sample(&mut rng);
                walk += 1e-3 * s;
                0.37 + 1e-2 * w + walk
            })
            .collect()
    }

    /// Σ D(i)² over starts 0, d, 2d, ... on a phase series: the definition, written out.
    fn strided_var(x: &[f64], m: usize, d: usize, span: usize, tau0: f64) -> (f64, usize) {
        let (mut sum, mut count) = (0.0, 0);
        let mut i = 0;
        while i + span * m < x.len() {
            let v = if span == 2 {
                x[i + 2 * m] - 2.0 * x[i + m] + x[i]
            } else {
                x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i]
            };
            sum += v * v;
            count += 1;
            i += d;
        }
        let tau = m as f64 * tau0;
        let divisor = if span == 2 { 2.0 } else { 6.0 };
        ((sum / (divisor * count as f64 * tau * tau)).sqrt(), count)
    }

    #[test]
    fn exact_factors_equal_the_batch_engine() {
        let tau0 = 0.01;
        let y = series(20_011, 1);
        let factors = [1, 2, 3, 4, 8, 16, 50, 100, 256, 1000, 3333, 6000, 9000];
        for est in [Estimator::Oadev, Estimator::Ohdev] {
            let mut s = Streaming::new(est, tau0, &factors, Config::default()).unwrap();
            s.extend(&y);
            let streamed = s.curve();
            let batch = allan::deviation(est, &phase_from_rate(&y, tau0), tau0, &factors);
            assert_eq!(streamed.deviation.m, batch.m, "{est}");
            assert_eq!(streamed.deviation.n, batch.n, "{est}");
            assert!(streamed.stride.iter().all(|&d| d == 1));
            for (a, b) in streamed.deviation.dev.iter().zip(&batch.dev) {
                assert!((a / b - 1.0).abs() < 1e-9, "{est}: {a} vs {b}");
            }
            assert_eq!(streamed.phase_points, y.len() + 1);
        }
    }

    #[test]
    fn strided_factors_sum_every_dth_start() {
        let tau0 = 0.02;
        let y = series(30_000, 2);
        let x = phase_from_rate(&y, tau0);
        let config = Config {
            exact_up_to: 100,
            strided_lag: 40,
        };
        // 1000 = 25 x 40; 2048 = 64 x 32; 997 is prime (non-overlapping); 4500 = 125 x 36.
        let factors = [64, 997, 1000, 2048, 4500];
        for (est, span) in [(Estimator::Oadev, 2), (Estimator::Ohdev, 3)] {
            let mut s = Streaming::new(est, tau0, &factors, config).unwrap();
            // Fed in uneven batches: the batching must not matter.
            for chunk in y.chunks(777) {
                s.extend(chunk);
            }
            let c = s.curve();
            let expected_stride = [1, 997, 25, 64, 125];
            for (k, &m) in c.deviation.m.iter().enumerate() {
                let j = factors.iter().position(|&f| f == m).unwrap();
                assert_eq!(c.stride[k], expected_stride[j], "{est} m = {m}");
                let (dev, count) = strided_var(&x, m, c.stride[k], span, tau0);
                assert_eq!(c.deviation.n[k], count, "{est} m = {m}");
                assert!(
                    (c.deviation.dev[k] / dev - 1.0).abs() < 1e-9,
                    "{est} m = {m}: {} vs {dev}",
                    c.deviation.dev[k]
                );
            }
        }
    }

    #[test]
    fn sample_by_sample_equals_one_batch() {
        let y = series(5000, 3);
        let factors = [1, 7, 64, 300, 1200];
        let config = Config {
            exact_up_to: 64,
            strided_lag: 16,
        };
        let mut one = Streaming::new(Estimator::Oadev, 0.1, &factors, config).unwrap();
        let mut each = one.clone();
        one.extend(&y);
        y.iter().for_each(|&v| each.push(v));
        assert_eq!(one.curve(), each.curve());
        assert_eq!(one.samples(), 5000);
    }

    #[test]
    fn memory_does_not_grow_with_the_record() {
        let factors: Vec<usize> = (0..24).map(|k| 1usize << k).collect();
        let mut s = Streaming::new(Estimator::Oadev, 1e-3, &factors, Config::default()).unwrap();
        let before = s.ring_bytes();
        s.extend(&series(100_000, 4));
        assert_eq!(s.ring_bytes(), before);
        // The exact range's ring (2 x 2^14 + 1 points, rounded up) plus one (2 x 2^10 + 1)-point
        // ring, rounded up, per stride above it (2^15 .. 2^23: nine strides).
        assert_eq!(before, (1 << 16) * 8 + 9 * (1 << 12) * 8);
    }

    /// The decimated estimator agrees with the fully overlapping one, and its EDF is theirs:
    /// it leaves out only the starts between i and i + d, whose terms share all but a
    /// fraction of about d / m of their samples with a neighbour's, so its extra relative
    /// spread is of order `(d / m) sqrt(2 / edf)` (measured: 4e-5 and 9e-5 here); checked
    /// at 4 times that.
    #[test]
    fn strided_and_exact_agree_within_their_spread() {
        let y = series(200_000, 5);
        let factors = [4096, 8192];
        let exact = {
            let mut s = Streaming::new(Estimator::Oadev, 1.0, &factors, Config::default()).unwrap();
            s.extend(&y);
            s.curve()
        };
        let config = Config {
            exact_up_to: 1,
            strided_lag: 256,
        };
        let mut s = Streaming::new(Estimator::Oadev, 1.0, &factors, config).unwrap();
        s.extend(&y);
        let strided = s.curve();
        for (k, m) in factors.into_iter().enumerate() {
            assert_eq!(strided.stride[k], m / 256);
            // Random walk dominates at these taus in `series`.
            let edf = strided.edf(k, -2);
            assert!(edf > 0.0 && edf <= exact.edf(k, -2) * 1.001);
            let rel = (strided.deviation.dev[k] / exact.deviation.dev[k]).powi(2) - 1.0;
            let tolerance = 4.0 / 256.0 * (2.0 / edf).sqrt();
            assert!(rel.abs() < tolerance, "{k}: {rel}, edf {edf}");
        }
    }

    #[test]
    fn snapped_ladders_keep_their_lag() {
        let config = Config::default();
        let ladder = taus::factors(TauGrid::PerDecade(10), 100_000_000);
        let snapped = snap_factors(&ladder, config);
        assert_eq!(snapped.len(), ladder.len());
        for (&m, &s) in ladder.iter().zip(&snapped) {
            if m <= config.exact_up_to {
                assert_eq!(m, s);
                continue;
            }
            assert!((s as f64 / m as f64 - 1.0).abs() <= 1.0 / config.strided_lag as f64);
            let d = stride_for(s, config.strided_lag);
            assert!(s / d > config.strided_lag / 2, "{s}: stride {d}");
        }
    }

    #[test]
    fn bad_arguments_are_errors() {
        let c = Config::default();
        assert_eq!(
            Streaming::new(Estimator::Mdev, 1.0, &[1], c).unwrap_err(),
            StreamingError::Estimator(Estimator::Mdev)
        );
        assert!(Streaming::new(Estimator::Oadev, 0.0, &[1], c).is_err());
        assert!(Streaming::new(Estimator::Oadev, 1.0, &[0, 1], c).is_err());
        let empty = Streaming::new(Estimator::Oadev, 1.0, &[1, 2], c).unwrap();
        assert!(empty.curve().deviation.m.is_empty());
    }
}

//! The analysis engine: the Allan family of deviations with confidence intervals, the power
//! spectral density, and the IEEE-952 noise terms read from both.
//!
//! Conventions (docs/ARCHITECTURE.md, "Units and conventions"):
//! - Estimators work on **phase** data x (for an IMU: the integrated rate, i.e. angle or
//!   velocity) sampled every `tau0` seconds. Rate data y (rad/s, m/s^2) becomes phase with
//!   [`phase_from_rate`]: `x[0] = 0, x[k+1] = x[k] + (y[k] - mean(y)) * tau0` — the mean is
//!   subtracted first for precision; it does not change any deviation.
//! - Averaging factor m, tau = m * tau0.
//! - PSDs are one-sided; white rate noise with Allan coefficient N has one-sided PSD 2 N^2.

pub mod allan;
pub mod bounded;
pub mod brent;
pub mod ci;
pub mod compare;
pub mod filter;
pub mod fit;
pub mod gauss_markov;
pub mod lines;
pub mod live;
pub mod low_pass;
pub mod noise_id;
pub mod numerics;
pub mod pipeline;
pub mod power_fft;
pub mod precision;
pub mod psd;
pub mod shared_plans;
pub mod square_fft;
pub mod streaming;
pub mod taus;
pub mod units;

use serde::{Deserialize, Serialize};

/// Whether samples are rates (fractional frequency y; for an IMU rad/s or m/s^2) or phase
/// (time error x; for an IMU the integrated angle or velocity).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataType {
    Rate,
    Phase,
}

/// The estimators of the Allan family. Definitions: NIST SP 1065 (Riley 2008), section 5.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// Non-overlapping Allan deviation (SP 1065 eq. 7).
    Adev,
    /// Overlapping Allan deviation (SP 1065 eq. 11).
    Oadev,
    /// Modified Allan deviation (SP 1065 eq. 14).
    Mdev,
    /// Non-overlapping Hadamard deviation (SP 1065 eq. 17).
    Hdev,
    /// Overlapping Hadamard deviation (SP 1065 eq. 18).
    Ohdev,
    /// Time deviation, tau * mdev / sqrt(3) (SP 1065 eq. 15).
    Tdev,
    /// Total deviation (SP 1065 eq. 25), with reflected extension of the phase data.
    Totdev,
}

impl Estimator {
    pub const ALL: [Estimator; 7] = [
        Estimator::Adev,
        Estimator::Oadev,
        Estimator::Mdev,
        Estimator::Hdev,
        Estimator::Ohdev,
        Estimator::Tdev,
        Estimator::Totdev,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Estimator::Adev => "adev",
            Estimator::Oadev => "oadev",
            Estimator::Mdev => "mdev",
            Estimator::Hdev => "hdev",
            Estimator::Ohdev => "ohdev",
            Estimator::Tdev => "tdev",
            Estimator::Totdev => "totdev",
        }
    }
}

impl std::fmt::Display for Estimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is none of the [`Estimator`]s'.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown estimator '{0}': one of {names}", names = Estimator::ALL.map(Estimator::name).join(", "))]
pub struct UnknownEstimator(pub String);

impl std::str::FromStr for Estimator {
    type Err = UnknownEstimator;
    fn from_str(s: &str) -> Result<Self, UnknownEstimator> {
        Estimator::ALL
            .into_iter()
            .find(|e| e.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| UnknownEstimator(s.to_string()))
    }
}

/// One deviation curve: for each averaging factor m that the data allow, tau = m * tau0, the
/// deviation, and the number of terms summed (Stable32's `#` column).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Deviation {
    pub estimator: Estimator,
    pub m: Vec<usize>,
    pub tau: Vec<f64>,
    pub dev: Vec<f64>,
    pub n: Vec<usize>,
}

/// Phase from rate data: `x[0] = 0, x[k+1] = x[k] + (y[k] - mean(y)) * tau0`; N rates give
/// N + 1 phase points. The sums are compensated (see [`into_phase`]) so that 10^7-sample
/// records lose no digits.
pub fn phase_from_rate(y: &[f64], tau0: f64) -> Vec<f64> {
    use rayon::prelude::*;
    let mut x = vec![0.0; y.len() + 1];
    // The copy and the blocks' sums for the mean in one pass.
    let block_sums: Vec<f64> = x[1..]
        .par_chunks_mut(PHASE_BLOCK)
        .zip(y.par_chunks(PHASE_BLOCK))
        .map(|(to, from)| {
            to.copy_from_slice(from);
            neumaier_sum(from.iter().copied())
        })
        .collect();
    running_sum(&mut x[1..], &block_sums, tau0);
    x
}

/// Samples per block of [`into_phase`]'s running sum.
const PHASE_BLOCK: usize = 1024;

/// [`phase_from_rate`] in place: the rate buffer becomes the phase buffer, so converting a
/// long record costs no second copy of it.
///
/// The running sum is cut into blocks of 1024 samples (`PHASE_BLOCK`), summed on all
/// cores: each block's running sum starts from zero in plain arithmetic (its partial sums
/// stay small, so their rounding error is that of at most 1024 additions of the block's own
/// size), and the blocks' offsets are the compensated (Neumaier) running sum of the blocks'
/// compensated totals. A phase point is then one rounding from its exact value plus the
/// block's small error, as accurate as one compensated sum over the record, without its
/// serial chain.
pub fn into_phase(mut y: Vec<f64>, tau0: f64) -> Vec<f64> {
    use rayon::prelude::*;
    let n = y.len();
    // x[0] = 0, and y moves one place up to become x[1..]. Exactly one more place: a full
    // buffer would otherwise double.
    y.reserve_exact(1);
    y.push(0.0);
    y.copy_within(0..n, 1);
    y[0] = 0.0;
    let block_sums: Vec<f64> = y[1..]
        .par_chunks(PHASE_BLOCK)
        .map(|b| neumaier_sum(b.iter().copied()))
        .collect();
    running_sum(&mut y[1..], &block_sums, tau0);
    y
}

/// `values[k]` becomes Σ_{j ≤ k} (values\[j\] - mean) tau0, the mean taken from the sums of
/// the [`PHASE_BLOCK`]-sample blocks (`block_sums`), as [`into_phase`] describes.
fn running_sum(values: &mut [f64], block_sums: &[f64], tau0: f64) {
    use rayon::prelude::*;
    let mean = neumaier_sum(block_sums.iter().copied()) / values.len().max(1) as f64;
    // Each block's running sum from zero, and its compensated total.
    let totals: Vec<f64> = values
        .par_chunks_mut(PHASE_BLOCK)
        .map(|block| {
            let (mut run, mut total) = (0.0f64, Neumaier::default());
            for v in block.iter_mut() {
                let term = (*v - mean) * tau0;
                run += term;
                total.add(term);
                *v = run;
            }
            total.value()
        })
        .collect();
    let mut offset = Neumaier::default();
    let offsets: Vec<f64> = totals
        .iter()
        .map(|&t| {
            let before = offset.value();
            offset.add(t);
            before
        })
        .collect();
    values
        .par_chunks_mut(PHASE_BLOCK)
        .zip(offsets)
        .for_each(|(block, start)| block.iter_mut().for_each(|v| *v += start));
}

/// A running sum with Neumaier's compensation (Neumaier 1974, an improved Kahan sum).
#[derive(Debug, Clone, Copy, Default)]
struct Neumaier {
    sum: f64,
    carry: f64,
}

impl Neumaier {
    fn add(&mut self, v: f64) {
        let t = self.sum + v;
        self.carry += if self.sum.abs() >= v.abs() {
            (self.sum - t) + v
        } else {
            (v - t) + self.sum
        };
        self.sum = t;
    }

    fn value(&self) -> f64 {
        self.sum + self.carry
    }
}

/// Sum with Neumaier's compensation.
pub fn neumaier_sum(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut acc = Neumaier::default();
    values.into_iter().for_each(|v| acc.add(v));
    acc.value()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_is_the_centred_cumulative_sum() {
        let x = phase_from_rate(&[1.0, 3.0, 2.0], 0.5);
        assert_eq!(x, vec![0.0, -0.5, 0.0, 0.0]);
        assert_eq!(phase_from_rate(&[], 1.0), vec![0.0]);
        assert_eq!(into_phase(vec![1.0, 3.0, 2.0], 0.5), x);
    }

    #[test]
    fn blocked_phase_is_as_accurate_as_one_compensated_sum() {
        // A large offset on small fluctuations: the case the mean removal and the
        // compensation are for. The samples are multiples of 2^-10, so that every sum of
        // them, and so the mean, is exact whichever way it is summed; the reference then
        // differs only by the blocks' plain partial sums.
        let n = 5 * PHASE_BLOCK + 17;
        let mut s = 7u64;
        let y: Vec<f64> = (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                1e6 + ((s >> 54) as f64 - 512.0) / 1024.0
            })
            .collect();
        let x = phase_from_rate(&y, 0.01);
        let mean = neumaier_sum(y.iter().copied()) / n as f64;
        let mut acc = Neumaier::default();
        let mut want = vec![0.0];
        for v in &y {
            acc.add((v - mean) * 0.01);
            want.push(acc.value());
        }
        assert_eq!(x.len(), n + 1);
        // Terms are at most 0.005: partial sums within a block stay below 1024 * 0.005, and
        // 1024 roundings of that size bound the difference.
        let bound = 1024.0 * 1024.0 * 0.005 * f64::EPSILON;
        for (k, (a, b)) in x.iter().zip(&want).enumerate() {
            assert!((a - b).abs() <= bound, "x[{k}] {a} vs {b}");
        }
    }

    #[test]
    fn estimator_names_parse() {
        for e in Estimator::ALL {
            assert_eq!(e.name().parse::<Estimator>(), Ok(e));
        }
        assert_eq!(
            "avar".parse::<Estimator>().unwrap_err().to_string(),
            "unknown estimator 'avar': one of adev, oadev, mdev, hdev, ohdev, tdev, totdev"
        );
    }
}

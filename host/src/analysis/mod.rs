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
pub mod precision;
pub mod psd;
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
/// N + 1 phase points. Summation is compensated (Neumaier) so that 10^7-sample records
/// lose no digits.
pub fn phase_from_rate(y: &[f64], tau0: f64) -> Vec<f64> {
    let mut x = Vec::with_capacity(y.len() + 1);
    x.extend_from_slice(y);
    into_phase(x, tau0)
}

/// [`phase_from_rate`] in place: the rate buffer becomes the phase buffer, so converting a
/// long record costs no second copy of it.
pub fn into_phase(mut y: Vec<f64>, tau0: f64) -> Vec<f64> {
    let n = y.len();
    let mean = neumaier_sum(y.iter().copied()) / n.max(1) as f64;
    y.push(0.0);
    // x[k + 1] overwrites y[k + 1], so y[k] is carried in `pending` one step ahead.
    let mut pending = y[0];
    y[0] = 0.0;
    let (mut sum, mut carry) = (0.0f64, 0.0f64);
    for k in 0..n {
        let next = y[k + 1];
        let term = (pending - mean) * tau0;
        let t = sum + term;
        carry += if sum.abs() >= term.abs() {
            (sum - t) + term
        } else {
            (term - t) + sum
        };
        sum = t;
        y[k + 1] = sum + carry;
        pending = next;
    }
    y
}

/// Sum with Neumaier's compensation.
pub fn neumaier_sum(values: impl IntoIterator<Item = f64>) -> f64 {
    let (mut sum, mut carry) = (0.0f64, 0.0f64);
    for v in values {
        let t = sum + v;
        carry += if sum.abs() >= v.abs() {
            (sum - t) + v
        } else {
            (v - t) + sum
        };
        sum = t;
    }
    sum + carry
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

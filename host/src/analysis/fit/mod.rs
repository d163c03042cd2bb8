//! IEEE-952 noise terms from an Allan variance curve.
//!
//! The five-term model (IEEE Std 952-1997, Annex C, Table C.1):
//!
//! ```text
//! AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2
//! ```
//!
//! Q: quantization noise (u*s), N: angle/velocity random walk (u/sqrt(Hz)), B: bias
//! instability (u), K: rate random walk (u*sqrt(Hz)), R: rate ramp (u/s); u is rad/s or
//! m/s^2. The same terms in the **two-sided** rate PSD (Table C.1):
//!
//! ```text
//! S(f) = (2 pi f)^2 Q^2 tau0 (quantization, f < 1/(2 tau0)) + N^2 + B^2 / (2 pi f)
//!        + K^2 / (2 pi f)^2 + R^2 / (2 pi f)^3
//! ```
//!
//! The one-sided PSD our Welch estimate returns is twice that.
//!
//! Three routes:
//! - [`fit_allan`] (`allan.rs`): weighted non-negative least squares of the whole Allan
//!   curve, with intervals;
//! - [`slope_readouts`] (`slopes.rs`): the classic graphical read-outs (tangent lines of slope
//!   -1/2, +1/2, and the flat minimum);
//! - [`psd::fit_psd`]: N, B and K fitted to the multi-resolution PSD, with intervals.

mod allan;
pub mod psd;
mod slopes;

pub use allan::{fit_allan, fit_allan_with, fit_deviation};
pub use slopes::{BiasReadout, SLOPE_TOLERANCE, SlopeLine, SlopeReadouts, slope_readouts};
pub(crate) use slopes::{longest_run, ls_slope};

use crate::analysis::low_pass::LowPass;
use serde::Serialize;
use std::f64::consts::{LN_2, PI};

/// Number of terms in the IEEE-952 model.
pub(crate) const TERMS: usize = 5;
/// Order of the terms in every 5-array of this module.
pub(crate) const Q: usize = 0;
pub(crate) const N: usize = 1;
/// Index of bias instability in [`basis`] and every 5-array here.
pub const B: usize = 2;
/// Index of rate random walk in [`basis`] and every 5-array here.
pub const K: usize = 3;
pub(crate) const R: usize = 4;

/// `2 ln2 / pi`: AVAR of bias instability per B^2 (IEEE 952 Table C.1).
pub const FLICKER_AVAR_FACTOR: f64 = 2.0 * LN_2 / PI;

/// The model's basis functions at `tau`: AVAR = sum_j basis_j(tau) * theta_j with
/// theta = (Q^2, N^2, B^2, K^2, R^2).
pub fn basis(tau: f64) -> [f64; TERMS] {
    [
        3.0 / (tau * tau),
        1.0 / tau,
        FLICKER_AVAR_FACTOR,
        tau / 3.0,
        tau * tau / 2.0,
    ]
}

/// [`basis`] with the N column replaced, when the sensor's low-pass filter is known, by the
/// Allan variance of white noise through that filter ([`LowPass::white_avar`]), which tends
/// to `1 / tau` at long tau: N stays the long-tau white level and every tau can be fitted.
pub fn basis_with(tau: f64, low_pass: Option<&LowPass>) -> [f64; TERMS] {
    let mut row = basis(tau);
    if let Some(lp) = low_pass {
        row[N] = lp.white_avar(tau);
    }
    row
}

/// One fitted coefficient with its interval (`lo <= value <= hi`), in SI units (see
/// [`NoiseFit`]). A term the non-negativity constraint pinned at zero has `value = lo = 0`
/// and `hi` its upper bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Term {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
}

/// The result of [`fit_allan`]: the five IEEE-952 coefficients.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseFit {
    /// Quantization noise Q, u*s.
    pub q: Term,
    /// Angle (velocity) random walk N, u/sqrt(Hz) — the Allan deviation at tau = 1 s of the
    /// white-rate-noise part.
    pub n: Term,
    /// Bias instability B, u.
    pub b: Term,
    /// Rate random walk K, u*sqrt(Hz).
    pub k: Term,
    /// Rate ramp R, u/s.
    pub r: Term,
    /// Confidence level of the intervals.
    pub confidence: f64,
    /// Points fitted.
    pub points: usize,
    /// Effectively independent points, `n^2 / sum_ij rho_ij` under the correlation model.
    pub effective_points: f64,
    /// `sum_i (avar_i - model_i)^2 / Var_i` divided by the points minus free terms: about 1
    /// (more precisely, about `effective_points / points` for correlated curves) when the
    /// model and the edf describe the data.
    pub reduced_chi2: f64,
    /// Reweighting iterations used.
    pub iterations: usize,
    /// The shortest tau fitted, s.
    pub tau_min: f64,
    /// The sensor's low-pass filter the N column was shaped by ([`FitOptions::low_pass`]).
    pub low_pass: Option<LowPass>,
    /// How well the model describes the curve, with the correlation of the points taken
    /// into account; its Birge ratio has widened the intervals.
    pub goodness: Goodness,
    /// Whether the data support each term (see [`fit_allan_with`]).
    pub support: TermSupport,
}

/// Goodness of fit of [`fit_allan_with`] under the correlated-residual model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Goodness {
    /// The weighted residual sum divided by its expectation under the model: about 1 when
    /// the model and the points' variances and correlations describe the curve. NaN when
    /// the curve has no residual degrees of freedom.
    pub reduced_chi2: f64,
    /// Effective degrees of freedom of the residual sum (Satterthwaite), at most the
    /// points minus the fitted terms and usually far fewer: neighbouring taus share data.
    pub dof: f64,
    /// Probability of a residual sum at least this large if the model were right.
    pub p_value: f64,
    /// `sqrt(max(1, reduced_chi2))`: the factor every term's standard deviation was
    /// multiplied by before its interval and its detection test.
    pub birge_ratio: f64,
}

/// [`Goodness::p_value`] below which the model is said not to describe the curve.
pub const POOR_FIT_P: f64 = 1e-3;

impl Goodness {
    /// A fit without lack of fit (for fits written by hand): reduced chi-square 1, p = 0.5.
    pub const NOMINAL: Goodness = Goodness {
        reduced_chi2: 1.0,
        dof: 5.0,
        p_value: 0.5,
        birge_ratio: 1.0,
    };

    /// True when the five-term model does not describe the curve
    /// (`p_value <` [`POOR_FIT_P`]).
    pub fn poor(&self) -> bool {
        self.p_value < POOR_FIT_P
    }
}

/// The detection test of one term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Support {
    /// The term is in the final model (see [`fit_allan_with`]). A term not detected is
    /// reported as value 0, lo 0 and hi its upper bound.
    pub detected: bool,
    /// p-value of the term in the final model, or in the final model with it added when it
    /// is not detected: the likelihood-ratio test of dropping it (the deviance increase,
    /// scaled for the points' correlation and the Birge ratio; one-sided, as the term
    /// cannot be negative), 1 when the non-negativity constraint puts it at 0. Below
    /// [`FitOptions::detection_level`] for every detected term unless no model the curve
    /// supports has all its terms that significant (then the comparison with the full fit
    /// alone kept it; a p-value above the level marks such a weakly supported term).
    pub p_value: f64,
}

/// [`Support`] of each of the five terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TermSupport {
    pub q: Support,
    pub n: Support,
    pub b: Support,
    pub k: Support,
    pub r: Support,
}

impl TermSupport {
    /// The same support for every term (for fits written by hand).
    pub fn same(s: Support) -> Self {
        Self::from_array([s; TERMS])
    }

    pub(crate) fn from_array(s: [Support; TERMS]) -> Self {
        TermSupport {
            q: s[Q],
            n: s[N],
            b: s[B],
            k: s[K],
            r: s[R],
        }
    }
}

impl NoiseFit {
    /// The fitted model's Allan variance at `tau`.
    pub fn avar(&self, tau: f64) -> f64 {
        let theta = self.squared();
        basis_with(tau, self.low_pass.as_ref())
            .iter()
            .zip(theta)
            .map(|(a, t)| a * t)
            .sum()
    }

    /// The power-law exponent alpha (S_y(f) ∝ f^alpha) of the term that dominates the
    /// model's AVAR at `tau`: Q white PM (2), N white FM (0), B flicker FM (-1), K and R
    /// random-walk FM (-2; a ramp has no power law, and its AVAR grows like random walk's
    /// over the taus where it matters). 0 when every term is zero.
    pub fn dominant_alpha(&self, tau: f64) -> i32 {
        const ALPHA: [i32; TERMS] = [2, 0, -1, -2, -2];
        basis(tau)
            .into_iter()
            .zip(self.squared())
            .map(|(a, theta)| a * theta)
            .enumerate()
            .filter(|(_, part)| *part > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(0, |(t, _)| ALPHA[t])
    }

    fn squared(&self) -> [f64; TERMS] {
        [self.q, self.n, self.b, self.k, self.r].map(|t| t.value * t.value)
    }
}

/// Settings of [`fit_allan_with`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitOptions {
    /// Two-sided confidence level of each term's interval, in (0, 1). Default 0.683 (1 sigma).
    pub confidence: f64,
    /// Cap on the reweighting iterations. Default 50.
    pub max_iterations: usize,
    /// Shortest tau [`fit_deviation`] fits, s; `None` fits every tau.
    pub tau_min: Option<f64>,
    /// The sensor's low-pass filter: white noise is fitted with its shape ([`basis_with`]).
    /// `None`: white noise is `N^2 / tau` down to the shortest tau.
    pub low_pass: Option<LowPass>,
    /// Significance level of the test that keeps a term in the model, in (0, 1). Default
    /// 0.01: on curves without the term it is claimed in about 1 % of records.
    pub detection_level: f64,
    /// Largest Q the record allows, u*s: a fit with more is not adequate and an interval is
    /// cut there. [`fit_deviation`] sets it from the taus a fitted low-pass leaves out of the
    /// fit (quantization is added after the filter, so its `3 Q^2 / tau^2` cannot exceed
    /// the Allan variance measured at any tau); `None`: no bound.
    pub q_max: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            confidence: 0.683,
            max_iterations: 50,
            tau_min: None,
            low_pass: None,
            detection_level: 0.01,
            q_max: None,
        }
    }
}

/// Errors from [`fit_allan`]; each names the input at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    #[error("tau, avar and edf differ in length ({tau}, {avar}, {edf})")]
    LengthMismatch { tau: usize, avar: usize, edf: usize },
    #[error("{0} points: the noise fit needs at least 2")]
    TooFewPoints(usize),
    #[error("{what}[{index}] = {value} is not a positive finite number")]
    NotPositive {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("confidence {0} is not in (0, 1)")]
    BadConfidence(f64),
    #[error("detection level {0} is not in (0, 1)")]
    BadDetectionLevel(f64),
}

#[cfg(test)]
mod tests;

//! The model's stochastic terms fitted to one Allan variance curve — the measured one or a
//! simulated realisation's, by the same code.
//!
//! **Fit.** AVAR(tau) = sum_c theta_c basis_c(tau), theta >= 0, by reweighted non-negative
//! least squares (Lawson-Hanson, [`numerics::nnls`]) approximating least squares in ln AVAR
//! ([`refit`]), each point scaled by `1 / s_i`, `s_i` the standard deviation of ln AVAR at tau_i over the
//! simulated realisations of the current model. The simulated spread is used rather than
//! an EDF formula because it is what the record is compared with: it holds the estimator's
//! scatter at every tau whatever the mix of noise types, and whatever the analytic bases
//! miss of the simulator's processes (a finite flicker bank, a sampled Gauss-Markov), so a
//! model this fit prefers is one whose simulations lie closer to the record.
//!
//! **Misfit.** `sum_i (ln(model_i / avar_i) / s_i)^2`. The points are correlated, so its
//! absolute value is no chi-square; the workflow only compares its change between nested
//! models with the same change on simulated curves, which carry the same correlation.

use crate::analysis::low_pass::{LowPass, LowPassSource};
use crate::analysis::{fit, numerics};
use crate::sim::noise::{GaussMarkov, NoiseTerms, gauss_markov_avar};

/// Smallest `s_i` used: the simulated spread at the shortest taus of long records can be
/// far below what the bases' own accuracy (about a percent) supports.
pub const SD_FLOOR: f64 = 0.01;

/// A curve to fit: taus (s), AVAR (u^2), and each point's standard deviation of ln AVAR.
#[derive(Debug, Clone, Copy)]
pub struct Curve<'a> {
    pub tau: &'a [f64],
    pub avar: &'a [f64],
    pub sd_ln: &'a [f64],
}

/// One amplitude-squared column of the fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Column {
    Q,
    N,
    B,
    K,
    /// A first-order Gauss-Markov process of this correlation time, s.
    GaussMarkov(f64),
}

/// The shape of the white-rate-noise column: `N^2 / tau` unfiltered, or the Allan variance of
/// unit-density white noise through the sensor's low-pass filter.
pub type WhiteShape<'a> = &'a (dyn Fn(f64) -> f64 + Sync);

/// `1 / tau`: white rate noise of unit density, unfiltered (IEEE 952 Table C.1).
pub fn unfiltered(tau: f64) -> f64 {
    1.0 / tau
}

impl Column {
    fn at(self, tau: f64, white: WhiteShape) -> f64 {
        let basis = fit::basis(tau);
        match self {
            Column::Q => basis[0],
            Column::N => white(tau),
            Column::B => basis[2],
            Column::K => basis[3],
            Column::GaussMarkov(tau_c) => gauss_markov_avar(GaussMarkov { sigma: 1.0, tau_c }, tau),
        }
    }
}

/// The columns a model's stochastic terms occupy (N always).
pub fn columns_of(terms: &NoiseTerms) -> Vec<Column> {
    let mut columns = vec![Column::N];
    if terms.q > 0.0 {
        columns.push(Column::Q);
    }
    if terms.b > 0.0 {
        columns.push(Column::B);
    }
    if terms.k > 0.0 {
        columns.push(Column::K);
    }
    if let Some(g) = terms.gauss_markov {
        columns.push(Column::GaussMarkov(g.tau_c));
    }
    columns
}

/// The model's stochastic AVAR at `tau`.
pub fn avar(terms: &NoiseTerms, tau: f64, white: WhiteShape) -> f64 {
    let basis = fit::basis(tau);
    let mut v = basis[0] * terms.q * terms.q
        + white(tau) * terms.n * terms.n
        + basis[2] * terms.b * terms.b
        + basis[3] * terms.k * terms.k;
    if let Some(g) = terms.gauss_markov {
        v += gauss_markov_avar(g, tau);
    }
    v
}

/// Reweighting rounds of [`refit`].
const REWEIGHTS: usize = 6;

/// Fit `columns` to `curve`; terms outside the columns are 0. Each round solves the NNLS
/// with rows weighted by `1 / (s_i sqrt(a_i m_i))`, `m_i` the previous round's model (the
/// measured value at first): the residual `(a - m) / sqrt(a m) = 2 sinh(ln(a / m) / 2)` is
/// symmetric in ln(a / m), so a model far below the curve costs as much as one far above
/// (plain relative error, `(a - m) / a`, caps the cost of a model that is too low at 1).
pub fn refit(curve: Curve, columns: &[Column], white: WhiteShape) -> NoiseTerms {
    refit_cleaned(curve, columns, white, None)
}

/// Expected Allan variance a removal of regressors takes from unit random walk (K = 1) and
/// unit flicker (B = 1), per point of the curve, u^2 per unit level squared
/// ([`super::restore`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    pub k: Vec<f64>,
    pub b: Vec<f64>,
}

/// [`refit`] to a curve from which regressors were removed: the K and B columns are their
/// bases less what the removal takes from them (`loss`), so K and B are estimated at the
/// level the raw noise had.
pub fn refit_cleaned(
    curve: Curve,
    columns: &[Column],
    white: WhiteShape,
    loss: Option<&Loss>,
) -> NoiseTerms {
    let mut terms = NoiseTerms::default();
    for round in 0..REWEIGHTS {
        let reference: Vec<f64> = curve
            .avar
            .iter()
            .enumerate()
            .map(|(i, &a)| {
                if round == 0 {
                    a
                } else {
                    (a * point(&terms, curve, i, white, loss))
                        .sqrt()
                        .max(a * 1e-6)
                }
            })
            .collect();
        terms = solve(curve, columns, white, &reference, loss);
    }
    terms
}

/// The model's AVAR at point `i` of a curve cleaned with `loss`.
fn point(
    terms: &NoiseTerms,
    curve: Curve,
    i: usize,
    white: WhiteShape,
    loss: Option<&Loss>,
) -> f64 {
    let lost = loss.map_or(0.0, |l| {
        terms.k * terms.k * l.k[i] + terms.b * terms.b * l.b[i]
    });
    avar(terms, curve.tau[i], white) - lost
}

/// One weighted NNLS solve with rows scaled by `1 / (s_i reference_i)`.
fn solve(
    curve: Curve,
    columns: &[Column],
    white: WhiteShape,
    reference: &[f64],
    loss: Option<&Loss>,
) -> NoiseTerms {
    let mut g = Vec::with_capacity(curve.tau.len());
    let mut b = Vec::with_capacity(curve.tau.len());
    for (i, (((&tau, &avar), &sd), &r)) in curve
        .tau
        .iter()
        .zip(curve.avar)
        .zip(curve.sd_ln)
        .zip(reference)
        .enumerate()
    {
        if !(avar > 0.0 && r > 0.0) {
            continue;
        }
        let w = 1.0 / (sd.max(SD_FLOOR) * r);
        let lost = |c: &Column| match (c, loss) {
            (Column::K, Some(l)) => l.k[i],
            (Column::B, Some(l)) => l.b[i],
            _ => 0.0,
        };
        g.push(
            columns
                .iter()
                .map(|c| (c.at(tau, white) - lost(c)) * w)
                .collect::<Vec<f64>>(),
        );
        b.push(avar * w);
    }
    let theta = numerics::nnls_normalised(g, &b);
    let mut out = NoiseTerms::default();
    for (c, th) in columns.iter().zip(theta) {
        let amp = th.max(0.0).sqrt();
        match *c {
            Column::Q => out.q = amp,
            Column::N => out.n = amp,
            Column::B => out.b = amp,
            Column::K => out.k = amp,
            Column::GaussMarkov(tau_c) => {
                out.gauss_markov = (amp > 0.0).then_some(GaussMarkov { sigma: amp, tau_c })
            }
        }
    }
    out
}

/// `sd_ln` with the points at taus (`tau`, s) below a fitted low-pass's
/// [`LowPass::first_tau`] left out (an infinite standard deviation: no weight in a refit, no
/// share of a misfit). A fitted filter is the nearest shape of the catalogue, not the
/// sensor's own: where the filter lowers the white Allan variance by more than
/// [`crate::analysis::low_pass::FITTED_SHAPE_SHARE`], the difference between the two would
/// read as quantization or a Gauss-Markov process a few samples long. `analyze` starts its
/// fit at the same tau.
pub fn beyond_fitted_filter(sd_ln: &[f64], tau: &[f64], low_pass: Option<&LowPass>) -> Vec<f64> {
    let first = low_pass
        .filter(|lp| lp.source == LowPassSource::Fitted)
        .map_or(0.0, LowPass::first_tau);
    sd_ln
        .iter()
        .zip(tau)
        .map(|(&s, &t)| if t < first { f64::INFINITY } else { s })
        .collect()
}

/// `sum_i (ln(model_i / avar_i) / s_i)^2` over the curve's positive points.
pub fn misfit(curve: Curve, terms: &NoiseTerms, white: WhiteShape) -> f64 {
    curve
        .tau
        .iter()
        .zip(curve.avar)
        .zip(curve.sd_ln)
        .filter(|((_, a), _)| **a > 0.0)
        .map(|((&tau, &a), &sd)| {
            let ratio = avar(terms, tau, white).max(f64::MIN_POSITIVE) / a;
            (ratio.ln() / sd.max(SD_FLOOR)).powi(2)
        })
        .sum()
}

/// The best Gauss-Markov addition to `columns` over a log grid of correlation times in
/// `[lo, hi]` s (16 per decade): the refitted terms and their misfit.
pub fn best_gauss_markov(
    curve: Curve,
    columns: &[Column],
    lo: f64,
    hi: f64,
    white: WhiteShape,
) -> Option<(NoiseTerms, f64)> {
    if !(hi > lo && lo > 0.0) {
        return None;
    }
    let count = ((hi / lo).log10() * 16.0).ceil() as usize + 1;
    (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1).max(1) as f64))
        .filter_map(|tau_c| {
            let mut with = columns.to_vec();
            with.push(Column::GaussMarkov(tau_c));
            let terms = refit(curve, &with, white);
            terms.gauss_markov?;
            Some((terms, misfit(curve, &terms, white)))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refit_recovers_exact_terms() {
        let tau: Vec<f64> = (0..30).map(|i| 0.01 * 1.5f64.powi(i)).collect();
        let truth = NoiseTerms {
            n: 1e-3,
            b: 2e-4,
            k: 1e-5,
            ..NoiseTerms::default()
        };
        let avar: Vec<f64> = tau.iter().map(|&t| avar(&truth, t, &unfiltered)).collect();
        let sd_ln = vec![0.1; tau.len()];
        let curve = Curve {
            tau: &tau,
            avar: &avar,
            sd_ln: &sd_ln,
        };
        let got = refit(curve, &[Column::N, Column::B, Column::K], &unfiltered);
        for (g, t) in [(got.n, truth.n), (got.b, truth.b), (got.k, truth.k)] {
            assert!((g / t - 1.0).abs() < 1e-6, "{got:?}");
        }
        assert!(misfit(curve, &got, &unfiltered) < 1e-9);
    }

    #[test]
    fn gauss_markov_grid_finds_the_correlation_time() {
        let tau: Vec<f64> = (0..40).map(|i| 0.1 * 1.3f64.powi(i)).collect();
        let truth = NoiseTerms {
            n: 1e-3,
            gauss_markov: Some(GaussMarkov {
                sigma: 1e-3,
                tau_c: 30.0,
            }),
            ..NoiseTerms::default()
        };
        let avar: Vec<f64> = tau.iter().map(|&t| avar(&truth, t, &unfiltered)).collect();
        let sd_ln = vec![0.1; tau.len()];
        let curve = Curve {
            tau: &tau,
            avar: &avar,
            sd_ln: &sd_ln,
        };
        let (terms, _) = best_gauss_markov(curve, &[Column::N], 1.0, 1000.0, &unfiltered).unwrap();
        let g = terms.gauss_markov.unwrap();
        assert!((g.tau_c / 30.0 - 1.0).abs() < 0.08, "{g:?}");
    }
}

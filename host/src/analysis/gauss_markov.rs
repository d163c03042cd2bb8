//! A first-order Gauss-Markov bias state from an Allan curve, for filters that cannot carry
//! flicker noise (it has no finite-dimensional state model).
//!
//! **Model.** The IEEE-952 model with the flicker term replaced by a Gauss-Markov process of
//! standard deviation sigma and correlation time tau_c:
//!
//! ```text
//! AVAR(tau) = 3 Q^2 / tau^2 + N^2 / tau + AVAR_GM(sigma, tau_c; tau) + K^2 tau / 3
//! AVAR_GM   = (sigma^2 tau_c / tau^2) (2 tau - tau_c (3 - 4 e^(-tau/tau_c) + e^(-2 tau/tau_c)))
//! ```
//!
//! (the Gauss-Markov Allan variance of IEEE 952-1997 Annex C and Xing & Gebre-Egziabher,
//! "Modeling and bounding low cost inertial sensor errors", IEEE/ION PLANS 2008; computed by
//! [`gauss_markov_avar`]). Its Allan deviation rises as sqrt(tau) well below tau_c, peaks at
//! tau = 1.89 tau_c at 0.437 sqrt(q tau_c) = 0.617 sigma (q = 2 sigma^2 / tau_c the driving
//! noise's PSD; Xing & Gebre-Egziabher's read-out, checked in the tests), and falls as
//! tau^-1/2 beyond: a hump where the flicker floor is flat.
//!
//! **Fit.** tau_c is searched on a grid of [`GRID_PER_DECADE`] per decade over the fitted taus;
//! for each, the four squared amplitudes (Q^2, N^2, sigma^2, K^2) follow by non-negative least
//! squares on the relative errors of the Allan variance, each point weighted by its EDF
//! (`Var(avar) = 2 avar^2 / edf`), first with the measured and then with the fitted variance
//! (weighting by the measured value alone favours points that fell low). The tau_c with the
//! smallest weighted misfit wins.
//!
//! **When the data support it**: sigma > 0; tau_c not at either end of the grid (at the short
//! end the process is indistinguishable from white noise, at the long end from a random
//! walk: tau_c is then not determined); the peak of its Allan deviation (1.89 tau_c) at least
//! [`TURNOVER_OCTAVES`] octaves below the longest fitted tau, so that the fall after the
//! peak — what tells a Gauss-Markov process from a random walk — is in the record (without
//! it, a random walk's noisy last points are fitted as well by a slow Gauss-Markov); and the
//! Gauss-Markov term at least half of the model's Allan variance at some fitted tau
//! (otherwise it only dents the curve); and it must earn its two parameters: the misfit
//! (sum of edf/2 x squared relative error, a chi-squared-like sum) must drop against the
//! same fit without it by more than the 99 % quantile of chi-squared with 2 degrees of
//! freedom (9.21), after dividing the drop by the points per effectively independent point
//! of the curve (Allan variances at neighbouring taus are strongly correlated; the noise
//! fit's correlation model gives that ratio, `NoiseFit::effective_points`). Otherwise the
//! reason is returned.

use crate::analysis::pipeline::ChannelResult;
use crate::analysis::{fit, numerics};
use crate::sim::noise::{GaussMarkov, gauss_markov_avar};
use serde::Serialize;

/// Chi-squared (2 degrees of freedom) 99 % quantile: -2 ln(0.01).
pub const IMPROVEMENT_CHI2: f64 = 9.21;
/// Points per decade of the tau_c search.
pub const GRID_PER_DECADE: f64 = 16.0;
/// Octaves of the Allan curve that must follow the Gauss-Markov peak.
pub const TURNOVER_OCTAVES: f64 = 3.0;
/// Where the Gauss-Markov Allan deviation peaks, in correlation times (Xing & Gebre-Egziabher).
pub const PEAK_TAU_PER_TAU_C: f64 = 1.89;
/// Share of the model's Allan variance the Gauss-Markov term must reach at some tau.
pub const MIN_SHARE: f64 = 0.5;

/// The fitted model: the Gauss-Markov process and its companions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GaussMarkovFit {
    /// Standard deviation, u.
    pub sigma: f64,
    /// Correlation time, s.
    pub tau_c: f64,
    /// Quantization Q (u*s), white N (u/sqrt(Hz)) and random walk K (u*sqrt(Hz)) fitted with it.
    pub q: f64,
    pub n: f64,
    pub k: f64,
    /// Largest share of the model's Allan variance the Gauss-Markov term has over the taus.
    pub peak_share: f64,
}

impl GaussMarkovFit {
    pub fn process(&self) -> GaussMarkov {
        GaussMarkov {
            sigma: self.sigma,
            tau_c: self.tau_c,
        }
    }
}

/// Why the data do not support a Gauss-Markov bias ([`fit_points`], [`fit_channel`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GaussMarkovError {
    /// The channel has no noise fit to start from.
    #[error("{0}")]
    NoNoiseFit(fit::FitError),
    #[error("no Allan variance points to fit")]
    NoPoints,
    #[error("{0} Allan points: too few to place a correlation time")]
    TooFewPoints(usize),
    #[error("no Gauss-Markov component: the fit puts its sigma at 0")]
    NoComponent,
    /// The best correlation time is the shortest (`short`) or the longest tau of the grid.
    #[error(
        "not supported by the data: the correlation time ran to the {} end of the record's taus ({tau_c:.3e} s), where a Gauss-Markov process cannot be told from {}",
        if *.short { "short" } else { "long" },
        if *.short { "white noise" } else { "a random walk" }
    )]
    AtGridEnd { short: bool, tau_c: f64 },
    #[error(
        "not supported by the data: the Allan deviation of the fitted Gauss-Markov (tau_c {tau_c:.3e} s) would peak at {peak:.3e} s, less than {TURNOVER_OCTAVES} octaves below the longest tau ({longest:.3e} s): its fall, which tells it from a random walk, is not in the record"
    )]
    NoFall { tau_c: f64, peak: f64, longest: f64 },
    #[error(
        "not supported by the data: the Gauss-Markov term improves the fit by {0:.1} (chi-squared, per independent point), under the {IMPROVEMENT_CHI2} its two parameters must earn"
    )]
    SmallImprovement(f64),
    #[error(
        "not supported by the data: the Gauss-Markov term is at most {:.0} % of the Allan variance at any tau (needs {:.0} %)",
        100.0 * .0,
        100.0 * MIN_SHARE
    )]
    SmallShare(f64),
}

/// The Gauss-Markov fit of a channel's overlapping Allan curve, from the tau where its noise
/// fit starts; `Err` says why the data do not support one.
pub fn fit_channel(channel: &ChannelResult) -> Result<GaussMarkovFit, GaussMarkovError> {
    let fit = channel
        .fit
        .as_ref()
        .map_err(|e| GaussMarkovError::NoNoiseFit(e.clone()))?;
    let curve = &channel.fit_curve;
    let first = curve
        .deviation
        .tau
        .iter()
        .position(|&t| t >= fit.tau_min * (1.0 - 1e-9))
        .unwrap_or(0);
    let points: Vec<Point> = (first..curve.deviation.tau.len())
        .map(|i| Point {
            tau: curve.deviation.tau[i],
            avar: curve.deviation.dev[i].powi(2),
            edf: curve.intervals.edf[i],
        })
        .filter(|p| p.avar > 0.0 && p.edf.is_finite() && p.edf > 0.0)
        .collect();
    let inflation = (fit.points as f64 / fit.effective_points).max(1.0);
    fit_points(&points, inflation)
}

/// One Allan variance estimate and its equivalent degrees of freedom.
#[derive(Debug, Clone, Copy)]
pub struct Point {
    pub tau: f64,
    pub avar: f64,
    pub edf: f64,
}

/// The fit of the module documentation on `points` (ascending tau); `inflation` is the
/// number of points per effectively independent point (1 for independent points).
pub fn fit_points(points: &[Point], inflation: f64) -> Result<GaussMarkovFit, GaussMarkovError> {
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return Err(GaussMarkovError::NoPoints);
    };
    if points.len() < 6 {
        return Err(GaussMarkovError::TooFewPoints(points.len()));
    }
    let decades = (last.tau / first.tau).log10();
    let steps = (decades * GRID_PER_DECADE).ceil().max(2.0) as usize;
    let grid: Vec<f64> = (0..=steps)
        .map(|i| first.tau * 10f64.powf(decades * i as f64 / steps as f64))
        .collect();
    let ((best, misfit), index) = grid
        .iter()
        .map(|&tau_c| fit_at(points, Some(tau_c)))
        .zip(0..)
        .min_by(|a, b| a.0.1.total_cmp(&b.0.1))
        .expect("the grid has points");
    let improvement = (fit_at(points, None).1 - misfit) / inflation;
    if best.sigma <= 0.0 {
        return Err(GaussMarkovError::NoComponent);
    }
    if index == 0 || index == steps {
        return Err(GaussMarkovError::AtGridEnd {
            short: index == 0,
            tau_c: best.tau_c,
        });
    }
    let peak = PEAK_TAU_PER_TAU_C * best.tau_c;
    if peak * TURNOVER_OCTAVES.exp2() > last.tau {
        return Err(GaussMarkovError::NoFall {
            tau_c: best.tau_c,
            peak,
            longest: last.tau,
        });
    }
    if improvement < IMPROVEMENT_CHI2 {
        return Err(GaussMarkovError::SmallImprovement(improvement));
    }
    if best.peak_share < MIN_SHARE {
        return Err(GaussMarkovError::SmallShare(best.peak_share));
    }
    Ok(best)
}

/// The best amplitudes for one tau_c (`None`: without the Gauss-Markov term), and the
/// weighted misfit.
fn fit_at(points: &[Point], tau_c: Option<f64>) -> (GaussMarkovFit, f64) {
    let columns = |tau: f64| {
        let b = fit::basis(tau);
        let gm = tau_c.map_or(0.0, |tau_c| {
            gauss_markov_avar(GaussMarkov { sigma: 1.0, tau_c }, tau)
        });
        [b[0], b[1], gm, b[3]]
    };
    let model = |theta: &[f64], tau: f64| -> f64 {
        columns(tau).iter().zip(theta).map(|(c, t)| c * t).sum()
    };
    // Relative error weights: sqrt(edf / 2) / reference variance.
    let solve = |reference: &dyn Fn(&Point) -> f64| -> Vec<f64> {
        let w: Vec<f64> = points
            .iter()
            .map(|p| (p.edf / 2.0).sqrt() / reference(p))
            .collect();
        let rows: Vec<[f64; 4]> = points.iter().map(|p| columns(p.tau)).collect();
        let norms: Vec<f64> = (0..4)
            .map(|j| {
                let s: f64 = rows.iter().zip(&w).map(|(r, w)| (r[j] * w).powi(2)).sum();
                s.sqrt().max(f64::MIN_POSITIVE)
            })
            .collect();
        let g: Vec<Vec<f64>> = rows
            .iter()
            .zip(&w)
            .map(|(r, w)| (0..4).map(|j| r[j] * w / norms[j]).collect())
            .collect();
        let y: Vec<f64> = points.iter().zip(&w).map(|(p, w)| p.avar * w).collect();
        let scaled = numerics::nnls(&g, &y);
        scaled.iter().zip(&norms).map(|(x, n)| x / n).collect()
    };
    let first = solve(&|p| p.avar);
    let theta = solve(&|p| model(&first, p.tau).max(f64::MIN_POSITIVE));
    let misfit: f64 = points
        .iter()
        .map(|p| {
            let m = model(&theta, p.tau).max(f64::MIN_POSITIVE);
            p.edf / 2.0 * ((p.avar - m) / m).powi(2)
        })
        .sum();
    let peak_share = points
        .iter()
        .map(|p| columns(p.tau)[2] * theta[2] / model(&theta, p.tau).max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    let amplitude = |t: f64| t.max(0.0).sqrt();
    (
        GaussMarkovFit {
            sigma: amplitude(theta[2]),
            tau_c: tau_c.unwrap_or(f64::NAN),
            q: amplitude(theta[0]),
            n: amplitude(theta[1]),
            k: amplitude(theta[3]),
            peak_share,
        },
        misfit,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The read-out the module documentation quotes: the Gauss-Markov Allan deviation peaks
    /// at tau = 1.89 tau_c with 0.437 sqrt(q tau_c), q = 2 sigma^2 / tau_c (Xing &
    /// Gebre-Egziabher 2008), i.e. 0.617 sigma; found here by a fine search of
    /// [`gauss_markov_avar`].
    #[test]
    fn gauss_markov_allan_peak() {
        let gm = GaussMarkov {
            sigma: 2.0,
            tau_c: 10.0,
        };
        let (tau, avar) = (0..100_000)
            .map(|i| 1.0 + i as f64 * 1e-3)
            .map(|t| (t, gauss_markov_avar(gm, t)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!((tau / gm.tau_c - PEAK_TAU_PER_TAU_C).abs() < 0.005, "{tau}");
        let q = 2.0 * gm.sigma * gm.sigma / gm.tau_c;
        assert!((avar.sqrt() / (q * gm.tau_c).sqrt() - 0.437).abs() < 0.0005);
        assert!(
            (avar.sqrt() / gm.sigma - 0.617).abs() < 0.0005,
            "{}",
            avar.sqrt()
        );
    }

    /// The exact model curve (no estimation noise) gives back its own parameters, to the
    /// grid's resolution in tau_c.
    #[test]
    fn exact_curve_is_recovered() {
        let gm = GaussMarkov {
            sigma: 3e-4,
            tau_c: 20.0,
        };
        let (n, k) = (1e-3, 1e-6);
        let points: Vec<Point> = (0..60)
            .map(|i| 0.05 * 10f64.powf(i as f64 / 12.0))
            .map(|tau| Point {
                tau,
                avar: n * n / tau + gauss_markov_avar(gm, tau) + k * k * tau / 3.0,
                edf: 100.0,
            })
            .collect();
        let fit = fit_points(&points, 1.0).unwrap();
        // Grid step: 10^(1/16) = 1.155, so tau_c is within half a step (7.5 %).
        assert!((fit.tau_c / gm.tau_c - 1.0).abs() < 0.08, "{fit:?}");
        assert!((fit.sigma / gm.sigma - 1.0).abs() < 0.1, "{fit:?}");
        assert!((fit.n / n - 1.0).abs() < 0.05, "{fit:?}");
    }

    #[test]
    fn white_and_random_walk_alone_do_not_support_a_gauss_markov() {
        let (n, k) = (1e-3, 1e-5);
        let points: Vec<Point> = (0..50)
            .map(|i| 0.05 * 10f64.powf(i as f64 / 10.0))
            .map(|tau| Point {
                tau,
                avar: n * n / tau + k * k * tau / 3.0,
                edf: 100.0,
            })
            .collect();
        let reason = fit_points(&points, 1.0).unwrap_err();
        assert!(
            matches!(
                reason,
                GaussMarkovError::NoComponent
                    | GaussMarkovError::AtGridEnd { .. }
                    | GaussMarkovError::NoFall { .. }
                    | GaussMarkovError::SmallImprovement(_)
                    | GaussMarkovError::SmallShare(_)
            ),
            "{reason}"
        );
    }
}

//! Confidence intervals for the Allan family: equivalent degrees of freedom (EDF) and
//! chi-squared bounds.
//!
//! - adev, oadev, mdev, tdev, hdev, ohdev: C. A. Greenhall and W. J. Riley, "Uncertainty of
//!   stability variances based on finite differences", Proc. 35th PTTI, 2003 (the algorithm
//!   Stable32 uses; allantools calls it `edf_greenhall`).
//! - totdev: NIST SP 1065 §5.2.11 and Table 7, edf = b (T/tau) - c for alpha = 0, -1, -2;
//!   other noise types fall back to the simple SP 1065 Table 5 formulas.
//! - bounds: SP 1065 eq. 45, var * edf / chi²(p, edf).

use super::fit::NoiseFit;
use super::noise_id::{MIN_ACF_POINTS, identify_all};
use super::{Deviation, Estimator};
use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Confidence of a "1-sigma" interval, erf(1/sqrt(2)) (Stable32's 0.683).
pub const ONE_SIGMA: f64 = 0.682_689_492_137_085_9;

/// Per-tau noise type, EDF and bounds of a [`Deviation`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Intervals {
    /// Power-law exponent alpha used for the EDF (S_y(f) ∝ f^alpha).
    pub alpha: Vec<i32>,
    pub edf: Vec<f64>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

/// Two-sided bounds (lo, hi) of a deviation with `edf` degrees of freedom at `confidence`
/// (e.g. [`ONE_SIGMA`]): lo = dev sqrt(edf / chi²(1 - (1-c)/2)), hi = dev sqrt(edf /
/// chi²((1-c)/2)) (SP 1065 eq. 45). NaN bounds when edf is not positive or finite, or the
/// confidence is outside (0, 1).
pub fn chi2_bounds(dev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    if !(edf > 0.0 && edf.is_finite() && confidence > 0.0 && confidence < 1.0) {
        return (f64::NAN, f64::NAN);
    }
    let Ok(chi2) = ChiSquared::new(edf) else {
        return (f64::NAN, f64::NAN);
    };
    let tail = (1.0 - confidence) / 2.0;
    let lo = dev * (edf / chi2.inverse_cdf(1.0 - tail)).sqrt();
    let hi = dev * (edf / chi2.inverse_cdf(tail)).sqrt();
    (lo, hi)
}

/// Equivalent degrees of freedom of `est` at factor m on `n_phase` phase points for noise
/// exponent `alpha` (-2..=2). NaN when the estimator has no terms there or alpha is out of
/// range.
pub fn edf(est: Estimator, alpha: i32, m: usize, n_phase: usize) -> f64 {
    if !(-2..=2).contains(&alpha) || m == 0 || n_phase < 2 {
        return f64::NAN;
    }
    let (d, overlapping, modified) = match est {
        Estimator::Adev => (2, false, false),
        Estimator::Oadev => (2, true, false),
        Estimator::Mdev | Estimator::Tdev => (2, true, true),
        Estimator::Hdev => (3, false, false),
        Estimator::Ohdev => (3, true, false),
        Estimator::Totdev => return edf_totdev(alpha, m, n_phase),
    };
    greenhall(alpha, d, m, n_phase, overlapping, modified)
}

/// Noise type, EDF and `confidence` bounds for every tau of `dev`, computed on the phase data
/// `x` it came from. Noise identification per tau ([`identify_all`]); where that is impossible the
/// alpha of the nearest identified tau is used (the smaller tau on a tie), else 0 (white FM).
pub fn intervals(dev: &Deviation, x: &[f64], confidence: f64) -> Intervals {
    intervals_with_model(dev, x, confidence, None)
}

/// [`intervals`], with the noise type taken from a fitted five-term model (the power law of
/// the term that dominates its AVAR, [`NoiseFit::dominant_alpha`]) at the taus it was fitted
/// to; identified per tau elsewhere (below the fit's shortest tau), and, when the model does
/// not describe the curve ([`crate::analysis::fit::Goodness::poor`]), also wherever enough
/// clusters remain for the lag-1 autocorrelation method ([`MIN_ACF_POINTS`] decimated
/// points).
///
/// Why: at the longest taus only a handful of clusters remain, and per-tau identification
/// (the B1 ratio there) often names a white or flicker phase noise whose larger EDF gives
/// intervals several times too narrow (+-8-30 % where +-50-200 % is right on records
/// dominated by rate random walk); the fit's dominant term rests on the whole curve.
pub fn intervals_with_model(
    dev: &Deviation,
    x: &[f64],
    confidence: f64,
    model: Option<&NoiseFit>,
) -> Intervals {
    let model_alpha = |k: usize| -> Option<i32> {
        let fit = model?;
        let (tau, m) = (dev.tau[k], dev.m[k]);
        let few_clusters = x.len().div_ceil(m.max(1)) < MIN_ACF_POINTS;
        let applies = tau >= fit.tau_min * (1.0 - 1e-9) && (!fit.goodness.poor() || few_clusters);
        applies.then(|| fit.dominant_alpha(tau))
    };
    let from_model: Vec<Option<i32>> = (0..dev.m.len()).map(model_alpha).collect();
    let unknown: Vec<usize> = (0..dev.m.len())
        .filter(|&k| from_model[k].is_none())
        .map(|k| dev.m[k])
        .collect();
    let mut identified = identify_all(dev.estimator, x, &unknown).into_iter();
    let found: Vec<Option<i32>> = from_model
        .iter()
        .map(|a| a.or_else(|| identified.next().flatten()))
        .collect();
    let alpha: Vec<i32> = (0..found.len()).map(|k| fill_alpha(&found, k)).collect();
    let edf: Vec<f64> = dev
        .m
        .iter()
        .zip(&alpha)
        .map(|(&m, &a)| edf(dev.estimator, a, m, x.len()))
        .collect();
    let (lo, hi) = dev
        .dev
        .iter()
        .zip(&edf)
        .map(|(&d, &e)| chi2_bounds(d, e, confidence))
        .unzip();
    Intervals { alpha, edf, lo, hi }
}

/// Alpha at index k, or the nearest identified neighbour's, or 0.
fn fill_alpha(found: &[Option<i32>], k: usize) -> i32 {
    (0..found.len())
        .flat_map(|d| [k.checked_sub(d), Some(k + d)])
        .flatten()
        .find_map(|i| found.get(i).copied().flatten())
        .unwrap_or(0)
}

/// SP 1065 Table 7: TOTVAR edf = b (T/tau) - c with T/tau = N/m (N phase points), for white,
/// flicker and random-walk FM; for phase noises (alpha 1, 2) the simple formulas of SP 1065
/// Table 5 (as allantools does).
fn edf_totdev(alpha: i32, m: usize, n: usize) -> f64 {
    let ratio = n as f64 / m as f64;
    match alpha {
        0 => 1.50 * ratio,
        -1 => 1.17 * ratio - 0.22,
        -2 => 0.93 * ratio - 0.36,
        _ => edf_simple(alpha, m, n),
    }
}

/// SP 1065 Table 5 (Stein's approximations) for white and flicker PM, N phase points.
fn edf_simple(alpha: i32, m: usize, n: usize) -> f64 {
    let (n, m) = (n as f64, m as f64);
    match alpha {
        2 => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        _ => {
            let a = (n - 1.0) / (2.0 * m);
            let b = (2.0 * m + 1.0) * (n - 1.0) / 4.0;
            (a.ln() * b.ln()).sqrt().exp()
        }
    }
}

/// Greenhall & Riley 2003: EDF of a d-th difference variance (d = 2 Allan, 3 Hadamard) with
/// filter factor F (1 modified, m unmodified) and stride factor S (m overlapping, 1 not).
/// L = m/F + m d is the filter length, M = 1 + floor(S (N - L) / m) the number of terms,
/// J = min(M, (d+1) S), r = M / S; the cases below are the paper's.
fn greenhall(alpha: i32, d: u32, m: usize, n: usize, overlapping: bool, modified: bool) -> f64 {
    const J_MAX: f64 = 100.0;
    let mf = m as f64;
    let f = if modified { 1.0 } else { mf };
    let s = if overlapping { mf } else { 1.0 };
    let l = mf / f + mf * f64::from(d);
    let big_m = 1.0 + (s * (n as f64 - l) / mf).floor();
    if big_m < 1.0 || alpha + 2 * d as i32 <= 1 {
        return f64::NAN;
    }
    let j = big_m.min((f64::from(d) + 1.0) * s);
    let r = big_m / s;
    let sz0 = |f: Filter| sz(0.0, f, alpha, d);
    let inv = if modified {
        // Case 1: modified variances, all alpha.
        if j <= J_MAX {
            basic_sum(j, big_m, s, Filter::F(1.0), alpha, d) / (sz0(Filter::F(1.0)).powi(2) * big_m)
        } else if r > f64::from(d) + 1.0 {
            let (a0, a1) = table1(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, Filter::F(1.0), alpha, d)
                / (sz0(Filter::F(1.0)).powi(2) * J_MAX)
        }
    } else if alpha <= 0 {
        // Case 2: unmodified variances, alpha <= 0.
        if j <= J_MAX {
            let fp = if mf * (f64::from(d) + 1.0) <= J_MAX {
                Filter::F(mf)
            } else {
                Filter::Infinite
            };
            basic_sum(j, big_m, s, fp, alpha, d) / (sz0(fp).powi(2) * big_m)
        } else if r > f64::from(d) + 1.0 {
            let (a0, a1) = table2(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, Filter::Infinite, alpha, d)
                / (sz0(Filter::Infinite).powi(2) * J_MAX)
        }
    } else if alpha == 1 {
        // Case 3: unmodified variances, flicker PM.
        if j <= J_MAX {
            basic_sum(j, big_m, s, Filter::F(mf), 1, d) / (sz0(Filter::F(mf)).powi(2) * big_m)
        } else {
            let (b0, b1) = table3(d);
            let norm = (b0 + b1 * mf.ln()).powi(2);
            if r > f64::from(d) + 1.0 {
                let (a0, a1) = table2(alpha, d);
                (a0 - a1 / r) / (norm * r)
            } else {
                let mp = J_MAX / r;
                basic_sum(J_MAX, J_MAX, mp, Filter::F(mp), 1, d) / (norm * J_MAX)
            }
        }
    } else {
        // Case 4: unmodified variances, white PM. Only lags that are whole multiples of tau
        // correlate: rho(k) = (-1)^k C(2d, d-k) / C(2d, d), k = 1..d, so
        // 1/edf = (1/M) [1 + 2 Σ_{k=1}^{min(d, K-1)} (1 - k/r) rho(k)²], K = ceil(r); for
        // K > d this is the paper's (1/M)(a0 - a1/r), a0 = C(4d,2d)/C(2d,d)², a1 = d/2.
        let k_max = (r.ceil() as u32).saturating_sub(1).min(d);
        let c0 = binomial(2 * d, d);
        let sum: f64 = (1..=k_max)
            .map(|k| 2.0 * (1.0 - f64::from(k) / r) * (binomial(2 * d, d - k) / c0).powi(2))
            .sum();
        (1.0 + sum) / big_m
    };
    1.0 / inv
}

/// The x-filter of Greenhall's eq. 8: a finite factor F (m for unmodified variances, 1 for
/// modified) or its limit F → ∞.
#[derive(Clone, Copy)]
enum Filter {
    F(f64),
    Infinite,
}

/// Greenhall eq. 10: the basic sum
/// sz(0)² + (1 - J/M) sz(J/S)² + 2 Σ_{j=1}^{J-1} (1 - j/M) sz(j/S)².
fn basic_sum(j: f64, big_m: f64, s: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let term = |t: f64| sz(t, f, alpha, d).powi(2);
    let inner: f64 = (1..j as u64)
        .map(|jj| 2.0 * (1.0 - jj as f64 / big_m) * term(jj as f64 / s))
        .sum();
    term(0.0) + (1.0 - j / big_m) * term(j / s) + inner
}

/// Greenhall eq. 9: sz(t) = Σ_k (-1)^k C(2d, d+k) sx(t + k), k = -d..=d.
fn sz(t: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let d = d as i32;
    (-d..=d)
        .map(|k| {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            sign * binomial((2 * d) as u32, (d + k) as u32) * sx(t + f64::from(k), f, alpha)
        })
        .sum()
}

/// Greenhall eq. 8: sx(t) = F² (2 sw(t) - sw(t - 1/F) - sw(t + 1/F)), and sw(t, alpha + 2)
/// in the limit F → ∞.
fn sx(t: f64, f: Filter, alpha: i32) -> f64 {
    match f {
        Filter::Infinite => sw(t, alpha + 2),
        Filter::F(f) => {
            f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha))
        }
    }
}

/// Greenhall eq. 7: sw(t) = -|t| (alpha 2), t² ln|t| (1), |t|³ (0), t⁴ ln|t| (-1), |t|⁵ (-2),
/// t⁶ ln|t| (-3), |t|⁷ (-4); t ln|t| terms are 0 at t = 0.
fn sw(t: f64, alpha: i32) -> f64 {
    let a = t.abs();
    let log_term = |p: i32| if t == 0.0 { 0.0 } else { t.powi(p) * a.ln() };
    match alpha {
        2 => -a,
        1 => log_term(2),
        0 => a.powi(3),
        -1 => log_term(4),
        -2 => a.powi(5),
        -3 => log_term(6),
        _ => a.powi(7),
    }
}

/// Greenhall Table 1 (modified variances, J > J_max, r > d + 1): (a0, a1) by alpha and d.
fn table1(alpha: i32, d: u32) -> (f64, f64) {
    let row: [(f64, f64); 3] = match alpha {
        2 => [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 0.5),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        1 => [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        0 => [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        -1 => [(f64::NAN, f64::NAN), (1.048, 0.534), (1.180, 0.816)],
        _ => [(f64::NAN, f64::NAN), (1.302, 0.535), (1.175, 0.777)],
    };
    row[(d - 1) as usize]
}

/// Greenhall Table 2 (unmodified variances, J > J_max, r > d + 1): (a0, a1) by alpha and d.
fn table2(alpha: i32, d: u32) -> (f64, f64) {
    let row: [(f64, f64); 3] = match alpha {
        2 => [(1.5, 0.5), (35.0 / 18.0, 1.0), (231.0 / 100.0, 1.5)],
        1 => [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        0 => [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 0.5),
        ],
        -1 => [(f64::NAN, f64::NAN), (0.852, 0.375), (0.997, 0.617)],
        _ => [(f64::NAN, f64::NAN), (1.079, 0.368), (1.033, 0.607)],
    };
    row[(d - 1) as usize]
}

/// Greenhall Table 3 (unmodified, flicker PM): (b0, b1) by d.
fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

/// Binomial coefficient C(n, k) as f64 (small n only).
fn binomial(n: u32, k: u32) -> f64 {
    if k > n {
        return 0.0;
    }
    (0..k).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn chi2_bounds_use_the_chi_squared_quantiles() {
        // chi²(0.025, 10) = 3.246973, chi²(0.975, 10) = 20.483177 (standard tables).
        let (lo, hi) = chi2_bounds(1.0, 10.0, 0.95);
        assert!(close(lo, (10.0f64 / 20.483_177).sqrt(), 1e-6), "{lo}");
        assert!(close(hi, (10.0f64 / 3.246_973).sqrt(), 1e-6), "{hi}");
        // chi²(0.1587, 1) and chi²(0.8413, 1): the 1-sigma interval of a single degree.
        let (lo, hi) = chi2_bounds(2.0, 1.0, ONE_SIGMA);
        assert!(lo < 2.0 && hi > 2.0 * 4.0, "{lo} {hi}");
        assert!(chi2_bounds(1.0, 0.0, 0.5).0.is_nan());
        assert!(chi2_bounds(1.0, f64::NAN, 0.5).1.is_nan());
        assert!(chi2_bounds(1.0, 5.0, 1.0).0.is_nan());
    }

    #[test]
    fn edf_edge_cases() {
        // No terms, bad alpha: NaN, not a panic.
        assert!(edf(Estimator::Oadev, 0, 600, 1001).is_nan());
        assert!(edf(Estimator::Adev, 3, 1, 1001).is_nan());
        assert!(edf(Estimator::Mdev, 0, 0, 1001).is_nan());
        assert!(edf(Estimator::Hdev, 0, 1, 0).is_nan());
        // White FM, adev at m = 1: the EDF is close to the number of terms / (some constant)
        // and grows with N; all cases (small J, table branch, J_max branch) are finite.
        for est in Estimator::ALL {
            for alpha in -2..=2 {
                for m in [1, 2, 10, 40, 300] {
                    let e = edf(est, alpha, m, 1001);
                    assert!(e.is_finite() && e > 0.0, "{est} a={alpha} m={m}: {e}");
                    assert!(edf(est, alpha, m, 100_001) > e, "{est} a={alpha} m={m}");
                }
            }
        }
        // Non-overlapping white PM, M <= d (case 4 with K <= d): two terms of adev.
        let e = edf(Estimator::Adev, 2, 333, 1001);
        assert!(e.is_finite() && e > 0.0, "{e}");
        // Totdev white FM, SP 1065 Table 7: 1.5 N/m.
        assert!(close(edf(Estimator::Totdev, 0, 10, 1000), 150.0, 1e-12));
    }

    #[test]
    fn nearest_alpha_fills_gaps() {
        let f = [None, Some(1), None, None, Some(-2), None];
        let got: Vec<i32> = (0..f.len()).map(|k| fill_alpha(&f, k)).collect();
        assert_eq!(got, vec![1, 1, 1, -2, -2, -2]);
        assert_eq!(fill_alpha(&[None, None], 1), 0);
    }
}

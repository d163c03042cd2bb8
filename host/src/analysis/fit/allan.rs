//! The five-term IEEE-952 fit of an Allan variance curve: iteratively reweighted
//! non-negative least squares, the choice of the terms the data support, the points'
//! correlation model, the goodness of fit and the intervals ([`fit_allan_with`]).

use super::{
    B, FitError, FitOptions, Goodness, K, N, NoiseFit, Q, R, Support, TERMS, Term, TermSupport,
    basis_with,
};
use crate::analysis::low_pass::LowPass;
use crate::analysis::numerics::{invert_spd, mat_mul, nnls};
use crate::analysis::{Deviation, ci};
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

/// [`fit_allan_with`] with the default options (68.3 % intervals).
pub fn fit_allan(tau: &[f64], avar: &[f64], edf: &[f64]) -> Result<NoiseFit, FitError> {
    fit_allan_with(tau, avar, edf, &FitOptions::default())
}

/// Fits the five-term IEEE-952 model to an Allan variance curve.
///
/// **Estimate.** The model is linear in theta = (Q^2, N^2, B^2, K^2, R^2) >= 0. Each point's
/// estimator variance is `Var(avar_i) = 2 m_i^2 / edf_i` (chi-squared with edf_i degrees of
/// freedom, m_i the true AVAR), so the fit minimises `sum_i (avar_i - m_i)^2 / Var_i` subject to
/// theta >= 0 (Lawson–Hanson NNLS on the column-normalised weighted design, with Householder
/// QR for the sub-problems). The variances use the **model** value m_i, not the measured one,
/// iterated to convergence (IRLS): weighting by the measured value gives the points that
/// happen to fall low the most weight and biases the fit low. At that fixed point the fit is
/// the maximum-likelihood estimate for gamma-distributed (scaled chi-squared) points, whose
/// deviance (`deviance`) compares models.
///
/// **Which terms.** A term is kept only when the data support it: every subset of the five
/// terms is fitted on its own, a subset is adequate when its deviance is not significantly
/// above the full fit's (quasi-likelihood ratio scaled for the points' correlation,
/// `nested_p_value`; level [`FitOptions::detection_level`], 1 %), and the fit reported is
/// the adequate subset with the fewest terms (ties: without R, then least deviance) each of
/// whose terms is needed in it (dropping it raises the deviance significantly,
/// `lr_p_value`), if any (`select_terms`). The other terms are "not detected": value 0, lo 0
/// and hi the largest upper bound any adequate subset allows them. A fit whose Q exceeds
/// [`FitOptions::q_max`] (the bound the taus a fitted low-pass leaves out set, see
/// [`fit_deviation`]) is not adequate, and Q's interval stops at it. Without this, a
/// non-negative B or R that noise made positive takes its share from K. Measured on white
/// noise plus rate random walk (N = 1e-3, 2 h at 100 Hz, seeds 0..200 of
/// `tests/tests/fit_support.rs`'s simulation): at K = 1e-5 (the random walk owns the last 1.3
/// decades) B is claimed in 7 of 200 records, R in 1, Q in none, K is detected in 192 and its
/// mean bias is -6.5 % (-2.6 % where detected; the rest are records whose long-tau end is
/// better described by a flicker floor, where K is reported as 0); at K = 3e-5 and 1e-4 K is
/// detected in every record and within 1 %.
///
/// **Goodness.** [`Goodness`]: the weighted residual sum over its expectation under the
/// correlation model, with Satterthwaite's effective degrees of freedom and p-value
/// (`goodness_of_fit`); `poor()` below p = 0.001.
///
/// **Intervals.** Allan variances at neighbouring taus share most of their data, so they are
/// strongly correlated and the naive WLS covariance `(A^T W A)^-1` is too small by about the
/// ratio of points to effectively independent points. We use the sandwich covariance
/// `H^-1 (A^T W C W A) H^-1`, `H = A^T W A`, with a modelled correlation matrix C of the
/// estimates: each noise process contributes its share `f_it = A_it theta_t / m_i` of point i,
/// and a process-specific kernel in the tau ratio `r >= 1`,
///
/// ```text
/// rho_ik = sum_t sqrt(f_it f_kt) kappa_t(tau_k / tau_i)
/// kappa_Q = 0.45 + 0.55 r^-4, kappa_R = 1,
/// kappa_N = exp(-1.1 ln(r)^1.6), kappa_B = exp(-0.62 ln(r)^1.5), kappa_K = exp(-0.23 ln(r)^1.55)
/// ```
///
/// (each kernel is positive definite in ln tau, so C is too: `exp(-c |x|^a)` with
/// `0 < a <= 2` is the characteristic function of a symmetric stable law; Lévy, 1925). The
/// kernels were measured by Monte Carlo — overlapping AVAR at octave-spaced m of 300 records
/// of 2^16 samples of each pure noise type (`tests/data/fit/allan_correlation.py`):
/// neighbouring-octave correlations 0.54 / 0.16 / 0.03 at ratios 2 / 4 / 8 for white rate
/// noise, 0.88 / 0.67 / 0.49 for rate random walk, 0.70 / 0.32 / 0.14 for flicker, 0.44 /
/// 0.53 / 0.53 for quantization, and 1 for the rate ramp. The stable-law kernels meet them
/// within 0.02 (flicker, 0.70 / 0.36 / 0.16, within 0.04 on the correlated side); a power law in r that meets
/// the first octave falls too slowly to meet the third (white: 0.125 against 0.03). The
/// interval of theta_t is `theta_t +- z sigma_t` (z the two-sided
/// normal quantile of `confidence`), cut at 0 and mapped through the square root
/// (`interval`); a term not detected gets the `hi` of its fit together with the kept
/// terms (see above).
/// Why not a parametric bootstrap: drawing avar_i independently from scaled chi-squared has
/// the same flaw as the naive covariance (it ignores the correlation), and drawing them
/// correlated needs the same correlation model; the sandwich is deterministic and cheap.
///
/// Lack of fit widens them: every standard deviation is multiplied by the Birge ratio
/// `sqrt(max(1, reduced chi-square))` of [`Goodness`] (R. T. Birge, Phys. Rev. 40, 207,
/// 1932; the Particle Data Group's scale factor), so the intervals grow with the scatter the
/// model does not explain. They remain statistical: a model missing a process the data
/// contain (a tone, a Gauss-Markov bias) biases the terms beyond them — a poor goodness says
/// so.
pub fn fit_allan_with(
    tau: &[f64],
    avar: &[f64],
    edf: &[f64],
    opts: &FitOptions,
) -> Result<NoiseFit, FitError> {
    validate(tau, avar, edf, opts)?;
    let rows: Vec<[f64; TERMS]> = tau
        .iter()
        .map(|&t| basis_with(t, opts.low_pass.as_ref()))
        .collect();
    let fit_cols = |cols: &[usize]| {
        let (theta, sigma, iterations) = irls(&rows, avar, edf, cols, opts.max_iterations);
        Candidate {
            theta,
            sigma,
            iterations,
        }
    };
    let curve = Curve {
        tau,
        rows: &rows,
        avar,
        edf,
    };
    let adequate = select_terms(&curve, opts, &fit_cols);
    let Candidate {
        theta,
        ref sigma,
        iterations,
    } = adequate[0];
    let active: Vec<usize> = (0..TERMS).filter(|&j| theta[j] > 0.0).collect();
    let corr = correlation(tau, &rows, &theta);
    let goodness = goodness_of_fit(&rows, avar, sigma, &corr, &theta, &active);
    let inflate = goodness.birge_ratio;
    let z = Normal::standard().inverse_cdf(0.5 + opts.confidence / 2.0);
    // Term j in `model` or, when absent, in `model` refitted with it; with the columns.
    let with_term = |model: &Candidate, j: usize| -> (Candidate, Vec<usize>) {
        let mut cols: Vec<usize> = (0..TERMS).filter(|&t| model.theta[t] > 0.0).collect();
        if cols.contains(&j) {
            return (model.clone(), cols);
        }
        cols.push(j);
        cols.sort_unstable();
        (fit_cols(&cols), cols)
    };
    // Each term's evidence given the final model, or the final model with it added.
    let p_values: [f64; TERMS] = std::array::from_fn(|j| {
        let (with, cols) = with_term(&adequate[0], j);
        lr_p_value(&curve, &with, &cols, j, &fit_cols)
    });
    // The record's bound on Q caps its interval (`FitOptions::q_max`).
    let capped = |j: usize, t: Term| match opts.q_max {
        Some(q) if j == Q => Term {
            hi: t.hi.min(q),
            ..t
        },
        _ => t,
    };
    let term = |j: usize| -> Term {
        if active.contains(&j) {
            let sd = sandwich_sd(&rows, sigma, &corr, &active, j);
            return capped(j, interval(theta[j], sd * inflate, z, opts.confidence));
        }
        // Not detected: 0, with the largest upper bound any adequate model allows (where it
        // stands in for another term, its bound is not held down by that term).
        let hi = adequate
            .iter()
            .map(|model| {
                let (with, cols) = with_term(model, j);
                let corr = correlation(tau, &rows, &with.theta);
                let sd = sandwich_sd(&rows, &with.sigma, &corr, &cols, j);
                interval(with.theta[j], sd * inflate, z, opts.confidence).hi
            })
            .fold(0.0, f64::max);
        capped(
            j,
            Term {
                value: 0.0,
                lo: 0.0,
                hi,
            },
        )
    };
    let support = std::array::from_fn(|j| Support {
        detected: active.contains(&j),
        p_value: p_values[j],
    });
    let residual = weighted_rss(&rows, avar, sigma, &theta);
    let dof = (tau.len() as f64 - active.len() as f64).max(1.0);
    let total_corr: f64 = corr.iter().flatten().sum();
    Ok(NoiseFit {
        q: term(Q),
        n: term(N),
        b: term(B),
        k: term(K),
        r: term(R),
        confidence: opts.confidence,
        points: tau.len(),
        effective_points: (tau.len() * tau.len()) as f64 / total_corr,
        reduced_chi2: residual / dof,
        iterations,
        tau_min: tau.first().copied().unwrap_or(f64::NAN),
        low_pass: opts.low_pass.clone(),
        goodness,
        support: TermSupport::from_array(support),
    })
}

/// `sum_i ((y_i - a_i . theta) / sigma_i)^2`.
fn weighted_rss(rows: &[[f64; TERMS]], y: &[f64], sigma: &[f64], theta: &[f64; TERMS]) -> f64 {
    rows.iter()
        .zip(y)
        .zip(sigma)
        .map(|((a, y), s)| ((y - dot(a, theta)) / s).powi(2))
        .sum()
}

/// Goodness of fit of the model `theta` (terms `active`) with the points' modelled
/// correlation `corr` (see [`fit_allan_with`]).
///
/// The standardised residuals `r_i = (avar_i - m_i) / sigma_i` of a weighted least-squares
/// fit are `r = (I - P) e`, `P = G (G^T G)^-1 G^T` the hat matrix of the whitened design G
/// and `e ~ (0, C)`, so `S = r^T r` has mean `tr(M)` and variance `2 tr(M^2)` with
/// `M = (I - P) C (I - P)` (quadratic forms of normal vectors). Satterthwaite's
/// approximation (F. E. Satterthwaite, Biometrics Bulletin 2, 1946; Box, Ann. Math. Stat.
/// 25, 1954) takes `S ~ g chi2(h)` with `g = tr(M^2) / tr(M)` and `h = tr(M)^2 / tr(M^2)`:
/// the reduced chi-square is `S / tr(M)`, the p-value `P(chi2(h) > S / g)`.
///
/// Why not `r^T C^-1 r` over `points - terms`: the fit is weighted, not generalised, least
/// squares, so that form's expectation is not `points - terms`; and inverting C makes the
/// statistic hinge on the smallest eigenvalues of a correlation model whose kernels are
/// rounded Monte-Carlo fits. `S` uses C only through two traces.
fn goodness_of_fit(
    rows: &[[f64; TERMS]],
    avar: &[f64],
    sigma: &[f64],
    corr: &[Vec<f64>],
    theta: &[f64; TERMS],
    active: &[usize],
) -> Goodness {
    let n = rows.len();
    let s = weighted_rss(rows, avar, sigma, theta);
    let hat = hat_matrix(rows, sigma, active);
    // Q = I - P; M = Q C Q.
    let q: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|k| f64::from(u8::from(i == k)) - hat[i][k])
                .collect()
        })
        .collect();
    let qc = mat_mul(&q, corr);
    let m = mat_mul(&qc, &q);
    let tr1: f64 = (0..n).map(|i| m[i][i]).sum();
    let tr2: f64 = m.iter().flatten().map(|v| v * v).sum();
    if !(tr1 > 1e-9 && tr2 > 0.0) {
        return Goodness {
            reduced_chi2: f64::NAN,
            dof: 0.0,
            p_value: 1.0,
            birge_ratio: 1.0,
        };
    }
    let dof = tr1 * tr1 / tr2;
    let reduced_chi2 = s / tr1;
    let p_value = ChiSquared::new(dof).map_or(1.0, |c| c.sf(reduced_chi2 * dof));
    Goodness {
        reduced_chi2,
        dof,
        p_value,
        birge_ratio: reduced_chi2.max(1.0).sqrt(),
    }
}

/// `P = G (G^T G)^-1 G^T` of the whitened design over `cols` (zero when those columns
/// cannot be separated).
// Dense small-matrix algebra reads best with explicit indices.
#[allow(clippy::needless_range_loop)]
fn hat_matrix(rows: &[[f64; TERMS]], sigma: &[f64], cols: &[usize]) -> Vec<Vec<f64>> {
    let (g, _) = scaled_design(rows, sigma, cols);
    let n = g.len();
    let k = cols.len();
    let mut h = vec![vec![0.0; k]; k];
    for gi in &g {
        for a in 0..k {
            for b in 0..k {
                h[a][b] += gi[a] * gi[b];
            }
        }
    }
    let Some(hinv) = invert_spd(&h) else {
        return vec![vec![0.0; n]; n];
    };
    let gh = mat_mul(&g, &hinv);
    (0..n)
        .map(|i| {
            (0..n)
                .map(|l| (0..k).map(|a| gh[i][a] * g[l][a]).sum())
                .collect()
        })
        .collect()
}

/// The fit of the terms the data support: the subset of the five terms with the fewest
/// non-zero terms whose fit is not significantly worse than the full fit's (at the detection
/// level; [`nested_p_value`] over the full fit's non-zero terms the subset lacks, with the
/// full fit's correlation model and Birge ratio) and each of whose terms is needed in it
/// ([`lr_p_value`] below the level), the one with the smallest deviance among subsets of
/// that size, those without R first. Each subset is fitted on its own ([`irls`] with its own
/// model-based weights) and compared by the deviance.
///
/// Why all subsets rather than removing the least significant term one at a time: B, K and
/// R are nearly collinear over the last decade of a curve (flat plus quadratic looks
/// linear), so each alone is insignificant while the others stand in for it; one at a time,
/// the first removal can be the term the data need, after which the rest only degrades.
/// Why R last: a rate random walk's AVAR (`K^2 tau / 3`) and a ramp's (`R^2 tau^2 / 2`)
/// differ by one power of tau, and where only the last, least-determined decade shows
/// either, every random-walk realisation whose long-tau end happens to bend upwards would
/// otherwise be read as a deterministic ramp (1 record in 20 on white noise plus random
/// walk); R is claimed when no model of as many terms without it explains the curve.
/// Why the deviance and not the weighted residual sum with shared weights: the weights
/// follow the model (a model without K predicts small long-tau variances and so small
/// sigmas there), and shared weights hide exactly the misfit the test is for.
/// Why subsets of all five terms and not only of the full fit's non-zero ones: the
/// non-negative full fit can give K's share of the last decade to B plus R (flat plus
/// quadratic looks linear) and pin K at 0, after which no candidate has K.
/// Why a term's need is tested by the likelihood ratio and not by its Wald statistic
/// `theta_j / sd_j`: a term's sd comes from the variances of the points it dominates, which
/// grow with it (`sigma_i = m_i sqrt(2 / edf_i)`), so `sd_j` is proportional to theta_j and
/// the Wald z saturates at about `sqrt(edf / 2)` of those taus however large the term is (the
/// Hauck-Donner effect; W. W. Hauck and A. Donner, JASA 72, 1977). On white noise plus
/// random walk (N = 1e-3, K = 1e-5, 2 h at 100 Hz), where K owns the last 1.3 decades, K's
/// Wald p came out 0.011 on a record where dropping K raised the deviance from 56 to 645,
/// and a white-plus-flicker model with the worse deviance (70) was chosen. The likelihood
/// ratio compares the model with and without the term, each under its own variances.
fn select_terms(
    curve: &Curve,
    opts: &FitOptions,
    fit_cols: &dyn Fn(&[usize]) -> Candidate,
) -> Vec<Candidate> {
    let Curve {
        tau,
        rows,
        avar,
        edf,
    } = *curve;
    let all = fit_cols(&[Q, N, B, K, R]);
    let full: Vec<usize> = (0..TERMS).filter(|&j| all.theta[j] > 0.0).collect();
    let corr = correlation(tau, rows, &all.theta);
    let birge = goodness_of_fit(rows, avar, &all.sigma, &corr, &all.theta, &full).birge_ratio;
    let cov = Covariance::new(rows, &all.sigma, &corr, &full);
    let deviance_full = deviance(rows, avar, edf, &all.theta);
    // (adequate, (size, has R, deviance), fit) of every subset.
    let mut fits: Vec<(bool, (usize, bool, f64), Candidate)> = Vec::new();
    for mask in 1u32..(1 << TERMS) {
        let subset: Vec<usize> = (0..TERMS).filter(|&j| mask & (1 << j) != 0).collect();
        let fitted = if subset == full {
            all.clone()
        } else {
            fit_cols(&subset)
        };
        let kept: Vec<usize> = (0..TERMS).filter(|&j| fitted.theta[j] > 0.0).collect();
        let dropped: Vec<usize> = (0..full.len())
            .filter(|&c| !kept.contains(&full[c]))
            .collect();
        let dev = deviance(rows, avar, edf, &fitted.theta);
        let p = nested_p_value(dev - deviance_full, cov.as_ref(), &dropped, birge);
        let adequate =
            (dropped.is_empty() || p >= opts.detection_level) && within_q_max(&fitted, opts);
        fits.push((adequate, (kept.len(), kept.contains(&R), dev), fitted));
    }
    fits.sort_by(|a, b| {
        let (ka, kb) = (a.1, b.1);
        (ka.0, ka.1).cmp(&(kb.0, kb.1)).then(ka.2.total_cmp(&kb.2))
    });
    // The first adequate fit whose every term is needed in it (adequacy compares with the
    // full fit, where a term can carry weight that a smaller model does without); else the
    // first adequate one: a fit whose terms are all needed but which the curve rejects
    // trades a weak term for a reduced chi-square in the hundreds (two gyro axes of the
    // MPU-6050 record in tests/data).
    let significant = |c: &Candidate| {
        let cols: Vec<usize> = (0..TERMS).filter(|&j| c.theta[j] > 0.0).collect();
        cols.iter()
            .all(|&j| lr_p_value(curve, c, &cols, j, fit_cols) < opts.detection_level)
    };
    let chosen = fits
        .iter()
        .position(|(adequate, _, c)| *adequate && significant(c))
        .or_else(|| fits.iter().position(|f| f.0));
    let first = chosen.map(|i| fits.remove(i).2);
    // Without an adequate fit, the best of those within the record's bound on Q.
    let fallback = fits
        .iter()
        .filter(|f| within_q_max(&f.2, opts))
        .min_by(|a, b| a.1.2.total_cmp(&b.1.2))
        .map(|f| f.2.clone());
    let adequate = fits.into_iter().filter(|f| f.0).map(|f| f.2);
    let mut out: Vec<Candidate> = first.into_iter().chain(adequate).collect();
    if out.is_empty() {
        out.push(fallback.unwrap_or(all));
    }
    out
}

/// Whether a fit's Q is within [`FitOptions::q_max`].
fn within_q_max(fit: &Candidate, opts: &FitOptions) -> bool {
    opts.q_max.is_none_or(|q| fit.theta[Q] <= q * q)
}

/// p-value of term j in `model` (its non-zero terms `cols`, which contain j) by the
/// likelihood ratio: the increase of the deviance when j is dropped and the rest refitted,
/// tested by [`nested_p_value`] with `model`'s correlation model and Birge ratio; 1 when
/// theta_j is 0.
fn lr_p_value(
    curve: &Curve,
    model: &Candidate,
    cols: &[usize],
    j: usize,
    fit_cols: &dyn Fn(&[usize]) -> Candidate,
) -> f64 {
    if model.theta[j] <= 0.0 {
        return 1.0;
    }
    let rest: Vec<usize> = cols.iter().copied().filter(|&c| c != j).collect();
    let without = if rest.is_empty() {
        [0.0; TERMS]
    } else {
        fit_cols(&rest).theta
    };
    let rows = curve.rows;
    let deviance_of = |theta: &[f64; TERMS]| deviance(rows, curve.avar, curve.edf, theta);
    let delta = deviance_of(&without) - deviance_of(&model.theta);
    let corr = correlation(curve.tau, rows, &model.theta);
    let birge =
        goodness_of_fit(rows, curve.avar, &model.sigma, &corr, &model.theta, cols).birge_ratio;
    let cov = Covariance::new(rows, &model.sigma, &corr, cols);
    let at = cols.iter().position(|&c| c == j).unwrap_or(0);
    nested_p_value(delta, cov.as_ref(), &[at], birge)
}

/// The curve being fitted: taus (s), the model's basis rows, the Allan variances and their
/// EDFs.
#[derive(Clone, Copy)]
struct Curve<'a> {
    tau: &'a [f64],
    rows: &'a [[f64; TERMS]],
    avar: &'a [f64],
    edf: &'a [f64],
}

/// One fitted subset of the terms: theta (zero outside the subset), the points' standard
/// deviations under it, and the reweighting iterations it took.
#[derive(Debug, Clone)]
struct Candidate {
    theta: [f64; TERMS],
    sigma: Vec<f64>,
    iterations: usize,
}

/// The deviance of the model `theta` for Allan variances distributed as
/// `m_i chi2(edf_i) / edf_i`, i.e. gamma with shape `edf_i / 2` and mean `m_i`:
/// `D = sum_i edf_i ((y_i - m_i) / m_i - ln(y_i / m_i))` (McCullagh & Nelder, "Generalized
/// Linear Models", 2nd ed., 1989, Table 2.1). [`irls`] maximises this likelihood (its fixed
/// point is the gamma quasi-score equation), and near the fit `D` is the weighted residual
/// sum. `m_i` is floored as in [`irls`].
fn deviance(rows: &[[f64; TERMS]], avar: &[f64], edf: &[f64], theta: &[f64; TERMS]) -> f64 {
    rows.iter()
        .zip(avar)
        .zip(edf)
        .map(|((a, &y), &e)| {
            let m = dot(a, theta).max(MODEL_FLOOR * y);
            e * ((y - m) / m - (y / m).ln())
        })
        .sum()
}

/// p-value of the hypothesis that the terms at positions `dropped` of the covariance's
/// columns are 0, from the increase `delta` of the weighted residual sum when they are
/// removed and the rest refitted with the same weights.
///
/// In a linear model `delta = theta_D^T (V_naive,DD)^-1 theta_D`; with correlated points
/// `theta_D ~ N(0, V_sandwich,DD)`, so `delta` is a sum of `lambda_k chi2(1)`, lambda the
/// eigenvalues of `A = V_naive,DD^-1 V_sandwich,DD` (the Rao–Scott correction of a
/// chi-square test under correlated sampling: J. N. K. Rao and A. J. Scott, JASA 76, 1981),
/// further scaled by the squared Birge ratio b. One term: `T = delta / (lambda b^2)` is
/// `(theta_j / sd_j)^2` with the sandwich sd, and on the boundary `theta_j = 0` its null
/// distribution is `0.5 chi2(0) + 0.5 chi2(1)` (S. G. Self and K.-Y. Liang, JASA 82, 1987):
/// `p = 1 - Phi(sqrt(T))`. Several terms: Satterthwaite's `g chi2(h)` with
/// `g = tr(A^2) / tr(A)`, `h = tr(A)^2 / tr(A^2)` (the boundary ignored, which errs towards
/// larger p, i.e. towards not claiming terms). 1 when the columns cannot be separated.
fn nested_p_value(delta: f64, cov: Option<&Covariance>, dropped: &[usize], birge: f64) -> f64 {
    let Some(cov) = cov.filter(|_| !dropped.is_empty()) else {
        return 1.0;
    };
    let block = |m: &[Vec<f64>]| -> Vec<Vec<f64>> {
        dropped
            .iter()
            .map(|&a| dropped.iter().map(|&b| m[a][b]).collect())
            .collect()
    };
    let Some(naive_inv) = invert_spd(&block(&cov.naive)) else {
        return 1.0;
    };
    let a = mat_mul(&naive_inv, &block(&cov.sandwich));
    let d = dropped.len();
    let tr1: f64 = (0..d).map(|i| a[i][i]).sum();
    let tr2: f64 = (0..d)
        .flat_map(|i| (0..d).map(move |k| (i, k)))
        .map(|(i, k)| a[i][k] * a[k][i])
        .sum();
    if !(tr1 > 0.0 && tr2 > 0.0 && tr1.is_finite() && tr2.is_finite()) {
        return 1.0;
    }
    let t = delta.max(0.0) / (birge * birge);
    if d == 1 {
        return Normal::standard().sf((t / tr1).sqrt());
    }
    let (g, h) = (tr2 / tr1, tr1 * tr1 / tr2);
    ChiSquared::new(h).map_or(1.0, |c| c.sf(t / g))
}

/// The five-term fit of an overlapping (or non-overlapping) Allan deviation curve computed
/// from `n_phase` phase points, with each point's EDF taken from the **fitted model**: at
/// every tau the dominant term sets the noise type (Q: white PM, alpha 2; N: white FM, 0;
/// B: flicker FM, -1; K and R: random-walk FM, -2) and Greenhall's EDF for it
/// ([`crate::analysis::ci::edf`]) sets the point's variance. Starting from white FM, fit and
/// EDFs are iterated until the noise types stop changing (at most 5 rounds).
///
/// Taus before [`FitOptions::tau_min`] or a fitted low-pass's first reliable tau are left
/// out of the fit, and bound Q (`q_bound`).
///
/// Why not the per-tau noise identification of the confidence intervals: at the longest taus
/// it rests on a handful of clusters and often names the wrong type, whose larger EDF then
/// gives the noisiest points the most weight. On simulated white + flicker + random walk
/// (`tests/tests/fit_coverage.rs`) that biased K low by ~15 % and let a spurious flicker
/// floor appear on pure white noise in 18 % of records; with model-based EDFs both go away.
pub fn fit_deviation(
    dev: &Deviation,
    n_phase: usize,
    opts: &FitOptions,
) -> Result<NoiseFit, FitError> {
    // A fitted low-pass's shape is reliable only from its `first_tau` on (see there).
    let start = opts
        .tau_min
        .or_else(|| opts.low_pass.as_ref().map(LowPass::first_tau));
    let first = start.map_or(0, |t| {
        dev.tau
            .iter()
            .position(|&x| x >= t * (1.0 - 1e-9))
            .unwrap_or(dev.tau.len())
    });
    let bound = q_bound(dev, first, n_phase);
    let bounded;
    let opts = match bound {
        Some(q) if opts.q_max.is_none_or(|given| q < given) => {
            bounded = FitOptions {
                q_max: Some(q),
                ..opts.clone()
            };
            &bounded
        }
        _ => opts,
    };
    let (tau, m) = (&dev.tau[first..], &dev.m[first..]);
    let avar: Vec<f64> = dev.dev[first..].iter().map(|s| s * s).collect();
    let edf_for = |alpha: &[i32]| -> Vec<f64> {
        m.iter()
            .zip(alpha)
            .map(|(&m, &a)| ci::edf(dev.estimator, a, m, n_phase))
            .collect()
    };
    let mut alpha = vec![0; m.len()];
    let mut fit = fit_allan_with(tau, &avar, &edf_for(&alpha), opts)?;
    for _ in 0..5 {
        let next: Vec<i32> = tau.iter().map(|&t| fit.dominant_alpha(t)).collect();
        if next == alpha {
            break;
        }
        alpha = next;
        fit = fit_allan_with(tau, &avar, &edf_for(&alpha), opts)?;
    }
    Ok(fit)
}

/// Confidence of the upper limits on the Allan variance that bound Q.
const Q_BOUND_CONFIDENCE: f64 = 0.999;

/// The largest Q the taus before `first` allow: quantization enters after the sensor's
/// filter, so its `3 Q^2 / tau^2` (IEEE 952 Table C.1) is at most the Allan variance at
/// every tau, `Q <= tau sqrt(avar_hi / 3)`, with `avar_hi` the measured value's upper
/// limit at [`Q_BOUND_CONFIDENCE`] (chi-square). Its degrees of freedom are the white-FM
/// EDF over the first fitted averaging factor: the filter correlates samples over about the
/// lags it leaves out, so the record holds fewer independent differences there than white
/// noise would.
fn q_bound(dev: &Deviation, first: usize, n_phase: usize) -> Option<f64> {
    let lags = dev
        .m
        .get(first)
        .or(dev.m.last())
        .copied()
        .unwrap_or(1)
        .max(1) as f64;
    (0..first.min(dev.tau.len()))
        .filter(|&i| dev.dev[i] > 0.0)
        .map(|i| {
            let edf = (ci::edf(dev.estimator, 0, dev.m[i], n_phase) / lags).max(1.0);
            let upper = edf / chi_square_quantile(edf, 1.0 - Q_BOUND_CONFIDENCE);
            dev.tau[i] * (dev.dev[i] * dev.dev[i] * upper / 3.0).sqrt()
        })
        // A bound that is not a number bounds nothing (and a negative NaN would sort first).
        .filter(|q| q.is_finite())
        .min_by(f64::total_cmp)
}

/// The `p` quantile of chi-square with `dof` degrees of freedom: statrs' inversion, or where
/// it fails (it returns NaN at 1 and 1.37 degrees of freedom for p = 0.001, which voided the
/// Q bound of every record whose fit starts a thousand samples in), bisection of its CDF.
fn chi_square_quantile(dof: f64, p: f64) -> f64 {
    let Ok(chi2) = ChiSquared::new(dof) else {
        return f64::NAN;
    };
    let exact = chi2.inverse_cdf(p);
    if exact.is_finite() {
        return exact;
    }
    // The CDF is increasing; its quantiles lie within (0, dof + 40 sqrt(dof) + 100).
    let (mut lo, mut hi) = (0.0, dof + 40.0 * dof.sqrt() + 100.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2.cdf(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

fn validate(tau: &[f64], avar: &[f64], edf: &[f64], opts: &FitOptions) -> Result<(), FitError> {
    if tau.len() != avar.len() || tau.len() != edf.len() {
        return Err(FitError::LengthMismatch {
            tau: tau.len(),
            avar: avar.len(),
            edf: edf.len(),
        });
    }
    if tau.len() < 2 {
        return Err(FitError::TooFewPoints(tau.len()));
    }
    for (what, values) in [("tau", tau), ("avar", avar), ("edf", edf)] {
        if let Some((index, &value)) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v > 0.0))
        {
            return Err(FitError::NotPositive { what, index, value });
        }
    }
    if !(opts.confidence > 0.0 && opts.confidence < 1.0) {
        return Err(FitError::BadConfidence(opts.confidence));
    }
    if !(opts.detection_level > 0.0 && opts.detection_level < 1.0) {
        return Err(FitError::BadDetectionLevel(opts.detection_level));
    }
    Ok(())
}

fn dot(a: &[f64; TERMS], theta: &[f64; TERMS]) -> f64 {
    a.iter().zip(theta).map(|(x, y)| x * y).sum()
}

/// Smallest model AVAR, as a fraction of the measured one, that weights and deviances use.
const MODEL_FLOOR: f64 = 1e-3;

/// Iteratively reweighted NNLS. Returns theta, the final standard deviations
/// `sigma_i = m_i sqrt(2 / edf_i)` (model-based) and the iterations used.
fn irls(
    rows: &[[f64; TERMS]],
    avar: &[f64],
    edf: &[f64],
    cols: &[usize],
    max_iterations: usize,
) -> ([f64; TERMS], Vec<f64>, usize) {
    let sd = |m: &[f64]| -> Vec<f64> {
        m.iter()
            .zip(edf)
            .zip(avar)
            // The floor keeps a weight finite where the model is (nearly) zero.
            .map(|((m, e), y)| m.max(MODEL_FLOOR * y) * (2.0 / e).sqrt())
            .collect()
    };
    let mut sigma = sd(avar);
    let mut theta = [0.0; TERMS];
    let mut iterations = 0;
    while iterations < max_iterations.max(1) {
        iterations += 1;
        theta = weighted_nnls(rows, avar, &sigma, cols);
        let model: Vec<f64> = rows.iter().map(|a| dot(a, &theta)).collect();
        let next = sd(&model);
        let change = next
            .iter()
            .zip(&sigma)
            .map(|(a, b)| (a / b - 1.0).abs())
            .fold(0.0, f64::max);
        sigma = next;
        if change < 1e-10 {
            break;
        }
    }
    (theta, sigma, iterations)
}

/// min sum_i ((y_i - a_i . theta) / sigma_i)^2 subject to theta >= 0 and theta_j = 0 outside
/// `cols`, solved on the design with unit-norm columns (the basis spans many decades) and
/// mapped back.
fn weighted_nnls(rows: &[[f64; TERMS]], y: &[f64], sigma: &[f64], cols: &[usize]) -> [f64; TERMS] {
    let (g, norms) = scaled_design(rows, sigma, cols);
    let b: Vec<f64> = y.iter().zip(sigma).map(|(y, s)| y / s).collect();
    let phi = nnls(&g, &b);
    let mut theta = [0.0; TERMS];
    for ((&j, p), norm) in cols.iter().zip(phi).zip(norms) {
        theta[j] = p / norm;
    }
    theta
}

/// Rows `a_i[cols] / sigma_i`, each column divided by its norm; returns the matrix (row-major,
/// `cols.len()` wide) and the norms.
fn scaled_design(
    rows: &[[f64; TERMS]],
    sigma: &[f64],
    cols: &[usize],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut norms = vec![0.0; cols.len()];
    for (a, s) in rows.iter().zip(sigma) {
        for (c, &j) in cols.iter().enumerate() {
            norms[c] += (a[j] / s).powi(2);
        }
    }
    norms
        .iter_mut()
        .for_each(|n| *n = n.sqrt().max(f64::MIN_POSITIVE));
    let g = rows
        .iter()
        .zip(sigma)
        .map(|(a, s)| {
            cols.iter()
                .enumerate()
                .map(|(c, &j)| a[j] / s / norms[c])
                .collect()
        })
        .collect();
    (g, norms)
}

/// Correlation kernel of AVAR estimates of process `t` at tau ratio `r >= 1` (see
/// [`fit_allan_with`] for the measurements behind the numbers).
fn kernel(t: usize, r: f64) -> f64 {
    match t {
        Q => 0.45 + 0.55 * r.powi(-4),
        N => (-1.1 * r.ln().powf(1.6)).exp(),
        B => (-0.62 * r.ln().powf(1.5)).exp(),
        K => (-0.23 * r.ln().powf(1.55)).exp(),
        _ => 1.0,
    }
}

/// The modelled correlation matrix of the AVAR estimates (see [`fit_allan_with`]).
fn correlation(tau: &[f64], rows: &[[f64; TERMS]], theta: &[f64; TERMS]) -> Vec<Vec<f64>> {
    let shares: Vec<[f64; TERMS]> = rows
        .iter()
        .map(|a| {
            let m = dot(a, theta);
            if m > 0.0 {
                std::array::from_fn(|t| a[t] * theta[t] / m)
            } else {
                std::array::from_fn(|t| if t == N { 1.0 } else { 0.0 })
            }
        })
        .collect();
    (0..tau.len())
        .map(|i| {
            (0..tau.len())
                .map(|k| {
                    let r = (tau[i] / tau[k]).max(tau[k] / tau[i]);
                    (0..TERMS)
                        .map(|t| (shares[i][t] * shares[k][t]).sqrt() * kernel(t, r))
                        .sum()
                })
                .collect()
        })
        .collect()
}

/// Covariances of the weighted least-squares estimate over the columns `cols`, on the
/// column-normalised design (theta_c times the column's norm): the naive `H^-1` and the
/// sandwich `H^-1 (G^T C G) H^-1`, `H = G^T G`, with the column norms. None when those
/// columns cannot be separated by the data.
struct Covariance {
    naive: Vec<Vec<f64>>,
    sandwich: Vec<Vec<f64>>,
    norms: Vec<f64>,
}

impl Covariance {
    // Dense small-matrix algebra reads best with explicit indices.
    #[allow(clippy::needless_range_loop)]
    fn new(
        rows: &[[f64; TERMS]],
        sigma: &[f64],
        corr: &[Vec<f64>],
        cols: &[usize],
    ) -> Option<Covariance> {
        let (g, norms) = scaled_design(rows, sigma, cols);
        let k = cols.len();
        let gc = mat_mul(corr, &g); // C G
        let mut h = vec![vec![0.0; k]; k];
        let mut m = vec![vec![0.0; k]; k];
        for (gi, gci) in g.iter().zip(&gc) {
            for a in 0..k {
                for c in 0..k {
                    h[a][c] += gi[a] * gi[c];
                    m[a][c] += gi[a] * gci[c];
                }
            }
        }
        let naive = invert_spd(&h)?;
        let sandwich = mat_mul(&mat_mul(&naive, &m), &naive);
        Some(Covariance {
            naive,
            sandwich,
            norms,
        })
    }

    /// Standard deviation of the `c`-th column's theta from the sandwich covariance.
    fn sd(&self, c: usize) -> f64 {
        self.sandwich[c][c].max(0.0).sqrt() / self.norms[c]
    }
}

/// Standard deviation of theta_j from the sandwich covariance over the columns `cols`
/// (which contain j); infinite when those columns cannot be separated by the data.
fn sandwich_sd(
    rows: &[[f64; TERMS]],
    sigma: &[f64],
    corr: &[Vec<f64>],
    cols: &[usize],
    j: usize,
) -> f64 {
    let c = cols.iter().position(|&x| x == j).unwrap_or(0);
    Covariance::new(rows, sigma, corr, cols).map_or(f64::INFINITY, |cov| cov.sd(c))
}

/// The interval of a coefficient from that of its square theta (standard deviation `sd`).
///
/// A fitted theta is a weighted sum of chi-squared-distributed AVAR estimates, so it is
/// itself approximately `theta chi2(nu) / nu` with Satterthwaite's `nu = 2 theta^2 / sd^2` —
/// the same approximation behind the Allan deviation's own chi-squared intervals:
/// `[nu theta / chi2_{(1+c)/2}(nu), nu theta / chi2_{(1-c)/2}(nu)]`, longer upwards for small
/// nu. Because theta may also be a difference of estimates (when terms compete), whose
/// distribution is closer to normal and can reach 0, the interval used is the union of that
/// one and the normal `theta +- z sd` cut at 0 (the two agree for large nu). A theta pinned at
/// 0 gets `[0, z sd]`. Square roots give the coefficient's interval.
fn interval(theta: f64, sd: f64, z: f64, confidence: f64) -> Term {
    let value = theta.sqrt();
    let nu = 2.0 * theta * theta / (sd * sd);
    let normal = ((theta - z * sd).max(0.0), theta + z * sd);
    let (lo, hi) = if theta <= 0.0 || !sd.is_finite() || !(1e-3..=1e7).contains(&nu) {
        normal
    } else {
        match ChiSquared::new(nu) {
            Ok(chi2) => (
                normal
                    .0
                    .min(nu * theta / chi2.inverse_cdf(0.5 + confidence / 2.0)),
                normal
                    .1
                    .max(nu * theta / chi2.inverse_cdf(0.5 - confidence / 2.0)),
            ),
            Err(_) => normal,
        }
    };
    Term {
        value,
        lo: lo.max(0.0).sqrt().min(value),
        hi: hi.sqrt().max(value),
    }
}

#[cfg(test)]
mod quantile_tests {
    use super::*;

    /// Against closed forms: chi-square(1) is a squared standard normal, so its p quantile
    /// is `Phi^-1((1 + p) / 2)^2`; chi-square(2) is exponential with mean 2, `-2 ln(1 - p)`.
    /// statrs' own inversion returns NaN at 1 degree of freedom for p = 0.001.
    #[test]
    fn chi_square_quantiles_match_closed_forms() {
        for p in [0.001, 0.01, 0.5, 0.999] {
            let z = Normal::standard().inverse_cdf(0.5 + p / 2.0);
            let one = chi_square_quantile(1.0, p);
            assert!(
                (one / (z * z) - 1.0).abs() < 1e-6,
                "p {p}: {one} against {}",
                z * z
            );
            let two = chi_square_quantile(2.0, p);
            let exact = -2.0 * (1.0 - p).ln();
            assert!(
                (two / exact - 1.0).abs() < 1e-6,
                "p {p}: {two} against {exact}"
            );
        }
    }
}

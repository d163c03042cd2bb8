//! Standard errors of a slow sinusoid's frequency and amplitude under the noise model.
//!
//! **The estimator.** A slow line is measured by least squares beside an offset and a slope
//! ([`crate::analysis::lines::tone_near`]): `x_t ~ c0 + c1 u_t + a cos(w t_c) + b sin(w t_c)`,
//! `t_c` the sample index about the record's centre, `w` the frequency maximising the
//! periodogram of the detrended series. Linearised at the estimate (Gauss-Newton), every
//! parameter is a linear functional of the noise, `theta_hat - theta = r^T e`, with `r` the
//! parameter's row of `(X^T X)^-1 X^T` and `X` the columns `1`, `u`, `cos w t_c`, `sin w t_c`
//! and the derivative in `w`, `t_c (b cos w t_c - a sin w t_c)`; the amplitude `A =
//! hypot(a, b)` moves by `(a da + b db) / A`.
//!
//! **The variance.** `var(theta_hat) = r^T Sigma r`, Sigma the noise model's covariance. In
//! the orthonormal DCT-II basis every term of the model is diagonal (see [`super::cosine`]),
//! so `var = sum_k c_k(r)^2 v_k` with `c_k(r)` the coefficients of `r` and `v_k` the model's
//! variance of coefficient k. The random walk's unbounded variance at k = 0 never enters:
//! `r` is orthogonal to the offset column. The coefficients above the view's highest
//! (half the sample rate's half) take the variance there, by Parseval on what of `|r|^2`
//! they hold; a slow sinusoid's rows hold almost none of it.
//!
//! Under white noise alone this is the Cramer-Rao bound of a sinusoid in white noise (Kay,
//! "Fundamentals of Statistical Signal Processing: Estimation Theory", 1993, example 3.14):
//! `sd(A) = sqrt(S / T)` and `sd(f) = sqrt(12 S / T^3) / (2 pi A)`, S the one-sided PSD
//! (test `white_noise_gives_the_cramer_rao_bound`). Under a random walk and flicker it adds
//! what leaks from lower frequencies through the estimator's window, which at a few cycles
//! per record is most of the error.

use super::cosine::{dct2, model_variances};
use crate::analysis::low_pass::LowPass;
use crate::analysis::numerics::invert_spd;
use crate::sim::noise::NoiseTerms;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// `r^T Sigma r` for a row `r` orthogonal to the constant, Sigma diagonal in the DCT-II
/// basis with `variances` of coefficients 1..=kmax, the last one standing for all above.
fn quadratic_form(r: &[f64], variances: &[f64]) -> f64 {
    let kmax = variances.len();
    let c = dct2(r, kmax);
    let held: f64 = c.iter().map(|v| v * v).sum();
    let total: f64 = r.iter().map(|v| v * v).sum();
    let beyond = (total - held).max(0.0);
    c.iter().zip(variances).map(|(c, v)| c * c * v).sum::<f64>()
        + beyond * variances.last().copied().unwrap_or(0.0)
}

/// The standard errors (`"freq_hz"`, Hz; `"amplitude"`, u) of the sinusoid at `freq_hz` in
/// `series` (rate samples at `rate_hz`, the regressors already removed), estimated as
/// [`crate::analysis::lines::tone_near`] does, under the noise `terms` (white noise through
/// `low_pass`). Empty when the record is too short or the fit singular.
pub fn sinusoid_standard_errors(
    series: &[f64],
    rate_hz: f64,
    freq_hz: f64,
    terms: &NoiseTerms,
    low_pass: Option<&LowPass>,
) -> BTreeMap<&'static str, f64> {
    let n = series.len();
    let kmax = n.saturating_sub(1) / 2;
    if kmax < 4 || freq_hz.is_nan() || freq_hz <= 0.0 {
        return BTreeMap::new();
    }
    let w = 2.0 * PI * freq_hz / rate_hz;
    let half = n as f64 / 2.0;
    let centre = (n as f64 - 1.0) / 2.0;
    let phasor = |t: usize| (w * (t as f64 - centre)).sin_cos();
    // The offset, slope and sinusoid first, for the derivative column's a and b.
    let linear = |t: usize| {
        let (s, c) = phasor(t);
        [1.0, (t as f64 - centre) / half, c, s]
    };
    let Some((_, coef)) = least_squares::<4>(n, linear, series) else {
        return BTreeMap::new();
    };
    let (a, b) = (coef[2], coef[3]);
    let amplitude = a.hypot(b);
    if amplitude.is_nan() || amplitude <= 0.0 {
        return BTreeMap::new();
    }
    // The derivative in w, scaled by 1 / half as the slope is: its coefficient is dw half.
    let columns = |t: usize| {
        let (s, c) = phasor(t);
        let u = (t as f64 - centre) / half;
        [1.0, u, c, s, u * (b * c - a * s)]
    };
    let Some((inverse, _)) = least_squares::<5>(n, columns, series) else {
        return BTreeMap::new();
    };
    let row = |weights: [f64; 5]| -> Vec<f64> {
        (0..n)
            .map(|t| {
                let x = columns(t);
                (0..5)
                    .map(|m| {
                        let coefficient: f64 = (0..5).map(|j| weights[j] * inverse[j][m]).sum();
                        coefficient * x[m]
                    })
                    .sum()
            })
            .collect()
    };
    let variances = model_variances(terms, low_pass, rate_hz, n, kmax);
    let amplitude_row = row([0.0, 0.0, a / amplitude, b / amplitude, 0.0]);
    let freq_row = row([0.0, 0.0, 0.0, 0.0, rate_hz / (2.0 * PI * half)]);
    BTreeMap::from([
        (
            "amplitude",
            quadratic_form(&amplitude_row, &variances).sqrt(),
        ),
        ("freq_hz", quadratic_form(&freq_row, &variances).sqrt()),
    ])
}

/// The inverse normal matrix `(X^T X)^-1` of the `M` columns `x(t)`, t in 0..n, and the
/// least-squares coefficients of `y` on them.
fn least_squares<const M: usize>(
    n: usize,
    x: impl Fn(usize) -> [f64; M],
    y: &[f64],
) -> Option<(Vec<Vec<f64>>, [f64; M])> {
    let mut g = vec![vec![0.0; M]; M];
    let mut h = [0.0; M];
    for (t, yt) in y.iter().enumerate().take(n) {
        let row = x(t);
        for i in 0..M {
            h[i] += row[i] * yt;
            for j in 0..M {
                g[i][j] += row[i] * row[j];
            }
        }
    }
    let inverse = invert_spd(&g)?;
    let mut coef = [0.0; M];
    for (i, c) in coef.iter_mut().enumerate() {
        *c = (0..M).map(|j| inverse[i][j] * h[j]).sum();
    }
    Some((inverse, coef))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::lines::tone_near;
    use crate::model::families::{self, Kind, Shape};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn white_noise_gives_the_cramer_rao_bound() {
        let (rate_hz, n) = (10.0, 20_000);
        let t_rec = n as f64 / rate_hz;
        let terms = NoiseTerms {
            n: 1e-3,
            ..NoiseTerms::default()
        };
        let (freq_hz, amplitude) = (60.3 / t_rec, 4e-4);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let series: Vec<f64> = (0..n)
            .map(|t| {
                let noise: f64 = StandardNormal.sample(&mut rng);
                amplitude * (2.0 * PI * freq_hz * t as f64 / rate_hz + 0.4).cos()
                    + noise * terms.n * rate_hz.sqrt()
            })
            .collect();
        let errors = sinusoid_standard_errors(&series, rate_hz, freq_hz, &terms, None);
        // One-sided white PSD S = 2 N^2 (N the two-sided density of the rate).
        let s = 2.0 * terms.n * terms.n;
        let sd_a = (s / t_rec).sqrt();
        // The bound at the amplitude measured, which the linearisation is taken at.
        let (_, measured) = tone_near(&series, rate_hz, freq_hz).expect("a fit");
        let sd_f = (12.0 * s / t_rec.powi(3)).sqrt() / (2.0 * PI * measured);
        // The bound holds where the offset and slope fitted beside the sinusoid take nothing
        // from it: at 60 cycles per record, to a few parts in a thousand (at 7 cycles the
        // slope's share raises the frequency's error by 8 %).
        assert!(
            (errors["amplitude"] / sd_a - 1.0).abs() < 0.005,
            "{errors:?} vs {sd_a}"
        );
        assert!(
            (errors["freq_hz"] / sd_f - 1.0).abs() < 0.005,
            "{errors:?} vs {sd_f}"
        );
    }

    /// On the family's slow-sinusoid records (white noise, flicker and a random walk drawn
    /// from ranges; a sinusoid of 5 to 20 cycles per record), the errors over their stated
    /// standard errors, under the generator's terms, have a mean square of 1: the bound is
    /// 4 standard deviations of a mean of `count` chi-square(1) values.
    #[test]
    fn the_stated_errors_match_the_errors_on_slow_sinusoids() {
        let shape = Shape {
            rate_hz: 10.0,
            duration_s: 3600.0,
        };
        let count = 150;
        let (mut z2_f, mut z2_a) = (0.0, 0.0);
        for seed in 0..count {
            let hidden = families::generate(Kind::SlowSinusoid, shape, 9000 + seed);
            let truth = hidden.sinusoid.expect("a slow-sinusoid record");
            let series = &hidden.record.channels[0].values;
            let (freq_hz, amplitude) =
                tone_near(series, shape.rate_hz, truth.freq_hz).expect("a fit");
            let errors =
                sinusoid_standard_errors(series, shape.rate_hz, freq_hz, &hidden.terms, None);
            z2_f += ((freq_hz - truth.freq_hz) / errors["freq_hz"]).powi(2);
            z2_a += ((amplitude - truth.amplitude) / errors["amplitude"]).powi(2);
        }
        let (z2_f, z2_a) = (z2_f / count as f64, z2_a / count as f64);
        eprintln!("mean z^2: frequency {z2_f:.3}, amplitude {z2_a:.3}");
        let bound = 4.0 * (2.0 / count as f64).sqrt();
        assert!((z2_f - 1.0).abs() < bound, "frequency: {z2_f}");
        assert!((z2_a - 1.0).abs() < bound, "amplitude: {z2_a}");
    }
}

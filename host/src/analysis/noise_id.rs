//! Dominant power-law noise type at an averaging factor, as Stable32 does it (NIST SP 1065
//! §5.5): the lag-1 autocorrelation method when the decimated series is long enough, else the
//! B1 ratio, with the R(n) ratio to tell flicker from white phase noise.
//!
//! alpha is the exponent of the fractional-frequency PSD, S_y(f) ∝ f^alpha: 2 white PM,
//! 1 flicker PM, 0 white FM, -1 flicker FM, -2 random-walk FM.
//!
//! References: W. J. Riley and C. A. Greenhall, "Power law noise identification using the lag
//! 1 autocorrelation", EFTF 2004; SP 1065 §5.5.2 (B1 and R(n) ratios).

use super::Estimator;
use super::allan::deviation;
use super::numerics::solve3;

/// Shortest decimated series for which the lag-1 autocorrelation is trusted (Riley &
/// Greenhall recommend at least about 30 points).
pub const MIN_ACF_POINTS: usize = 30;

/// Longest decimated series the autocorrelation method uses. The noise type at a tau is a
/// local property, and the standard error of r1 is about 1/sqrt(n) (0.003 at 2^17 points),
/// far inside the method's decision margins (delta is rounded at 0.25 steps); capping keeps
/// the cost of identification at small m from dominating an 8-hour analysis.
const MAX_ACF_POINTS: usize = 1 << 17;

/// Dominant noise exponent alpha (-2..=2) of phase data `x` at averaging factor m, for
/// estimator `est` (it sets how many differences the autocorrelation method may take: two
/// for the Allan family, three for the Hadamard family, and whether R(n) splits flicker from
/// white PM in the B1 method). None when the data cannot tell (too few points, constant
/// data).
pub fn identify(est: Estimator, x: &[f64], m: usize) -> Option<i32> {
    identify_all(est, x, &[m]).pop().flatten()
}

/// [`identify`] at every factor of `ms`. The B1 method needs the Allan variance at each of
/// its factors: they are computed together in one pass over the data.
pub fn identify_all(est: Estimator, x: &[f64], ms: &[usize]) -> Vec<Option<i32>> {
    let uses_b1 = |m: usize| m > 0 && x.len() >= 2 && x.len().div_ceil(m) < MIN_ACF_POINTS;
    let b1_factors: Vec<usize> = ms.iter().copied().filter(|&m| uses_b1(m)).collect();
    let avar = variances_at(Estimator::Oadev, x, &b1_factors);
    let mu: Vec<Option<i32>> = b1_factors
        .iter()
        .zip(&avar)
        .map(|(&m, &a)| b1_mu(x, m, a?))
        .collect();
    // mu = -2 is white or flicker PM: R(n) = MVAR / AVAR tells them apart.
    let rn_factors: Vec<usize> = b1_factors
        .iter()
        .zip(&mu)
        .filter(|(_, mu)| **mu == Some(-2))
        .map(|(&m, _)| m)
        .collect();
    let mvar = variances_at(Estimator::Mdev, x, &rn_factors);
    let b1_alpha = |m: usize| -> Option<i32> {
        let i = b1_factors.iter().position(|&f| f == m)?;
        match mu[i]? {
            -2 => {
                let j = rn_factors.iter().position(|&f| f == m)?;
                Some(rn_alpha(m, avar[i]?, mvar[j]?))
            }
            mu => Some(-mu - 1),
        }
    };
    ms.iter()
        .map(|&m| {
            if m == 0 || x.len() < 2 {
                None
            } else if uses_b1(m) {
                b1_alpha(m)
            } else {
                let decimated: Vec<f64> =
                    x.iter().step_by(m).take(MAX_ACF_POINTS).copied().collect();
                let d_max = match est {
                    Estimator::Hdev | Estimator::Ohdev => 3,
                    _ => 2,
                };
                lag1_noise_id(decimated, d_max)
            }
        })
        .collect()
}

/// The variance of `est` at each factor (None where the data cannot support it), all from
/// one call so that the estimator sweeps the data once.
fn variances_at(est: Estimator, x: &[f64], ms: &[usize]) -> Vec<Option<f64>> {
    let d = deviation(est, x, 1.0, ms);
    ms.iter()
        .map(|&m| {
            let i = d.m.iter().position(|&f| f == m)?;
            let v = d.dev[i].powi(2);
            (v.is_finite() && v > 0.0).then_some(v)
        })
        .collect()
}

/// Riley & Greenhall 2004 on (decimated) phase z: remove a quadratic trend, then difference z
/// until delta = r1 / (1 + r1) < 0.25 (the series is stationary) or `d_max` differences are
/// taken, r1 being the lag-1 autocorrelation. Then alpha = 2 - round(2 delta) - 2 d
/// (phase data: p = -2 (delta + d) is the exponent of the phase PSD, alpha = p + 2).
fn lag1_noise_id(mut z: Vec<f64>, d_max: u32) -> Option<i32> {
    detrend_quadratic(&mut z);
    let mut d = 0;
    loop {
        let r1 = lag1_autocorrelation(&z)?;
        let delta = r1 / (1.0 + r1);
        if delta < 0.25 || d >= d_max {
            let alpha = 2 - (2.0 * delta).round() as i32 - 2 * d as i32;
            return Some(alpha.clamp(-2, 2));
        }
        z = z.windows(2).map(|w| w[1] - w[0]).collect();
        d += 1;
    }
}

/// r1 = Σ (z_i - z̄)(z_{i+1} - z̄) / Σ (z_i - z̄)² (Riley & Greenhall eq. 2); None when z
/// is too short or constant.
fn lag1_autocorrelation(z: &[f64]) -> Option<f64> {
    if z.len() < 3 {
        return None;
    }
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let den: f64 = z.iter().map(|v| (v - mean).powi(2)).sum();
    let num: f64 = z.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
    (den > 0.0 && den.is_finite()).then(|| num / den)
}

/// Subtract the least-squares quadratic in the sample index (frequency offset and drift).
fn detrend_quadratic(z: &mut [f64]) {
    let n = z.len();
    if n < 3 {
        return;
    }
    // Centred, scaled abscissa in [-1, 1] keeps the normal equations well conditioned.
    let half = (n - 1) as f64 / 2.0;
    let t = |i: usize| (i as f64 - half) / half;
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for (i, &v) in z.iter().enumerate() {
        let p = [1.0, t(i), t(i) * t(i)];
        for r in 0..3 {
            b[r] += p[r] * v;
            for c in 0..3 {
                a[r][c] += p[r] * p[c];
            }
        }
    }
    let Some(coef) = solve3(a, b) else { return };
    for (i, v) in z.iter_mut().enumerate() {
        *v -= coef[0] + coef[1] * t(i) + coef[2] * t(i) * t(i);
    }
}

/// SP 1065 §5.5.2: B1 = (sample variance of the n averages of frequency over m samples) /
/// (Allan variance at m); compared with its expectation for each tau exponent mu of AVAR,
/// the boundary between neighbours being the geometric mean of the two. Returns mu: 1, 0, -1
/// are alpha = -2, -1, 0; -2 is white or flicker PM, split with R(n) (see [`rn_alpha`]).
fn b1_mu(x: &[f64], m: usize, avar: f64) -> Option<i32> {
    let means: Vec<f64> = x
        .iter()
        .step_by(m)
        .collect::<Vec<_>>()
        .windows(2)
        .map(|w| (w[1] - w[0]) / m as f64)
        .collect();
    let n = means.len();
    if n < 2 {
        return None;
    }
    let mean = means.iter().sum::<f64>() / n as f64;
    let var = means.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let b1 = var / avar;
    Some(
        (-1..=1)
            .rev()
            .find(|&mu| b1 > (b1_expected(n, mu) * b1_expected(n, mu - 1)).sqrt())
            .unwrap_or(-2),
    )
}

/// Expected B1 ratio for n averages and AVAR tau exponent mu (SP 1065 §5.5.2; Barnes 1969):
/// n (1 - n^mu) / (2 (n-1) (1 - 2^mu)), with its limit n ln n / (2 (n-1) ln 2) at mu = 0,
/// 1 at mu = -1, and (n² - 1) / (1.5 n (n-1)) at mu = -2 (white and flicker PM).
fn b1_expected(n: usize, mu: i32) -> f64 {
    let n = n as f64;
    match mu {
        0 => n * n.ln() / (2.0 * (n - 1.0) * 2f64.ln()),
        -1 => 1.0,
        -2 => (n * n - 1.0) / (1.5 * n * (n - 1.0)),
        mu => n * (1.0 - n.powi(mu)) / (2.0 * (n - 1.0) * (1.0 - 2f64.powi(mu))),
    }
}

/// R(n) = MVAR / AVAR at m (SP 1065 §5.5.2): about 1/m for white PM and
/// 3 ln(256/27) / (2 (1.038 + 3 ln(pi m))) for flicker PM (bandwidth f_h = 1/(2 tau0));
/// the boundary is their geometric mean. Returns 1 (flicker) above it, 2 (white) below.
fn rn_alpha(m: usize, avar: f64, mvar: f64) -> i32 {
    let rn = mvar / avar;
    let mf = m as f64;
    let white = 1.0 / mf;
    let flicker =
        3.0 * (256.0f64 / 27.0).ln() / (2.0 * (1.038 + 3.0 * (std::f64::consts::PI * mf).ln()));
    if rn > (white * flicker).sqrt() { 1 } else { 2 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::phase_from_rate;

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                // Sum of 12 uniforms: close enough to Gaussian for these tests.
                (0..12)
                    .map(|_| {
                        s = s
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (s >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0
            })
            .collect()
    }

    #[test]
    fn identifies_white_pm_white_fm_and_random_walk_fm() {
        let w = white(4096, 7);
        assert_eq!(identify(Estimator::Oadev, &w, 1), Some(2));
        assert_eq!(identify(Estimator::Oadev, &w, 8), Some(2));
        let x = phase_from_rate(&w, 1.0);
        assert_eq!(identify(Estimator::Oadev, &x, 1), Some(0));
        assert_eq!(identify(Estimator::Hdev, &x, 4), Some(0));
        let rw = phase_from_rate(&w, 1.0);
        let x2 = phase_from_rate(&rw, 1.0);
        assert_eq!(identify(Estimator::Oadev, &x2, 2), Some(-2));
    }

    #[test]
    fn b1_path_for_few_points() {
        // 4096 / 256 = 16 decimated points: the B1 ratio (and R(n)) decide. With so few
        // averages single draws can miss, so require 12 of 20 seeds to be right
        // (B1 from 16 averages has a relative spread of about 0.4).
        let (mut wfm, mut wpm) = (0, 0);
        for seed in 0..20 {
            let w = white(4096, seed);
            let x = phase_from_rate(&w, 1.0);
            wfm += usize::from(identify(Estimator::Oadev, &x, 256) == Some(0));
            wpm += usize::from(identify(Estimator::Mdev, &w, 256) == Some(2));
        }
        assert!(
            wfm >= 12 && wpm >= 12,
            "white FM {wfm}/20, white PM {wpm}/20"
        );
    }

    #[test]
    fn degenerate_input_gives_none() {
        assert_eq!(identify(Estimator::Oadev, &[], 1), None);
        assert_eq!(identify(Estimator::Oadev, &[1.0; 100], 1), None);
        assert_eq!(identify(Estimator::Oadev, &[1.0, 2.0, 3.0], 0), None);
        assert_eq!(identify(Estimator::Oadev, &[1.0, 2.0, 3.0], 5), None);
    }

    #[test]
    fn b1_expectations() {
        assert!((b1_expected(10, 1) - 5.0).abs() < 1e-12);
        assert!((b1_expected(10, -1) - 1.0).abs() < 1e-12);
        assert!(b1_expected(10, 0) > 1.0 && b1_expected(10, -2) < 1.0);
    }
}

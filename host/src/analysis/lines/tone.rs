//! Tones: a tone's frequency read from the DFT and refined on the continuous periodogram,
//! its amplitude and phase fitted by least squares with an offset and a slope, and its
//! subtraction in the time domain (module documentation of [`super`], step 4).

use super::{Trend, detrend};
use crate::analysis::numerics::solve4;
use realfft::num_complex::Complex;
use std::f64::consts::PI;

/// Golden-section steps refining a tone's frequency over a fifth of a bin: `0.618^40` of it
/// is 9e-10 bins.
const TONE_GOLDEN_STEPS: usize = 40;

/// A fitted tone `a cos(w t_c) + b sin(w t_c)`, `t_c = t - (n - 1) / 2`, w in rad/sample.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tone {
    pub(super) omega: f64,
    pub(super) a: f64,
    pub(super) b: f64,
    /// The bin it was found at, and its statistic and family-wise p-value there.
    pub(super) bin: usize,
    pub(super) statistic: f64,
    pub(super) p_value: f64,
}

impl Tone {
    pub(super) fn power(&self) -> f64 {
        (self.a * self.a + self.b * self.b) / 2.0
    }

    /// Its frequency in Hz on a record sampled at `rate_hz`.
    pub(super) fn freq_hz(&self, rate_hz: f64) -> f64 {
        self.omega * rate_hz / (2.0 * PI)
    }
}

/// The least-squares sinusoid near `freq_hz` in `rate` (within a bin of it), with an offset
/// and a slope fitted jointly: its frequency, Hz, and amplitude, u. `None` when the fit is
/// singular.
///
/// The frequency maximises the periodogram of the detrended series, `|sum x_t e^(-i w t)|^2`,
/// over +-1 bin: a grid of tenths of a bin, then golden section around the best point. A
/// Newton step from the bin (as the line search uses) can stall on a slow line, where the
/// random walk's leakage leaves the periodogram convex at the start; a frequency half a bin
/// off leaves a third of the tone behind when the tone is regressed out at it.
pub fn tone_near(rate: &[f64], rate_hz: f64, freq_hz: f64) -> Option<(f64, f64)> {
    let n = rate.len();
    if n < 4 {
        return None;
    }
    let (trend, _) = detrend(rate);
    let bin = 2.0 * PI / n as f64;
    let start = 2.0 * PI * freq_hz / rate_hz;
    let power = |w: f64| {
        let mut f0 = Complex::new(0.0, 0.0);
        for_each_phasor(n, w, |t, _, c, s| {
            let x = rate[t] - trend.at(t, n);
            f0 += Complex::new(x * c, -x * s);
        });
        f0.norm_sqr()
    };
    let grid = (0..=20)
        .map(|k| start + (k as f64 / 10.0 - 1.0) * bin)
        .filter(|&w| w > 0.0 && w < PI);
    let (best, _) = grid
        .map(|w| (w, power(w)))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let w = crate::analysis::low_pass::golden_min(
        |w| -power(w),
        (best - 0.1 * bin).max(0.5 * bin),
        best + 0.1 * bin,
        TONE_GOLDEN_STEPS,
    );
    let tone = fit_at(rate, w)?;
    Some((tone.freq_hz(rate_hz), tone.a.hypot(tone.b)))
}

/// Jacobsen's fractional-bin offset of a tone near bin k from the rectangular-window DFT:
/// `-Re[(X_{k+1} - X_{k-1}) / (2 X_k - X_{k-1} - X_{k+1})]`, clipped to +-1 bin.
pub(super) fn jacobsen(dft: &[Complex<f64>], k: usize) -> f64 {
    if k == 0 || k + 1 >= dft.len() {
        return 0.0;
    }
    let den = 2.0 * dft[k] - dft[k - 1] - dft[k + 1];
    if den.norm_sqr() == 0.0 {
        return 0.0;
    }
    (-((dft[k + 1] - dft[k - 1]) / den).re).clamp(-1.0, 1.0)
}

/// Calls `f(t_c, cos(w t_c), sin(w t_c))` for t = 0..n, `t_c = t - (n - 1) / 2`: the phasor is
/// rotated sample by sample and recomputed exactly every 1024 samples (rounding stays near
/// 1e-13).
pub(super) fn for_each_phasor(n: usize, omega: f64, mut f: impl FnMut(usize, f64, f64, f64)) {
    let centre = (n as f64 - 1.0) / 2.0;
    let (rs, rc) = omega.sin_cos();
    let mut t = 0;
    while t < n {
        let end = (t + 1024).min(n);
        let (mut s, mut c) = (omega * (t as f64 - centre)).sin_cos();
        for i in t..end {
            f(i, i as f64 - centre, c, s);
            (c, s) = (c * rc - s * rs, s * rc + c * rs);
        }
        t = end;
    }
}

/// The least-squares tone near `omega` (rad/sample) in `y`: Newton steps on the periodogram
/// of `y - trend` (at most a bin from the start), then amplitude and phase fitted together with
/// an offset and a slope. `None` when the fit is singular.
pub(super) fn fit_tone(y: &[f64], trend: Trend, omega: f64) -> Option<Tone> {
    let n = y.len();
    let bin = 2.0 * PI / n as f64;
    let mut w = omega;
    for _ in 0..4 {
        // F_j = sum t^j x e^(-i w t); I = |F0|^2, I' = 2 Re(conj(F0) (-i F1)),
        // I'' = 2 (|F1|^2 - Re(conj(F0) F2)).
        let (mut f0, mut f1, mut f2) = (
            Complex::new(0.0, 0.0),
            Complex::new(0.0, 0.0),
            Complex::new(0.0, 0.0),
        );
        for_each_phasor(n, w, |t, tc, c, s| {
            let x = y[t] - trend.at(t, n);
            let e = Complex::new(x * c, -x * s);
            f0 += e;
            f1 += e * tc;
            f2 += e * (tc * tc);
        });
        let d1 = 2.0 * (f0.conj() * Complex::new(0.0, -1.0) * f1).re;
        let d2 = 2.0 * (f1.norm_sqr() - (f0.conj() * f2).re);
        if d2.is_nan() || d2 >= 0.0 {
            break;
        }
        let step = (-d1 / d2).clamp(-0.5 * bin, 0.5 * bin);
        w += step;
        if (w - omega).abs() > bin {
            w = omega;
            break;
        }
        if step.abs() < 1e-7 * bin {
            break;
        }
    }
    fit_at(y, w)
}

/// The least-squares tone at `w` (rad/sample) in `y`, fitted with an offset and a slope.
/// `None` when the fit is singular.
fn fit_at(y: &[f64], w: f64) -> Option<Tone> {
    let n = y.len();
    // Normal equations of y ~ c0 + c1 u + a cos + b sin, u = t_c / (n / 2).
    let half = n as f64 / 2.0;
    let mut g = [[0.0f64; 4]; 4];
    let mut h = [0.0f64; 4];
    for_each_phasor(n, w, |t, tc, c, s| {
        let row = [1.0, tc / half, c, s];
        for i in 0..4 {
            h[i] += row[i] * y[t];
            for j in i..4 {
                g[i][j] += row[i] * row[j];
            }
        }
    });
    for i in 1..4 {
        let (upper, lower) = g.split_at_mut(i);
        for (j, row) in upper.iter().enumerate() {
            lower[0][j] = row[i];
        }
    }
    let coef = solve4(g, h)?;
    Some(Tone {
        omega: w,
        a: coef[2],
        b: coef[3],
        bin: 0,
        statistic: 0.0,
        p_value: 1.0,
    })
}

pub(super) fn subtract(y: &mut [f64], tone: &Tone) {
    let n = y.len();
    for_each_phasor(n, tone.omega, |t, _, c, s| {
        y[t] -= tone.a * c + tone.b * s;
    });
}

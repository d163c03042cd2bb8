//! N, B and K from the power spectral density of a rate record, each with an interval.
//!
//! IEEE Std 952-1997 (Annex C, Table C.1) gives each noise term's **two-sided** rate PSD:
//! white rate noise `N^2`, bias instability (flicker) `B^2 / (2 pi f)`, rate random walk
//! `K^2 / (2 pi f)^2`. Our spectra are one-sided, twice that ([`crate::analysis::psd`]):
//!
//! ```text
//! S1(f) = 2 N^2 + 2 B^2 / (2 pi f) + 2 K^2 / (2 pi f)^2
//! ```
//!
//! **Why a multi-resolution spectrum.** K shows only where the rate random walk dominates,
//! below `f = K / (2 pi N)` (1.6 mHz for N = 1e-3, K = 1e-5): one decade above `1 / T` for a
//! 2 h record. One Welch estimate cannot have both the many averages the high band needs and
//! the resolution of `1 / T`. [`spectrum`] therefore builds a pyramid: level 0 is Welch's
//! estimate of the record with segments of `L` samples; level r is Welch's estimate, with
//! the same `L`, of the record averaged in blocks of `2^r` samples (pairs of level r - 1
//! averaged), down to the deepest level that still holds one segment. Level r contributes
//! the octave its own ordinates `j = 3, 4, 5` cover (level 0: every ordinate from 3 up to,
//! but not including, Nyquist), so every frequency comes from the level with the most
//! averages that resolves it, the lowest at `3 / T .. 6 / T`. A deeper level's three
//! ordinates are summed directly from each segment (`psd::welch_bins_of`), not by a
//! transform of the whole segment. Averaging pairs keeps the
//! density of white noise exactly (variance halves, rate halves) and passes the octave a
//! level uses with gain `prod cos^2(pi f 2^k / fs)`, above 0.99 for segments of 256 samples
//! or more. The two ordinates next to DC
//! are left out at every level: with a Hann window they share the main lobe of the removed
//! segment mean.
//!
//! **Statistics of each point.** Ordinates are averaged into [`PSD_BINS_PER_DECADE`] log
//! bins per level. A Welch ordinate is `S chi2(nu) / nu` with `nu = 2 K_eff`, where `K_eff`
//! counts the overlapping segments as independent ones (Percival & Walden, *Spectral
//! Analysis for Physical Applications*, 1993, section 6.17, the WOSA equivalent degrees of
//! freedom, eq. 292b; Welch 1967, IEEE Trans. Audio Electroacoust. 15(2)):
//!
//! ```text
//! K_eff = K / (1 + 2 sum_{m=1}^{K-1} (1 - m/K) rho(m)),  rho(m) = (sum_t w_t w_{t+m s})^2 / (sum_t w_t^2)^2
//! ```
//!
//! (s the segment step; Hann at 50 % overlap: rho(1) = 1/36, so `K_eff ~ 0.95 K`). Ordinates
//! j and k of one level are correlated by `c(j - k)^2`, `c(m) = |sum_t w_t^2 e^(-2 pi i m t / L)|
//! / sum_t w_t^2` (Percival & Walden, chapter 6; Hann: c(1) = 2/3, c(2) = 1/6, 0 beyond), so
//! a bin's mean of M ordinates has relative covariance with another bin's
//! `R_ab = sum_{j in a, k in b} c(j - k)^2 / (M_a M_b K_eff)` and equivalent degrees of
//! freedom `2 / R_aa`. Points of different levels are treated as independent.
//!
//! **The fit.** The model is linear in theta = (N^2, B^2, K^2) >= 0; each point's expected
//! value is the mean over its ordinates of the model smoothed by the window's kernel
//! (`window_smoothing`). [`fit_psd`] minimises
//! `sum_a (S_a - m_a)^2 / (m_a^2 R_aa)` subject to theta >= 0, with the variances taken
//! from the model value `m_a` (iterated, as for the Allan fit: weighting by the measured
//! value favours the points that fell low). The covariance of theta is the sandwich
//! `H^-1 G^T C G H^-1` with C the correlation `R_ab / sqrt(R_aa R_bb)`. The band fitted
//! ends where the flat (white) part of the spectrum ends, less 0.2 decade: above, the
//! sensor's low-pass filter or quantization shape the spectrum and no term of this model
//! describes them.
//!
//! **The sensor's filter.** A flat band judged by its slope is far coarser than N's own
//! precision on a long record: a filter that tilts the top of the band by 1-2 % biases N by
//! several of its standard deviations (2 h of the MPU-6050 at 200 Hz with the 98 Hz DLPF: N
//! 2.4 % low with a +/-0.1 % interval). When the filter is known from the sensor's settings
//! ([`PsdFitOptions::low_pass`]) every term is multiplied by its folded power gain
//! (`filtered_band_end`), so N is the DC white level the Allan deviation's N is; the same
//! record then gives N within its interval of the Allan fit's.
//!
//! **Intervals.** A squared coefficient theta with standard deviation sd is reported as
//! resolved when `theta > z sd` (z the two-sided normal quantile of the confidence); its
//! interval is then Satterthwaite's chi-squared one, `nu = 2 theta^2 / sd^2`,
//! `[nu theta / chi2_{(1+c)/2}(nu), nu theta / chi2_{(1-c)/2}(nu)]` (the same approximation
//! as the Allan deviation's intervals). An unresolved term has `lo = 0` and the upper bound
//! `theta + z sd`. Square roots give the coefficients' intervals.

use super::{longest_run, ls_slope};
use crate::analysis::low_pass::{LowPass, LowPassSource};
use crate::analysis::numerics::inverse;
use crate::analysis::psd::{
    self, PsdError, Samples, SegmentTransform, Taper, WelchOptions, Window,
};
use realfft::num_complex::Complex;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};
use std::borrow::Cow;
use std::f64::consts::PI;

/// Log-spaced bins per decade of the spectrum [`fit_psd`] fits.
pub const PSD_BINS_PER_DECADE: usize = 10;
/// The lowest DFT ordinate used at every level (see the module documentation).
pub const FIRST_ORDINATE: usize = 3;

/// Half-width of the band of local slopes counted as flat (white noise).
const FLAT_SLOPE: f64 = 0.15;
/// Bins left out below the end of the flat band (0.2 decade).
const BAND_END_MARGIN: usize = 2;
/// Largest ordinate lag whose correlation [`fit_psd`] models (Blackman reaches 4).
const MAX_LAG: usize = 6;

/// Settings of [`fit_psd`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PsdFitOptions {
    /// Samples per segment at every level; 0 chooses [`psd::segment_len_for`].
    pub segment_len: usize,
    pub window: Window,
    /// Two-sided confidence level of the intervals, in (0, 1).
    pub confidence: f64,
    /// The sensor's low-pass filter: when it comes from the sensor's settings, the model is
    /// the filtered spectrum (`filtered_band_end`); a fitted one is not used.
    pub low_pass: Option<LowPass>,
}

impl Default for PsdFitOptions {
    fn default() -> Self {
        PsdFitOptions {
            segment_len: 0,
            window: Window::Hann,
            confidence: 0.683,
            low_pass: None,
        }
    }
}

/// Errors from [`fit_psd`]; each names the input at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PsdFitError {
    #[error(transparent)]
    Psd(#[from] PsdError),
    #[error("{0} usable spectrum points: the PSD fit needs at least 3")]
    TooFewPoints(usize),
    #[error("confidence {0} is not in (0, 1)")]
    BadConfidence(f64),
    #[error("not computed: {0}")]
    NotComputed(&'static str),
}

/// One coefficient from the PSD, SI (N in u/sqrt(Hz), B in u, K in u*sqrt(Hz)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PsdReadout {
    /// The estimate; 0 when the fit pinned the term at 0.
    pub value: f64,
    /// The interval at [`PsdNoiseTerms::confidence`]; `lo = 0` when the term is not resolved.
    pub lo: f64,
    pub hi: f64,
    /// Satterthwaite's equivalent degrees of freedom of `value^2` (0 when not resolved).
    pub dof: f64,
    /// Frequency range where the term is at least half of the fitted PSD, Hz (0 and 0 when
    /// it is nowhere).
    pub f_min: f64,
    pub f_max: f64,
    /// Spectrum points in that range.
    pub bins: usize,
}

impl PsdReadout {
    /// Whether the spectrum tells the term from zero at the stated confidence.
    pub fn resolved(&self) -> bool {
        self.lo > 0.0
    }
}

/// One point of the multi-resolution spectrum: a log bin of one level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SpectrumPoint {
    /// Geometric mean of the ordinates' frequencies, Hz.
    pub freq: f64,
    /// Mean one-sided density of the ordinates, u^2/Hz.
    pub density: f64,
    /// Equivalent degrees of freedom of `density` (chi-squared).
    pub dof: f64,
    /// Pyramid level: the record averaged in blocks of `2^level` samples.
    pub level: usize,
}

/// N, B and K fitted to the multi-resolution PSD, with the spectrum they came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PsdNoiseTerms {
    pub n: PsdReadout,
    pub b: PsdReadout,
    pub k: PsdReadout,
    pub confidence: f64,
    /// The band fitted, Hz.
    pub f_min: f64,
    pub f_max: f64,
    /// Points fitted.
    pub points: usize,
    /// `sum_a (S_a - m_a)^2 / Var_a` over the points minus the free terms: about 1 when the
    /// model describes the spectrum (correlated neighbours make it scatter more).
    pub reduced_chi2: f64,
    /// `sqrt(max(1, reduced_chi2))`: every term's standard deviation was multiplied by it
    /// before its interval (R. T. Birge, Phys. Rev. 40, 207, 1932), as in the Allan fit.
    pub birge_ratio: f64,
    /// Samples per segment at every level.
    pub segment_len: usize,
    /// The whole spectrum, every level, in increasing frequency (the fitted band and above).
    pub spectrum: Vec<SpectrumPoint>,
}

/// A spectrum point with what the fit needs: the model's basis averaged over its ordinates,
/// and where its ordinates lie (for the correlation).
#[derive(Debug, Clone)]
struct Point {
    public: SpectrumPoint,
    /// One-sided density per unit (N^2, B^2, K^2) averaged over the ordinates.
    basis: [f64; 3],
    /// First ordinate and count, at its level.
    first: usize,
    count: usize,
    k_eff: f64,
    /// `c(m)^2` of its level's window, m = 0..=MAX_LAG.
    lag_corr: [f64; MAX_LAG + 1],
}

/// The multi-resolution spectrum of `rate` (see the module documentation), every level's
/// points in increasing frequency.
pub fn spectrum(
    rate: &[f64],
    rate_hz: f64,
    segment_len: usize,
    window: Window,
) -> Result<Vec<SpectrumPoint>, PsdError> {
    Ok(pyramid(
        Samples::rate(rate),
        rate_hz,
        segment_len,
        window,
        (None, None),
    )?
    .into_iter()
    .map(|p| p.public)
    .collect())
}

/// Every level's points. Level `l` reads the record as means of `2^l` samples
/// ([`Samples::decimated`]), so no decimated copy is held; every level uses one segment
/// length, window and FFT plan (the caller's `transform` when it has that length).
fn pyramid(
    samples: Samples,
    rate_hz: f64,
    segment_len: usize,
    window: Window,
    (level0, transform): (Option<&psd::Psd>, Option<&SegmentTransform>),
) -> Result<Vec<Point>, PsdError> {
    let len = match segment_len {
        0 => psd::segment_len_for(samples.len()),
        l => l,
    };
    let opts = WelchOptions {
        segment_len: len,
        overlap: 0.5,
        window,
        detrend_mean: true,
    };
    let transform = match transform {
        Some(t) if t.len() == len => Cow::Borrowed(t),
        _ => Cow::Owned(SegmentTransform::new(len, window)),
    };
    let w = transform.window();
    let lags = LagPowers::of(w);
    let lag_corr = correlation_of(w, &lags);
    let smoothing = smoothing_of(&lags);
    let mut points = Vec::new();
    let mut level = 0;
    loop {
        let series = samples.decimated(1 << level);
        let fs = rate_hz / (1u64 << level) as f64;
        let spec = match level0 {
            // The caller's Welch estimate of the record with these options.
            Some(p) if level == 0 && p.density.len() == len / 2 + 1 => Cow::Borrowed(p),
            _ if level == 0 => Cow::Owned(psd::welch_of(series, fs, &opts, Some(&transform))?),
            // A deeper level is read at its lowest octave's bins only.
            _ => Cow::Owned(psd::welch_bins_of(
                series,
                fs,
                &opts,
                w,
                FIRST_ORDINATE..2 * FIRST_ORDINATE,
            )?),
        };
        let k_eff = effective_segments(w, len - (len as f64 * 0.5).floor() as usize, spec.segments);
        // Level 0: up to Nyquist (excluded: one degree of freedom); deeper levels: the
        // octave below the previous level's first ordinate.
        let end = if level == 0 {
            len.div_ceil(2)
        } else {
            2 * FIRST_ORDINATE
        };
        let mut level_points =
            bin_level(&spec.freq, &spec.density, FIRST_ORDINATE..end, &smoothing);
        for p in &mut level_points {
            p.k_eff = k_eff;
            p.lag_corr = lag_corr;
            p.public.level = level;
            p.public.dof = 2.0 / relative_covariance(p, p);
        }
        points.extend(level_points);
        if series.len() / 2 < len {
            break;
        }
        level += 1;
    }
    points.sort_by(|a, b| a.public.freq.total_cmp(&b.public.freq));
    Ok(points)
}

/// Ordinates `range` of one level averaged into log bins (points with a non-finite density
/// skipped). Each ordinate's expected value is the model smoothed by the window's kernel
/// `smoothing` ([`window_smoothing`]).
fn bin_level(
    freq: &[f64],
    density: &[f64],
    range: std::ops::Range<usize>,
    smoothing: &[f64; MAX_LAG + 1],
) -> Vec<Point> {
    let b = PSD_BINS_PER_DECADE as f64;
    let df = freq.get(1).copied().unwrap_or(0.0);
    let end = range.end.min(freq.len());
    let mut out: Vec<Point> = Vec::new();
    let mut current: Option<(i64, usize)> = None; // (bin index, first ordinate)
    let flush = |bin: Option<(i64, usize)>, last: usize, out: &mut Vec<Point>| {
        let Some((_, first)) = bin else { return };
        let js = first..last;
        let count = js.len();
        let m = count as f64;
        let ln_f: f64 = js.clone().map(|j| freq[j].ln()).sum::<f64>() / m;
        let s: f64 = js.clone().map(|j| density[j]).sum::<f64>() / m;
        let mut basis = [0.0; 3];
        for j in js {
            for (lag, weight) in smoothing.iter().enumerate() {
                for f in [freq[j] + lag as f64 * df, freq[j] - lag as f64 * df] {
                    let w = 2.0 * PI * f;
                    // Lag 0 is visited twice; its weight is halved for that.
                    let weight = if lag == 0 { weight / 2.0 } else { *weight };
                    if weight > 0.0 && w > 0.0 {
                        basis[0] += 2.0 * weight / m;
                        basis[1] += 2.0 * weight / (w * m);
                        basis[2] += 2.0 * weight / (w * w * m);
                    }
                }
            }
        }
        out.push(Point {
            public: SpectrumPoint {
                freq: ln_f.exp(),
                density: s,
                dof: 0.0,
                level: 0,
            },
            basis,
            first,
            count,
            k_eff: 1.0,
            lag_corr: [0.0; MAX_LAG + 1],
        });
    };
    for j in range.start..end {
        if !(freq[j] > 0.0 && density[j].is_finite()) {
            flush(current.take(), j, &mut out);
            continue;
        }
        let bin = (freq[j].log10() * b + 1e-9).floor() as i64;
        match current {
            Some((c, _)) if c == bin => {}
            _ => {
                flush(current.take(), j, &mut out);
                current = Some((bin, j));
            }
        }
    }
    flush(current, end, &mut out);
    out
}

#[cfg(test)]
fn window_smoothing(w: &Taper) -> [f64; MAX_LAG + 1] {
    smoothing_of(&LagPowers::of(w))
}

/// The weights `|W(m)|^2 / sum_m |W(m)|^2`, m = 0..=MAX_LAG (each applying at +m and -m), of
/// the window's DFT `W(m) = sum_t w_t e^(-2 pi i m t / L)`: a windowed ordinate is the
/// combination `sum_m W(m) X(j + m) / L` of the rectangular ordinates X, which for the
/// increments of a random walk and for flicker are nearly uncorrelated with mean S(f_j+m),
/// so its expected value is `sum_m |W(m)|^2 S(f_j+m)` normalised (Hann: 2/3 at 0, 1/6 at
/// +-1). On the steep spectra of the lowest ordinates this matters: for `1 / f^2` at j = 3 the
/// smoothed value is 13.5 % above `S(f_3)`.
fn smoothing_of(lags: &LagPowers) -> [f64; MAX_LAG + 1] {
    let power = lags.window;
    let total = power[0] + 2.0 * power[1..].iter().sum::<f64>();
    power.map(|p| p / total)
}

/// `|sum_t v_t e^(-2 pi i m t / L)|^2`, m = 0..=MAX_LAG, of the window (v = w) and of its
/// square (v = w^2), L the window's length; 0 below rounding (a generalised cosine window's
/// transform is exactly 0 beyond its reach).
struct LagPowers {
    window: [f64; MAX_LAG + 1],
    squared: [f64; MAX_LAG + 1],
}

impl LagPowers {
    /// One pass over the window: `e^(-2 pi i m t / L)` is the m-th power of
    /// `e^(-2 pi i t / L)`, whose sine and cosine are computed once per sample (no table of
    /// L phases is held).
    fn of(w: &Taper) -> LagPowers {
        let l = w.len() as f64;
        let mut window = [Complex::new(0.0, 0.0); MAX_LAG + 1];
        let mut squared = window;
        let (mut scale, mut scale2) = (0.0, 0.0);
        for (t, x) in w.iter().enumerate() {
            let (sin, cos) = (2.0 * PI * t as f64 / l).sin_cos();
            let turn = Complex::new(cos, -sin);
            let mut phase = Complex::new(1.0, 0.0);
            let x2 = x * x;
            for (a, b) in window.iter_mut().zip(squared.iter_mut()) {
                *a += phase * x;
                *b += phase * x2;
                phase *= turn;
            }
            scale += x.abs();
            scale2 += x2;
        }
        let power = |sum: &[Complex<f64>; MAX_LAG + 1], scale: f64| {
            sum.map(|z| {
                if z.norm() < 1e-9 * scale {
                    0.0
                } else {
                    z.norm_sqr()
                }
            })
        };
        LagPowers {
            window: power(&window, scale),
            squared: power(&squared, scale2),
        }
    }
}

/// `c(m)^2`, m = 0..=MAX_LAG: the squared correlation of Welch ordinates m apart for a
/// window `w` (see the module documentation).
#[cfg(test)]
fn ordinate_correlation(w: &Taper) -> [f64; MAX_LAG + 1] {
    correlation_of(w, &LagPowers::of(w))
}

fn correlation_of(w: &Taper, lags: &LagPowers) -> [f64; MAX_LAG + 1] {
    let total = w.sum_of_squares();
    lags.squared.map(|p| p / (total * total))
}

/// Welch's segments counted as independent ones (Percival & Walden eq. 292b), for `count`
/// segments of window `w` starting every `step` samples.
fn effective_segments(w: &Taper, step: usize, count: usize) -> f64 {
    let sum_w2 = w.sum_of_squares();
    let k = count as f64;
    let mut denominator = 1.0;
    for m in 1..count {
        let shift = m * step;
        if shift >= w.len() {
            break;
        }
        let overlap: f64 = w.iter().skip(shift).zip(w.iter()).map(|(a, b)| a * b).sum();
        denominator += 2.0 * (1.0 - m as f64 / k) * (overlap / sum_w2).powi(2);
    }
    k / denominator
}

/// `R_ab`, the covariance of two points' densities relative to their means (0 across
/// levels).
fn relative_covariance(a: &Point, b: &Point) -> f64 {
    if a.public.level != b.public.level {
        return 0.0;
    }
    let mut sum = 0.0;
    for j in a.first..a.first + a.count {
        let lo = j.saturating_sub(MAX_LAG).max(b.first);
        let hi = (j + MAX_LAG + 1).min(b.first + b.count);
        for k in lo..hi {
            sum += a.lag_corr[j.abs_diff(k)];
        }
    }
    sum / (a.count * b.count) as f64 / a.k_eff
}

/// N, B and K with intervals from the multi-resolution PSD of a **rate** record (u, sampled
/// at `rate_hz`); see the module documentation for the spectrum, the fit and the intervals.
pub fn fit_psd(
    rate: &[f64],
    rate_hz: f64,
    opts: &PsdFitOptions,
) -> Result<PsdNoiseTerms, PsdFitError> {
    fit_psd_with(Samples::rate(rate), rate_hz, opts, (None, None))
}

/// [`fit_psd`] of the series `samples` reads (a rate record or the rate of a phase record),
/// given the record's own Welch estimate with the fit's segment length and window (Hann or
/// `opts.window`, 50 % overlap, segment means removed), which is then not computed again, and
/// that segment length's window and plan; a `welch` or `transform` of another segment
/// length is not used.
pub fn fit_psd_with(
    samples: Samples,
    rate_hz: f64,
    opts: &PsdFitOptions,
    given: (Option<&psd::Psd>, Option<&SegmentTransform>),
) -> Result<PsdNoiseTerms, PsdFitError> {
    if !(opts.confidence > 0.0 && opts.confidence < 1.0) {
        return Err(PsdFitError::BadConfidence(opts.confidence));
    }
    let mut all: Vec<Point> = pyramid(samples, rate_hz, opts.segment_len, opts.window, given)?
        .into_iter()
        .filter(|p| p.public.density > 0.0)
        .collect();
    let f_hi = match &opts.low_pass {
        Some(lp) if lp.source == LowPassSource::Settings => filtered_band_end(&mut all, lp),
        _ => white_band_end(&all),
    };
    let pts: Vec<&Point> = all.iter().filter(|p| p.public.freq <= f_hi).collect();
    if pts.len() < 3 {
        return Err(PsdFitError::TooFewPoints(pts.len()));
    }
    let rows: Vec<[f64; 3]> = pts.iter().map(|p| p.basis).collect();
    let y: Vec<f64> = pts.iter().map(|p| p.public.density).collect();
    let rel_var: Vec<f64> = pts.iter().map(|p| relative_covariance(p, p)).collect();
    let (theta, sigma) = irls(&rows, &y, &rel_var);
    let corr: Vec<Vec<f64>> = pts
        .iter()
        .enumerate()
        .map(|(a, pa)| {
            pts.iter()
                .enumerate()
                .map(|(b, pb)| relative_covariance(pa, pb) / (rel_var[a] * rel_var[b]).sqrt())
                .collect()
        })
        .collect();
    let support: Vec<usize> = (0..3).filter(|&t| theta[t] > 0.0).collect();
    let z = Normal::standard().inverse_cdf(0.5 + opts.confidence / 2.0);
    let model: Vec<f64> = rows.iter().map(|r| dot(r, &theta)).collect();
    let residual: f64 = y
        .iter()
        .zip(&model)
        .zip(&sigma)
        .map(|((y, m), s)| ((y - m) / s).powi(2))
        .sum();
    let dof = (pts.len() as f64 - support.len() as f64).max(1.0);
    let reduced_chi2 = residual / dof;
    // Lack of fit widens every interval by the Birge ratio, as in the Allan fit
    // (`super::allan`): the residuals' sum has the expected value `dof` whatever the
    // points' correlation, which only widens its spread.
    let birge_ratio = reduced_chi2.max(1.0).sqrt();
    let readout = |t: usize| {
        let mut cols = support.clone();
        if !cols.contains(&t) {
            cols.push(t);
            cols.sort_unstable();
        }
        let sd = birge_ratio * sandwich_sd(&rows, &sigma, &corr, &cols, t);
        let mut r = interval(theta[t], sd, z, opts.confidence);
        let dominant: Vec<f64> = pts
            .iter()
            .zip(&rows)
            .zip(&model)
            .filter(|((_, row), m)| theta[t] > 0.0 && row[t] * theta[t] >= 0.5 * **m)
            .map(|((p, _), _)| p.public.freq)
            .collect();
        r.bins = dominant.len();
        r.f_min = dominant.first().copied().unwrap_or(0.0);
        r.f_max = dominant.last().copied().unwrap_or(0.0);
        r
    };
    Ok(PsdNoiseTerms {
        n: readout(0),
        b: readout(1),
        k: readout(2),
        confidence: opts.confidence,
        f_min: pts[0].public.freq,
        f_max: pts[pts.len() - 1].public.freq,
        points: pts.len(),
        reduced_chi2,
        birge_ratio,
        segment_len: match opts.segment_len {
            0 => psd::segment_len_for(samples.len()),
            l => l,
        },
        spectrum: all.into_iter().map(|p| p.public).collect(),
    })
}

/// With the sensor's filter known from its settings: every point's basis times the filter's
/// folded power gain at its frequency ([`LowPass::power_gain`], 1 at DC), so N is the white
/// level at DC that the Allan deviation's N is, and the band ends where the spectrum divided
/// by that gain stops being flat. A filter only fitted to the spectrum is not used: its shape
/// is the generic two-pole family's, and a chain that folds aliases back (an ADXL345-like
/// filter at half the rate) rises where that family falls, so dividing by it biases N more
/// than the flat band does.
fn filtered_band_end(points: &mut [Point], lp: &LowPass) -> f64 {
    let mut flattened = Vec::with_capacity(points.len());
    for p in points.iter_mut() {
        let gain = lp.power_gain(p.public.freq);
        p.basis = p.basis.map(|b| b * gain);
        let mut q = p.clone();
        q.public.density /= gain.max(f64::MIN_POSITIVE);
        flattened.push(q);
    }
    white_band_end(&flattened)
}

/// The highest frequency fitted: the end of the longest run of flat points (local log-log
/// slope within [`FLAT_SLOPE`] of 0, over each point and two either side), less
/// [`BAND_END_MARGIN`] points; every point when there is no flat run.
fn white_band_end(points: &[Point]) -> f64 {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.public.freq.ln(), p.public.density.ln()))
        .collect();
    let slopes: Vec<f64> = (0..logs.len())
        .map(|i| ls_slope(&logs[i.saturating_sub(2)..(i + 3).min(logs.len())]))
        .collect();
    match longest_run(&slopes, |s| s.abs() <= FLAT_SLOPE, true) {
        Some(run) if run.len() > BAND_END_MARGIN => {
            points[run.end - 1 - BAND_END_MARGIN].public.freq
        }
        _ => f64::INFINITY,
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Model-weighted non-negative least squares: the weights come from the model of the
/// previous solution (the first from the data), repeated until theta settles. Returns theta
/// and the standard deviations `m_a sqrt(R_aa)`.
fn irls(rows: &[[f64; 3]], y: &[f64], rel_var: &[f64]) -> ([f64; 3], Vec<f64>) {
    // Model values floored at 1e-3 of the data keep every weight finite.
    let sd = |theta: Option<&[f64; 3]>| -> Vec<f64> {
        let level = |a: usize| theta.map_or(y[a], |t| dot(&rows[a], t).max(1e-3 * y[a]));
        (0..y.len()).map(|a| level(a) * rel_var[a].sqrt()).collect()
    };
    let mut theta = nnls3(rows, y, &sd(None));
    for _ in 0..50 {
        let next = nnls3(rows, y, &sd(Some(&theta)));
        let settled = next
            .iter()
            .zip(&theta)
            .all(|(a, b)| (a - b).abs() <= 1e-10 * a.abs().max(*b));
        theta = next;
        if settled {
            break;
        }
    }
    (theta, sd(Some(&theta)))
}

/// Weighted non-negative least squares in three unknowns by exhausting the supports: the
/// optimum is the unconstrained solution on its own support, so it is the best of the
/// feasible support solutions.
fn nnls3(rows: &[[f64; 3]], y: &[f64], sigma: &[f64]) -> [f64; 3] {
    let mut best = ([0.0; 3], f64::INFINITY);
    for mask in 0u8..8 {
        let cols: Vec<usize> = (0..3).filter(|t| mask & (1 << t) != 0).collect();
        let Some(x) = weighted_lstsq(rows, y, sigma, &cols) else {
            continue;
        };
        if x.iter().any(|&v| v < 0.0) {
            continue;
        }
        let cost: f64 = rows
            .iter()
            .zip(y)
            .zip(sigma)
            .map(|((r, y), s)| ((y - dot(r, &x)) / s).powi(2))
            .sum();
        if cost < best.1 {
            best = (x, cost);
        }
    }
    best.0
}

/// The design on `cols`, each row divided by its sigma and each column by its norm; returns
/// it and the norms.
fn normalised_design(
    rows: &[[f64; 3]],
    sigma: &[f64],
    cols: &[usize],
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let g: Vec<Vec<f64>> = rows
        .iter()
        .zip(sigma)
        .map(|(r, s)| cols.iter().map(|&t| r[t] / s).collect())
        .collect();
    let norms: Vec<f64> = (0..cols.len())
        .map(|c| g.iter().map(|row| row[c] * row[c]).sum::<f64>().sqrt())
        .collect();
    let g = g
        .into_iter()
        .map(|row| row.iter().zip(&norms).map(|(v, n)| v / n).collect())
        .collect();
    (g, norms)
}

/// Unconstrained weighted least squares on `cols` (normal equations of the normalised
/// design); `None` when they are singular.
fn weighted_lstsq(rows: &[[f64; 3]], y: &[f64], sigma: &[f64], cols: &[usize]) -> Option<[f64; 3]> {
    let mut x = [0.0; 3];
    if cols.is_empty() {
        return Some(x);
    }
    let (g, norms) = normalised_design(rows, sigma, cols);
    let h = gram(&g, None);
    let rhs: Vec<f64> = (0..cols.len())
        .map(|c| {
            g.iter()
                .zip(y)
                .zip(sigma)
                .map(|((row, y), s)| row[c] * y / s)
                .sum()
        })
        .collect();
    let inv = inverse(&h)?;
    for (c, &t) in cols.iter().enumerate() {
        x[t] = inv[c].iter().zip(&rhs).map(|(a, b)| a * b).sum::<f64>() / norms[c];
    }
    Some(x)
}

/// `G^T G`, or `G^T C G` with a correlation matrix C.
fn gram(g: &[Vec<f64>], corr: Option<&[Vec<f64>]>) -> Vec<Vec<f64>> {
    let k = g.first().map_or(0, Vec::len);
    let mut out = vec![vec![0.0; k]; k];
    for (a, ga) in g.iter().enumerate() {
        for (b, gb) in g.iter().enumerate() {
            let c = match corr {
                Some(c) => c[a][b],
                None if a == b => 1.0,
                None => continue,
            };
            if c == 0.0 {
                continue;
            }
            for (i, row) in out.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v += ga[i] * c * gb[j];
                }
            }
        }
    }
    out
}

/// Standard deviation of theta_t from the sandwich covariance over the columns `cols` (which
/// contain t); infinite when the data cannot separate those columns.
fn sandwich_sd(
    rows: &[[f64; 3]],
    sigma: &[f64],
    corr: &[Vec<f64>],
    cols: &[usize],
    t: usize,
) -> f64 {
    let (g, norms) = normalised_design(rows, sigma, cols);
    let Some(h_inv) = inverse(&gram(&g, None)) else {
        return f64::INFINITY;
    };
    let meat = gram(&g, Some(corr));
    let c = cols.iter().position(|&x| x == t).unwrap_or(0);
    let row = &h_inv[c];
    let var: f64 = (0..cols.len())
        .flat_map(|i| (0..cols.len()).map(move |j| (i, j)))
        .map(|(i, j)| row[i] * meat[i][j] * row[j])
        .sum();
    var.max(0.0).sqrt() / norms[c]
}

/// The coefficient's read-out from its square `theta` with standard deviation `sd` (see the
/// module documentation, Intervals); the frequency range is filled in by the caller.
fn interval(theta: f64, sd: f64, z: f64, confidence: f64) -> PsdReadout {
    let unresolved = PsdReadout {
        value: theta.sqrt(),
        lo: 0.0,
        hi: (theta + z * sd).sqrt(),
        dof: 0.0,
        f_min: 0.0,
        f_max: 0.0,
        bins: 0,
    };
    if !(sd.is_finite() && theta > z * sd) {
        return unresolved;
    }
    let nu = 2.0 * theta * theta / (sd * sd);
    let (Some(upper), Some(lower)) = (
        chi2_quantile(nu, 0.5 + confidence / 2.0),
        chi2_quantile(nu, 0.5 - confidence / 2.0),
    ) else {
        return unresolved;
    };
    PsdReadout {
        lo: (nu * theta / upper).sqrt(),
        hi: (nu * theta / lower).sqrt(),
        dof: nu,
        ..unresolved
    }
}

/// Degrees of freedom above which [`chi2_quantile`] uses the Wilson-Hilferty approximation.
const WILSON_HILFERTY_DOF: f64 = 1000.0;

/// The `p` quantile of chi-squared with `nu` degrees of freedom: statrs' inversion up to
/// [`WILSON_HILFERTY_DOF`], above it Wilson & Hilferty's cube-root normal approximation
/// (Proc. Natl. Acad. Sci. 17, 684, 1931), `nu (1 - 2/(9 nu) + z_p sqrt(2/(9 nu)))^3`,
/// whose relative error is below 1e-5 from there on, where the inversion loses accuracy.
fn chi2_quantile(nu: f64, p: f64) -> Option<f64> {
    if nu > WILSON_HILFERTY_DOF {
        let z = Normal::standard().inverse_cdf(p);
        let a = 2.0 / (9.0 * nu);
        return Some(nu * (1.0 - a + z * a.sqrt()).powi(3));
    }
    let q = ChiSquared::new(nu).ok()?.inverse_cdf(p);
    (q.is_finite() && q > 0.0).then_some(q)
}

#[cfg(test)]
mod tests;

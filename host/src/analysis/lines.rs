//! Spectral lines: tones and narrow resonances on top of a smooth noise background, found in
//! the full-record periodogram of a rate record, with their frequency, amplitude, width and
//! power; and the record with them removed.
//!
//! # Method
//!
//! 1. **Periodograms.** The record minus its least-squares straight line, one FFT of the whole
//!    record: the rectangular-window periodogram `P_k = 2 |X_k|^2 / (f_s n)` (one-sided PSD,
//!    u^2/Hz) at `f_k = k f_s / n`, bin width `df = f_s / n`, and the periodic-Hann one from the
//!    same DFT (`X_k / 2 - (X_{k-1} + X_{k+1}) / 4`, normalised by `sum w^2 = 3 n / 8`). For a
//!    background whose PSD S is smooth over a few bins, each `P_k / S(f_k)` is a standard
//!    exponential (chi-square with 2 degrees of freedom over 2; Percival & Walden, *Spectral
//!    Analysis for Physical Applications*, 1993, sec. 6.6); rectangular bins are independent,
//!    Hann bins correlated with their neighbours but free of leakage beyond +-2 bins of a tone.
//!    Single bins are tested on the Hann periodogram (a strong tone's leakage cannot hide a
//!    weak one or raise the background near it), runs of bins on the rectangular one (their
//!    sums keep an exact distribution). A tone of amplitude A holds `A^2 / 2` of power.
//! 2. **Background**, per periodogram. Bins from 3 up (bins 1 and 2 share power with the
//!    removed line) are cut into blocks 1/40 decade wide (at least 5 bins, at most half the
//!    widest line searched); each block's median over an odd number of bins, divided by
//!    `ln 2`, estimates its level without bias in the median (the median of `2r + 1`
//!    exponentials is `ln 2` at its own median: its distribution function there is the
//!    symmetric Beta(r + 1, r + 1) at 1/2; David & Nagaraja, *Order Statistics*, 2003,
//!    sec. 2.1). A running median over 11 neighbouring blocks removes blocks that a line
//!    raised and keeps any monotone trend (white, flicker, random walk, Gauss-Markov knees, a
//!    low-pass roll-off, quantization's f^2); near the lowest frequencies, where the window
//!    cannot be centred, the levels are first moved along the window's Theil-Sen line in
//!    ln-ln (see `window_level`). The result is interpolated linearly in ln-ln between block
//!    centres. Bins that a first search flagged are left out and the background estimated
//!    again. Its relative variance is taken as `c / n_w` (times the off-centre leverage) plus
//!    `0.03^2` for the background's shape within a block, n_w the bins under the window:
//!    the median of m exponentials has relative variance `1 / (m ln^2 2)`, a median of 11
//!    block medians about `pi / 2` times that over all 11 blocks, so `c ~ 3.3`; measured on
//!    white noise (test `background_calibration`), c = 3.3 for the rectangular and 4.6 for the
//!    Hann periodogram.
//! 3. **Tests at every scale.** Single bins, and runs of `L = 2, 4, 8, ...` bins up to the
//!    widest line searched ([`LineOptions::max_width_hz`], and at most
//!    [`LineOptions::max_relative_width`] of the frequency), overlapping by half, from
//!    [`LineOptions::min_cycles`] cycles per record to below Nyquist: the mean of `P_k / S_k`
//!    over a run is F-distributed with `(2L, nu)` degrees of freedom, `nu = 2 / relative
//!    variance` of the background (a sum of L independent exponentials over an independent
//!    scaled chi-square). The family-wise false-alarm probability
//!    [`LineOptions::false_alarm`] is split (Bonferroni, valid for dependent tests) equally
//!    among the octaves of frequency searched and within an octave among its tests: on a
//!    record without lines the probability of reporting any line at all is at most that, and
//!    the few tests of the lowest octaves, whose background is known least well, keep a
//!    usable threshold. A line passes at many scales and positions: the passing runs are
//!    taken in order of how unlikely they are without a line, each only if it overlaps none
//!    taken before (the best run covers the line's significant part), and the runs taken are
//!    merged into bands when they lie within a quarter of the longer of them.
//! 4. **Tones (CLEAN).** A band whose excess power (on the Hann periodogram) lies mostly within
//!    +-2 bins of its peak is a tone candidate: its frequency is first read from the three
//!    rectangular bins around the peak (Jacobsen & Kootsookos, "Fast, accurate frequency
//!    estimators", IEEE Signal Processing Magazine 24(3), 2007), refined by Newton steps on the
//!    continuous periodogram `|sum x_t e^(-i w t)|^2` (its maximum is the least-squares
//!    frequency; Rife & Boorstyn, "Single-tone parameter estimation from discrete-time
//!    observations", IEEE Trans. Information Theory 20(5), 1974), and the tone's amplitude and
//!    phase are fitted by least squares together with an offset and a slope. The tone is
//!    subtracted in the time domain, leakage and all, and the search is repeated on the rest
//!    (at most 4 rounds), which finds weaker tones that the leakage of strong ones hid and
//!    what is left of a line that is not a pure tone (Roberts, Lehar & Dreher, "Time series
//!    analysis with CLEAN", Astronomical Journal 93, 1987).
//! 5. **What is reported.** Each band is measured on the Hann periodogram over a window
//!    centred on its excess and reaching two interquartile ranges (at least the band's width)
//!    beyond it. A tone: its power `A^2 / 2` plus whatever excess the last round still finds
//!    around it; its frequency, the power-weighted mean of the tone's and that excess's; its
//!    width, that excess's (0 when nothing is left: a pure tone). Any other band: the
//!    frequency where its excess power reaches half of its total; its width the interquartile
//!    range of the excess in frequency (for a Lorentzian line exactly its full width at half
//!    maximum, the quartiles of a Cauchy distribution being the half-maximum points); its
//!    power the excess in the window. Both are corrected for the Lorentzian's tails beyond
//!    the window (see `lorentzian_truncation`). Amplitude is always `sqrt(2 power)`. The
//!    statistic is the excess over the band's bins in standard deviations of the background
//!    there, `sum (P - S) / sqrt(1.944 sum S^2 + (0.03 sum S)^2)` (1.944 for the Hann bins'
//!    correlation).
//!
//! Limits: a line wider than about 1/8 of its frequency is a feature of the background
//! (a Gauss-Markov knee is a line at zero frequency); lines below [`LineOptions::min_cycles`]
//! cycles per record are not searched (the record cannot tell them from a trend); near the
//! lowest frequencies searched few bins estimate the background, so a tone there must be
//! stronger to be found (the module's tests state the detectability). Cost: one FFT of the
//! record and a few O(n) passes per round, plus a few O(n) passes per tone; 0.2-0.3 s for
//! 10^6 samples.

use super::numerics::solve4;
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use serde::Serialize;
use statrs::distribution::{Continuous, ContinuousCDF, FisherSnedecor};
use std::collections::HashMap;
use std::f64::consts::{LN_2, PI};
use std::sync::Arc;

/// One spectral line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Line {
    /// Centre frequency, Hz.
    pub freq_hz: f64,
    /// Peak amplitude of the equivalent sinusoid, `sqrt(2 power)`, in the record's unit u.
    pub amplitude: f64,
    /// Spread of the line's power, Hz: 0 for a pure tone, else the interquartile range of its
    /// excess power in frequency (the full width at half maximum of a Lorentzian line).
    pub width_hz: f64,
    /// Power (variance) the line adds to the record, u^2.
    pub power: f64,
    /// Excess power over the line's bins in standard deviations of the background there.
    pub statistic: f64,
}

/// Settings of [`detect`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LineOptions {
    /// Family-wise false-alarm probability: on a record without lines, the chance that any
    /// line is reported. Default 0.01.
    pub false_alarm: f64,
    /// Lowest frequency searched, in cycles per record. Default 5.
    pub min_cycles: f64,
    /// Widest line searched, Hz. Default 1.
    pub max_width_hz: f64,
    /// Widest line searched as a fraction of its frequency. Default 1/8 (the background's
    /// running median spans about +-30 % of the frequency and must stay mostly off the line).
    pub max_relative_width: f64,
}

impl Default for LineOptions {
    fn default() -> Self {
        LineOptions {
            false_alarm: 0.01,
            min_cycles: 5.0,
            max_width_hz: 1.0,
            max_relative_width: 0.125,
        }
    }
}

/// Why lines could not be searched for; each names the input at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineError {
    #[error("{n} samples: the line search needs at least {needed}")]
    TooShort { n: usize, needed: usize },
    #[error("sample {index} is {value}; the data must be finite")]
    NotFinite { index: usize, value: f64 },
    #[error("sample rate {0} Hz: a positive finite number is needed")]
    BadRate(f64),
    #[error("line option {name} = {value}: {expected}")]
    BadOption {
        name: &'static str,
        value: f64,
        expected: &'static str,
    },
}

/// The lines of a record and the record with them removed ([`remove`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Removed {
    pub lines: Vec<Line>,
    /// The record with the tones subtracted and the excess power of every line's band scaled
    /// down to the background's level (same length, mean and trend as the input).
    pub rate: Vec<f64>,
}

/// Fewest samples searched.
pub const MIN_SAMPLES: usize = 64;
/// Search rounds (tone subtraction and search again).
const MAX_ROUNDS: usize = 4;
/// Blocks of the background per decade, and their fewest bins.
const BLOCKS_PER_DECADE: f64 = 40.0;
const MIN_BLOCK: usize = 5;
/// Half-width of the running median over blocks, in blocks.
const MEDIAN_HALF_WIDTH: usize = 5;
/// Relative variance of the background estimate, `c / n_w + SHAPE_ERROR^2` (module
/// documentation, step 2), with c for each periodogram.
const RECT_MEDIAN_VARIANCE: f64 = 3.3;
const HANN_MEDIAN_VARIANCE: f64 = 4.6;
const SHAPE_ERROR: f64 = 0.03;
/// A tone's power lies within this many bins of its peak.
const TONE_LOBE: usize = 2;

/// Spectral lines of a rate record sampled at `rate_hz` (module documentation).
pub fn detect(rate: &[f64], rate_hz: f64, opts: &LineOptions) -> Result<Vec<Line>, LineError> {
    Ok(search(rate, rate_hz, opts)?.lines)
}

/// [`detect`], and the record with the lines removed: each tone subtracted, and in each line's
/// band the Fourier coefficients scaled so that the band's power falls to the background's
/// (the background's own fluctuation within the band is kept; only the excess goes).
pub fn remove(rate: &[f64], rate_hz: f64, opts: &LineOptions) -> Result<Removed, LineError> {
    let found = search(rate, rate_hz, opts)?;
    if found.bands.is_empty() {
        return Ok(Removed {
            lines: found.lines,
            rate: found.work,
        });
    }
    let (trend, mut x) = detrend(&found.work);
    let n = x.len();
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let mut spectrum = forward.make_output_vec();
    // Lengths come from the plans, so neither transform can fail.
    forward
        .process(&mut x, &mut spectrum)
        .expect("buffer lengths match the FFT plan");
    let scale = 2.0 / (rate_hz * n as f64);
    for &(a, b) in &found.bands {
        let observed: f64 = spectrum[a..=b].iter().map(|c| c.norm_sqr() * scale).sum();
        let expected: f64 = found.background[a..=b].iter().sum();
        if observed > expected && observed > 0.0 {
            let g = (expected / observed).sqrt();
            spectrum[a..=b].iter_mut().for_each(|c| *c *= g);
        }
    }
    let mut y = inverse.make_output_vec();
    inverse
        .process(&mut spectrum, &mut y)
        .expect("buffer lengths match the FFT plan");
    let rate = y
        .iter()
        .enumerate()
        .map(|(t, v)| v / n as f64 + trend.at(t, n))
        .collect();
    Ok(Removed {
        lines: found.lines,
        rate,
    })
}

/// Share of the background a removed line's wing may still add where a roll-off is fitted.
pub const WING_SHARE: f64 = 0.05;

/// Whether a line's wings still stand out at `f` Hz: its Lorentzian excess (power `power`
/// u^2, full width at half maximum `width_hz` around `freq_hz`) above [`WING_SHARE`] of the
/// one-sided `background` PSD there. The excess is `(2 P / (pi w)) / (1 + (2 (f - f0) / w)^2)`;
/// a pure tone (`width_hz` 0) has none, its power lying in its own bins. A line's removal
/// scales only its core down to the background, and wings that rise towards a line near
/// Nyquist read as quantization over a roll-off.
pub fn wings_stand_out(freq_hz: f64, width_hz: f64, power: f64, f: f64, background: f64) -> bool {
    if width_hz <= 0.0 {
        return false;
    }
    let peak = 2.0 * power / (PI * width_hz);
    peak / (1.0 + (2.0 * (f - freq_hz) / width_hz).powi(2)) > WING_SHARE * background
}

/// A line's Allan variance at `tau` (s). The line is taken as a sinusoid whose phase diffuses
/// (a Lorentzian of full width at half maximum `width_hz` around `freq_hz`), autocovariance
/// `R(s) = P e^(-pi w |s|) cos(2 pi f s)` with `P = amplitude^2 / 2`. With the Allan
/// variance of a process of autocovariance R, `(1/tau^2) [2 int_0^tau (tau - s) R(s) ds -
/// int_0^(2 tau) (tau - |s - tau|) R(s) ds]`, and `lambda = pi w - 2 pi i f`:
///
/// ```text
/// AVAR(tau) = (P / tau^2) Re[ 2 tau / lambda - (3 - 4 e^(-lambda tau) + e^(-2 lambda tau)) / lambda^2 ]
/// ```
///
/// For `w = 0` this is the tone's `A^2 sin^4(pi f tau) / (pi f tau)^2`; for `f = 0` the
/// first-order Gauss-Markov formula (IEEE Std 952-1997, Annex C) with `tau_c = 1 / (pi w)`.
/// For `|lambda tau| < 0.1` the bracket's Taylor series is used (its leading terms cancel).
pub fn line_avar(line: &Line, tau: f64) -> f64 {
    let p = line.amplitude * line.amplitude / 2.0;
    let lambda = Complex::new(PI * line.width_hz.max(0.0), -2.0 * PI * line.freq_hz);
    let u = lambda * tau;
    if tau.is_nan() || tau <= 0.0 || p == 0.0 {
        return 0.0;
    }
    if u.norm() < 0.1 {
        // 3 - 4 e^-u + e^-2u = sum_j c_j u^j with c_j = (-4 (-1)^j + (-2)^j) / j!; c_1 u / lambda^2
        // cancels 2 tau / lambda and c_2 = 0, so AVAR = P Re[-sum_{j>=3} c_j u^(j-2)].
        let mut sum = Complex::new(0.0, 0.0);
        let mut power = u; // u^(j-2)
        let mut factorial = 6.0;
        for j in 3..14 {
            let c = (-4.0 * (-1f64).powi(j) + (-2f64).powi(j)) / factorial;
            sum -= power * c;
            power *= u;
            factorial *= f64::from(j + 1);
        }
        return (p * sum.re).max(0.0);
    }
    let e = (-u).exp();
    let bracket = 2.0 * tau / lambda - (3.0 - 4.0 * e + e * e) / (lambda * lambda);
    (p / (tau * tau) * bracket.re).max(0.0)
}

/// A straight line `mean + slope * (t - (n - 1) / 2)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Trend {
    mean: f64,
    slope: f64,
}

impl Trend {
    fn at(&self, t: usize, n: usize) -> f64 {
        self.mean + self.slope * (t as f64 - (n as f64 - 1.0) / 2.0)
    }
}

/// The least-squares line of `y` and `y` minus it.
pub(crate) fn detrend(y: &[f64]) -> (Trend, Vec<f64>) {
    let n = y.len();
    let centre = (n as f64 - 1.0) / 2.0;
    let mean = super::neumaier_sum(y.iter().copied()) / n as f64;
    let (mut sty, mut stt) = (0.0, 0.0);
    for (t, v) in y.iter().enumerate() {
        let tc = t as f64 - centre;
        sty += tc * (v - mean);
        stt += tc * tc;
    }
    let trend = Trend {
        mean,
        slope: if stt > 0.0 { sty / stt } else { 0.0 },
    };
    let x = y
        .iter()
        .enumerate()
        .map(|(t, v)| v - trend.at(t, n))
        .collect();
    (trend, x)
}

/// A fitted tone `a cos(w t_c) + b sin(w t_c)`, `t_c = t - (n - 1) / 2`, w in rad/sample.
#[derive(Debug, Clone, Copy)]
struct Tone {
    omega: f64,
    a: f64,
    b: f64,
    /// The bin it was found at, and its statistic there.
    bin: usize,
    statistic: f64,
}

impl Tone {
    fn power(&self) -> f64 {
        (self.a * self.a + self.b * self.b) / 2.0
    }
}

/// One band's excess over the background.
#[derive(Debug, Clone, Copy)]
struct Measured {
    /// The bins measured (inclusive).
    lo: usize,
    hi: usize,
    /// Bin of the largest excess.
    peak: usize,
    /// Excess power, u^2.
    power: f64,
    /// Half of the excess lies below this frequency, Hz.
    freq_hz: f64,
    /// Interquartile range of the excess, Hz.
    width_hz: f64,
    statistic: f64,
    /// Half or more of the excess lies within +-TONE_LOBE bins of the peak.
    concentrated: bool,
}

/// What a search found.
struct Found {
    lines: Vec<Line>,
    /// Measured bands of the last round (inclusive bin ranges).
    bands: Vec<(usize, usize)>,
    /// The background of the last round, one-sided PSD per bin.
    background: Vec<f64>,
    /// The record minus the tones.
    work: Vec<f64>,
}

/// The fixed parts of one search: record length, rate, options and the FFT plan.
struct Search<'a> {
    n: usize,
    rate_hz: f64,
    opts: &'a LineOptions,
    fft: Arc<dyn RealToComplex<f64>>,
    /// First and last bin searched.
    k_lo: usize,
    k_hi: usize,
    /// `ln k` for k = 0..=n/2 (`ln 0` unused).
    ln_bin: Vec<f64>,
}

fn validate(rate: &[f64], rate_hz: f64, opts: &LineOptions) -> Result<(), LineError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(LineError::BadRate(rate_hz));
    }
    let checks: [(&'static str, f64, bool, &'static str); 4] = [
        (
            "false_alarm",
            opts.false_alarm,
            opts.false_alarm > 0.0 && opts.false_alarm < 1.0,
            "a probability in (0, 1)",
        ),
        (
            "min_cycles",
            opts.min_cycles,
            opts.min_cycles.is_finite() && opts.min_cycles >= 1.0,
            "at least 1",
        ),
        (
            "max_width_hz",
            opts.max_width_hz,
            opts.max_width_hz.is_finite() && opts.max_width_hz >= 0.0,
            "a finite width >= 0",
        ),
        (
            "max_relative_width",
            opts.max_relative_width,
            opts.max_relative_width > 0.0 && opts.max_relative_width <= 0.25,
            "a fraction in (0, 0.25]",
        ),
    ];
    if let Some(&(name, value, _, expected)) = checks.iter().find(|c| !c.2) {
        return Err(LineError::BadOption {
            name,
            value,
            expected,
        });
    }
    if let Some(index) = rate.iter().position(|v| !v.is_finite()) {
        return Err(LineError::NotFinite {
            index,
            value: rate[index],
        });
    }
    let needed = MIN_SAMPLES.max((4.0 * opts.min_cycles).ceil() as usize + 2 * MIN_BLOCK * 4);
    if rate.len() < needed {
        return Err(LineError::TooShort {
            n: rate.len(),
            needed,
        });
    }
    Ok(())
}

fn search(rate: &[f64], rate_hz: f64, opts: &LineOptions) -> Result<Found, LineError> {
    validate(rate, rate_hz, opts)?;
    let n = rate.len();
    let s = Search {
        n,
        rate_hz,
        opts,
        fft: RealFftPlanner::<f64>::new().plan_fft_forward(n),
        k_lo: (opts.min_cycles.ceil() as usize).max(2),
        // The Nyquist bin of an even length is real (one degree of freedom): not searched.
        k_hi: (n - 1) / 2,
        ln_bin: (0..=n / 2).map(|k| (k as f64).ln()).collect(),
    };
    let mut work = rate.to_vec();
    let mut tones: Vec<Tone> = Vec::new();
    let mut round = 0;
    loop {
        let (trend, x) = detrend(&work);
        let spectra = s.periodograms(&x);
        let (backgrounds, bands) = s.backgrounds_and_bands(&spectra);
        let measured: Vec<Measured> = bands
            .iter()
            .map(|&band| s.measure(&spectra.hann, &backgrounds.hann.level, band, &bands))
            .filter(|m| m.power > 0.0)
            .collect();
        let mut new: Vec<&Measured> = measured
            .iter()
            .filter(|m| m.concentrated && !tones.iter().any(|t| m.lo <= t.bin && t.bin <= m.hi))
            .collect();
        round += 1;
        if new.is_empty() || round == MAX_ROUNDS {
            return Ok(s.assemble(&tones, &measured, backgrounds.rect.level, work));
        }
        new.sort_by(|a, b| b.power.total_cmp(&a.power));
        for m in new {
            let start = m.peak as f64 + jacobsen(&spectra.dft, m.peak);
            if let Some(mut tone) = fit_tone(&work, trend, start * 2.0 * PI / n as f64) {
                tone.bin = m.peak;
                tone.statistic = m.statistic;
                subtract(&mut work, &tone);
                tones.push(tone);
            }
        }
    }
}

/// The DFT of a record and its two periodograms (one-sided PSD, u^2/Hz, k = 0..=n/2).
struct Spectra {
    dft: Vec<Complex<f64>>,
    /// Rectangular window: `2 |X_k|^2 / (f_s n)`.
    rect: Vec<f64>,
    /// Periodic Hann window `w_t = (1 - cos(2 pi t / n)) / 2`, whose DFT is
    /// `X_k / 2 - (X_{k-1} + X_{k+1}) / 4`: `2 |X^H_k|^2 / (f_s sum w^2)`, `sum w^2 = 3 n / 8`.
    hann: Vec<f64>,
}

/// A background for each periodogram.
struct Backgrounds {
    rect: Background,
    hann: Background,
}

/// Complex amplitude correlation of neighbouring Hann-window bins of a smooth spectrum
/// (`-2/3` at lag 1, `1/6` at lag 2) makes the variance of a sum of their powers
/// `1 + 2 (4/9 + 1/36)` times that of independent bins.
const HANN_SUM_VARIANCE: f64 = 1.0 + 2.0 * (4.0 / 9.0 + 1.0 / 36.0);

impl Search<'_> {
    fn df(&self) -> f64 {
        self.rate_hz / self.n as f64
    }

    /// The widest line searched, in bins.
    fn widest(&self) -> usize {
        ((self.opts.max_width_hz / self.df()).floor() as usize).max(1)
    }

    fn periodograms(&self, x: &[f64]) -> Spectra {
        let mut input = x.to_vec();
        let mut dft = self.fft.make_output_vec();
        self.fft
            .process(&mut input, &mut dft)
            .expect("buffer lengths match the FFT plan");
        let n = self.n as f64;
        let rect_scale = 2.0 / (self.rate_hz * n);
        let hann_scale = 2.0 / (self.rate_hz * 3.0 * n / 8.0);
        let last = dft.len() - 1;
        // X_{-1} = conj(X_1); past the end, X_{n/2 + 1} = conj(X_{n/2 - 1}) (even n) or
        // conj(X_{(n-1)/2}) (odd n).
        let at = |k: isize| -> Complex<f64> {
            if k < 0 {
                dft[(-k) as usize].conj()
            } else if k as usize > last {
                let mirror = if self.n.is_multiple_of(2) {
                    2 * last - k as usize
                } else {
                    2 * last + 1 - k as usize
                };
                dft[mirror].conj()
            } else {
                dft[k as usize]
            }
        };
        let hann = (0..=last as isize)
            .map(|k| (0.5 * at(k) - 0.25 * (at(k - 1) + at(k + 1))).norm_sqr() * hann_scale)
            .collect();
        let rect = dft.iter().map(|c| c.norm_sqr() * rect_scale).collect();
        Spectra { dft, rect, hann }
    }

    /// The backgrounds (two passes: the second leaves out what the first flagged) and the
    /// bands that stand out of them.
    fn backgrounds_and_bands(&self, spectra: &Spectra) -> (Backgrounds, Vec<(usize, usize)>) {
        let mut mask = vec![false; spectra.rect.len()];
        let widest = self.widest();
        let estimate = |mask: &[bool]| Backgrounds {
            rect: background(
                &spectra.rect,
                mask,
                &self.ln_bin,
                self.k_hi,
                widest,
                RECT_MEDIAN_VARIANCE,
            ),
            hann: background(
                &spectra.hann,
                mask,
                &self.ln_bin,
                self.k_hi,
                widest,
                HANN_MEDIAN_VARIANCE,
            ),
        };
        let first = estimate(&mask);
        let bands = self.bands(spectra, &first);
        if bands.is_empty() {
            return (first, bands);
        }
        for &(a, b) in &bands {
            let (lo, hi) = self.widen(a, b, &[]);
            mask[lo..=hi].iter_mut().for_each(|m| *m = true);
        }
        let second = estimate(&mask);
        let bands = self.bands(spectra, &second);
        (second, bands)
    }

    /// Bins of `[a, b]` widened by its own width (at least TONE_LOBE) on each side, within the
    /// searched range and short of the neighbouring bands.
    fn widen(&self, a: usize, b: usize, others: &[(usize, usize)]) -> (usize, usize) {
        let extra = (b - a + 1).max(TONE_LOBE);
        self.clip(a.saturating_sub(extra), b + extra, (a, b), others)
    }

    /// `[lo, hi]` within the searched range and short of the bands in `others` other than
    /// `band` (halfway to each).
    fn clip(
        &self,
        lo: usize,
        hi: usize,
        band: (usize, usize),
        others: &[(usize, usize)],
    ) -> (usize, usize) {
        let (a, b) = band;
        let mut lo = lo.max(self.k_lo);
        let mut hi = hi.min(self.k_hi);
        for &(c, d) in others {
            if d < a {
                lo = lo.max((d + a) / 2 + 1);
            } else if c > b {
                hi = hi.min((b + c) / 2);
            }
        }
        (lo, hi.max(lo))
    }

    /// Runs of L bins whose mean ratio to the background passes the F-test (single bins on
    /// the Hann periodogram, longer runs on the rectangular one). The false-alarm probability
    /// is shared equally among the octaves of frequency searched and, within an octave, among
    /// its tests. A line passes at many scales and positions: the passing runs are taken in
    /// order of [`surprise`], each only if it overlaps none taken before (a matched filter:
    /// the best run covers the line's significant part), and the runs taken are merged into
    /// bands (inclusive bin ranges).
    fn bands(&self, spectra: &Spectra, bg: &Backgrounds) -> Vec<(usize, usize)> {
        let (k_lo, k_hi) = (self.k_lo, self.k_hi);
        if k_hi < k_lo {
            return Vec::new();
        }
        let mut cum = vec![0.0; k_hi - k_lo + 2];
        for k in k_lo..=k_hi {
            cum[k - k_lo + 1] = cum[k - k_lo] + spectra.rect[k] / bg.rect.level[k];
        }
        let widest = self.widest();
        let scales: Vec<usize> = std::iter::successors(Some(1usize), |l| Some(l * 2))
            .take_while(|&l| l <= widest)
            .collect();
        let allowed = |j: usize, l: usize| {
            l == 1 || l as f64 <= self.opts.max_relative_width * (j as f64 + (l as f64 - 1.0) / 2.0)
        };
        let runs = |l: usize| {
            let step = (l / 2).max(1);
            (k_lo..)
                .step_by(step)
                .take_while(move |&j| j + l - 1 <= k_hi)
                .filter(move |&j| allowed(j, l))
        };
        let octave = |j: usize, l: usize| (j + l / 2).ilog2() as usize;
        let mut per_octave = vec![0usize; k_hi.ilog2() as usize + 1];
        for &l in &scales {
            for j in runs(l) {
                per_octave[octave(j, l)] += 1;
            }
        }
        let octaves = per_octave.iter().filter(|&&c| c > 0).count().max(1);
        let mut thresholds = Thresholds::default();
        // Passing tests as (surprise, first bin, length): ranked by how unlikely they are
        // without a line, so that each line is located by the run that fits it best.
        let mut passed: Vec<(f64, usize, usize)> = Vec::new();
        for &l in &scales {
            for j in runs(l) {
                let o = octave(j, l);
                let level = self.opts.false_alarm / (octaves * per_octave[o]) as f64;
                let centre = j + l / 2;
                let (mean, background) = if l == 1 {
                    (spectra.hann[j] / bg.hann.level[j], &bg.hann)
                } else {
                    ((cum[j + l - k_lo] - cum[j - k_lo]) / l as f64, &bg.rect)
                };
                let v = background.rel_var[centre];
                // Every threshold lies beyond two standard deviations (level < 1 %): most runs
                // are settled without one.
                if mean <= 1.0 + 2.0 * (1.0 / l as f64 + v).sqrt() {
                    continue;
                }
                if mean > thresholds.get(l, background.bucket[centre], o, level) {
                    passed.push((surprise(mean, l, v), j, l));
                }
            }
        }
        // The best run first; a run that overlaps one already taken adds nothing.
        passed.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut marked = vec![false; k_hi - k_lo + 1];
        for &(_, j, l) in &passed {
            let run = &mut marked[j - k_lo..j - k_lo + l];
            if !run.iter().any(|&m| m) {
                run.iter_mut().for_each(|m| *m = true);
            }
        }
        merge_runs(&marked, k_lo)
    }

    /// The excess of one band over the background, on the Hann periodogram (no leakage
    /// beyond +-2 bins of a tone).
    fn measure(
        &self,
        power: &[f64],
        background: &[f64],
        band: (usize, usize),
        others: &[(usize, usize)],
    ) -> Measured {
        let df = self.df();
        let (lo, hi) = self.widen(band.0, band.1, others);
        let first = Excess::of(power, background, lo, hi, df);
        // Again on a window centred on the line, reaching two widths beyond its quartiles
        // (a band found off-centre would bias the centre and width towards its own side).
        let reach =
            (((band.1 - band.0 + 1) as f64).max(2.0 * first.iqr).ceil() as usize).max(TONE_LOBE);
        let centre = (first.centre.round().max(0.0) as usize).clamp(lo, hi);
        let (lo, hi) = self.clip(centre.saturating_sub(reach), centre + reach, band, others);
        let e = Excess::of(power, background, lo, hi, df);
        let (width, fraction) = lorentzian_truncation(
            e.iqr,
            e.centre - (lo as f64 - 0.5),
            hi as f64 + 0.5 - e.centre,
        );
        let near: f64 = (e.peak.saturating_sub(TONE_LOBE).max(lo)..=(e.peak + TONE_LOBE).min(hi))
            .map(|k| (power[k] - background[k]) * df)
            .sum();
        let (lo, hi, peak, total, centre) = (lo, hi, e.peak, e.total, e.centre);
        let (band_lo, band_hi) = band;
        let sum_s: f64 = background[band_lo..=band_hi].iter().sum();
        let sum_s2: f64 = background[band_lo..=band_hi].iter().map(|s| s * s).sum();
        let sum_p: f64 = power[band_lo..=band_hi].iter().sum();
        let spread = (HANN_SUM_VARIANCE * sum_s2 + (SHAPE_ERROR * sum_s).powi(2)).sqrt();
        Measured {
            lo,
            hi,
            peak,
            power: total / fraction,
            freq_hz: centre * df,
            width_hz: width * df,
            statistic: (sum_p - sum_s) / spread,
            concentrated: total > 0.0 && near >= 0.5 * total,
        }
    }

    /// Lines from the fitted tones and the last round's bands.
    fn assemble(
        &self,
        tones: &[Tone],
        measured: &[Measured],
        background: Vec<f64>,
        work: Vec<f64>,
    ) -> Found {
        // Each band left after the tones belongs to the strongest tone inside it (its
        // residual: the line's width), or else is a line of its own.
        let mut used = vec![false; measured.len()];
        let mut order: Vec<usize> = (0..tones.len()).collect();
        order.sort_by(|&a, &b| tones[b].power().total_cmp(&tones[a].power()));
        let mut lines: Vec<Line> = Vec::with_capacity(tones.len() + measured.len());
        for &i in &order {
            let t = &tones[i];
            let rest = measured
                .iter()
                .zip(&used)
                .position(|(m, u)| !*u && m.lo <= t.bin + TONE_LOBE && t.bin <= m.hi + TONE_LOBE);
            let tone_hz = t.omega * self.rate_hz / (2.0 * PI);
            let (extra, width, rest_hz) = match rest {
                Some(i) => {
                    used[i] = true;
                    let m = &measured[i];
                    (m.power, m.width_hz, m.freq_hz)
                }
                None => (0.0, 0.0, tone_hz),
            };
            let power = t.power() + extra;
            lines.push(Line {
                // Power-weighted: the tone's frequency when it holds the line's power, the
                // rest's centre when the tone was only a peak of a wider line.
                freq_hz: (t.power() * tone_hz + extra * rest_hz) / power,
                amplitude: (2.0 * power).sqrt(),
                width_hz: width,
                power,
                statistic: t.statistic,
            });
        }
        lines.extend(
            measured
                .iter()
                .zip(&used)
                .filter(|(_, u)| !**u)
                .map(|(m, _)| Line {
                    freq_hz: m.freq_hz,
                    amplitude: (2.0 * m.power).sqrt(),
                    width_hz: m.width_hz,
                    power: m.power,
                    statistic: m.statistic,
                }),
        );
        lines.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
        Found {
            lines,
            bands: measured.iter().map(|m| (m.lo, m.hi)).collect(),
            background,
            work,
        }
    }
}

/// The excess of a periodogram over its background in bins `lo..=hi`: total power (u^2), the
/// bin of its largest value, and its median and interquartile range in bins (bin k covers
/// `[k - 1/2, k + 1/2)`).
struct Excess {
    total: f64,
    peak: usize,
    centre: f64,
    iqr: f64,
}

impl Excess {
    fn of(power: &[f64], background: &[f64], lo: usize, hi: usize, df: f64) -> Excess {
        let excess: Vec<f64> = (lo..=hi).map(|k| (power[k] - background[k]) * df).collect();
        let total: f64 = excess.iter().sum();
        let peak = lo
            + excess
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map_or(0, |(i, _)| i);
        let quantile = |q: f64| -> f64 {
            let target = q * total;
            let mut acc = 0.0;
            for (i, &e) in excess.iter().enumerate() {
                if e > 0.0 && acc + e >= target {
                    return (lo + i) as f64 - 0.5 + (target - acc) / e;
                }
                acc += e;
            }
            hi as f64 + 0.5
        };
        Excess {
            total,
            peak,
            centre: quantile(0.5),
            iqr: (quantile(0.75) - quantile(0.25)).max(0.0),
        }
    }
}

/// About `-ln P(mean > r)` without a line, for the mean ratio r of L bins to a background of
/// relative variance v: for one bin, exactly `(nu / 2) ln(1 + 2 r / nu)` (F(2, nu) with
/// `nu = 2 / v`); for L bins, the Chernoff exponent of a mean of L exponentials,
/// `L (r - 1 - ln r)`, combined with the background's `(r - 1)^2 / (2 v)` as variances add
/// (both are `(r - 1)^2 / (2 sd^2)` for small excess). Only ranks runs against each other.
fn surprise(r: f64, l: usize, v: f64) -> f64 {
    if r <= 1.0 {
        return 0.0;
    }
    if l == 1 {
        let nu = 2.0 / v;
        return nu / 2.0 * (1.0 + 2.0 * r / nu).ln();
    }
    let sampling = l as f64 * (r - 1.0 - r.ln());
    let background = (r - 1.0).powi(2) / (2.0 * v);
    1.0 / (1.0 / sampling + 1.0 / background)
}

/// Width and contained fraction of a Lorentzian (Cauchy) line of which only `[-a, b]` bins
/// around its centre were measured, from the interquartile range `iqr` (bins) of the measured
/// part. With half-width g, `A = atan(a/g)`, `B = atan(b/g)`, the truncated quantiles are
/// `x_q = g tan(q (A + B) - A)`; g is solved from `x_0.75 - x_0.25 = iqr` (bisection; the
/// IQR grows with g) and the fraction is `(A + B) / pi`. Returns (full width 2g, fraction);
/// an IQR under 1.5 bins is a line the bins do not resolve: (iqr, 1).
fn lorentzian_truncation(iqr: f64, a: f64, b: f64) -> (f64, f64) {
    if iqr < 1.5 || a <= 0.0 || b <= 0.0 {
        return (iqr, 1.0);
    }
    let model = |g: f64| {
        let (aa, bb) = ((a / g).atan(), (b / g).atan());
        let x = |q: f64| g * (q * (aa + bb) - aa).tan();
        (x(0.75) - x(0.25), (aa + bb) / PI)
    };
    let (mut lo, mut hi) = (1e-3, 1e3 * (a + b));
    if model(hi).0 <= iqr {
        // Flatter than any Lorentzian within the band: not that shape; no correction.
        return (iqr, 1.0);
    }
    for _ in 0..100 {
        let mid = (lo * hi).sqrt();
        if model(mid).0 < iqr {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (2.0 * hi, model(hi).1)
}

/// Marked bins (index 0 is bin `first`) as inclusive bin ranges; runs that touch or lie
/// within a quarter of the longer run (at least 2 bins) of each other are one band (a line's
/// wing that dipped below the threshold for a few bins).
fn merge_runs(marked: &[bool], first: usize) -> Vec<(usize, usize)> {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut i = 0;
    while i < marked.len() {
        if !marked[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i < marked.len() && marked[i] {
            i += 1;
        }
        let run = (first + start, first + i - 1);
        match runs.last_mut() {
            Some(last) => {
                let gap = run.0 - last.1 - 1;
                let longer = (last.1 - last.0 + 1).max(run.1 - run.0 + 1);
                if gap <= (longer / 4).max(2) {
                    last.1 = run.1;
                } else {
                    runs.push(run);
                }
            }
            None => runs.push(run),
        }
    }
    runs
}

/// F-test thresholds on the mean ratio of L bins to the background, by L, by the background's
/// degrees of freedom (as a [`Background::bucket`]) and by octave (each has its own level),
/// computed when first needed.
#[derive(Default)]
struct Thresholds {
    cache: HashMap<(usize, i32, usize), f64>,
    /// The last key asked for and its threshold (neighbouring tests share them).
    last: Option<((usize, i32, usize), f64)>,
}

/// Ratio of the grid on which the background's degrees of freedom are rounded down (which
/// errs on the cautious side).
const DOF_GRID: f64 = 1.25;

impl Thresholds {
    fn get(&mut self, l: usize, bucket: i32, octave: usize, level: f64) -> f64 {
        let key = (l, bucket, octave);
        if let Some((k, t)) = self.last
            && k == key
        {
            return t;
        }
        let t = *self.cache.entry(key).or_insert_with(|| {
            let nu = 2.0 * DOF_GRID.powi(bucket);
            f_threshold(2.0 * l as f64, nu, level)
        });
        self.last = Some((key, t));
        t
    }
}

/// The x with `P(F(d1, d2) > x) = p`. For `d1 = 2` in closed form, `(d2/2)(p^(-2/d2) - 1)`;
/// otherwise Newton's method on `ln P(F > x)` in `ln x` (its derivative is `-x pdf / sf`),
/// kept inside a bracket by bisection, on statrs' survival function.
fn f_threshold(d1: f64, d2: f64, p: f64) -> f64 {
    if d1 == 2.0 {
        return d2 / 2.0 * (p.powf(-2.0 / d2) - 1.0);
    }
    let Ok(f) = FisherSnedecor::new(d1, d2) else {
        return f64::INFINITY;
    };
    let target = p.ln();
    let excess = |u: f64| f.sf(u.exp()).ln() - target;
    // Bracket in u = ln x: excess(lo) > 0 > excess(hi).
    let (mut lo, mut hi) = (0.0f64, 0.25f64);
    while excess(hi) > 0.0 {
        lo = hi;
        hi *= 2.0;
        if hi > 60.0 {
            return hi.exp();
        }
    }
    let mut u = 0.5 * (lo + hi);
    for _ in 0..60 {
        let x = u.exp();
        let sf = f.sf(x);
        let e = sf.ln() - target;
        if e > 0.0 {
            lo = u;
        } else {
            hi = u;
        }
        let slope = -x * f.pdf(x) / sf;
        let newton = u - e / slope;
        let next = if slope < 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - u).abs() < 1e-9 || hi - lo < 1e-9 {
            return next.exp();
        }
        u = next;
    }
    u.exp()
}

/// A smooth background PSD per bin, the relative variance of its estimate, and the degrees of
/// freedom `nu = 2 / rel_var` of the scaled chi-square that stands for it, rounded down to
/// the grid `2 DOF_GRID^bucket`.
struct Background {
    level: Vec<f64>,
    rel_var: Vec<f64>,
    bucket: Vec<i32>,
}

impl Background {
    fn new(level: Vec<f64>, rel_var: Vec<f64>) -> Self {
        let step = DOF_GRID.ln();
        let bucket = rel_var
            .iter()
            .map(|v| ((1.0 / v).max(1.0).ln() / step).floor() as i32)
            .collect();
        Background {
            level,
            rel_var,
            bucket,
        }
    }
}

/// The running-median background of `power` over bins 3..=k_hi, leaving out masked bins
/// (module documentation, step 2); `median_variance` is the constant c of its relative
/// variance `c / n_w`.
fn background(
    power: &[f64],
    mask: &[bool],
    ln_bin: &[f64],
    k_hi: usize,
    widest: usize,
    median_variance: f64,
) -> Background {
    // Blocks 1/40 decade wide, at least MIN_BLOCK bins and at most half the widest line:
    // (ln centre bin, ln level, bins used).
    let growth = 10f64.powf(1.0 / BLOCKS_PER_DECADE) - 1.0;
    let most = (widest / 2).max(MIN_BLOCK);
    let mut blocks: Vec<(f64, f64, usize)> = Vec::new();
    // Bins 1 and 2 share power with the mean and slope the search removes first.
    let mut start = 3;
    let mut values = Vec::new();
    while start <= k_hi {
        let width = ((start as f64 * growth) as usize).clamp(MIN_BLOCK, most);
        let end = (start + width).min(k_hi + 1);
        values.clear();
        values.extend((start..end).filter(|&k| !mask[k]).map(|k| power[k]));
        if values.len() * 2 >= end - start && values.len() >= 3 {
            // An odd count, so that the median is one order statistic.
            let m = values.len() - (1 - values.len() % 2);
            let (_, median, _) = values[..m].select_nth_unstable_by(m / 2, f64::total_cmp);
            let level = *median / LN_2;
            if level > 0.0 {
                let centre = 0.5 * (start + end - 1) as f64;
                blocks.push((centre.ln(), level.ln(), m));
            }
        }
        start = end;
    }
    let smoothed: Vec<(f64, f64, f64)> = (0..blocks.len())
        .map(|i| {
            // Near the lowest frequencies the window is pushed up (few bins there; see
            // window_level); near Nyquist it shrinks, staying centred (many bins there, and
            // a low-pass filter can bend the spectrum sharply).
            let last = blocks.len() - 1;
            let h = MEDIAN_HALF_WIDTH.min(last - i);
            let span = (2 * h + 1).min(blocks.len());
            let first = i.saturating_sub(h).min(blocks.len() - span);
            let window = &blocks[first..first + span];
            let bins: usize = window.iter().map(|b| b.2).sum();
            let (level, leverage) = window_level(window, i - first);
            let rel_var = median_variance / bins as f64 * leverage + SHAPE_ERROR * SHAPE_ERROR;
            (blocks[i].0, level, rel_var)
        })
        .collect();
    let mut level = vec![f64::MIN_POSITIVE; power.len()];
    let mut rel_var = vec![1.0; power.len()];
    if smoothed.is_empty() {
        return Background::new(level, rel_var);
    }
    let mut i = 0;
    for (k, &x) in ln_bin.iter().enumerate().skip(1) {
        while i + 1 < smoothed.len() && smoothed[i + 1].0 <= x {
            i += 1;
        }
        let (ln_level, var) = if x <= smoothed[0].0 {
            (smoothed[0].1, smoothed[0].2)
        } else if i + 1 >= smoothed.len() {
            (smoothed[i].1, smoothed[i].2)
        } else {
            let (a, b) = (smoothed[i], smoothed[i + 1]);
            let w = (x - a.0) / (b.0 - a.0);
            (a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2))
        };
        level[k] = ln_level.exp().max(f64::MIN_POSITIVE);
        rel_var[k] = var;
    }
    Background::new(level, rel_var)
}

/// The background's ln level at block `at` of a window of blocks (ln centre, ln level), and
/// the factor by which its variance exceeds that at the window's centre. A window centred on
/// `at` gives its median (exact for any monotone trend). A window that the ends of the
/// spectrum push off-centre gives the median of the levels moved along the window's
/// Theil-Sen line in ln-ln (the median of pairwise slopes; Sen, "Estimates of the regression
/// coefficient based on Kendall's tau", JASA 63, 1968), so that a power law is not read
/// off-centre; its variance grows as for a line fitted by least squares, `1 + 3 x^2`, x the
/// offset from the window's centre in half-widths.
fn window_level(window: &[(f64, f64, usize)], at: usize) -> (f64, f64) {
    let mid = window.len() / 2;
    let mut levels: Vec<f64> = window.iter().map(|b| b.1).collect();
    if at == mid || window.len() < 3 {
        let half = levels.len() / 2;
        let (_, median, _) = levels.select_nth_unstable_by(half, f64::total_cmp);
        return (*median, 1.0);
    }
    let mut slopes = Vec::with_capacity(window.len() * (window.len() - 1) / 2);
    for i in 0..window.len() {
        for j in i + 1..window.len() {
            slopes.push((window[j].1 - window[i].1) / (window[j].0 - window[i].0));
        }
    }
    let half = slopes.len() / 2;
    let (_, slope, _) = slopes.select_nth_unstable_by(half, f64::total_cmp);
    let slope = *slope;
    let x0 = window[at].0;
    for (l, b) in levels.iter_mut().zip(window) {
        *l -= slope * (b.0 - x0);
    }
    let half = levels.len() / 2;
    let (_, median, _) = levels.select_nth_unstable_by(half, f64::total_cmp);
    let offset = (at as f64 - mid as f64) / mid.max(1) as f64;
    (*median, 1.0 + 3.0 * offset * offset)
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
    );
    let tone = fit_at(rate, w)?;
    Some((tone.omega * rate_hz / (2.0 * PI), tone.a.hypot(tone.b)))
}

/// Jacobsen's fractional-bin offset of a tone near bin k from the rectangular-window DFT:
/// `-Re[(X_{k+1} - X_{k-1}) / (2 X_k - X_{k-1} - X_{k+1})]`, clipped to +-1 bin.
fn jacobsen(dft: &[Complex<f64>], k: usize) -> f64 {
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
fn for_each_phasor(n: usize, omega: f64, mut f: impl FnMut(usize, f64, f64, f64)) {
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
fn fit_tone(y: &[f64], trend: Trend, omega: f64) -> Option<Tone> {
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
    })
}

fn subtract(y: &mut [f64], tone: &Tone) {
    let n = y.len();
    for_each_phasor(n, tone.omega, |t, _, c, s| {
        y[t] -= tone.a * c + tone.b * s;
    });
}

#[cfg(test)]
mod tests;

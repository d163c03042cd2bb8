//! Spectral lines: tones and narrow resonances on top of a smooth noise background, found in
//! the full-record periodogram of a rate record, with their frequency, amplitude, width and
//! power; and the record with them removed.
//!
//! # Method
//!
//! 1. **Periodograms.** The record minus its least-squares straight line, one FFT of the whole
//!    record (from [`SQUARE_MIN_SAMPLES`] on, of its first `2 m^2` samples, all but a few
//!    tenths of a percent of it, transformed in place: see `transform`): the
//!    rectangular-window periodogram `P_k = 2 |X_k|^2 / (f_s n)` (one-sided PSD,
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
//!    centres. Where the levels fall ever more steeply to the last block (the zero at Nyquist
//!    of a digital filter run at the output rate: a bilinear filter's PSD falls as
//!    `cos^4(pi f / f_s)`), the chord between centres would lie up to a factor 4 below the
//!    curve, so blocks there are halved (down to the least block, at most eight times) until
//!    the chord, an eighth of the levels' second difference, stays within the shape error
//!    below or within four standard deviations of its own noise; a line's flank, which levels
//!    out again beyond it, is not split. Bins that a first search flagged are left out and the background estimated
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
//!    beyond it. A tone: its power `A^2 / 2` plus the excess the last round still finds
//!    around it, when the tone lies within that excess's half-power width of its centre (a
//!    strong line's window can reach a separate tone on a steep background); its frequency, the power-weighted mean of the tone's and that excess's; its
//!    width, that excess's (0 when nothing is left: a pure tone). Any other band: the
//!    frequency where its excess power reaches half of its total; its width the interquartile
//!    range of the excess in frequency (for a Lorentzian line exactly its full width at half
//!    maximum, the quartiles of a Cauchy distribution being the half-maximum points); its
//!    power the excess in the window. All three are corrected for the Lorentzian's tails
//!    beyond the window (see `lorentzian_truncation`; a window cut short on one side pulls
//!    the median to the other). A resolved line's wings reach past its band into the
//!    background's running median and raise it there; so the background is estimated again
//!    with each resolved line's measured Lorentzian, and its images that sampling folds in
//!    (mirrored about Nyquist and about zero), taken out of every bin, and the bands measured
//!    again against that background plus their own images (twice; lines wider than
//!    [`LineOptions::max_relative_width`] of their frequency are left as measured, their
//!    wings filling the median's window). Amplitude is always `sqrt(2 power)`. The
//!    statistic is the excess over the band's bins in standard deviations of the background
//!    there, `sum (P - S) / sqrt(1.944 sum S^2 + (0.03 sum S)^2)` (1.944 for the Hann bins'
//!    correlation).
//! 6. **Standard errors** ([`Line::standard_errors`], `uncertainty`). A pure tone's are the
//!    Cramer-Rao bounds of a sinusoid in white noise at the rectangular periodogram's
//!    background S there (the noise the whole-record least-squares fit sees): `sd(A) =
//!    sqrt(S / T)`, `sd(f) = sqrt(12 S / T^3) / (2 pi A)`, T the record's length; its width
//!    has none. A band's come from a parametric bootstrap: 100 periodograms drawn around it
//!    from what was measured (complex normal DFT bins of mean square background plus the
//!    line's Lorentzian, combined into Hann bins so that neighbours are correlated as in the
//!    record), each measured as the record was; the spread of the draws, and for the power the
//!    background's own relative variance over the window besides. A tone with a measured
//!    excess around it combines both, propagated through the power-weighted frequency. On
//!    120 tones and 40 lines 0.02-1 Hz wide (test `the_stated_errors_match_the_measurement_errors`)
//!    the errors over the stated standard errors have mean squares 0.98 (frequency) and 1.20
//!    (amplitude) for the tones, and 1.03, 0.90 and 0.83 (frequency, amplitude, width) for
//!    the lines.
//!
//! Limits: a line wider than about 1/8 of its frequency is a feature of the background
//! (a Gauss-Markov knee is a line at zero frequency); lines below [`LineOptions::min_cycles`]
//! cycles per record are not searched (the record cannot tell them from a trend); near the
//! lowest frequencies searched few bins estimate the background, so a tone there must be
//! stronger to be found (the module's tests state the detectability). Cost: one FFT of the
//! record and a few O(n) passes per round (the tests of runs shared among threads by chunks
//! of bins), plus a few O(n) passes per tone; 0.2-0.3 s for 10^6 samples, 0.54 s for 10^7 on
//! two cores. Memory: the record's DFT beside the record (and, once a tone is found, the
//! record without its tones).

pub use tone::tone_near;

use background::Background;
use realfft::num_complex::Complex;
use serde::Serialize;
use std::borrow::Cow;
use std::f64::consts::PI;
use tone::{Tone, fit_tone, jacobsen, subtract};
pub use transform::SQUARE_MIN_SAMPLES;
use transform::{InPlace, Transform};

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
    /// The family-wise false-alarm probability at which the search would just have reported
    /// it: the tail probability of its most unlikely test without a line, times the tests
    /// the false-alarm budget is split among (Bonferroni). The chance that a record without
    /// lines shows a line at least this unlikely anywhere in the search is at most this; it
    /// is below [`LineOptions::false_alarm`] for every line reported (0 where it underflows
    /// double precision).
    pub p_value: f64,
    /// Standard errors of `freq_hz`, `amplitude` and `width_hz` (module documentation, step
    /// 6).
    pub standard_errors: LineErrors,
}

/// Standard errors (one standard deviation) of a [`Line`]'s reported values, in their units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LineErrors {
    pub freq_hz: f64,
    pub amplitude: f64,
    /// `None` for a pure tone, whose width (0) is below the resolution `1 / T`.
    pub width_hz: Option<f64>,
}

impl LineErrors {
    /// Errors not known (a line stated rather than measured).
    pub const UNKNOWN: LineErrors = LineErrors {
        freq_hz: f64::NAN,
        amplitude: f64::NAN,
        width_hz: None,
    };
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
    /// Whether to compute each line's [`Line::standard_errors`] (step 6; otherwise
    /// [`LineErrors::UNKNOWN`]). Default true; the model workflow, which searches every
    /// simulated realisation and reads no error, leaves them out.
    pub standard_errors: bool,
}

impl Default for LineOptions {
    fn default() -> Self {
        LineOptions {
            false_alarm: 0.01,
            min_cycles: 5.0,
            max_width_hz: 1.0,
            max_relative_width: 0.125,
            standard_errors: true,
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
/// band the Fourier coefficients scaled bin by bin by the background's share of the measured
/// line's density there, then as a whole until the band's power is the background's (the
/// background's own fluctuation within the band is kept; only the excess goes).
pub fn remove(rate: &[f64], rate_hz: f64, opts: &LineOptions) -> Result<Removed, LineError> {
    let Cleaned { lines, rate, .. } = clean(rate, rate_hz, opts)?;
    Ok(Removed {
        lines,
        rate: rate.into_owned(),
    })
}

/// The lines of a record and the record without them, borrowed when there were none.
#[derive(Debug, Clone, PartialEq)]
pub struct Cleaned<'a> {
    pub lines: Vec<Line>,
    pub rate: Cow<'a, [f64]>,
    /// The frequency ranges (Hz, inclusive) whose excess was scaled down to the background:
    /// a wide line's wings beyond its range are still in `rate`.
    pub bands_hz: Vec<(f64, f64)>,
}

impl Cleaned<'_> {
    /// The record without its lines when there were lines; `None` when it is the record
    /// itself.
    pub fn changed(self) -> Option<Cleaned<'static>> {
        match self.rate {
            Cow::Borrowed(_) => None,
            Cow::Owned(line_free) => Some(Cleaned {
                lines: self.lines,
                rate: Cow::Owned(line_free),
                bands_hz: self.bands_hz,
            }),
        }
    }
}

/// [`remove`] without a copy of a record that has no lines.
pub fn clean<'a>(
    rate: &'a [f64],
    rate_hz: f64,
    opts: &LineOptions,
) -> Result<Cleaned<'a>, LineError> {
    let Found {
        lines,
        bands,
        background,
        work,
        mut spectrum,
        trend,
        transform,
    } = search(rate, rate_hz, opts)?;
    if bands.is_empty() {
        return Ok(Cleaned {
            lines,
            rate: work,
            bands_hz: Vec::new(),
        });
    }
    // `spectrum` is the DFT of the searched samples of `work` less `trend`, from the search's
    // last round.
    let n = transform.len();
    let total = work.len();
    let df = rate_hz / n as f64;
    let bands_hz = bands
        .iter()
        .map(|&(a, b)| (a as f64 * df, b as f64 * df))
        .collect();
    let removal = Removal {
        bands: &bands,
        lines: &lines,
        background: &background,
        n,
        rate_hz,
    };
    // The samples after the searched ones: the same bands scaled down in the DFT of the
    // record's last n samples.
    let tail = (total > n).then(|| {
        let (trend, mut end) = transform.dft_detrended(&work[total - n..], 0);
        removal.apply(&mut end);
        transform.samples(end, trend)[2 * n - total..].to_vec()
    });
    drop(work);
    removal.apply(&mut spectrum);
    let mut y = transform.samples(spectrum, trend);
    y.extend(tail.into_iter().flatten());
    Ok(Cleaned {
        lines,
        rate: Cow::Owned(y),
        bands_hz,
    })
}

/// The removal of the lines' excess from the DFT of `n` searched samples at `rate_hz`.
struct Removal<'a> {
    bands: &'a [(usize, usize)],
    lines: &'a [Line],
    background: &'a Background,
    n: usize,
    rate_hz: f64,
}

impl Removal<'_> {
    /// Scales the DFT bins of each band (inclusive bin ranges) so that the band's excess goes
    /// and its background stays. Each bin is first scaled by `sqrt(S / (S + L))`, S the
    /// background and L the density its measured lines put there (their Lorentzians and
    /// folded images, [`line_density`]): a bin of expected power `S + L` then has expected
    /// power S, so the line's shape leaves the band and the background's own scatter stays.
    /// The band is then scaled as a whole until its power is the background's, which alone
    /// removes what a pure tone's or an unresolved line's bins hold (they have no
    /// Lorentzian) and what a line not shaped like a Lorentzian leaves. A band already at or
    /// below its background is left alone.
    fn apply(&self, spectrum: &mut [Complex<f64>]) {
        let scale = 2.0 / (self.rate_hz * self.n as f64);
        let df = self.rate_hz / self.n as f64;
        let power = |spectrum: &[Complex<f64>], a: usize, b: usize| -> f64 {
            spectrum[a..=b].iter().map(|c| c.norm_sqr() * scale).sum()
        };
        for &(a, b) in self.bands {
            let expected: f64 = (a..=b).map(|k| self.background.level(k)).sum();
            if power(spectrum, a, b) <= expected {
                continue;
            }
            let inside: Vec<&Line> = self
                .lines
                .iter()
                .filter(|l| {
                    l.width_hz > 0.0
                        && (a as f64 - 0.5) * df <= l.freq_hz
                        && l.freq_hz <= (b as f64 + 0.5) * df
                })
                .collect();
            for (k, c) in spectrum.iter_mut().enumerate().take(b + 1).skip(a) {
                let s = self.background.level(k);
                let f = k as f64 * df;
                let excess: f64 = inside
                    .iter()
                    .map(|l| line_density(l.freq_hz, l.width_hz, l.power, self.rate_hz, f))
                    .sum();
                if excess > 0.0 {
                    *c *= (s / (s + excess)).sqrt();
                }
            }
            let observed = power(spectrum, a, b);
            if observed > expected && observed > 0.0 {
                let g = (expected / observed).sqrt();
                spectrum[a..=b].iter_mut().for_each(|c| *c *= g);
            }
        }
    }
}

/// Share of the background that the part of a line's wing its width decides may reach where
/// a roll-off is fitted ([`wings_stand_out`]).
pub const WING_SHARE: f64 = 0.05;

/// Whether a line's wings still stand out at `f` Hz of a roll-off fit that takes the wings'
/// scale as a free parameter ([`crate::analysis::low_pass::Outside::known`]): the part of
/// the Lorentzian ([`lorentzian`]) that an error in its width moves beyond that scale,
/// above [`WING_SHARE`] of the one-sided `background` PSD there. With `x = 2 (f - f0) / w`,
/// `d ln L / d ln w = 1 - 2 / (1 + x^2)`: the constant is the scale's, and
/// `L 2 / (1 + x^2)` what is left, which falls as `1 / x^4` where the wing itself falls as
/// `1 / x^2`. A pure tone (`width_hz` 0) has no wings, its power lying in its own bins.
pub fn wings_stand_out(freq_hz: f64, width_hz: f64, power: f64, f: f64, background: f64) -> bool {
    let x = 2.0 * (f - freq_hz) / width_hz;
    lorentzian(freq_hz, width_hz, power, f) * 2.0 / (1.0 + x * x) > WING_SHARE * background
}

/// The one-sided PSD (u^2/Hz) at `f` Hz of a Lorentzian line of power `power` (u^2), full
/// width at half maximum `width_hz` and centre `freq_hz`: `(2 P / (pi w)) / (1 + (2 (f -
/// f0) / w)^2)`; 0 for a pure tone (`width_hz` 0), whose power lies in its own bins.
pub fn lorentzian(freq_hz: f64, width_hz: f64, power: f64, f: f64) -> f64 {
    if width_hz.is_nan() || width_hz <= 0.0 {
        return 0.0;
    }
    let x = 2.0 * (f - freq_hz) / width_hz;
    2.0 * power / (PI * width_hz) / (1.0 + x * x)
}

/// The one-sided PSD (u^2/Hz) at `f` Hz of a Lorentzian line ([`lorentzian`]) in a record
/// sampled at `rate_hz`: its own Lorentzian plus the images that sampling folds into `[0,
/// rate / 2]`, the one mirrored about Nyquist (centre `rate - f0`) and the one mirrored about
/// zero (`-f0`). A line's samples carry its spectrum periodised over the rate: at Nyquist the
/// mirror adds as much density as the line itself.
pub fn line_density(freq_hz: f64, width_hz: f64, power: f64, rate_hz: f64, f: f64) -> f64 {
    [freq_hz, rate_hz - freq_hz, -freq_hz]
        .iter()
        .map(|&centre| lorentzian(centre, width_hz, power, f))
        .sum()
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

/// A line's Allan variance at `tau = m tau0` in a record sampled every `tau0` s, as the
/// overlapping estimator sees it: the means are of m samples, not integrals over tau, and
/// pass a line at f by the Dirichlet kernel rather than the sinc, `(pi f tau0 / sin(pi f
/// tau0))^2` more than [`line_avar`] (13 % at a fifth of the rate). From the autocovariance
/// at integer lags `R(k) = P Re z^k`, `z = e^(-lambda tau0)`, AVAR is the variance of a mean,
/// `(1/m^2) sum_{|k|<m} (m - |k|) R(k)`, less the covariance of neighbouring means,
/// `(1/m^2) sum_{k=1}^{2m-1} (m - |k - m|) R(k)` (its weights are those of
/// `z (sum_{i<m} z^i)^2`). Summed in closed form:
///
/// ```text
/// AVAR = (P / m^2) [ m (1 - |z|^2) / |1 - z|^2 - Re( z (1 - z^m) (3 - z^m) / (1 - z)^2 ) ]
/// ```
///
/// the first term `Re(m (1 + z) / (1 - z))` written so that it does not cancel (it vanishes
/// for a tone, `|z| = 1`, which leaves `A^2 sin^4(pi f m tau0) / (m sin(pi f tau0))^2`). Where
/// `|lambda tau0| < 0.01` the two differ by under 1e-5 and the continuous form is used (its
/// `1 - z` does not lose digits).
pub fn sampled_line_avar(line: &Line, m: usize, tau0: f64) -> f64 {
    let p = line.amplitude * line.amplitude / 2.0;
    let lambda = Complex::new(PI * line.width_hz.max(0.0), -2.0 * PI * line.freq_hz);
    if m == 0 || p == 0.0 || (lambda * tau0).norm() < 0.01 {
        return line_avar(line, m as f64 * tau0);
    }
    let z = (-lambda * tau0).exp();
    let one = Complex::new(1.0, 0.0);
    let mf = m as f64;
    let zm = (-lambda * (mf * tau0)).exp();
    let damped = mf * (1.0 - z.norm_sqr()) / (one - z).norm_sqr();
    let bounded = (z * (one - zm) * (3.0 * one - zm) / ((one - z) * (one - z))).re;
    (p / (mf * mf) * (damped - bounded)).max(0.0)
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

/// The least-squares line of `y`.
fn line_of(y: &[f64]) -> Trend {
    let n = y.len();
    let centre = (n as f64 - 1.0) / 2.0;
    let mean = super::neumaier_sum(y.iter().copied()) / n as f64;
    let (mut sty, mut stt) = (0.0, 0.0);
    for (t, v) in y.iter().enumerate() {
        let tc = t as f64 - centre;
        sty += tc * (v - mean);
        stt += tc * tc;
    }
    Trend {
        mean,
        slope: if stt > 0.0 { sty / stt } else { 0.0 },
    }
}

/// The least-squares line of `y` and `y` minus it.
pub(crate) fn detrend(y: &[f64]) -> (Trend, Vec<f64>) {
    let n = y.len();
    let trend = line_of(y);
    let x = y
        .iter()
        .enumerate()
        .map(|(t, v)| v - trend.at(t, n))
        .collect();
    (trend, x)
}

/// One band's excess over the background.
#[derive(Debug, Clone, Copy)]
struct Measured {
    /// The band that passed the tests (inclusive bins).
    band: (usize, usize),
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
    /// Family-wise false-alarm probability of the band's best test (`scan::Bands`).
    p_value: f64,
    /// Half or more of the excess lies within +-TONE_LOBE bins of the peak.
    concentrated: bool,
}

/// What a search found.
struct Found<'a> {
    lines: Vec<Line>,
    /// Measured bands of the last round (inclusive bin ranges).
    bands: Vec<(usize, usize)>,
    /// The background of the last round's rectangular periodogram.
    background: Background,
    /// The record minus the tones (the record itself when there were none).
    work: Cow<'a, [f64]>,
    /// The DFT of the searched samples of `work` less `trend`, their least-squares line.
    spectrum: Vec<Complex<f64>>,
    trend: Trend,
    /// The transform that gave `spectrum`.
    transform: Transform,
}

/// The fixed parts of one search: samples searched, rate, options and the DFT.
struct Search<'a> {
    /// Samples searched ([`Transform::len`]): the record's first n.
    n: usize,
    rate_hz: f64,
    opts: &'a LineOptions,
    fft: Transform,
    /// First and last bin searched.
    k_lo: usize,
    k_hi: usize,
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

impl<'a> Search<'a> {
    /// The search of a record of `samples` samples.
    fn new(samples: usize, rate_hz: f64, opts: &'a LineOptions) -> Self {
        let fft = Transform::for_record(samples);
        let n = fft.len();
        Search {
            n,
            rate_hz,
            opts,
            fft,
            k_lo: (opts.min_cycles.ceil() as usize).max(2),
            // The Nyquist bin of an even length is real (one degree of freedom): not searched.
            k_hi: (n - 1) / 2,
        }
    }
}

/// [`clean`] of a record its caller gives up for the search's duration: from
/// [`SQUARE_MIN_SAMPLES`] on, the first round's DFT is taken in `rate`'s own buffer, and when
/// no band stands out of the background (no line, as [`clean`] would find) `rate` is
/// transformed back and `None` returned: the search costs no copy of the record. `rate` then
/// holds the record to the transforms' rounding (within `1e-12` of its largest value, test
/// `a_record_given_up_is_searched_in_place`). When something stands out, `rate` is restored
/// and [`clean`] searches it again; the record without its lines is returned (`None` when
/// that search finds none after all). Below [`SQUARE_MIN_SAMPLES`] this is [`clean`].
pub fn clean_in_place(
    rate: &mut Vec<f64>,
    rate_hz: f64,
    opts: &LineOptions,
) -> Result<Option<Cleaned<'static>>, LineError> {
    validate(rate, rate_hz, opts)?;
    let s = Search::new(rate.len(), rate_hz, opts);
    if let Some(in_place) = s.fft.dft_in_place(rate) {
        let InPlace { trend, dft, tail } = in_place;
        let spectra = s.periodograms(dft);
        let (backgrounds, bands) = s.backgrounds_and_bands(&spectra);
        let quiet = s.measure_bands(&spectra, &backgrounds, &bands).is_empty();
        drop(backgrounds);
        *rate = s.fft.restore(InPlace {
            trend,
            dft: spectra.dft,
            tail,
        });
        if quiet {
            return Ok(None);
        }
    }
    Ok(clean(rate, rate_hz, opts)?.changed())
}

fn search<'a>(rate: &'a [f64], rate_hz: f64, opts: &LineOptions) -> Result<Found<'a>, LineError> {
    validate(rate, rate_hz, opts)?;
    let s = Search::new(rate.len(), rate_hz, opts);
    let n = s.n;
    let mut work = Cow::Borrowed(rate);
    let mut tones: Vec<Tone> = Vec::new();
    let mut round = 0;
    loop {
        let (trend, dft) = s.fft.dft_detrended(&work, rate.len());
        let spectra = s.periodograms(dft);
        let (backgrounds, bands) = s.backgrounds_and_bands(&spectra);
        let measured = s.measure_bands(&spectra, &backgrounds, &bands);
        let mut new: Vec<&Measured> = measured
            .iter()
            .filter(|m| m.concentrated && !tones.iter().any(|t| m.lo <= t.bin && t.bin <= m.hi))
            .collect();
        round += 1;
        if new.is_empty() || round == MAX_ROUNDS {
            let (backgrounds, measured) = s.remeasure_wide(&spectra, &bands, backgrounds, measured);
            let lines = s.assemble(&tones, &measured, &backgrounds, &bands.ranges);
            return Ok(Found {
                lines,
                bands: measured.iter().map(|m| (m.lo, m.hi)).collect(),
                background: backgrounds.rect,
                work,
                spectrum: spectra.dft,
                trend,
                transform: s.fft,
            });
        }
        new.sort_by(|a, b| b.power.total_cmp(&a.power));
        // Tones are fitted to, and subtracted from, the whole record.
        let whole = if n == work.len() {
            trend
        } else {
            line_of(&work)
        };
        for m in new {
            let start = m.peak as f64 + jacobsen(&spectra.dft, m.peak);
            if let Some(mut tone) = fit_tone(&work, whole, start * 2.0 * PI / n as f64) {
                tone.bin = m.peak;
                tone.statistic = m.statistic;
                tone.p_value = m.p_value;
                subtract(work.to_mut(), &tone);
                tones.push(tone);
            }
        }
    }
}

mod background;
mod scan;
#[cfg(test)]
mod tests;
mod tone;
mod transform;
mod uncertainty;

//! The low-frequency spectrum view: where a slow sinusoid (a few to a hundred cycles per
//! record) shows as one bin far above the background, and where the line detector
//! ([`crate::analysis::lines`]), whose background is a running median of few bins there and
//! whose false-alarm budget is split over every octave, is least sensitive.
//!
//! **Periodogram.** The series minus its least-squares line, times a periodic Hann window,
//! one real FFT of the whole record: `P_k = 2 |X_k|^2 / (f_s sum w^2)`, `sum w^2 = 3 n / 8`,
//! the one-sided PSD (u^2/Hz) at `f_k = k f_s / n`. The Hann window's sidelobes fall as
//! `1/f^3` in power, faster than a rate random walk's `1/f^2`, so a steep background does not
//! leak into the bins above it; its expectation at bin k is the background smoothed over the
//! neighbouring rectangular bins, `2/3 S_k + 1/6 (S_(k-1) + S_(k+1))` (the Hann DFT is
//! `X_k / 2 - (X_(k-1) + X_(k+1)) / 4`; Harris, "On the use of windows for harmonic analysis
//! with the discrete Fourier transform", Proc. IEEE 66(1), 1978), and each bin over its
//! expectation is about a standard exponential (Percival & Walden, *Spectral Analysis for
//! Physical Applications*, 1993, sec. 6.6).
//!
//! **Reduced rate.** The view's highest frequency is the low-frequency band's top
//! ([`highest_hz`]: a twentieth of the rate, a quarter of a known filter's cutoff) but at
//! most [`VIEW_OCTAVES`] octaves above the single bins ([`view_top_hz`]), so the view reads
//! the means of blocks of samples ([`view_block`], [`super::slow_view`]), on the record and
//! on its realisations alike.
//!
//! **Background fit (Whittle).** Bins from [`FIRST_BIN`] to the view's highest frequency
//! are grouped into bands: one bin per band below [`SINGLE_BINS`], then
//! [`BANDS_PER_OCTAVE`] per octave. The background `S(f) = sum_c theta_c phi_c(f)`,
//! `theta >= 0`, over the columns of the IEEE-952 two-sided PSD's shapes (IEEE 952 Table C.1): f^2
//! (quantization), 1 or the sensor filter's power gain (white rate noise), 1/f (flicker),
//! 1/f^2 (rate random walk), and Lorentzians `1 / (1 + (f / f_c)^2)` (the PSD of a
//! Gauss-Markov process of correlation time `1 / (2 pi f_c)`) with corners from one bin to
//! [`LORENTZIAN_TOP_BIN`] bins a factor [`LORENTZIAN_STEP`] apart, each smoothed by the Hann
//! window and averaged over the band's bins. theta maximises Whittle's likelihood of the band means
//! `-sum_j m_j (P_j / S_j + ln S_j)` (m_j bins in band j; Whittle, "Curve and periodogram
//! smoothing", JRSS B 19, 1957), found by iteratively reweighted non-negative least squares
//! with weights `m_j / S_j^2` (Fisher scoring of a gamma model with identity link; McCullagh
//! & Nelder, *Generalized Linear Models*, 1989, sec. 2.5). Its deviance is
//! `2 sum_j m_j (P_j / S_j - ln(P_j / S_j) - 1)`. The scoring only accepts steps that lower
//! it, so a fit with a few bands left out is also started from the weights of the fit
//! beside it and the lower deviance kept ([`Banded::fit_near`]).
//!
//! **Statistic.** The largest `P_k / S_k` over the single bins from [`LINE_FIRST_BIN`] up
//! and the half bins beside them (the series zero-padded to twice its length: a line
//! between two bins would lose up to 28 % of its power in each, [`Periodogram::half`]),
//! each of the strongest [`LEAVE_OUT_CANDIDATES`] (under the first fit and under the power
//! laws alone, which cannot step down just above a line and take part of it) judged against
//! the background refitted
//! without its own main lobe and without the bins far above the first fit
//! ([`OUTLIER_RATIO`]): a slow line's own power would otherwise raise the random-walk and
//! flicker shapes and hide it. Under the
//! null its tail is that of the maximum of exponentials, a Gumbel law of scale 1 whose
//! location is the log of the effective number of bins (Gumbel, *Statistics of Extremes*,
//! 1958); the location is taken from the simulated realisations, on which the same code
//! runs (see [`gumbel_p_value`]).
//!
//! **Why Lorentzians.** A line is what stands out of a smooth spectrum, and the noise's
//! spectrum need not be a sum of power laws: a Gauss-Markov process of minutes is flat
//! below its corner and falls as `1/f^2` above it, a knee that the power laws cannot follow.
//! Against them the bins beside the knee stood out as a slow line: on eight 4 h, 50 Hz
//! records of such a process made outside the project (`scripts/foreign_records.py --kinds
//! gm --seeds 41-48`) two were named a sinusoid. Non-negative mixtures of Lorentzians are
//! smooth and fall monotonically, so they follow any such knee (and sums of processes) but
//! cannot raise one bin above its neighbours. Screened under the first fit alone, on 200
//! records without an effect (4 h, 50 Hz, the families' baseline) the statistic's
//! quantiles stayed where they were (median 5.58 to
//! 5.44, 99 % 10.3 to 9.8); on 100 of the families' Gauss-Markov records its mean fell from
//! 6.32 to 6.10 (the null's 5.84 to 5.73), and on 100 slow-sinusoid records its lowest
//! tenth rose from 19.8 to 23.6: the fewer degrees of freedom the power laws leave to a
//! line's neighbours, the more the background fitted without it tracks the noise there.
//! The price: fitted without a bin's main lobe, the mixture can bend inside that gap, so
//! the null's largest ratios spread wider where the random walk is strong (on a 3 h, 50 Hz
//! foreign record of a process and a slow sinusoid, 5.98 +- 2.27 against 5.68 +- 1.59 over
//! the open model's 96 realisations, and the line's own ratio 14.5 against 16.2).
//! The process itself is judged in the Allan and cosine-transform views
//! ([`super::evidence`]): its plateau spans only the ~10 lowest bins of a 3 h record, too
//! few for this view to name it.

use crate::analysis::low_pass::LowPass;
use crate::analysis::shared_plans;
use crate::analysis::{lines, numerics};
use std::borrow::Cow;
use std::f64::consts::PI;

/// Bins 1 and 2 share their power with the removed line (and the window's DC lobe).
pub const FIRST_BIN: usize = 3;
/// Below this bin every bin is its own band: the slow effects live there.
pub const SINGLE_BINS: usize = 128;
/// Bands per octave above [`SINGLE_BINS`].
pub const BANDS_PER_OCTAVE: f64 = 16.0;
/// The slow-line search starts at this many cycles per record (a slower one is a trend).
pub const LINE_FIRST_BIN: usize = 4;
/// Bins this many times above the background are left out of the slow-line search's
/// background: the null exceeds it in 1 bin in 400 (`e^-6`), so a record without lines
/// loses about a third of a bin of the ~125 that fix the slow shapes.
pub const OUTLIER_RATIO: f64 = 6.0;
/// How many of the strongest bins under the first fit are judged against a background
/// fitted without them.
pub const LEAVE_OUT_CANDIDATES: usize = 8;
/// The low-frequency band reaches up to `rate / VIEW_RATE_DIVISOR` (and a quarter of a
/// known filter's cutoff), below the tones and roll-offs that other views judge.
pub const VIEW_RATE_DIVISOR: f64 = 20.0;
/// The view's bands reach at most this many octaves above its single bins (bin
/// `SINGLE_BINS * 2^VIEW_OCTAVES`): 96 bands that fix the white level and the quantization
/// above the slow shapes, and a top low enough to read the view at a reduced rate
/// ([`super::slow_view`]).
pub const VIEW_OCTAVES: u32 = 6;
/// The view's reduced rate is at least this many times its highest frequency: there a
/// block's mean still passes 95 % of the power (`sinc^2(pi / 8)`), and the block-mean
/// synthesis's approximations, near the reduced Nyquist frequency, lie above the view
/// ([`crate::sim::noise`]).
pub const VIEW_OVERSAMPLING: f64 = 8.0;
/// Euler-Mascheroni constant: the mean of a standard Gumbel variable.
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// The Hann periodogram of a series at bins 0..=k_max, and between them.
#[derive(Debug, Clone)]
pub struct Periodogram {
    /// Bin width `f_s / n`, Hz.
    pub df: f64,
    /// One-sided PSD, u^2/Hz; index k is `k df` Hz.
    pub power: Vec<f64>,
    /// The same half a bin higher: index k is `(k + 1/2) df` Hz (the series zero-padded to
    /// twice its length). A line between two bins loses up to 1.42 dB (28 %) of its power
    /// in each (the Hann window's scalloping loss; Harris 1978); at the half bin nearest
    /// it, at most 0.35 dB (8 %).
    pub half: Vec<f64>,
}

/// The top of the low-frequency band for a record at `rate_hz` with the sensor filter
/// `low_pass`, Hz: a pure line below it is a slow tone.
pub fn highest_hz(rate_hz: f64, low_pass: Option<&LowPass>) -> f64 {
    let top = rate_hz / VIEW_RATE_DIVISOR;
    low_pass.map_or(top, |lp| top.min(lp.cutoff_hz / 4.0))
}

/// The view's highest frequency for a record of `len` samples at `rate_hz` with the sensor
/// filter `low_pass`, Hz: the low-frequency band, up to [`VIEW_OCTAVES`] octaves above the
/// single bins.
pub fn view_top_hz(rate_hz: f64, len: usize, low_pass: Option<&LowPass>) -> f64 {
    let octaves = (SINGLE_BINS << VIEW_OCTAVES) as f64 * rate_hz / len.max(1) as f64;
    highest_hz(rate_hz, low_pass).min(octaves)
}

/// How many samples the view averages into one: the most that keep the reduced rate at
/// least [`VIEW_OVERSAMPLING`] times the view's highest frequency (1 when none do).
pub fn view_block(rate_hz: f64, len: usize, low_pass: Option<&LowPass>) -> usize {
    let top = view_top_hz(rate_hz, len, low_pass);
    ((rate_hz / (VIEW_OVERSAMPLING * top)).floor() as usize).max(1)
}

/// The Hann periodogram of `series` minus its least-squares line, up to `f_hi` Hz.
pub fn periodogram(series: &[f64], rate_hz: f64, f_hi: f64) -> Periodogram {
    let n = series.len();
    let df = rate_hz / n.max(1) as f64;
    let empty = Periodogram {
        df,
        power: Vec::new(),
        half: Vec::new(),
    };
    if n < 8 {
        return empty;
    }
    let (_, mut x) = lines::detrend(series);
    x.iter_mut()
        .zip(shared_plans::hann(n).iter())
        .for_each(|(v, w)| *v *= w);
    // Zero-padded to 2n: the even bins are the periodogram's, the odd ones its half bins.
    x.resize(2 * n, 0.0);
    let fft = shared_plans::forward(2 * n);
    let mut spectrum = fft.make_output_vec();
    if fft.process(&mut x, &mut spectrum).is_err() {
        return empty;
    }
    let k_max = ((f_hi / df).floor() as usize).min(n / 2);
    let norm = 2.0 / (rate_hz * 3.0 * n as f64 / 8.0);
    let at = |i: usize| spectrum.get(i).map_or(0.0, |c| c.norm_sqr() * norm);
    Periodogram {
        df,
        power: (0..=k_max).map(|k| at(2 * k)).collect(),
        half: (0..=k_max).map(|k| at(2 * k + 1)).collect(),
    }
}

/// A column of the background: the shape of one noise process's PSD.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Quantization,
    White,
    Flicker,
    RandomWalk,
    /// A first-order Gauss-Markov process's PSD, flat below its corner and falling as
    /// `1/f^2` above it: `1 / (1 + (f / corner_hz)^2)` (`corner_hz = 1 / (2 pi tau_c)`).
    Lorentzian {
        corner_hz: f64,
    },
}

impl Shape {
    /// The shape at `f` Hz (> 0), up to a constant.
    fn at(self, f: f64, low_pass: Option<&LowPass>) -> f64 {
        match self {
            Shape::Quantization => f * f,
            Shape::White => low_pass.map_or(1.0, |lp| lp.power_gain(f)),
            Shape::Flicker => 1.0 / f,
            Shape::RandomWalk => 1.0 / (f * f),
            Shape::Lorentzian { corner_hz } => 1.0 / (1.0 + (f / corner_hz).powi(2)),
        }
    }

    /// The Hann periodogram's expectation at bin k for a unit of this shape.
    fn hann(self, k: usize, df: f64, low_pass: Option<&LowPass>) -> f64 {
        let at = |j: usize| self.at(j as f64 * df, low_pass);
        2.0 / 3.0 * at(k) + (at(k - 1) + at(k + 1)) / 6.0
    }
}

/// The bands of a periodogram with bins up to `k_max`: `(first bin, bins)`.
fn bands(k_max: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut k = FIRST_BIN;
    while k <= k_max {
        let width = if k < SINGLE_BINS {
            1
        } else {
            ((k as f64 * (2f64.powf(1.0 / BANDS_PER_OCTAVE) - 1.0)).round() as usize).max(1)
        };
        let width = width.min(k_max + 1 - k);
        out.push((k, width));
        k += width;
    }
    out
}

/// The periodogram grouped into bands, with the design of any set of shapes.
pub struct Banded<'a> {
    pgram: &'a Periodogram,
    low_pass: Option<&'a LowPass>,
    bands: Vec<(usize, usize)>,
    /// Mean power per band.
    mean: Vec<f64>,
    /// Each shape's band means, for [`NOISE`] and the slow-line background's Lorentzians
    /// ([`Banded::smooth_shapes`]): they depend on the bins and the filter alone, and every
    /// fit of the series uses them (the filter's folded gain is costly to evaluate).
    columns: Vec<(Shape, Vec<f64>)>,
}

/// A fitted background: coefficients per shape, the band expectations and the deviance.
#[derive(Debug, Clone)]
pub struct Background {
    pub shapes: Vec<Shape>,
    pub theta: Vec<f64>,
    pub deviance: f64,
}

impl<'a> Banded<'a> {
    pub fn new(pgram: &'a Periodogram, low_pass: Option<&'a LowPass>) -> Self {
        // Bin k + 1 must exist for the Hann smoothing of the last band.
        let k_max = pgram.power.len().saturating_sub(2);
        let bands = bands(k_max);
        let mean = bands
            .iter()
            .map(|&(k, m)| pgram.power[k..k + m].iter().sum::<f64>() / m as f64)
            .collect();
        let mut banded = Banded {
            pgram,
            low_pass,
            bands,
            mean,
            columns: Vec::new(),
        };
        banded.columns = banded
            .smooth_shapes()
            .into_iter()
            .map(|s| (s, banded.column(s)))
            .collect();
        banded
    }

    /// The shapes of a smooth background in this view: [`NOISE`] and Lorentzians whose
    /// corners step by [`LORENTZIAN_STEP`] from one bin to [`LORENTZIAN_TOP_BIN`] bins
    /// (see [`slow_line`]).
    pub fn smooth_shapes(&self) -> Vec<Shape> {
        let df = self.pgram.df;
        let steps = (LORENTZIAN_TOP_BIN.ln() / LORENTZIAN_STEP.ln()).round() as i32;
        let corners = (0..=steps).map(|i| Shape::Lorentzian {
            corner_hz: df * LORENTZIAN_STEP.powi(i),
        });
        NOISE.into_iter().chain(corners).collect()
    }

    /// Bands enough for a background of a handful of shapes.
    pub fn usable(&self) -> bool {
        self.bands.len() >= 16
    }

    fn column(&self, shape: Shape) -> Vec<f64> {
        self.bands
            .iter()
            .map(|&(k, m)| {
                (k..k + m)
                    .map(|j| shape.hann(j, self.pgram.df, self.low_pass))
                    .sum::<f64>()
                    / m as f64
            })
            .collect()
    }

    /// The Whittle fit of `shapes` to the bands not `left_out`.
    pub fn fit(&self, shapes: &[Shape], left_out: &[bool]) -> Background {
        self.fit_from(shapes, left_out, None)
    }

    /// [`Banded::fit`], also started from `near` (a fit of the same shapes to other bands)
    /// and the better of the two kept: the scoring iterations move only downhill from their
    /// first step, and a first step weighted by the bands' own relative errors can land
    /// far from the optimum when a few bands are left out (a fit of quantization alone,
    /// its deviance 10^5 times the fit it started beside, was seen on one realisation).
    pub fn fit_near(&self, shapes: &[Shape], left_out: &[bool], near: &Background) -> Background {
        self.fit_from(shapes, left_out, Some(near))
    }

    fn fit_from(
        &self,
        shapes: &[Shape],
        left_out: &[bool],
        near: Option<&Background>,
    ) -> Background {
        // The cached columns are borrowed: every leave-out fit of every realisation reads them.
        let columns: Vec<Cow<[f64]>> = shapes
            .iter()
            .map(|&s| {
                self.columns.iter().find(|(c, _)| *c == s).map_or_else(
                    || Cow::Owned(self.column(s)),
                    |(_, v)| Cow::Borrowed(&v[..]),
                )
            })
            .collect();
        let keep: Vec<usize> = (0..self.bands.len())
            .filter(|&j| !left_out.get(j).copied().unwrap_or(false) && self.mean[j] > 0.0)
            .collect();
        let (mut theta, mut best) = self.scoring(&columns, &keep, None);
        if let Some(near) = near.filter(|b| b.shapes == shapes) {
            let (warm, deviance) = self.scoring(&columns, &keep, Some(&near.theta));
            if deviance < best {
                (theta, best) = (warm, deviance);
            }
        }
        Background {
            shapes: shapes.to_vec(),
            theta,
            deviance: best,
        }
    }

    /// Fisher scoring of the Whittle likelihood over the bands `keep`, its first weights
    /// those of the background `start` (`m_j / S_j^2`), or without one each band's relative
    /// error (`m_j / P_j^2`): the coefficients and their deviance.
    fn scoring(
        &self,
        columns: &[Cow<[f64]>],
        keep: &[usize],
        start: Option<&[f64]>,
    ) -> (Vec<f64>, f64) {
        let expect = |theta: &[f64], j: usize| -> f64 {
            columns.iter().zip(theta).map(|(c, t)| c[j] * t).sum()
        };
        let weights_of = |theta: &[f64]| -> Vec<f64> {
            keep.iter()
                .map(|&j| {
                    let s = expect(theta, j).max(f64::MIN_POSITIVE);
                    self.bands[j].1 as f64 / (s * s)
                })
                .collect()
        };
        let mut weight: Vec<f64> = match start {
            Some(theta) => weights_of(theta),
            None => keep
                .iter()
                .map(|&j| self.bands[j].1 as f64 / (self.mean[j] * self.mean[j]))
                .collect(),
        };
        let deviance = |theta: &[f64]| -> f64 {
            keep.iter()
                .map(|&j| {
                    let s = expect(theta, j).max(f64::MIN_POSITIVE);
                    let r = self.mean[j] / s;
                    2.0 * self.bands[j].1 as f64 * (r - r.ln() - 1.0)
                })
                .sum()
        };
        let mut theta = vec![0.0; columns.len()];
        let mut best = f64::INFINITY;
        for _ in 0..40 {
            let g: Vec<Vec<f64>> = keep
                .iter()
                .zip(&weight)
                .map(|(&j, w)| columns.iter().map(|c| c[j] * w.sqrt()).collect())
                .collect();
            let b: Vec<f64> = keep
                .iter()
                .zip(&weight)
                .map(|(&j, w)| self.mean[j] * w.sqrt())
                .collect();
            let next: Vec<f64> = numerics::nnls_normalised(g, &b)
                .into_iter()
                .map(|t| t.max(0.0))
                .collect();
            let d = deviance(&next);
            let settled = (best - d).abs() <= 1e-9 * d.abs().max(1.0);
            if d.is_finite() && d <= best {
                best = d;
                theta = next;
            }
            if settled {
                break;
            }
            weight = weights_of(&theta);
        }
        (theta, best)
    }

    /// The fitted background's expectation at bin k.
    pub fn expected(&self, bg: &Background, k: usize) -> f64 {
        bg.shapes
            .iter()
            .zip(&bg.theta)
            .map(|(s, t)| s.hann(k, self.pgram.df, self.low_pass) * t)
            .sum()
    }
}

/// Ratio of neighbouring Lorentzian corners in the slow-line background: a Lorentzian
/// whose corner lies between two of them is matched by their mixture to within 3 %
/// everywhere, well below a bin's own scatter.
pub const LORENTZIAN_STEP: f64 = std::f64::consts::SQRT_2;
/// The highest Lorentzian corner of the slow-line background, in bins: twice the single
/// bins, above which the background is banded and a Lorentzian is the white and
/// random-walk shapes' sum there.
pub const LORENTZIAN_TOP_BIN: f64 = 2.0 * SINGLE_BINS as f64;

/// The IEEE-952 shapes every background has.
pub const NOISE: [Shape; 4] = [
    Shape::Quantization,
    Shape::White,
    Shape::Flicker,
    Shape::RandomWalk,
];

/// The strongest single bin above the background from [`LINE_FIRST_BIN`] to the last
/// single-bin band, leaving out bins for which `skip(freq_hz)` holds: its ratio to the
/// background and its frequency, Hz. A bin's ratio is the largest of its own and its two
/// half bins' ([`Periodogram::half`]), each against the background there (the geometric
/// mean of the two bins' expectations: the smoothed background is a power law over a bin),
/// so a line between bins stands out as much as one on a bin.
pub fn slow_line(banded: &Banded, skip: &dyn Fn(f64) -> bool) -> Option<(f64, f64)> {
    slow_line_over(banded, skip, &banded.smooth_shapes())
}

/// [`slow_line`] against a background of `shapes`.
fn slow_line_over(
    banded: &Banded,
    skip: &dyn Fn(f64) -> bool,
    shapes: &[Shape],
) -> Option<(f64, f64)> {
    if !banded.usable() {
        return None;
    }
    let pgram = banded.pgram;
    let expected = |bg: &Background, k: usize| banded.expected(bg, k).max(f64::MIN_POSITIVE);
    let bin_ratio = |bg: &Background, j: usize| {
        let k = banded.bands[j].0;
        pgram.power[k] / expected(bg, k)
    };
    // Single bins start at FIRST_BIN and end a bin below the last bin there is, so k - 1
    // and k + 1 exist.
    let ratio = |bg: &Background, j: usize| -> (f64, f64) {
        let k = banded.bands[j].0;
        let (below, at, above) = (expected(bg, k - 1), expected(bg, k), expected(bg, k + 1));
        [
            (pgram.half[k - 1] / (below * at).sqrt(), k as f64 - 0.5),
            (pgram.power[k] / at, k as f64),
            (pgram.half[k] / (at * above).sqrt(), k as f64 + 0.5),
        ]
        .into_iter()
        .fold((f64::NEG_INFINITY, 0.0), |best, r| {
            if r.0 > best.0 { r } else { best }
        })
    };
    let single: Vec<usize> = (0..banded.bands.len())
        .filter(|&j| banded.bands[j].1 == 1)
        .collect();
    // A line's bins pull the flicker and random-walk shapes up (only the single bins
    // constrain them) and so mask themselves: each of the strongest bins is judged against
    // the background fitted without its Hann main lobe (+-2 bins) and without any bin far
    // above the first fit.
    let first = banded.fit(shapes, &[]);
    let far: Vec<bool> = (0..banded.bands.len())
        .map(|j| banded.bands[j].1 == 1 && bin_ratio(&first, j) > OUTLIER_RATIO)
        .collect();
    // The strongest bins under the power laws too: a mixture of Lorentzians can step down
    // just above a line and take part of it into the first fit, which the power laws,
    // unable to bend, do not.
    let rigid = (shapes != NOISE).then(|| banded.fit(&NOISE, &[]));
    let strongest = |bg: &Background| {
        let mut ranked: Vec<(f64, usize)> = single
            .iter()
            .filter(|&&j| banded.bands[j].0 >= LINE_FIRST_BIN)
            .filter(|&&j| !skip(banded.bands[j].0 as f64 * pgram.df))
            .map(|&j| (ratio(bg, j).0, j))
            .collect();
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        ranked.truncate(LEAVE_OUT_CANDIDATES);
        ranked.into_iter().map(|(_, j)| j)
    };
    let mut candidates: Vec<usize> = strongest(&first)
        .chain(rigid.iter().flat_map(strongest))
        .collect();
    candidates.sort_unstable();
    candidates.dedup();
    candidates
        .into_iter()
        .map(|j| {
            let mut out = far.clone();
            let end = (j + 3).min(out.len());
            out[j.saturating_sub(2)..end]
                .iter_mut()
                .for_each(|o| *o = true);
            let bg = banded.fit_near(shapes, &out, &first);
            let (r, bin) = ratio(&bg, j);
            (r, bin * pgram.df)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// A line's window reaches this many of its widths either side of its centre.
pub const LINE_WINDOW_WIDTHS: f64 = 10.0;

/// The power (u^2) of a Lorentzian line of full width at half maximum `width_hz` at `freq_hz`
/// in `series` at `rate_hz`: the rectangular periodogram's excess over `background` (the
/// model's one-sided PSD, u^2/Hz) within +-[`LINE_WINDOW_WIDTHS`] widths (at least +-20
/// bins), over the Lorentzian's share of that window, `(1 / pi) (atan(2 (hi - f0) / w) -
/// atan(2 (lo - f0) / w))`. A line's wings hold much of its power (a fifth beyond +-1.5
/// widths), and the detector, whose background is a running median that the wings raise,
/// under-reads a wide line; the model's background does not.
pub fn line_power(
    series: &[f64],
    rate_hz: f64,
    freq_hz: f64,
    width_hz: f64,
    background: &dyn Fn(f64) -> f64,
) -> Option<f64> {
    let n = series.len();
    if n < 8 || width_hz <= 0.0 {
        return None;
    }
    let mean = series.iter().sum::<f64>() / n as f64;
    let mut x: Vec<f64> = series.iter().map(|v| v - mean).collect();
    let fft = shared_plans::forward(n);
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut x, &mut spectrum).ok()?;
    let df = rate_hz / n as f64;
    let half = (LINE_WINDOW_WIDTHS * width_hz).max(20.0 * df);
    let nyquist = rate_hz / 2.0;
    let (lo, hi) = ((freq_hz - half).max(df), (freq_hz + half).min(nyquist));
    let norm = 2.0 / (rate_hz * n as f64);
    let excess: f64 = ((lo / df).ceil() as usize..=((hi / df).floor() as usize))
        .filter_map(|k| spectrum.get(k).map(|c| (k, c)))
        .map(|(k, c)| (c.norm_sqr() * norm - background(k as f64 * df)) * df)
        .sum();
    // What lies beyond Nyquist folds back into the window: only the low side is lost.
    let share = (((freq_hz + half) - freq_hz) * 2.0 / width_hz).atan() / PI
        - ((lo - freq_hz) * 2.0 / width_hz).atan() / PI;
    (excess > 0.0 && share > 0.0).then(|| excess / share)
}

/// P(max > `measured`) for a maximum of bin ratios, from its simulated values: a Gumbel
/// law whose scale is that of the exponential tail (1), widened to the simulations' own
/// spread when that is larger (`sd sqrt(6) / pi`), and whose location is set by their mean
/// (`mean - gamma scale`).
pub fn gumbel_p_value(measured: f64, simulated: &[f64]) -> f64 {
    if simulated.len() < 2 {
        return 1.0;
    }
    let r = simulated.len() as f64;
    let mean = simulated.iter().sum::<f64>() / r;
    let sd = (simulated.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (r - 1.0)).sqrt();
    let scale = (sd * 6f64.sqrt() / PI).max(1.0);
    let location = mean - EULER_GAMMA * scale;
    let z = (measured - location) / scale;
    // 1 - exp(-exp(-z)), accurate for small p.
    -(-(-z).exp()).exp_m1()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::noise::{AxisNoise, NoiseTerms};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn series(terms: NoiseTerms, rate_hz: f64, seconds: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = (rate_hz * seconds) as usize;
        AxisNoise::new(terms, rate_hz, seconds, &mut rng).take(n, &mut rng)
    }

    /// The Whittle fit recovers white noise's level: one-sided PSD 2 N^2 (two-sided N^2).
    /// 20 000 bins: the level's relative s.d. is about 1 / sqrt(number of bins) < 1 %.
    #[test]
    fn white_level_is_two_n_squared() {
        let n_density = 1e-3;
        let y = series(
            NoiseTerms {
                n: n_density,
                ..NoiseTerms::default()
            },
            50.0,
            3600.0,
            1,
        );
        let p = periodogram(&y, 50.0, 2.5);
        let banded = Banded::new(&p, None);
        let bg = banded.fit(&[Shape::White], &[]);
        let level = bg.theta[0];
        assert!(
            (level / (2.0 * n_density * n_density) - 1.0).abs() < 0.03,
            "{level}"
        );
    }

    /// A sinusoid of 12 cycles per record whose bin holds 30 times the background stands
    /// out; the null's largest ratio over ~120 bins is near ln 120 + 0.58 = 5.4.
    #[test]
    fn a_slow_sinusoid_stands_out() {
        let rate_hz = 20.0;
        let seconds = 7200.0;
        let terms = NoiseTerms {
            n: 1e-4,
            k: 2e-7,
            ..NoiseTerms::default()
        };
        let mut y = series(terms, rate_hz, seconds, 5);
        let f0 = 12.0 / seconds;
        let p0 = periodogram(&y, rate_hz, 1.0);
        let b0 = Banded::new(&p0, None);
        let (null, _) = slow_line(&b0, &|_| false).unwrap();
        assert!(null < 12.0, "{null}");
        // Background at f0 from the fit, then a tone holding 30 bins' worth of it.
        let bg = b0.fit(&NOISE, &[]);
        let s = b0.expected(&bg, 12);
        let amplitude = (2.0 * 30.0 * s * p0.df).sqrt();
        for (t, v) in y.iter_mut().enumerate() {
            *v += amplitude * (2.0 * PI * f0 * t as f64 / rate_hz + 0.3).sin();
        }
        let p = periodogram(&y, rate_hz, 1.0);
        let (ratio, f) = slow_line(&Banded::new(&p, None), &|_| false).unwrap();
        assert!(ratio > 12.0, "{ratio}");
        assert!((f - f0).abs() <= p.df, "{f} vs {f0}");
    }

    /// A Lorentzian line of 0.5 Hz holding 20 times the white level's power per its width:
    /// its power read against the known background within 5 %. The line's own power over a
    /// record of T s fluctuates by about `1 / sqrt(pi w T)` = 1.3 % (the number of its
    /// independent bins), the white bins in the window add 0.5 %: 5 % is 3.5 s.d.
    /// A sinusoid half way between two bins stands out by its half bin as one on a bin does
    /// by its bin: its ratio is within 10 % of the same sinusoid's on a bin (Hann's
    /// scalloping at a quarter bin or less is under 0.35 dB), its half bin holds at least
    /// 1.3 times the power of either bin beside it (1.42 dB lost there), and its frequency
    /// is within a quarter bin.
    #[test]
    fn a_line_between_bins_is_read_at_its_half_bin() {
        let (rate_hz, seconds) = (20.0, 7200.0);
        let terms = NoiseTerms {
            n: 1e-4,
            k: 2e-7,
            ..NoiseTerms::default()
        };
        let noise = series(terms, rate_hz, seconds, 5);
        let p0 = periodogram(&noise, rate_hz, 1.0);
        let b0 = Banded::new(&p0, None);
        let s = b0.expected(&b0.fit(&NOISE, &[]), 12);
        // A line 1000 times the background at bin 12: the noise in its bins moves its
        // power by about 2 / sqrt(1000), 6 %, so the ratio is the line's.
        let amplitude = (2.0 * 1000.0 * s * p0.df).sqrt();
        let with_line = |cycles: f64| -> (f64, f64, Periodogram) {
            let f0 = cycles / seconds;
            let y: Vec<f64> = noise
                .iter()
                .enumerate()
                .map(|(t, v)| v + amplitude * (2.0 * PI * f0 * t as f64 / rate_hz + 0.3).sin())
                .collect();
            let p = periodogram(&y, rate_hz, 1.0);
            let (ratio, f) = slow_line(&Banded::new(&p, None), &|_| false).unwrap();
            (ratio, f, p)
        };
        let (on_bin, _, _) = with_line(12.0);
        let (between, f, p) = with_line(12.5);
        assert!(
            (between / on_bin - 1.0).abs() < 0.1,
            "{between} between bins against {on_bin} on one"
        );
        let best_bin = p.power[12].max(p.power[13]);
        assert!(
            p.half[12] >= 1.3 * best_bin,
            "half bin {}, bins {best_bin}",
            p.half[12]
        );
        assert!((f - 12.5 / seconds).abs() <= 0.25 * p.df, "{f}");
    }

    #[test]
    fn a_wide_lines_power_is_read_against_the_background() {
        let (rate_hz, seconds, n_density) = (50.0, 3600.0, 1e-3);
        let white = 2.0 * n_density * n_density;
        let (freq_hz, width_hz) = (10.0, 0.5);
        let power = 20.0 * white * width_hz;
        let mut y = series(
            NoiseTerms {
                n: n_density,
                ..NoiseTerms::default()
            },
            rate_hz,
            seconds,
            7,
        );
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        crate::sim::noise::add_line(
            &mut y,
            rate_hz,
            freq_hz,
            width_hz,
            (2.0 * power).sqrt(),
            &mut rng,
        );
        let got = line_power(&y, rate_hz, freq_hz, width_hz, &|_| white).unwrap();
        assert!((got / power - 1.0).abs() < 0.05, "{got} vs {power}");
    }

    /// A Gauss-Markov knee is background, not a line: on the noise-free expectation of
    /// white noise and a process 30 times stronger on its plateau, its corner at 11.9 bins
    /// (between two of the Lorentzians' corners), the background with Lorentzians follows
    /// every bin within 3 % (their mixture's error between corners; 1.0 % measured) and no
    /// bin stands out by more than 3 % (0.6 %); the power laws alone miss some bins by a
    /// factor of 5 and leave one 1.41 times its background before any scatter: on a record,
    /// whose bins scatter about it as exponentials, that bin's ratio is 1.41 times a noise
    /// bin's, the line the knee would be taken for.
    #[test]
    fn a_gauss_markov_knee_is_background() {
        let df = 1e-4;
        let corner = 10.0 * LORENTZIAN_STEP.sqrt();
        let truth = |f: f64| 1.0 + 30.0 / (1.0 + (f / (corner * df)).powi(2));
        let hann = |k: usize| {
            let at = |j: usize| truth(j as f64 * df);
            2.0 / 3.0 * at(k) + (at(k - 1) + at(k + 1)) / 6.0
        };
        let k_max = 1024;
        let mut power = vec![0.0; k_max + 1];
        (1..k_max).for_each(|k| power[k] = hann(k));
        let half = (0..=k_max)
            .map(|k| (power[k] * power[(k + 1).min(k_max)]).sqrt())
            .collect();
        let pgram = Periodogram { df, power, half };
        let banded = Banded::new(&pgram, None);
        let misfit = |shapes: &[Shape]| {
            let bg = banded.fit(shapes, &[]);
            (FIRST_BIN..k_max - 1)
                .map(|k| (banded.expected(&bg, k) / pgram.power[k] - 1.0).abs())
                .fold(0.0, f64::max)
        };
        let with_lorentzians = misfit(&banded.smooth_shapes());
        let (ratio_l, _) = slow_line(&banded, &|_| false).unwrap();
        let power_laws = misfit(&NOISE);
        let (ratio_p, _) = slow_line_over(&banded, &|_| false, &NOISE).unwrap();
        assert!(with_lorentzians < 0.03, "{with_lorentzians}");
        assert!(ratio_l < 1.03, "{ratio_l}");
        assert!(power_laws > 1.0, "{power_laws}");
        assert!(ratio_p > 1.3, "{ratio_p}");
    }

    #[test]
    fn gumbel_p_value_is_small_far_in_the_tail() {
        let sims: Vec<f64> = (0..24).map(|i| 5.0 + 0.05 * f64::from(i)).collect();
        let p = gumbel_p_value(20.0, &sims);
        assert!(p > 0.0 && p < 1e-5, "{p}");
        assert!(gumbel_p_value(5.0, &sims) > 0.3);
    }
}

//! One-sided power spectral density by Welch's method, and log-frequency binning for plots
//! and slope fitting.
//!
//! [`welch`] reproduces `scipy.signal.welch(y, fs, window=w, nperseg=L, noverlap=D,
//! detrend='constant' | False, scaling='density', return_onesided=True, average='mean')`:
//!
//! - segments of `L` samples start every `L - D` samples; the number of segments is
//!   `(n - D) / (L - D)` (integer division), trailing samples that do not fill a segment are
//!   dropped, exactly as scipy does;
//! - each segment optionally has its own mean removed, is multiplied by the *periodic*
//!   (DFT-even) window `w[k]`, `k = 0..L` (scipy's `get_window(..., fftbins=True)`), and
//!   transformed: `X[j] = sum_k w[k] s[k] exp(-2 pi i j k / L)`;
//! - `P[j] = |X[j]|^2 / (fs * sum_k w[k]^2)`, doubled for every bin except DC and (for even
//!   `L`) Nyquist — the one-sided density, in u^2/Hz;
//! - the density is the mean of `P` over segments, at `f[j] = j fs / L`, `j = 0..=L/2`.
//!
//! Convention (docs/ARCHITECTURE.md, "Units and conventions"): the estimate is **one-sided**. White rate noise with Allan
//! coefficient N (AVAR = N^2/tau) has one-sided PSD `2 N^2`; IEEE-952's `S = N^2` is the
//! two-sided density.

use crate::analysis::power_fft::PowerFft;
use crate::analysis::shared_plans;
use rayon::prelude::*;
use realfft::RealToComplex;
use serde::Serialize;
use std::borrow::Cow;
use std::f64::consts::PI;
use std::sync::Arc;

/// Errors from [`welch`]; each names the input at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PsdError {
    #[error("no samples: the PSD needs at least one segment of data")]
    Empty,
    #[error("sample {index} is not finite ({value}): the PSD needs finite samples")]
    NonFinite { index: usize, value: f64 },
    #[error("sample rate {0} Hz is not a positive finite number")]
    BadRate(f64),
    #[error("segment length {0} is too short: at least 2 samples are needed")]
    SegmentTooShort(usize),
    #[error("segment length {segment_len} is longer than the record ({samples} samples)")]
    SegmentTooLong { segment_len: usize, samples: usize },
    #[error("overlap {0} is not a fraction in [0, 1)")]
    BadOverlap(f64),
}

/// The taper applied to each segment; all are the periodic (DFT-even) forms scipy's
/// `get_window` returns for spectral analysis, `k = 0..L`:
/// - `hann`: `0.5 - 0.5 cos(2 pi k / L)`
/// - `hamming`: `0.54 - 0.46 cos(2 pi k / L)`
/// - `blackman`: `0.42 - 0.5 cos(2 pi k / L) + 0.08 cos(4 pi k / L)`
/// - `rectangular`: `1` (scipy's `boxcar`)
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Window {
    Hann,
    Hamming,
    Blackman,
    Rectangular,
}

impl Window {
    pub const ALL: [Window; 4] = [
        Window::Hann,
        Window::Hamming,
        Window::Blackman,
        Window::Rectangular,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Window::Hann => "hann",
            Window::Hamming => "hamming",
            Window::Blackman => "blackman",
            Window::Rectangular => "rectangular",
        }
    }

    /// The generalised-cosine coefficients `a` of `w[k] = sum_m (-1)^m a_m cos(2 pi m k / L)`.
    fn cosine_terms(self) -> &'static [f64] {
        match self {
            Window::Hann => &[0.5, 0.5],
            Window::Hamming => &[0.54, 0.46],
            Window::Blackman => &[0.42, 0.5, 0.08],
            Window::Rectangular => &[1.0],
        }
    }

    /// The periodic window of length `len` (see the type's documentation).
    pub fn coefficients(self, len: usize) -> Vec<f64> {
        (0..len).map(|k| self.at(k, len)).collect()
    }

    /// Coefficient k of the periodic window of length `len`.
    fn at(self, k: usize, len: usize) -> f64 {
        let phase = 2.0 * PI * k as f64 / len as f64;
        self.cosine_terms()
            .iter()
            .enumerate()
            .map(|(m, a)| {
                let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
                sign * a * (m as f64 * phase).cos()
            })
            .sum()
    }
}

/// A periodic window held by its first half: `w[k] = w[L - k]` (each term is a cosine of
/// `2 pi m k / L`), so coefficients `0..=L/2` give the rest, and a segment's window costs
/// half a segment of memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Taper {
    kind: Window,
    len: usize,
    /// `w[k]`, k = 0..=L/2.
    half: Vec<f64>,
}

impl Taper {
    /// The window `kind` for segments of `len` samples.
    pub fn new(kind: Window, len: usize) -> Taper {
        Taper {
            kind,
            len,
            half: (0..len.div_ceil(2) + usize::from(len.is_multiple_of(2)))
                .map(|k| kind.at(k, len))
                .collect(),
        }
    }

    /// Coefficients, L.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Which window.
    pub fn kind(&self) -> Window {
        self.kind
    }

    /// The coefficients `w[0..L]` in order.
    pub fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        let rising = &self.half[..self.half.len().min(self.len)];
        let falling = &self.half[1..self.len - rising.len() + 1];
        rising.iter().chain(falling.iter().rev()).copied()
    }

    /// `sum w[k]^2`.
    pub fn sum_of_squares(&self) -> f64 {
        self.iter().map(|w| w * w).sum()
    }
}

impl std::fmt::Display for Window {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is none of the [`Window`]s' (nor an alias of one).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown window '{0}': one of {names}", names = Window::ALL.map(Window::name).join(", "))]
pub struct UnknownWindow(pub String);

impl std::str::FromStr for Window {
    type Err = UnknownWindow;
    fn from_str(s: &str) -> Result<Self, UnknownWindow> {
        let wanted = match s.to_ascii_lowercase().as_str() {
            "hanning" => "hann",
            "boxcar" | "rect" | "none" => "rectangular",
            other => return Self::by_name(other, s),
        };
        Self::by_name(wanted, s)
    }
}

impl Window {
    fn by_name(name: &str, original: &str) -> Result<Self, UnknownWindow> {
        Window::ALL
            .into_iter()
            .find(|w| w.name() == name)
            .ok_or_else(|| UnknownWindow(original.to_string()))
    }
}

/// Settings of [`welch`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WelchOptions {
    /// Samples per segment (scipy's `nperseg`). `0` means "choose for the record" with
    /// [`segment_len_for`].
    pub segment_len: usize,
    /// Overlap between consecutive segments as a fraction of `segment_len`, in `[0, 1)`;
    /// scipy's `noverlap = floor(overlap * segment_len)`.
    pub overlap: f64,
    pub window: Window,
    /// Remove each segment's mean before windowing (scipy's `detrend='constant'`).
    pub detrend_mean: bool,
}

impl Default for WelchOptions {
    /// Hann window, 50 % overlap, segment mean removed, segment length chosen per record.
    fn default() -> Self {
        WelchOptions {
            segment_len: 0,
            overlap: 0.5,
            window: Window::Hann,
            detrend_mean: true,
        }
    }
}

/// Smallest segment [`segment_len_for`] picks when the record allows it.
pub const MIN_AUTO_SEGMENT: usize = 256;
/// Largest segment [`segment_len_for`] picks (2^20; at 100 Hz the lowest bin is 95 uHz).
pub const MAX_AUTO_SEGMENT: usize = 1 << 20;

/// The segment length used when [`WelchOptions::segment_len`] is 0, for an `n`-sample record.
///
/// Rule: the largest power of two `L <= n / 8`, then clamped to `[256, 2^20]`, and never more
/// than `n`. With 50 % overlap `n / 8` gives at least 15 averaged segments, so each bin's
/// relative standard error is about `1 / sqrt(15 * 0.95) ~ 0.27` or better (Hann, 50 %:
/// equivalent independent segments ~ 0.95 per segment), while the lowest non-zero frequency
/// `fs / L` lies within a factor 8..16 of `1 / T` (T the record length): the same long-tau
/// region where the Allan curve shows the rate random walk slope. The lower clamp keeps
/// enough frequency resolution for short records; the upper clamp bounds memory and time.
pub fn segment_len_for(n: usize) -> usize {
    let target = (n / 8).max(1);
    let pow2 = 1usize << (usize::BITS - 1 - target.leading_zeros());
    pow2.clamp(MIN_AUTO_SEGMENT, MAX_AUTO_SEGMENT).min(n)
}

/// A one-sided power spectral density.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Psd {
    /// Frequencies, Hz, `j * fs / L` for `j = 0..=L/2`.
    pub freq: Vec<f64>,
    /// One-sided density, u^2/Hz (u the unit of the samples).
    pub density: Vec<f64>,
    /// Number of segments averaged.
    pub segments: usize,
}

/// Welch's one-sided PSD of `y` sampled at `rate_hz` (see the module documentation for the
/// exact definition; it equals scipy's `welch` with `scaling='density'`).
pub fn welch(y: &[f64], rate_hz: f64, opts: &WelchOptions) -> Result<Psd, PsdError> {
    welch_of(Samples::rate(y), rate_hz, opts, None)
}

/// [`welch`] of the series `samples` reads, whose own sample rate is `rate_hz`, with the
/// segment length's window and FFT plan when the caller has them (a caller computing several
/// spectra with one segment length makes them once).
pub fn welch_of(
    samples: Samples,
    rate_hz: f64,
    opts: &WelchOptions,
    transform: Option<&SegmentTransform>,
) -> Result<Psd, PsdError> {
    let plan = SegmentPlan::new(&samples, rate_hz, opts)?;
    let transform = match transform {
        Some(t) if t.len() == plan.len && t.window.kind() == opts.window => Cow::Borrowed(t),
        _ => Cow::Owned(SegmentTransform::new(plan.len, opts.window)),
    };
    let sums = plan.sum_periodograms(&samples, &transform, opts.detrend_mean);
    Ok(density_of(sums, &transform.window, plan.count, rate_hz))
}

/// [`welch_of`] at the bins `bins` only: `X[j]` of every segment summed directly, one pass
/// over each segment for all the bins, so the cost is `O(L)` per bin where a transform costs
/// `O(L log L)` for all of them, and no segment-long buffer is held. The densities of the
/// other bins are NaN. The multi-resolution PSD reads three bins of each deeper level: for
/// those this gives the same numbers as [`welch_of`] up to rounding (tested) at a small
/// fraction of its time.
pub fn welch_bins_of(
    samples: Samples,
    rate_hz: f64,
    opts: &WelchOptions,
    window: &Taper,
    bins: std::ops::Range<usize>,
) -> Result<Psd, PsdError> {
    let plan = SegmentPlan::new(&samples, rate_hz, opts)?;
    let window = match window.len() == plan.len && window.kind() == opts.window {
        true => Cow::Borrowed(window),
        false => Cow::Owned(Taper::new(opts.window, plan.len)),
    };
    let direct = DirectBins::new(bins.filter(|&j| j <= plan.len / 2).collect(), plan.len);
    let bins = &direct.bins;
    let partial = plan.in_ordered_groups(
        || (vec![0.0; bins.len()], vec![0.0; direct.width()]),
        |(acc, chunk), start| {
            let powers = direct.powers(&samples, start, &window, opts.detrend_mean, chunk);
            acc.iter_mut().zip(powers).for_each(|(a, p)| *a += p);
        },
    );
    let mut sums = vec![f64::NAN; plan.len / 2 + 1];
    for &j in bins {
        sums[j] = 0.0;
    }
    for (acc, _) in partial {
        for (&j, p) in bins.iter().zip(acc) {
            sums[j] += p;
        }
    }
    Ok(density_of(sums, &window, plan.count, rate_hz))
}

/// Samples read at a time by [`DirectBins::powers`]: within a chunk each bin's phasors come
/// from a table of one chunk's length, turned to the chunk's start by one multiplication.
const DIRECT_CHUNK: usize = 1024;

/// The phasors `exp(-2 pi i j k / L)` of bin `j` of a segment of `len` samples, for `k` in
/// `from..from + count`, each from its phase reduced exactly to one turn.
fn phasors(j: usize, len: usize, from: usize, count: usize) -> Vec<(f64, f64)> {
    (from..from + count).map(|k| phasor(j, len, k)).collect()
}

/// `exp(-2 pi i j k / L)` as (cos, sin), its phase reduced exactly to one turn.
/// `exp(-2 pi i j k / len)` as `(cos, sin)`, its phase reduced exactly to one turn first so
/// that large `j k` keep full precision.
fn phasor(j: usize, len: usize, k: usize) -> (f64, f64) {
    let turns = (j as u128 * k as u128 % len as u128) as f64 / len as f64;
    let (s, c) = (-2.0 * PI * turns).sin_cos();
    (c, s)
}

/// Bins of a segment length summed directly, with each bin's [`phasors`] over one chunk.
struct DirectBins {
    bins: Vec<usize>,
    len: usize,
    tables: Vec<Vec<(f64, f64)>>,
}

impl DirectBins {
    fn new(bins: Vec<usize>, len: usize) -> Self {
        let width = DIRECT_CHUNK.min(len);
        let tables = bins.iter().map(|&j| phasors(j, len, 0, width)).collect();
        DirectBins { bins, len, tables }
    }

    /// Samples per chunk.
    fn width(&self) -> usize {
        DIRECT_CHUNK.min(self.len)
    }

    /// `|X[j]|^2` of the segment from `start`, tapered as [`taper`] does (its mean, summed in
    /// the same order, taken out when `detrend`), for every bin; `chunk` is the work buffer.
    fn powers(
        &self,
        samples: &Samples,
        start: usize,
        window: &Taper,
        detrend: bool,
        chunk: &mut [f64],
    ) -> Vec<f64> {
        let len = self.len;
        let width = chunk.len().max(1);
        let chunks = || (0..len).step_by(width);
        let mut mean = 0.0;
        if detrend {
            let mut sum = 0.0;
            for from in chunks() {
                let part = &mut chunk[..width.min(len - from)];
                samples.read(start + from, part);
                sum = part.iter().fold(sum, |s, v| s + v);
            }
            mean = sum / len as f64;
        }
        let mut sums = vec![(0.0, 0.0); self.bins.len()];
        let mut w = window.iter();
        for from in chunks() {
            let part = &mut chunk[..width.min(len - from)];
            samples.read(start + from, part);
            for v in part.iter_mut() {
                *v = (*v - mean) * w.next().unwrap_or(0.0);
            }
            let bins = self.bins.iter().zip(&self.tables);
            for ((&j, table), (re, im)) in bins.zip(sums.iter_mut()) {
                // Four partial sums each, so that the additions do not wait on one another.
                let (mut r, mut i) = ([0.0; 4], [0.0; 4]);
                for (vs, ts) in part.chunks(4).zip(table.chunks(4)) {
                    for (lane, (v, (c, s))) in vs.iter().zip(ts).enumerate() {
                        r[lane] += v * c;
                        i[lane] += v * s;
                    }
                }
                let (r, i) = (r.iter().sum::<f64>(), i.iter().sum::<f64>());
                let (c, s) = phasor(j, len, from);
                *re += r * c - i * s;
                *im += r * s + i * c;
            }
        }
        sums.into_iter().map(|(re, im)| re * re + im * im).collect()
    }
}

/// A segment length's window coefficients and transform.
#[derive(Clone)]
pub struct SegmentTransform {
    window: Taper,
    fft: SegmentFft,
}

/// How segments are transformed: by a real-FFT plan, or, from [`LONG_SEGMENT`] samples on,
/// by [`PowerFft`] in one buffer of the segment's length (a plan of that length holds a table
/// about as large as the segment, and its output lies beside its input).
#[derive(Clone)]
enum SegmentFft {
    Plan(Arc<dyn RealToComplex<f64>>),
    Powers(Arc<PowerFft>),
}

impl SegmentTransform {
    /// The window `kind`'s coefficients for segments of `len` samples, and their transform.
    pub fn new(len: usize, kind: Window) -> Self {
        let powers = (len >= LONG_SEGMENT).then(|| PowerFft::new(len)).flatten();
        SegmentTransform {
            window: Taper::new(kind, len),
            fft: match powers {
                Some(p) => SegmentFft::Powers(Arc::new(p)),
                None => SegmentFft::Plan(shared_plans::forward(len)),
            },
        }
    }

    /// Samples per segment.
    pub fn len(&self) -> usize {
        self.window.len()
    }

    pub fn is_empty(&self) -> bool {
        self.window.is_empty()
    }

    /// The window.
    pub fn window(&self) -> &Taper {
        &self.window
    }
}

/// The series a Welch estimate reads: a rate record, or the rate whose phase is held, as
/// block means of `factor` consecutive samples.
///
/// From the phase `x[k] = tau0 sum_{j<k} (y[j] - c)` (the Allan family's input, `c` a constant
/// such as the mean that [`crate::analysis::into_phase`] takes out) the rate is
/// `y[k] - c = (x[k+1] - x[k]) / tau0`, and the mean of `f` consecutive rates is
/// `(x[(k+1) f] - x[k f]) / (f tau0)`: one buffer serves the Allan curves and every level of
/// the multi-resolution PSD, with no copy of the rate or of its decimated versions. The
/// constant is lost, which no estimate that removes each segment's mean sees; the difference
/// of two phase values carries their rounding, about `1e-16 max|x| / tau0`.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a> {
    source: Source<'a>,
    factor: usize,
}

#[derive(Debug, Clone, Copy)]
enum Source<'a> {
    Rate(&'a [f64]),
    Phase { x: &'a [f64], tau0: f64 },
}

impl<'a> Samples<'a> {
    /// The rate samples `y`.
    pub fn rate(y: &'a [f64]) -> Self {
        Samples {
            source: Source::Rate(y),
            factor: 1,
        }
    }

    /// The rate whose phase, sampled every `tau0` seconds, is `x`.
    pub fn of_phase(x: &'a [f64], tau0: f64) -> Self {
        Samples {
            source: Source::Phase { x, tau0 },
            factor: 1,
        }
    }

    /// Means of `by` consecutive samples of this series (trailing samples that fill no block
    /// dropped).
    pub fn decimated(self, by: usize) -> Self {
        Samples {
            factor: self.factor * by.max(1),
            ..self
        }
    }

    /// Samples in the series.
    pub fn len(&self) -> usize {
        match self.source {
            Source::Rate(y) => y.len() / self.factor,
            Source::Phase { x, .. } => x.len().saturating_sub(1) / self.factor,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The first value held that is not finite, with its index in the buffer held.
    fn first_non_finite(&self) -> Option<(usize, f64)> {
        let held = match self.source {
            Source::Rate(y) => y,
            Source::Phase { x, .. } => x,
        };
        held.iter()
            .copied()
            .enumerate()
            .find(|(_, v)| !v.is_finite())
    }

    /// Samples `start..start + out.len()` into `out`.
    fn read(&self, start: usize, out: &mut [f64]) {
        let f = self.factor;
        match self.source {
            Source::Rate(y) if f == 1 => out.copy_from_slice(&y[start..start + out.len()]),
            Source::Rate(y) => {
                let blocks = y[start * f..(start + out.len()) * f].chunks_exact(f);
                for (o, block) in out.iter_mut().zip(blocks) {
                    *o = block.iter().sum::<f64>() / f as f64;
                }
            }
            Source::Phase { x, tau0 } => {
                let scale = 1.0 / (f as f64 * tau0);
                for (i, o) in out.iter_mut().enumerate() {
                    let k = (start + i) * f;
                    *o = (x[k + f] - x[k]) * scale;
                }
            }
        }
    }
}

/// The one-sided density from the sum over `count` segments of `|X[j]|^2` (the module
/// documentation's normalisation).
fn density_of(mut sums: Vec<f64>, window: &Taper, count: usize, rate_hz: f64) -> Psd {
    let len = window.len();
    let sum_w2 = window.sum_of_squares();
    let scale = 1.0 / (rate_hz * sum_w2 * count as f64);
    let nyquist = if len.is_multiple_of(2) {
        len / 2
    } else {
        usize::MAX
    };
    for (j, s) in sums.iter_mut().enumerate() {
        let one_sided = if j == 0 || j == nyquist { 1.0 } else { 2.0 };
        *s *= scale * one_sided;
    }
    let freq = (0..=len / 2)
        .map(|j| j as f64 * rate_hz / len as f64)
        .collect();
    Psd {
        freq,
        density: sums,
        segments: count,
    }
}

/// One segment's transform, added to the running sum of `|X[j]|^2`.
struct Periodogram {
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    spectrum: Vec<realfft::num_complex::Complex<f64>>,
    scratch: Vec<realfft::num_complex::Complex<f64>>,
    acc: Vec<f64>,
}

impl Periodogram {
    /// Buffers for `fft`, adding to `acc` (`len / 2 + 1` sums).
    fn new(fft: Arc<dyn RealToComplex<f64>>, acc: Vec<f64>) -> Self {
        Periodogram {
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            acc,
            fft,
        }
    }

    /// Remove the segment's mean (when `detrend`), taper, transform, and add.
    fn add(&mut self, seg: &[f64], window: &Taper, detrend: bool) {
        self.input.copy_from_slice(seg);
        self.add_input(window, detrend);
    }

    /// [`Periodogram::add`] of the segment of `samples` from `start`, read straight into the
    /// transform's input.
    fn add_read(&mut self, samples: &Samples, start: usize, window: &Taper, detrend: bool) {
        samples.read(start, &mut self.input);
        self.add_input(window, detrend);
    }

    /// [`Periodogram::add`] of the segment already in the transform's input.
    fn add_input(&mut self, window: &Taper, detrend: bool) {
        taper(&mut self.input, window, detrend);
        // Lengths come from the plan itself, so this cannot fail.
        self.fft
            .process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch)
            .expect("buffer lengths match the FFT plan");
        for (a, c) in self.acc.iter_mut().zip(&self.spectrum) {
            *a += c.norm_sqr();
        }
    }
}

/// A segment less its mean (when `detrend`), times the window.
fn taper(segment: &mut [f64], window: &Taper, detrend: bool) {
    let mean = if detrend {
        segment.iter().sum::<f64>() / segment.len() as f64
    } else {
        0.0
    };
    for (v, w) in segment.iter_mut().zip(window.iter()) {
        *v = (*v - mean) * w;
    }
}

thread_local! {
    /// One FFT's work buffers per thread, serving every [`WelchStream`] the thread feeds
    /// (kept for the next segment: allocating them per segment costs more than the FFT).
    static WORK: std::cell::RefCell<Option<Periodogram>> = const { std::cell::RefCell::new(None) };
}

/// [`welch`] fed a record chunk by chunk, for records not held in memory: it keeps one
/// segment of samples and the sums, the FFT's work buffers being its thread's; estimates made with [`WelchStream::empty_like`] share the window
/// and the FFT's plan. With the record's length known in advance it averages the same
/// segments as [`welch`] (scipy's), so the density is the same up to rounding.
pub struct WelchStream {
    rate_hz: f64,
    detrend: bool,
    window: Arc<Taper>,
    fft: Arc<dyn RealToComplex<f64>>,
    step: usize,
    /// Samples of the segment being filled (the next segment starts at its front).
    pending: Vec<f64>,
    count: usize,
    /// Sum over segments of `|X[j]|^2`.
    acc: Vec<f64>,
}

impl WelchStream {
    /// A Welch estimate of `samples` samples at `rate_hz`; `opts.segment_len` 0 chooses the
    /// segment with [`segment_len_for`]`(samples)`. Errors as [`welch`]'s for a record of that
    /// length.
    pub fn new(samples: usize, rate_hz: f64, opts: &WelchOptions) -> Result<Self, PsdError> {
        if samples == 0 {
            return Err(PsdError::Empty);
        }
        let plan = SegmentPlan::for_length(samples, rate_hz, opts)?;
        Ok(WelchStream {
            rate_hz,
            detrend: opts.detrend_mean,
            window: Arc::new(Taper::new(opts.window, plan.len)),
            fft: shared_plans::forward(plan.len),
            step: plan.step,
            pending: Vec::with_capacity(plan.len),
            count: 0,
            acc: vec![0.0; plan.len / 2 + 1],
        })
    }

    /// An estimate with this one's settings and nothing fed, sharing its window and plan
    /// (another channel of the same record).
    pub fn empty_like(&self) -> WelchStream {
        WelchStream {
            rate_hz: self.rate_hz,
            detrend: self.detrend,
            window: self.window.clone(),
            fft: self.fft.clone(),
            step: self.step,
            pending: Vec::with_capacity(self.window.len()),
            count: 0,
            acc: vec![0.0; self.acc.len()],
        }
    }

    /// Take the record's next samples (finite: the caller validates them).
    pub fn extend(&mut self, mut ys: &[f64]) {
        let len = self.window.len();
        while !ys.is_empty() {
            let take = (len - self.pending.len()).min(ys.len());
            self.pending.extend_from_slice(&ys[..take]);
            ys = &ys[take..];
            if self.pending.len() == len {
                WORK.with_borrow_mut(|work| {
                    let periodogram = match work {
                        Some(p) if p.fft.len() == len => p,
                        _ => work.insert(Periodogram::new(self.fft.clone(), Vec::new())),
                    };
                    std::mem::swap(&mut periodogram.acc, &mut self.acc);
                    periodogram.add(&self.pending, &self.window, self.detrend);
                    std::mem::swap(&mut periodogram.acc, &mut self.acc);
                });
                self.count += 1;
                self.pending.drain(..self.step);
            }
        }
    }

    /// The density over the segments completed (trailing samples that fill none are
    /// dropped, as [`welch`] drops them); `Empty` when none was.
    pub fn finish(&self) -> Result<Psd, PsdError> {
        if self.count == 0 {
            return Err(PsdError::Empty);
        }
        Ok(density_of(
            self.acc.clone(),
            &self.window,
            self.count,
            self.rate_hz,
        ))
    }
}

/// Where the segments are: length, step and count, after validating the inputs.
struct SegmentPlan {
    len: usize,
    step: usize,
    count: usize,
}

impl SegmentPlan {
    /// The segments in contiguous groups, a few per thread, each group folded in parallel
    /// into its own accumulator (`start` of `add` is the segment's first sample); the
    /// accumulators come back in the segments' order, so sums taken over them in that order
    /// do not depend on the threads.
    fn in_ordered_groups<A: Send>(
        &self,
        init: impl Fn() -> A + Sync,
        add: impl Fn(&mut A, usize) + Sync,
    ) -> Vec<A> {
        let groups = (rayon::current_num_threads() * 2).clamp(1, self.count);
        let per_group = self.count.div_ceil(groups);
        (0..groups)
            .into_par_iter()
            .map(|g| {
                let mut acc = init();
                for s in g * per_group..((g + 1) * per_group).min(self.count) {
                    add(&mut acc, s * self.step);
                }
                acc
            })
            .collect()
    }

    fn new(y: &Samples, rate_hz: f64, opts: &WelchOptions) -> Result<Self, PsdError> {
        if y.is_empty() {
            return Err(PsdError::Empty);
        }
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(PsdError::BadRate(rate_hz));
        }
        if let Some((index, value)) = y.first_non_finite() {
            return Err(PsdError::NonFinite { index, value });
        }
        Self::for_length(y.len(), rate_hz, opts)
    }

    /// The plan for a record of `samples` finite samples.
    fn for_length(samples: usize, rate_hz: f64, opts: &WelchOptions) -> Result<Self, PsdError> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(PsdError::BadRate(rate_hz));
        }
        if !(opts.overlap.is_finite() && (0.0..1.0).contains(&opts.overlap)) {
            return Err(PsdError::BadOverlap(opts.overlap));
        }
        let len = match opts.segment_len {
            0 => segment_len_for(samples),
            l => l,
        };
        if len < 2 {
            return Err(PsdError::SegmentTooShort(len));
        }
        if len > samples {
            return Err(PsdError::SegmentTooLong {
                segment_len: len,
                samples,
            });
        }
        let overlap = ((opts.overlap * len as f64).floor() as usize).min(len - 1);
        let step = len - overlap;
        let count = (samples - overlap) / step;
        Ok(SegmentPlan { len, step, count })
    }

    /// Sum over segments of `|X[j]|^2`, `j = 0..=len/2`. With a plan, segments are split
    /// into contiguous groups handled in parallel and the group sums are added in order
    /// (deterministic); with [`PowerFft`] one buffer of a segment's length serves every
    /// segment in turn, while a record with segments that long keeps the other cores busy
    /// with its Allan curves ([`crate::analysis::pipeline`]).
    fn sum_periodograms(
        &self,
        y: &Samples,
        transform: &SegmentTransform,
        detrend: bool,
    ) -> Vec<f64> {
        let fft = match &transform.fft {
            SegmentFft::Plan(fft) => fft,
            SegmentFft::Powers(powers) => {
                let mut segment = vec![0.0; self.len];
                let mut sums = powers.sums();
                for s in 0..self.count {
                    y.read(s * self.step, &mut segment);
                    taper(&mut segment, &transform.window, detrend);
                    powers.add(&mut segment, &mut sums);
                }
                drop(segment);
                return powers.natural(&sums);
            }
        };
        let partial = self.in_ordered_groups(
            || Periodogram::new(fft.clone(), vec![0.0; self.len / 2 + 1]),
            |periodogram, start| periodogram.add_read(y, start, &transform.window, detrend),
        );
        let mut parts = partial.into_iter().map(|p| p.acc);
        let mut total = parts.next().unwrap_or_else(|| vec![0.0; self.len / 2 + 1]);
        for acc in parts {
            for (t, a) in total.iter_mut().zip(acc) {
                *t += a;
            }
        }
        total
    }
}

/// Segments from this length on are transformed by [`PowerFft`] when their length allows
/// ([`SegmentTransform::new`]).
pub const LONG_SEGMENT: usize = 1 << 18;

/// A PSD averaged into logarithmically spaced frequency bins.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BinnedPsd {
    /// Geometric mean of the frequencies of the points averaged in each bin, Hz.
    pub freq: Vec<f64>,
    /// Arithmetic mean of their densities (same units as the input).
    pub density: Vec<f64>,
    /// Number of points averaged.
    pub count: Vec<usize>,
}

/// Averages `psd` into bins `[10^(k/b), 10^((k+1)/b))` Hz, `b = bins_per_decade` (taken as
/// at least 1). DC (f <= 0) and points with a non-finite frequency or density are skipped;
/// empty bins are omitted. The density is averaged linearly (an unbiased estimate of the
/// mean density in the bin; its relative spread shrinks like `1/sqrt(count)`), the frequency
/// geometrically (the centre of the points on a log axis).
pub fn log_binned(psd: &Psd, bins_per_decade: usize) -> BinnedPsd {
    log_binned_arrays(&psd.freq, &psd.density, bins_per_decade)
}

/// [`log_binned`] on plain arrays (extra elements of the longer array are ignored).
pub fn log_binned_arrays(freq: &[f64], density: &[f64], bins_per_decade: usize) -> BinnedPsd {
    let b = bins_per_decade.max(1) as f64;
    let mut out = BinnedPsd {
        freq: Vec::new(),
        density: Vec::new(),
        count: Vec::new(),
    };
    let mut current: Option<(i64, f64, f64, usize)> = None; // (bin, sum ln f, sum S, count)
    let points = freq
        .iter()
        .zip(density)
        .filter(|(f, s)| f.is_finite() && **f > 0.0 && s.is_finite());
    for (&f, &s) in points {
        let bin = (f.log10() * b + 1e-9).floor() as i64;
        match current.as_mut() {
            Some(c) if c.0 == bin => {
                c.1 += f.ln();
                c.2 += s;
                c.3 += 1;
            }
            _ => {
                flush_bin(&mut out, current.take());
                current = Some((bin, f.ln(), s, 1));
            }
        }
    }
    flush_bin(&mut out, current);
    out
}

fn flush_bin(out: &mut BinnedPsd, bin: Option<(i64, f64, f64, usize)>) {
    if let Some((_, sum_ln_f, sum_s, n)) = bin {
        out.freq.push((sum_ln_f / n as f64).exp());
        out.density.push(sum_s / n as f64);
        out.count.push(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};
    use realfft::RealFftPlanner;

    const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/psd/");

    fn read_column(name: &str) -> Vec<f64> {
        let text = std::fs::read_to_string(format!("{DATA}{name}"))
            .unwrap_or_else(|e| panic!("reading {name}: {e}"));
        text.lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
            .map(|l| l.trim().parse::<f64>().expect("a number per line"))
            .collect()
    }

    /// (file, options) pairs written by tests/data/psd/make_reference.py.
    fn reference_cases() -> Vec<(&'static str, WelchOptions)> {
        let opts = |window, segment_len, overlap, detrend_mean| WelchOptions {
            segment_len,
            overlap,
            window,
            detrend_mean,
        };
        vec![
            ("hann.txt", opts(Window::Hann, 512, 0.5, true)),
            ("hamming.txt", opts(Window::Hamming, 512, 0.5, true)),
            ("blackman.txt", opts(Window::Blackman, 512, 0.5, true)),
            ("rectangular.txt", opts(Window::Rectangular, 512, 0.5, true)),
            ("hann_nodetrend.txt", opts(Window::Hann, 512, 0.5, false)),
            (
                "hann_overlap75_odd.txt",
                opts(Window::Hann, 333, 0.75, true),
            ),
        ]
    }

    #[test]
    fn welch_matches_scipy() {
        let y = read_column("series.txt");
        assert_eq!(y.len(), 4096);
        for (file, opts) in reference_cases() {
            let expected = read_column(file);
            let psd = welch(&y, 100.0, &opts).unwrap();
            assert_eq!(psd.density.len(), expected.len(), "{file}: length");
            let peak = expected.iter().cloned().fold(0.0, f64::max);
            let worst = psd
                .density
                .iter()
                .zip(&expected)
                .filter(|(_, w)| **w > 1e-6 * peak)
                .map(|(g, w)| (g / w - 1.0).abs())
                .fold(0.0, f64::max);
            println!("{file}: max relative difference from scipy {worst:.1e}");
            for (j, (got, want)) in psd.density.iter().zip(&expected).enumerate() {
                // Relative 1e-9, with an absolute floor for bins that are zero up to rounding
                // (the DC bin after mean removal).
                let tol = 1e-9 * want.abs() + 1e-13 * peak;
                assert!(
                    (got - want).abs() <= tol,
                    "{file} bin {j}: got {got:e}, scipy {want:e}"
                );
            }
            assert!((psd.freq[1] - 100.0 / opts.segment_len as f64).abs() < 1e-12);
        }
    }

    fn white(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sigma * z
            })
            .collect()
    }

    #[test]
    fn white_noise_level_is_two_n_squared() {
        // sigma = 0.3 at 100 Hz: N^2 = sigma^2 / rate = 9e-4, one-sided PSD 2 N^2 = 1.8e-3.
        let (sigma, rate) = (0.3, 100.0);
        let y = white(1 << 16, sigma, 7);
        let opts = WelchOptions {
            segment_len: 1024,
            ..WelchOptions::default()
        };
        let psd = welch(&y, rate, &opts).unwrap();
        assert_eq!(psd.segments, 127);
        let inner = &psd.density[1..psd.density.len() - 1];
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        let expected = 2.0 * sigma * sigma / rate;
        // Each bin ~ S chi2(2K)/(2K) with K ~ 0.95 * segments equivalent segments (Hann,
        // 50 %); averaging 511 bins (adjacent Hann bins are correlated: ~ half independent)
        // gives relative s.d. ~ 1/sqrt(0.95*127*511/2) = 0.0056; allow 4 s.d.
        let rel_sd = 1.0 / (0.95 * psd.segments as f64 * inner.len() as f64 / 2.0).sqrt();
        assert!(
            (mean / expected - 1.0).abs() < 4.0 * rel_sd,
            "mean PSD {mean:e}, expected {expected:e} (+- {rel_sd})"
        );
        // And one bin alone is within its own chi-squared spread most of the time: check the
        // fraction outside +-3 s.d. of a single bin is small.
        let bin_sd = 1.0 / (0.95 * psd.segments as f64).sqrt();
        let outside = inner
            .iter()
            .filter(|s| (*s / expected - 1.0).abs() > 3.0 * bin_sd)
            .count();
        assert!(outside < inner.len() / 50, "{outside} bins outside 3 s.d.");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let opts = WelchOptions::default();
        assert_eq!(welch(&[], 1.0, &opts), Err(PsdError::Empty));
        assert!(matches!(
            welch(&[1.0, f64::NAN, 2.0], 1.0, &opts),
            Err(PsdError::NonFinite { index: 1, .. })
        ));
        assert_eq!(welch(&[1.0; 8], 0.0, &opts), Err(PsdError::BadRate(0.0)));
        assert!(matches!(
            welch(&[1.0; 8], f64::NAN, &opts),
            Err(PsdError::BadRate(r)) if r.is_nan()
        ));
        let long = WelchOptions {
            segment_len: 16,
            ..opts.clone()
        };
        assert_eq!(
            welch(&[1.0; 8], 1.0, &long),
            Err(PsdError::SegmentTooLong {
                segment_len: 16,
                samples: 8
            })
        );
        let short = WelchOptions {
            segment_len: 1,
            ..opts.clone()
        };
        assert_eq!(
            welch(&[1.0; 8], 1.0, &short),
            Err(PsdError::SegmentTooShort(1))
        );
        let overlap = WelchOptions {
            overlap: 1.0,
            ..opts
        };
        assert_eq!(
            welch(&[1.0; 8], 1.0, &overlap),
            Err(PsdError::BadOverlap(1.0))
        );
    }

    #[test]
    fn window_names_parse_and_list_choices() {
        for w in Window::ALL {
            assert_eq!(w.to_string().parse::<Window>(), Ok(w));
        }
        assert_eq!("Hanning".parse::<Window>(), Ok(Window::Hann));
        assert_eq!("boxcar".parse::<Window>(), Ok(Window::Rectangular));
        let err = "kaiser".parse::<Window>().unwrap_err().to_string();
        assert_eq!(
            err,
            "unknown window 'kaiser': one of hann, hamming, blackman, rectangular"
        );
    }

    #[test]
    fn auto_segment_length_rule() {
        assert_eq!(segment_len_for(100), 100); // shorter than the minimum: whole record
        assert_eq!(segment_len_for(4096), 512);
        assert_eq!(segment_len_for(5_000), 512); // 625 -> 512
        assert_eq!(segment_len_for(1000), 256); // minimum
        assert_eq!(segment_len_for(5_760_000), 524_288);
        assert_eq!(segment_len_for(1 << 30), MAX_AUTO_SEGMENT);
        let psd = welch(&white(4096, 1.0, 1), 10.0, &WelchOptions::default()).unwrap();
        assert_eq!(psd.freq.len(), 257);
        assert_eq!(psd.segments, 15);
    }

    #[test]
    fn log_binning_averages_and_skips_dc() {
        let psd = Psd {
            freq: vec![0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 40.0],
            density: vec![9.0, 1.0, 3.0, 5.0, 2.0, 4.0, f64::NAN],
            segments: 1,
        };
        let b = log_binned(&psd, 1);
        assert_eq!(b.count, vec![3, 2]);
        assert!((b.freq[0] - 10f64.cbrt()).abs() < 1e-12); // (1*2*5)^(1/3)
        assert!((b.density[0] - 3.0).abs() < 1e-12);
        assert!((b.freq[1] - 200f64.sqrt()).abs() < 1e-12);
        assert!((b.density[1] - 3.0).abs() < 1e-12);
        let empty = log_binned(
            &Psd {
                freq: vec![],
                density: vec![],
                segments: 0,
            },
            0,
        );
        assert!(empty.freq.is_empty());
    }

    #[test]
    fn log_binning_of_white_noise_is_flat() {
        let psd = welch(&white(1 << 15, 0.3, 3), 100.0, &WelchOptions::default()).unwrap();
        let b = log_binned(&psd, 10);
        assert!(b.freq.windows(2).all(|w| w[1] > w[0]));
        assert_eq!(b.count.iter().sum::<usize>(), psd.freq.len() - 1);
        let expected = 1.8e-3;
        for (f, (s, n)) in b.freq.iter().zip(b.density.iter().zip(&b.count)) {
            let sd = 1.0 / (0.95 * psd.segments as f64 * (*n as f64 / 2.0).max(1.0)).sqrt();
            assert!(
                (s / expected - 1.0).abs() < 4.5 * sd,
                "bin at {f} Hz: {s:e}"
            );
        }
    }

    /// Fed in uneven chunks, the streamed estimate averages the same segments as `welch`
    /// and differs from it by rounding only (summation order).
    #[test]
    fn streamed_welch_is_welch() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let y: Vec<f64> = (0..10_007)
            .map(|_| 0.3 + Distribution::<f64>::sample(&StandardNormal, &mut rng))
            .collect();
        for (segment_len, window) in [(0, Window::Hann), (1000, Window::Blackman)] {
            let opts = WelchOptions {
                segment_len,
                window,
                ..WelchOptions::default()
            };
            let whole = welch(&y, 50.0, &opts).unwrap();
            let first = WelchStream::new(y.len(), 50.0, &opts).unwrap();
            let mut stream = first.empty_like();
            let mut rest = &y[..];
            for size in [1, 17, 4000, 333].iter().cycle() {
                let (chunk, tail) = rest.split_at((*size).min(rest.len()));
                stream.extend(chunk);
                rest = tail;
                if rest.is_empty() {
                    break;
                }
            }
            let streamed = stream.finish().unwrap();
            assert_eq!(streamed.segments, whole.segments);
            assert_eq!(streamed.freq, whole.freq);
            for (a, b) in streamed.density.iter().zip(&whole.density) {
                assert!((a / b - 1.0).abs() < 1e-12, "{a} vs {b}");
            }
        }
        assert_eq!(
            WelchStream::new(
                10,
                50.0,
                &WelchOptions {
                    segment_len: 11,
                    ..WelchOptions::default()
                }
            )
            .err(),
            Some(PsdError::SegmentTooLong {
                segment_len: 11,
                samples: 10
            })
        );
    }

    #[test]
    fn a_taper_holds_every_coefficient_of_its_window() {
        for kind in Window::ALL {
            for len in [1, 2, 3, 4, 5, 8, 255, 256, 1001] {
                let taper = Taper::new(kind, len);
                let direct = kind.coefficients(len);
                let held: Vec<f64> = taper.iter().collect();
                assert_eq!(held.len(), len, "{kind} {len}");
                for (k, (a, b)) in held.iter().zip(&direct).enumerate() {
                    assert!(
                        (a - b).abs() < 1e-15,
                        "{kind} {len} at {k}: {a} against {b}"
                    );
                }
            }
        }
    }

    /// The rate's running sum times tau0, x[0] = 0.
    fn phase_of(y: &[f64], tau0: f64) -> Vec<f64> {
        std::iter::once(0.0)
            .chain(y.iter().scan(0.0, |x, v| {
                *x += v * tau0;
                Some(*x)
            }))
            .collect()
    }

    #[test]
    fn the_rate_read_from_its_phase_and_in_block_means_is_the_rate() {
        let y: Vec<f64> = white(4099, 1.0, 11).iter().map(|v| v + 0.2).collect();
        let tau0 = 0.01;
        let x = phase_of(&y, tau0);
        for factor in [1, 2, 4, 7] {
            let from_rate = Samples::rate(&y).decimated(factor);
            let from_phase = Samples::of_phase(&x, tau0).decimated(factor);
            assert_eq!(from_rate.len(), y.len() / factor);
            assert_eq!(from_phase.len(), y.len() / factor);
            let (mut a, mut b) = (vec![0.0; 100], vec![0.0; 100]);
            from_rate.read(37, &mut a);
            from_phase.read(37, &mut b);
            for (i, (p, q)) in a.iter().zip(&b).enumerate() {
                let block = &y[(37 + i) * factor..(38 + i) * factor];
                let mean = block.iter().sum::<f64>() / factor as f64;
                assert!(
                    (p - mean).abs() < 1e-12,
                    "factor {factor}, rate, sample {i}"
                );
                assert!(
                    (q - mean).abs() < 1e-9,
                    "factor {factor}, phase, sample {i}"
                );
            }
        }
        // Welch from the phase is Welch from the rate.
        let opts = WelchOptions {
            segment_len: 512,
            ..WelchOptions::default()
        };
        let direct = welch(&y, 100.0, &opts).unwrap();
        let read = welch_of(Samples::of_phase(&x, tau0), 100.0, &opts, None).unwrap();
        for (a, b) in read.density.iter().zip(&direct.density).skip(1) {
            assert!((a / b - 1.0).abs() < 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn long_segments_are_summed_in_one_buffer_as_a_plan_sums_them() {
        // Segments of LONG_SEGMENT samples take PowerFft's route; the reference is Welch's
        // definition computed segment by segment with realfft's plan.
        let len = LONG_SEGMENT;
        let y = white(2 * len + len / 2 + 3, 0.5, 5);
        let opts = WelchOptions {
            segment_len: len,
            ..WelchOptions::default()
        };
        let transform = SegmentTransform::new(len, Window::Hann);
        assert!(matches!(transform.fft, SegmentFft::Powers(_)));
        let got = welch_of(Samples::rate(&y), 20.0, &opts, Some(&transform)).unwrap();
        let plan = RealFftPlanner::<f64>::new().plan_fft_forward(len);
        let w = Window::Hann.coefficients(len);
        let mut sums = vec![0.0; len / 2 + 1];
        let step = len / 2;
        let count = (y.len() - step) / step;
        for s in 0..count {
            let seg = &y[s * step..s * step + len];
            let mean = seg.iter().sum::<f64>() / len as f64;
            let mut input: Vec<f64> = seg.iter().zip(&w).map(|(v, w)| (v - mean) * w).collect();
            let mut out = plan.make_output_vec();
            plan.process(&mut input, &mut out).unwrap();
            for (a, x) in sums.iter_mut().zip(&out) {
                *a += x.norm_sqr();
            }
        }
        let want = density_of(sums, &Taper::new(Window::Hann, len), count, 20.0);
        assert_eq!(got.segments, count);
        for (k, (a, b)) in got.density.iter().zip(&want.density).enumerate() {
            assert!((a / b - 1.0).abs() < 1e-9, "bin {k}: {a} vs {b}");
        }
    }

    #[test]
    fn a_few_bins_summed_directly_are_welchs_bins() {
        // Odd and even lengths, every window, with and without the mean taken out, from the
        // rate and from block means of the phase, segments shorter and longer than a chunk.
        let y: Vec<f64> = white(9000, 1.0, 3)
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.3 + 1e-4 * k as f64)
            .collect();
        let x = phase_of(&y, 0.01);
        for (len, window, detrend, factor) in [
            (512, Window::Hann, true, 1),
            (3001, Window::Hamming, false, 1),
            (2048, Window::Blackman, true, 2),
            (1500, Window::Rectangular, true, 4),
            (4096, Window::Hann, false, 2),
        ] {
            let opts = WelchOptions {
                segment_len: len,
                overlap: 0.5,
                window,
                detrend_mean: detrend,
            };
            for samples in [
                Samples::rate(&y).decimated(factor),
                Samples::of_phase(&x, 0.01).decimated(factor),
            ] {
                let full = welch_of(samples, 100.0, &opts, None).unwrap();
                let taper = Taper::new(window, len);
                let some = welch_bins_of(samples, 100.0, &opts, &taper, 2..7).unwrap();
                assert_eq!(some.segments, full.segments);
                assert_eq!(some.freq, full.freq);
                for (j, (a, b)) in some.density.iter().zip(&full.density).enumerate() {
                    match j {
                        2..7 => assert!((a / b - 1.0).abs() < 1e-9, "{len} bin {j}: {a} vs {b}"),
                        _ => assert!(a.is_nan(), "{len} bin {j} outside the range: {a}"),
                    }
                }
            }
        }
    }
}

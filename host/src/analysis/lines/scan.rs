//! The periodograms, the tests of single bins and runs of bins at every scale, and the
//! measurement of the bands that pass (module documentation of [`super`], steps 1, 3 and 5).

use super::background::{Background, background};
use super::uncertainty::{Spread, tone_spread};
use super::{
    HANN_MEDIAN_VARIANCE, Line, LineErrors, Measured, RECT_MEDIAN_VARIANCE, SHAPE_ERROR, Search,
    TONE_LOBE, Tone, lorentzian,
};
use rayon::prelude::*;
use realfft::num_complex::Complex;
use statrs::distribution::{Continuous, FisherSnedecor};
use statrs::function::beta::checked_beta_reg;
use std::collections::HashMap;
use std::f64::consts::PI;

/// The DFT of a record and its two periodograms (one-sided PSD, u^2/Hz, k = 0..=n/2), the
/// periodograms computed from the DFT where they are read rather than held: a record's
/// periodograms would be as large as the record.
pub(super) struct Spectra {
    pub(super) dft: Vec<Complex<f64>>,
    /// The record's length.
    n: usize,
    rect_scale: f64,
    hann_scale: f64,
}

impl Spectra {
    /// Bins k = 0..=n/2.
    pub(super) fn len(&self) -> usize {
        self.dft.len()
    }

    /// Rectangular window: `2 |X_k|^2 / (f_s n)`.
    pub(super) fn rect(&self, k: usize) -> f64 {
        self.dft[k].norm_sqr() * self.rect_scale
    }

    /// Periodic Hann window `w_t = (1 - cos(2 pi t / n)) / 2`, whose DFT is
    /// `X_k / 2 - (X_{k-1} + X_{k+1}) / 4`: `2 |X^H_k|^2 / (f_s sum w^2)`, `sum w^2 = 3 n / 8`.
    pub(super) fn hann(&self, k: usize) -> f64 {
        let k = k as isize;
        (0.5 * self.at(k) - 0.25 * (self.at(k - 1) + self.at(k + 1))).norm_sqr() * self.hann_scale
    }

    /// `X_k` for k from -1 to n/2 + 1: `X_{-1} = conj(X_1)`; past the end,
    /// `X_{n/2 + 1} = conj(X_{n/2 - 1})` (even n) or `conj(X_{(n-1)/2})` (odd n).
    fn at(&self, k: isize) -> Complex<f64> {
        let last = self.dft.len() - 1;
        if k < 0 {
            self.dft[(-k) as usize].conj()
        } else if k as usize > last {
            let mirror = if self.n.is_multiple_of(2) {
                2 * last - k as usize
            } else {
                2 * last + 1 - k as usize
            };
            self.dft[mirror].conj()
        } else {
            self.dft[k as usize]
        }
    }
}

/// A background for each periodogram, and the bins left out of both.
pub(super) struct Backgrounds {
    pub(super) rect: Background,
    pub(super) hann: Background,
    mask: Vec<bool>,
}

/// The bands that stand out of a background (inclusive bin ranges) and, for each, the
/// family-wise false-alarm probability of the least likely test taken inside it.
pub(super) struct Bands {
    pub(super) ranges: Vec<(usize, usize)>,
    pub(super) p_values: Vec<f64>,
}

/// Rounds of [`Search::remeasure_wide`]: each takes out the wings the last one measured. The
/// first makes the correction; the second changes width and power by under 1 %.
const WING_ROUNDS: usize = 2;

/// Bins whose background's lowest level is found at once for the single-bin tests.
const SETTLED_STRETCH: usize = 256;

/// A line narrower than this many bins is not resolved: its power lies in its own bins.
const RESOLVED_WIDTH_BINS: f64 = 4.0;

impl Search<'_> {
    /// The one-sided PSD at `f` of a measured line as sampled, its images folded in
    /// ([`super::line_density`]).
    fn folded_density(&self, m: &Measured, f: f64) -> f64 {
        super::line_density(m.freq_hz, m.width_hz, m.power, self.rate_hz, f)
    }

    /// The folded images alone ([`Search::folded_density`] less the line's own Lorentzian).
    pub(super) fn image_density(&self, m: &Measured, f: f64) -> f64 {
        lorentzian(self.rate_hz - m.freq_hz, m.width_hz, m.power, f)
            + lorentzian(-m.freq_hz, m.width_hz, m.power, f)
    }
}

/// Complex amplitude correlation of neighbouring Hann-window bins of a smooth spectrum
/// (`-2/3` at lag 1, `1/6` at lag 2) makes the variance of a sum of their powers
/// `1 + 2 (4/9 + 1/36)` times that of independent bins.
const HANN_SUM_VARIANCE: f64 = 1.0 + 2.0 * (4.0 / 9.0 + 1.0 / 36.0);

impl Search<'_> {
    pub(super) fn df(&self) -> f64 {
        self.rate_hz / self.n as f64
    }

    /// The widest line searched, in bins.
    pub(super) fn widest(&self) -> usize {
        ((self.opts.max_width_hz / self.df()).floor() as usize).max(1)
    }

    /// The periodograms of a DFT of the searched samples (bins 0..=n/2).
    pub(super) fn periodograms(&self, dft: Vec<Complex<f64>>) -> Spectra {
        let n = self.n as f64;
        Spectra {
            dft,
            n: self.n,
            rect_scale: 2.0 / (self.rate_hz * n),
            hann_scale: 2.0 / (self.rate_hz * 3.0 * n / 8.0),
        }
    }

    /// The backgrounds (two passes: the second leaves out what the first flagged) and the
    /// bands that stand out of them.
    pub(super) fn backgrounds_and_bands(&self, spectra: &Spectra) -> (Backgrounds, Bands) {
        let first = self.estimate(spectra, vec![false; spectra.len()], None);
        let bands = self.bands(spectra, &first);
        if bands.ranges.is_empty() {
            return (first, bands);
        }
        let mut mask = first.mask;
        self.mask_bands(&mut mask, &bands.ranges);
        let second = self.estimate(spectra, mask, None);
        let bands = self.bands(spectra, &second);
        (second, bands)
    }

    /// Both backgrounds, leaving out the masked bins. With `wings` (lines and the backgrounds
    /// they were measured against), each bin's power is first scaled by the share of it that
    /// those backgrounds put in the background, `S / (S + L)`, L the lines' Lorentzian
    /// excess there: a bin of expected value `S + L` scaled so is again an exponential of
    /// mean S, whose median the background reads without bias. (Subtracting L instead
    /// leaves a median of `S ln 2 - 0.31 L`, below zero wherever the wings exceed twice the
    /// background, as they do on a filter's roll-off.)
    fn estimate(
        &self,
        spectra: &Spectra,
        mask: Vec<bool>,
        wings: Option<(&[Measured], &Backgrounds)>,
    ) -> Backgrounds {
        let df = self.df();
        // The share of bin k's power that a background `level` holds.
        let share = |level: &dyn Fn(&Backgrounds) -> &Background, k: usize| -> f64 {
            wings.map_or(1.0, |(lines, previous)| {
                let f = k as f64 * df;
                let excess: f64 = lines.iter().map(|m| self.folded_density(m, f)).sum();
                let s = level(previous).level(k);
                s / (s + excess)
            })
        };
        let (rect, hann) = rayon::join(
            || {
                background(
                    |k| spectra.rect(k) * share(&|b| &b.rect, k),
                    &mask,
                    self.k_hi,
                    self.widest(),
                    RECT_MEDIAN_VARIANCE,
                )
            },
            || {
                background(
                    |k| spectra.hann(k) * share(&|b| &b.hann, k),
                    &mask,
                    self.k_hi,
                    self.widest(),
                    HANN_MEDIAN_VARIANCE,
                )
            },
        );
        Backgrounds { rect, hann, mask }
    }

    /// Marks every band of `bands`, widened by its own width on each side.
    fn mask_bands(&self, mask: &mut [bool], bands: &[(usize, usize)]) {
        for &(a, b) in bands {
            let (lo, hi) = self.widen(a, b, &[]);
            mask[lo..=hi].iter_mut().for_each(|m| *m = true);
        }
    }

    /// The bands measured again against a background from which the measured lines'
    /// Lorentzian wings were taken out ([`WING_ROUNDS`] times, each round's lines giving the
    /// next round's wings). A resolved line's wings reach far beyond its band (a Lorentzian
    /// 15 times the background at its peak is still above it at two widths from its centre):
    /// left in, they raise the running median there, and the excess measured against it
    /// comes out narrower and weaker than the line (5-16 % for lines 0.3-1 Hz wide at 10-40
    /// times the background). Lines the bins do not resolve have no wings and leave the
    /// background as it was; lines wider than [`LineOptions::max_relative_width`] of their
    /// frequency fill the running median's window, and taking their wings out would feed
    /// back on itself (each round wider than the last), so they too are left as measured.
    pub(super) fn remeasure_wide(
        &self,
        spectra: &Spectra,
        bands: &Bands,
        backgrounds: Backgrounds,
        measured: Vec<Measured>,
    ) -> (Backgrounds, Vec<Measured>) {
        let resolved = |m: &Measured| {
            m.width_hz > RESOLVED_WIDTH_BINS * self.df()
                && m.width_hz <= self.opts.max_relative_width * m.freq_hz
        };
        if !measured.iter().any(resolved) {
            return (backgrounds, measured);
        }
        // The bins the backgrounds left out (the final bands, widened, may reach the end of
        // the spectrum and leave nothing to extrapolate from).
        let mask = backgrounds.mask.clone();
        let (mut backgrounds, mut measured) = (backgrounds, measured);
        for _ in 0..WING_ROUNDS {
            let wings: Vec<Measured> = measured.iter().copied().filter(resolved).collect();
            backgrounds = self.estimate(spectra, mask.clone(), Some((&wings, &backgrounds)));
            measured = self.measure_bands_beside(spectra, &backgrounds, bands, &wings);
        }
        (backgrounds, measured)
    }

    /// Every band with an excess, measured on the Hann periodogram against its background.
    pub(super) fn measure_bands(
        &self,
        spectra: &Spectra,
        backgrounds: &Backgrounds,
        bands: &Bands,
    ) -> Vec<Measured> {
        self.measure_bands_beside(spectra, backgrounds, bands, &[])
    }

    /// [`Search::measure_bands`], each band's own folded images (from `lines`, the previous
    /// measurement of the resolved lines) added to its background: the excess is then the
    /// line's unfolded Lorentzian, whose tails beyond the window the truncation correction
    /// restores (left in, a line 1.5-3 widths below Nyquist read 4 % wide and 4 % strong).
    fn measure_bands_beside(
        &self,
        spectra: &Spectra,
        backgrounds: &Backgrounds,
        bands: &Bands,
        lines: &[Measured],
    ) -> Vec<Measured> {
        let df = self.df();
        bands
            .ranges
            .iter()
            .zip(&bands.p_values)
            .map(|(&(a, b), &p_value)| {
                let own = lines.iter().find(|m| {
                    let bin = m.freq_hz / df;
                    a as f64 - 0.5 <= bin && bin <= b as f64 + 0.5
                });
                let hann = |k| spectra.hann(k);
                let background = |k: usize| {
                    backgrounds.hann.level(k)
                        + own.map_or(0.0, |m| self.image_density(m, k as f64 * df))
                };
                Measured {
                    p_value,
                    ..self.measure(hann, background, (a, b), &bands.ranges)
                }
            })
            .filter(|m| m.power > 0.0)
            .collect()
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
    fn bands(&self, spectra: &Spectra, bg: &Backgrounds) -> Bands {
        let (k_lo, k_hi) = (self.k_lo, self.k_hi);
        if k_hi < k_lo {
            return Bands {
                ranges: Vec::new(),
                p_values: Vec::new(),
            };
        }
        let widest = self.widest();
        let scales: Vec<usize> = std::iter::successors(Some(1usize), |l| Some(l * 2))
            .take_while(|&l| l <= widest)
            .collect();
        let allowed = |j: usize, l: usize| {
            l == 1 || l as f64 <= self.opts.max_relative_width * (j as f64 + (l as f64 - 1.0) / 2.0)
        };
        // The runs of l bins starting in [from, to): every step-th bin from k_lo on.
        let runs = |l: usize, from: usize, to: usize| {
            let step = (l / 2).max(1);
            let first = k_lo + (from.saturating_sub(k_lo)).div_ceil(step) * step;
            (first..to.min((k_hi + 2).saturating_sub(l)))
                .step_by(step)
                .filter(move |&j| allowed(j, l))
        };
        let octave = |j: usize, l: usize| (j + l / 2).ilog2() as usize;
        let mut per_octave = vec![0usize; k_hi.ilog2() as usize + 1];
        for &l in &scales {
            for j in runs(l, k_lo, k_hi + 1) {
                per_octave[octave(j, l)] += 1;
            }
        }
        let octaves = per_octave.iter().filter(|&&c| c > 0).count().max(1);
        let least_rel_var = [bg.hann.least_rel_var(), bg.rect.least_rel_var()];
        // The runs starting in one chunk of bins, tested against the ratios' running sum over
        // the chunk and the widest run beyond it: chunks go to threads, and no sum as long as
        // the spectrum is held.
        let chunk = (4 * widest).max(1 << 16);
        let starts: Vec<usize> = (k_lo..=k_hi).step_by(chunk).collect();
        let tested = |from: usize| -> Vec<Passed> {
            let to = (from + chunk).min(k_hi + 1);
            let end = (to + widest).min(k_hi + 1);
            let (mut rect, mut hann) = (bg.rect.cursor(), bg.hann.cursor());
            let mut cum = Vec::with_capacity(end - from + 1);
            cum.push(0.0);
            let mut sum = 0.0;
            for k in from..end {
                sum += spectra.rect(k) / rect.level(k);
                cum.push(sum);
            }
            let mut thresholds = Thresholds::default();
            let mut passed = Vec::new();
            for &l in &scales {
                // Every threshold lies beyond two standard deviations (level < 1 %): most
                // runs are settled without one, and most of those by the least variance
                // alone.
                let settled =
                    1.0 + 2.0 * (1.0 / l as f64 + least_rel_var[usize::from(l > 1)]).sqrt();
                // A single bin at most `settled` times the background's lowest level over its
                // stretch is settled without its own level (an exponential per bin).
                let mut floor = (0, 0.0);
                for j in runs(l, from, to) {
                    let (mean, background) = if l == 1 {
                        if j >= floor.0 {
                            let end = (j + SETTLED_STRETCH).min(k_hi + 1);
                            floor = (end, settled * bg.hann.lowest(j, end - 1) * (1.0 - 1e-12));
                        }
                        let power = spectra.hann(j);
                        if power <= floor.1 {
                            continue;
                        }
                        (power / hann.level(j), &mut hann)
                    } else {
                        ((cum[j + l - from] - cum[j - from]) / l as f64, &mut rect)
                    };
                    if mean <= settled {
                        continue;
                    }
                    let o = octave(j, l);
                    let level = self.opts.false_alarm / (octaves * per_octave[o]) as f64;
                    let centre = j + l / 2;
                    let v = background.rel_var(centre);
                    if mean <= 1.0 + 2.0 * (1.0 / l as f64 + v).sqrt() {
                        continue;
                    }
                    let bucket = background.bucket(centre);
                    if mean > thresholds.get(l, bucket, o, level) {
                        passed.push(Passed {
                            surprise: surprise(mean, l, v),
                            first: j,
                            len: l,
                            mean,
                            bucket,
                            tests: octaves * per_octave[o],
                        });
                    }
                }
            }
            passed
        };
        // Passing tests, ranked by how unlikely they are without a line, so that each line is
        // located by the run that fits it best (ties: the shorter, then the lower run first).
        let mut passed: Vec<Passed> = starts.into_par_iter().flat_map_iter(tested).collect();
        passed.sort_by(|a, b| {
            b.surprise
                .total_cmp(&a.surprise)
                .then(a.len.cmp(&b.len))
                .then(a.first.cmp(&b.first))
        });
        // The best run first; a run that overlaps one already taken adds nothing.
        let mut marked = vec![false; k_hi - k_lo + 1];
        let mut taken: Vec<&Passed> = Vec::new();
        for t in &passed {
            let run = &mut marked[t.first - k_lo..t.first - k_lo + t.len];
            if !run.iter().any(|&m| m) {
                run.iter_mut().for_each(|m| *m = true);
                taken.push(t);
            }
        }
        let ranges = merge_runs(&marked, k_lo);
        let p_values = ranges
            .iter()
            .map(|&(a, b)| {
                taken
                    .iter()
                    .filter(|t| a <= t.first && t.first <= b)
                    .map(|t| t.family_wise_p())
                    .fold(1.0, f64::min)
            })
            .collect();
        Bands { ranges, p_values }
    }

    /// The excess of one band over the background, on the Hann periodogram (no leakage
    /// beyond +-2 bins of a tone).
    pub(super) fn measure(
        &self,
        power: impl Fn(usize) -> f64,
        background: impl Fn(usize) -> f64,
        band: (usize, usize),
        others: &[(usize, usize)],
    ) -> Measured {
        let df = self.df();
        let (lo, hi) = self.widen(band.0, band.1, others);
        let first = Excess::of(&power, &background, lo, hi, df);
        // Again on a window centred on the line, reaching two widths beyond its quartiles
        // (a band found off-centre would bias the centre and width towards its own side).
        let reach =
            (((band.1 - band.0 + 1) as f64).max(2.0 * first.iqr).ceil() as usize).max(TONE_LOBE);
        let centre = (first.centre.round().max(0.0) as usize).clamp(lo, hi);
        let (lo, hi) = self.clip(centre.saturating_sub(reach), centre + reach, band, others);
        let e = Excess::of(&power, &background, lo, hi, df);
        let (width, fraction, centre) =
            lorentzian_truncation(e.iqr, e.centre, lo as f64 - 0.5, hi as f64 + 0.5);
        let near: f64 = (e.peak.saturating_sub(TONE_LOBE).max(lo)..=(e.peak + TONE_LOBE).min(hi))
            .map(|k| (power(k) - background(k)) * df)
            .sum();
        let (lo, hi, peak, total) = (lo, hi, e.peak, e.total);
        let (band_lo, band_hi) = band;
        let sum_s: f64 = (band_lo..=band_hi).map(&background).sum();
        let sum_s2: f64 = (band_lo..=band_hi)
            .map(|k| {
                let s = background(k);
                s * s
            })
            .sum();
        let sum_p: f64 = (band_lo..=band_hi).map(&power).sum();
        let spread = (HANN_SUM_VARIANCE * sum_s2 + (SHAPE_ERROR * sum_s).powi(2)).sqrt();
        Measured {
            band,
            lo,
            hi,
            peak,
            power: total / fraction,
            freq_hz: centre * df,
            width_hz: width * df,
            statistic: (sum_p - sum_s) / spread,
            p_value: 1.0,
            concentrated: total > 0.0 && near >= 0.5 * total,
        }
    }

    /// Lines from the fitted tones and the last round's bands, with their standard errors
    /// (`bands`: every band of the round). A band's errors are drawn against the Hann
    /// periodogram's background, which it was measured against; a tone's are taken at the
    /// rectangular one's, the noise a least-squares fit over the whole record sees (leakage
    /// included).
    pub(super) fn assemble(
        &self,
        tones: &[Tone],
        measured: &[Measured],
        backgrounds: &Backgrounds,
        bands: &[(usize, usize)],
    ) -> Vec<Line> {
        let duration_s = self.n as f64 / self.rate_hz;
        let wanted = self.opts.standard_errors;
        let spreads: Vec<Spread> = measured
            .iter()
            .map(|m| {
                if wanted {
                    self.spread(m, &backgrounds.hann, bands)
                } else {
                    Spread::UNKNOWN
                }
            })
            .collect();
        // Each band left after the tones belongs to the strongest tone at its core (its
        // residual: the line's width), or else is a line of its own. The core is the band's
        // half-power extent (plus the tone's lobe), not its measurement window: on a steep
        // background a strong line's window can reach a separate tone several widths away.
        let df = self.df();
        let at_core = |m: &Measured, t: &Tone| {
            let tone_hz = t.freq_hz(self.rate_hz);
            m.lo <= t.bin + TONE_LOBE
                && t.bin <= m.hi + TONE_LOBE
                && (tone_hz - m.freq_hz).abs() <= m.width_hz + TONE_LOBE as f64 * df
        };
        let mut used = vec![false; measured.len()];
        let mut order: Vec<usize> = (0..tones.len()).collect();
        order.sort_by(|&a, &b| tones[b].power().total_cmp(&tones[a].power()));
        let mut lines: Vec<Line> = Vec::with_capacity(tones.len() + measured.len());
        for &i in &order {
            let t = &tones[i];
            let rest = measured
                .iter()
                .zip(&used)
                .position(|(m, u)| !*u && at_core(m, t));
            let tone_hz = t.freq_hz(self.rate_hz);
            let own = if wanted {
                tone_spread(t, backgrounds.rect.level(t.bin), duration_s)
            } else {
                Spread::UNKNOWN
            };
            let (extra, width, rest_hz, statistic, p_value, rest_spread) = match rest {
                Some(i) => {
                    used[i] = true;
                    let m = &measured[i];
                    (
                        m.power,
                        m.width_hz,
                        m.freq_hz,
                        m.statistic.max(t.statistic),
                        m.p_value.min(t.p_value),
                        Some(spreads[i]),
                    )
                }
                None => (0.0, 0.0, tone_hz, t.statistic, t.p_value, None),
            };
            let power = t.power() + extra;
            // Power-weighted: the tone's frequency when it holds the line's power, the rest's
            // centre when the tone was only a peak of a wider line.
            let freq_hz = (t.power() * tone_hz + extra * rest_hz) / power;
            let spread = match rest_spread {
                None => own,
                // Independent errors of the two parts, propagated through the weighted mean
                // (its weights move with the powers) and the sum.
                Some(r) => {
                    let (w_tone, w_rest) = (t.power() / power, extra / power);
                    let freq_var = (w_tone * own.freq_hz).powi(2)
                        + (w_rest * r.freq_hz).powi(2)
                        + ((tone_hz - freq_hz) / power * own.power).powi(2)
                        + ((rest_hz - freq_hz) / power * r.power).powi(2);
                    Spread {
                        freq_hz: freq_var.sqrt(),
                        width_hz: r.width_hz,
                        power: own.power.hypot(r.power),
                    }
                }
            };
            lines.push(line(freq_hz, width, power, statistic, p_value, spread));
        }
        lines.extend(
            measured
                .iter()
                .zip(&used)
                .zip(&spreads)
                .filter(|((_, u), _)| !**u)
                .map(|((m, _), spread)| {
                    line(
                        m.freq_hz,
                        m.width_hz,
                        m.power,
                        m.statistic,
                        m.p_value,
                        *spread,
                    )
                }),
        );
        lines.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
        lines
    }
}

/// A line of `power` (u^2), its amplitude `sqrt(2 power)` and that amplitude's error
/// `sd(power) / amplitude`.
fn line(
    freq_hz: f64,
    width_hz: f64,
    power: f64,
    statistic: f64,
    p_value: f64,
    spread: Spread,
) -> Line {
    let amplitude = (2.0 * power).sqrt();
    Line {
        freq_hz,
        amplitude,
        width_hz,
        power,
        statistic,
        p_value,
        standard_errors: LineErrors {
            freq_hz: spread.freq_hz,
            amplitude: spread.power / amplitude,
            width_hz: (width_hz > 0.0).then_some(spread.width_hz),
        },
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
    fn of(
        power: impl Fn(usize) -> f64,
        background: impl Fn(usize) -> f64,
        lo: usize,
        hi: usize,
        df: f64,
    ) -> Excess {
        let excess: Vec<f64> = (lo..=hi).map(|k| (power(k) - background(k)) * df).collect();
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

/// Width, contained fraction and centre of a Lorentzian (Cauchy) line of which only the bins
/// from `lo` to `hi` (edges, in bins) were measured, from the interquartile range `iqr` and the
/// median `median` (bins) of the measured part. With half-width g and the window `[-a, b]`
/// around the centre, `A = atan(a/g)`, `B = atan(b/g)`, the truncated quantiles are
/// `x_q = g tan(q (A + B) - A)`; g is solved from `x_0.75 - x_0.25 = iqr` (bisection; the
/// IQR grows with g), the fraction is `(A + B) / pi`, and the centre lies `g tan((B - A) / 2)`
/// below the truncated median (a window cut short on one side, by Nyquist or a neighbouring
/// band, pulls the median towards the other); a and b are taken from the centre, which is
/// found by a few fixed-point steps from the median. Returns (full width 2g, fraction,
/// centre); an IQR under 1.5 bins is a line the bins do not resolve: (iqr, 1, median).
fn lorentzian_truncation(iqr: f64, median: f64, lo: f64, hi: f64) -> (f64, f64, f64) {
    let mut centre = median;
    let mut out = (iqr, 1.0, median);
    for _ in 0..CENTRE_STEPS {
        let (a, b) = (centre - lo, hi - centre);
        let Some((g, fraction)) = truncated_half_width(iqr, a, b) else {
            return out;
        };
        let (aa, bb) = ((a / g).atan(), (b / g).atan());
        centre = median - g * (0.5 * (bb - aa)).tan();
        out = (2.0 * g, fraction, centre);
    }
    out
}

/// Fixed-point steps of a truncated line's centre: each shrinks the error by the ratio of the
/// median's shift to the window's asymmetry, a few tenths at most.
const CENTRE_STEPS: usize = 4;

/// The half-width g (bins) of a Lorentzian whose part within `[-a, b]` of its centre has
/// interquartile range `iqr`, and that part's fraction of its power; None when the bins do not
/// resolve it (IQR under 1.5 bins) or the measured part is flatter than any Lorentzian.
fn truncated_half_width(iqr: f64, a: f64, b: f64) -> Option<(f64, f64)> {
    if iqr < 1.5 || a <= 0.0 || b <= 0.0 {
        return None;
    }
    let model = |g: f64| {
        let (aa, bb) = ((a / g).atan(), (b / g).atan());
        let x = |q: f64| g * (q * (aa + bb) - aa).tan();
        (x(0.75) - x(0.25), (aa + bb) / PI)
    };
    let (mut lo, mut hi) = (1e-3, 1e3 * (a + b));
    if model(hi).0 <= iqr {
        return None;
    }
    for _ in 0..100 {
        let mid = (lo * hi).sqrt();
        if model(mid).0 < iqr {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((hi, model(hi).1))
}

/// Marked bins (index 0 is bin `first`) as inclusive bin ranges; runs that touch or lie
/// within a quarter of the longer run (at least 2 bins) of each other are one band (a line's
/// wing that dipped below the threshold for a few bins).
pub(super) fn merge_runs(marked: &[bool], first: usize) -> Vec<(usize, usize)> {
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

/// A test that passed its threshold: a run of `len` bins from `first` whose mean ratio to the
/// background is `mean`, the background's degrees of freedom on the grid at `bucket`, and the
/// number of tests its false-alarm share was divided among (octaves times the tests in its
/// octave).
struct Passed {
    surprise: f64,
    first: usize,
    len: usize,
    mean: f64,
    bucket: i32,
    tests: usize,
}

impl Passed {
    /// The family-wise false-alarm probability at which this test would just pass: its own
    /// tail probability `P(F(2 len, nu) > mean)` times the tests it shares the budget with
    /// (the Bonferroni split of [`LineOptions::false_alarm`] run backwards), at most 1. It is
    /// below the search's `false_alarm` for every test that passed; 0 where the tail
    /// underflows double precision.
    fn family_wise_p(&self) -> f64 {
        let nu = 2.0 * DOF_GRID.powi(self.bucket);
        let tail = f_tail(2.0 * self.len as f64, nu, self.mean);
        (tail * self.tests as f64).min(1.0)
    }
}

/// `P(F(d1, d2) > x)` as `I_z(d2 / 2, d1 / 2)` with `z = d2 / (d2 + d1 x)`, the regularised
/// incomplete beta function (Abramowitz and Stegun 26.6.2), written so that a ratio too large
/// for double precision (a background near zero, as on a synthetic periodic record) gives
/// z = 0 and a tail of 0: statrs' own survival function forms `1 - d1 x / (d1 x + d2)`, which
/// is NaN there, and fails.
pub(super) fn f_tail(d1: f64, d2: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let z = d2 / (d2 + d1 * x);
    if z.is_finite() {
        checked_beta_reg(d2 / 2.0, d1 / 2.0, z.clamp(0.0, 1.0)).unwrap_or(0.0)
    } else {
        0.0
    }
}

/// Ratio of the grid on which the background's degrees of freedom are rounded down (which
/// errs on the cautious side).
pub(super) const DOF_GRID: f64 = 1.25;

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
pub(super) fn f_threshold(d1: f64, d2: f64, p: f64) -> f64 {
    if d1 == 2.0 {
        return d2 / 2.0 * (p.powf(-2.0 / d2) - 1.0);
    }
    let Ok(f) = FisherSnedecor::new(d1, d2) else {
        return f64::INFINITY;
    };
    let target = p.ln();
    let excess = |u: f64| f_tail(d1, d2, u.exp()).ln() - target;
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
        let sf = f_tail(d1, d2, x);
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

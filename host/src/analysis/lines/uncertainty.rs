//! The standard errors of what the search reports of a line (module documentation of
//! [`super`], step 6): analytic for a pure tone, a parametric bootstrap of the periodogram
//! for a band.

use super::background::Background;
use super::{Measured, Search, Tone, lorentzian};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use realfft::num_complex::Complex;
use std::f64::consts::PI;

/// Periodograms drawn per band: the standard deviation of 100 draws is within 7 % (one
/// standard error, `1 / sqrt(2 (R - 1))`) of the spread it estimates.
pub(super) const SPREAD_DRAWS: usize = 100;

/// Standard errors of a line's centre (Hz), width (Hz) and power (u^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Spread {
    pub(super) freq_hz: f64,
    pub(super) width_hz: f64,
    pub(super) power: f64,
}

impl Spread {
    /// Not computed ([`super::LineOptions::standard_errors`] off).
    pub(super) const UNKNOWN: Spread = Spread {
        freq_hz: f64::NAN,
        width_hz: f64::NAN,
        power: f64::NAN,
    };
}

/// A pure tone's standard errors in a record of `duration_s` over a background of one-sided
/// PSD `background` (u^2/Hz) at its frequency: the Cramer-Rao bounds of a real sinusoid in
/// white noise, which least squares attains at the detectabilities reported (Kay,
/// *Fundamentals of Statistical Signal Processing: Estimation Theory*, 1993, example 3.14:
/// `var(A) = 2 sigma^2 / N`, `var(omega) = 12 / (eta N (N^2 - 1))` rad/sample with
/// `eta = A^2 / (2 sigma^2)`). With the per-sample variance `sigma^2 = S / (2 tau0)` and
/// `T = N tau0`: `sd(A) = sqrt(S / T)` and `sd(f) = sqrt(12 S / T^3) / (2 pi A)`; the power
/// `A^2 / 2` has `sd = A sqrt(S / T)`. The width is below the resolution and has no error
/// (`NaN`).
pub(super) fn tone_spread(tone: &Tone, background: f64, duration_s: f64) -> Spread {
    let amplitude = (2.0 * tone.power()).sqrt();
    let s = background.max(0.0);
    Spread {
        freq_hz: (12.0 * s / duration_s.powi(3)).sqrt() / (2.0 * PI * amplitude),
        width_hz: f64::NAN,
        power: amplitude * (s / duration_s).sqrt(),
    }
}

impl Search<'_> {
    /// The spread of a band's measurement ([`Search::measure`]) over periodograms drawn from
    /// what was measured: the rectangular DFT bins around the band as independent complex
    /// normals of mean square `S_k + L_k` (the background, with the line's folded images, and
    /// the line's own Lorentzian at its measured centre, width (at least a bin) and power),
    /// their Hann combinations `X_k / 2 - (X_(k-1) + X_(k+1)) / 4` (so neighbouring bins are
    /// correlated as in the record), each draw measured as the record was. The background is
    /// held fixed in the draws, so the power's error adds its relative variance
    /// ([`super::background`]) times the square of the background's power over the window.
    /// Seeded by the band's position: the same record gives the same errors.
    pub(super) fn spread(
        &self,
        m: &Measured,
        background: &Background,
        others: &[(usize, usize)],
    ) -> Spread {
        let df = self.df();
        let last = self.n / 2;
        let reach = (m.hi - m.lo + 1) + 2 * super::TONE_LOBE + 2;
        let a = m.lo.saturating_sub(reach).max(1);
        let b = (m.hi + reach).min(last.saturating_sub(1)).max(a);
        let floor = |k: usize| background.level(k) + self.image_density(m, k as f64 * df);
        let width = m.width_hz.max(df);
        let expected = |k: usize| floor(k) + lorentzian(m.freq_hz, width, m.power, k as f64 * df);
        // Rectangular bins a - 1 ..= b + 1, in units of the one-sided PSD; a Hann bin is
        // 8/3 of the squared combination (sum w^2 = 3 n / 8).
        let scale: Vec<f64> = (a - 1..=b + 1)
            .map(|k| (expected(k) / 2.0).sqrt())
            .collect();
        let draws: Vec<(f64, f64, f64)> = (0..SPREAD_DRAWS)
            .into_par_iter()
            .map(|draw| {
                let mut rng = ChaCha8Rng::seed_from_u64((m.band.0 as u64) << 16 | draw as u64);
                let mut normal = || rng.sample::<f64, _>(StandardNormal);
                let z: Vec<Complex<f64>> = scale
                    .iter()
                    .map(|s| Complex::new(s * normal(), s * normal()))
                    .collect();
                let hann: Vec<f64> = z
                    .windows(3)
                    .map(|w| (8.0 / 3.0) * (0.5 * w[1] - 0.25 * (w[0] + w[2])).norm_sqr())
                    .collect();
                let power = |k: usize| {
                    if (a..=b).contains(&k) {
                        hann[k - a]
                    } else {
                        expected(k)
                    }
                };
                let d = self.measure(power, floor, m.band, others);
                (d.freq_hz, d.width_hz, d.power)
            })
            .collect();
        let sd = |pick: fn(&(f64, f64, f64)) -> f64| {
            let values: Vec<f64> = draws.iter().map(pick).filter(|v| v.is_finite()).collect();
            let count = values.len() as f64;
            let mean = values.iter().sum::<f64>() / count;
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (count - 1.0)).sqrt()
        };
        let centre = ((m.freq_hz / df).round() as usize).clamp(1, last.max(1));
        let held: f64 = (m.lo..=m.hi).map(&floor).sum::<f64>() * df;
        let level_var = background.cursor().rel_var(centre) * held * held;
        Spread {
            freq_hz: sd(|d| d.0),
            width_hz: sd(|d| d.1),
            power: (sd(|d| d.2).powi(2) + level_var).sqrt(),
        }
    }
}

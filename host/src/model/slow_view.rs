//! The slow-line view ([`super::spectrum`]) read at a reduced rate.
//!
//! The view reads the spectrum from a few cycles per record up to at most
//! [`spectrum::VIEW_OCTAVES`] octaves above its single bins, far below the record's
//! Nyquist frequency, yet each of its realisations was synthesised, cleaned and transformed
//! at the record's rate: on a 3 h record at 100 Hz, more than half of `model`'s synthesis.
//! It therefore reads the means of blocks of D samples ([`spectrum::view_block`], 16 on that
//! record), with D chosen so the reduced rate is at least [`spectrum::VIEW_OVERSAMPLING`]
//! times the view's top.
//!
//! **The same steps on both sides.** The record and every realisation of the open noise
//! model go through the same three: notches (named lines) at the record's rate, block means,
//! then the regressors removed at the reduced rate with their own columns averaged the same
//! way (a tone's sine and cosine span the same plane averaged, a ramp stays a ramp, the
//! temperature's columns are averaged). Then the view's periodogram, background fit and
//! statistic, unchanged. Averaging is linear, so a block-mean series carries the record's
//! spectrum below the reduced rate with the boxcar's gain, on both sides alike.
//!
//! **Realisations as block means.** A noise model without named lines is synthesised as
//! block means directly ([`crate::sim::noise::AxisNoise::block_means`]): exact for white,
//! quantization, random-walk and Gauss-Markov noise and for the flicker processes up to a
//! few blocks long, whose slower processes are sampled once per block (their mean and their
//! sample differ by a share of order `(D tau0 / tau_c)^2 / 12`); white noise through the
//! sensor's filter is drawn with its block means' exact autocovariance
//! ([`LowPass::white_through_block_means`]). With lines, the realisation is synthesised at
//! the record's rate and averaged.

use super::Effect;
use super::clean::{self, Cleaner, Removal, Temperature};
use super::spectrum;
use crate::analysis::lines;
use crate::analysis::low_pass::LowPass;

/// The view for one record shape and removal: its block, its top and its reduced-rate
/// regressors.
pub struct SlowView<'a> {
    removal: Removal,
    rate_hz: f64,
    block: usize,
    /// `rate_hz / block`.
    reduced_hz: f64,
    top_hz: f64,
    low_pass: Option<&'a LowPass>,
    /// The removal's regressors at the reduced rate (its notches act before averaging).
    cleaner: Cleaner<'a>,
}

impl<'a> SlowView<'a> {
    /// The view of records of `len` samples at `rate_hz` under `removal`, averaging `block`
    /// samples ([`spectrum::view_block`]); `temperature` is the record's temperature
    /// regressors averaged the same way ([`Temperature::block_means`]).
    pub fn new(
        removal: &Removal,
        len: usize,
        rate_hz: f64,
        block: usize,
        temperature: Option<&'a Temperature>,
        low_pass: Option<&'a LowPass>,
    ) -> SlowView<'a> {
        let block = block.max(1);
        let regressors = Removal {
            notches: Vec::new(),
            ..removal.clone()
        };
        let reduced_hz = rate_hz / block as f64;
        SlowView {
            removal: removal.clone(),
            rate_hz,
            block,
            reduced_hz,
            top_hz: spectrum::view_top_hz(rate_hz, len, low_pass),
            low_pass,
            cleaner: Cleaner::new(&regressors, len / block, reduced_hz, temperature),
        }
    }

    /// Samples per block.
    pub fn block(&self) -> usize {
        self.block
    }

    /// Whether the removal notches anything (at the record's rate, before averaging).
    pub fn notches(&self) -> bool {
        !self.removal.notches.is_empty()
    }

    /// A series at the record's rate as the view reads it: notched, then averaged.
    pub fn reduce(&self, series: &[f64]) -> Vec<f64> {
        if self.notches() {
            clean::block_means(
                &clean::notch(series, self.rate_hz, &self.removal.notches),
                self.block,
            )
        } else {
            clean::block_means(series, self.block)
        }
    }

    /// The view's statistic on a reduced series (see [`spectrum::slow_line`]): the largest
    /// ratio of a single bin to the background fitted without it, with, when `effects`,
    /// the least-squares tone at its frequency.
    pub fn statistic(&self, reduced: &[f64], effects: bool) -> (f64, Option<Effect>) {
        let reduced_hz = self.reduced_hz;
        let (clean, _) = self.cleaner.apply(reduced);
        let pgram = spectrum::periodogram(&clean, reduced_hz, self.top_hz);
        let banded = spectrum::Banded::new(&pgram, self.low_pass);
        match spectrum::slow_line(&banded, &|f| self.removal.near_removed(f)) {
            Some((ratio, freq_hz)) => {
                let fitted = effects
                    .then(|| lines::tone_near(&clean, reduced_hz, freq_hz))
                    .flatten();
                let effect = fitted.map(|(freq_hz, amplitude)| Effect::Sinusoid {
                    freq_hz,
                    amplitude,
                    width_hz: 0.0,
                });
                (ratio, effect)
            }
            None => (0.0, None),
        }
    }
}

/// The view's statistic on `series` at `rate_hz` under `removal`, its view built for it.
pub fn statistic_of(
    series: &[f64],
    rate_hz: f64,
    removal: &Removal,
    temperature: Option<&Temperature>,
    low_pass: Option<&LowPass>,
    effects: bool,
) -> (f64, Option<Effect>) {
    let block = spectrum::view_block(rate_hz, series.len(), low_pass);
    let reduced_temperature = temperature.map(|t| t.block_means(block));
    let view = SlowView::new(
        removal,
        series.len(),
        rate_hz,
        block,
        reduced_temperature.as_ref(),
        low_pass,
    );
    view.statistic(&view.reduce(series), effects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::noise::{AxisNoise, GaussMarkov, NoiseTerms};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The view of 3 h at 100 Hz averages 16 samples and reads up to bin 8192 (0.76 Hz); a
    /// filter of 2 Hz lowers its top to a quarter of the cutoff and so lengthens the block.
    #[test]
    fn the_block_keeps_the_reduced_rate_eight_times_the_top() {
        let len = 3 * 3600 * 100;
        let top = spectrum::view_top_hz(100.0, len, None);
        assert!((top - 8192.0 * 100.0 / len as f64).abs() < 1e-12, "{top}");
        assert_eq!(spectrum::view_block(100.0, len, None), 16);
        let lp = LowPass::two_pole(2.0, 100.0).unwrap();
        assert!((spectrum::view_top_hz(100.0, len, Some(&lp)) - 0.5).abs() < 1e-12);
        assert_eq!(spectrum::view_block(100.0, len, Some(&lp)), 25);
        // On a short record the top is a twentieth of the rate: 2 samples a block.
        assert_eq!(spectrum::view_block(100.0, 60_000, None), 2);
    }

    /// Realisations synthesised as block means and realisations synthesised at the rate and
    /// averaged are read alike by the view: over 64 seeds of each (2^19 samples at 10 Hz, 8
    /// samples a block; white, quantization, flicker, random walk and a Gauss-Markov process
    /// shorter than a block), the mean power in each octave of the view's bands agrees
    /// within 4.5 standard errors plus 2 %, and the mean statistic within 4.5 standard
    /// errors.
    #[test]
    fn block_mean_realisations_are_read_as_averaged_ones() {
        let (rate_hz, len, seeds) = (10.0, 1usize << 19, 64u64);
        let terms = NoiseTerms {
            q: 2e-4,
            n: 1e-3,
            b: 4e-4,
            k: 2e-5,
            gauss_markov: Some(GaussMarkov {
                sigma: 1.5e-3,
                tau_c: 0.3,
            }),
            ..NoiseTerms::default()
        };
        let block = spectrum::view_block(rate_hz, len, None);
        assert_eq!(block, 8);
        let removal = Removal {
            ramp: true,
            ..Removal::default()
        };
        let view = SlowView::new(&removal, len, rate_hz, block, None, None);
        let duration = len as f64 / rate_hz;
        let reduced_hz = rate_hz / block as f64;
        // Per seed: the statistic, then the mean power per octave from bin 4.
        let read = |reduced: Vec<f64>| -> Vec<f64> {
            let (clean, _) = view.cleaner.apply(&reduced);
            let pgram = spectrum::periodogram(&clean, reduced_hz, view.top_hz);
            let mut out = vec![view.statistic(&reduced, false).0];
            let mut lo = 4;
            while 2 * lo < pgram.power.len() {
                let band = &pgram.power[lo..2 * lo];
                out.push(band.iter().sum::<f64>() / band.len() as f64);
                lo *= 2;
            }
            out
        };
        let averaged: Vec<Vec<f64>> = (0..seeds)
            .map(|s| {
                let mut rng = ChaCha8Rng::seed_from_u64(100 + s);
                let mut g = AxisNoise::new(terms, rate_hz, duration, &mut rng);
                read(view.reduce(&g.take(len, &mut rng)))
            })
            .collect();
        let means: Vec<Vec<f64>> = (0..seeds)
            .map(|s| {
                let mut rng = ChaCha8Rng::seed_from_u64(900 + s);
                let mut g = AxisNoise::block_means(terms, rate_hz, duration, block, &mut rng);
                read(g.take(len / block, &mut rng))
            })
            .collect();
        let summary = |rows: &[Vec<f64>], j: usize| {
            let r = rows.len() as f64;
            let mean = rows.iter().map(|v| v[j]).sum::<f64>() / r;
            let var = rows.iter().map(|v| (v[j] - mean).powi(2)).sum::<f64>() / (r - 1.0);
            (mean, var / r)
        };
        assert!(averaged[0].len() >= 10, "{} octaves", averaged[0].len() - 1);
        for j in 0..averaged[0].len() {
            let (a, va) = summary(&averaged, j);
            let (b, vb) = summary(&means, j);
            let systematic = if j == 0 { 0.0 } else { 0.02 * a };
            let allowed = 4.5 * (va + vb).sqrt() + systematic;
            assert!(
                (a - b).abs() <= allowed,
                "column {j}: averaged {a:.4e}, block means {b:.4e} (allowed {allowed:.2e})"
            );
        }
    }

    /// A realisation on which a leave-out background fit, from its cold start, settled on
    /// quantization alone (deviance 9e7) and the statistic read 1.0e7: the fit also
    /// started beside the first fit ([`spectrum::Banded::fit_near`]) reads it as noise.
    #[test]
    fn a_leave_out_fit_stuck_far_from_its_optimum_is_started_again_beside_the_first() {
        let terms = NoiseTerms {
            n: 2.092e-4,
            b: 3.467e-5,
            k: 2.019e-6,
            gauss_markov: Some(GaussMarkov {
                sigma: 9.406e-5,
                tau_c: 47.59,
            }),
            ..NoiseTerms::default()
        };
        let removal = Removal {
            ramp: true,
            ..Removal::default()
        };
        let view = SlowView::new(&removal, 72_000, 20.0, 2, None, None);
        let mut rng = ChaCha8Rng::seed_from_u64(1001);
        let mut g = AxisNoise::block_means(terms, 20.0, 3600.0, 2, &mut rng);
        let (statistic, _) = view.statistic(&g.take(36_000, &mut rng), false);
        assert!(statistic > 1.0 && statistic < 20.0, "{statistic}");
    }
}

//! Streaming synthesis of one axis's IEEE-952 noise terms, sample by sample, in bounded
//! memory. Parameters are the Allan coefficients in SI (DESIGN.md, Units), u the axis's unit:
//!
//! | term | parameter | generated as | Allan variance |
//! |---|---|---|---|
//! | quantization | Q (u*s) | rate = (e[k+1] - e[k]) / tau0, e ~ N(0, Q^2) (white phase noise) | 3 Q^2 / tau^2 |
//! | white rate | N (u/sqrt(Hz)) | N(0, N^2 / tau0) per sample | N^2 / tau |
//! | bias instability | B (u) | bank of first-order processes (below) | (2 ln2 / pi) B^2 |
//! | rate random walk | K (u*sqrt(Hz)) | b[k+1] = b[k] + K sqrt(tau0) w | K^2 tau / 3 |
//! | rate ramp | R (u/s) | R * t | R^2 tau^2 / 2 |
//!
//! Bias instability is flicker noise, two-sided PSD B^2 / (2 pi f) (IEEE 952 Table C.1),
//! synthesised as a sum of first-order Gauss-Markov processes with correlation times spaced
//! geometrically, [`FLICKER_POLES_PER_DECADE`] per decade, from tau0 to ten times the record
//! length. Each process of variance s^2 and correlation time T has two-sided PSD
//! 2 s^2 T / (1 + (2 pi f T)^2); with d = 1 / ln(r) processes per unit of ln T (r the spacing
//! ratio) the sum's density is s^2 d / (2 f), so s^2 = B^2 ln(r) / pi gives B^2 / (2 pi f)
//! over the band (ripple under 1 % at three poles per decade). Each process starts in its
//! stationary state, so there is no warm-up transient.

use rand::Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// Spacing of the flicker bank's correlation times.
pub const FLICKER_POLES_PER_DECADE: f64 = 3.0;

/// One axis's noise terms, each 0 when absent.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NoiseTerms {
    pub q: f64,
    pub n: f64,
    pub b: f64,
    pub k: f64,
    pub r: f64,
}

/// A running generator of rate samples with the given terms.
#[derive(Debug, Clone)]
pub struct AxisNoise {
    terms: NoiseTerms,
    tau0: f64,
    step: u64,
    last_phase_error: f64,
    walk: f64,
    /// (phi, innovation scale, state) of each flicker process.
    flicker: Vec<(f64, f64, f64)>,
}

impl AxisNoise {
    /// A generator at `rate_hz` whose flicker band reaches beyond `duration_s`.
    pub fn new(terms: NoiseTerms, rate_hz: f64, duration_s: f64, rng: &mut impl Rng) -> Self {
        let tau0 = 1.0 / rate_hz;
        let flicker = if terms.b > 0.0 {
            flicker_bank(terms.b, tau0, 10.0 * duration_s.max(tau0), rng)
        } else {
            Vec::new()
        };
        AxisNoise {
            terms,
            tau0,
            step: 0,
            last_phase_error: terms.q * rng.sample::<f64, _>(StandardNormal),
            walk: 0.0,
            flicker,
        }
    }

    /// The next rate sample.
    pub fn next(&mut self, rng: &mut impl Rng) -> f64 {
        let t = self.terms;
        let mut y = 0.0;
        if t.q > 0.0 {
            let e = t.q * rng.sample::<f64, _>(StandardNormal);
            y += (e - self.last_phase_error) / self.tau0;
            self.last_phase_error = e;
        }
        if t.n > 0.0 {
            y += t.n / self.tau0.sqrt() * rng.sample::<f64, _>(StandardNormal);
        }
        for (phi, scale, state) in &mut self.flicker {
            *state = *phi * *state + *scale * rng.sample::<f64, _>(StandardNormal);
            y += *state;
        }
        if t.k > 0.0 {
            y += self.walk;
            self.walk += t.k * self.tau0.sqrt() * rng.sample::<f64, _>(StandardNormal);
        }
        y += t.r * self.step as f64 * self.tau0;
        self.step += 1;
        y
    }

    /// `n` samples at once.
    pub fn take(&mut self, n: usize, rng: &mut impl Rng) -> Vec<f64> {
        (0..n).map(|_| self.next(rng)).collect()
    }
}

/// First-order processes with correlation times from `tau0` to `tau_max`, geometrically
/// spaced, each of variance B^2 ln(r) / pi, started in their stationary state.
fn flicker_bank(b: f64, tau0: f64, tau_max: f64, rng: &mut impl Rng) -> Vec<(f64, f64, f64)> {
    let ratio = 10f64.powf(1.0 / FLICKER_POLES_PER_DECADE);
    let sigma = b * (ratio.ln() / PI).sqrt();
    let count = ((tau_max / tau0).log10() * FLICKER_POLES_PER_DECADE).ceil() as i32 + 1;
    (0..count)
        .map(|i| {
            let tau_c = tau0 * ratio.powi(i);
            let phi = (-tau0 / tau_c).exp();
            let scale = sigma * (1.0 - phi * phi).sqrt();
            (phi, scale, sigma * rng.sample::<f64, _>(StandardNormal))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{Estimator, allan, phase_from_rate};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Allan deviation at factors `ms` of `n` samples of `terms` at 10 Hz.
    fn adev(terms: NoiseTerms, n: usize, ms: &[usize], seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut g = AxisNoise::new(terms, 10.0, n as f64 / 10.0, &mut rng);
        let x = phase_from_rate(&g.take(n, &mut rng), 0.1);
        allan::deviation(Estimator::Oadev, &x, 0.1, ms).dev
    }

    #[test]
    fn each_term_follows_its_allan_curve() {
        // Tolerances: >= 2000 clusters per tau give a few percent for white-like noise; the
        // random walk and flicker have fewer degrees of freedom (SP 1065 Table 6).
        let n = 200_000;
        let cases = [
            NoiseTerms {
                n: 0.01,
                ..Default::default()
            },
            NoiseTerms {
                q: 0.01,
                ..Default::default()
            },
            NoiseTerms {
                b: 0.01,
                ..Default::default()
            },
            NoiseTerms {
                k: 0.001,
                ..Default::default()
            },
        ];
        // tau from 1 s to 10 s: inside the flicker bank's band (which starts at tau0).
        let ms = [10, 20, 40, 100];
        for (i, terms) in cases.iter().enumerate() {
            let dev = adev(*terms, n, &ms, i as u64);
            for (&m, d) in ms.iter().zip(&dev) {
                let tau = m as f64 * 0.1;
                let avar = 3.0 * terms.q.powi(2) / tau.powi(2)
                    + terms.n.powi(2) / tau
                    + 2.0 * 2f64.ln() / PI * terms.b.powi(2)
                    + terms.k.powi(2) * tau / 3.0;
                let tolerance = if terms.k > 0.0 || terms.b > 0.0 {
                    0.15
                } else {
                    0.05
                };
                let rel = d / avar.sqrt() - 1.0;
                assert!(
                    rel.abs() < tolerance,
                    "case {i} tau {tau}: {d} vs {} ({rel:+.3})",
                    avar.sqrt()
                );
            }
        }
    }

    #[test]
    fn ramp_is_deterministic() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let terms = NoiseTerms {
            r: 2.0,
            ..Default::default()
        };
        let mut g = AxisNoise::new(terms, 4.0, 1.0, &mut rng);
        assert_eq!(g.take(3, &mut rng), [0.0, 0.5, 1.0]);
    }
}

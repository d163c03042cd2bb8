//! Removing the deterministic effects already named — spectral lines, a rate ramp, a
//! temperature coupling — from a series. The same [`Removal`] is applied to the measured
//! record and to every simulated realisation, so a statistic computed after it has the same
//! meaning on both (what the removal itself takes out of pure noise is part of the simulated
//! spread).
//!
//! **Lines** are notched: the full-record real FFT's bins inside each line's band are set to
//! zero and the series transformed back. A notch of total width W Hz removes the fraction
//! `W / (rate / 2)` of white noise too; the simulated realisations lose the same.
//!
//! **Regressors** (a constant always; time for a ramp; the centred temperature and its
//! derivative for a temperature coupling; a sine and a cosine for each slow pure tone) are
//! removed jointly by ordinary least squares, on the notched series, through the normal
//! equations of the centred, unit-norm columns.
//!
//! **Slow tones are regressors, not notches.** A notch takes the bins around a line from the
//! series but not from the regressor columns: a temperature cycle a few bins from a slow
//! line would vanish from the series and stay in the temperature column, and the coupling
//! would be estimated from the warm-up alone. Regressed jointly, the tone and the coupling
//! share the record's information as least squares allots it; a tone within a bin or so of
//! the temperature cycle stays confounded with the coupling to the temperature's rate of
//! change (their columns are nearly collinear over the record), which no method separates.

use crate::analysis::numerics::{dot, householder_solve};
use crate::analysis::shared_plans;
use rayon::prelude::*;

/// The temperature channel as regressors: centred, and its time derivative.
#[derive(Debug, Clone)]
pub struct Temperature {
    /// Temperature minus its mean, degC.
    pub centred: Vec<f64>,
    /// d(temperature)/dt, degC/s, from a centred difference of the temperature smoothed over
    /// [`DERIVATIVE_WINDOW_S`] (the channel's own quantisation would otherwise dominate).
    pub derivative: Vec<f64>,
}

/// Smoothing window of the temperature derivative, s: couplings through the rate of change
/// of temperature act on thermal time scales (minutes), far longer than this.
pub const DERIVATIVE_WINDOW_S: f64 = 30.0;

impl Temperature {
    pub fn new(values: &[f64], rate_hz: f64) -> Temperature {
        let n = values.len();
        let mean = values.iter().sum::<f64>() / n.max(1) as f64;
        let centred: Vec<f64> = values.iter().map(|v| v - mean).collect();
        let half = ((DERIVATIVE_WINDOW_S * rate_hz / 2.0).round() as usize).max(1);
        let smooth = moving_average(&centred, half);
        let derivative = (0..n)
            .map(|i| {
                let lo = i.saturating_sub(half);
                let hi = (i + half).min(n.saturating_sub(1));
                if hi > lo {
                    (smooth[hi] - smooth[lo]) * rate_hz / (hi - lo) as f64
                } else {
                    0.0
                }
            })
            .collect();
        Temperature {
            centred,
            derivative,
        }
    }

    /// The regressors as means of blocks of `block` samples: the columns of a series read
    /// at a reduced rate ([`super::slow_view`]).
    pub fn block_means(&self, block: usize) -> Temperature {
        Temperature {
            centred: block_means(&self.centred, block),
            derivative: block_means(&self.derivative, block),
        }
    }
}

/// The means of consecutive blocks of `block` values of `x` (a last, partial block left out).
pub fn block_means(x: &[f64], block: usize) -> Vec<f64> {
    let block = block.max(1);
    x.chunks_exact(block)
        .map(|c| c.iter().sum::<f64>() / block as f64)
        .collect()
}

/// Centred moving average over `2 half + 1` samples (shorter at the ends).
fn moving_average(x: &[f64], half: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(x.len() + 1);
    prefix.push(0.0);
    for v in x {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
    }
    (0..x.len())
        .map(|i| {
            let lo = i.saturating_sub(half);
            let hi = (i + half + 1).min(x.len());
            (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// A frequency band to notch, Hz.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Notch {
    pub lo_hz: f64,
    pub hi_hz: f64,
}

/// A pure tone removed by regression, and the band around it that its removal leaves
/// disturbed (the periodogram's main lobe), Hz.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tone {
    pub freq_hz: f64,
    pub guard_hz: f64,
}

/// What to remove from a series.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Removal {
    pub ramp: bool,
    pub temperature: bool,
    pub notches: Vec<Notch>,
    pub tones: Vec<Tone>,
}

/// Least-squares coefficients of the regressors, in the series' unit u: `slope` u/s,
/// `temp` u/degC, `temp_rate` u/(degC/s).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Coefficients {
    pub slope: Option<f64>,
    pub temp: Option<f64>,
    pub temp_rate: Option<f64>,
    /// Each tone's amplitude, u (peak), in the order of [`Removal::tones`].
    pub tone_amplitudes: Vec<f64>,
}

impl Removal {
    /// Whether `freq_hz` lies in a notch or within its width of it, or within a removed
    /// tone's guard: what a removal leaves of a named line is that line, not a new one.
    pub fn near_removed(&self, freq_hz: f64) -> bool {
        let near_notch = self.notches.iter().any(|n| {
            let width = n.hi_hz - n.lo_hz;
            freq_hz > n.lo_hz - width && freq_hz < n.hi_hz + width
        });
        near_notch
            || self
                .tones
                .iter()
                .any(|t| (freq_hz - t.freq_hz).abs() < t.guard_hz)
    }

    /// Whether a line at `freq_hz` is removed as a tone (by regression).
    pub fn is_tone(&self, freq_hz: f64) -> bool {
        self.tones.iter().any(|t| t.freq_hz == freq_hz)
    }

    /// `x` with the notches and the regressors removed, and the regressors' coefficients.
    pub fn apply(
        &self,
        x: &[f64],
        rate_hz: f64,
        temperature: Option<&Temperature>,
    ) -> (Vec<f64>, Coefficients) {
        Cleaner::new(self, x.len(), rate_hz, temperature).apply(x)
    }

    /// The regressor columns, each centred, in the order of the regression: the ramp, the
    /// temperature and its derivative, then each tone's sine and cosine. Empty when the
    /// removal regresses on nothing but the constant.
    pub fn design(
        &self,
        n: usize,
        rate_hz: f64,
        temperature: Option<&Temperature>,
    ) -> Vec<Vec<f64>> {
        /// One column, made on its own thread: a tone's sine and cosine cost far more per
        /// sample than the regression.
        enum Regressor<'t> {
            Time,
            Given(&'t [f64]),
            Sine(f64),
            Cosine(f64),
        }
        let mut regressors = Vec::new();
        if self.ramp {
            regressors.push(Regressor::Time);
        }
        if let Some(t) = temperature.filter(|_| self.temperature) {
            regressors.push(Regressor::Given(&t.centred));
            regressors.push(Regressor::Given(&t.derivative));
        }
        for tone in &self.tones {
            let omega = 2.0 * std::f64::consts::PI * tone.freq_hz / rate_hz;
            regressors.push(Regressor::Sine(omega));
            regressors.push(Regressor::Cosine(omega));
        }
        regressors
            .par_iter()
            .map(|r| {
                let mut c: Vec<f64> = match *r {
                    Regressor::Time => (0..n).map(|i| i as f64 / rate_hz).collect(),
                    Regressor::Given(v) => v.to_vec(),
                    Regressor::Sine(omega) => (0..n).map(|i| (omega * i as f64).sin()).collect(),
                    Regressor::Cosine(omega) => (0..n).map(|i| (omega * i as f64).cos()).collect(),
                };
                let mean = c.iter().sum::<f64>() / n.max(1) as f64;
                c.iter_mut().for_each(|v| *v -= mean);
                c
            })
            .collect()
    }
}

/// A [`Removal`] made ready for series of one length and rate: the regressor columns,
/// centred and scaled to unit norm (so the normal equations stay well conditioned whatever
/// the units, seconds against degrees), and their Gram matrix. None of these depends on the
/// series, and building them (a sine and a cosine per tone and sample, `p^2` products per
/// sample) cost more than the regression itself; a round applies one removal to every
/// realisation, so it builds them once.
pub struct Cleaner<'a> {
    removal: Removal,
    len: usize,
    rate_hz: f64,
    temperature: Option<&'a Temperature>,
    columns: Vec<Vec<f64>>,
    norms: Vec<f64>,
    gram: Vec<Vec<f64>>,
}

impl<'a> Cleaner<'a> {
    pub fn new(
        removal: &Removal,
        len: usize,
        rate_hz: f64,
        temperature: Option<&'a Temperature>,
    ) -> Cleaner<'a> {
        let mut columns = removal.design(len, rate_hz, temperature);
        let norms: Vec<f64> = columns
            .par_iter_mut()
            .map(|c| {
                let norm = dot(c, c).sqrt().max(f64::MIN_POSITIVE);
                c.iter_mut().for_each(|v| *v /= norm);
                norm
            })
            .collect();
        let gram = columns
            .par_iter()
            .map(|a| columns.iter().map(|b| dot(a, b)).collect())
            .collect();
        Cleaner {
            removal: removal.clone(),
            len,
            rate_hz,
            temperature,
            columns,
            norms,
            gram,
        }
    }

    /// What this removes.
    pub fn removal(&self) -> &Removal {
        &self.removal
    }

    /// The regressor columns, centred and at unit norm.
    pub fn columns(&self) -> &[Vec<f64>] {
        &self.columns
    }

    /// The columns' Gram matrix.
    pub fn gram(&self) -> &[Vec<f64>] {
        &self.gram
    }

    /// `x` with the notches and the regressors removed, and the regressors' coefficients.
    /// A series of another length than the cleaner's is cleaned by a cleaner of its own.
    pub fn apply(&self, x: &[f64]) -> (Vec<f64>, Coefficients) {
        if x.len() != self.len {
            return Cleaner::new(&self.removal, x.len(), self.rate_hz, self.temperature).apply(x);
        }
        let mut y = if self.removal.notches.is_empty() {
            x.to_vec()
        } else {
            notch(x, self.rate_hz, &self.removal.notches)
        };
        let coefficients = self.regress_out(&mut y);
        (y, coefficients)
    }

    /// Remove the constant and the chosen regressors from `y` in place.
    fn regress_out(&self, y: &mut [f64]) -> Coefficients {
        let mean_y = y.iter().sum::<f64>() / y.len().max(1) as f64;
        y.iter_mut().for_each(|v| *v -= mean_y);
        if self.columns.is_empty() {
            return Coefficients::default();
        }
        let mut rhs: Vec<f64> = self.columns.iter().map(|c| dot(c, y)).collect();
        let mut gram = self.gram.clone();
        let beta = householder_solve(&mut gram, &mut rhs);
        for (c, b) in self.columns.iter().zip(&beta) {
            y.iter_mut().zip(c).for_each(|(v, a)| *v -= b * a);
        }
        let coeff = |j: usize| beta[j] / self.norms[j];
        let mut out = Coefficients::default();
        let mut j = 0;
        if self.removal.ramp {
            out.slope = Some(coeff(j));
            j += 1;
        }
        if self.temperature.is_some() && self.removal.temperature {
            out.temp = Some(coeff(j));
            out.temp_rate = Some(coeff(j + 1));
            j += 2;
        }
        out.tone_amplitudes = (0..self.removal.tones.len())
            .map(|t| coeff(j + 2 * t).hypot(coeff(j + 2 * t + 1)))
            .collect();
        out
    }
}

/// `x` with the real-FFT bins inside any notch set to zero (the record's own resolution,
/// `rate / len` Hz per bin).
pub fn notch(x: &[f64], rate_hz: f64, notches: &[Notch]) -> Vec<f64> {
    let n = x.len();
    if n < 4 {
        return x.to_vec();
    }
    let forward = shared_plans::forward(n);
    let inverse = shared_plans::inverse(n);
    let mut input = x.to_vec();
    let mut spectrum = forward.make_output_vec();
    if forward.process(&mut input, &mut spectrum).is_err() {
        return x.to_vec();
    }
    let df = rate_hz / n as f64;
    for (k, c) in spectrum.iter_mut().enumerate() {
        let f = k as f64 * df;
        if notches.iter().any(|b| f >= b.lo_hz && f <= b.hi_hz) {
            *c = realfft::num_complex::Complex::new(0.0, 0.0);
        }
    }
    // The inverse needs a real DC (and Nyquist, for even n) bin; zeroing kept them real.
    let mut out = inverse.make_output_vec();
    if inverse.process(&mut spectrum, &mut out).is_err() {
        return x.to_vec();
    }
    out.iter_mut().for_each(|v| *v /= n as f64);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regression_recovers_slope_and_temperature() {
        let rate = 10.0;
        let n = 20_000;
        let temps: Vec<f64> = (0..n)
            .map(|i| 25.0 + 3.0 * (i as f64 / 5000.0).sin())
            .collect();
        let t = Temperature::new(&temps, rate);
        let x: Vec<f64> = (0..n)
            .map(|i| 1.0 + 2e-4 * i as f64 / rate + 5e-3 * t.centred[i])
            .collect();
        let removal = Removal {
            ramp: true,
            temperature: true,
            notches: vec![],
            tones: vec![],
        };
        let (y, c) = removal.apply(&x, rate, Some(&t));
        assert!((c.slope.unwrap() - 2e-4).abs() < 1e-10, "{c:?}");
        assert!((c.temp.unwrap() - 5e-3).abs() < 1e-9, "{c:?}");
        assert!(c.temp_rate.unwrap().abs() < 1e-6, "{c:?}");
        assert!(y.iter().all(|v| v.abs() < 1e-9));
    }

    /// One cleaner serves many series of its length, and cleans one of another length as a
    /// cleaner of its own would: a ramp and a tone regressed out of two series of 4000
    /// samples through one cleaner, and out of 2500 through the same, give each series'
    /// coefficients (to 1e-12 of the slope and 1e-9 of the amplitude) and leave nothing.
    #[test]
    fn a_cleaner_serves_every_series_of_its_length_and_others_too() {
        let rate = 10.0;
        let removal = Removal {
            ramp: true,
            tones: vec![Tone {
                freq_hz: 0.05,
                guard_hz: 0.01,
            }],
            ..Removal::default()
        };
        let series = |n: usize, slope: f64, amplitude: f64| -> Vec<f64> {
            (0..n)
                .map(|i| {
                    let t = i as f64 / rate;
                    0.3 + slope * t
                        + amplitude * (2.0 * std::f64::consts::PI * 0.05 * t + 0.4).sin()
                })
                .collect()
        };
        let cleaner = Cleaner::new(&removal, 4000, rate, None);
        for (n, slope, amplitude) in [(4000, 1e-3, 0.2), (4000, -2e-3, 0.05), (2500, 5e-4, 0.1)] {
            let (y, c) = cleaner.apply(&series(n, slope, amplitude));
            assert_eq!(y.len(), n);
            assert!((c.slope.unwrap() - slope).abs() < 1e-12, "{n}: {c:?}");
            assert!(
                (c.tone_amplitudes[0] - amplitude).abs() < 1e-9,
                "{n}: {c:?}"
            );
            assert!(y.iter().all(|v| v.abs() < 1e-9), "{n}");
        }
    }

    /// A slow tone two bins from the temperature's cycle: the joint regression gives both the
    /// coupling and the tone's amplitude.
    #[test]
    fn a_tone_beside_a_temperature_cycle_is_regressed_jointly() {
        let rate = 10.0;
        let n = 100_000;
        let duration = n as f64 / rate;
        let cycle_hz = 5.0 / duration;
        let tone_hz = 7.0 / duration;
        let phase = |f: f64, i: usize| 2.0 * std::f64::consts::PI * f * i as f64 / rate;
        let temps: Vec<f64> = (0..n)
            .map(|i| 25.0 + 2.0 * (1.0 - (-(i as f64) / 20_000.0).exp()) + phase(cycle_hz, i).sin())
            .collect();
        let t = Temperature::new(&temps, rate);
        let x: Vec<f64> = (0..n)
            .map(|i| 3e-3 * t.centred[i] + 2e-3 * (phase(tone_hz, i) + 0.7).sin())
            .collect();
        let removal = Removal {
            temperature: true,
            tones: vec![Tone {
                freq_hz: tone_hz,
                guard_hz: 2.0 / duration,
            }],
            ..Removal::default()
        };
        let (y, c) = removal.apply(&x, rate, Some(&t));
        assert!((c.temp.unwrap() - 3e-3).abs() < 1e-9, "{c:?}");
        assert!(c.temp_rate.unwrap().abs() < 1e-7, "{c:?}");
        assert!((c.tone_amplitudes[0] - 2e-3).abs() < 1e-9, "{c:?}");
        assert!(y.iter().all(|v| v.abs() < 1e-9));
        assert!(removal.near_removed(tone_hz + 1.5 / duration));
        assert!(!removal.near_removed(tone_hz - 2.5 / duration));
    }

    #[test]
    fn notch_removes_a_tone_and_keeps_the_rest() {
        let rate = 100.0;
        let n = 10_000;
        let tone = |i: usize| (2.0 * std::f64::consts::PI * 12.5 * i as f64 / rate).sin();
        let slow = |i: usize| (2.0 * std::f64::consts::PI * 0.3 * i as f64 / rate).cos();
        let x: Vec<f64> = (0..n).map(|i| tone(i) + slow(i)).collect();
        let y = notch(
            &x,
            rate,
            &[Notch {
                lo_hz: 12.0,
                hi_hz: 13.0,
            }],
        );
        for (i, v) in y.iter().enumerate() {
            assert!((v - slow(i)).abs() < 1e-9, "{i}: {v}");
        }
    }
}

//! Narrow-band test signals: spectral lines of a given frequency, power and width, to add to
//! simulated noise. Two shapes, both with total power `P = amplitude^2 / 2` and a spectrum
//! close to a Lorentzian of full width at half maximum `width_hz` (one-sided PSD
//! `(2 P / pi) (w / 2) / ((f - f0)^2 + (w / 2)^2)` near f0):
//!
//! - [`Shape::DiffusingPhase`]: `A cos(phi_k)`, `phi_{k+1} = phi_k + 2 pi f0 tau0 + sqrt(2 pi w
//!   tau0) g_k` (g standard normal), a constant-amplitude oscillator whose phase is a random
//!   walk. Its autocovariance is exactly `P e^(-pi w |s|) cos(2 pi f0 s)` (the phase change
//!   over s is normal with variance `2 pi w |s|`, and `E cos(phi) = e^(-var / 2)`), which is
//!   what [`crate::analysis::lines::line_avar`] assumes. Width 0 gives a pure tone of random
//!   phase.
//! - [`Shape::Resonance`]: a second-order resonance driven by white noise, the AR(2)
//!   recursion `y_k = 2 r cos(w0) y_{k-1} - r^2 y_{k-2} + s e_k` with poles `r e^(+-i w0)`,
//!   `w0 = 2 pi f0 tau0`, `r = e^(-pi w tau0)` (a pole at distance `pi w tau0` inside the unit
//!   circle gives a half-power half-width of w / 2). Its variance is
//!   `s^2 (1 + r^2) / ((1 - r^2) ((1 + r^2)^2 - 4 r^2 cos^2 w0))` (Box, Jenkins & Reinsel,
//!   *Time Series Analysis*, sec. 3.2.4), from which s is set; the amplitude fluctuates
//!   (Rayleigh), as a structural resonance excited by vibration does. It starts in its
//!   stationary state.

use rand::Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// The spectral shape of a [`LineNoise`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    DiffusingPhase,
    Resonance,
}

/// A line: `amplitude` (u, `sqrt(2 power)`), centre `freq_hz`, full width at half maximum
/// `width_hz`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NarrowBand {
    pub amplitude: f64,
    pub freq_hz: f64,
    pub width_hz: f64,
    pub shape: Shape,
}

/// A running generator of one line's samples at a fixed rate.
#[derive(Debug, Clone)]
pub struct LineNoise {
    line: NarrowBand,
    state: State,
}

#[derive(Debug, Clone)]
enum State {
    Phase {
        phase: f64,
        step: f64,
        diffusion: f64,
    },
    Resonance {
        c1: f64,
        c2: f64,
        scale: f64,
        prev: f64,
        prev2: f64,
    },
}

fn normal(rng: &mut impl Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

impl LineNoise {
    /// The generator at `rate_hz`, in its stationary state (random phase, or the resonance's
    /// stationary distribution).
    pub fn new(line: NarrowBand, rate_hz: f64, rng: &mut impl Rng) -> Self {
        let tau0 = 1.0 / rate_hz;
        let w0 = 2.0 * PI * line.freq_hz * tau0;
        let width = line.width_hz.max(0.0);
        let state = match line.shape {
            Shape::DiffusingPhase => State::Phase {
                phase: 2.0 * PI * rng.random::<f64>(),
                step: w0,
                diffusion: (2.0 * PI * width * tau0).sqrt(),
            },
            Shape::Resonance => {
                // A zero width would be an undamped oscillator of infinite variance per unit
                // drive: keep the pole just inside the circle.
                let r = (-PI * width * tau0).exp().min(1.0 - 1e-9);
                let (c1, c2) = (2.0 * r * w0.cos(), -r * r);
                let r2 = r * r;
                let gain =
                    (1.0 + r2) / ((1.0 - r2) * ((1.0 + r2).powi(2) - 4.0 * r2 * w0.cos().powi(2)));
                let variance = line.amplitude * line.amplitude / 2.0;
                let sd = variance.sqrt();
                // Lag-one correlation of the AR(2): c1 / (1 - c2).
                let rho = c1 / (1.0 - c2);
                let prev2 = sd * normal(rng);
                let prev = rho * prev2 + sd * (1.0 - rho * rho).max(0.0).sqrt() * normal(rng);
                State::Resonance {
                    c1,
                    c2,
                    scale: (variance / gain).sqrt(),
                    prev,
                    prev2,
                }
            }
        };
        LineNoise { line, state }
    }

    /// The next sample.
    pub fn next(&mut self, rng: &mut impl Rng) -> f64 {
        match &mut self.state {
            State::Phase {
                phase,
                step,
                diffusion,
            } => {
                let y = self.line.amplitude * phase.cos();
                *phase = (*phase + *step + *diffusion * normal(rng)).rem_euclid(2.0 * PI);
                y
            }
            State::Resonance {
                c1,
                c2,
                scale,
                prev,
                prev2,
            } => {
                let y = *c1 * *prev + *c2 * *prev2 + *scale * normal(rng);
                *prev2 = *prev;
                *prev = y;
                y
            }
        }
    }

    /// `n` samples at once.
    pub fn take(&mut self, n: usize, rng: &mut impl Rng) -> Vec<f64> {
        (0..n).map(|_| self.next(rng)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn autocovariance(y: &[f64], lag: usize) -> f64 {
        let n = y.len() - lag;
        (0..n).map(|i| y[i] * y[i + lag]).sum::<f64>() / n as f64
    }

    /// Both shapes have the stated power and the Lorentzian's autocovariance
    /// `P e^(-pi w s) cos(2 pi f s)` at a few lags. 2^18 samples, a line of width w decorrelates
    /// after ~1/(pi w) s: the estimate of P averages ~n w pi / rate independent stretches
    /// (~800 here), so its relative sd is ~0.05; 0.2 P is four of those.
    #[test]
    fn power_and_autocovariance_match_the_lorentzian() {
        let rate = 100.0;
        let n = 1 << 18;
        for (i, shape) in [Shape::DiffusingPhase, Shape::Resonance]
            .into_iter()
            .enumerate()
        {
            for (j, (f, w)) in [(7.3, 0.3), (31.0, 1.0), (0.9, 0.1)]
                .into_iter()
                .enumerate()
            {
                let line = NarrowBand {
                    amplitude: 2.0,
                    freq_hz: f,
                    width_hz: w,
                    shape,
                };
                let mut rng = ChaCha8Rng::seed_from_u64((10 * i + j) as u64);
                let y = LineNoise::new(line, rate, &mut rng).take(n, &mut rng);
                let p = 2.0;
                for lag in [0usize, 1, 3, 10] {
                    let s = lag as f64 / rate;
                    let expected = p * (-PI * w * s).exp() * (2.0 * PI * f * s).cos();
                    let got = autocovariance(&y, lag);
                    assert!(
                        (got - expected).abs() < 0.2 * p,
                        "{shape:?} f {f} w {w} lag {lag}: {got} vs {expected}"
                    );
                }
            }
        }
    }

    /// Width 0 with a diffusing phase is a pure tone: every sample on the same sinusoid.
    #[test]
    fn zero_width_is_a_pure_tone() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let line = NarrowBand {
            amplitude: 1.5,
            freq_hz: 5.0,
            width_hz: 0.0,
            shape: Shape::DiffusingPhase,
        };
        let y = LineNoise::new(line, 100.0, &mut rng).take(400, &mut rng);
        // A sinusoid with 20 samples per cycle repeats every 20 samples.
        for k in 0..380 {
            assert!((y[k] - y[k + 20]).abs() < 1e-9);
        }
        let peak = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!((peak - 1.5).abs() < 0.02, "{peak}");
    }
}

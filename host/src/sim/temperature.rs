//! The die temperature the simulated sensor sees, and how it couples into bias and scale
//! factor. The profile is deterministic (the TEMP_OUT noise is a [`super::noise::NoiseTerms`]
//! of its own):
//!
//! ```text
//!   T(t) = T0 + rise (1 - exp(-t / tau)) + ramp t + amplitude sin(2 pi t / period)
//! ```
//!
//! (a warm-up exponential after power-on, a linear ramp of the environment, a thermal cycle).
//! Coupling, linear about a reference temperature T_ref (datasheet-style "sensitivity change
//! vs. temperature" and "zero-rate output vs. temperature"):
//! `bias(T) = bias_coeff (T - T_ref) + rate_coeff dT/dt` (u/degC and u/(degC/s)),
//! `scale(T) = 1 + scale_coeff (T - T_ref)` (1/degC). The term in dT/dt is the bias a thermal
//! gradient across the die adds while the temperature changes: it follows the rate of change,
//! not the level (the model workflow names it beside the level's coefficient).

use std::f64::consts::PI;

/// Warm-up: the temperature rises by `rise` degC with time constant `tau` s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Warmup {
    pub rise: f64,
    pub tau: f64,
}

/// A thermal cycle of `amplitude` degC (peak) and `period` s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycle {
    pub amplitude: f64,
    pub period: f64,
}

/// A temperature profile (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemperatureProfile {
    /// Temperature at t = 0, degC.
    pub initial: f64,
    pub warmup: Option<Warmup>,
    /// degC/s.
    pub ramp: f64,
    pub cycle: Option<Cycle>,
}

impl Default for TemperatureProfile {
    /// A constant 25 degC.
    fn default() -> Self {
        TemperatureProfile {
            initial: 25.0,
            warmup: None,
            ramp: 0.0,
            cycle: None,
        }
    }
}

impl TemperatureProfile {
    /// The temperature at `t` seconds, degC.
    pub fn at(&self, t: f64) -> f64 {
        let mut temp = self.initial + self.ramp * t;
        if let Some(w) = self.warmup.filter(|w| w.tau > 0.0) {
            temp += w.rise * -(-t / w.tau).exp_m1();
        }
        if let Some(c) = self.cycle.filter(|c| c.period > 0.0) {
            temp += c.amplitude * (2.0 * PI * t / c.period).sin();
        }
        temp
    }

    /// The temperature's rate of change at `t` seconds, degC/s: the derivative of
    /// [`TemperatureProfile::at`] term by term.
    pub fn rate_at(&self, t: f64) -> f64 {
        let mut rate = self.ramp;
        if let Some(w) = self.warmup.filter(|w| w.tau > 0.0) {
            rate += w.rise / w.tau * (-t / w.tau).exp();
        }
        if let Some(c) = self.cycle.filter(|c| c.period > 0.0) {
            let omega = 2.0 * PI / c.period;
            rate += c.amplitude * omega * (omega * t).cos();
        }
        rate
    }
}

/// Linear temperature coupling of one sensor group (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TempCoupling {
    /// Bias change, u/degC.
    pub bias_coeff: f64,
    /// Relative scale-factor change, 1/degC.
    pub scale_coeff: f64,
    /// Bias per rate of temperature change, u/(degC/s).
    pub rate_coeff: f64,
}

impl TempCoupling {
    /// (bias, scale multiplier) at `delta` = T - T_ref while the temperature changes at
    /// `rate` degC/s.
    pub fn at(&self, delta: f64, rate: f64) -> (f64, f64) {
        (
            self.bias_coeff * delta + self.rate_coeff * rate,
            1.0 + self.scale_coeff * delta,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_pieces() {
        let p = TemperatureProfile {
            initial: 20.0,
            warmup: Some(Warmup {
                rise: 10.0,
                tau: 100.0,
            }),
            ramp: 0.01,
            cycle: Some(Cycle {
                amplitude: 2.0,
                period: 400.0,
            }),
        };
        assert_eq!(p.at(0.0), 20.0);
        // t = 100: 20 + 10 (1 - 1/e) + 1 + 2 sin(pi/2)
        let want = 20.0 + 10.0 * (1.0 - (-1f64).exp()) + 1.0 + 2.0;
        assert!((p.at(100.0) - want).abs() < 1e-12);
        assert_eq!(TemperatureProfile::default().at(1e6), 25.0);
        let c = TempCoupling {
            bias_coeff: 1e-3,
            scale_coeff: 2e-4,
            rate_coeff: 0.0,
        };
        assert_eq!(c.at(10.0, 5.0), (1e-2, 1.002));
        let with_rate = TempCoupling {
            rate_coeff: 0.5,
            ..c
        };
        assert_eq!(with_rate.at(10.0, 0.02), (1e-2 + 1e-2, 1.002));
    }

    /// The rate of change is the profile's derivative: against a central difference.
    #[test]
    fn rate_is_the_profiles_derivative() {
        let p = TemperatureProfile {
            initial: 20.0,
            warmup: Some(Warmup {
                rise: 6.0,
                tau: 300.0,
            }),
            ramp: -1e-3,
            cycle: Some(Cycle {
                amplitude: 1.5,
                period: 900.0,
            }),
        };
        for t in [0.0, 10.0, 299.0, 1234.5, 7200.0] {
            let h = 1e-3;
            let numeric = (p.at(t + h) - p.at(t - h)) / (2.0 * h);
            assert!(
                (p.rate_at(t) - numeric).abs() < 1e-8,
                "t = {t}: {} against {numeric}",
                p.rate_at(t)
            );
        }
        assert_eq!(TemperatureProfile::default().rate_at(5.0), 0.0);
    }
}

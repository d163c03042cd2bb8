//! The gyro's static bias: the mean rate of a record at rest, and how well that mean is
//! known.
//!
//! **Convention.** The uncertainty (1 sigma) of the mean of a record of length T is the Allan
//! deviation at tau = T, sigma_A(T): the Allan variance at tau is half the mean squared
//! difference of successive tau-averages, i.e. exactly the variance of one tau-average about
//! the next. For white rate noise it equals the textbook N / sqrt(T) (the standard error of
//! the mean); where bias instability or rate random walk dominate it stops falling or grows,
//! which is the settings study's point (docs/references.md) that the bias estimate wanders
//! the longer you wait. A
//! record cannot measure its own sigma_A(T) (the longest overlapping tau is T/2), so it is
//! the IEEE-952 five-term model fitted to the record's octave Allan curve
//! ([`crate::analysis::fit::fit_deviation`]) evaluated at T. The best averaging time (the
//! tau of the curve's minimum) says how long a bias measurement is worth making.

use crate::analysis::fit::{FitOptions, fit_deviation};
use crate::analysis::taus::{TauGrid, factors};
use crate::analysis::{Estimator, allan, phase_from_rate};
use serde::Serialize;

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StaticBias {
    /// Mean rate, rad/s.
    pub bias: f64,
    /// sigma_A(T) of the fitted model (module documentation), rad/s.
    pub uncertainty: f64,
    /// T, s.
    pub record_s: f64,
    /// The tau of the measured curve's minimum, s, and the deviation there, rad/s.
    pub best_tau_s: f64,
    pub best_adev: f64,
}

/// The static bias of `rate` (rad/s) sampled at `rate_hz`; None for fewer than 16 samples
/// (no Allan curve to speak of).
pub fn static_bias(rate: &[f64], rate_hz: f64) -> Option<StaticBias> {
    if rate.len() < 16 {
        return None;
    }
    let tau0 = 1.0 / rate_hz;
    let phase = phase_from_rate(rate, tau0);
    let max_m = allan::max_factor(Estimator::Oadev, phase.len());
    let dev = allan::deviation(
        Estimator::Oadev,
        &phase,
        tau0,
        &factors(TauGrid::Octave, max_m),
    );
    let record_s = rate.len() as f64 * tau0;
    let (best, best_adev) = dev
        .dev
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, &d)| (dev.tau[i], d))?;
    // Without a model (a fit that fails on a degenerate curve), the deviation at the longest
    // tau measured, which over-states a white-noise uncertainty by sqrt(2): the safe side.
    let uncertainty = match fit_deviation(&dev, phase.len(), &FitOptions::default()) {
        Ok(fit) => fit.avar(record_s).sqrt(),
        Err(_) => *dev.dev.last()?,
    };
    Some(StaticBias {
        bias: crate::analysis::neumaier_sum(rate.iter().copied()) / rate.len() as f64,
        uncertainty,
        record_s,
        best_tau_s: best,
        best_adev,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn white_noise_uncertainty_is_the_standard_error_of_the_mean() {
        // 100 s at 100 Hz of sigma 0.01 rad/s about a bias of 0.02 rad/s: the standard error
        // is 0.01 / sqrt(10^4) = 1e-4 rad/s. The fitted N from 10^4 white samples has a
        // relative standard deviation of a few percent (the fit's own interval); 15 % is
        // well outside that, yet would catch a sqrt(2) slip of the convention.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let normal = Normal::new(0.02, 0.01).unwrap();
        let rate: Vec<f64> = (0..10_000).map(|_| normal.sample(&mut rng)).collect();
        let b = static_bias(&rate, 100.0).unwrap();
        assert!((b.record_s - 100.0).abs() < 1e-9);
        assert!(
            (b.uncertainty / 1e-4 - 1.0).abs() < 0.15,
            "{}",
            b.uncertainty
        );
        // The mean is within 4 standard errors of the truth (probability 6e-5 to fail).
        assert!((b.bias - 0.02).abs() < 4e-4, "{}", b.bias);
        // White noise only: the curve keeps falling, so its minimum is at the longest tau.
        assert!(b.best_tau_s > 20.0, "{}", b.best_tau_s);
        assert!(static_bias(&rate[..10], 100.0).is_none());
    }
}

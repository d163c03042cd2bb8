//! What removing regressors takes from the random terms, and the refit that gives it back.
//!
//! Least squares on a ramp, a temperature channel or a slow tone also fits the part of the
//! noise that happens to look like them. For a random walk this part is large: with `c` the
//! OLS slope and `s` the end-to-end slope of a record of length T, detrending changes the
//! Allan variance at tau by `tau^2 (c s - c^2 / 2)`, whose expectation for a random walk is
//! `tau^2 K^2 (1 - 3/5) / T` (Cov(c, s) = K^2 / T, Var(c) = 6 K^2 / (5 T)); the overlapping
//! estimator's end effects bring it to about `0.32 K^2 tau^2 / T`, as measured below — a
//! quarter of `K^2 tau / 3` at `tau = T / 4`. Random terms fitted to the cleaned record with the
//! textbook bases would come out low (K most, B some), the simulations of that model too
//! quiet, and every test against them too eager: a ramp named on pure noise, then a
//! Gauss-Markov bump to fill the gap the low K left.
//!
//! **Loss.** The expected Allan variance a removal takes from unit-level random walk and
//! flicker noise, `l_K(tau)` and `l_B(tau)`, is measured on [`LOSS_REALISATIONS`] paired
//! simulations (each series' Allan variance before and after the same removal, so the
//! scatter of the series themselves cancels), capped at [`MAX_SHARE`] of the column's basis.
//! White noise and short Gauss-Markov processes
//! lose a share of order `p / n` (p regressors, n samples) and are left as they are.
//!
//! **Refit** ([`super::refit::refit_cleaned`]). The K and B columns of a cleaned curve are
//! their bases less the loss, `tau / 3 - l_K(tau)` and `2 ln 2 / pi - l_B(tau)`, so the fit
//! estimates the levels the raw noise had. (Lifting the curve by the fitted terms' loss
//! instead has a fixed point at K = 0: a weak random walk that the removal pushed below the
//! white line never comes back.)

use super::clean::{Removal, Temperature};
use super::evidence::allan_avar;
use super::refit::Loss;
use crate::analysis::fit;
use crate::sim::noise::{AxisNoise, NoiseTerms};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Paired simulations per loss: the loss is a mean difference whose relative scatter is
/// about `1 / sqrt(LOSS_REALISATIONS)` of the (already minor) correction.
pub const LOSS_REALISATIONS: usize = 16;
/// Largest share of a column's basis a removal is taken to remove, so the column stays
/// positive: at the longest taus of a 3 h record 16 pairs put the mean difference of a
/// random walk's Allan variance at 1.7 times the basis (a few clusters make it
/// heavy-tailed), the K column went negative there and the refit set K to 0.
const MAX_SHARE: f64 = 0.95;
/// Seeds of the loss simulations, apart from the model's realisations.
const LOSS_SEED: u64 = 0x1055;

/// The series and the curve's averaging factors a loss is measured on.
pub struct Record<'a> {
    pub len: usize,
    pub rate_hz: f64,
    pub m: &'a [usize],
    pub temperature: Option<&'a Temperature>,
}

/// The removal's loss on unit noise of `record`'s shape; `None` when it removes no regressor
/// (a constant and narrow notches take nothing that matters).
pub fn loss(removal: &Removal, record: &Record) -> Option<Loss> {
    if !(removal.ramp || removal.temperature || !removal.tones.is_empty()) {
        return None;
    }
    let duration = record.len as f64 / record.rate_hz;
    let one = |terms: NoiseTerms, i: usize| -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(LOSS_SEED + i as u64);
        let raw =
            AxisNoise::new(terms, record.rate_hz, duration, &mut rng).take(record.len, &mut rng);
        let (clean, _) = removal.apply(&raw, record.rate_hz, record.temperature);
        let before = allan_avar(raw, record.rate_hz, record.m);
        let after = allan_avar(clean, record.rate_hz, record.m);
        before.iter().zip(after).map(|(b, a)| b - a).collect()
    };
    let mean = |terms: NoiseTerms| -> Vec<f64> {
        let sums = (0..LOSS_REALISATIONS)
            .into_par_iter()
            .map(|i| one(terms, i))
            .reduce(
                || vec![0.0; record.m.len()],
                |a, b| a.iter().zip(b).map(|(x, y)| x + y).collect(),
            );
        sums.iter()
            .map(|s| (s / LOSS_REALISATIONS as f64).max(0.0))
            .collect::<Vec<f64>>()
    };
    // A removal cannot take more than the noise had: where the longest taus' few clusters
    // make the mean difference of 16 pairs exceed the basis, it is capped below it.
    let tau0 = 1.0 / record.rate_hz;
    let capped = |loss: Vec<f64>, column: usize| -> Vec<f64> {
        loss.iter()
            .zip(record.m)
            .map(|(l, &m)| l.min(MAX_SHARE * fit::basis(m as f64 * tau0)[column]))
            .collect()
    };
    let unit = |k: f64, b: f64| NoiseTerms {
        k,
        b,
        ..NoiseTerms::default()
    };
    Some(Loss {
        k: capped(mean(unit(1.0, 0.0)), fit::K),
        b: capped(mean(unit(0.0, 1.0)), fit::B),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::refit::{self, Column, Curve};

    /// A random walk's Allan variance after detrending: the measured loss grows as tau^2 with
    /// the coefficient `(1 - 3/5) K^2 / T` to first order, less the overlapping estimator's end
    /// effects (0.32 measured; the test allows 0.25 to 0.45 where the 16 pairs scatter by less
    /// than 10 %), and the refit restores K where a plain refit leaves it low.
    #[test]
    fn a_ramp_takes_what_the_slope_variance_says_and_the_refit_gives_it_back() {
        let rate_hz = 10.0;
        let len = 72_000;
        let duration = len as f64 / rate_hz;
        let m: Vec<usize> = (0..14)
            .map(|i| 10usize << i)
            .filter(|&m| m <= len / 4)
            .collect();
        let removal = Removal {
            ramp: true,
            ..Removal::default()
        };
        let record = Record {
            len,
            rate_hz,
            m: &m,
            temperature: None,
        };
        let loss = loss(&removal, &record).expect("a ramp is a regressor");
        for (&mi, lk) in m.iter().zip(&loss.k) {
            let tau = mi as f64 / rate_hz;
            let coefficient = lk * duration / (tau * tau);
            if tau <= duration / 64.0 {
                assert!(
                    (0.25..0.45).contains(&coefficient),
                    "tau {tau}: {coefficient}"
                );
            }
        }
        // A curve that is exactly the detrended expectation of K = 2e-4 (and N = 1e-3).
        let (n, k) = (1e-3, 2e-4);
        let tau: Vec<f64> = m.iter().map(|&mi| mi as f64 / rate_hz).collect();
        let avar: Vec<f64> = tau
            .iter()
            .zip(&loss.k)
            .map(|(&t, lk)| n * n / t + k * k * (t / 3.0) - k * k * lk)
            .collect();
        let sd = vec![0.1; tau.len()];
        let curve = Curve {
            tau: &tau,
            avar: &avar,
            sd_ln: &sd,
        };
        let columns = [Column::N, Column::K];
        let plain = refit::refit(curve, &columns, &refit::unfiltered);
        let restored = refit::refit_cleaned(curve, &columns, &refit::unfiltered, Some(&loss));
        assert!(plain.k < 0.98 * k, "{plain:?}");
        assert!((restored.k / k - 1.0).abs() < 0.005, "{restored:?}");
        assert!((restored.n / n - 1.0).abs() < 0.005, "{restored:?}");
    }
}

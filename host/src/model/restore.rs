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
//! flicker noise, `l_K(tau)` and `l_B(tau)`. The random walk's is computed exactly from its
//! covariance (`random_walk_loss`): a mean over simulated pairs is heavy-tailed at the
//! longest taus, where 16 pairs of a 3 h record put it at 1.7 times the K basis at T / 2.7,
//! the K column went negative there, and the refit set K to 0 (the simulations then too
//! quiet, a Gauss-Markov or Q term named to fill the hole). Flicker's, far smaller, is
//! measured on [`LOSS_REALISATIONS`] paired simulations (each series' Allan variance before
//! and after the same removal, so the scatter of the series themselves cancels), capped at
//! `MAX_SHARE` of its basis. White noise and short Gauss-Markov processes
//! lose a share of order `p / n` (p regressors, n samples) and are left as they are.
//!
//! **Refit** ([`super::refit::refit_cleaned`]). The K and B columns of a cleaned curve are
//! their bases less the loss, `tau / 3 - l_K(tau)` and `2 ln 2 / pi - l_B(tau)`, so the fit
//! estimates the levels the raw noise had. (Lifting the curve by the fitted terms' loss
//! instead has a fixed point at K = 0: a weak random walk that the removal pushed below the
//! white line never comes back.)

use super::clean::{Cleaner, Removal, Temperature};
use super::evidence::allan_avar;
use super::refit::Loss;
use crate::analysis::{fit, numerics};
use crate::sim::noise::{AxisNoise, NoiseTerms};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::sync::{Arc, Mutex};

/// Paired simulations of flicker's loss: a mean difference whose relative scatter is about
/// `1 / sqrt(LOSS_REALISATIONS)` of the (already minor) correction.
pub const LOSS_REALISATIONS: usize = 16;
/// Largest share of flicker's basis a removal is taken to remove, so the B column stays
/// positive where the longest taus' few clusters make a mean of 16 pairs heavy-tailed.
const MAX_SHARE: f64 = 0.95;
/// Samples per block of [`random_walk_loss`]'s sums.
const LOSS_BLOCK: usize = 4096;
/// Seeds of the loss simulations, apart from the model's realisations.
const LOSS_SEED: u64 = 0x1055;
/// The most samples of unit flicker [`Losses`] keeps for the next removal's loss (256 MiB;
/// the [`LOSS_REALISATIONS`] series of 3 h at 100 Hz take 132 MiB). Longer records
/// synthesise them again for each removal rather than hold them.
const KEPT_LOSS_SAMPLES: usize = 1 << 25;

/// The series and the curve's averaging factors a loss is measured on.
pub struct Record<'a> {
    pub len: usize,
    pub rate_hz: f64,
    pub m: &'a [usize],
    pub temperature: Option<&'a Temperature>,
    /// The losses already measured on this record.
    pub known: &'a Losses,
}

/// The losses measured on one record, by removal and averaging factors: the open noise
/// model and the candidates' refits ask for the same removal's loss round after round, and
/// each costs [`LOSS_REALISATIONS`] simulated flicker series as long as the record. The
/// series themselves do not depend on the removal, so they are kept too, with their Allan
/// variances before it (up to 256 MiB of samples).
#[derive(Default)]
pub struct Losses {
    measured: Mutex<Vec<(String, Option<Loss>)>>,
    flicker: Mutex<Option<Arc<UnitFlicker>>>,
}

/// The unit flicker series of [`loss`]'s paired simulations for one record shape, each with
/// its Allan variance before any removal.
struct UnitFlicker {
    len: usize,
    rate_hz: f64,
    m: Vec<usize>,
    /// `(series, its Allan variance at m)`, by seed.
    pairs: Vec<(Vec<f64>, Vec<f64>)>,
}

impl UnitFlicker {
    fn new(record: &Record) -> UnitFlicker {
        let pairs = (0..LOSS_REALISATIONS)
            .into_par_iter()
            .map(|i| {
                let raw = unit_flicker(record, i);
                let before = allan_avar(raw.clone(), record.rate_hz, record.m);
                (raw, before)
            })
            .collect();
        UnitFlicker {
            len: record.len,
            rate_hz: record.rate_hz,
            m: record.m.to_vec(),
            pairs,
        }
    }

    fn fits(&self, record: &Record) -> bool {
        self.len == record.len && self.rate_hz == record.rate_hz && self.m == record.m
    }
}

impl Losses {
    /// [`loss`] of `removal` on `record`, measured once.
    pub fn of(&self, removal: &Removal, record: &Record) -> Option<Loss> {
        let key = format!("{removal:?} {:?}", record.m);
        if let Some((_, found)) = self.held().iter().find(|(k, _)| *k == key) {
            return found.clone();
        }
        let measured = loss(removal, record);
        self.held().push((key, measured.clone()));
        measured
    }

    // A thread that panicked while holding a lock left its value whole: entries are
    // pushed and set complete.
    fn held(&self) -> std::sync::MutexGuard<'_, Vec<(String, Option<Loss>)>> {
        self.measured.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The unit flicker series for `record`, made once per record shape; `None` beyond
    /// [`KEPT_LOSS_SAMPLES`].
    fn unit_flicker(&self, record: &Record) -> Option<Arc<UnitFlicker>> {
        if LOSS_REALISATIONS.saturating_mul(record.len) > KEPT_LOSS_SAMPLES {
            return None;
        }
        let kept = || self.flicker.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(f) = kept().as_ref().filter(|f| f.fits(record)) {
            return Some(Arc::clone(f));
        }
        let made = Arc::new(UnitFlicker::new(record));
        *kept() = Some(Arc::clone(&made));
        Some(made)
    }
}

/// Unit flicker (B = 1) as long as `record`, loss simulation `i`.
fn unit_flicker(record: &Record, i: usize) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(LOSS_SEED + i as u64);
    let unit = NoiseTerms {
        b: 1.0,
        ..NoiseTerms::default()
    };
    let duration = record.len as f64 / record.rate_hz;
    AxisNoise::new(unit, record.rate_hz, duration, &mut rng).take(record.len, &mut rng)
}

/// The removal's loss on unit noise of `record`'s shape; `None` when it removes no regressor
/// (a constant and narrow notches take nothing that matters).
pub fn loss(removal: &Removal, record: &Record) -> Option<Loss> {
    if takes_nothing(removal) {
        return None;
    }
    loss_on(removal, record, record.known.unit_flicker(record))
}

fn takes_nothing(removal: &Removal) -> bool {
    !(removal.ramp || removal.temperature || !removal.tones.is_empty())
}

/// [`loss`] of a removal that takes something, with the unit flicker `kept` from an
/// earlier removal, or synthesised here when `None`.
fn loss_on(removal: &Removal, record: &Record, kept: Option<Arc<UnitFlicker>>) -> Option<Loss> {
    let tau0 = 1.0 / record.rate_hz;
    let cleaner = Cleaner::new(removal, record.len, record.rate_hz, record.temperature);
    let k = random_walk_loss(&cleaner, tau0, record.m);
    // Flicker's loss by paired simulation: each series' Allan variance before and after the
    // same removal, so the scatter of the series themselves cancels.
    let one = |i: usize| -> Vec<f64> {
        let (clean, before) = match &kept {
            Some(f) => {
                let (raw, before) = &f.pairs[i];
                (cleaner.apply(raw).0, before.clone())
            }
            None => {
                let raw = unit_flicker(record, i);
                let clean = cleaner.apply(&raw).0;
                (clean, allan_avar(raw, record.rate_hz, record.m))
            }
        };
        let after = allan_avar(clean, record.rate_hz, record.m);
        before.iter().zip(after).map(|(b, a)| b - a).collect()
    };
    let sums = (0..LOSS_REALISATIONS).into_par_iter().map(one).reduce(
        || vec![0.0; record.m.len()],
        |a, b| a.iter().zip(b).map(|(x, y)| x + y).collect(),
    );
    // A removal cannot take more than the noise had.
    let b = sums
        .iter()
        .map(|s| (s / LOSS_REALISATIONS as f64).clamp(0.0, MAX_SHARE * fit::FLICKER_AVAR_FACTOR))
        .collect();
    Some(Loss { k, b })
}

/// The expected overlapping Allan variance that regressing out the `cleaner`'s centred,
/// unit-norm columns (H does not depend on their scale, and G stays well conditioned) takes
/// from a unit random walk (K = 1, `y_k = sqrt(tau0) sum_{j<k} w_j`, so `Cov(y_a, y_b) =
/// tau0 min(a, b)`), at each averaging factor in `m`, u^2 per K^2: exact, not simulated.
///
/// With `d = D y` the second differences of phase over m samples (`d_i = P_(i+2m) - 2
/// P_(i+m) + P_i`, P the prefix sums of y), the Allan variance is `c |D y|^2`, `c = 1 / (2
/// m^2 L)`, L the number of differences. Least squares leaves `(I - H) y`, `H = X G X^T`,
/// `G = (X^T X)^-1`, so the expected loss is `c (2 tr(D H Sigma D^T) - tr(D H Sigma H D^T))
/// = c (2 tr(G W^T U) - tr(G S G U^T U))` with `U = D X`, `W = D Sigma X` and `S = X^T Sigma
/// X` (expectations of quadratic forms, `E[y^T A y] = tr(A Sigma)`). Sigma times a vector
/// is two running sums, so each averaging factor costs O(n p^2).
fn random_walk_loss(cleaner: &Cleaner, tau0: f64, m: &[usize]) -> Vec<f64> {
    let x = cleaner.columns();
    let p = x.len();
    let n = x.first().map_or(0, Vec::len);
    if p == 0 || n < 4 {
        return vec![0.0; m.len()];
    }
    // Sigma v with Sigma_ab = min(a, b) (the factor tau0 is applied to the result).
    let sigma_times = |v: &[f64]| -> Vec<f64> {
        let mut out = vec![0.0; n];
        let mut weighted = 0.0;
        let mut tail: f64 = v.iter().sum();
        for a in 0..n {
            weighted += a as f64 * v[a];
            tail -= v[a];
            out[a] = weighted + a as f64 * tail;
        }
        out
    };
    let sx: Vec<Vec<f64>> = x.iter().map(|c| sigma_times(c)).collect();
    let s: Vec<Vec<f64>> = (0..p)
        .map(|j| (0..p).map(|k| numerics::dot(&x[j], &sx[k])).collect())
        .collect();
    let Some(g) = numerics::invert_spd(cleaner.gram()) else {
        return vec![0.0; m.len()];
    };
    let prefix = |c: &[f64]| -> Vec<f64> {
        let mut out = Vec::with_capacity(n + 1);
        let mut acc = 0.0;
        out.push(0.0);
        for v in c {
            acc += v;
            out.push(acc);
        }
        out
    };
    let px: Vec<Vec<f64>> = x.iter().map(|c| prefix(c)).collect();
    let psx: Vec<Vec<f64>> = sx.iter().map(|c| prefix(c)).collect();
    let mat_mul = |a: &[Vec<f64>], b: &[Vec<f64>]| -> Vec<Vec<f64>> {
        (0..p)
            .map(|i| {
                (0..p)
                    .map(|j| (0..p).map(|k| a[i][k] * b[k][j]).sum())
                    .collect()
            })
            .collect()
    };
    let trace = |a: &[Vec<f64>]| (0..p).map(|i| a[i][i]).sum::<f64>();
    let gsg = mat_mul(&mat_mul(&g, &s), &g);
    m.par_iter()
        .map(|&m| {
            if n < 2 * m {
                return 0.0;
            }
            let l = n + 1 - 2 * m;
            // Each column's (and Sigma column's) second differences at lag m, a block at a
            // time, then their products summed pair by pair: short contiguous runs the
            // processor streams through, in memory that does not grow with the record.
            let mut utu = vec![vec![0.0; p]; p];
            let mut wtu = vec![vec![0.0; p]; p];
            let mut u = vec![vec![0.0; LOSS_BLOCK]; p];
            let mut w = vec![vec![0.0; LOSS_BLOCK]; p];
            for start in (0..l).step_by(LOSS_BLOCK) {
                let len = LOSS_BLOCK.min(l - start);
                let second = |c: &[f64], out: &mut [f64]| {
                    for (t, o) in out[..len].iter_mut().enumerate() {
                        let i = start + t;
                        *o = c[i + 2 * m] - 2.0 * c[i + m] + c[i];
                    }
                };
                for j in 0..p {
                    second(&px[j], &mut u[j]);
                    second(&psx[j], &mut w[j]);
                }
                for j in 0..p {
                    for k in 0..p {
                        utu[j][k] += numerics::dot(&u[j][..len], &u[k][..len]);
                        wtu[j][k] += numerics::dot(&w[j][..len], &u[k][..len]);
                    }
                }
            }
            let term1 = trace(&mat_mul(&g, &wtu));
            let term2 = trace(&mat_mul(&gsg, &utu));
            let c = 1.0 / (2.0 * (m * m) as f64 * l as f64);
            // Sigma above is min(a, b); the random walk's is tau0 times that.
            (tau0 * c * (2.0 * term1 - term2)).max(0.0)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::refit::{self, Column, Curve};

    /// The exact random-walk loss against paired simulations of a ramp and a tone removed
    /// from 200 s at 10 Hz, out to a quarter of the record where a few clusters remain: the
    /// mean difference of 3000 pairs within four of its standard errors at every tau.
    #[test]
    fn the_exact_random_walk_loss_matches_simulation() {
        let (rate_hz, len) = (10.0, 2000);
        let m = [1, 10, 40, 160, 500];
        let removal = Removal {
            ramp: true,
            tones: vec![crate::model::clean::Tone {
                freq_hz: 0.031,
                guard_hz: 0.01,
            }],
            ..Removal::default()
        };
        let cleaner = Cleaner::new(&removal, len, rate_hz, None);
        let exact = random_walk_loss(&cleaner, 1.0 / rate_hz, &m);
        let pairs = 3000;
        let diffs: Vec<Vec<f64>> = (0..pairs)
            .map(|i| {
                let mut rng = ChaCha8Rng::seed_from_u64(50_000 + i);
                let unit = NoiseTerms {
                    k: 1.0,
                    ..NoiseTerms::default()
                };
                let raw = AxisNoise::new(unit, rate_hz, 200.0, &mut rng).take(len, &mut rng);
                let (clean, _) = removal.apply(&raw, rate_hz, None);
                let before = allan_avar(raw, rate_hz, &m);
                let after = allan_avar(clean, rate_hz, &m);
                before.iter().zip(after).map(|(b, a)| b - a).collect()
            })
            .collect();
        for (j, e) in exact.iter().enumerate() {
            let mean = diffs.iter().map(|d| d[j]).sum::<f64>() / pairs as f64;
            let var = diffs.iter().map(|d| (d[j] - mean).powi(2)).sum::<f64>() / (pairs - 1) as f64;
            let se = (var / pairs as f64).sqrt();
            assert!(
                (e - mean).abs() < 4.0 * se,
                "m {}: exact {e}, simulated {mean} +- {se}",
                m[j]
            );
            assert!(*e > 0.0, "m {}: {e}", m[j]);
        }
    }

    /// The unit flicker kept from one removal's loss gives the next removal the loss it
    /// would measure on series synthesised for it alone.
    #[test]
    fn kept_unit_flicker_measures_what_fresh_series_do() {
        let (rate_hz, len) = (10.0, 6000);
        let m = [1, 10, 100, 1000];
        let losses = Losses::default();
        let record = Record {
            len,
            rate_hz,
            m: &m,
            temperature: None,
            known: &losses,
        };
        let ramp = Removal {
            ramp: true,
            ..Removal::default()
        };
        let tone = Removal {
            tones: vec![crate::model::clean::Tone {
                freq_hz: 0.013,
                guard_hz: 0.005,
            }],
            ..Removal::default()
        };
        let first = losses.of(&ramp, &record).expect("a ramp takes something");
        let second = losses.of(&tone, &record).expect("a tone takes something");
        assert!(losses.unit_flicker(&record).is_some());
        // Equal but for the order in which the parallel sum adds the 16 pairs.
        let same = |a: &Loss, b: &Loss| {
            let close = |x: &[f64], y: &[f64]| {
                x.len() == y.len()
                    && x.iter()
                        .zip(y)
                        .all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs().max(y.abs()))
            };
            close(&a.k, &b.k) && close(&a.b, &b.b)
        };
        for (removal, kept) in [(&ramp, &first), (&tone, &second)] {
            let fresh = loss_on(removal, &record, None).expect("the same removal");
            assert!(same(kept, &fresh), "{kept:?} against {fresh:?}");
        }
        assert!(second.b.iter().any(|&b| b > 0.0), "{second:?}");
    }

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
            known: &Losses::default(),
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

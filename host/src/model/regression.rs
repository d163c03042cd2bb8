//! Whether the rate follows a regressor — time (a ramp) or the temperature channel and its
//! derivative — tested by a Wald statistic whose covariance comes from simulation.
//!
//! The coefficients `c` (one for a ramp, two for temperature) are estimated by least squares
//! with the effects already named ([`super::clean`]). Their covariance under noise alone is
//! estimated from `R` realisations of the round's **open noise model**: the random terms
//! refitted to the record with every deterministic candidate removed — ramp, temperature and
//! the strongest slow line (the alternative's noise model, as a Wald test takes it) — each
//! regressed in the same way: `S = (1/R) sum_i c_i c_i^T` (the coefficients of pure noise
//! have mean 0). The statistic is `T^2 = c^T S^-1 c`; with S estimated from R draws,
//! `(R - p + 1) / (p R) T^2` follows F(p, R - p + 1) (Hotelling, 1931; p the number of
//! coefficients), which gives the p-value. R is [`super::REGRESSION_REALISATIONS`] times the
//! round's realisations: a regression realisation costs only a synthesis and a least-squares
//! pass, and Hotelling's penalty shrinks with R.
//!
//! Why the open model: a baseline fitted to the raw record has absorbed the effects — a
//! temperature cycle, a ramp or a slow sinusoid inflates K — and realisations of that
//! inflated random walk project onto any smooth regressor as strongly as the effect itself,
//! so the test would have almost no power exactly when the effect is large, and one effect
//! would hide another (a slow sinusoid beside a temperature coupling: 3 of 10 records named
//! nothing when each regressor was removed alone). The refit gives back what the
//! regressors take from the random walk and flicker ([`super::restore`]); without that K
//! comes out low once a ramp is removed, and pure noise shows a ramp.
//!
//! **Limit.** K is taken as the refit gives it: a record whose random walk came out low can
//! still show a ramp (one record in ten without an effect, in the family study). Running
//! each realisation through its own refit (a studentised test) accounts for that, but K read
//! off the few longest taus is so uncertain that the studentised law's tail then hides ramps
//! that raise the deviation at T/4 three to five times (4 of 10 named, measured).

use super::Effect;
use super::clean::{Coefficients, Removal};
use super::evidence::{Context, Evidence, Probe};
use crate::sim::noise::NoiseTerms;
use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// What a regressor test needs besides the record.
pub struct Setup<'a> {
    /// The round's record, taus, spread, removal and white shape, as the other views see them.
    pub view: &'a Context<'a>,
    pub realisations: usize,
    /// The noise model H1: the round's random terms refitted with every deterministic
    /// candidate removed (see `super::open_noise`).
    pub open: &'a NoiseTerms,
    /// Realisation `i` of a stochastic model, as long as the record.
    pub realise: &'a (dyn Fn(&NoiseTerms, usize) -> Vec<f64> + Sync),
    /// Candidates in the round (for the Bonferroni share).
    pub candidates: usize,
}

/// The coefficients of `probe`'s regressor(s) among the fitted ones.
fn of_probe(probe: Probe, c: &Coefficients) -> Vec<f64> {
    match probe {
        Probe::Ramp => vec![c.slope.unwrap_or(0.0)],
        _ => vec![c.temp.unwrap_or(0.0), c.temp_rate.unwrap_or(0.0)],
    }
}

/// The coefficients of `probe`'s regressor(s) in `series`.
fn coefficients(probe: Probe, series: &[f64], removal: &Removal, s: &Setup) -> Vec<f64> {
    let (_, c) = removal.apply(series, s.view.rate_hz, s.view.temperature);
    of_probe(probe, &c)
}

/// The removal with `probe`'s regressor added.
fn with_regressor(removal: &Removal, probe: Probe) -> Removal {
    let mut more = removal.clone();
    match probe {
        Probe::Ramp => more.ramp = true,
        _ => more.temperature = true,
    }
    more
}

/// `c^T S^-1 c` for a 1x1 or 2x2 `S`; None when S is singular.
fn quadratic(c: &[f64], s: &[[f64; 2]; 2]) -> Option<f64> {
    match c.len() {
        1 => (s[0][0] > 0.0).then(|| c[0] * c[0] / s[0][0]),
        _ => {
            let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
            if det.is_nan() || det <= 0.0 {
                return None;
            }
            let inv = [
                [s[1][1] / det, -s[0][1] / det],
                [-s[1][0] / det, s[0][0] / det],
            ];
            Some(
                c[0] * (inv[0][0] * c[0] + inv[0][1] * c[1])
                    + c[1] * (inv[1][0] * c[0] + inv[1][1] * c[1]),
            )
        }
    }
}

/// The Wald test of `probe` (a ramp or a temperature coupling) on the record `x`.
pub fn test(probe: Probe, x: &[f64], s: &Setup) -> Evidence {
    let more = with_regressor(s.view.removal, probe);
    let (_, c) = more.apply(x, s.view.rate_hz, s.view.temperature);
    let measured = of_probe(probe, &c);
    let effect = match probe {
        Probe::Ramp => Effect::RateRamp { slope: measured[0] },
        _ => Effect::Temperature {
            coeff: measured[0],
            rate_coeff: measured[1],
        },
    };
    let r = s.realisations.max(3);
    let sims: Vec<Vec<f64>> = (0..r)
        .into_par_iter()
        .map(|i| coefficients(probe, &(s.realise)(s.open, i), &more, s))
        .collect();
    let p = measured.len();
    let mut cov = [[0.0; 2]; 2];
    for c in &sims {
        for a in 0..p {
            for b in 0..p {
                cov[a][b] += c[a] * c[b] / r as f64;
            }
        }
    }
    let stat = quadratic(&measured, &cov).unwrap_or(0.0);
    let simulated: Vec<f64> = sims
        .iter()
        .map(|c| quadratic(c, &cov).unwrap_or(0.0))
        .collect();
    let (d1, d2) = (p as f64, (r - p + 1) as f64);
    let p_value = match FisherSnedecor::new(d1, d2) {
        Ok(f) => f.sf(stat * d2 / (d1 * r as f64)),
        Err(_) => 1.0,
    };
    Evidence::with_p(
        probe.name(),
        probe.view(),
        (stat, Some(effect)),
        &simulated,
        p_value,
        s.candidates,
    )
}

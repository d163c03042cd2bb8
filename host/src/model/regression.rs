//! Whether the rate follows a regressor — time (a ramp) or the temperature channel and its
//! derivative — tested by a Wald statistic under the round's open noise model.
//!
//! The coefficients (one for a ramp, two for temperature) are estimated jointly with the
//! constant and the effects already named ([`super::clean`]) by generalised least squares on
//! block means ([`super::gls`]), whose covariance comes from the **open noise model**: the
//! random terms refitted to the record with every deterministic candidate removed — ramp,
//! temperature and the strongest slow line (the alternative's noise model, as a Wald test
//! takes it). With that covariance `C` of the tested coefficients `c`, `T^2 = c^T C^-1 c`
//! follows chi-square with as many degrees of freedom as coefficients when the regressor
//! plays no part, which gives the p-value exactly: no covariance is estimated from
//! realisations, so there is no Hotelling penalty (at the naming level, p = 1.4e-3, two
//! coefficients from 48 draws need 15.4 where chi-square needs 13.1). The effect shown is
//! the least-squares coefficient, the one the removal takes out of the record.
//!
//! Why the open model: a baseline fitted to the raw record has absorbed the effects — a
//! temperature cycle, a ramp or a slow sinusoid inflates K — and that inflated random walk
//! projects onto any smooth regressor as strongly as the effect itself, so the test would
//! have almost no power exactly when the effect is large, and one effect would hide another
//! (a slow sinusoid beside a temperature coupling: 3 of 10 records named nothing when each
//! regressor was removed alone). The refit gives back what the regressors take from the
//! random walk and flicker ([`super::restore`]).
//!
//! **Limit.** K is taken as the refit gives it, not as uncertain: a record whose random walk
//! came out low can still show a ramp. Its GLS statistic leans on the frequencies where the
//! white noise dominates, which makes it less sensitive to K than least squares.

use super::Effect;
use super::clean::{Removal, notch};
use super::evidence::{Context, Evidence, Probe};
use super::gls::{Estimator, wald};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// What a regressor test needs besides the record.
pub struct Setup<'a> {
    /// The round's record, removal and temperature, as the other views see them.
    pub view: &'a Context<'a>,
    /// GLS under the round's open noise model (see `super::open_noise`); None when that
    /// model has no noise at all.
    pub gls: Option<&'a Estimator>,
    /// Candidates in the round (for the Bonferroni share).
    pub candidates: usize,
}

/// The positions of `probe`'s regressor(s) among the columns of [`Removal::design`] for a
/// removal that has it: the ramp first, then the temperature and its derivative.
fn positions(probe: Probe, removal: &Removal) -> Vec<usize> {
    match probe {
        Probe::Ramp => vec![0],
        _ => {
            let first = usize::from(removal.ramp);
            vec![first, first + 1]
        }
    }
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

/// The Wald test of `probe` (a ramp or a temperature coupling) on the record `x`.
pub fn test(probe: Probe, x: &[f64], s: &Setup) -> Evidence {
    let view = s.view;
    let more = with_regressor(view.removal, probe);
    let (_, c) = more.apply(x, view.rate_hz, view.temperature);
    let effect = match probe {
        Probe::Ramp => Effect::RateRamp {
            slope: c.slope.unwrap_or(0.0),
        },
        _ => Effect::Temperature {
            coeff: c.temp.unwrap_or(0.0),
            rate_coeff: c.temp_rate.unwrap_or(0.0),
        },
    };
    let indices = positions(probe, &more);
    let dof = indices.len();
    let statistic = s.gls.and_then(|gls| {
        let notched = if more.notches.is_empty() {
            x.to_vec()
        } else {
            notch(x, view.rate_hz, &more.notches)
        };
        let mut columns = vec![vec![1.0; x.len()]];
        columns.extend(more.design(x.len(), view.rate_hz, view.temperature));
        let shifted: Vec<usize> = indices.iter().map(|i| i + 1).collect();
        wald(&gls.fit(&columns, &notched)?, &shifted)
    });
    let statistic = statistic.unwrap_or(0.0);
    let p_value = ChiSquared::new(dof as f64).map_or(1.0, |chi| chi.sf(statistic));
    Evidence::exact(
        probe.name(),
        probe.view(),
        (statistic, Some(effect)),
        dof,
        p_value,
        s.candidates,
    )
}

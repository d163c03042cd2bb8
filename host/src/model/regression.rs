//! Whether the rate follows a regressor — time (a ramp) or the temperature channel and its
//! derivative — tested by a likelihood ratio calibrated by a parametric bootstrap
//! ([`super::gls`]).
//!
//! The record, with the lines already named notched out, is cut into block means; the fixed
//! effects are a constant, the regressors already named ([`super::clean`]) and the
//! candidate's (one column for a ramp, two for temperature). Where the record can carry
//! another regressor not yet named (a ramp beside a temperature channel), the candidate is
//! tested twice on the same draws — alone, and beside that other regressor — and the
//! statistic is the larger ratio: a ramp and a warm-up of opposite signs cancel when each
//! is tested alone, while a warm-up tested beside a ramp column loses what the column
//! takes of it ([`super::gls::Estimator::test_designs`]). The noise is the round's **open
//! noise model** — the random terms refitted to the record with every deterministic
//! candidate removed (ramp, temperature, the strongest slow line) — for its white noise,
//! quantization and Gauss-Markov terms; its flicker and random-walk levels are re-estimated
//! from the block means on each side of the ratio, and the bootstrap draws come from the
//! levels the record shows without the candidate. The p-value is the scaled chi-square
//! matched to [`super::REGRESSION_DRAWS`] draws, as for the other simulated views
//! ([`super::evidence::Evidence::new`]). The effect shown is the least-squares coefficient,
//! the one the removal takes out of the record, with its standard error under the noise the
//! record shows with the regressor in ([`super::gls::Estimator::coefficient_sd`]).
//!
//! Why the open model's short-tau terms: a baseline fitted to the raw record has absorbed
//! the effects — a temperature cycle, a ramp or a slow sinusoid inflates K — and it is K and
//! B, the terms an absorbed effect moves, that each likelihood estimates afresh.
//!
//! **Limit.** A ramp and a random walk's own trend differ only in the wander the random walk
//! adds at minutes, and a record gives the random walk's level only roughly: ramps that raise
//! the Allan deviation at a quarter of the record three times are found in about a quarter
//! of records, six times in nearly all (see [`super::gls`]). Knowing K, a test would find every
//! ramp of the family; searching K on the record's full-resolution cosine transform instead of
//! block means finds no more (the `ramp_power` test measures both).

use super::Effect;
use super::clean::{Removal, notch};
use super::evidence::{Context, Evidence, Probe};
use super::gls::{Bootstrap, Design, Estimator};
use std::collections::BTreeMap;

/// What a regressor test needs besides the record.
pub struct Setup<'a> {
    /// The round's record, removal and temperature, as the other views see them.
    pub view: &'a Context<'a>,
    /// GLS under the round's open noise model (see `super::open_noise`): its white noise,
    /// quantization and Gauss-Markov terms, its flicker and random-walk levels re-estimated.
    pub gls: &'a Estimator,
    /// Series drawn under the null, and the seed of the first.
    pub draws: usize,
    pub seed: u64,
    /// Candidates in the round (for the Bonferroni share).
    pub candidates: usize,
    /// Whether the p-value is the draws' Monte Carlo one ([`Evidence::monte_carlo`]) rather
    /// than a scaled chi-square matched to them.
    pub monte_carlo: bool,
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

/// `more` (a removal with the candidate's regressor) with every other regressor the record
/// can carry and `more` lacks (a ramp; the temperature and its rate when there is a
/// channel); `None` when there is none.
fn with_every_regressor(more: &Removal, has_temperature: bool) -> Option<Removal> {
    let all = Removal {
        ramp: true,
        temperature: more.temperature || has_temperature,
        ..more.clone()
    };
    (all.ramp != more.ramp || all.temperature != more.temperature).then_some(all)
}

/// The likelihood-ratio test of `probe` (a ramp or a temperature coupling) on the record `x`.
pub fn test(probe: Probe, x: &[f64], s: &Setup) -> Evidence {
    let view = s.view;
    let more = with_regressor(view.cleaner.removal(), probe);
    // Notched once: the least-squares coefficients and the likelihoods both start there.
    let notched = if more.notches.is_empty() {
        x.to_vec()
    } else {
        notch(x, view.rate_hz, &more.notches)
    };
    let regressors = Removal {
        notches: Vec::new(),
        ..more.clone()
    };
    let (_, c) = regressors.apply(&notched, view.rate_hz, view.temperature);
    let effect = match probe {
        Probe::Ramp => Effect::RateRamp {
            slope: c.slope.unwrap_or(0.0),
        },
        _ => Effect::Temperature {
            coeff: c.temp.unwrap_or(0.0),
            rate_coeff: c.temp_rate.unwrap_or(0.0),
        },
    };
    // The regressor alone (beside those named) and beside every other one: a ramp and a
    // warm-up of opposite signs cancel in the first, and a warm-up that a ramp column would
    // take loses its power in the second, so the statistic is the larger of the two.
    let every = with_every_regressor(&more, view.temperature.is_some());
    let removals: Vec<Removal> = std::iter::once(more).chain(every).collect();
    let null = bootstrap(&notched, &removals, probe, s);
    let (statistic, simulated) = null.map_or((0.0, Vec::new()), |t| (t.statistic, t.null));
    let judged = if s.monte_carlo {
        Evidence::monte_carlo
    } else {
        Evidence::new
    };
    let mut evidence = judged(
        probe.name(),
        probe.view(),
        (statistic, Some(effect)),
        &simulated,
        s.candidates,
    );
    evidence.standard_errors = standard_errors(&notched, &removals[0], probe, s);
    evidence
}

/// The standard deviations of `probe`'s least-squares coefficients beside the regressors of
/// `removal` and a constant, by the effect's parameter names.
fn standard_errors(
    notched: &[f64],
    removal: &Removal,
    probe: Probe,
    s: &Setup,
) -> BTreeMap<&'static str, f64> {
    let view = s.view;
    let mut columns = vec![vec![1.0; notched.len()]];
    columns.extend(removal.design(notched.len(), view.rate_hz, view.temperature));
    let names: &[&'static str] = match probe {
        Probe::Ramp => &["slope"],
        _ => &["coeff", "rate_coeff"],
    };
    let tested: Vec<usize> = positions(probe, removal).iter().map(|i| i + 1).collect();
    let Some(sd) = s.gls.coefficient_sd(&columns, notched) else {
        return BTreeMap::new();
    };
    tested
        .iter()
        .zip(names)
        .map(|(&i, &name)| (name, sd[i]))
        .collect()
}

/// The bootstrap test ([`super::gls::Estimator::test_designs`]) of `probe`'s regressors in
/// the design of each of `removals`, on the notched record, with a constant beside them.
fn bootstrap(notched: &[f64], removals: &[Removal], probe: Probe, s: &Setup) -> Option<Bootstrap> {
    let view = s.view;
    let x = notched;
    let designs: Vec<(Vec<Vec<f64>>, Vec<usize>)> = removals
        .iter()
        .map(|removal| {
            let mut columns = vec![vec![1.0; x.len()]];
            columns.extend(removal.design(x.len(), view.rate_hz, view.temperature));
            let shifted = positions(probe, removal).iter().map(|i| i + 1).collect();
            (columns, shifted)
        })
        .collect();
    let designs: Vec<Design> = designs
        .iter()
        .map(|(columns, tested)| Design { columns, tested })
        .collect();
    // A Monte Carlo verdict cannot pass once e draws reach the statistic, (1 + e) / (draws +
    // 1) being no longer below the threshold, so drawing stops there.
    let enough = if s.monte_carlo {
        ((s.draws + 1) as f64 * super::p_needed(s.candidates) - 1.0)
            .ceil()
            .max(1.0) as usize
    } else {
        usize::MAX
    };
    s.gls
        .test_designs_until(&designs, x, s.draws, s.seed, enough)
}

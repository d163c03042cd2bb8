//! Effects named before an effect of the other kind, tested again once it is in the model
//! (`named_before`): backward elimination after the forward search, as in stepwise
//! regression, where a term entered early can become redundant once later ones are in
//! (Draper & Smith, *Applied Regression Analysis*, 3rd ed., 1998, the chapter on selecting
//! the best regression equation).
//!
//! **Why.** Each round tests a candidate against realisations of the model named so far,
//! which lacks whatever else the record holds, and deterministic candidates (lines, ramp,
//! temperature) are judged before random terms. Excess power at slow frequencies is seen by
//! both: a slow line found in a Gauss-Markov process's plateau passes the line view (judged
//! against an open noise model without the process) and is named first; the process, named
//! next, then explains what the line took. The other way round, a process named before a
//! sinusoid whose own test passed only once the process was in explains what the sinusoid
//! already explains. The forward rule never asks again whether the earlier effect is needed.
//!
//! **The rule.** After the forward search, each effect followed by a later effect of the
//! other kind (deterministic or random; a line standing in for a random term counts as
//! random; filters are neither) is taken out of the final model, the random terms refitted
//! without it (`candidates::without`), and a round is simulated for that model. The
//! effect goes only if that round is one where the forward search would have stopped: no
//! candidate passes its naming rule, the effect's own test included. Otherwise it stays, and
//! the check says what it saw. Effects of one kind are not checked against each other: the
//! regressors are estimated jointly (`super::joint`) and random terms passing together are
//! weighed by the Allan gap (`super::naming`).
//!
//! **Lines named together are tested again together** (`together`), as they were named
//! (`super::naming::lines_beside`): the final model without all of them, one simulated round
//! of the line view, and each judged against the strongest false line of each realisation.
//! A line that still passes there passes at the level its own round would name it at, so it
//! stays; only a line that does not is checked again alone. One round for a comb of eight
//! lines instead of eight: on a real ADIS16405 accelerometer channel whose later slow line
//! stood in for a random term, the check of its six lines took 3.3 s, and 35.5 s one by one.

use super::Line;
use super::candidates;
use super::clean::Removal;
use super::evidence::{Probe, View};
use super::refit::Column;
use super::simulate::{Round, simulate_probe, simulate_round};
use super::{Data, Effect, Step};
use serde::Serialize;

/// One effect tested again against the final model without it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rechecked {
    /// The effect as the model held it.
    pub effect: Effect,
    /// Its test's p-value against realisations of the model without it.
    pub p_value: f64,
    /// The p-value its naming rule needs in that round.
    pub p_needed: f64,
    /// Whether its test still passes there.
    pub passes: bool,
    /// Whether another candidate passes there (the effect then stays whatever its own test
    /// says: the model without it is not one the search would stop at); `None` when its own
    /// test passes, which decides alone, and the others were not judged.
    pub other_passes: Option<bool>,
    /// Allan gap of the final model with the effect, and without it.
    pub gap_with: f64,
    pub gap_without: f64,
    /// Whether it was dropped from the model.
    pub dropped: bool,
    /// How many lines of one naming round were taken out together for the test, this one
    /// included (module documentation); 1 when it was tested alone.
    pub together: usize,
}

impl Rechecked {
    /// In words, `u` the channel's unit.
    pub fn describe(&self, u: &str) -> String {
        use super::report::p_text;
        use crate::report::sig;
        // The words for what the test left out, and for the Allan gap without and with it.
        let (without, gap_without, gap_with) = match self.together {
            0 | 1 => (
                "without it".to_string(),
                "without it".to_string(),
                "with it",
            ),
            n => (
                format!(
                    "without it and the {} other lines named in its round",
                    n - 1
                ),
                format!("without the {n} lines"),
                "with them",
            ),
        };
        let verdict = if self.dropped {
            "dropped: with the effects named after it in the model its test no longer passes and nothing else stands out"
        } else if self.passes {
            "kept: its test still passes with the effects named after it in the model"
        } else {
            "kept: its test no longer passes, but without it another candidate does"
        };
        format!(
            "{} tested again {without}: p = {} (needs < {}); Allan gap {} {gap_without}, {} {gap_with}; {verdict}",
            self.effect.describe(u),
            p_text(self.p_value),
            p_text(self.p_needed),
            sig(self.gap_without, 3),
            sig(self.gap_with, 3),
        )
    }
}

/// The probe that tests the effect a step named; none for a filter or a line standing in
/// for a random term.
fn probe_of(step: &Step) -> Option<Probe> {
    Some(match step.effect {
        _ if step.stands_in => return None,
        Effect::GaussMarkov { .. } => Probe::GaussMarkov,
        Effect::Quantization { .. } => Probe::Term(Column::Q),
        Effect::BiasInstability { .. } => Probe::Term(Column::B),
        Effect::RateRandomWalk { .. } => Probe::Term(Column::K),
        Effect::RateRamp { .. } => Probe::Ramp,
        Effect::Temperature { .. } => Probe::Temperature,
        Effect::Sinusoid { .. } if step.view == View::Lines => Probe::Line,
        Effect::Sinusoid { .. } => Probe::SlowLine,
        Effect::LowPass { .. } => return None,
    })
}

/// Whether a step's effect is deterministic (a line standing in for a random term is not);
/// none for a filter.
fn kind_of(step: &Step) -> Option<bool> {
    match step.effect {
        Effect::LowPass { .. } => None,
        _ => Some(step.view.is_deterministic() && !step.stands_in),
    }
}

/// Each effect of `steps` followed by a later effect of the other kind, tested again
/// against the final model without it (module documentation), in the order they were
/// named; an effect that goes is removed from `steps` and `removal`, and the last step then
/// holds the model without it and its comparison. Returns the round of the final model
/// (`last` when nothing went) and what each check saw.
pub(super) fn named_before(
    data: &Data,
    steps: &mut Vec<Step>,
    removal: &mut Removal,
    last: Round,
) -> (Round, Vec<Rechecked>) {
    let mut round = last;
    let mut seen = Vec::new();
    // The lines that passed when tested with the rest of their naming round, and the rounds
    // so tested.
    let mut kept_together: Vec<Rechecked> = Vec::new();
    let mut rounds_tested = Vec::new();
    let mut i = 0;
    while i + 1 < steps.len() {
        let later_of_other_kind = kind_of(&steps[i]).is_some_and(|deterministic| {
            steps[i + 1..]
                .iter()
                .any(|s| kind_of(s).is_some_and(|d| d != deterministic))
        });
        let Some(probe) = probe_of(&steps[i]).filter(|_| later_of_other_kind) else {
            i += 1;
            continue;
        };
        if probe == Probe::Line && !rounds_tested.contains(&steps[i].round) {
            rounds_tested.push(steps[i].round);
            kept_together.extend(together(data, steps, i, removal, &round));
        }
        if let Some(check) = kept_together.iter().find(|c| c.effect == steps[i].effect) {
            seen.push(*check);
            i += 1;
            continue;
        }
        let Some(model) = steps.last().map(|s| s.model.clone()) else {
            break;
        };
        let unnamed = candidates::unnamed_filter(&round, data.rate_hz);
        let Some((without, less)) = candidates::without(
            data,
            (&model, removal),
            (probe, steps[i].effect),
            &round.sd_ln,
            unnamed.as_ref(),
        ) else {
            i += 1;
            continue;
        };
        // The effect's own test first: when it passes the effect stays, and the round's
        // other candidates are not needed.
        let Some(alone) = simulate_probe(data, &without, &less, probe) else {
            i += 1;
            continue;
        };
        let own = &alone.evidence[0];
        let mut check = Rechecked {
            effect: steps[i].effect,
            p_value: own.p_value,
            p_needed: own.p_needed,
            passes: own.passes,
            other_passes: None,
            gap_with: round.comparison.gap,
            gap_without: alone.comparison.gap,
            dropped: false,
            together: 1,
        };
        if check.passes {
            seen.push(check);
            i += 1;
            continue;
        }
        let again = simulate_round(data, &without, &less, None);
        let Some(own) = again.probes.iter().position(|p| *p == probe) else {
            i += 1;
            continue;
        };
        check.passes = again.evidence[own].passes;
        let other_passes = again
            .evidence
            .iter()
            .enumerate()
            .any(|(k, e)| k != own && e.passes);
        check.other_passes = Some(other_passes);
        check.p_value = again.evidence[own].p_value;
        check.p_needed = again.evidence[own].p_needed;
        check.dropped = !check.passes && !other_passes;
        let dropped = check.dropped;
        seen.push(check);
        if !dropped {
            i += 1;
            continue;
        }
        steps.remove(i);
        *removal = less;
        if let Some(s) = steps.last_mut() {
            s.model = without;
            s.comparison = again.comparison.clone();
            s.gap_after = again.comparison.gap;
        }
        round = again;
    }
    (round, seen)
}

/// The lines of `steps[i]`'s naming round tested again together (module documentation):
/// taken out of the final model (`steps`' last) and `removal` at once, the line view's round
/// simulated for that model, the line search run on the record without them, and each line
/// matched to what it finds there and judged against the round's simulations
/// ([`super::evidence::Evidence::of_another_line`]). Returns the checks of the lines that
/// pass; none when the round named a single line, or when the model without them cannot be
/// simulated.
fn together(
    data: &Data,
    steps: &[Step],
    i: usize,
    removal: &Removal,
    round: &Round,
) -> Vec<Rechecked> {
    let group: Vec<Effect> = steps
        .iter()
        .filter(|s| s.round == steps[i].round && probe_of(s) == Some(Probe::Line))
        .map(|s| s.effect)
        .collect();
    let (Some(last), true) = (steps.last(), group.len() > 1) else {
        return Vec::new();
    };
    let effects: Vec<(Probe, Effect)> = group.iter().map(|&e| (Probe::Line, e)).collect();
    let unnamed = candidates::unnamed_filter(round, data.rate_hz);
    let Some((without, less)) = candidates::without_each(
        data,
        (&last.model, removal),
        &effects,
        &round.sd_ln,
        unnamed.as_ref(),
    ) else {
        return Vec::new();
    };
    let Some(alone) = simulate_probe(data, &without, &less, Probe::Line) else {
        return Vec::new();
    };
    let judged = &alone.evidence[0];
    let (clean, _) = less.apply(data.rate, data.rate_hz, data.temperature.as_ref());
    let found: Vec<Line> = (data.lines)(&clean, data.rate_hz)
        .into_iter()
        .filter(|l| !less.near_removed(l.freq_hz))
        .collect();
    let bin_hz = data.rate_hz / data.rate.len() as f64;
    group
        .into_iter()
        .filter_map(|effect| {
            let line = found_again(&found, effect, bin_hz)?;
            let e = judged.of_another_line(line);
            e.passes.then_some(Rechecked {
                effect,
                p_value: e.p_value,
                p_needed: e.p_needed,
                passes: true,
                other_passes: None,
                gap_with: round.comparison.gap,
                gap_without: alone.comparison.gap,
                dropped: false,
                together: effects.len(),
            })
        })
        .collect()
}

/// The line of `found` nearest to a named line `effect`, when it lies within half the wider
/// of the two widths and two bins of it (the search's frequency estimates differ by a
/// fraction of a width from record to cleaned record).
fn found_again(found: &[Line], effect: Effect, bin_hz: f64) -> Option<&Line> {
    let Effect::Sinusoid {
        freq_hz, width_hz, ..
    } = effect
    else {
        return None;
    };
    let line = &found[candidates::nearest_line(found, freq_hz)?];
    let near = (line.freq_hz - freq_hz).abs() <= 0.5 * line.width_hz.max(width_hz) + 2.0 * bin_hz;
    near.then_some(line)
}

//! How a round's chosen candidate becomes the model's next effect ([`name`]): the effect
//! with its errors and intervals, the model and removal with it added, and, when several
//! stochastic terms pass together, the one that brings the simulations closest to the
//! record.
//!
//! **Why not the smallest p among stochastic terms.** A nested test of one random term is
//! judged against realisations of a model that lacks whatever else the record holds. A
//! Gauss-Markov bump the baseline took into B moves the fitted N and bends the short taus,
//! and quantization then passes with a smaller p than the process itself: on 30 records made
//! outside this code (`scripts/foreign_records.py`, 3 h at 50 Hz), quantization was named
//! first on two, once in the process's place (the process, tried next, was taken back because
//! the gap no longer shrank) and once beside it. Which term explains the record is what the
//! Allan gap measures: each passing term is added in turn, the model realised
//! ([`super::simulate::Realised`]), and the term whose gap is least is named. Only the
//! Allan comparison is simulated for the terms not chosen (a fraction of a round: no
//! candidate's statistic is computed), and only when two or more stochastic terms pass.
//!
//! Measured: on those 30 records random terms passed together on 17, p preferred flicker
//! or quantization on 11, and the gap chose the process on all 17 (gaps 0.54-1.61 against
//! 1.53-3.19); 21 of 30 named exactly right, 20 by p. On the families' 3 h study (15 kinds,
//! 150 records) they passed together on 7, the gap chose the process wherever one was
//! hidden, and every kind's count stayed as by p (flicker, which p named first on three, is
//! a baseline term); at CI size a process named by p as quantization is now named right
//! (`of_random_terms_passing_together_the_one_closest_to_the_record_is_named`).
//!
//! **A slow line beside a passing process.** Excess power at a slow frequency passes the
//! Gauss-Markov tests whether it is a process or a sinusoid: their likelihood ratio has a
//! nearly pivotal null and no frequency to search, where the slow-line view takes the
//! largest of a few hundred bins and pays for that search (on the families' slow-sinusoid
//! seed 108, a sinusoid of 5.3 cycles per record at 80 % of its amplitude: the process at
//! p = 2.2e-4, the line at 8.4e-3). So where a process passes, the slow line the
//! low-frequency view found is weighed
//! beside it, whatever its own p, and named in its place when its model lies closer to the
//! record; it then stands for a random term and, like one, is taken back unless it shrinks
//! the gap. Measured on the families' 3 h records: on seed 108 (read on the bins alone,
//! before the view read half bins) the line's gap was 0.92 against the process's 1.27; on
//! the ten Gauss-Markov records the process's is 0.62-1.25
//! against the line's 1.55-2.78, so no process becomes a line.

use super::candidates::{self, add};
use super::clean::Removal;
use super::evidence::{self, Evidence, Probe};
use super::simulate::{self, Realised, Round};
use super::{Data, Effect, Model, sinusoid_errors};
use serde::Serialize;

/// A candidate made into the model's next effect.
pub(super) struct Named {
    /// Its index in the round.
    pub index: usize,
    pub effect: Effect,
    /// The round's evidence, the named candidate's with its errors and intervals.
    pub evidence: Vec<Evidence>,
    /// The model and removal with the effect added.
    pub model: Model,
    pub removal: Removal,
    /// The rivals weighed by the Allan gap, the named one among them (empty when none
    /// were).
    pub weighed: Vec<Weighed>,
    /// Whether it was named by the gap in place of a passing random term, not by its own
    /// test: it must then shrink the gap to stay, as that term must.
    pub stands_in: bool,
    /// The Allan band the gap was weighed on, when rivals were: the next round's band.
    pub band: Option<Realised>,
}

/// A rival weighed by the Allan gap: its effect and the gap of the model with it added.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Weighed {
    pub effect: Effect,
    pub gap: f64,
}

/// The effect `chosen` names in `round` ([`super::candidates::choose`]), made into the
/// model's next step; among two or more passing stochastic candidates not `taken_back`, and
/// the slow line found beside a passing Gauss-Markov process, the one whose model lies
/// closest to the record (module documentation).
pub(super) fn name(
    data: &Data,
    model: &Model,
    removal: &Removal,
    round: &Round,
    chosen: usize,
    taken_back: &[Probe],
) -> Named {
    let stochastic = |i: usize| !round.evidence[i].view.is_deterministic();
    let mut rivals: Vec<usize> = (0..round.probes.len())
        .filter(|&i| {
            round.evidence[i].passes && stochastic(i) && !taken_back.contains(&round.probes[i])
        })
        .collect();
    let process_passes = rivals
        .iter()
        .any(|&i| round.probes[i] == Probe::GaussMarkov);
    if stochastic(chosen) && process_passes {
        rivals.extend((0..round.probes.len()).filter(|&i| {
            round.probes[i] == Probe::SlowLine
                && round.evidence[i].effect.is_some()
                && !taken_back.contains(&round.probes[i])
        }));
    }
    if !stochastic(chosen) || rivals.len() < 2 {
        return made(data, model, removal, round, chosen);
    }
    // Each rival's band is made and weighed in turn; only the closest so far is kept (the
    // first of equals), for the next round: a band's realisations are 24 records' worth, so
    // at most two bands live at once, no more than a round holds (the run's peak resident
    // memory on bench's 3 h slow-sinusoid record: 518 MB, 511 MB before the band was kept).
    let mut gaps: Vec<Weighed> = Vec::new();
    let mut closest: Option<(f64, Named)> = None;
    for i in rivals {
        let mut named = made(data, model, removal, round, i);
        let band = Realised::of(data, &named.model, &named.removal);
        let gap = band.comparison(data).gap;
        gaps.push(Weighed {
            effect: named.effect,
            gap,
        });
        if closest
            .as_ref()
            .is_none_or(|(least, _)| gap.total_cmp(least).is_lt())
        {
            named.band = Some(band);
            closest = Some((gap, named));
        }
    }
    let Some((_, mut named)) = closest else {
        unreachable!("two or more rivals were weighed")
    };
    named.stands_in = !round.evidence[named.index].passes;
    named.weighed = gaps;
    named
}

/// The further lines the round's line view passes beside the one `named` (candidate
/// `named.index` of `round`, a line), each added to the model in turn, strongest first.
///
/// **Why in one round.** A comb of lines (the ADIS16405's accelerometers carry six to ten)
/// would otherwise take a round each, and the search's [`super::MAX_STEPS`] rounds would
/// end with lines left and the filter never judged. The line search is run once more on the
/// record with the named line removed, and each line it finds is judged against the round's
/// own simulations of the strongest false line ([`Evidence::of_another_line`]); the rounds
/// after are simulated with every line named, as they would be one line at a time. A line
/// within a removed line's notch or guard, or one a named wide line's wings explain, is not
/// a line of its own (the view's own rule), and the lines are taken strongest first, so a
/// wide line is in the model before its wings are weighed.
pub(super) fn lines_beside(data: &Data, named: &Named, round: &Round) -> Vec<Named> {
    let judged = &round.evidence[named.index];
    let (clean, _) = named
        .removal
        .apply(data.rate, data.rate_hz, data.temperature.as_ref());
    let mut found = (data.lines)(&clean, data.rate_hz);
    found.sort_by(|a, b| evidence::line_surprise(b).total_cmp(&evidence::line_surprise(a)));
    let mut out: Vec<Named> = Vec::new();
    for line in found {
        let last = out.last().unwrap_or(named);
        if last.removal.near_removed(line.freq_hz)
            || evidence::in_named_wings(&line, &last.model.lines, data.rate_hz)
        {
            continue;
        }
        let judged = judged.of_another_line(&line);
        if !judged.passes {
            // The rest are weaker: their surprise no larger, their p-value no smaller.
            break;
        }
        let mut evidence = round.evidence.clone();
        evidence[named.index] = judged;
        let next = made_of(
            data,
            (&last.model, &last.removal),
            round,
            named.index,
            evidence,
        );
        out.push(next);
    }
    out
}

/// Candidate `chosen` of `round` added to `model`: its effect with the errors the round's
/// evidence lacks, and the model refitted with it.
fn made(data: &Data, model: &Model, removal: &Removal, round: &Round, chosen: usize) -> Named {
    made_of(
        data,
        (model, removal),
        round,
        chosen,
        round.evidence.clone(),
    )
}

/// [`made`] with the round's `evidence` given (a further line's in the chosen slot).
fn made_of(
    data: &Data,
    (model, removal): (&Model, &Removal),
    round: &Round,
    chosen: usize,
    mut evidence: Vec<Evidence>,
) -> Named {
    let probe = round.probes[chosen];
    let Some(mut effect) = evidence[chosen].effect else {
        unreachable!("a passing candidate has an effect")
    };
    // A named line's errors: the line search once more on the record as the round cleaned
    // it, with the errors its realisations' searches leave out. A slow line's: the
    // least-squares sandwich under the open noise model it was judged against, on the
    // record its view read.
    match (probe, effect) {
        (Probe::Line, Effect::Sinusoid { freq_hz, .. }) => {
            let (clean, _) = removal.apply(data.rate, data.rate_hz, data.temperature.as_ref());
            evidence[chosen].standard_errors =
                candidates::line_standard_errors(&clean, data.rate_hz, freq_hz);
        }
        (Probe::SlowLine, Effect::Sinusoid { freq_hz, .. }) => {
            let (clean, _) = simulate::regressors_out(data, removal).apply(
                data.rate,
                data.rate_hz,
                data.temperature.as_ref(),
            );
            evidence[chosen].standard_errors = sinusoid_errors::sinusoid_standard_errors(
                &clean,
                data.rate_hz,
                freq_hz,
                &round.open,
                model.low_pass.as_ref(),
            );
        }
        // A Gauss-Markov term's: its maximum-likelihood parameters in the cosine view,
        // whichever view named it, with their profile intervals. Where that view's profile
        // leaves sigma unbounded below (it gives the term's power to flicker and the random
        // walk, free beside it), it does not resolve the term, and the estimate of the view
        // that named it stands, without intervals: a process named by its Allan misfit drop
        // on a filtered 3 h record was otherwise named at sigma = 3.6e-9 (interval [0,
        // 1.8e-5]), and the model refitted with it put sigma at 1.7e-5.
        (Probe::GaussMarkov, Effect::GaussMarkov { .. }) => {
            let resolved = simulate::gauss_markov_fit(data, model, removal)
                .filter(|fit| fit.sigma_interval.0.is_some_and(|low| low > 0.0));
            if let Some(fit) = resolved {
                effect = Effect::GaussMarkov {
                    tau_c: fit.tau_c,
                    sigma: fit.sigma,
                };
                let e = &mut evidence[chosen];
                e.effect = Some(effect);
                e.intervals = [("tau_c", fit.tau_c_interval), ("sigma", fit.sigma_interval)]
                    .into_iter()
                    .collect();
            }
        }
        _ => {}
    }
    let mut removal = removal.clone();
    let unnamed = candidates::unnamed_filter(round, data.rate_hz);
    let model = add(
        data,
        model,
        &mut removal,
        (probe, effect),
        &round.sd_ln,
        unnamed.as_ref(),
    );
    Named {
        index: chosen,
        effect,
        evidence,
        model,
        removal,
        weighed: Vec::new(),
        stands_in: false,
        band: None,
    }
}

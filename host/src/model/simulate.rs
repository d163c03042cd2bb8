//! A round's simulations: the current model realised many times, its Allan band compared
//! with the record ([`compare`]), and every candidate's statistic on the record and on each
//! realisation ([`simulate_round`]).

use super::candidates::{open_noise, probes};
use super::clean::{self, Removal};
use super::evidence::{self, Context, Evidence, Probe, View};
use super::slow_view::SlowView;
use super::{
    Band, Comparison, Data, Effect, GAUSS_MARKOV_MIN_SAMPLES, Line, MONTE_CARLO_EXCEEDANCES, Model,
    REFINE, REGRESSION_DRAWS, Range, UNSURE_ABOVE, UNSURE_BELOW, Z_DISAGREE, cosine, gls, refit,
    regression, spectrum,
};
use crate::analysis::Deviation;
use crate::analysis::low_pass::{LowPass, LowPassSource};
use crate::sim::noise::{AxisNoise, NoiseTerms, add_line};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// The most samples a round keeps of its realisations between its two passes over them
/// (the Allan band, then the candidates' statistics): 256 MiB, enough for 24 realisations
/// of 3 h at 100 Hz (198 MiB). Longer records synthesise each realisation again, at the
/// cost of a third of the round's synthesis, rather than hold many times their own size.
const KEPT_REALISATION_SAMPLES: usize = 1 << 25;

/// One round: the current model simulated, compared with the record, and every candidate's
/// evidence.
#[derive(Clone)]
pub(super) struct Round {
    pub(super) comparison: Comparison,
    /// Standard deviation of ln AVAR per tau over the realisations (the refits' weights).
    pub(super) sd_ln: Vec<f64>,
    pub(super) probes: Vec<Probe>,
    pub(super) evidence: Vec<Evidence>,
    /// The open noise model the regressors and the slow line are judged against.
    pub(super) open: NoiseTerms,
}

/// The removal the slow line and the regressor candidates are judged under: the ramp and
/// the temperature (when the record has a channel) taken out with what is named.
pub(super) fn regressors_out(data: &Data, removal: &Removal) -> Removal {
    Removal {
        ramp: true,
        temperature: data.temperature.is_some(),
        ..removal.clone()
    }
}

/// `n` samples of the stochastic `terms`, realisation `i`; the white noise through
/// `low_pass` when there is one; plus the named `lines`, each at its estimated amplitude and
/// width with a random phase. A line is simulated rather than only notched out of both
/// series because a notch leaves a wide line's wings (a Lorentzian holds a fifth of its
/// power beyond +-1.5 widths): in the record and in the realisations alike, so they are not
/// taken for quantization noise or a new line.
pub(super) fn realise(
    data: &Data,
    terms: &NoiseTerms,
    low_pass: Option<&LowPass>,
    lines: &[Line],
    i: usize,
) -> Vec<f64> {
    let n = data.rate.len();
    let (mut rng, duration, noise) = seeded_noise(data, terms, low_pass, i);
    let mut generator = AxisNoise::new(noise, data.rate_hz, duration, &mut rng);
    let mut y = generator.take(n, &mut rng);
    if let Some(lp) = low_pass {
        let white = lp.white_through(terms.n, n, &mut rng);
        y.iter_mut().zip(white).for_each(|(a, b)| *a += b);
    }
    for l in lines {
        add_line(
            &mut y,
            data.rate_hz,
            l.freq_hz,
            l.width_hz,
            l.amplitude,
            &mut rng,
        );
    }
    y
}

/// Realisation `i` of the stochastic `terms` through `low_pass` as [`realise`] makes it
/// without lines, read as means of blocks of `block` samples and synthesised as such
/// ([`AxisNoise::block_means`], [`LowPass::white_through_block_means`]): what the slow-line
/// view reads ([`super::slow_view`]).
fn realise_block_means(
    data: &Data,
    terms: &NoiseTerms,
    low_pass: Option<&LowPass>,
    block: usize,
    i: usize,
) -> Vec<f64> {
    let (mut rng, duration, noise) = seeded_noise(data, terms, low_pass, i);
    let samples = data.rate.len() / block.max(1);
    let mut generator = AxisNoise::block_means(noise, data.rate_hz, duration, block, &mut rng);
    let mut y = generator.take(samples, &mut rng);
    if let Some(lp) = low_pass {
        let white = lp.white_through_block_means(terms.n, block, samples, &mut rng);
        y.iter_mut().zip(white).for_each(|(a, b)| *a += b);
    }
    y
}

/// Realisation `i`'s generator of random numbers, the record's duration (s) and the part
/// of `terms` the noise generator makes: no ramp and no sinusoid (the deterministic effects
/// are the record's own), and no white noise where `low_pass` filters it (drawn through the
/// filter instead).
fn seeded_noise(
    data: &Data,
    terms: &NoiseTerms,
    low_pass: Option<&LowPass>,
    i: usize,
) -> (ChaCha8Rng, f64, NoiseTerms) {
    let rng = ChaCha8Rng::seed_from_u64(data.settings.seed.wrapping_add(i as u64));
    let duration = data.rate.len() as f64 / data.rate_hz;
    let noise = NoiseTerms {
        r: 0.0,
        sinusoid: None,
        n: if low_pass.is_some() { 0.0 } else { terms.n },
        ..*terms
    };
    (rng, duration, noise)
}

/// How a round realises a model: its noise with the named lines, carrying the deterministic
/// effects as estimated from the record.
struct Realisations<'a> {
    data: &'a Data<'a>,
    model: &'a Model,
    /// The named lines the realisations carry (see [`realise`]); slow tones are regressors.
    lines: Vec<Line>,
    /// The record less its cleaned self: the regressors' estimated signal.
    deterministic: Vec<f64>,
}

impl<'a> Realisations<'a> {
    fn of(data: &'a Data<'a>, model: &'a Model, removal: &Removal) -> Realisations<'a> {
        // The regressors (slow tones among them) as estimated jointly from the record; the
        // notched lines are simulated (see `realise`).
        let regressors = Removal {
            notches: Vec::new(),
            ..removal.clone()
        };
        let lines = model
            .lines
            .iter()
            .filter(|l| !removal.is_tone(l.freq_hz))
            .copied()
            .collect();
        let (clean, _) = regressors.apply(data.rate, data.rate_hz, data.temperature.as_ref());
        let deterministic = data.rate.iter().zip(&clean).map(|(x, c)| x - c).collect();
        Realisations {
            data,
            model,
            lines,
            deterministic,
        }
    }

    /// Realisation `i` of the stochastic `terms` with the model's filter and lines.
    fn series(&self, terms: &NoiseTerms, i: usize) -> Vec<f64> {
        let low_pass = self.model.low_pass.as_ref();
        realise(self.data, terms, low_pass, &self.lines, i)
    }

    /// Realisation `i` of the stochastic `terms` as `view` reads it: synthesised as block
    /// means where the model has no lines and the view notches nothing, else synthesised at
    /// the record's rate and reduced.
    fn reduced(&self, terms: &NoiseTerms, i: usize, view: &SlowView) -> Vec<f64> {
        if self.lines.is_empty() && !view.notches() {
            let low_pass = self.model.low_pass.as_ref();
            realise_block_means(self.data, terms, low_pass, view.block(), i)
        } else {
            view.reduce(&self.series(terms, i))
        }
    }

    /// The ln ADEV of realisations `0..r` with the deterministic effects added, on the
    /// record's averaging factors, and each realisation itself when `keep`.
    fn band(&self, r: usize, keep: bool) -> (Vec<Vec<f64>>, Vec<Option<Vec<f64>>>) {
        let data = self.data;
        (0..r)
            .into_par_iter()
            .map(|i| {
                let s = self.series(&self.model.terms, i);
                let with: Vec<f64> = s
                    .iter()
                    .zip(&self.deterministic)
                    .map(|(a, b)| a + b)
                    .collect();
                let log = evidence::allan_avar(with, data.rate_hz, &data.measured.m)
                    .iter()
                    .map(|v| 0.5 * v.max(f64::MIN_POSITIVE).ln())
                    .collect();
                (log, keep.then_some(s))
            })
            .unzip()
    }
}

/// A model's Allan band: the ln ADEV of its realisations `0..r` (each carrying the named
/// deterministic effects as estimated from the record) on the record's averaging factors,
/// and the realisations themselves up to [`KEPT_REALISATION_SAMPLES`], for the model and
/// removal they were made with.
pub(super) struct Realised {
    model: Model,
    removal: Removal,
    logs: Vec<Vec<f64>>,
    kept: Vec<Option<Vec<f64>>>,
}

impl Realised {
    pub(super) fn of(data: &Data, model: &Model, removal: &Removal) -> Realised {
        Realised::by(&Realisations::of(data, model, removal), removal)
    }

    /// The band `realisations` make, they having been made for `removal`.
    fn by(realisations: &Realisations, removal: &Removal) -> Realised {
        let data = realisations.data;
        let r = data.settings.realisations.max(2);
        let keep = r.saturating_mul(data.rate.len()) <= KEPT_REALISATION_SAMPLES;
        let (logs, kept) = realisations.band(r, keep);
        Realised {
            model: realisations.model.clone(),
            removal: removal.clone(),
            logs,
            kept,
        }
    }

    /// The record against the band (the Allan comparison of a round, without the
    /// candidates' statistics): what choosing among stochastic candidates compares.
    pub(super) fn comparison(&self, data: &Data) -> Comparison {
        compare(&data.measured, &self.logs)
    }
}

/// Simulate the model twice over the same seeds: first its Allan band ([`Realised`]), whose
/// spread weights the refits, taken from `band` when that was made for this model and
/// removal (the rival the naming chose: the same seeds give the same realisations); then
/// every candidate's statistic, on the record and on each realisation (kept from the first
/// pass up to [`KEPT_REALISATION_SAMPLES`]).
pub(super) fn simulate_round(
    data: &Data,
    model: &Model,
    removal: &Removal,
    band: Option<Realised>,
) -> Round {
    simulate(data, model, removal, None, band)
}

/// The round of [`simulate_round`] with `probe` alone judged, at the threshold it has among
/// all the round's candidates; `None` when it is not one of them. What it shows of `probe`
/// is what the whole round shows, except where the whole round names a deterministic effect
/// and so leaves a random term's unsure verdict unrefined (a recheck keeps the effect then
/// either way: another candidate passes).
pub(super) fn simulate_probe(
    data: &Data,
    model: &Model,
    removal: &Removal,
    probe: Probe,
) -> Option<Round> {
    probes(data, model, removal)
        .contains(&probe)
        .then(|| simulate(data, model, removal, Some(probe), None))
}

/// A round judging every candidate, or `only` that one at the threshold it has among all.
fn simulate(
    data: &Data,
    model: &Model,
    removal: &Removal,
    only: Option<Probe>,
    band: Option<Realised>,
) -> Round {
    let every = probes(data, model, removal);
    let candidates = every.len();
    let probes: Vec<Probe> = match only {
        Some(p) => every.into_iter().filter(|q| *q == p).collect(),
        None => every,
    };
    let tau0 = 1.0 / data.rate_hz;
    let longest = data.measured.tau.last().copied().unwrap_or(tau0);
    let m = &data.measured.m;
    let r = data.settings.realisations.max(2);
    let realisations = Realisations::of(data, model, removal);
    let band = band
        .filter(|b| b.model == *model && b.removal == *removal && b.logs.len() == r)
        .unwrap_or_else(|| Realised::by(&realisations, removal));
    let comparison = band.comparison(data);
    let kept = band.kept;
    let realise = |terms: &NoiseTerms, i: usize| realisations.series(terms, i);
    let sd_ln: Vec<f64> = comparison.band.std_log.iter().map(|s| 2.0 * s).collect();
    let sd_ln = refit::beyond_fitted_filter(&sd_ln, &data.measured.tau, model.low_pass.as_ref());
    let stochastic = model.stochastic();
    let white = |tau: f64| model.white_shape(tau);
    let filter_alternatives = filter_alternatives(model.low_pass.as_ref());
    let background = |f: f64| model.one_sided_psd(f, tau0);
    let n = data.rate.len();
    let temperature = data.temperature.as_ref();
    let cleaner = clean::Cleaner::new(removal, n, data.rate_hz, temperature);
    let ctx = Context {
        rate_hz: data.rate_hz,
        m,
        tau: &data.measured.tau,
        sd_ln: &sd_ln,
        temperature,
        cleaner: &cleaner,
        terms: &stochastic,
        white: &white,
        low_pass: model.low_pass.as_ref(),
        filter_alternatives: &filter_alternatives,
        gauss_markov_range: (GAUSS_MARKOV_MIN_SAMPLES * tau0, longest / 2.0),
        lines: data.lines,
        named_lines: &model.lines,
        background: &background,
    };
    let on_sims: Vec<Probe> = probes
        .iter()
        .copied()
        .filter(|p| !matches!(p, Probe::Ramp | Probe::Temperature | Probe::SlowLine))
        .collect();
    let measured = evidence::statistics(data.rate, &on_sims, &ctx, true);
    // The statistics of `of` on realisations `seeds` of the model: the first pass's when
    // kept, else synthesised again from their seeds.
    let on_realisations = |seeds: std::ops::Range<usize>, of: &[Probe]| -> Vec<Vec<f64>> {
        seeds
            .into_par_iter()
            .map(|i| {
                let series = match kept.get(i) {
                    Some(Some(s)) => std::borrow::Cow::Borrowed(s),
                    _ => std::borrow::Cow::Owned(realise(&model.terms, i)),
                };
                evidence::statistics(&series, of, &ctx, false)
                    .into_iter()
                    .map(|(v, _)| v)
                    .collect()
            })
            .collect()
    };
    let sims = if on_sims.is_empty() {
        vec![Vec::new(); r]
    } else {
        on_realisations(0..r, &on_sims)
    };
    // The alternative's noise model has every IEEE-952 random term free: a baseline that put
    // K at 0 (a short record, an absorbed effect) must not make the test's noise too small.
    let columns = evidence::with_random_walks(&refit::columns_of(&stochastic));
    // The slow line is looked for with the regressor candidates out, against realisations of
    // the open noise model: a temperature cycle is not a slow line, and neither effect's
    // power, absorbed into the baseline's K, widens the spread the other is judged against.
    let regressors_out = regressors_out(data, removal);
    let slow_block = spectrum::view_block(data.rate_hz, n, ctx.low_pass);
    let slow_temperature = temperature.map(|t| t.block_means(slow_block));
    let slow_view = SlowView::new(
        &regressors_out,
        n,
        data.rate_hz,
        slow_block,
        slow_temperature.as_ref(),
        ctx.low_pass,
    );
    let slow = slow_view.statistic(&slow_view.reduce(data.rate), true);
    let slow_hz = match slow.1 {
        Some(Effect::Sinusoid { freq_hz, .. }) => Some(freq_hz),
        _ => None,
    };
    let open = open_noise(data, &regressors_out, slow_hz, &ctx, &columns);
    // The slow line's statistic on realisations `seeds` of the open noise model.
    let slow_on = |seeds: std::ops::Range<usize>| -> Vec<f64> {
        seeds
            .into_par_iter()
            .map(|i| {
                slow_view
                    .statistic(&realisations.reduced(&open, i, &slow_view), false)
                    .0
            })
            .collect()
    };
    let slow_sims = if probes.contains(&Probe::SlowLine) {
        slow_on(0..r)
    } else {
        Vec::new()
    };
    let gls = gls::Estimator::new(&open, data.rate_hz, data.rate.len());
    let setup = regression::Setup {
        view: &ctx,
        gls: &gls,
        draws: REGRESSION_DRAWS,
        seed: data.settings.seed,
        candidates,
        monte_carlo: false,
    };
    // A candidate's evidence from its simulated values (`on_sims` probes and the slow line)
    // or its own bootstrap of `draws` series (the regressors).
    let judge =
        |p: Probe, simulated: &[f64], draws: usize| match on_sims.iter().position(|q| *q == p) {
            Some(j) if p == Probe::Line => Evidence::with_p(
                p.name(),
                p.view(),
                measured[j],
                simulated,
                evidence::line_p_value(measured[j].0, simulated),
                candidates,
            ),
            Some(j) => Evidence::new(p.name(), p.view(), measured[j], simulated, candidates),
            // A maximum over bins: its tail is Gumbel, not a scaled chi-square.
            None if p == Probe::SlowLine => Evidence::with_p(
                p.name(),
                p.view(),
                slow,
                simulated,
                spectrum::gumbel_p_value(slow.0, simulated),
                candidates,
            ),
            None => regression::test(p, data.rate, &regression::Setup { draws, ..setup }),
        };
    let simulated_of = |p: Probe| -> Vec<f64> {
        match on_sims.iter().position(|q| *q == p) {
            Some(j) => sims.iter().map(|s| s[j]).collect(),
            None if p == Probe::SlowLine => slow_sims.clone(),
            None => Vec::new(),
        }
    };
    let mut evidence: Vec<Evidence> = probes
        .iter()
        .map(|&p| judge(p, &simulated_of(p), REGRESSION_DRAWS))
        .collect();
    // Verdicts that rest on the tail of a few simulations are simulated again, REFINE times
    // as often (the same seeds first, so the first simulations are kept), when they can
    // change what the round names: the deterministic candidates' first. A line or a
    // regressor that passes is named before any random term and stays whatever the gap
    // does (`View::must_close_gap`), so the random terms' verdicts are then left on the
    // round's own simulations (their `simulations` say so).
    let regressor = |p: Probe| matches!(p, Probe::Ramp | Probe::Temperature);
    let unsure_of = |evidence: &[Evidence], deterministic: bool| -> Vec<usize> {
        (0..probes.len())
            .filter(|&j| {
                !regressor(probes[j])
                    && probes[j].view().is_deterministic() == deterministic
                    && unsure(&evidence[j])
            })
            .collect()
    };
    let refine = |evidence: &mut [Evidence], unsure: Vec<usize>| {
        if unsure.is_empty() {
            return;
        }
        let more = r..REFINE * r;
        let again: Vec<Probe> = unsure
            .iter()
            .map(|&j| probes[j])
            .filter(|p| on_sims.contains(p))
            .collect();
        let extra = if again.is_empty() {
            Vec::new()
        } else {
            on_realisations(more.clone(), &again)
        };
        let slow_extra = if unsure.iter().any(|&j| probes[j] == Probe::SlowLine) {
            slow_on(more)
        } else {
            Vec::new()
        };
        for j in unsure {
            let p = probes[j];
            let mut simulated = simulated_of(p);
            match again.iter().position(|q| *q == p) {
                Some(k) => simulated.extend(extra.iter().map(|e| e[k])),
                None => simulated.extend(&slow_extra),
            }
            evidence[j] = judge(p, &simulated, REFINE * REGRESSION_DRAWS);
        }
    };
    let deterministic = unsure_of(&evidence, true);
    refine(&mut evidence, deterministic);
    // The regressors' draws are cheap: a verdict still near the line is decided on enough of
    // them for an exact Monte Carlo p-value (see `MONTE_CARLO_EXCEEDANCES`).
    for (j, &p) in probes.iter().enumerate() {
        if regressor(p) && near_the_line(&evidence[j]) {
            let draws = monte_carlo_draws(evidence[j].p_needed);
            let decisive = regression::Setup {
                draws,
                monte_carlo: true,
                ..setup
            };
            evidence[j] = regression::test(p, data.rate, &decisive);
        }
    }
    let signal_named = evidence
        .iter()
        .any(|e| e.passes && e.view.is_deterministic() && !e.view.must_close_gap());
    if !signal_named {
        let random = unsure_of(&evidence, false);
        refine(&mut evidence, random);
    }
    if let Some(j) = probes.iter().position(|p| *p == Probe::GaussMarkov) {
        let allan = evidence[j].clone();
        // The cosine view's unsure verdict is refined only where it can decide the
        // candidate: not when the Allan view passes on its own.
        let refined = !signal_named && !evidence::allan_passes_alone(&allan);
        if let Some(cosine) = cosine_evidence(data, model, removal, candidates, refined) {
            evidence[j] = evidence::gauss_markov_of_two(allan, cosine);
        }
    }
    Round {
        comparison,
        sd_ln,
        probes,
        evidence,
        open,
    }
}

/// The Gauss-Markov candidate's evidence in the cosine-transform view ([`cosine`]): the
/// record with the named lines notched, the named regressors as fixed effects, under the
/// model's white noise, quantization and filter; judged again on [`REFINE`] times as many
/// draws when unsure and `refined`.
fn cosine_evidence(
    data: &Data,
    model: &Model,
    removal: &Removal,
    candidates: usize,
    refined: bool,
) -> Option<Evidence> {
    let (view, start) = cosine_view(data, model, removal)?;
    let seed = data.settings.seed;
    let judged = |verdict: &cosine::Verdict| {
        let effect = (verdict.sigma > 0.0).then_some(Effect::GaussMarkov {
            tau_c: verdict.tau_c,
            sigma: verdict.sigma,
        });
        Evidence::new(
            Probe::GaussMarkov.name(),
            View::CosineLikelihood,
            (verdict.statistic, effect),
            &verdict.null,
            candidates,
        )
    };
    let verdict = view.test(start, REGRESSION_DRAWS, seed);
    let first = judged(&verdict);
    Some(if refined && unsure(&first) {
        judged(&view.extend(verdict, REFINE * REGRESSION_DRAWS, seed))
    } else {
        first
    })
}

/// The cosine-transform view of the record (the named lines notched, the named regressors
/// as fixed effects, under the model's white noise, quantization and filter), and the
/// model's flicker and random-walk levels (B^2, K^2) its searches start from.
fn cosine_view(
    data: &Data,
    model: &Model,
    removal: &Removal,
) -> Option<(cosine::CosineLikelihood, [f64; 2])> {
    let notched = if removal.notches.is_empty() {
        std::borrow::Cow::Borrowed(data.rate)
    } else {
        std::borrow::Cow::Owned(clean::notch(data.rate, data.rate_hz, &removal.notches))
    };
    let regressors = removal.design(data.rate.len(), data.rate_hz, data.temperature.as_ref());
    let terms = model.stochastic();
    let view = cosine::CosineLikelihood::new(
        &notched,
        data.rate_hz,
        &terms,
        model.low_pass.as_ref(),
        &regressors,
    )?;
    Some((view, [terms.b * terms.b, terms.k * terms.k]))
}

/// A Gauss-Markov term's maximum-likelihood fit and profile intervals in the cosine view of
/// the record under `model` and `removal` ([`super::gauss_markov_fit`]).
pub(super) fn gauss_markov_fit(
    data: &Data,
    model: &Model,
    removal: &Removal,
) -> Option<super::gauss_markov_fit::GaussMarkovFit> {
    let (view, start) = cosine_view(data, model, removal)?;
    view.gauss_markov_fit(start)
}

/// Whether a candidate's p-value lies near the naming threshold, from [`UNSURE_BELOW`] times
/// below it to [`UNSURE_ABOVE`] times above, whatever the largest simulated statistic.
fn near_the_line(e: &Evidence) -> bool {
    e.effect.is_some()
        && e.p_value < UNSURE_ABOVE * e.p_needed
        && e.p_value > e.p_needed / UNSURE_BELOW
}

/// Draws that put the threshold `p_needed` [`MONTE_CARLO_EXCEEDANCES`] draws deep in the
/// Monte Carlo null's tail, at least [`REFINE`] times [`REGRESSION_DRAWS`].
fn monte_carlo_draws(p_needed: f64) -> usize {
    let deep = (MONTE_CARLO_EXCEEDANCES / p_needed).ceil() as usize;
    deep.saturating_sub(1).max(REFINE * REGRESSION_DRAWS)
}

/// Whether a candidate's verdict rests on the tail of too few simulations (see
/// [`UNSURE_BELOW`]).
fn unsure(e: &Evidence) -> bool {
    e.statistic > e.sim_max && near_the_line(e)
}

/// The measured curve against the realisations' ln ADEV.
pub(super) fn compare(measured: &Deviation, logs: &[Vec<f64>]) -> Comparison {
    let taus = measured.tau.len();
    let r = logs.len().max(2) as f64;
    let mut mean_log = vec![0.0; taus];
    let mut std_log = vec![0.0; taus];
    for j in 0..taus {
        let mean = logs.iter().map(|l| l[j]).sum::<f64>() / r;
        let var = logs.iter().map(|l| (l[j] - mean).powi(2)).sum::<f64>() / (r - 1.0);
        mean_log[j] = mean;
        std_log[j] = var.sqrt();
    }
    let z: Vec<f64> = measured
        .dev
        .iter()
        .zip(&mean_log)
        .zip(&std_log)
        .map(|((d, m), s)| (d.max(f64::MIN_POSITIVE).ln() - m) / s.max(1e-6))
        .collect();
    let gap = (z.iter().map(|v| v * v).sum::<f64>() / z.len().max(1) as f64).sqrt();
    Comparison {
        gap,
        disagreeing: ranges(&measured.tau, &z),
        z,
        band: Band {
            tau: measured.tau.clone(),
            mean_log,
            std_log,
        },
    }
}

/// Contiguous runs of |z| > [`Z_DISAGREE`] with one sign.
pub(super) fn ranges(tau: &[f64], z: &[f64]) -> Vec<Range> {
    let mut out: Vec<Range> = Vec::new();
    let mut open = false;
    for (t, v) in tau.iter().zip(z) {
        let sign = if *v > Z_DISAGREE {
            1
        } else if *v < -Z_DISAGREE {
            -1
        } else {
            0
        };
        match out.last_mut() {
            Some(r) if open && r.sign == sign => r.tau_hi = *t,
            _ if sign != 0 => {
                out.push(Range {
                    tau_lo: *t,
                    tau_hi: *t,
                    sign,
                });
                open = true;
                continue;
            }
            _ => {}
        }
        if sign == 0 {
            open = false;
        }
    }
    out
}

/// A fitted filter at cutoffs one and two of its interval's half-widths either side (the
/// interval is the detection's 68.3 % one), of its own shape, and the shapes the spectrum
/// fits as well at their own cutoffs ([`LowPass::comparable`]); none for a filter from the
/// settings.
fn filter_alternatives(low_pass: Option<&LowPass>) -> Vec<LowPass> {
    let Some((lp, shape)) = low_pass
        .filter(|lp| lp.source == LowPassSource::Fitted)
        .and_then(|lp| Some((lp, lp.shape?)))
    else {
        return Vec::new();
    };
    let (below, above) = (
        lp.cutoff_hz - lp.cutoff_lo_hz,
        lp.cutoff_hi_hz - lp.cutoff_hz,
    );
    [-2.0 * below, -below, above, 2.0 * above]
        .iter()
        .filter(|step| step.abs() > 0.0)
        .filter_map(|step| LowPass::generic(shape, lp.cutoff_hz + step, lp.rate_hz).ok())
        .chain(
            lp.comparable
                .iter()
                .filter_map(|&(other, cutoff)| LowPass::generic(other, cutoff, lp.rate_hz).ok()),
        )
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::evidence::{Evidence, View};
    use super::super::{Effect, REFINE, REGRESSION_DRAWS};
    use super::{monte_carlo_draws, ranges, unsure};

    /// Evidence for a ramp whose statistic `statistic` is judged against `simulated` values.
    fn ramp(statistic: f64, simulated: &[f64]) -> Evidence {
        let effect = Some(Effect::RateRamp { slope: 1e-9 });
        Evidence::new(
            "rate_ramp",
            View::RegressionOnTime,
            (statistic, effect),
            simulated,
            8,
        )
    }

    #[test]
    fn only_verdicts_near_the_line_are_unsure() {
        // Bootstrap-sized draws of a chi-square with one degree of freedom: mean 1, sd 1.4.
        let draws: Vec<f64> = (0..REGRESSION_DRAWS)
            .map(|i| {
                let u = (i as f64 + 0.5) / REGRESSION_DRAWS as f64;
                let z = statrs::distribution::ContinuousCDF::inverse_cdf(
                    &statrs::distribution::Normal::standard(),
                    0.5 + u / 2.0,
                );
                z * z
            })
            .collect();
        let max = draws.iter().copied().fold(0.0, f64::max);
        // p_needed = 0.05 / 8 = 6.25e-3. A statistic of 9 gives p near 3e-3: passes, unsure.
        let near = ramp(9.0, &draws);
        assert!(near.passes && near.statistic > max, "{near:?}");
        assert!(unsure(&near), "{near:?}");
        // Far beyond every draw: certain.
        let far = ramp(200.0, &draws);
        assert!(
            far.passes && far.p_value < far.p_needed / 1e6 && !unsure(&far),
            "{far:?}"
        );
        // Not above every draw: the rule cannot name it whatever more draws say.
        let inside = ramp(max * 0.99, &draws);
        assert!(!inside.passes && !unsure(&inside), "{inside:?}");
        // Above every draw, p between the threshold and three times it: unsure.
        let above = ramp(7.0, &draws);
        assert!(
            !above.passes && above.p_value < 3.0 * above.p_needed && unsure(&above),
            "{above:?}"
        );
    }

    #[test]
    fn a_monte_carlo_verdict_rests_on_the_count_beyond_the_statistic() {
        // Eight candidates: p_needed = 6.25e-3, 10 / p_needed = 1600 draws in all.
        let draws = monte_carlo_draws(0.05 / 8.0);
        assert_eq!(draws, 1599);
        let simulated: Vec<f64> = (0..draws).map(|i| i as f64).collect();
        let judged = |statistic: f64| {
            Evidence::monte_carlo(
                "rate_ramp",
                View::RegressionOnTime,
                (statistic, Some(Effect::RateRamp { slope: 1e-9 })),
                &simulated,
                8,
            )
        };
        // Five draws at or beyond 1593.5: p = 6 / 1600, below the threshold though the
        // statistic is not above every draw.
        let five = judged(1593.5);
        assert_eq!(five.p_value, 6.0 / 1600.0);
        assert!(five.passes && five.statistic < five.sim_max, "{five:?}");
        // Ten beyond: p = 11 / 1600 = 6.9e-3, above it.
        let ten = judged(1588.5);
        assert_eq!(ten.p_value, 11.0 / 1600.0);
        assert!(!ten.passes, "{ten:?}");
        // The stop line states that rule.
        let stop = super::super::Stop::NothingStandsOut { best: Some(ten) }.to_string();
        assert!(
            stop.contains("the Monte Carlo count") && !stop.contains("above every"),
            "{stop}"
        );
        // Beyond every draw: 1 / 1600, a bound. It is ranked on the draws' tail fit, as
        // the other views' verdicts are; one with draws beyond it keeps its count.
        let beyond = judged(1e4);
        assert_eq!(beyond.p_value, 1.0 / 1600.0);
        let tail = super::evidence::scaled_chi_square_p(1e4, &simulated);
        assert!(tail < 1e-6 && beyond.ranking_p() == tail, "{beyond:?}");
        assert_eq!(five.ranking_p(), five.p_value);
        // Few candidates still draw at least as many as the refinement of the other views.
        assert_eq!(monte_carlo_draws(0.1), REFINE * REGRESSION_DRAWS);
    }

    #[test]
    fn ranges_group_runs() {
        let tau = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let z = [0.0, 3.0, 2.5, -3.0, 0.0, 2.1];
        let r = ranges(&tau, &z);
        assert_eq!(r.len(), 3);
        assert_eq!((r[0].tau_lo, r[0].tau_hi, r[0].sign), (2.0, 3.0, 1));
        assert_eq!((r[1].tau_lo, r[1].tau_hi, r[1].sign), (4.0, 4.0, -1));
        assert_eq!((r[2].tau_lo, r[2].tau_hi, r[2].sign), (6.0, 6.0, 1));
    }
}

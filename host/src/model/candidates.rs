//! The candidates of a round: which effects the model can still take ([`probes`]), the one
//! to name ([`choose`]), the model with it added ([`add`]), and the round's open noise model
//! ([`open_noise`]) that the regressors and the slow line are judged against.

use super::clean::{Notch, Removal, Tone};
use super::evidence::{self, Context, Probe};
use super::refit::{self, Column};
use super::simulate::Round;
use super::{Data, Effect, Line, Model, restore, spectrum};
use crate::analysis::lines::{self, LineOptions};
use crate::analysis::low_pass::{LowPass, LowPassSource};
use crate::analysis::pipeline::LowPassChoice;
use crate::sim::noise::{NoiseTerms, Sinusoid};
use std::collections::BTreeMap;

/// Lines as slow as [`LINE_MIN_CYCLES`] per record are searched: a period of a fifth of the
/// record is five cycles, and such a slow sinusoid is one of the effects to name.
pub const LINE_MIN_CYCLES: f64 = 4.0;

/// The line search as the workflow's line view runs it: [`lines::detect`] with its default
/// family-wise false-alarm probability from [`LINE_MIN_CYCLES`] cycles per record;
/// `standard_errors` only where they are shown (the record's named line), not on every
/// realisation.
fn line_options(standard_errors: bool) -> LineOptions {
    LineOptions {
        min_cycles: LINE_MIN_CYCLES,
        standard_errors,
        ..LineOptions::default()
    }
}

/// The spectral lines of a cleaned series, as the workflow's line view sees them.
pub(super) fn detect_lines(series: &[f64], rate_hz: f64) -> Vec<Line> {
    lines::detect(series, rate_hz, &line_options(false))
        .map(|found| {
            found
                .into_iter()
                .map(|l| Line {
                    freq_hz: l.freq_hz,
                    amplitude: l.amplitude,
                    width_hz: l.width_hz,
                    statistic: l.statistic,
                    p_value: l.p_value,
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The standard errors ([`lines::Line::standard_errors`]) of the line the view found at
/// `freq_hz` in `series` (the record cleaned as the round saw it), by parameter name: the
/// same search, with its errors. Empty when the search finds no line within a bin of it.
pub(super) fn line_standard_errors(
    series: &[f64],
    rate_hz: f64,
    freq_hz: f64,
) -> BTreeMap<&'static str, f64> {
    let found = lines::detect(series, rate_hz, &line_options(true)).unwrap_or_default();
    let bin = rate_hz / series.len().max(1) as f64;
    let same = found
        .iter()
        .filter(|l| (l.freq_hz - freq_hz).abs() <= bin)
        .min_by(|a, b| {
            (a.freq_hz - freq_hz)
                .abs()
                .total_cmp(&(b.freq_hz - freq_hz).abs())
        });
    let Some(line) = same else {
        return BTreeMap::new();
    };
    let e = line.standard_errors;
    [
        ("freq_hz", Some(e.freq_hz)),
        ("amplitude", Some(e.amplitude)),
        ("width_hz", e.width_hz),
    ]
    .into_iter()
    .filter_map(|(name, sd)| sd.filter(|v| v.is_finite()).map(|v| (name, v)))
    .collect()
}

/// The candidate to name, leaving out those `taken_back` in this round: a passing
/// temperature coupling first, then the smallest p-value ([`evidence::Evidence::ranking_p`];
/// the largest z, which is clamped where p underflows) among the other passing deterministic
/// candidates, else among the passing stochastic ones (which [`super::naming::name`] then
/// weighs against each other by the Allan gap). P-values below [`evidence::LEAST_P`]
/// are not told apart (a strong line and a strong roll-off both reach it), and ties go to
/// the earlier probe: lines first, whose removal can change what the roll-off and the
/// regressions see (a roll-off fitted with a strong line beyond it put the cutoff below the
/// line).
///
/// Why the coupling first: it has a measured cause, and a rate that follows the temperature
/// carries the temperature's own cycles as slow lines, which the line detectors see as
/// strongly as the regression does (a line's statistic is often the larger: it is judged
/// against the open model with the coupling removed). Named first, the coupling takes those
/// lines with it; a line at another frequency stays in the cleaned record and is named in
/// the next round. A slow sinusoid does not make a coupling pass: one at least
/// two periodogram bins from the temperature's cycles is nearly
/// orthogonal to the temperature and its derivative, and the regression's noise model is
/// fitted with the strongest slow line removed (`open_noise`).
pub(super) fn choose(round: &Round, taken_back: &[Probe]) -> Option<usize> {
    let open = |i: usize| !taken_back.contains(&round.probes[i]);
    let coupling = round
        .evidence
        .iter()
        .enumerate()
        .position(|(i, e)| open(i) && e.passes && round.probes[i] == Probe::Temperature);
    let best = |deterministic: bool| {
        round
            .evidence
            .iter()
            .enumerate()
            .filter(|&(i, _)| open(i))
            .filter(|(_, e)| e.passes && e.view.is_deterministic() == deterministic)
            .min_by(|a, b| {
                let told = |e: &evidence::Evidence| e.ranking_p().max(evidence::LEAST_P);
                told(a.1).total_cmp(&told(b.1))
            })
            .map(|(i, _)| i)
    };
    coupling.or_else(|| best(true)).or_else(|| best(false))
}

/// The candidates the model can still take.
pub(super) fn probes(data: &Data, model: &Model, removal: &Removal) -> Vec<Probe> {
    let t = &model.terms;
    let mut out = vec![Probe::Line, Probe::SlowLine];
    if !removal.ramp {
        out.push(Probe::Ramp);
    }
    if data.temperature.is_some() && !removal.temperature {
        out.push(Probe::Temperature);
    }
    if t.gauss_markov.is_none() {
        out.push(Probe::GaussMarkov);
    }
    for (absent, column) in [(t.b == 0.0, Column::B), (t.k == 0.0, Column::K)] {
        if absent {
            out.push(Probe::Term(column));
        }
    }
    if t.q == 0.0 {
        out.push(Probe::Term(Column::Q));
    }
    if model.low_pass.is_none() && matches!(data.settings.low_pass, LowPassChoice::Detect) {
        out.push(Probe::RollOff);
    }
    out
}

/// The roll-off a round's evidence shows but the model has not taken: the passing low-pass
/// candidate's filter, as a fitted one. Another effect named before it (a line, whose wings
/// could mimic the roll-off, comes first) is refitted beyond that filter's reach
/// ([`refit::beyond_fitted_filter`]): refitted with an unfiltered white column, the
/// record's short taus, far below `N^2 / tau` there, pull N down by orders of magnitude
/// and B up to make the long taus good again, and the roll-off is then no longer seen
/// against realisations that have almost no white noise (a filter at 4 % of the rate
/// beside a line 0.6 Hz wide above it was named as a Gauss-Markov process so).
pub(super) fn unnamed_filter(round: &Round, rate_hz: f64) -> Option<LowPass> {
    let (_, e) = round
        .probes
        .iter()
        .zip(&round.evidence)
        .find(|(p, e)| **p == Probe::RollOff && e.passes)?;
    let Some(Effect::LowPass { cutoff_hz, shape }) = e.effect else {
        return None;
    };
    let mut filter = LowPass::generic(shape, cutoff_hz, rate_hz).ok()?;
    filter.source = LowPassSource::Fitted;
    Some(filter)
}

/// The model with `effect` added: deterministic effects join the removal and the stochastic
/// terms are refitted to the record cleaned of them; stochastic ones are refitted with it.
/// `unnamed` is a roll-off the round showed but did not name ([`unnamed_filter`]): the
/// refit leaves its taus out until it is named.
pub(super) fn add(
    data: &Data,
    model: &Model,
    removal: &mut Removal,
    chosen: (Probe, Effect),
    sd_ln: &[f64],
    unnamed: Option<&LowPass>,
) -> Model {
    let (probe, effect) = chosen;
    let mut out = model.clone();
    let mut columns = refit::columns_of(&model.stochastic());
    // A pure line in the low-frequency view's band, whichever view found it, is a slow tone.
    let slow_tone = match effect {
        Effect::Sinusoid {
            freq_hz, width_hz, ..
        } => {
            width_hz == 0.0
                && freq_hz <= spectrum::highest_hz(data.rate_hz, model.low_pass.as_ref())
        }
        _ => false,
    };
    match (probe, effect) {
        (
            Probe::Line | Probe::SlowLine,
            Effect::Sinusoid {
                freq_hz, amplitude, ..
            },
        ) if slow_tone => {
            // A slow pure tone is regressed out jointly with the ramp and the temperature
            // (see `clean`): a notch would take its bins from the series but not from the
            // time and temperature columns. Its guard is the periodogram's main lobe, +-2 bins.
            let (freq_hz, amplitude) = if probe == Probe::Line {
                lines::tone_near(data.rate, data.rate_hz, freq_hz).unwrap_or((freq_hz, amplitude))
            } else {
                (freq_hz, amplitude)
            };
            let df = data.rate_hz / data.rate.len() as f64;
            removal.tones.push(Tone {
                freq_hz,
                guard_hz: 2.0 * df,
            });
            out.lines.push(Line {
                freq_hz,
                amplitude,
                width_hz: 0.0,
                statistic: 0.0,
                p_value: 1.0,
            });
        }
        (
            Probe::Line,
            Effect::Sinusoid {
                freq_hz,
                amplitude,
                width_hz,
            },
        ) => {
            // A wide line's power is read against the model's own background once the model
            // is refitted (`reread_wide_lines`); the notch below takes its core, the refit its
            // Allan variance (`RefitTarget`), and the realisations carry it whole (see
            // `realise`).
            // Half a Lorentzian's power lies beyond its half width; +-1.5 widths hold 80 %.
            let df = data.rate_hz / data.rate.len() as f64;
            let half = 1.5 * width_hz + 2.0 * df;
            removal.notches.push(Notch {
                lo_hz: freq_hz - half,
                hi_hz: freq_hz + half,
            });
            out.lines.push(Line {
                freq_hz,
                amplitude,
                width_hz,
                statistic: 0.0,
                p_value: 1.0,
            });
        }
        (Probe::RollOff, Effect::LowPass { cutoff_hz, shape }) => {
            // The detection on the record with the named effects removed gives the cutoff's
            // interval; the candidate's own cutoff stands if it no longer passes alone.
            let (clean, _) = removal.apply(data.rate, data.rate_hz, data.temperature.as_ref());
            let background = |f: f64| model.one_sided_psd(f, 1.0 / data.rate_hz);
            out.low_pass = evidence::roll_off(
                &clean,
                data.rate_hz,
                removal,
                (&model.lines, &detect_lines(&clean, data.rate_hz)),
                &background,
                true,
            )
            .ok()
            .and_then(|d| d.low_pass)
            .or_else(|| LowPass::generic(shape, cutoff_hz, data.rate_hz).ok());
        }
        (Probe::Ramp, _) => removal.ramp = true,
        (Probe::Temperature, _) => removal.temperature = true,
        (Probe::GaussMarkov, Effect::GaussMarkov { tau_c, .. }) => {
            columns.push(Column::GaussMarkov(tau_c))
        }
        (Probe::Term(c), _) => columns.push(c),
        _ => {}
    }
    if probe.view().is_deterministic() || probe == Probe::GaussMarkov {
        // With a deterministic effect gone, or a Gauss-Markov term in (whose test frees them
        // too), the random terms are refitted from scratch: the baseline may have put K at 0
        // or raised B to absorb the effect.
        columns = evidence::with_random_walks(&columns);
    }
    refitted(data, out, removal, &columns, sd_ln, unnamed)
}

/// `model` and `removal` without the effect `probe` named ([`super::recheck`]), the random
/// terms refitted as [`add`] refits them: a random term's column left out; a ramp or a
/// coupling no longer regressed out; a line no longer removed (regressed out as a tone or
/// notched) nor simulated. Without a Gauss-Markov term or a deterministic effect, B and K
/// are free again: the power either held may have gone to them, as it did in the baseline.
/// `effect` locates a line: the model's nearest to its frequency. None for a filter, or a
/// line the model does not hold.
pub(super) fn without(
    data: &Data,
    (model, removal): (&Model, &Removal),
    (probe, effect): (Probe, Effect),
    sd_ln: &[f64],
    unnamed: Option<&LowPass>,
) -> Option<(Model, Removal)> {
    without_each(data, (model, removal), &[(probe, effect)], sd_ln, unnamed)
}

/// [`without`] for several effects at once, the random terms refitted once without them
/// all. None when one of them is a filter or a line the model does not hold.
pub(super) fn without_each(
    data: &Data,
    (model, removal): (&Model, &Removal),
    effects: &[(Probe, Effect)],
    sd_ln: &[f64],
    unnamed: Option<&LowPass>,
) -> Option<(Model, Removal)> {
    let (mut out, mut removal) = (model.clone(), removal.clone());
    for &(probe, effect) in effects {
        take_out(&mut out, &mut removal, (probe, effect))?;
    }
    let mut columns = refit::columns_of(&out.stochastic());
    if effects
        .iter()
        .any(|&(p, _)| p.view().is_deterministic() || p == Probe::GaussMarkov)
    {
        columns = evidence::with_random_walks(&columns);
    }
    let out = refitted(data, out, &removal, &columns, sd_ln, unnamed);
    Some((out, removal))
}

/// `effect` taken out of `out` and `removal` (see [`without`]); None for a filter or a line
/// the model does not hold.
fn take_out(
    out: &mut Model,
    removal: &mut Removal,
    (probe, effect): (Probe, Effect),
) -> Option<()> {
    match (probe, effect) {
        (Probe::GaussMarkov, _) => out.terms.gauss_markov = None,
        (Probe::Term(Column::Q), _) => out.terms.q = 0.0,
        (Probe::Term(Column::B), _) => out.terms.b = 0.0,
        (Probe::Term(Column::K), _) => out.terms.k = 0.0,
        (Probe::Ramp, _) => {
            removal.ramp = false;
            out.terms.r = 0.0;
        }
        (Probe::Temperature, _) => removal.temperature = false,
        (Probe::Line | Probe::SlowLine, Effect::Sinusoid { freq_hz, .. }) => {
            let line = out.lines.remove(nearest_line(&out.lines, freq_hz)?);
            removal.tones.retain(|t| t.freq_hz != line.freq_hz);
            removal
                .notches
                .retain(|n| !(n.lo_hz <= line.freq_hz && line.freq_hz <= n.hi_hz));
        }
        _ => return None,
    }
    Some(())
}

/// The index of the line of `lines` nearest to `freq_hz`; none when there are none.
pub(super) fn nearest_line(lines: &[Line], freq_hz: f64) -> Option<usize> {
    lines
        .iter()
        .enumerate()
        .min_by(|a, b| {
            (a.1.freq_hz - freq_hz)
                .abs()
                .total_cmp(&(b.1.freq_hz - freq_hz).abs())
        })
        .map(|(i, _)| i)
}

/// `out` with its deterministic coefficients estimated jointly on the record under
/// `removal`, and its random terms in `columns` refitted to the record's Allan variance
/// with the named effects removed (weights from `sd_ln`).
fn refitted(
    data: &Data,
    mut out: Model,
    removal: &Removal,
    columns: &[Column],
    sd_ln: &[f64],
    unnamed: Option<&LowPass>,
) -> Model {
    // The deterministic coefficients, jointly estimated on the record.
    let (_, c) = removal.apply(data.rate, data.rate_hz, data.temperature.as_ref());
    out.terms.r = c.slope.unwrap_or(0.0);
    out.temp_coeff = c.temp;
    out.temp_rate_coeff = c.temp_rate;
    for (tone, amplitude) in removal.tones.iter().zip(&c.tone_amplitudes) {
        if let Some(line) = out.lines.iter_mut().find(|l| l.freq_hz == tone.freq_hz) {
            line.amplitude = *amplitude;
        }
    }
    let shape = restore::Record {
        len: data.rate.len(),
        rate_hz: data.rate_hz,
        m: &data.measured.m,
        temperature: data.temperature.as_ref(),
        known: &data.losses,
    };
    let tau0 = 1.0 / data.rate_hz;
    let target = RefitTarget::of(data.rate, removal, &out.lines, &shape);
    let sd_ln =
        &refit::beyond_fitted_filter(sd_ln, &data.measured.tau, out.low_pass.as_ref().or(unnamed));
    // A wide line's power is read against the refitted model's background, and the refit
    // takes the line's Allan variance out at that power: twice settles both.
    for _ in 0..2 {
        let (avar, sd_ln) = target.less_lines(&out.lines, removal, tau0, sd_ln);
        let curve = refit::Curve {
            tau: &data.measured.tau,
            avar: &avar,
            sd_ln: &sd_ln,
        };
        let shaped = out.clone();
        let white = |tau: f64| shaped.white_shape(tau);
        let terms = refit::refit_cleaned(curve, columns, &white, target.loss.as_ref());
        out.terms = NoiseTerms {
            r: out.terms.r,
            sinusoid: out.terms.sinusoid,
            ..terms
        };
        reread_wide_lines(data, &mut out, removal);
    }
    out
}

/// Whether `line` is a wide line of the model: one with a width that is not removed as a
/// tone by regression (it is notched, simulated whole, and its power read again).
fn is_wide(line: &Line, removal: &Removal) -> bool {
    line.width_hz > 0.0 && !removal.is_tone(line.freq_hz)
}

/// What the stochastic terms are refitted to: the Allan variance of the record with the
/// named effects removed — except that a wide line is not notched but has its own Allan
/// variance ([`lines::sampled_line_avar`], exact for a Lorentzian) subtracted
/// ([`RefitTarget::less_lines`]). A notch takes a wide line's core and leaves its wings (a
/// fifth of its power lies beyond +-1.5 widths), which the refit would take for white noise,
/// and takes the white noise within the notch with it: on a line 15 times the noise, 0.8 Hz
/// wide at 50 Hz, N came out 7 % high and the realisations' Allan curve above the record's
/// wherever the line is not. Subtracted, the line goes whole and the noise stays.
struct RefitTarget<'a> {
    /// The Allan variance of the record with `removal` applied, on `shape.m`.
    total: Vec<f64>,
    /// What that removal takes from K and B ([`restore::Losses::of`]).
    loss: Option<refit::Loss>,
    shape: &'a restore::Record<'a>,
}

/// The remainder of the Allan variance kept after a line's is subtracted, at least: where
/// less is left, the point carries next to no weight.
const LEAST_REMAINDER: f64 = 0.02;

impl<'a> RefitTarget<'a> {
    /// The record with `removal` applied, less the notches of the wide lines in `named`.
    fn of(
        rate: &[f64],
        removal: &Removal,
        named: &[Line],
        shape: &'a restore::Record<'a>,
    ) -> RefitTarget<'a> {
        let in_wide_line = |lo: f64, hi: f64| {
            named
                .iter()
                .any(|l| is_wide(l, removal) && lo <= l.freq_hz && l.freq_hz <= hi)
        };
        let kept = Removal {
            notches: removal
                .notches
                .iter()
                .filter(|n| !in_wide_line(n.lo_hz, n.hi_hz))
                .copied()
                .collect(),
            ..removal.clone()
        };
        let (clean, _) = kept.apply(rate, shape.rate_hz, shape.temperature);
        RefitTarget {
            total: evidence::allan_avar(clean, shape.rate_hz, shape.m),
            loss: shape.known.of(&kept, shape),
            shape,
        }
    }

    /// The Allan variance less the wide lines' of `named` at their current power, and the
    /// weights' ln-AVAR standard deviations: where the line dominates, the remainder is known
    /// less well, its sd the simulated one (`sd_ln`) times total over remainder.
    fn less_lines(
        &self,
        named: &[Line],
        removal: &Removal,
        tau0: f64,
        sd_ln: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let wide: Vec<lines::Line> = named
            .iter()
            .filter(|l| is_wide(l, removal))
            .map(Line::detected)
            .collect();
        self.total
            .iter()
            .zip(self.shape.m)
            .zip(sd_ln)
            .map(|((&a, &m), &sd)| {
                let line: f64 = wide
                    .iter()
                    .map(|l| lines::sampled_line_avar(l, m, tau0))
                    .sum();
                let rest = (a - line).max(LEAST_REMAINDER * a);
                (rest, sd * a / rest)
            })
            .unzip()
    }
}

/// Every wide line's power read again against `model`'s background. A line is read against
/// the background of the model it joins; a filter or a term named later changes that
/// background under it (a line above a filter's cutoff read against the unfiltered white
/// level comes out several times too weak, and its realisations then lack power that a
/// quantization term takes up).
fn reread_wide_lines(data: &Data, model: &mut Model, removal: &Removal) {
    let tau0 = 1.0 / data.rate_hz;
    let shaped = model.clone();
    let background = |f: f64| shaped.one_sided_psd(f, tau0);
    for line in model.lines.iter_mut().filter(|l| is_wide(l, removal)) {
        if let Some(p) = spectrum::line_power(
            data.rate,
            data.rate_hz,
            line.freq_hz,
            line.width_hz,
            &background,
        ) {
            line.amplitude = (2.0 * p).sqrt();
        }
    }
    model.terms.sinusoid = model.lines.first().map(|l| Sinusoid {
        amplitude: l.amplitude,
        freq_hz: l.freq_hz,
    });
}

/// The round's open noise model: the random terms refitted to the record with every
/// deterministic candidate removed — the regressors in `regressors_out` and the strongest
/// slow line (`slow_hz`) as a tone — with what that removal takes from K and B given back
/// ([`restore`]). A baseline fitted with an effect in the record has put its power into K;
/// tests against realisations of that K would let each effect hide the other.
pub(super) fn open_noise(
    data: &Data,
    regressors_out: &Removal,
    slow_hz: Option<f64>,
    ctx: &Context,
    columns: &[Column],
) -> NoiseTerms {
    let mut open = regressors_out.clone();
    if let Some(freq_hz) = slow_hz {
        let df = data.rate_hz / data.rate.len() as f64;
        open.tones.push(Tone {
            freq_hz,
            guard_hz: 2.0 * df,
        });
    }
    let shape = restore::Record {
        len: data.rate.len(),
        rate_hz: data.rate_hz,
        m: ctx.m,
        temperature: data.temperature.as_ref(),
        known: &data.losses,
    };
    let target = RefitTarget::of(data.rate, &open, ctx.named_lines, &shape);
    let tau0 = 1.0 / data.rate_hz;
    let (avar, sd_ln) = target.less_lines(ctx.named_lines, &open, tau0, ctx.sd_ln);
    let curve = refit::Curve {
        tau: ctx.tau,
        avar: &avar,
        sd_ln: &sd_ln,
    };
    refit::refit_cleaned(curve, columns, ctx.white, target.loss.as_ref())
}

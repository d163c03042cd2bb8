//! The model workflow: fit the IEEE-952 terms of one channel, simulate the model many times,
//! look for what the model misses in every view where an effect shows — the Allan curve,
//! the spectrum's lines, regressions of the rate on time and on temperature — name the
//! effect whose evidence stands out of the simulated spread, add it and repeat.
//!
//! **Baseline.** The stochastic terms Q, N, B, K of the pipeline's fit to the overlapping
//! Allan variance. The fit's rate ramp R is left out: a ramp is deterministic, estimated far
//! better by regressing the rate on time, and is one of the effects the workflow names.
//!
//! **Simulation.** The model's stochastic part is synthesised with [`AxisNoise`](crate::sim::noise::AxisNoise) at the
//! record's rate and length, `realisations` times (seeds `seed`, `seed + 1`, ...; the same
//! seeds for every model, so models are compared on common random numbers), in parallel.
//!
//! **Evidence** ([`evidence`]). Every candidate effect has a statistic computed by one
//! function on the measured record and on each realisation, after the effects already named
//! are removed from both ([`clean`]): the strongest spectral line, the strongest slow line
//! of the low-frequency periodogram ([`spectrum`]), the likelihood ratio of a regression on
//! time or on temperature ([`regression`]), the misfit drop of a nested Allan fit
//! (Gauss-Markov, B, K, Q). Its p-value is taken from the realisations' distribution of the
//! same statistic (for the regressors, from series drawn from the block-mean covariance of
//! the noise without the regressor: [`gls`]). The realisations carry the notched lines too (see `realise`); slow
//! tones are regressors, removed from both alike ([`clean`]).
//!
//! **Naming rule** ([`names`]). A candidate is named when its p-value against the simulated
//! distribution (a scaled chi-square matched to the realisations' statistics, see
//! [`Evidence`]) is below [`FAMILY_ALPHA`] divided by the number of candidates in the round,
//! *and* the measured statistic exceeds every simulated one. A verdict that rests on the tail
//! of the round's few realisations ([`UNSURE_BELOW`]) is taken again on [`REFINE`] times as
//! many (a sequential Monte Carlo test: Besag & Clifford, Biometrika 78, 1991). A regressor
//! test near the line, whose bootstrap draws are cheap, is decided instead by the Monte
//! Carlo p-value of as many draws as [`MONTE_CARLO_EXCEEDANCES`] asks for. Under the model (no missing
//! effect) the measured statistic is one more draw from the simulated distribution, so a
//! round names nothing with probability about `1 - FAMILY_ALPHA`. Deterministic
//! candidates (lines, ramp, temperature, the sensor's roll-off) are judged first: a baseline
//! that explains the curve through K, B or R must not hide what a regressor or a line
//! explains. The roll-off is a candidate like the others, so a wide line near Nyquist, whose
//! wings or notch can mimic one, is named (and carried by the realisations) before the
//! roll-off is judged. The regressors and the slow line are judged against realisations of
//! the round's open noise model (`open_noise`: the random terms refitted with every
//! deterministic candidate removed), so two effects the baseline put into K do not hide
//! each other. Among the passing
//! candidates of the first group that has any, the smallest p is named; among two or more
//! passing random terms, the one whose model the simulations bring closest to the record
//! (the least Allan gap, see `naming.rs`): a bump one term explains makes others pass
//! beside it, sometimes with a smaller p. Then the model takes
//! the effect, its stochastic terms are refitted to the cleaned record, and the loop repeats
//! (at most [`MAX_STEPS`] rounds that name effects; the lines that pass together are named
//! in one, `naming::lines_beside`), so a record with two effects gets both. A stochastic
//! term or a sensor filter after which the Allan gap does not shrink is taken back and the round's next passing
//! candidate tried: several random terms can pass one round (a Gauss-Markov bump moves the
//! fitted N, so quantization passes too), and only one of them is the missing effect.
//!
//! **Recheck** ([`recheck`]). After the loop, an effect named before one of the other kind
//! (deterministic or random) is taken out of the final model and dropped when, tested again
//! without it, no candidate passes (backward elimination): judged first, a slow line can take
//! part of a Gauss-Markov plateau that the process, named next, explains.
//!
//! **Gap** (reported, not decided on). `z(tau) = (ln ADEV_measured(tau) - mean ln
//! ADEV_sim(tau)) / std ln ADEV_sim(tau)`, the realisations carrying the named deterministic
//! effects as estimated from the record; `gap = sqrt(mean z^2)`. Taus with `|z| > 2` are the
//! disagreeing ranges.
//!
//! **Limits.** A Gauss-Markov process shorter than [`GAUSS_MARKOV_MIN_SAMPLES`] samples is
//! indistinguishable from a low-pass filter and is never proposed; one longer than half the
//! longest tau looks like rate random walk. A temperature coupling needs the temperature
//! channel. Effects that leave neither a line, a regression nor an Allan-curve shape (for
//! example a slowly varying scale factor on a static record) cannot be seen.

mod candidates;
use candidates::{choose, detect_lines};
pub mod clean;
pub mod cosine;
pub mod evidence;
pub mod gauss_markov_fit;
pub mod gls;
mod joint;
mod naming;
pub mod recheck;
pub mod refit;
pub mod regression;
pub mod report;
pub mod restore;
mod simulate;
pub mod sinusoid_errors;
pub mod slow_view;
use simulate::{Round, simulate_round};
pub mod spectrum;

use crate::analysis::low_pass::{LowPass, LowPassSource};
use crate::analysis::pipeline::{self, ChannelResult, LowPassChoice, Options};
use crate::analysis::{Deviation, Estimator, allan, fit, lines, phase_from_rate};
use crate::record::{Channel, Quantity, Record};
use crate::sim::noise::NoiseTerms;
use clean::{Removal, Temperature};
use evidence::{Evidence, Probe, View};
use serde::Serialize;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// Chance, per round, that pure noise gets some candidate named: split evenly over the
/// candidates of the round (Bonferroni). Half the one-in-ten false naming a workflow may
/// afford on a record without an effect; the family study (docs/guide/model.md) measured
/// what it buys: at 0.01, 78 of 100 records named right and no false name in 20 effect-free
/// records; at 0.05, 85 of 100 (ramps 3 -> 7 of 10, tone and ramp 2 -> 6) and 2 false
/// names in 20.
pub const FAMILY_ALPHA: f64 = 0.05;
/// Series drawn under the null for each regressor test: a draw is a few hundred block
/// means and a restricted-likelihood fit, not a synthesis of the record.
pub const REGRESSION_DRAWS: usize = 48;
/// How many times as many simulations (or bootstrap draws) a verdict gets when it is unsure
/// on the round's own: see [`UNSURE_BELOW`].
pub const REFINE: usize = 4;
/// A verdict is unsure when the candidate's statistic exceeds every simulated one and its
/// p-value lies from this factor below to [`UNSURE_ABOVE`] above the naming threshold. The
/// p-value is extrapolated from a scaled chi-square matched to few simulations' mean and
/// variance, and that extrapolation is wide and biased low: from 24 draws of a chi-square
/// (1/2 to 2 degrees of freedom) whose true tail beyond the statistic is 2e-3, the
/// extrapolated p has a median of 0.6e-3 to 1.1e-3 and a 90 % range of 1e-7 to 1.4e-2; from
/// 96 draws, a median of 1.5e-3 to 1.8e-3 and a range of 1e-4 to 8e-3. The effects the
/// workflow names are usually far beyond any simulation (p below 1e-12), where no
/// refinement would change the verdict.
pub const UNSURE_BELOW: f64 = 1e6;
/// See [`UNSURE_BELOW`].
pub const UNSURE_ABOVE: f64 = 3.0;
/// A regressor test (ramp, temperature) whose p-value lies near the threshold, whether or
/// not its statistic exceeds every draw, is decided by the Monte Carlo p-value
/// ([`evidence::Evidence::monte_carlo`]) of as many bootstrap draws as put the threshold this
/// many draws deep in their tail (about 1600 for eight candidates): the verdict's own Monte
/// Carlo error is then a third of the threshold (a binomial count of mean 10). The rule
/// "the statistic above every draw" would hold such a test at the level `1 / (draws + 1)`
/// instead of the threshold: with 192 draws and a threshold of 8.3e-3, 5.2e-3.
pub const MONTE_CARLO_EXCEEDANCES: f64 = 10.0;
/// Most rounds that name effects: each names one effect, or every line its line view
/// passes together (`naming::lines_beside`).
pub const MAX_STEPS: usize = 4;
/// |z| above this marks a disagreeing tau of the Allan curve.
pub const Z_DISAGREE: f64 = 2.0;
/// Shortest Gauss-Markov correlation time proposed, in samples: shorter ones are the
/// sensor's own low-pass filter.
pub const GAUSS_MARKOV_MIN_SAMPLES: f64 = 10.0;

/// The p-value a candidate must stay below in a round of `candidates`: [`FAMILY_ALPHA`]
/// split evenly over them (Bonferroni).
pub fn p_needed(candidates: usize) -> f64 {
    FAMILY_ALPHA / candidates.max(1) as f64
}

/// The naming rule: the p-value against the simulated distribution below `p_needed`, and the
/// measured statistic above every simulated one.
pub fn names(statistic: f64, p_value: f64, p_needed: f64, sim_max: f64) -> bool {
    p_value < p_needed && statistic > sim_max
}

/// Settings of [`run`].
#[derive(Debug, Clone)]
pub struct Settings {
    pub realisations: usize,
    pub seed: u64,
    /// Where the sensor's low-pass filter comes from (default: fitted to the record).
    pub low_pass: LowPassChoice,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            realisations: 24,
            seed: 1,
            low_pass: LowPassChoice::Detect,
        }
    }
}

/// A spectral line as the workflow sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Line {
    pub freq_hz: f64,
    /// Peak amplitude, u.
    pub amplitude: f64,
    /// Width of the line's excess power, Hz (0 for a pure tone).
    pub width_hz: f64,
    /// The detector's statistic.
    pub statistic: f64,
    /// The detector's family-wise p-value ([`lines::Line::p_value`]); 1 for a line the
    /// workflow named (it is then part of the model, not a finding).
    #[serde(skip_serializing)]
    pub p_value: f64,
}

impl Line {
    /// The power (variance) the line adds, u^2: `amplitude^2 / 2`.
    pub fn power(&self) -> f64 {
        self.amplitude * self.amplitude / 2.0
    }

    /// The line as the line detector states one (for its Allan variance).
    fn detected(&self) -> lines::Line {
        lines::Line {
            freq_hz: self.freq_hz,
            amplitude: self.amplitude,
            width_hz: self.width_hz,
            power: self.power(),
            statistic: self.statistic,
            p_value: self.p_value,
            standard_errors: lines::LineErrors::UNKNOWN,
        }
    }
}

/// An effect the workflow can add, with its parameters in SI (u the channel's unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Effect {
    /// First-order Gauss-Markov: correlation time `tau_c` (s), standard deviation `sigma` (u).
    GaussMarkov { tau_c: f64, sigma: f64 },
    /// A spectral line: `amplitude` (u, peak) at `freq_hz`, `width_hz` wide (0: a pure tone).
    Sinusoid {
        freq_hz: f64,
        amplitude: f64,
        width_hz: f64,
    },
    /// Sensitivity to the temperature channel, u per degC, and to its rate of change, u per
    /// degC/s.
    Temperature { coeff: f64, rate_coeff: f64 },
    /// A rate ramp, u/s.
    RateRamp { slope: f64 },
    /// Quantization Q, u s.
    Quantization { q: f64 },
    /// Bias instability B, u.
    BiasInstability { b: f64 },
    /// Rate random walk K, u sqrt(Hz).
    RateRandomWalk { k: f64 },
    /// The sensor's low-pass filter, -3 dB at `cutoff_hz`, of the generic `shape` that fits
    /// its roll-off best.
    LowPass {
        cutoff_hz: f64,
        shape: crate::analysis::low_pass::Shape,
    },
}

impl Effect {
    fn from_line(l: &Line) -> Effect {
        Effect::Sinusoid {
            freq_hz: l.freq_hz,
            amplitude: l.amplitude,
            width_hz: l.width_hz,
        }
    }

    pub fn kind(&self) -> &'static str {
        match self {
            Effect::GaussMarkov { .. } => "gauss_markov",
            Effect::Sinusoid { .. } => "sinusoid",
            Effect::Temperature { .. } => "temperature",
            Effect::RateRamp { .. } => "rate_ramp",
            Effect::Quantization { .. } => "quantization",
            Effect::BiasInstability { .. } => "bias_instability",
            Effect::RateRandomWalk { .. } => "rate_random_walk",
            Effect::LowPass { .. } => "low_pass",
        }
    }

    /// In words and numbers (4 significant digits), `u` the channel's unit.
    pub fn describe(&self, u: &str) -> String {
        use crate::report::sig;
        match *self {
            Effect::GaussMarkov { tau_c, sigma } => format!(
                "Gauss-Markov, tau_c = {} s, sigma = {} {u}",
                sig(tau_c, 4),
                sig(sigma, 4)
            ),
            // A frequency counted over many cycles is known to more digits than the rest.
            Effect::Sinusoid {
                freq_hz,
                amplitude,
                width_hz,
            } => format!(
                "spectral line, f = {} Hz, amplitude = {} {u}, width = {} Hz",
                sig(freq_hz, 5),
                sig(amplitude, 4),
                sig(width_hz, 3)
            ),
            Effect::Temperature { coeff, rate_coeff } => format!(
                "temperature sensitivity, {} {u}/degC and {} {u}/(degC/s)",
                sig(coeff, 4),
                sig(rate_coeff, 4)
            ),
            Effect::RateRamp { slope } => format!("rate ramp, R = {} {u}/s", sig(slope, 4)),
            Effect::Quantization { q } => format!("quantization, Q = {} {u} s", sig(q, 4)),
            Effect::BiasInstability { b } => format!("bias instability, B = {} {u}", sig(b, 4)),
            Effect::RateRandomWalk { k } => {
                format!("rate random walk, K = {} {u} sqrt(Hz)", sig(k, 4))
            }
            Effect::LowPass { cutoff_hz, shape } => format!(
                "low-pass filter (the sensor's own): {}, -3 dB at {} Hz",
                shape.describe(),
                sig(cutoff_hz, 4)
            ),
        }
    }
}

/// `effect` in words, with the standard errors and intervals of its parameters where its
/// `evidence` gives them: `rate ramp, R = -2.800e-8 rad/s/s (standard error: slope 4.1e-9)`,
/// `Gauss-Markov ... (68.3 % interval: sigma [2.63e-5, 3.63e-5], tau_c [30.0, 57.7])`.
fn described(effect: &Effect, evidence: &Evidence, unit: &str) -> String {
    let mut words = effect.describe(unit);
    if !evidence.standard_errors.is_empty() {
        let errors: Vec<String> = evidence
            .standard_errors
            .iter()
            .map(|(name, sd)| format!("{name} {}", crate::report::sig(*sd, 2)))
            .collect();
        words = format!("{words} (standard error: {})", errors.join(", "));
    }
    if !evidence.intervals.is_empty() {
        let end = |v: Option<f64>| v.map_or("open".to_string(), |v| crate::report::sig(v, 3));
        let intervals: Vec<String> = evidence
            .intervals
            .iter()
            .map(|(name, (lo, hi))| format!("{name} [{}, {}]", end(*lo), end(*hi)))
            .collect();
        words = format!("{words} (68.3 % interval: {})", intervals.join(", "));
    }
    words
}

/// The step `named` makes in `round`, the `naming_round`-th round that named effects, and
/// the removal with its effect added.
fn step_of(
    named: naming::Named,
    round: &Round,
    unit: &str,
    naming_round: usize,
) -> (Step, Removal) {
    let chosen = named.index;
    let evidence = named.evidence;
    let step = Step {
        description: described(&named.effect, &evidence[chosen], unit)
            + &weighed_words(&named.weighed, named.stands_in),
        effect: named.effect,
        at_naming: named.effect,
        standard_errors: evidence[chosen].standard_errors.clone(),
        view: evidence[chosen].view,
        round: naming_round,
        gap_before: round.comparison.gap,
        gap_after: f64::NAN,
        evidence,
        rivals: named.weighed,
        stands_in: named.stands_in,
        model: named.model,
        comparison: round.comparison.clone(),
    };
    (step, named.removal)
}

/// How a step was chosen among rivals, in words: each one's Allan gap with it added, and
/// whether the step stands in for a random term that passed (empty when none were weighed).
pub(super) fn weighed_words(weighed: &[naming::Weighed], stands_in: bool) -> String {
    if weighed.is_empty() {
        return String::new();
    }
    let gaps: Vec<String> = weighed
        .iter()
        .map(|w| format!("{} {}", w.effect.kind(), crate::report::sig(w.gap, 3)))
        .collect();
    let how = if stands_in {
        "named in place of the random term that passed, its model being the closest to the record"
    } else {
        "the closest to the record among the rivals"
    };
    format!(" ({how}; Allan gap with each: {})", gaps.join(", "))
}

/// The model: stochastic noise terms, the deterministic effects named (as estimated from the
/// record), and the sensor's low-pass filter where one is known or was named.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Model {
    /// Stochastic terms; `r` holds the named ramp and `sinusoid` the first named line (for
    /// the model file), neither of which is simulated as noise.
    pub terms: NoiseTerms,
    /// u/degC, applied to the record's own temperature channel.
    pub temp_coeff: Option<f64>,
    /// u/(degC/s), on the temperature's derivative.
    pub temp_rate_coeff: Option<f64>,
    pub lines: Vec<Line>,
    /// The sensor's low-pass filter: from its settings (part of the baseline) or named from
    /// the record's roll-off. The white noise N is simulated and fitted through it.
    pub low_pass: Option<LowPass>,
}

impl Model {
    /// The Allan variance of unit-density white rate noise at `tau` through the model's
    /// low-pass (`1 / tau` without one).
    fn white_shape(&self, tau: f64) -> f64 {
        match &self.low_pass {
            Some(lp) => lp.white_avar(tau),
            None => refit::unfiltered(tau),
        }
    }

    /// The stochastic terms' one-sided PSD at `f` Hz, u^2/Hz: twice IEEE 952 Table C.1's
    /// two-sided `(2 pi f)^2 Q^2 tau0 + N^2 |H(f)|^2 + B^2 / (2 pi f) + K^2 / (2 pi f)^2`
    /// (`tau0` the sample interval; H the sensor filter, if any).
    fn one_sided_psd(&self, f: f64, tau0: f64) -> f64 {
        let t = &self.terms;
        let w = 2.0 * PI * f;
        let gain = self.low_pass.as_ref().map_or(1.0, |lp| lp.power_gain(f));
        2.0 * (w * w * t.q * t.q * tau0 + t.n * t.n * gain + t.b * t.b / w + t.k * t.k / (w * w))
    }

    /// Only the stochastic terms, as the simulator synthesises them.
    fn stochastic(&self) -> NoiseTerms {
        NoiseTerms {
            r: 0.0,
            sinusoid: None,
            ..self.terms
        }
    }
}

/// The simulated spread of ln ADEV at each tau.
#[derive(Debug, Clone, Serialize)]
pub struct Band {
    pub tau: Vec<f64>,
    pub mean_log: Vec<f64>,
    pub std_log: Vec<f64>,
}

/// A tau range where the measured deviation lies outside the simulated band (|z| > 2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Range {
    pub tau_lo: f64,
    pub tau_hi: f64,
    /// Measured above (+1) or below (-1) the simulations.
    pub sign: i32,
}

/// A model compared with the data.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub gap: f64,
    pub z: Vec<f64>,
    pub disagreeing: Vec<Range>,
    pub band: Band,
}

/// One effect added.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// The effect as the final model holds it: a ramp, a temperature coupling and a slow
    /// tone at their joint estimate with every effect named (`model::joint`), the others as
    /// named.
    pub effect: Effect,
    /// The effect as estimated when it was named, beside the effects named before it.
    pub at_naming: Effect,
    /// Standard errors of `effect`'s parameters, by name, where known.
    pub standard_errors: BTreeMap<&'static str, f64>,
    /// The effect in words, with its parameters' standard errors where known.
    pub description: String,
    pub view: View,
    /// The round that named it, counted over the rounds that named effects (1 for the
    /// first): lines passing together are named in one round (`naming::lines_beside`).
    pub round: usize,
    /// The Allan gap of the round that named it, and of the round after it.
    pub gap_before: f64,
    pub gap_after: f64,
    /// Every candidate's evidence at this step (the named one among them).
    pub evidence: Vec<Evidence>,
    /// The rivals weighed by the Allan gap when several could explain the same excess
    /// (`model::naming`), the named one among them; empty when none were.
    pub rivals: Vec<naming::Weighed>,
    /// Whether it was named by the gap in place of a random term that passed, not by its
    /// own test (`model::naming`).
    #[serde(skip)]
    pub stands_in: bool,
    #[serde(skip)]
    pub model: Model,
    #[serde(skip)]
    pub comparison: Comparison,
}

impl Step {
    /// Whether the step must shrink the Allan gap to stay: a random term, a filter, or an
    /// effect standing in for a random term.
    pub fn must_close_gap(&self) -> bool {
        self.view.must_close_gap() || self.stands_in
    }
}

/// Why the loop stopped.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum Stop {
    /// No candidate passed the naming rule; the strongest is given.
    NothingStandsOut { best: Option<Evidence> },
    /// [`MAX_STEPS`] rounds named effects.
    MaxSteps,
    /// The stochastic terms that passed their tests did not bring the simulations closer to
    /// the record (the Allan gap did not shrink), so they were taken back; the last is given.
    NoCloser { undone: Option<Effect> },
}

impl std::fmt::Display for Stop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stop::NothingStandsOut { best: Some(e) } => write!(
                f,
                "no further effect stands out of the simulated spread (strongest: {} in the {}, p = {}, z = {}; naming needs p < {}{})",
                e.candidate,
                e.view.describe(),
                report::p_text(e.p_value),
                report::z_text(e.z),
                report::p_text(e.p_needed),
                if e.monte_carlo {
                    ", the Monte Carlo count of its draws"
                } else {
                    " and a statistic above every simulation's"
                },
            ),
            Stop::NothingStandsOut { best: None } => write!(f, "no candidate effect applies"),
            Stop::MaxSteps => write!(f, "stopped after {MAX_STEPS} rounds that named effects"),
            Stop::NoCloser { undone } => write!(
                f,
                "{} passed its test but did not bring the simulations closer to the record (Allan gap did not shrink), so it was taken back",
                undone.map_or("the last term", |e| e.kind())
            ),
        }
    }
}

/// The workflow's outcome for one channel.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub channel: String,
    pub quantity: Quantity,
    pub unit: &'static str,
    pub rate_hz: f64,
    pub n: usize,
    pub realisations: usize,
    pub measured: Deviation,
    pub baseline: Model,
    /// The pipeline's five-term fit the baseline came from (its R is not in the baseline).
    pub baseline_fit: fit::NoiseFit,
    /// The temperature channel used, if any.
    pub temperature: Option<String>,
    /// Why the record's temperature channel was not used, where it was not.
    pub temperature_note: Option<String>,
    pub initial: Comparison,
    /// The candidates' evidence against the baseline.
    pub initial_evidence: Vec<Evidence>,
    pub steps: Vec<Step>,
    /// The effects named before a later effect of the other kind, tested again against the
    /// final model without them ([`recheck`]); those dropped are no longer among `steps`.
    pub rechecked: Vec<recheck::Rechecked>,
    /// The candidates' evidence against the final model (none of which was named).
    pub final_evidence: Vec<Evidence>,
    pub stop: Stop,
}

impl Outcome {
    pub fn final_model(&self) -> &Model {
        self.steps.last().map_or(&self.baseline, |s| &s.model)
    }
    pub fn final_comparison(&self) -> &Comparison {
        self.steps.last().map_or(&self.initial, |s| &s.comparison)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("no channel '{0}' in the record")]
    NoChannel(String),
    #[error(
        "the record has no gyro or accelerometer channel (gx, ax, ...) and more than one other: \
         choose one of {0} with --column"
    )]
    NoGyro(String),
    #[error("temperature channel '{0}': not in the record")]
    NoTemperature(String),
    #[error(transparent)]
    Analysis(#[from] pipeline::AnalysisError),
    #[error("channel '{channel}': the baseline fit failed: {message}")]
    Fit { channel: String, message: String },
    #[error("channel '{0}': the Allan curve has too few taus to compare")]
    TooFewTaus(String),
}

/// What the workflow works on.
struct Data<'a> {
    rate: &'a [f64],
    rate_hz: f64,
    temperature: Option<Temperature>,
    measured: Deviation,
    settings: Settings,
    lines: &'a (dyn Fn(&[f64], f64) -> Vec<Line> + Sync),
    /// What the removals tried so far take from K and B.
    losses: restore::Losses,
}

/// The channel to model: `column`; else the first gyro channel, else the first
/// accelerometer channel, else the record's only channel of no known quantity (a
/// one-column `.npy` or a table whose one signal has a name of its own).
fn pick<'r>(record: &'r Record, column: Option<&str>) -> Result<&'r Channel, ModelError> {
    if let Some(name) = column {
        return record
            .channel(name)
            .ok_or_else(|| ModelError::NoChannel(name.to_string()));
    }
    let first = |q: Quantity| record.channels.iter().find(|c| c.quantity == q);
    let unknown: Vec<&Channel> = record
        .channels
        .iter()
        .filter(|c| c.quantity == Quantity::Other)
        .collect();
    first(Quantity::AngularRate)
        .or_else(|| first(Quantity::Acceleration))
        .or(match unknown[..] {
            [only] => Some(only),
            _ => None,
        })
        .ok_or_else(|| ModelError::NoGyro(record.names().join(", ")))
}

/// The temperature channel: `temp_column`, or the record's temperature channel if it has one.
fn pick_temperature<'r>(
    record: &'r Record,
    temp_column: Option<&str>,
) -> Result<Option<&'r Channel>, ModelError> {
    match temp_column {
        Some(name) => record
            .channel(name)
            .map(Some)
            .ok_or_else(|| ModelError::NoTemperature(name.to_string())),
        None => Ok(record
            .channels
            .iter()
            .find(|c| c.quantity == Quantity::Temperature)),
    }
}

/// Run the workflow on `column` (default: the first gyro channel, else the first
/// accelerometer channel, else the record's only channel of no known quantity) of `record`, with the
/// temperature channel `temp_column` (default: the record's temperature channel, if any).
pub fn run(
    record: &Record,
    column: Option<&str>,
    temp_column: Option<&str>,
    settings: &Settings,
) -> Result<Outcome, ModelError> {
    let channel = pick(record, column)?;
    let picked_temperature = pick_temperature(record, temp_column)?;
    // A temperature that never changed explains nothing and makes the regression's columns
    // degenerate: the coupling is not a candidate then, and the outcome says why.
    let temperature_note = picked_temperature
        .filter(|t| t.is_constant())
        .map(|t| {
            format!(
                "temperature channel '{}' is constant ({} for all {} samples): the temperature coupling is not tried",
                t.name,
                t.values[0],
                t.values.len()
            )
        });
    let temp_channel = picked_temperature.filter(|_| temperature_note.is_none());
    // The baseline is fitted to the record without its spectral lines: a strong tone would
    // otherwise become quantization noise or a roll-off, and the lines are named as steps.
    let line_free = pipeline::without_lines(&channel.values, record.rate_hz);
    let single = Record {
        source: record.source.clone(),
        rate_hz: record.rate_hz,
        channels: vec![Channel {
            values: line_free,
            ..channel.clone()
        }],
    };
    // The lines were removed above (the workflow names them itself).
    let options = Options {
        low_pass: settings.low_pass,
        lines: None,
        ..Options::default()
    };
    let result: ChannelResult = pipeline::analyze(&single, &options, &|| {})?
        .into_iter()
        .next()
        .expect("one channel in, one result out");
    let fitted = result.fit.clone().map_err(|message| ModelError::Fit {
        channel: channel.name.clone(),
        message: message.to_string(),
    })?;
    // The record's own curve (lines included) on the fit's averaging factors.
    let tau0 = 1.0 / record.rate_hz;
    let measured = allan::deviation(
        Estimator::Oadev,
        &phase_from_rate(&channel.values, tau0),
        tau0,
        &result.fit_curve.deviation.m,
    );
    if measured.tau.len() < 3 {
        return Err(ModelError::TooFewTaus(channel.name.clone()));
    }
    let data = Data {
        rate: &channel.values,
        rate_hz: record.rate_hz,
        temperature: temp_channel.map(|t| Temperature::new(&t.values, record.rate_hz)),
        measured,
        settings: settings.clone(),
        lines: &detect_lines,
        losses: restore::Losses::default(),
    };
    // A filter known from the sensor's settings is part of the baseline; one the record's
    // roll-off shows is a candidate like any other effect (`Probe::RollOff`), judged after
    // the lines whose removal or wings could mimic it.
    let known = fitted
        .low_pass
        .clone()
        .filter(|lp| lp.source == LowPassSource::Settings);
    let baseline = Model {
        terms: NoiseTerms {
            q: fitted.q.value,
            n: fitted.n.value,
            b: fitted.b.value,
            k: fitted.k.value,
            ..NoiseTerms::default()
        },
        low_pass: known,
        ..Model::default()
    };
    let mut model = baseline.clone();
    let mut removal = Removal::default();
    let mut steps: Vec<Step> = Vec::new();
    let mut initial: Option<(Comparison, Vec<Evidence>)> = None;
    // The round a step was chosen in, with the model and removal before it and the probe
    // chosen: a stochastic term taken back makes room for the round's next passing candidate.
    let mut chosen_in: Option<(Round, Model, Removal, Probe)> = None;
    // Candidates taken back since the last step that stayed.
    let mut taken_back: Vec<Probe> = Vec::new();
    let mut last_undone: Option<Effect> = None;
    // The band the last naming weighed its rivals on, made for the model it named.
    let mut named_band = None;
    let (final_round, stop) = loop {
        let round = simulate_round(&data, &model, &removal, named_band.take());
        let round = match steps.last_mut() {
            Some(s) if s.must_close_gap() && round.comparison.gap >= s.gap_before => {
                // A stochastic term or a filter (or an effect standing in for a stochastic
                // term) that does not bring the simulations closer to the record explains
                // nothing (see `View::must_close_gap`, `naming`).
                let undone = steps.pop().expect("matched a last step");
                last_undone = Some(undone.effect);
                let Some((before, m, r, probe)) = chosen_in.take() else {
                    unreachable!("every step records the round it was chosen in")
                };
                taken_back.push(probe);
                (model, removal) = (m, r);
                before
            }
            Some(last) => {
                // Every step the last naming round named (lines found together) closes here.
                let named_last = last.round;
                for s in steps.iter_mut().filter(|s| s.round == named_last) {
                    s.gap_after = round.comparison.gap;
                    s.comparison = round.comparison.clone();
                }
                taken_back.clear();
                round
            }
            None => {
                initial = Some((round.comparison.clone(), round.evidence.clone()));
                round
            }
        };
        let Some(chosen) = choose(&round, &taken_back) else {
            if !taken_back.is_empty() {
                break (
                    round,
                    Stop::NoCloser {
                        undone: last_undone,
                    },
                );
            }
            let best = strongest(&round.evidence);
            break (round, Stop::NothingStandsOut { best });
        };
        let naming_round = steps.last().map_or(0, |s| s.round) + 1;
        if naming_round > MAX_STEPS {
            break (round, Stop::MaxSteps);
        }
        let mut named = naming::name(&data, &model, &removal, &round, chosen, &taken_back);
        named_band = named.band.take();
        let probe = round.probes[named.index];
        let beside = if probe == Probe::Line {
            naming::lines_beside(&data, &named, &round)
        } else {
            Vec::new()
        };
        let before = (model, removal);
        let beside_words = match named.effect {
            Effect::Sinusoid { freq_hz, .. } => format!(
                "; found beside the line at {} Hz, in the same round",
                crate::report::sig(freq_hz, 5)
            ),
            _ => String::new(),
        };
        let (mut step, mut after) = step_of(named, &round, channel.unit(), naming_round);
        for named in beside {
            steps.push(step);
            (step, after) = step_of(named, &round, channel.unit(), naming_round);
            step.description += &beside_words;
        }
        (model, removal) = (step.model.clone(), after);
        steps.push(step);
        chosen_in = Some((round, before.0, before.1, probe));
    };
    let (initial, initial_evidence) = initial.expect("the first round always runs");
    let (final_round, rechecked) =
        recheck::named_before(&data, &mut steps, &mut removal, final_round);
    let stop = if rechecked.iter().any(|r| r.dropped) {
        Stop::NothingStandsOut {
            best: strongest(&final_round.evidence),
        }
    } else {
        stop
    };
    let model = steps.last().map_or(model, |s| s.model.clone());
    joint::restate(
        &mut steps,
        &data,
        &removal,
        &model,
        &final_round.open,
        channel.unit(),
    );
    Ok(Outcome {
        channel: channel.name.clone(),
        quantity: channel.quantity,
        unit: channel.unit(),
        rate_hz: record.rate_hz,
        n: channel.values.len(),
        realisations: settings.realisations.max(2),
        measured: data.measured,
        baseline,
        baseline_fit: fitted,
        temperature: temp_channel.map(|t| t.name.clone()),
        temperature_note,
        initial,
        initial_evidence,
        steps,
        rechecked,
        final_evidence: final_round.evidence,
        stop,
    })
}

/// The candidate with the least p-value among those that found an effect.
fn strongest(evidence: &[Evidence]) -> Option<Evidence> {
    evidence
        .iter()
        .filter(|e| e.effect.is_some())
        .min_by(|a, b| a.p_value.total_cmp(&b.p_value))
        .cloned()
}

#[cfg(test)]
pub mod families;
#[cfg(test)]
mod gauss_markov_power;
#[cfg(test)]
mod independent;
#[cfg(test)]
mod ramp_power;
#[cfg(test)]
mod sensor_filters;
#[cfg(test)]
mod tests;

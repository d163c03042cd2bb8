//! The deterministic effects as the final model holds them. Each effect is estimated when it
//! is named, beside the effects named before it; an effect named later changes what the
//! earlier ones take. A temperature warm-up and a ramp are the plain case: both rise over
//! the first hour, so a warm-up named first also takes part of the ramp, and once the ramp
//! is named the two are estimated jointly. The model's least squares over every regressor
//! named (the ramp, the temperature and its rate of change, the slow tones; see
//! [`super::clean`]) is what the final model holds, so that is what each step reports, with
//! its standard errors beside every regressor named; the estimate at naming stays in the
//! step (`at_naming`) and in its evidence.

use super::clean::{Removal, notch};
use super::{Data, Effect, Model, Step, described, gls, weighed_words};
use crate::sim::noise::NoiseTerms;
use std::collections::BTreeMap;

/// Every step's regressor effect restated at the `model`'s joint estimate, with the
/// standard errors of that estimate under the `open` noise model of the last round (the one
/// the regressors were judged against; [`gls::Estimator::coefficient_sd`]).
pub(super) fn restate(
    steps: &mut [Step],
    data: &Data,
    removal: &Removal,
    model: &Model,
    open: &NoiseTerms,
    unit: &str,
) {
    let errors = joint_standard_errors(data, removal, open);
    for step in steps.iter_mut() {
        let (effect, names): (Effect, &[&'static str]) = match step.at_naming {
            Effect::RateRamp { .. } if removal.ramp => (
                Effect::RateRamp {
                    slope: model.terms.r,
                },
                &["slope"],
            ),
            Effect::Temperature { .. } if removal.temperature => (
                Effect::Temperature {
                    coeff: model.temp_coeff.unwrap_or(0.0),
                    rate_coeff: model.temp_rate_coeff.unwrap_or(0.0),
                },
                &["coeff", "rate_coeff"],
            ),
            Effect::Sinusoid {
                freq_hz,
                width_hz: 0.0,
                ..
            } => match jointly_fitted_tone(removal, model, freq_hz) {
                Some(effect) => (effect, &[]),
                None => continue,
            },
            _ => continue,
        };
        if effect == step.at_naming {
            continue;
        }
        step.effect = effect;
        let mut evidence = step
            .evidence
            .iter()
            .find(|e| e.effect == Some(step.at_naming))
            .cloned();
        if let Some(e) = evidence.as_mut() {
            // A tone keeps the errors of its own view at naming (frequency and amplitude).
            if !names.is_empty() {
                e.standard_errors = names
                    .iter()
                    .filter_map(|&name| Some((name, *errors.get(name)?)))
                    .collect();
            }
            step.standard_errors = e.standard_errors.clone();
            step.description = format!(
                "{}; estimated with every effect named (at naming, beside those before it: {}){}",
                described(&effect, e, unit),
                step.at_naming.describe(unit),
                weighed_words(&step.rivals, step.stands_in)
            );
        }
    }
}

/// The slow tone of `model` the removal regresses out at `freq_hz` (within its guard), at the
/// joint estimate of its amplitude.
fn jointly_fitted_tone(removal: &Removal, model: &Model, freq_hz: f64) -> Option<Effect> {
    let tone = removal
        .tones
        .iter()
        .filter(|t| (t.freq_hz - freq_hz).abs() < t.guard_hz)
        .min_by(|a, b| {
            (a.freq_hz - freq_hz)
                .abs()
                .total_cmp(&(b.freq_hz - freq_hz).abs())
        })?;
    let line = model.lines.iter().find(|l| l.freq_hz == tone.freq_hz)?;
    Some(Effect::Sinusoid {
        freq_hz: line.freq_hz,
        amplitude: line.amplitude,
        width_hz: 0.0,
    })
}

/// The standard errors of the ramp's and the temperature's joint least-squares coefficients
/// (beside a constant and every regressor of `removal`, on the record with its notches), by
/// parameter name.
fn joint_standard_errors(
    data: &Data,
    removal: &Removal,
    open: &NoiseTerms,
) -> BTreeMap<&'static str, f64> {
    let n = data.rate.len();
    let notched = if removal.notches.is_empty() {
        data.rate.to_vec()
    } else {
        notch(data.rate, data.rate_hz, &removal.notches)
    };
    let mut columns = vec![vec![1.0; n]];
    columns.extend(removal.design(n, data.rate_hz, data.temperature.as_ref()));
    let estimator = gls::Estimator::new(open, data.rate_hz, n);
    let Some(sd) = estimator.coefficient_sd(&columns, &notched) else {
        return BTreeMap::new();
    };
    // The design's order: the constant, the ramp, the temperature and its rate, the tones.
    let mut names: Vec<&'static str> = Vec::new();
    if removal.ramp {
        names.push("slope");
    }
    if removal.temperature && data.temperature.is_some() {
        names.extend(["coeff", "rate_coeff"]);
    }
    names.iter().zip(&sd[1..]).map(|(&k, &v)| (k, v)).collect()
}

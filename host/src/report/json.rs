//! The JSON document of `analyze --json`: per channel `name`, `unit`, `rate_hz`, `n`;
//! `deviations.<estimator>` with `tau`, `dev`, `lo`, `hi`, `n` (and `alpha`, `edf`); `noise`
//! with `Q N B K R`, each `{value, lo, hi, unit, detected, p_value}` in SI; `fit.goodness`;
//! `psd` with `freq` and `density` (one-sided, log-binned); `lines[]`, the spectral lines
//! removed before the fit, each `{freq_hz, amplitude, width_hz, power, statistic}` (amplitude
//! in the channel's unit, power in its square); plus conventional units, slope and PSD
//! read-outs and Kalibr's numbers. Conventions are stated in the document itself.

use super::{NOISE_TERMS, conventions, kalibr, support_of, term_of};
use crate::analysis::fit::NoiseFit;
use crate::analysis::pipeline::{ChannelResult, Options};
use crate::analysis::units::{self, NoiseTerm, SensorKind};
use crate::record::Record;
use serde_json::{Map, Value, json};

pub fn document(record: &Record, options: &Options, results: &[ChannelResult]) -> Value {
    json!({
        "tool": "imunoise",
        "version": env!("CARGO_PKG_VERSION"),
        "source": record.source,
        "rate_hz": record.rate_hz,
        "samples": record.len(),
        "duration_s": record.duration_s(),
        "data_type": options.data_type,
        "confidence": options.confidence,
        "conventions": conventions(options),
        "channels": results.iter().map(channel).collect::<Vec<_>>(),
        "kalibr": kalibr::numbers(results).ok(),
    })
}

fn channel(r: &ChannelResult) -> Value {
    let deviations: Map<String, Value> = r
        .deviations
        .iter()
        .map(|d| {
            let (dev, ci) = (&d.deviation, &d.intervals);
            (
                dev.estimator.to_string(),
                json!({
                    "tau": dev.tau, "dev": dev.dev, "lo": ci.lo, "hi": ci.hi, "n": dev.n,
                    "m": dev.m, "alpha": ci.alpha, "edf": ci.edf,
                }),
            )
        })
        .collect();
    let (noise, noise_conventional, fit_info) = match &r.fit {
        Ok(fit) => (
            terms(fit, r.kind, false),
            terms(fit, r.kind, true),
            json!({
                "method": "weighted non-negative least squares on the overlapping Allan variance; terms kept only when the data support them",
                "points": fit.points,
                "effective_points": fit.effective_points,
                "iterations": fit.iterations,
                "tau_min": fit.tau_min,
                "confidence": fit.confidence,
                "goodness": {
                    "reduced_chi2": fit.goodness.reduced_chi2,
                    "dof": fit.goodness.dof,
                    "p_value": fit.goodness.p_value,
                    "birge_ratio": fit.goodness.birge_ratio,
                    "poor": fit.goodness.poor(),
                    "definition": "weighted residual sum over its expectation under the model with the points' modelled correlation; dof and p-value by Satterthwaite's approximation; poor when p < 0.001",
                    "intervals": "every term's standard deviation was multiplied by birge_ratio = sqrt(max(1, reduced_chi2)) before its interval and detection test",
                },
            }),
        ),
        Err(e) => (Value::Null, Value::Null, json!({ "error": e })),
    };
    let psd = match &r.psd {
        Ok((full, binned)) => json!({
            "freq": binned.freq,
            "density": binned.density,
            "count": binned.count,
            "unit": format!("({})^2/Hz", r.unit),
            "sided": "one-sided",
            "segments": full.segments,
            "resolution_hz": full.freq.get(1).copied(),
        }),
        Err(e) => json!({ "error": e }),
    };
    json!({
        "name": r.name,
        "quantity": r.quantity,
        "unit": r.unit,
        "rate_hz": r.rate_hz,
        "n": r.n,
        "deviations": deviations,
        "noise": noise,
        "noise_conventional": noise_conventional,
        "fit": fit_info,
        "slope_readouts": readouts(r),
        "psd": psd,
        "psd_noise": psd_noise(r),
        "low_pass": r.fit.as_ref().ok().and_then(|f| f.low_pass.as_ref()),
        "lines": r.lines,
    })
}

/// Each term `{value, lo, hi, unit}`, in SI or in conventional units.
fn terms(fit: &NoiseFit, kind: SensorKind, conventional: bool) -> Value {
    let convert = |t: NoiseTerm, v: f64| {
        if conventional {
            units::conventional(kind, t, v)
        } else {
            units::si(kind, t, v)
        }
    };
    let map: Map<String, Value> = NOISE_TERMS
        .iter()
        .map(|&t| {
            let term = term_of(fit, t);
            let value = convert(t, term.value);
            (
                format!("{t:?}"),
                json!({
                    "value": value.value,
                    "lo": convert(t, term.lo).value,
                    "hi": convert(t, term.hi).value,
                    "unit": value.unit,
                    "detected": support_of(fit, t).detected,
                    "p_value": support_of(fit, t).p_value,
                }),
            )
        })
        .collect();
    Value::Object(map)
}

fn readouts(r: &ChannelResult) -> Value {
    let ro = &r.readouts;
    json!({
        "N": ro.n.as_ref().map(|l| json!({
            "value": l.value, "unit": units::si_unit(r.kind, NoiseTerm::N),
            "definition": "the -1/2 slope line's value at tau = 1 s",
            "tau_min": l.tau_min, "tau_max": l.tau_max, "points": l.points,
        })),
        "B": ro.b.as_ref().map(|b| json!({
            "value": b.value, "unit": units::si_unit(r.kind, NoiseTerm::B),
            "definition": "minimum Allan deviation / sqrt(2 ln2 / pi) (= / 0.664)",
            "tau": b.tau,
        })),
        "K": ro.k.as_ref().map(|l| json!({
            "value": l.value, "unit": units::si_unit(r.kind, NoiseTerm::K),
            "definition": "the +1/2 slope line's value at tau = 3 s",
            "tau_min": l.tau_min, "tau_max": l.tau_max, "points": l.points,
        })),
    })
}

fn psd_noise(r: &ChannelResult) -> Value {
    let p = match &r.psd_terms {
        Ok(p) => p,
        Err(e) => return json!({ "error": e }),
    };
    let one = |t: NoiseTerm, x: &crate::analysis::fit::psd::PsdReadout| {
        json!({
            "value": x.value, "lo": x.lo, "hi": x.hi, "unit": units::si_unit(r.kind, t),
            "resolved": x.resolved(), "dof": x.dof,
            "f_min": x.f_min, "f_max": x.f_max, "bins": x.bins,
        })
    };
    json!({
        "method": "weighted non-negative least squares of 2 N^2 + 2 B^2/(2 pi f) + 2 K^2/(2 pi f)^2 on the multi-resolution one-sided PSD; chi-squared intervals",
        "confidence": p.confidence,
        "f_min": p.f_min,
        "f_max": p.f_max,
        "points": p.points,
        "reduced_chi2": p.reduced_chi2,
        "segment_len": p.segment_len,
        "N": one(NoiseTerm::N, &p.n),
        "B": one(NoiseTerm::B, &p.b),
        "K": one(NoiseTerm::K, &p.k),
        "spectrum": {
            "freq": p.spectrum.iter().map(|s| s.freq).collect::<Vec<_>>(),
            "density": p.spectrum.iter().map(|s| s.density).collect::<Vec<_>>(),
            "dof": p.spectrum.iter().map(|s| s.dof).collect::<Vec<_>>(),
            "level": p.spectrum.iter().map(|s| s.level).collect::<Vec<_>>(),
        },
    })
}

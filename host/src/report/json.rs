//! The JSON document of `analyze --json`. The types here are its schema: [`Document`] is the
//! whole document, and every field below is one key (its name in the JSON is the field's, or
//! the `rename` beside it). [`document`] writes it as a `serde_json::Value`, whose objects
//! list their keys in alphabetical order.
//!
//! Per channel ([`Channel`]): `name`, `unit`, `rate_hz`, `n`; `deviations.<estimator>` with
//! `tau`, `dev`, `lo`, `hi`, `n` (and `m`, `alpha`, `edf`); `noise` with `Q N B K R`, each
//! `{value, lo, hi, unit, detected, p_value}` in SI; `fit.goodness`; `psd` with `freq` and
//! `density` (one-sided, log-binned); `lines[]`, the spectral lines removed before the fit,
//! each `{freq_hz, amplitude, width_hz, power, statistic, p_value}` (amplitude in the channel's unit,
//! power in its square); plus conventional units, slope and PSD read-outs and Kalibr's
//! numbers. A part that could not be computed is `{"error": "why"}` ([`Part::Failed`]).
//! Conventions are stated in the document itself.

use super::kalibr::{self, KalibrNumbers};
use super::{NOISE_TERMS, conventions, support_of, term_of};
use crate::analysis::DataType;
use crate::analysis::fit::psd::{PsdNoiseTerms, PsdReadout};
use crate::analysis::fit::{BiasReadout, NoiseFit, SlopeLine};
use crate::analysis::lines::Line;
use crate::analysis::low_pass::LowPass;
use crate::analysis::pipeline::{ChannelResult, DeviationResult, Options};
use crate::analysis::units::{self, NoiseTerm, SensorKind};
use crate::record::{Quantity, Record};
use serde::Serialize;
use serde_json::Value;
use std::collections::BTreeMap;

/// The whole document.
#[derive(Debug, Clone, Serialize)]
pub struct Document<'a> {
    /// `"imunoise"`.
    pub tool: &'static str,
    /// The version of imunoise that wrote it.
    pub version: &'static str,
    /// The record's source (file or session).
    pub source: &'a str,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Samples per channel.
    pub samples: usize,
    pub duration_s: f64,
    pub data_type: DataType,
    /// Two-sided confidence of every interval.
    pub confidence: f64,
    /// Units, model, interval, PSD and line conventions, in words ([`super::conventions`]).
    pub conventions: Value,
    pub channels: Vec<Channel<'a>>,
    /// Kalibr's four numbers; null when the record lacks a fitted gyro or accelerometer.
    pub kalibr: Option<KalibrNumbers>,
}

/// A part of a channel's results, or why it is missing.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum Part<T> {
    Done(T),
    Failed { error: String },
}

impl<T> Part<T> {
    fn of<'r, R, E: ToString>(result: &'r Result<R, E>, done: impl FnOnce(&'r R) -> T) -> Part<T> {
        match result {
            Ok(r) => Part::Done(done(r)),
            Err(e) => Part::Failed {
                error: e.to_string(),
            },
        }
    }
}

/// One channel.
#[derive(Debug, Clone, Serialize)]
pub struct Channel<'a> {
    pub name: &'a str,
    pub quantity: Quantity,
    /// u, the channel's unit.
    pub unit: &'static str,
    pub rate_hz: f64,
    /// Samples analysed.
    pub n: usize,
    /// Each requested estimator's curve, by its name (`oadev`, `mdev`, ...).
    pub deviations: BTreeMap<String, Curve<'a>>,
    /// The IEEE-952 terms in SI; null without a noise fit.
    pub noise: Option<Terms>,
    /// The same in conventional units (deg/h, ...).
    pub noise_conventional: Option<Terms>,
    pub fit: Part<FitSummary>,
    pub slope_readouts: SlopeReadouts,
    pub psd: Part<Spectrum<'a>>,
    pub psd_noise: Part<PsdNoise>,
    /// The sensor's low-pass filter the fit modelled; null when none (or no fit).
    pub low_pass: Option<&'a LowPass>,
    /// The spectral lines removed before the fit.
    pub lines: &'a [Line],
    /// How the channel was computed when the record was not held in memory (what is exact,
    /// what approximated, what left out); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub computation: Option<&'a str>,
}

/// One estimator's curve with its intervals, point by point.
#[derive(Debug, Clone, Serialize)]
pub struct Curve<'a> {
    /// s.
    pub tau: &'a [f64],
    /// u.
    pub dev: &'a [f64],
    pub lo: &'a [f64],
    pub hi: &'a [f64],
    /// Terms summed (Stable32's `#`).
    pub n: &'a [usize],
    /// Averaging factors, tau = m tau0.
    pub m: &'a [usize],
    /// The power-law noise type each interval assumed.
    pub alpha: &'a [i32],
    /// Equivalent degrees of freedom.
    pub edf: &'a [f64],
}

/// The five IEEE-952 terms.
#[derive(Debug, Clone, Serialize)]
pub struct Terms {
    #[serde(rename = "Q")]
    pub q: TermValue,
    #[serde(rename = "N")]
    pub n: TermValue,
    #[serde(rename = "B")]
    pub b: TermValue,
    #[serde(rename = "K")]
    pub k: TermValue,
    #[serde(rename = "R")]
    pub r: TermValue,
}

/// One fitted term with its interval and detection test.
#[derive(Debug, Clone, Serialize)]
pub struct TermValue {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
    pub unit: &'static str,
    pub detected: bool,
    pub p_value: f64,
}

/// How the noise fit was made and how well it describes the curve.
#[derive(Debug, Clone, Serialize)]
pub struct FitSummary {
    pub method: &'static str,
    pub points: usize,
    pub effective_points: f64,
    pub iterations: usize,
    /// s.
    pub tau_min: f64,
    pub confidence: f64,
    pub goodness: Goodness,
}

/// [`crate::analysis::fit::Goodness`] with its definition.
#[derive(Debug, Clone, Serialize)]
pub struct Goodness {
    pub reduced_chi2: f64,
    pub dof: f64,
    pub p_value: f64,
    pub birge_ratio: f64,
    pub poor: bool,
    pub definition: &'static str,
    pub intervals: &'static str,
}

/// The classic graphical read-outs, each null when the curve does not show it.
#[derive(Debug, Clone, Serialize)]
pub struct SlopeReadouts {
    #[serde(rename = "N")]
    pub n: Option<SlopeReadout>,
    #[serde(rename = "B")]
    pub b: Option<MinimumReadout>,
    #[serde(rename = "K")]
    pub k: Option<SlopeReadout>,
}

/// A tangent line's read-out.
#[derive(Debug, Clone, Serialize)]
pub struct SlopeReadout {
    pub value: f64,
    pub unit: &'static str,
    pub definition: &'static str,
    /// The taus the line was fitted through, s.
    pub tau_min: f64,
    pub tau_max: f64,
    pub points: usize,
}

/// Bias instability from the Allan minimum.
#[derive(Debug, Clone, Serialize)]
pub struct MinimumReadout {
    pub value: f64,
    pub unit: &'static str,
    pub definition: &'static str,
    /// The tau of the minimum, s.
    pub tau: f64,
}

/// The log-binned Welch PSD.
#[derive(Debug, Clone, Serialize)]
pub struct Spectrum<'a> {
    /// Hz.
    pub freq: &'a [f64],
    /// One-sided, `unit`.
    pub density: &'a [f64],
    /// Welch ordinates per bin.
    pub count: &'a [usize],
    pub unit: String,
    pub sided: &'static str,
    pub segments: usize,
    /// The Welch estimate's frequency step, Hz.
    pub resolution_hz: Option<f64>,
}

/// N, B and K from the multi-resolution PSD.
#[derive(Debug, Clone, Serialize)]
pub struct PsdNoise {
    pub method: &'static str,
    pub confidence: f64,
    /// The band fitted, Hz.
    pub f_min: f64,
    pub f_max: f64,
    pub points: usize,
    pub reduced_chi2: f64,
    pub birge_ratio: f64,
    pub segment_len: usize,
    #[serde(rename = "N")]
    pub n: PsdTerm,
    #[serde(rename = "B")]
    pub b: PsdTerm,
    #[serde(rename = "K")]
    pub k: PsdTerm,
    pub spectrum: PsdPoints,
}

/// One PSD read-out.
#[derive(Debug, Clone, Serialize)]
pub struct PsdTerm {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
    pub unit: &'static str,
    pub resolved: bool,
    pub dof: f64,
    pub f_min: f64,
    pub f_max: f64,
    pub bins: usize,
}

/// The multi-resolution spectrum the PSD read-outs were fitted to, point by point.
#[derive(Debug, Clone, Serialize)]
pub struct PsdPoints {
    pub freq: Vec<f64>,
    pub density: Vec<f64>,
    pub dof: Vec<f64>,
    pub level: Vec<usize>,
}

impl<'a> Document<'a> {
    pub fn new(record: &'a Record, options: &Options, results: &'a [ChannelResult]) -> Self {
        Document {
            tool: "imunoise",
            version: env!("CARGO_PKG_VERSION"),
            source: &record.source,
            rate_hz: record.rate_hz,
            samples: super::samples(record, results),
            duration_s: super::duration_s(record, results),
            data_type: options.data_type,
            confidence: options.confidence,
            conventions: conventions(options),
            channels: results.iter().map(channel).collect(),
            kalibr: kalibr::numbers(results).ok(),
        }
    }
}

/// The document as a JSON value (keys in alphabetical order).
pub fn document(record: &Record, options: &Options, results: &[ChannelResult]) -> Value {
    // Every key is a string and every number a float or an integer, so this cannot fail.
    serde_json::to_value(Document::new(record, options, results))
        .expect("the document serialises to JSON")
}

fn channel(r: &ChannelResult) -> Channel<'_> {
    Channel {
        name: &r.name,
        quantity: r.quantity,
        unit: r.unit,
        rate_hz: r.rate_hz,
        n: r.n,
        deviations: r
            .deviations
            .iter()
            .map(|d| (d.deviation.estimator.to_string(), curve(d)))
            .collect(),
        noise: r.fit.as_ref().ok().map(|f| terms(f, r.kind, false)),
        noise_conventional: r.fit.as_ref().ok().map(|f| terms(f, r.kind, true)),
        fit: Part::of(&r.fit, fit_summary),
        slope_readouts: readouts(r),
        psd: Part::of(&r.psd, |(full, binned)| Spectrum {
            freq: &binned.freq,
            density: &binned.density,
            count: &binned.count,
            unit: format!("({})^2/Hz", r.unit),
            sided: "one-sided",
            segments: full.segments,
            resolution_hz: full.freq.get(1).copied(),
        }),
        psd_noise: Part::of(&r.psd_terms, |p| psd_noise(p, r.kind)),
        low_pass: r.fit.as_ref().ok().and_then(|f| f.low_pass.as_ref()),
        lines: &r.lines,
        computation: r.computation.as_deref(),
    }
}

fn curve(d: &DeviationResult) -> Curve<'_> {
    let (dev, ci) = (&d.deviation, &d.intervals);
    Curve {
        tau: &dev.tau,
        dev: &dev.dev,
        lo: &ci.lo,
        hi: &ci.hi,
        n: &dev.n,
        m: &dev.m,
        alpha: &ci.alpha,
        edf: &ci.edf,
    }
}

fn fit_summary(fit: &NoiseFit) -> FitSummary {
    let g = &fit.goodness;
    FitSummary {
        method: "weighted non-negative least squares on the overlapping Allan variance; terms kept only when the data support them",
        points: fit.points,
        effective_points: fit.effective_points,
        iterations: fit.iterations,
        tau_min: fit.tau_min,
        confidence: fit.confidence,
        goodness: Goodness {
            reduced_chi2: g.reduced_chi2,
            dof: g.dof,
            p_value: g.p_value,
            birge_ratio: g.birge_ratio,
            poor: g.poor(),
            definition: "weighted residual sum over its expectation under the model with the points' modelled correlation; dof and p-value by Satterthwaite's approximation; poor when p < 0.001",
            intervals: "every term's standard deviation was multiplied by birge_ratio = sqrt(max(1, reduced_chi2)) before its interval and detection test",
        },
    }
}

/// Each term `{value, lo, hi, unit}`, in SI or in conventional units.
fn terms(fit: &NoiseFit, kind: SensorKind, conventional: bool) -> Terms {
    let convert = |t: NoiseTerm, v: f64| {
        if conventional {
            units::conventional(kind, t, v)
        } else {
            units::si(kind, t, v)
        }
    };
    let [n, b, k, q, r] = NOISE_TERMS.map(|t| {
        let term = term_of(fit, t);
        let value = convert(t, term.value);
        TermValue {
            value: value.value,
            lo: convert(t, term.lo).value,
            hi: convert(t, term.hi).value,
            unit: value.unit,
            detected: support_of(fit, t).detected,
            p_value: support_of(fit, t).p_value,
        }
    });
    Terms { q, n, b, k, r }
}

fn readouts(r: &ChannelResult) -> SlopeReadouts {
    let ro = &r.readouts;
    let line = |l: &SlopeLine, term: NoiseTerm, definition: &'static str| SlopeReadout {
        value: l.value,
        unit: units::si_unit(r.kind, term),
        definition,
        tau_min: l.tau_min,
        tau_max: l.tau_max,
        points: l.points,
    };
    SlopeReadouts {
        n: ro
            .n
            .as_ref()
            .map(|l| line(l, NoiseTerm::N, "the -1/2 slope line's value at tau = 1 s")),
        b: ro.b.as_ref().map(|b: &BiasReadout| MinimumReadout {
            value: b.value,
            unit: units::si_unit(r.kind, NoiseTerm::B),
            definition: "minimum Allan deviation / sqrt(2 ln2 / pi) (= / 0.664)",
            tau: b.tau,
        }),
        k: ro
            .k
            .as_ref()
            .map(|l| line(l, NoiseTerm::K, "the +1/2 slope line's value at tau = 3 s")),
    }
}

fn psd_noise(p: &PsdNoiseTerms, kind: SensorKind) -> PsdNoise {
    let one = |t: NoiseTerm, x: &PsdReadout| PsdTerm {
        value: x.value,
        lo: x.lo,
        hi: x.hi,
        unit: units::si_unit(kind, t),
        resolved: x.resolved(),
        dof: x.dof,
        f_min: x.f_min,
        f_max: x.f_max,
        bins: x.bins,
    };
    PsdNoise {
        method: "weighted non-negative least squares of 2 N^2 + 2 B^2/(2 pi f) + 2 K^2/(2 pi f)^2 on the multi-resolution one-sided PSD of the record without its spectral lines; chi-squared intervals, each standard deviation multiplied by birge_ratio = sqrt(max(1, reduced_chi2))",
        confidence: p.confidence,
        f_min: p.f_min,
        f_max: p.f_max,
        points: p.points,
        reduced_chi2: p.reduced_chi2,
        birge_ratio: p.birge_ratio,
        segment_len: p.segment_len,
        n: one(NoiseTerm::N, &p.n),
        b: one(NoiseTerm::B, &p.b),
        k: one(NoiseTerm::K, &p.k),
        spectrum: PsdPoints {
            freq: p.spectrum.iter().map(|s| s.freq).collect(),
            density: p.spectrum.iter().map(|s| s.density).collect(),
            dof: p.spectrum.iter().map(|s| s.dof).collect(),
            level: p.spectrum.iter().map(|s| s.level).collect(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::Part;
    use crate::analysis::fit::FitError;
    use serde_json::json;

    #[test]
    fn a_part_is_its_value_or_its_error_text() {
        let failed: Result<f64, FitError> = Err(FitError::TooFewPoints(0));
        assert_eq!(
            serde_json::to_value(Part::of(&failed, |x| *x)).unwrap(),
            json!({ "error": "0 points: the noise fit needs at least 2" })
        );
        let done: Result<f64, FitError> = Ok(2.5);
        assert_eq!(
            serde_json::to_value(Part::of(&done, |x| *x)).unwrap(),
            json!(2.5)
        );
    }
}

//! The whole analysis of a record in one call: for every channel, in parallel, the requested
//! Allan-family deviations with confidence intervals, the IEEE-952 noise terms fitted to the
//! overlapping Allan variance, the classic slope read-outs, and the Welch PSD with the terms
//! read from it.

use super::psd::{self, BinnedPsd, Psd, WelchOptions, Window};
use super::taus::TauGrid;
use super::units::SensorKind;
use super::{DataType, Deviation, Estimator, allan, ci, fit, phase_from_rate, taus};
use crate::record::{Channel, Quantity, Record};
use rayon::prelude::*;
use serde::Serialize;
use std::borrow::Cow;

/// What to compute.
#[derive(Debug, Clone)]
pub struct Options {
    pub data_type: DataType,
    /// Estimators to report; the noise fit always uses the overlapping Allan variance.
    pub estimators: Vec<Estimator>,
    pub taus: TauGrid,
    /// Two-sided confidence of the intervals, e.g. 0.683 (1 sigma).
    pub confidence: f64,
    /// Welch segment length in samples; `None` chooses it from the record length
    /// ([`psd::segment_len_for`]).
    pub psd_segment: Option<usize>,
    pub psd_window: Window,
    /// Points per decade of the log-binned PSD used for plots, JSON and the PSD fit.
    pub psd_bins_per_decade: usize,
    /// Shortest tau of the noise fit, s; `None` leaves out the taus the sensor's low-pass
    /// filter shaped ([`fit::low_pass_onset`]).
    pub fit_tau_min: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            data_type: DataType::Rate,
            estimators: vec![Estimator::Oadev],
            taus: TauGrid::PerDecade(10),
            confidence: 0.683,
            psd_segment: None,
            psd_window: Window::Hann,
            psd_bins_per_decade: 20,
            fit_tau_min: None,
        }
    }
}

/// One estimator's curve with its intervals.
#[derive(Debug, Clone, Serialize)]
pub struct DeviationResult {
    pub deviation: Deviation,
    pub intervals: ci::Intervals,
}

/// Everything computed for one channel.
#[derive(Debug, Clone)]
pub struct ChannelResult {
    pub name: String,
    pub quantity: Quantity,
    /// What u is for the noise terms' units.
    pub kind: SensorKind,
    pub unit: &'static str,
    pub rate_hz: f64,
    /// Samples analysed.
    pub n: usize,
    pub deviations: Vec<DeviationResult>,
    /// The overlapping Allan curve the fit used (also in `deviations` when requested).
    pub fit_curve: DeviationResult,
    pub fit: Result<fit::NoiseFit, String>,
    pub readouts: fit::SlopeReadouts,
    /// The Welch PSD of the rate (one-sided), log-binned; `Err` says why there is none.
    pub psd: Result<(Psd, BinnedPsd), String>,
    pub psd_terms: Option<fit::PsdNoiseTerms>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    #[error("the record has no channels")]
    NoChannels,
    #[error(
        "channel '{channel}': {n} samples; at least {needed} are needed (three phase points make one Allan cluster at the smallest tau)"
    )]
    TooShort {
        channel: String,
        n: usize,
        needed: usize,
    },
    #[error("channel '{channel}': sample {index} is {value}; the data must be finite")]
    NotFinite {
        channel: String,
        index: usize,
        value: f64,
    },
    #[error(
        "channel '{channel}' is constant ({value} for all {n} samples): it has no noise to analyse"
    )]
    Constant {
        channel: String,
        value: f64,
        n: usize,
    },
    #[error("{0}")]
    Options(String),
}

/// Fewest rate samples worth analysing: enough for three clusters at tau0 and a handful of
/// taus to fit.
pub const MIN_SAMPLES: usize = 16;

/// Analyse every channel of `record` in parallel; `tick` is called once per finished step
/// (estimators + PSD per channel) for progress display.
pub fn analyze(
    record: &Record,
    options: &Options,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<ChannelResult>, AnalysisError> {
    if record.channels.is_empty() {
        return Err(AnalysisError::NoChannels);
    }
    if !(options.confidence > 0.0 && options.confidence < 1.0) {
        return Err(AnalysisError::Options(format!(
            "--confidence {}: between 0 and 1 (e.g. 0.683, 0.95)",
            options.confidence
        )));
    }
    record.channels.iter().try_for_each(validate)?;
    record
        .channels
        .par_iter()
        .map(|c| Ok(analyze_channel(c, record.rate_hz, options, tick)))
        .collect()
}

/// Steps [`analyze`] ticks per channel.
pub fn steps_per_channel(options: &Options) -> usize {
    // The fit's oadev curve is one more step when it is not among the reported estimators.
    let fit_curve = usize::from(!options.estimators.contains(&Estimator::Oadev));
    options.estimators.len() + fit_curve + 2
}

fn validate(c: &Channel) -> Result<(), AnalysisError> {
    let n = c.values.len();
    if n < MIN_SAMPLES {
        return Err(AnalysisError::TooShort {
            channel: c.name.clone(),
            n,
            needed: MIN_SAMPLES,
        });
    }
    if let Some(index) = c.values.iter().position(|v| !v.is_finite()) {
        return Err(AnalysisError::NotFinite {
            channel: c.name.clone(),
            index,
            value: c.values[index],
        });
    }
    if c.values.iter().all(|v| *v == c.values[0]) {
        return Err(AnalysisError::Constant {
            channel: c.name.clone(),
            value: c.values[0],
            n,
        });
    }
    Ok(())
}

fn analyze_channel(
    channel: &Channel,
    rate_hz: f64,
    options: &Options,
    tick: &(dyn Fn() + Sync),
) -> ChannelResult {
    let tau0 = 1.0 / rate_hz;
    // Phase for the Allan family; rate for the PSD.
    let (phase, rate): (Vec<f64>, Cow<[f64]>) = match options.data_type {
        DataType::Rate => (
            phase_from_rate(&channel.values, tau0),
            Cow::Borrowed(&channel.values[..]),
        ),
        DataType::Phase => (
            channel.values.clone(),
            Cow::Owned(
                channel
                    .values
                    .windows(2)
                    .map(|w| (w[1] - w[0]) / tau0)
                    .collect(),
            ),
        ),
    };
    let curve = |est: Estimator| {
        let factors = taus::factors(options.taus, allan::max_factor(est, phase.len()));
        allan::deviation(est, &phase, tau0, &factors)
    };
    let curves: Vec<Deviation> = options.estimators.par_iter().map(|&e| curve(e)).collect();
    let fit_deviation = curves
        .iter()
        .find(|d| d.estimator == Estimator::Oadev)
        .cloned()
        .unwrap_or_else(|| curve(Estimator::Oadev));
    let (fit, readouts) = fit_noise(&fit_deviation, phase.len(), options);
    // The intervals take the noise type from the fit where it has one (ci::intervals_with_model).
    let with_intervals = |deviation: Deviation| {
        let model = fit.as_ref().ok();
        let intervals = ci::intervals_with_model(&deviation, &phase, options.confidence, model);
        tick();
        DeviationResult {
            deviation,
            intervals,
        }
    };
    let deviations: Vec<DeviationResult> = curves.into_par_iter().map(with_intervals).collect();
    let fit_curve = deviations
        .iter()
        .find(|d| d.deviation.estimator == Estimator::Oadev)
        .cloned()
        .unwrap_or_else(|| with_intervals(fit_deviation));
    drop(phase);
    tick();
    let psd = spectrum(&rate, rate_hz, options);
    let psd_terms = psd
        .as_ref()
        .ok()
        .map(|(full, _)| fit::fit_psd(&full.freq, &full.density));
    tick();
    ChannelResult {
        name: channel.name.clone(),
        quantity: channel.quantity,
        kind: sensor_kind(channel.quantity),
        unit: channel.unit(),
        rate_hz,
        n: channel.values.len(),
        deviations,
        fit_curve,
        fit,
        readouts,
        psd,
        psd_terms,
    }
}

/// Gyro terms are in rad/s units, accelerometer terms in m/s^2 units; the rest in their own.
pub fn sensor_kind(quantity: Quantity) -> SensorKind {
    match quantity {
        Quantity::AngularRate => SensorKind::Gyro,
        Quantity::Acceleration => SensorKind::Accel,
        Quantity::Temperature | Quantity::Other => SensorKind::Other,
    }
}

fn fit_noise(
    d: &Deviation,
    n_phase: usize,
    options: &Options,
) -> (Result<fit::NoiseFit, String>, fit::SlopeReadouts) {
    let fit_options = fit::FitOptions {
        confidence: options.confidence,
        tau_min: options.fit_tau_min,
        ..fit::FitOptions::default()
    };
    let fitted = fit::fit_deviation(d, n_phase, &fit_options).map_err(|e| e.to_string());
    (fitted, fit::slope_readouts(&d.tau, &d.dev))
}

fn spectrum(rate: &[f64], rate_hz: f64, options: &Options) -> Result<(Psd, BinnedPsd), String> {
    let welch = WelchOptions {
        segment_len: options
            .psd_segment
            .unwrap_or_else(|| psd::segment_len_for(rate.len())),
        window: options.psd_window,
        ..WelchOptions::default()
    };
    let spectrum = psd::welch(rate, rate_hz, &welch).map_err(|e| e.to_string())?;
    let binned = psd::log_binned(&spectrum, options.psd_bins_per_decade);
    Ok((spectrum, binned))
}

//! The workflow on records whose low-pass filter is none of the generic shapes' own code:
//! filters written independently here, as a sensor or its firmware would run them — a
//! one-pole exponential average, a fourth-order Butterworth from the RBJ cookbook's
//! biquads (R. Bristow-Johnson, "Cookbook formulae for audio EQ biquad filter
//! coefficients"), a boxcar FIR and a Bartlett (triangular) FIR — at an internal rate of 2
//! to 8 times the output rate (1 to 8 for the FIRs), drawn per record (the MPU-6050 filters
//! at 1 kHz and outputs 100-500 Hz; the ADIS16405 runs its Bartlett at 819.2 Hz and outputs
//! at that rate or a fraction of it), then every k-th sample kept; and three run on the
//! output samples themselves, as
//! a record's author or a sensor without an oversampled stage would run them: the
//! exponential average and the RBJ Butterworths of second and fourth order. White noise
//! goes through the filter; flicker and random walk from the families' baseline
//! ([`families::baseline`]) are added after it.
//!
//! The workflow should name one effect, `low_pass`, and its N should be the output's
//! long-tau N: the input's times `sqrt(sum_j |H(j f_s)|^2)`, j = 0..k-1 (the internal rate's
//! aliases of DC, folded in by the decimation; 1.12 for an exponential average at a
//! cutoff of 0.3 f_s and k = 4), and the input's own for a filter run at the output rate.

use super::families::{self, Shape as RecordShape};
use super::*;
use crate::record::Channel;
use crate::sim::noise::AxisNoise;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// Internal rates of the oversampled recursive filters, in multiples of the output rate
/// (run at the output rate, they are the `...AtOutputRate` filters).
const OVERSAMPLED: std::ops::RangeInclusive<usize> = 2..=8;

/// Internal rates of the FIR filters, whose taps may also run at the output rate.
const FIR_INTERNAL: std::ops::RangeInclusive<usize> = 1..=8;

/// A filter written independently of [`crate::analysis::low_pass`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum SensorFilter {
    /// `y += (1 - a) (x - y)`, `a = exp(-2 pi f_c / f_i)`.
    ExponentialAverage,
    /// Two RBJ low-pass biquads, Q = 0.5412 and 1.3066.
    Butterworth4,
    /// The mean of the last m internal samples, m = round(0.443 f_i / f_c).
    Boxcar,
    /// A boxcar of m/2 samples applied twice.
    Bartlett,
    /// The exponential average on the output samples.
    ExponentialAverageAtOutputRate,
    /// One RBJ low-pass biquad, Q = 0.7071, on the output samples.
    Butterworth2AtOutputRate,
    /// Two RBJ low-pass biquads on the output samples.
    Butterworth4AtOutputRate,
}

const FILTERS: [SensorFilter; 7] = [
    SensorFilter::ExponentialAverage,
    SensorFilter::Butterworth4,
    SensorFilter::Boxcar,
    SensorFilter::Bartlett,
    SensorFilter::ExponentialAverageAtOutputRate,
    SensorFilter::Butterworth2AtOutputRate,
    SensorFilter::Butterworth4AtOutputRate,
];

/// The quality factors of the fourth-order Butterworth's two sections.
const BUTTERWORTH4_Q: [f64; 2] = [0.5412, 1.3066];

impl SensorFilter {
    /// The internal rates the filter is drawn at, in multiples of the output rate; `None`
    /// for a filter run at the output rate.
    fn internal_rates(self) -> Option<std::ops::RangeInclusive<usize>> {
        match self {
            SensorFilter::ExponentialAverageAtOutputRate
            | SensorFilter::Butterworth2AtOutputRate
            | SensorFilter::Butterworth4AtOutputRate => None,
            SensorFilter::Boxcar | SensorFilter::Bartlett => Some(FIR_INTERNAL),
            SensorFilter::ExponentialAverage | SensorFilter::Butterworth4 => Some(OVERSAMPLED),
        }
    }

    /// `x` (at the internal rate `fi`) through the filter with nominal cutoff `cutoff`.
    fn apply(self, x: &[f64], cutoff: f64, fi: f64) -> Vec<f64> {
        match self {
            SensorFilter::ExponentialAverage | SensorFilter::ExponentialAverageAtOutputRate => {
                let a = (-2.0 * PI * cutoff / fi).exp();
                let mut y = 0.0;
                x.iter()
                    .map(|v| {
                        y = a * y + (1.0 - a) * v;
                        y
                    })
                    .collect()
            }
            SensorFilter::Butterworth4 | SensorFilter::Butterworth4AtOutputRate => {
                rbj_low_passes(x, &BUTTERWORTH4_Q, cutoff, fi)
            }
            SensorFilter::Butterworth2AtOutputRate => {
                rbj_low_passes(x, &[std::f64::consts::FRAC_1_SQRT_2], cutoff, fi)
            }
            SensorFilter::Boxcar | SensorFilter::Bartlett => {
                let m = ((0.443 * fi / cutoff).round() as usize).max(2);
                let taps = if self == SensorFilter::Boxcar {
                    vec![1.0 / m as f64; m]
                } else {
                    let half = m.div_ceil(2);
                    let mut h = vec![0.0; 2 * half - 1];
                    for i in 0..half {
                        for j in 0..half {
                            h[i + j] += 1.0 / (half * half) as f64;
                        }
                    }
                    h
                };
                (0..x.len())
                    .map(|i| {
                        taps.iter()
                            .take(i + 1)
                            .enumerate()
                            .map(|(j, h)| h * x[i - j])
                            .sum()
                    })
                    .collect()
            }
        }
    }

    /// `sum_j |H(j f_s)|^2` over the aliases of DC at an internal rate of `internal` times
    /// the output's, from the impulse response.
    fn dc_folding(self, cutoff: f64, fi: f64, internal: usize) -> f64 {
        let mut impulse = vec![0.0; 1 << 16];
        impulse[0] = 1.0;
        let h = self.apply(&impulse, cutoff, fi);
        (0..internal)
            .map(|j| {
                let w = 2.0 * PI * j as f64 / internal as f64;
                let (re, im) = h.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, v)| {
                    (re + v * (w * k as f64).cos(), im - v * (w * k as f64).sin())
                });
                re * re + im * im
            })
            .sum()
    }
}

/// `x` at `fi` through RBJ low-pass biquads of quality factors `qs` in series, each with its
/// -3 dB point (for Q = 0.7071) at `cutoff` (RBJ cookbook, LPF).
fn rbj_low_passes(x: &[f64], qs: &[f64], cutoff: f64, fi: f64) -> Vec<f64> {
    qs.iter().fold(x.to_vec(), |v, &q| {
        let w0 = 2.0 * PI * cutoff / fi;
        let alpha = w0.sin() / (2.0 * q);
        let c = w0.cos();
        let b = [(1.0 - c) / 2.0, 1.0 - c, (1.0 - c) / 2.0];
        let a = [1.0 + alpha, -2.0 * c, 1.0 - alpha];
        let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        v.iter()
            .map(|&x0| {
                let y0 = (b[0] * x0 + b[1] * x1 + b[2] * x2 - a[1] * y1 - a[2] * y2) / a[0];
                (x2, x1, y2, y1) = (x1, x0, y1, y0);
                y0
            })
            .collect()
    })
}

/// A record of `shape` with white noise through `filter` (cutoff 10-30 % of the rate and,
/// for an oversampled filter, its internal rate drawn from `seed`), the output's long-tau N,
/// the cutoff and the internal rate in multiples of the output's.
fn record(filter: SensorFilter, shape: RecordShape, seed: u64) -> (Record, f64, f64, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut terms = families::baseline(&mut rng, shape.duration_s);
    let n_in = terms.n;
    let cutoff = shape.rate_hz * (0.1 + 0.2 * rng.random::<f64>());
    let internal = filter
        .internal_rates()
        .map_or(1, |rates| rng.random_range(rates));
    terms.n = 0.0;
    let samples = (shape.rate_hz * shape.duration_s) as usize;
    let mut values =
        AxisNoise::new(terms, shape.rate_hz, shape.duration_s, &mut rng).take(samples, &mut rng);
    let fi = shape.rate_hz * internal as f64;
    // White rate noise of density N has per-sample sd N sqrt(f) at rate f.
    let sigma = n_in * fi.sqrt();
    let settle = 4096;
    let white: Vec<f64> = (0..samples * internal + settle)
        .map(|_| sigma * rng.sample::<f64, _>(StandardNormal))
        .collect();
    let filtered = filter.apply(&white, cutoff, fi);
    for (v, w) in values
        .iter_mut()
        .zip(filtered[settle..].iter().step_by(internal))
    {
        *v += w;
    }
    let record = Record {
        source: format!("{filter:?} seed {seed}"),
        rate_hz: shape.rate_hz,
        channels: vec![Channel::named("gx", values)],
    };
    let n_out = n_in * filter.dc_folding(cutoff, fi, internal).sqrt();
    (record, n_out, cutoff, internal)
}

/// What the workflow made of one filter over a range of seeds.
struct FilterOutcome {
    filter: SensorFilter,
    /// Seeds named exactly `low_pass` (B and K aside, as in the families' study).
    exactly: usize,
    /// Seeds that named `low_pass` and neither of the terms a mis-modelled filter turns
    /// into (a short Gauss-Markov process, quantization), whatever else they named.
    filter_named: usize,
    /// The largest relative error of the final N against the output's.
    worst_n: f64,
}

fn study(shape: RecordShape, seeds: std::ops::Range<u64>) -> Vec<FilterOutcome> {
    let settings = Settings {
        seed: 1000,
        ..Settings::default()
    };
    // STUDY_FILTERS=Butterworth2AtOutputRate,Boxcar runs only those filters (names as in
    // `SensorFilter`'s Debug).
    let only = std::env::var("STUDY_FILTERS").unwrap_or_default();
    // STUDY_SEEDS=104,108 runs only those seeds of the range; STUDY_TABLES=1 prints every
    // record's table, not only those of records named otherwise.
    let chosen: Vec<u64> = std::env::var("STUDY_SEEDS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let seeds: Vec<u64> = seeds
        .filter(|s| chosen.is_empty() || chosen.contains(s))
        .collect();
    FILTERS
        .iter()
        .filter(|f| only.is_empty() || only.split(',').any(|o| o == format!("{f:?}")))
        .map(|&filter| {
            let mut outcome = FilterOutcome {
                filter,
                exactly: 0,
                filter_named: 0,
                worst_n: 0.0,
            };
            for &seed in &seeds {
                let (record, n_out, cutoff, internal) = record(filter, shape, seed);
                let o = run(&record, Some("gx"), None, &settings).unwrap();
                let named: Vec<&str> = o
                    .steps
                    .iter()
                    .map(|s| s.effect.kind())
                    .filter(|k| !matches!(*k, "bias_instability" | "rate_random_walk"))
                    .collect();
                let n_error = o.final_model().terms.n / n_out - 1.0;
                outcome.worst_n = outcome.worst_n.max(n_error.abs());
                if named.contains(&"low_pass")
                    && !named
                        .iter()
                        .any(|k| matches!(*k, "gauss_markov" | "quantization"))
                {
                    outcome.filter_named += 1;
                }
                if named == ["low_pass"] && std::env::var("STUDY_TABLES").is_err() {
                    outcome.exactly += 1;
                } else {
                    eprintln!(
                        "{filter:?} seed {seed}: named {named:?}\n{}",
                        report::table(&o)
                    );
                }
                let found = o.final_model().low_pass.as_ref();
                eprintln!(
                    "{filter:?} at {internal}x, seed {seed}: N {:+.2} %, Q {:.2e} (baseline {:.2e}), {:?} at {:.3} Hz against {cutoff:.3} Hz, Allan gap {:.2}",
                    100.0 * n_error,
                    o.final_model().terms.q,
                    o.baseline.terms.q,
                    found.and_then(|lp| lp.shape),
                    found.map_or(f64::NAN, |lp| lp.cutoff_hz),
                    o.steps.last().map_or(f64::NAN, |s| s.gap_after),
                );
            }
            eprintln!(
                "{filter:?}: {}/{} exactly right",
                outcome.exactly,
                seeds.len()
            );
            outcome
        })
        .collect()
}

/// One seed of each filter at CI size (1 h at 20 Hz): every record names the filter as
/// `low_pass`, with neither a short Gauss-Markov process nor quantization, and N within 3 %
/// of the output's (measured: at most 1.2 %, the oversampled filters drawn at 7 times the rate). An
/// unrelated effect named beside it is not asserted against here: each round may name one
/// by chance at the workflow's family-wise level (`FAMILY_ALPHA`, 0.05 per round), and the
/// study and the families measure that rate on more records.
#[test]
fn sensor_filters_at_ci_size() {
    for o in study(families::CI_SHAPE, 1..2) {
        assert_eq!(o.filter_named, 1, "{:?}", o.filter);
        assert!(o.worst_n < 0.03, "{:?}: N off by {}", o.filter, o.worst_n);
    }
}

/// Ten seeds of each filter at the study's size (3 h at 50 Hz): at least 9 of 10 named
/// exactly `low_pass`, N within 2 %.
#[test]
#[ignore]
fn sensor_filters_study() {
    for o in study(families::STUDY_SHAPE, 100..110) {
        assert!(o.exactly >= 9, "{:?}: {}/10", o.filter, o.exactly);
        assert!(o.worst_n < 0.02, "{:?}: N off by {}", o.filter, o.worst_n);
    }
}

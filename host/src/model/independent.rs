//! The workflow on noise that its own simulator did not make. Every null the workflow judges
//! against comes from [`crate::sim::noise::AxisNoise`] (flicker as a bank of first-order
//! processes, the random walk stepped with it), and so do the family records
//! ([`super::families`]); a record made another way could differ from those simulations in
//! ways no real effect explains and be given an effect. Here the same three terms are made
//! independently:
//! - flicker by shaping white noise in the frequency domain: `X_k` complex normal with
//!   `E|X_k|^2 = n S(f_k) / tau0`, `S(f) = B^2 / (2 pi f)` the two-sided flicker PSD (IEEE 952
//!   Table C.1), then one inverse real FFT (the standard synthesis of Timmer & Koenig, "On
//!   generating power law noise", A&A 300, 1995, without their amplitude randomisation);
//! - the random walk as the running sum of white increments of variance `K^2 tau0`;
//! - white noise of variance `N^2 / tau0` per sample.
//!
//! Levels are drawn from the family's ranges. Measured on twelve such records of 3 h at
//! 50 Hz (seeds 200..212, `INDEPENDENT_STUDY=1`): no effect named on any.

use super::families::{self, CI_SHAPE, STUDY_SHAPE, Shape};
use super::*;
use crate::record::{Channel, Record};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;
use std::f64::consts::PI;

/// Flicker of level `b` (u), `n` samples at `tau0`, shaped in the frequency domain.
fn shaped_flicker(b: f64, n: usize, tau0: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let c2r = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
    let mut spectrum = c2r.make_input_vec();
    let last = spectrum.len() - 1;
    for (k, z) in spectrum.iter_mut().enumerate().skip(1) {
        let f = k as f64 / (n as f64 * tau0);
        let sd = (n as f64 * b * b / (2.0 * PI * f) / tau0 / 2.0).sqrt();
        let mut draw = || sd * rng.sample::<f64, _>(StandardNormal);
        *z = Complex::new(draw(), draw());
    }
    // A real series' Nyquist bin (even n) is real.
    if n.is_multiple_of(2) {
        spectrum[last].im = 0.0;
    }
    let mut out = c2r.make_output_vec();
    c2r.process(&mut spectrum, &mut out)
        .expect("buffers of the plan's sizes");
    out.iter().map(|v| v / n as f64).collect()
}

/// White + flicker + random walk made independently of the simulator, levels drawn as in
/// the family records ([`families::baseline`]); channel `gx` (rad/s).
fn record(shape: Shape, seed: u64) -> Record {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let terms = families::baseline(&mut rng, shape.duration_s);
    let tau0 = 1.0 / shape.rate_hz;
    let n = (shape.rate_hz * shape.duration_s) as usize;
    let flicker = shaped_flicker(terms.b, n, tau0, &mut rng);
    let mut walk = 0.0;
    let values = flicker
        .iter()
        .map(|f| {
            walk += terms.k * tau0.sqrt() * rng.sample::<f64, _>(StandardNormal);
            f + walk + terms.n / tau0.sqrt() * rng.sample::<f64, _>(StandardNormal)
        })
        .collect();
    Record {
        source: format!("independent noise, seed {seed}"),
        rate_hz: shape.rate_hz,
        channels: vec![Channel::named("gx", values)],
    }
}

/// Effects named on `seeds` independent noise records, with the seed.
fn named(shape: Shape, seeds: std::ops::Range<u64>) -> Vec<(u64, Vec<&'static str>)> {
    let settings = Settings {
        seed: 1000,
        ..Settings::default()
    };
    seeds
        .map(|seed| {
            let o = run(&record(shape, seed), Some("gx"), None, &settings).expect("a valid record");
            let kinds = o.steps.iter().map(|s| s.effect.kind()).collect();
            (seed, kinds)
        })
        .collect()
}

/// At CI size (1 h at 20 Hz), six records: at most one names anything beyond the terms the
/// record has (B, K). The naming rule's family-wise level is 5 % per round, so one in six
/// would already be three times the expected 0.3. With `INDEPENDENT_STUDY=1` (and
/// `--release`): twelve records of 3 h at 50 Hz, none of which may name anything.
#[test]
fn independent_noise_gets_no_effect_named() {
    let study = std::env::var("INDEPENDENT_STUDY").is_ok_and(|v| v == "1");
    let (shape, seeds, allowed) = match study {
        true => (STUDY_SHAPE, 200..212, 0),
        false => (CI_SHAPE, 200..206, 1),
    };
    let results = named(shape, seeds);
    let false_names = results
        .iter()
        .filter(|(_, kinds)| {
            kinds
                .iter()
                .any(|k| !matches!(*k, "bias_instability" | "rate_random_walk"))
        })
        .count();
    assert!(false_names <= allowed, "{results:?}");
}

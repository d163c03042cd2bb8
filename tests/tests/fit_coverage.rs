//! The fitted IEEE-952 terms and their intervals, through the whole analysis (phase,
//! overlapping Allan deviation, fit), on simulated records with known N, B and K.
//!
//! Record: 4 h at 50 Hz (720,000 samples) with N = 1e-3 u/sqrt(Hz), B = 3e-4 u and
//! K = 2e-5 u*sqrt(Hz): white noise dominates tau < 25 s, the flicker floor 25-300 s and the
//! random walk beyond, so each term owns at least a decade of the curve. Fixed seeds 0..50.
//!
//! Why 50 Hz: the simulated flicker is band-limited at about 1/(2 pi tau0) (its fastest
//! process has tau_c = tau0), so at the first few taus its Allan variance is up to 25 % below
//! the model's floor. At 20 Hz that shortfall is 0.1 % of the (white-dominated) Allan
//! variance there and biases the fitted N by half its standard deviation; at 50 Hz it is
//! 2.5 times smaller.

use imunoise::analysis::fit::Term;
use imunoise::analysis::pipeline::{self, Options};
use imunoise::record::{Channel, Record};
use imunoise::sim::noise::{AxisNoise, NoiseTerms};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const RATE_HZ: f64 = 50.0;
const SAMPLES: usize = 4 * 3600 * 50;
const SEEDS: u64 = 50;

/// The fitted (N, B, K) terms of one simulated record, at `confidence`.
fn fitted(truth: NoiseTerms, seed: u64, confidence: f64) -> [Term; 3] {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let duration = SAMPLES as f64 / RATE_HZ;
    let mut axis = AxisNoise::new(truth, RATE_HZ, duration, &mut rng);
    let record = Record {
        source: format!("seed {seed}"),
        rate_hz: RATE_HZ,
        channels: vec![Channel::named("gx", axis.take(SAMPLES, &mut rng))],
    };
    let options = Options {
        confidence,
        ..Options::default()
    };
    let results = pipeline::analyze(&record, &options, &|| {}).unwrap();
    let fit = results[0].fit.as_ref().unwrap();
    [fit.n, fit.b, fit.k]
}

/// How many of the seeds' intervals contain the true N, B, K.
fn coverage(truth: NoiseTerms, confidence: f64, seeds: u64) -> [u64; 3] {
    let fits: Vec<[Term; 3]> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..seeds)
            .map(|seed| s.spawn(move || fitted(truth, seed, confidence)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let values = [truth.n, truth.b, truth.k];
    std::array::from_fn(|i| {
        fits.iter()
            .filter(|f| f[i].lo <= values[i] && values[i] <= f[i].hi)
            .count() as u64
    })
}

/// The criterion: each true term inside its 95 % interval in at least 90 % of 50
/// seeds. (Measured: N 49, B 47, K 49 of 50. With binomial(50, 0.95) the chance of fewer
/// than 45 is 4 %; the seeds are fixed, so the outcome is deterministic.)
#[test]
fn true_terms_lie_in_their_intervals() {
    let truth = NoiseTerms {
        n: 1e-3,
        b: 3e-4,
        k: 2e-5,
        ..NoiseTerms::default()
    };
    let covered = coverage(truth, 0.95, SEEDS);
    for (name, c) in ["N", "B", "K"].iter().zip(covered) {
        assert!(
            c * 10 >= SEEDS * 9,
            "{name}: {c} of {SEEDS} intervals contain the truth"
        );
    }
}

/// No false discoveries: on pure white noise the B and K intervals reach down to zero
/// (nothing is claimed that the data do not contain), in at least 90 % of the seeds.
#[test]
fn white_noise_claims_no_flicker_or_random_walk() {
    let truth = NoiseTerms {
        n: 1e-3,
        ..NoiseTerms::default()
    };
    let seeds = 20;
    let covered = coverage(truth, 0.95, seeds);
    assert!(covered[0] * 10 >= seeds * 9, "N covered {}", covered[0]);
    assert!(
        covered[1] * 10 >= seeds * 9,
        "B > 0 claimed in {}",
        seeds - covered[1]
    );
    assert!(
        covered[2] * 10 >= seeds * 9,
        "K > 0 claimed in {}",
        seeds - covered[2]
    );
}

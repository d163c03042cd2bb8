//! Which noise terms the fit claims, and how well its intervals cover the truth, through the
//! whole analysis (phase, overlapping Allan deviation, fit, curve intervals) on simulated
//! records of white rate noise plus rate random walk (no B, Q or R), and of white noise
//! plus flicker (B present).
//!
//! A term is "claimed" when its interval's lower bound is above 0. The fit keeps a term only
//! when the data support it at a 1 % level (`FitOptions::detection_level`), so on curves
//! without B or Q those are claimed in about 1 % of records.
//!
//! Binomial ranges: with `n` records and a per-record probability `p` a count lies within
//! `n p +- 2 sqrt(n p (1 - p))` about 95 % of the time; each bound below is derived from
//! that and stated with its numbers. The seeds are fixed, so every outcome is deterministic.

use imunoise::analysis::fit::NoiseFit;
use imunoise::analysis::pipeline::{self, ChannelResult, Options};
use imunoise::record::{Channel, Record};
use imunoise::sim::noise::{AxisNoise, NoiseTerms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const RATE_HZ: f64 = 100.0;

/// The analysis of one simulated record of `seconds` at [`RATE_HZ`].
fn analyse(truth: NoiseTerms, seconds: f64, seed: u64) -> ChannelResult {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = (RATE_HZ * seconds) as usize;
    let mut axis = AxisNoise::new(truth, RATE_HZ, seconds, &mut rng);
    let record = Record {
        source: format!("seed {seed}"),
        rate_hz: RATE_HZ,
        channels: vec![Channel::named("gx", axis.take(n, &mut rng))],
    };
    let mut results = pipeline::analyze(&record, &Options::default(), &|| {}).unwrap();
    results.remove(0)
}

/// Every seed's analysis, in parallel; `truth(seed)` draws the terms.
fn analyse_all(
    seeds: std::ops::Range<u64>,
    seconds: f64,
    truth: impl Fn(u64) -> NoiseTerms + Sync,
) -> Vec<(NoiseTerms, ChannelResult)> {
    std::thread::scope(|s| {
        let handles: Vec<_> = seeds
            .map(|seed| {
                let truth = &truth;
                s.spawn(move || {
                    let t = truth(seed);
                    (t, analyse(t, seconds, seed))
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

/// What the study counts over its records.
#[derive(Debug, Default)]
struct Tally {
    claimed_q: usize,
    claimed_b: usize,
    claimed_r: usize,
    covered_n: usize,
    covered_k: usize,
    /// Mean of K_fit / K_true - 1.
    k_bias: f64,
    /// The same over the records where K is detected, and their number.
    k_bias_detected: f64,
    k_detected: usize,
    /// Goodness p-values below 0.01.
    poor_fits: usize,
    /// (covered, total) of the curve's intervals at the last `LONG_TAUS` taus.
    long_tau_covered: usize,
    long_tau_total: usize,
}

/// How many of the longest taus count as "long" for the curve's interval coverage.
const LONG_TAUS: usize = 10;

fn fit_of(r: &ChannelResult) -> &NoiseFit {
    r.fit.as_ref().unwrap()
}

fn tally(results: &[(NoiseTerms, ChannelResult)]) -> Tally {
    let mut t = Tally::default();
    for (truth, r) in results {
        let f = fit_of(r);
        t.claimed_q += usize::from(f.q.lo > 0.0);
        t.claimed_b += usize::from(f.b.lo > 0.0);
        t.claimed_r += usize::from(f.r.lo > 0.0);
        t.covered_n += usize::from(f.n.lo <= truth.n && truth.n <= f.n.hi);
        t.covered_k += usize::from(f.k.lo <= truth.k && truth.k <= f.k.hi);
        t.k_bias += (f.k.value / truth.k - 1.0) / results.len() as f64;
        if f.support.k.detected {
            t.k_detected += 1;
            t.k_bias_detected += f.k.value / truth.k - 1.0;
        }
        t.poor_fits += usize::from(f.goodness.p_value < 0.01);
        let (d, iv) = (&r.fit_curve.deviation, &r.fit_curve.intervals);
        for i in d.tau.len().saturating_sub(LONG_TAUS)..d.tau.len() {
            let tau = d.tau[i];
            let adev = (truth.n * truth.n / tau + truth.k * truth.k * tau / 3.0).sqrt();
            t.long_tau_total += 1;
            t.long_tau_covered += usize::from(iv.lo[i] <= adev && adev <= iv.hi[i]);
        }
    }
    t.k_bias_detected /= t.k_detected.max(1) as f64;
    t
}

/// White noise N drawn log-uniformly from [5e-4, 2e-3] u/sqrt(Hz) and rate random walk K
/// set so the two cross (`N^2 / tau = K^2 tau / 3`) at a tau drawn log-uniformly from
/// [`cross_lo`, `cross_hi`] s.
fn white_and_random_walk(seed: u64, cross_lo: f64, cross_hi: f64) -> NoiseTerms {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let log_uniform = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| {
        (lo.ln() + rng.random::<f64>() * (hi / lo).ln()).exp()
    };
    let n = log_uniform(&mut rng, 5e-4, 2e-3);
    let cross = log_uniform(&mut rng, cross_lo, cross_hi);
    NoiseTerms {
        n,
        k: 3f64.sqrt() * n / cross,
        ..NoiseTerms::default()
    }
}

/// CI-sized: 16 records of 30 min, N from [5e-4, 2e-3], random walk crossing white noise
/// between 5 and 50 s (K = 1.7e-5 .. 7e-4), so K owns 1.5 to 2.5 decades of the curve.
#[test]
fn white_and_random_walk_claim_no_flicker_and_cover_n_and_k() {
    let results = analyse_all(0..16, 1800.0, |s| white_and_random_walk(s, 5.0, 50.0));
    let t = tally(&results);
    println!("{t:?}");
    // Null rate of a claim 1 % (detection level): P(>= 2 of 16) = 1.1 %.
    assert!(
        t.claimed_b <= 1 && t.claimed_q <= 1 && t.claimed_r <= 1,
        "{t:?}"
    );
    // 68.3 % intervals: 16 x 0.683 = 10.9 +- 2 x 1.86 -> 7 ..= 14 (rounded outwards).
    assert!((7..=14).contains(&t.covered_n), "{t:?}");
    assert!((7..=14).contains(&t.covered_k), "{t:?}");
    // K from the last 1.5-2.5 decades: relative s.d. of one record's K about 10-20 %, of
    // the mean of 16 about 4 %; a bias within 10 % is 2.5 s.d.
    assert!(t.k_bias.abs() < 0.1, "{t:?}");
    // Goodness: p < 0.01 in at most 2 of 16 if the p-value is calibrated (P = 1.1 %).
    assert!(t.poor_fits <= 2, "{t:?}");
    // The curve's 68.3 % intervals at the 10 longest taus (160 intervals, strongly
    // correlated within a record, so the range is wider than binomial(160): the mean of
    // 16 records' coverages of 10 taus each, s.d. about 0.47 / 4): 0.45 ..= 0.92.
    let cover = t.long_tau_covered as f64 / t.long_tau_total as f64;
    assert!((0.45..=0.92).contains(&cover), "{cover} {t:?}");
}

/// CI-sized: a flicker floor that owns 2-3 decades is claimed in every record. White N from
/// [5e-4, 2e-3], B such that the floor `0.664 B` meets `N / sqrt(tau)` at 1-10 s.
#[test]
fn a_flicker_floor_is_claimed() {
    let results = analyse_all(100..108, 1800.0, |seed| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = 5e-4 + 1.5e-3 * rng.random::<f64>();
        let cross = 10f64.powf(rng.random::<f64>());
        NoiseTerms {
            n,
            b: n / (0.441 * cross).sqrt(),
            ..NoiseTerms::default()
        }
    });
    for (truth, r) in &results {
        let f = fit_of(r);
        assert!(f.support.b.detected && f.b.lo > 0.0, "{truth:?}: {f:?}");
        // 68.3 % interval; 8 records: not asserted per record, only that B is near.
        assert!((f.b.value / truth.b - 1.0).abs() < 0.3, "{truth:?}: {f:?}");
    }
}

/// The issue's targets on 20 records of 2 h at 100 Hz, N = 1e-3, K = 1e-5 and K = 1e-4 (a
/// few seconds at opt-level 3). Run with
/// `cargo test --release -p imunoise-tests --test fit_support -- --ignored --nocapture`.
///
/// Bounds: B and Q each claimed in at most 3 of 20; N covered by its 68.3 % intervals in
/// 20 x 0.683 = 13.7 +- 2 x 2.1, i.e. 10 ..= 17 of 20; K in at least 10 of 20 (its intervals
/// are conservative where the random walk owns only the last decades: 178 of 200 records on
/// seeds 0..200 at K = 1e-5, 154 of 200 at K = 1e-4, so no upper bound); K's mean bias
/// within 10 %, overall and where K is detected. Measured on these seeds: at K = 1e-5, B, Q
/// and R claimed in none, K detected in all 20, covered in 20, bias -6.6 %; at K = 1e-4, K
/// detected in all, covered in 16, bias -1.2 %; on seeds 100..120 the same counts and -6.7 %
/// and +0.8 %. On seeds 0..200 at K = 1e-5 the mean bias is -6.5 %, -2.6 % where detected:
/// K is reported as 0 in the 8 of 200 records whose long-tau end a flicker floor describes
/// better. One record's K scatters by about 20 %, a mean of 20 by about 5 %, so another
/// seed range can land near the 10 % bound.
#[test]
#[ignore = "20 records of 2 h at 100 Hz per K; run with --release (see the doc comment)"]
fn issue_targets_on_two_hour_records() {
    for k in [1e-5, 1e-4] {
        let truth = NoiseTerms {
            n: 1e-3,
            k,
            ..NoiseTerms::default()
        };
        let results = analyse_all(0..20, 7200.0, |_| truth);
        let t = tally(&results);
        println!("K = {k:e}: {t:?}");
        assert!(t.claimed_b <= 3 && t.claimed_q <= 3, "{t:?}");
        assert!((10..=17).contains(&t.covered_n), "{t:?}");
        assert!(t.covered_k >= 10, "{t:?}");
        assert!(t.k_bias_detected.abs() < 0.1, "{t:?}");
        assert!(t.k_bias.abs() < 0.1, "{t:?}");
    }
}

/// Calibration of the goodness-of-fit p-value on 100 records of 30 min (white + rate random
/// walk, the CI test's draws; about 8 s). Measured on seeds 0..100: 1 below 0.01, 9 below
/// 0.05, 12 below 0.1, 52 below 0.5. Bounds (binomial, +-2 s.d., rounded outwards): below
/// 0.01 at most 3; below 0.5 within 40 ..= 60. With a flicker floor added (B at 0.3 times
/// the CI flicker test's) 9 fall below 0.01 and 67 below 0.5, most of it the
/// simulator's flicker lying 4 % below the textbook level the fit assumes
/// (docs/guide/simulation.md); with a flicker at that level, 4 and 60.
#[test]
fn goodness_calibration_study() {
    let results = analyse_all(0..100, 1800.0, |s| white_and_random_walk(s, 5.0, 50.0));
    let p: Vec<f64> = results
        .iter()
        .map(|(_, r)| fit_of(r).goodness.p_value)
        .collect();
    let below = |a: f64| p.iter().filter(|&&v| v < a).count();
    println!(
        "p < 0.01: {}, < 0.05: {}, < 0.1: {}, < 0.5: {} of {}",
        below(0.01),
        below(0.05),
        below(0.1),
        below(0.5),
        p.len()
    );
    assert!(below(0.01) <= 3, "{p:?}");
    assert!((40..=60).contains(&below(0.5)), "{p:?}");
}

//! Repeatability (`imunoise compare`): sessions simulated with the same model are not told
//! apart more often than the significance level allows, a session with twice the white
//! noise is, and the CLI compares a stored session with a file, as a table and as JSON.
//!
//! Records: 1 h at 50 Hz of N = 1e-3 u/sqrt(Hz), B = 3e-4 u, K = 2e-5 u*sqrt(Hz) (the model
//! of `tests/tests/fit_coverage.rs`, where each term owns a stretch of the curve: white
//! below 25 s, the flicker floor 25-300 s, the random walk beyond).

mod common;

use common::{TempStore, json};
use imunoise::analysis::compare::{self, Comparison, SessionFits};
use imunoise::analysis::pipeline::{self, ChannelResult, Options};
use imunoise::analysis::units::NoiseTerm;
use imunoise::record::{Channel, Record};
use imunoise::sim::noise::{AxisNoise, NoiseTerms};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const RATE_HZ: f64 = 50.0;
const SAMPLES: usize = 3600 * 50;
const ALPHA: f64 = 0.05;

fn truth() -> NoiseTerms {
    NoiseTerms {
        n: 1e-3,
        b: 3e-4,
        k: 2e-5,
        ..NoiseTerms::default()
    }
}

fn samples(terms: NoiseTerms, seed: u64, count: usize) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut axis = AxisNoise::new(terms, RATE_HZ, count as f64 / RATE_HZ, &mut rng);
    axis.take(count, &mut rng)
}

fn analysed(terms: NoiseTerms, seed: u64) -> Vec<ChannelResult> {
    let record = Record {
        source: format!("seed {seed}"),
        rate_hz: RATE_HZ,
        channels: vec![Channel::named("gx", samples(terms, seed, SAMPLES))],
    };
    pipeline::analyze(&record, &Options::default(), &|| {}).unwrap()
}

/// As `imunoise compare` does it: fits aligned to a common start, then the tests.
fn compared(sessions: &[Vec<ChannelResult>]) -> Comparison {
    let mut sessions = sessions.to_vec();
    compare::align_fit_start(&mut sessions, 0.683);
    let fits: Vec<SessionFits> = sessions
        .iter()
        .enumerate()
        .map(|(i, channels)| SessionFits {
            label: format!("run {i}"),
            channels,
        })
        .collect();
    compare::compare(&fits, ALPHA, 0.683)
}

fn in_parallel<T: Send>(jobs: Vec<Box<dyn FnOnce() -> T + Send + '_>>) -> Vec<T> {
    std::thread::scope(|s| {
        let handles: Vec<_> = jobs.into_iter().map(|job| s.spawn(job)).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

/// 30 independent pairs of same-model sessions (seeds 2i, 2i + 1). Per term the 30 verdicts
/// are independent Bernoulli trials with false-alarm probability at most alpha = 0.05 (the
/// intervals are, if anything, wide: `fit_coverage.rs`), so the count of pairs flagged is at
/// most Binomial(30, 0.05): mean 1.5, and P(count >= 6) = 0.003. Six or more flags in one
/// term would mean the test claims differences that are not there.
#[test]
fn same_model_sessions_are_not_told_apart_beyond_the_level() {
    const PAIRS: u64 = 30;
    let jobs: Vec<Box<dyn FnOnce() -> Vec<ChannelResult> + Send>> = (0..2 * PAIRS)
        .map(|seed| Box::new(move || analysed(truth(), seed)) as Box<_>)
        .collect();
    let runs = in_parallel(jobs);
    let mut flagged = [0usize; 3];
    for pair in runs.chunks(2) {
        let c = compared(pair);
        for (count, term) in flagged
            .iter_mut()
            .zip([NoiseTerm::N, NoiseTerm::B, NoiseTerm::K])
        {
            let row = c.rows.iter().find(|r| r.term == term).unwrap();
            assert_eq!(row.pairs.len(), 1);
            *count += usize::from(row.pairs[0].significant);
        }
    }
    eprintln!("false alarms in {PAIRS} pairs at alpha {ALPHA}: N, B, K = {flagged:?}");
    for (count, term) in flagged.iter().zip(["N", "B", "K"]) {
        assert!(
            *count <= 5,
            "{term}: {count} of {PAIRS} same-model pairs flagged"
        );
    }
}

/// Three sessions, the third with N doubled: its N differs from both others (the fitted N is
/// good to about 1 %, so a factor 2 is tens of standard errors), the first two agree on N,
/// and Holm's adjustment keeps the family's error at alpha.
#[test]
fn doubled_white_noise_is_flagged() {
    let doubled = NoiseTerms { n: 2e-3, ..truth() };
    let terms = [truth(), truth(), doubled];
    let jobs: Vec<Box<dyn FnOnce() -> Vec<ChannelResult> + Send>> = terms
        .into_iter()
        .zip(100..)
        .map(|(t, seed)| Box::new(move || analysed(t, seed)) as Box<_>)
        .collect();
    let c = compared(&in_parallel(jobs));
    let n = c.rows.iter().find(|r| r.term == NoiseTerm::N).unwrap();
    assert_eq!(n.pairs.len(), 3);
    for p in &n.pairs {
        let involves_third = p.b == 2;
        assert_eq!(p.significant, involves_third, "{p:?}");
        assert_eq!(p.scale, "log");
        assert!(p.p_holm >= p.p);
    }
    assert_eq!(n.flagged(), vec![0, 1, 2]);
}

/// A stored session (imported CSV) against a file with N doubled, and against a file of the
/// same model, through the CLI.
#[test]
fn cli_compares_a_session_with_files() {
    let store = TempStore::new();
    let write = |name: &str, n: f64, seed: u64| {
        let path = store.file(name);
        let terms = NoiseTerms {
            n,
            ..NoiseTerms::default()
        };
        let mut text = String::from("gx\n");
        for y in samples(terms, seed, 30_000) {
            text.push_str(&format!("{y}\n"));
        }
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let (base, same, doubled) = (
        write("base.csv", 1e-3, 1),
        write("same.csv", 1e-3, 2),
        write("doubled.csv", 2e-3, 3),
    );
    store.ok(&["import", &base, "--rate", "50", "--name", "bench-a"]);

    let doc = json(&store.run(&[
        "compare", "bench-a", &same, &doubled, "--rate", "50", "--json", "-",
    ]));
    let c = &doc["comparison"];
    assert!(c["sessions"][0].as_str().unwrap().contains("bench-a"));
    assert!(c["test"].as_str().unwrap().contains("Holm"));
    let rows = c["rows"].as_array().unwrap();
    let n = rows.iter().find(|r| r["term"] == "N").unwrap();
    assert_eq!(n["unit"], "rad/s/sqrt(Hz)");
    assert_eq!(n["values"].as_array().unwrap().len(), 3);
    let significant: Vec<(u64, u64)> = n["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["significant"] == true)
        .map(|p| (p["a"].as_u64().unwrap(), p["b"].as_u64().unwrap()))
        .collect();
    assert_eq!(significant, vec![(0, 2), (1, 2)]);

    let table = store.ok(&["compare", "bench-a", &doubled, "--rate", "50"]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("DIFFER: [1] vs [2]"), "{text}");
    assert!(text.contains("rows differ significantly: gx N"), "{text}");
    assert!(text.contains("rad/s/sqrt(Hz)"), "{text}");

    let one = store.run(&["compare", "bench-a"]);
    assert_eq!(
        one.status.code(),
        Some(2),
        "a single input is a usage error"
    );
    let missing = store.run(&["compare", "bench-a", "nope"]);
    assert_eq!(missing.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nope"));
}

/// Fits that started at different taus are refitted from the latest start, and then equal
/// the fit made from that start in the first place.
#[test]
fn fits_are_aligned_to_the_latest_start() {
    let record = Record {
        source: "white".into(),
        rate_hz: RATE_HZ,
        channels: vec![Channel::named("gx", samples(truth(), 9, 30_000))],
    };
    let from = |tau_min: f64| {
        let options = Options {
            fit_tau_min: Some(tau_min),
            ..Options::default()
        };
        pipeline::analyze(&record, &options, &|| {}).unwrap()
    };
    let mut sessions = vec![from(0.1), from(0.4)];
    let start = compare::align_fit_start(&mut sessions, 0.683).unwrap();
    let reference = from(0.4);
    let expected = reference[0].fit.as_ref().unwrap();
    assert!((start - expected.tau_min).abs() < 1e-12, "{start}");
    for session in &sessions {
        assert_eq!(session[0].fit.as_ref().unwrap(), expected);
    }
}

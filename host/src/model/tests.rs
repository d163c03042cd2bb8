//! The workflow on families of generated records ([`super::families`]): each kind of hidden
//! effect over several seeds, every parameter drawn from a range. The default tests are
//! sized for CI (1 h at 20 Hz, 3 seeds per kind); `study_families` is the full study (3 h at
//! 50 Hz, 10 seeds per kind), run with
//! `cargo test --release -p imunoise --lib model::tests::study -- --ignored --nocapture`.

use super::families::{self, Kind, Shape};
use super::*;

const KINDS: [Kind; 10] = [
    Kind::LowPass,
    Kind::None,
    Kind::NoneWithTemperature,
    Kind::GaussMarkov,
    Kind::SlowSinusoid,
    Kind::Tone,
    Kind::Ramp,
    Kind::Temperature,
    Kind::ToneAndRamp,
    Kind::SlowSinusoidAndTemperature,
];

fn settings() -> Settings {
    Settings {
        seed: 1000,
        ..Settings::default()
    }
}

/// The kinds named, sorted, and the outcome.
fn named(kind: Kind, shape: Shape, seed: u64) -> (Vec<&'static str>, Outcome) {
    let record = families::record(kind, shape, seed);
    let o = run(&record, Some("gx"), None, &settings()).unwrap();
    let mut kinds: Vec<&'static str> = o.steps.iter().map(|s| s.effect.kind()).collect();
    kinds.sort_unstable();
    (kinds, o)
}

/// Seeds per kind whose named effects are exactly the hidden ones.
fn study(shape: Shape, seeds: std::ops::Range<u64>, kinds: &[Kind]) -> Vec<(Kind, usize, usize)> {
    kinds
        .iter()
        .map(|&kind| {
            let mut right = 0;
            for seed in seeds.clone() {
                let (got, o) = named(kind, shape, seed);
                if got == kind.expected() {
                    right += 1;
                } else {
                    eprintln!("{kind:?} seed {seed}: named {got:?}\n{}", report::table(&o));
                }
            }
            eprintln!("{kind:?}: {right}/{} right", seeds.end - seeds.start);
            (kind, right, (seeds.end - seeds.start) as usize)
        })
        .collect()
}

#[test]
fn ranges_group_runs() {
    let tau = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let z = [0.0, 3.0, 2.5, -3.0, 0.0, 2.1];
    let r = ranges(&tau, &z);
    assert_eq!(r.len(), 3);
    assert_eq!((r[0].tau_lo, r[0].tau_hi, r[0].sign), (2.0, 3.0, 1));
    assert_eq!((r[1].tau_lo, r[1].tau_hi, r[1].sign), (4.0, 4.0, -1));
    assert_eq!((r[2].tau_lo, r[2].tau_hi, r[2].sign), (6.0, 6.0, 1));
}

#[test]
fn model_toml_parses_as_a_model_file() {
    let m = Model {
        terms: NoiseTerms {
            n: 1e-4,
            k: 1e-7,
            gauss_markov: Some(crate::sim::noise::GaussMarkov {
                sigma: 3e-5,
                tau_c: 50.0,
            }),
            ..NoiseTerms::default()
        },
        ..Model::default()
    };
    let text = report::model_toml(Quantity::AngularRate, &m);
    let parsed = crate::sim::model_file::parse(&text, std::path::Path::new("model.toml"));
    assert!(parsed.is_ok(), "{text}: {:?}", parsed.err());
}

const CI_SHAPE: Shape = Shape {
    rate_hz: 20.0,
    duration_s: 3600.0,
};

/// Every kind on three seeds at CI size: at most one miss per kind (the full study's 9 of 10
/// leaves a miss in three seeds about a 27 % chance per kind; two misses in three would be a
/// failure rate far above the study's).
#[test]
fn families_at_ci_size() {
    let results = study(CI_SHAPE, 1..4, &KINDS);
    for (kind, right, total) in results {
        assert!(right + 1 >= total, "{kind:?}: {right}/{total}");
    }
}

#[test]
#[ignore = "the full study: 3 h at 50 Hz, 10 seeds per kind; run with --release"]
fn study_families() {
    let shape = Shape {
        rate_hz: 50.0,
        duration_s: 3.0 * 3600.0,
    };
    let results = study(shape, 100..110, &KINDS);
    for (kind, right, total) in &results {
        eprintln!("{kind:?}: {right}/{total}");
    }
    for (kind, right, total) in results {
        assert!(right * 10 >= 9 * total, "{kind:?}: {right}/{total}");
    }
}

#[test]
#[ignore]
fn debug_study() {
    let kinds: Vec<Kind> = std::env::var("KINDS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|k| KINDS.iter().copied().find(|x| format!("{x:?}") == k))
        .collect();
    let hours: f64 = std::env::var("HOURS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3.0);
    let rate: f64 = std::env::var("RATE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50.0);
    let seeds: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let shape = Shape {
        rate_hz: rate,
        duration_s: hours * 3600.0,
    };
    study(shape, 100..100 + seeds, &kinds);
}

#[test]
#[ignore]
fn debug_one() {
    let kind = KINDS
        .iter()
        .copied()
        .find(|x| format!("{x:?}") == std::env::var("KIND").unwrap_or_default())
        .unwrap_or(Kind::None);
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let hours: f64 = std::env::var("HOURS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    let rate: f64 = std::env::var("RATE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10.0);
    let shape = Shape {
        rate_hz: rate,
        duration_s: hours * 3600.0,
    };
    let (_, o) = named(kind, shape, seed);
    eprintln!("{}", report::table(&o));
    eprintln!("{:?}", o.baseline_fit);
    let last = o.final_comparison();
    for s in &o.steps {
        eprintln!("{:?}", s.model);
    }
    for (i, t) in o.measured.tau.iter().enumerate() {
        eprintln!(
            "{t:10.3} {:.4e} base {:.4e} {:.3} final {:.4e} {:.3} edf {:.1}",
            o.measured.dev[i],
            o.initial.band.mean_log[i].exp(),
            o.initial.band.std_log[i],
            last.band.mean_log[i].exp(),
            last.band.std_log[i],
            0.0
        );
    }
}

#[test]
#[ignore]
fn debug_flicker_shape() {
    let rate = 50.0;
    let n = (3.0 * 3600.0 * rate) as usize;
    let terms = NoiseTerms {
        b: 1.0,
        ..NoiseTerms::default()
    };
    let m: Vec<usize> = [
        1usize, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 50000,
    ]
    .to_vec();
    let mut acc = vec![0.0; m.len()];
    let reps = 8;
    for seed in 0..reps {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut g = AxisNoise::new(terms, rate, n as f64 / rate, &mut rng);
        let y = g.take(n, &mut rng);
        let a = evidence::allan_avar(y, rate, &m);
        for (s, v) in acc.iter_mut().zip(a) {
            *s += v / reps as f64;
        }
    }
    for (mm, a) in m.iter().zip(acc) {
        eprintln!(
            "tau {:8.2} avar/B^2 {:.4} (flat {:.4})",
            *mm as f64 / rate,
            a,
            2.0 * 2f64.ln() / std::f64::consts::PI
        );
    }
}

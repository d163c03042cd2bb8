//! Filter-ready noise parameters (`imunoise analyze --filter-period/--filter`): the
//! Gauss-Markov bias recovered from a simulated record, the discrete-time convention checked
//! by simulating with the produced numbers, and the CLI's table, JSON and YAML.

mod common;

use imunoise::analysis::filter::{self, FilterNoise};
use imunoise::analysis::fit::{Goodness, NoiseFit, Support, Term, TermSupport};
use imunoise::analysis::gauss_markov::{self, GaussMarkovFit};
use imunoise::analysis::pipeline::{self, Options};
use imunoise::analysis::units::SensorKind;
use imunoise::analysis::{Estimator, allan, ci, phase_from_rate};
use imunoise::record::{Channel, Record};
use imunoise::sim::noise::{AxisNoise, GaussMarkov, NoiseTerms, gauss_markov_avar};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// White noise N = 1e-3 rad/s/sqrt(Hz) plus a Gauss-Markov bias of sigma = 1e-3 rad/s and
/// tau_c = 20 s, 2 h at 20 Hz. The Gauss-Markov hump (Allan deviation 0.617 sigma at 38 s)
/// is 94 % of the Allan variance there, so the data support it.
///
/// Tolerances: the record holds T / tau_c = 360 correlation times. The time average of g^2
/// over T has variance 2 sigma^4 tau_c / T (the autocovariance of g^2 is
/// 2 sigma^4 e^(-2|s|/tau_c)), so sigma^2 is known to sqrt(2 tau_c / T) = 7.5 % and sigma to
/// 3.7 %; allowing 4 standard deviations: 15 %. tau_c is fixed by the hump's position, which
/// shares that 7.5 % relative scatter, plus half a grid step (7.5 %): 4 x 7.5 % + 7.5 % =
/// 37.5 %. Five seeds.
#[test]
fn gauss_markov_bias_is_recovered_from_a_simulated_record() {
    let gm = GaussMarkov {
        sigma: 1e-3,
        tau_c: 20.0,
    };
    let terms = NoiseTerms {
        n: 1e-3,
        gauss_markov: Some(gm),
        ..NoiseTerms::default()
    };
    let fits: Vec<GaussMarkovFit> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..5u64)
            .map(|seed| s.spawn(move || recovered(terms, seed)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (seed, fit) in fits.iter().enumerate() {
        eprintln!(
            "seed {seed}: sigma {:.4e} rad/s, tau_c {:.2} s, N {:.4e} rad/s/sqrt(Hz)",
            fit.sigma, fit.tau_c, fit.n
        );
        assert!((fit.sigma / gm.sigma - 1.0).abs() < 0.15, "{fit:?}");
        assert!((fit.tau_c / gm.tau_c - 1.0).abs() < 0.375, "{fit:?}");
    }
}

fn recovered(terms: NoiseTerms, seed: u64) -> GaussMarkovFit {
    let (rate, samples) = (20.0, 2 * 3600 * 20);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut axis = AxisNoise::new(terms, rate, samples as f64 / rate, &mut rng);
    let record = Record {
        source: format!("seed {seed}"),
        rate_hz: rate,
        channels: vec![Channel::named("gx", axis.take(samples, &mut rng))],
    };
    let results = pipeline::analyze(&record, &Options::default(), &|| {}).unwrap();
    gauss_markov::fit_channel(&results[0]).unwrap()
}

/// White noise and a random walk alone (no hump): over ten seeds, the Gauss-Markov bias is
/// declined with a reason (a finite record of a random walk can look like a slow
/// Gauss-Markov, which is what the turnover and improvement criteria guard against), and
/// the filter numbers still come for N and K.
#[test]
fn white_and_random_walk_give_no_gauss_markov() {
    let terms = NoiseTerms {
        n: 1e-3,
        k: 3e-5,
        ..NoiseTerms::default()
    };
    let outcomes: Vec<Result<(), String>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..10u64)
            .map(|seed| s.spawn(move || no_gauss_markov(terms, seed)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let named: Vec<&String> = outcomes.iter().filter_map(|o| o.as_ref().err()).collect();
    assert!(named.is_empty(), "{named:?}");
}

fn no_gauss_markov(terms: NoiseTerms, seed: u64) -> Result<(), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut axis = AxisNoise::new(terms, 20.0, 7200.0, &mut rng);
    let record = Record {
        source: "white + random walk".into(),
        rate_hz: 20.0,
        channels: vec![Channel::named("gx", axis.take(144_000, &mut rng))],
    };
    let results = pipeline::analyze(&record, &Options::default(), &|| {}).unwrap();
    let f = &filter::for_channels(&results, 0.01).unwrap()[0];
    match &f.gauss_markov {
        Ok(g) => Err(format!("seed {seed}: {g:?}")),
        Err(reason) => {
            eprintln!("seed {seed}: {reason}");
            let reason = reason.to_string();
            assert!(reason.contains("not supported") || reason.contains("no Gauss-Markov"));
            assert!(!f.random_walk.upper_bound);
            Ok(())
        }
    }
}

/// The convention, checked independently: simulate the discrete-time model a filter would
/// run — x_k = w_k + b_k + g_k with w_k ~ N(0, sample_std^2), b_(k+1) = b_k + N(0, Q_d of the
/// random walk), g_(k+1) = phi g_k + N(0, Q_d of the Gauss-Markov) — with the numbers
/// `filter_noise` produced for dt = 0.05 s, and require its overlapping Allan variance to be
/// the continuous model's, N^2/tau + K^2 tau/3 + AVAR_GM(tau), at octave taus.
///
/// Tolerance per tau: the two-sided 99.99 % chi-squared interval with the smallest EDF of
/// white, flicker and random-walk FM at that tau (the least certain noise type present, so
/// the interval is never too narrow); 12 taus at 1e-4 each make a false failure 1e-3 likely.
/// A wrong convention (e.g. Q_d = K^2 / dt, or phi^2 instead of 1 - phi^2) misses by factors.
#[test]
fn discrete_simulation_with_q_d_reproduces_the_continuous_allan_curve() {
    let dt = 0.05;
    let (n, k) = (2e-3, 4e-5);
    let gm = GaussMarkov {
        sigma: 5e-4,
        tau_c: 30.0,
    };
    let f = filter_numbers(n, k, gm, dt);
    let g = f.gauss_markov.as_ref().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut normal = move || rng.sample::<f64, _>(StandardNormal);
    let count = 400_000; // 5.6 h
    let mut bias = 0.0;
    let mut markov = gm.sigma * normal(); // the stationary distribution
    let rate: Vec<f64> = (0..count)
        .map(|_| {
            let y = f.white.sample_std.value * normal() + bias + markov;
            bias += f.random_walk.variance_per_step.value.sqrt() * normal();
            markov = g.phi * markov + g.variance_per_step.value.sqrt() * normal();
            y
        })
        .collect();
    let phase = phase_from_rate(&rate, dt);
    let factors: Vec<usize> = (0..12).map(|i| 1 << i).collect();
    let d = allan::deviation(Estimator::Oadev, &phase, dt, &factors);
    for ((&tau, &dev), &m) in d.tau.iter().zip(&d.dev).zip(&d.m) {
        let model = n * n / tau + k * k * tau / 3.0 + gauss_markov_avar(gm, tau);
        let edf = [0, -1, -2]
            .map(|alpha| ci::edf(Estimator::Oadev, alpha, m, phase.len()))
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        let (lo, hi) = ci::chi2_bounds(dev, edf, 0.9999);
        eprintln!(
            "tau {tau:8.2} s: sim {dev:.4e}, model {:.4e} rad/s",
            model.sqrt()
        );
        assert!(
            lo <= model.sqrt() && model.sqrt() <= hi,
            "tau {tau}: model {} outside [{lo}, {hi}]",
            model.sqrt()
        );
    }
}

fn filter_numbers(n: f64, k: f64, gm: GaussMarkov, dt: f64) -> FilterNoise {
    let term = |value: f64| Term {
        value,
        lo: value * 0.9,
        hi: value * 1.1,
    };
    let fit = NoiseFit {
        q: Term {
            value: 0.0,
            lo: 0.0,
            hi: 0.0,
        },
        n: term(n),
        b: term(0.0),
        k: term(k),
        r: term(0.0),
        confidence: 0.683,
        points: 40,
        effective_points: 10.0,
        reduced_chi2: 1.0,
        iterations: 3,
        tau_min: dt,
        low_pass: None,
        goodness: Goodness::NOMINAL,
        support: TermSupport::same(Support {
            detected: true,
            p_value: 0.0,
        }),
    };
    let gm_fit = GaussMarkovFit {
        sigma: gm.sigma,
        tau_c: gm.tau_c,
        q: 0.0,
        n,
        k,
        peak_share: 1.0,
    };
    filter::filter_noise("gx", SensorKind::Gyro, "rad/s", &fit, Ok(gm_fit), dt)
}

/// `imunoise analyze FILE --rate 50 ARGS...`.
fn analyze(args: &[&str]) -> std::process::Output {
    common::imunoise()
        .arg("analyze")
        .args(args)
        .args(["--rate", "50"])
        .output()
        .unwrap()
}

/// `analyze --filter-period 0.01 --filter f.json --filter f.yaml`: the table, both files and
/// the `filter` key of the JSON document, each number derived from the fitted N and K as the
/// module documentation says.
#[test]
fn cli_writes_filter_json_and_yaml() {
    let dir = common::scratch();
    let csv = dir.path().join("gx.csv");
    let terms = NoiseTerms {
        n: 1e-3,
        k: 2e-5,
        ..NoiseTerms::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut axis = AxisNoise::new(terms, 50.0, 1200.0, &mut rng);
    let mut text = String::from("gx\n");
    for y in axis.take(60_000, &mut rng) {
        text.push_str(&format!("{y}\n"));
    }
    std::fs::write(&csv, text).unwrap();
    let (json_path, yaml_path) = (dir.path().join("f.json"), dir.path().join("f.yaml"));
    let (csv, json, yaml) = (
        csv.to_str().unwrap(),
        json_path.to_str().unwrap(),
        yaml_path.to_str().unwrap(),
    );
    let out = analyze(&[
        csv,
        "--filter-period",
        "0.01",
        "--filter",
        json,
        "--filter",
        yaml,
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("Filter noise for period dt = 0.01 s"),
        "{stdout}"
    );
    assert!(stdout.contains("white: sample std N/sqrt(dt)"), "{stdout}");

    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert_eq!(doc["period_s"], 0.01);
    assert!(doc["conventions"].as_str().unwrap().contains("two-sided"));
    let gx = &doc["channels"][0];
    let n = gx["white"]["density"]["value"].as_f64().unwrap();
    let close = |a: &serde_json::Value, b: f64| (a.as_f64().unwrap() / b - 1.0).abs() < 1e-12;
    assert!((n / 1e-3 - 1.0).abs() < 0.05, "N = {n}");
    assert!(close(&gx["white"]["psd"]["value"], n * n));
    assert_eq!(gx["white"]["psd"]["unit"], "(rad/s)^2/Hz");
    assert!(close(&gx["white"]["sample_std"]["value"], n / 0.1));
    assert!(close(
        &gx["white"]["integrated_variance"]["value"],
        n * n * 0.01
    ));
    let k = gx["random_walk"]["density"]["value"].as_f64().unwrap();
    assert!(close(
        &gx["random_walk"]["variance_per_step"]["value"],
        k * k * 0.01
    ));
    assert_eq!(gx["gauss_markov"]["supported"], false);

    let yaml = std::fs::read_to_string(&yaml_path).unwrap();
    assert!(yaml.starts_with("# Filter noise parameters"), "{yaml}");
    assert!(yaml.contains("period_s: 1.0e-2"), "{yaml}");
    assert!(yaml.contains("  - channel: \"gx\""), "{yaml}");

    let document = analyze(&[csv, "--filter-period", "0.01", "--json", "-"]);
    assert!(document.status.success());
    let document: serde_json::Value = serde_json::from_slice(&document.stdout).unwrap();
    assert_eq!(document["filter"]["channels"][0], doc["channels"][0]);

    for (option, value, expected) in [
        ("--filter", "f.txt", "--filter f.txt"),
        ("--filter-period", "0", "--filter-period 0:"),
    ] {
        let bad = analyze(&[csv, option, value]);
        assert_eq!(bad.status.code(), Some(1));
        assert!(String::from_utf8_lossy(&bad.stderr).contains(expected));
    }
}

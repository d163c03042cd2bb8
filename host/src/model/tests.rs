//! Records generated with [`AxisNoise`]: a baseline (white N + small K) plus one hidden
//! effect; the workflow names it and recovers its key parameter. Run with `--release`.

use super::*;
use crate::record::Channel;
use rand::Rng;

const RATE: f64 = 20.0;
const HOURS: f64 = 1.0;
const N: f64 = 1e-4;
const K: f64 = 1e-7;

fn record(terms: NoiseTerms, seed: u64) -> Record {
    let n = (HOURS * 3600.0 * RATE) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut g = AxisNoise::new(terms, RATE, n as f64 / RATE, &mut rng);
    Record {
        source: "test".into(),
        rate_hz: RATE,
        channels: vec![Channel::named("gx", g.take(n, &mut rng))],
    }
}

fn baseline() -> NoiseTerms {
    NoiseTerms {
        n: N,
        k: K,
        ..NoiseTerms::default()
    }
}

fn settings() -> Settings {
    Settings {
        realisations: 20,
        seed: 1000,
    }
}

fn outcome(terms: NoiseTerms, seed: u64) -> Outcome {
    let o = run(&record(terms, seed), None, None, &settings()).unwrap();
    eprintln!("{}", report::table(&o));
    o
}

fn assert_named(o: &Outcome, kind: &str) -> Effect {
    let first = o.steps.first().expect("a step");
    assert_eq!(first.effect.kind(), kind, "{:?}", o.steps);
    assert!(
        first.gap_after <= 0.5 * first.gap_before,
        "gap {} -> {}",
        first.gap_before,
        first.gap_after
    );
    first.effect
}

fn within(value: f64, truth: f64, tol: f64) -> bool {
    (value / truth - 1.0).abs() <= tol
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
fn ramp_slope_of_a_line() {
    let rate: Vec<f64> = (0..100).map(|i| 2.0 + 0.5 * i as f64 * 0.1).collect();
    assert!((ramp_slope(&rate, 0.1) - 0.5).abs() < 1e-12);
}

#[test]
fn model_toml_parses_as_a_model_file() {
    let m = Model {
        terms: NoiseTerms {
            n: 1e-4,
            k: 1e-7,
            gauss_markov: Some(GaussMarkov {
                sigma: 3e-5,
                tau_c: 50.0,
            }),
            ..NoiseTerms::default()
        },
        temp_coeff: None,
    };
    let text = report::model_toml(Quantity::AngularRate, &m);
    let parsed = crate::sim::model_file::parse(&text, std::path::Path::new("model.toml"));
    assert!(parsed.is_ok(), "{text}: {:?}", parsed.err());
}

#[test]
fn no_hidden_effect_no_step() {
    let o = outcome(baseline(), 11);
    assert!(o.steps.is_empty(), "{:?}", o.steps);
    assert!(o.initial.gap < GAP_ACCEPT);
}

#[test]
fn names_gauss_markov() {
    let mut t = baseline();
    t.gauss_markov = Some(GaussMarkov {
        sigma: 1e-4,
        tau_c: 5.0,
    });
    let o = outcome(t, 12);
    let Effect::GaussMarkov { tau_c, .. } = assert_named(&o, "gauss_markov") else {
        unreachable!()
    };
    assert!(within(tau_c, 5.0, 0.25), "tau_c {tau_c}");
}

#[test]
fn names_sinusoid() {
    let mut t = baseline();
    t.sinusoid = Some(Sinusoid {
        amplitude: 1e-4,
        freq_hz: 0.02,
    });
    let o = outcome(t, 13);
    let Effect::Sinusoid { freq_hz, amplitude } = assert_named(&o, "sinusoid") else {
        unreachable!()
    };
    assert!(within(freq_hz, 0.02, 0.25), "f {freq_hz}");
    assert!(within(amplitude, 1e-4, 0.25), "A {amplitude}");
}

#[test]
fn names_rate_ramp() {
    let mut t = baseline();
    t.r = 2e-8;
    let o = outcome(t, 14);
    let Effect::RateRamp { slope } = assert_named(&o, "rate_ramp") else {
        unreachable!()
    };
    assert!(within(slope, 2e-8, 0.25), "slope {slope}");
}

#[test]
fn no_false_discoveries_over_seeds() {
    for seed in 20..26 {
        let o = run(&record(baseline(), seed), None, None, &settings()).unwrap();
        assert!(o.steps.is_empty(), "seed {seed}: {}", report::table(&o));
    }
}

#[test]
fn names_temperature() {
    let coeff = 2e-5;
    let mut r = record(baseline(), 15);
    let n = r.len();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let temp: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / RATE;
            25.0 + 10.0 * (1.0 - (-t / 900.0).exp())
                + 0.01 * rng.sample::<f64, _>(rand_distr::StandardNormal)
        })
        .collect();
    let gx = &mut r.channels[0].values;
    gx.iter_mut()
        .zip(&temp)
        .for_each(|(v, t)| *v += coeff * (t - 25.0));
    r.channels.push(Channel::named("temp", temp));
    let o = run(&r, None, Some("temp"), &settings()).unwrap();
    eprintln!("{}", report::table(&o));
    let Effect::Temperature { coeff: found } = assert_named(&o, "temperature") else {
        unreachable!()
    };
    assert!(within(found, coeff, 0.25), "coeff {found}");
}

#[test]
fn two_effects_two_steps() {
    let mut t = baseline();
    t.sinusoid = Some(Sinusoid {
        amplitude: 1e-4,
        freq_hz: 0.02,
    });
    t.r = 2e-8;
    let o = outcome(t, 16);
    let kinds: Vec<&str> = o.steps.iter().map(|s| s.effect.kind()).collect();
    assert_eq!(kinds, ["sinusoid", "rate_ramp"], "{:?}", o.steps);
    assert!(o.final_comparison().gap < GAP_ACCEPT);
}

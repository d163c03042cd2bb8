//! The workflow on families of generated records ([`super::families`]): each kind of hidden
//! effect over several seeds, every parameter drawn from a range. The default tests are
//! sized for CI (1 h at 20 Hz, 3 seeds per kind); `study_families` is the full study (3 h at
//! 50 Hz, 10 seeds per kind, and the pairs of effects that hide each other), run with
//! `cargo test --release -p imunoise --lib model::tests::study -- --ignored --nocapture`.

use super::families::{self, CI_SHAPE, Hidden, Kind, Shape};
use super::*;

const KINDS: [Kind; 11] = [
    Kind::LowPass,
    Kind::LowPassAndTone,
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

/// Two effects that hide each other, in the full study only: a warm-up that is nearly a
/// ramp beside a ramp, a Gauss-Markov bump beside a resonance's notch, a ramp beside a
/// filter, a coupling to the temperature's rate of change beside one to the temperature.
const HIDING_PAIRS: [Kind; 4] = [
    Kind::RampAndTemperature,
    Kind::GaussMarkovAndTone,
    Kind::LowPassAndRamp,
    Kind::TemperatureAndItsRate,
];

/// Several effects of one kind, in the full study only: a comb of lines beside a filter
/// (`a_comb_of_lines_is_named_in_one_round_beside_the_filter` is its CI-size test).
const COMBS: [Kind; 1] = [Kind::LowPassAndLines];

fn settings() -> Settings {
    Settings {
        seed: 1000,
        ..Settings::default()
    }
}

/// The kinds named, sorted, the outcome and what was hidden.
fn named(kind: Kind, shape: Shape, seed: u64) -> (Vec<&'static str>, Outcome, Hidden) {
    named_record(families::generate(kind, shape, seed))
}

/// [`named`] on a record made already.
fn named_record(hidden: Hidden) -> (Vec<&'static str>, Outcome, Hidden) {
    let o = run(&hidden.record, Some("gx"), None, &settings()).unwrap();
    // Every family record has flicker (B) and a random walk (K): naming them is right, not
    // an extra effect (the baseline fit leaves out a term it cannot resolve at its level).
    let mut kinds: Vec<&'static str> = o
        .steps
        .iter()
        .map(|s| s.effect.kind())
        .filter(|k| !matches!(*k, "bias_instability" | "rate_random_walk"))
        .collect();
    kinds.sort_unstable();
    (kinds, o, hidden)
}

/// The errors of the named slow sinusoid's, ramp's and temperature coupling's parameters (as
/// the final model holds them) over their stated standard errors: `(parameter, z)`.
fn parameter_z(o: &Outcome, hidden: &Hidden) -> Vec<(&'static str, f64)> {
    let mut out = Vec::new();
    for step in &o.steps {
        let errors = &step.standard_errors;
        let mut z = |name: &'static str, got: f64, truth: f64| {
            if let Some(sd) = errors.get(name) {
                out.push((name, (got - truth) / sd));
            }
        };
        match (step.effect, hidden.sinusoid, hidden.slope) {
            (
                Effect::Sinusoid {
                    freq_hz, amplitude, ..
                },
                Some(s),
                _,
            ) if (freq_hz - s.freq_hz).abs() * o.n as f64 / o.rate_hz < 2.0 => {
                z("freq_hz", freq_hz, s.freq_hz);
                z("amplitude", amplitude, s.amplitude);
            }
            (Effect::RateRamp { slope }, _, Some(truth)) => z("slope", slope, truth),
            (Effect::Temperature { coeff, rate_coeff }, _, _) => {
                if let Some(truth) = hidden.temp_coeff {
                    z("coeff", coeff, truth);
                }
                z(
                    "rate_coeff",
                    rate_coeff,
                    hidden.temp_rate_coeff.unwrap_or(0.0),
                );
            }
            _ => {}
        }
    }
    out
}

/// Whether the named Gauss-Markov term's 68.3 % intervals hold the hidden one's parameters:
/// `(parameter, held)`.
fn interval_hits(o: &Outcome, hidden: &Hidden) -> Vec<(&'static str, bool)> {
    let Some(truth) = hidden.terms.gauss_markov else {
        return Vec::new();
    };
    let holds = |(lo, hi): (Option<f64>, Option<f64>), v: f64| {
        lo.is_none_or(|lo| lo <= v) && hi.is_none_or(|hi| v <= hi)
    };
    o.steps
        .iter()
        .filter_map(|step| {
            step.evidence
                .iter()
                .find(|e| e.effect == Some(step.at_naming) && !e.intervals.is_empty())
        })
        .flat_map(|e| {
            [("tau_c", truth.tau_c), ("sigma", truth.sigma)]
                .into_iter()
                .filter_map(|(name, v)| e.intervals.get(name).map(|i| (name, holds(*i, v))))
        })
        .collect()
}

/// Seeds per kind whose named effects are exactly the hidden ones (`only`: just those seeds,
/// if any).
fn study(
    shape: Shape,
    seeds: std::ops::Range<u64>,
    kinds: &[Kind],
    only: &[u64],
) -> Vec<(Kind, usize, usize)> {
    kinds
        .iter()
        .map(|&kind| {
            let mut right = 0;
            let mut z2: std::collections::BTreeMap<&str, (f64, usize)> = Default::default();
            let mut held_in: std::collections::BTreeMap<&str, (usize, usize)> = Default::default();
            let chosen: Vec<u64> = seeds
                .clone()
                .filter(|s| only.is_empty() || only.contains(s))
                .collect();
            for &seed in &chosen {
                let (got, o, hidden) = named(kind, shape, seed);
                for (name, z) in parameter_z(&o, &hidden) {
                    let e = z2.entry(name).or_default();
                    (e.0, e.1) = (e.0 + z * z, e.1 + 1);
                }
                for (name, held) in interval_hits(&o, &hidden) {
                    let e = held_in.entry(name).or_default();
                    (e.0, e.1) = (e.0 + usize::from(held), e.1 + 1);
                }
                for r in &o.rechecked {
                    eprintln!("{kind:?} seed {seed}: {}", r.describe(o.unit));
                }
                if got == hidden.expected(kind) {
                    right += 1;
                } else {
                    eprintln!(
                        "{kind:?} seed {seed}: named {got:?}; hidden: {}\n{}",
                        hidden.describe(),
                        report::table(&o)
                    );
                }
            }
            eprintln!("{kind:?}: {right}/{} right", chosen.len());
            for (name, (sum, count)) in z2 {
                eprintln!(
                    "{kind:?}: {name}: mean z^2 {:.2} over {count}",
                    sum / count as f64
                );
            }
            for (name, (held, count)) in held_in {
                eprintln!("{kind:?}: {name}: 68.3 % interval held the truth {held} of {count}");
            }
            (kind, right, chosen.len())
        })
        .collect()
}

/// The model file the workflow writes is its model in the simulator's terms. Parsed back,
/// every term, line and coupling is there, with the white density and the lines' amplitudes
/// referred to the filter's input; and the simulated MPU-6050 at the filter's own settings
/// (100 Hz, DLPF 98 Hz: its aliases fold noise in, and a line at 40 Hz keeps part of its
/// power) puts out the model's N and the line's amplitude again. Tolerances: four standard
/// errors of a 10-minute record (amplitude `sqrt(2 S / T)` for a one-sided PSD S; the band
/// mean of the periodogram over its bins).
#[test]
fn model_toml_is_the_model_for_the_simulator() {
    use crate::analysis::low_pass::LowPass;
    use crate::sim::dlpf::Sensor;
    use crate::sim::imu::Imu;
    use protocol::mpu6050::SensorSettings;
    let (rate_hz, bandwidth_hz) = (100.0, 98.0);
    let low_pass = LowPass::for_bandwidth(bandwidth_hz, rate_hz, Sensor::Gyro)
        .expect("an MPU-6050 setting")
        .expect("a filter");
    let line = |freq_hz: f64, amplitude: f64, width_hz: f64| Line {
        freq_hz,
        amplitude,
        width_hz,
        statistic: 0.0,
        p_value: 1.0,
    };
    let n_out = 2e-3;
    let m = Model {
        terms: NoiseTerms {
            n: n_out,
            k: 1e-6,
            gauss_markov: Some(crate::sim::noise::GaussMarkov {
                sigma: 3e-5,
                tau_c: 50.0,
            }),
            sinusoid: Some(crate::sim::noise::Sinusoid {
                amplitude: 4e-3,
                freq_hz: 40.0,
            }),
            ..NoiseTerms::default()
        },
        temp_coeff: Some(1e-3),
        temp_rate_coeff: Some(0.05),
        lines: vec![line(40.0, 4e-3, 0.0), line(12.0, 2e-3, 0.3)],
        low_pass: Some(low_pass.clone()),
    };
    let text = report::model_toml(Quantity::AngularRate, &m);
    let parsed = crate::sim::model_file::parse(&text, std::path::Path::new("model.toml"))
        .unwrap_or_else(|e| panic!("{text}: {e}"));
    let gyro = &parsed.gyro;
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
    let n_in = low_pass.input_density(n_out);
    assert!(close(gyro.noise.n, n_in), "{text}");
    assert!(
        n_in < 0.9 * n_out,
        "the 98 Hz filter at 100 Hz folds noise in: {n_in}"
    );
    assert!(close(gyro.noise.k, 1e-6) && gyro.noise.gauss_markov == m.terms.gauss_markov);
    assert_eq!(
        gyro.noise.sinusoid, None,
        "the first line is not simulated twice"
    );
    assert_eq!(
        (gyro.temperature.bias_coeff, gyro.temperature.rate_coeff),
        (1e-3, 0.05)
    );
    assert_eq!(gyro.lines.len(), 2, "{text}");
    for (written, named) in gyro.lines.iter().zip(&m.lines) {
        let gain = low_pass.line_power_gain(named.freq_hz);
        assert!(
            close(written.amplitude, named.amplitude / gain.sqrt()),
            "{text}"
        );
        assert_eq!(
            (written.freq_hz, written.width_hz),
            (named.freq_hz, named.width_hz)
        );
    }
    assert!(
        low_pass.line_power_gain(40.0) < 0.9,
        "the test's line is attenuated"
    );

    let settings =
        SensorSettings::for_rate_and_bandwidth(rate_hz, bandwidth_hz).expect("a setting");
    let seconds = 600.0;
    let n = (seconds * rate_hz) as usize;
    let mut imu = Imu::new(&parsed, settings, 7, seconds);
    let x: Vec<f64> = (0..n).map(|_| imu.next_si().gyro[0]).collect();
    let mean = x.iter().sum::<f64>() / n as f64;
    // The one-sided periodogram at the k-th bin and the complex amplitude at 40 Hz.
    let dft = |f: f64| {
        let w = 2.0 * std::f64::consts::PI * f / rate_hz;
        x.iter().enumerate().fold((0.0, 0.0), |(re, im), (i, v)| {
            let (s, c) = (w * i as f64).sin_cos();
            (re + (v - mean) * c, im - (v - mean) * s)
        })
    };
    let amplitude = {
        let (re, im) = dft(40.0);
        2.0 * re.hypot(im) / n as f64
    };
    // The white level between the lines: 2..8 Hz, 6 * 600 bins.
    let bins: Vec<f64> = (2 * 600..8 * 600).map(|k| k as f64 / seconds).collect();
    let psd = bins
        .iter()
        .map(|&f| {
            let (re, im) = dft(f);
            2.0 * (re * re + im * im) / (n as f64 * rate_hz)
        })
        .sum::<f64>()
        / bins.len() as f64;
    let want_psd = bins
        .iter()
        .map(|&f| 2.0 * n_out * n_out * low_pass.power_gain(f))
        .sum::<f64>()
        / bins.len() as f64;
    let psd_se = want_psd / (bins.len() as f64).sqrt();
    assert!(
        (psd - want_psd).abs() < 4.0 * psd_se,
        "white PSD {psd:.4e} against {want_psd:.4e} +- {psd_se:.1e}"
    );
    let amplitude_se = (2.0 * 2.0 * n_out * n_out * low_pass.power_gain(40.0) / seconds).sqrt();
    assert!(
        (amplitude - 4e-3).abs() < 4.0 * amplitude_se,
        "line amplitude {amplitude:.4e} against 4e-3 +- {amplitude_se:.1e}"
    );
}

/// A temperature channel that never changed (a simulated sensor at a constant temperature, a
/// reading that never moved a count) is not a regressor: the outcome says so, and the
/// workflow runs exactly as on the record without it, its ramp test alive (on a record with
/// a ramp the family names at this size).
#[test]
fn a_constant_temperature_channel_is_set_aside() {
    let hidden = families::generate(Kind::Ramp, CI_SHAPE, 1);
    let mut with_temp = hidden.record.clone();
    let n = with_temp.channels[0].values.len();
    with_temp
        .channels
        .push(crate::record::Channel::named("temp", vec![25.5; n]));
    let plain = run(&hidden.record, Some("gx"), None, &settings()).unwrap();
    let o = run(&with_temp, Some("gx"), None, &settings()).unwrap();
    let note = o.temperature_note.as_deref().unwrap_or_default();
    assert!(note.contains("'temp' is constant (25.5 for all"), "{note}");
    assert_eq!(o.temperature, None);
    let kinds = |o: &Outcome| o.steps.iter().map(|s| s.effect.kind()).collect::<Vec<_>>();
    assert_eq!(kinds(&o), kinds(&plain));
    assert!(kinds(&o).contains(&"rate_ramp"), "{:?}", kinds(&o));
}

/// A filter low in the band (3 % of the rate) beside a line 0.64 Hz wide above its cutoff:
/// the line is named first, and the refit after it leaves the roll-off's taus out until the
/// filter is named ([`super::candidates::unnamed_filter`]). Refitted over them with an
/// unfiltered white column, N fell 200-fold, B rose to make the long taus good again, and
/// the roll-off was then named a Gauss-Markov process of 0.2 s. N within 10 %: its error is
/// a fraction of a percent on 180 000 samples; a fitted filter's shape moves it a few.
#[test]
fn a_filter_beside_a_wide_line_above_it_is_named_after_the_line() {
    let shape = Shape {
        rate_hz: 50.0,
        duration_s: 3600.0,
    };
    let (got, o, hidden) = named(Kind::LowPassAndTone, shape, 115);
    assert_eq!(
        got,
        Kind::LowPassAndTone.expected(),
        "{}",
        report::table(&o)
    );
    let last = o.steps.last().expect("two steps");
    assert!(
        (last.model.terms.n / hidden.terms.n - 1.0).abs() < 0.1,
        "N {} against {}",
        last.model.terms.n,
        hidden.terms.n
    );
}

/// A filter and a comb of four narrow lines (the first such record of the family at CI
/// size): every line is named, the lines in one round, and the filter after them. One line
/// a round, the four rounds the search allows ([`MAX_STEPS`]) ended with the filter or a
/// line left out. Each line within four of its standard errors of the generator's frequency.
#[test]
fn a_comb_of_lines_is_named_in_one_round_beside_the_filter() {
    let hidden = (1..100)
        .map(|seed| families::generate(Kind::LowPassAndLines, CI_SHAPE, seed))
        .find(|h| h.tones.len() == 4)
        .expect("a record of four lines among the first hundred");
    let (got, o, hidden) = named_record(hidden);
    assert_eq!(
        got,
        hidden.expected(Kind::LowPassAndLines),
        "{}: {}",
        hidden.describe(),
        report::table(&o)
    );
    let lines: Vec<&Step> = o
        .steps
        .iter()
        .filter(|s| s.effect.kind() == "sinusoid")
        .collect();
    assert!(
        lines.iter().all(|s| s.round == lines[0].round),
        "{}",
        report::table(&o)
    );
    let filter = o
        .steps
        .iter()
        .find(|s| s.effect.kind() == "low_pass")
        .expect("the filter named");
    assert_ne!(filter.round, lines[0].round);
    assert!(o.steps.iter().map(|s| s.round).max() <= Some(MAX_STEPS));
    let json = report::document(&o);
    let rounds: Vec<u64> = json["steps"]
        .as_array()
        .expect("steps")
        .iter()
        .map(|s| s["round"].as_u64().expect("a round"))
        .collect();
    let own: Vec<u64> = o.steps.iter().map(|s| s.round as u64).collect();
    assert_eq!(rounds, own);
    // The final filter's share of white noise after it, in the model's keys.
    let share = json["model"]["low_pass"]["unshaped_share"].as_f64();
    assert!(
        share.is_some_and(|s| (0.0..=crate::analysis::low_pass::MAX_UNSHAPED_SHARE).contains(&s)),
        "{share:?}"
    );
    for &(freq_hz, _, _) in &hidden.tones {
        let step = lines
            .iter()
            .find(|s| {
                matches!(s.effect, Effect::Sinusoid { freq_hz: f, .. }
                    if (f - freq_hz).abs() < 4.0 * s.standard_errors.get("freq_hz").copied().unwrap_or(f64::NAN))
            });
        assert!(
            step.is_some(),
            "no line at {freq_hz} Hz: {}",
            report::table(&o)
        );
    }
}

/// Three tones named in one round, then a Gauss-Markov process: the tones, named before an
/// effect of the other kind, are tested again, together as they were named
/// ([`recheck::named_before`]): one model without all three, and each still passes there.
#[test]
fn lines_named_together_are_tested_again_together() {
    use rand::SeedableRng;
    let mut hidden = families::generate(Kind::GaussMarkov, CI_SHAPE, 13);
    let rate_hz = CI_SHAPE.rate_hz;
    // Each tone 200 times the white PSD (one-sided 2 N^2) in its bin of the whole record.
    let amplitude = (2.0 * 200.0 * 2.0 * hidden.terms.n.powi(2) / CI_SHAPE.duration_s).sqrt();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for share in [0.11, 0.23, 0.37] {
        let freq_hz = share * rate_hz;
        crate::sim::noise::add_line(
            &mut hidden.record.channels[0].values,
            rate_hz,
            freq_hz,
            0.0,
            amplitude,
            &mut rng,
        );
        hidden
            .tones
            .push((freq_hz, 0.0, amplitude * amplitude / 2.0));
    }
    let (got, o, _) = named_record(hidden);
    assert_eq!(
        got,
        ["gauss_markov", "sinusoid", "sinusoid", "sinusoid"],
        "{}",
        report::table(&o)
    );
    assert_eq!(o.rechecked.len(), 3, "{:?}", o.rechecked);
    for r in &o.rechecked {
        assert_eq!(r.together, 3, "{r:?}");
        assert!(r.passes && !r.dropped && r.p_value < r.p_needed, "{r:?}");
        assert_eq!(r.gap_without, o.rechecked[0].gap_without);
    }
    let json = report::document(&o);
    assert_eq!(json["rechecked"][2]["together"], 3);
}

/// A Gauss-Markov bump the baseline took into its white and flicker terms makes
/// quantization pass beside the process, with the smaller p: named by p, quantization came
/// first and stayed (it shrank the gap a little), and the process was named after it. Of
/// random terms passing together, the one whose model lies closest to the record is named
/// ([`super::naming`]): here the process, and nothing else.
#[test]
fn of_random_terms_passing_together_the_one_closest_to_the_record_is_named() {
    let (got, o, _) = named(Kind::GaussMarkov, CI_SHAPE, 13);
    assert_eq!(got, Kind::GaussMarkov.expected(), "{}", report::table(&o));
    let first = &o.steps[0];
    let by_p = first
        .evidence
        .iter()
        .filter(|e| e.passes && !e.view.is_deterministic())
        .min_by(|a, b| a.ranking_p().total_cmp(&b.ranking_p()))
        .expect("random terms pass in the first round");
    assert_eq!(by_p.candidate, "quantization", "{}", report::table(&o));
    assert_eq!(first.effect.kind(), "gauss_markov", "{}", report::table(&o));
    assert!(first.gap_after < first.gap_before);
    // The slow line found beside the passing process was weighed too, and lay farther.
    let (process, line) = process_and_line_gaps(first);
    assert!(process < line && line.is_finite(), "{:?}", first.rivals);
}

/// The Allan gaps of the Gauss-Markov process and of the slow line weighed beside it in
/// `step`'s choice (infinite where one was not weighed).
fn process_and_line_gaps(step: &Step) -> (f64, f64) {
    let gap = |kind: &str| {
        step.rivals
            .iter()
            .find(|r| r.effect.kind() == kind)
            .map_or(f64::INFINITY, |r| r.gap)
    };
    (gap("gauss_markov"), gap("sinusoid"))
}

/// `hidden`'s slow sinusoid scaled by `factor`: the least-squares sine and cosine at its
/// frequency, `1 - factor` of them taken out of the record.
fn scale_sinusoid(hidden: &mut Hidden, factor: f64) {
    let freq_hz = hidden.sinusoid.expect("a slow-sinusoid kind").freq_hz;
    let rate_hz = hidden.record.rate_hz;
    let values = &mut hidden.record.channels[0].values;
    let phase = |i: usize| 2.0 * PI * freq_hz * i as f64 / rate_hz;
    // The normal equations of y ~ a sin + b cos.
    let (mut ss, mut cc, mut sc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (i, y) in values.iter().enumerate() {
        let (sin, cos) = phase(i).sin_cos();
        (ss, cc, sc, ys, yc) = (
            ss + sin * sin,
            cc + cos * cos,
            sc + sin * cos,
            ys + y * sin,
            yc + y * cos,
        );
    }
    let det = ss * cc - sc * sc;
    let (a, b) = ((ys * cc - yc * sc) / det, (yc * ss - ys * sc) / det);
    for (i, y) in values.iter_mut().enumerate() {
        let (sin, cos) = phase(i).sin_cos();
        *y -= (1.0 - factor) * (a * sin + b * cos);
    }
}

/// A slow sinusoid of 5.3 cycles in 3 h (the study's seed 108), between two periodogram
/// bins, is named by its own view at its half bin (p = 3.2e-5). At 80 % of its amplitude
/// that view leaves it at p = 8.4e-3 with the statistic below the largest simulated one,
/// while the Gauss-Markov tests, which search no frequency, pass (p = 2.2e-4): the slow
/// line found beside a passing process is weighed by the Allan gap, and here named in the
/// process's place ([`super::naming`]).
#[test]
fn a_slow_line_beside_a_passing_process_is_named_where_its_model_lies_closer() {
    let mut hidden = families::generate(Kind::SlowSinusoid, families::STUDY_SHAPE, 108);
    scale_sinusoid(&mut hidden, 0.8);
    let (got, o, _) = named_record(hidden);
    assert_eq!(got, Kind::SlowSinusoid.expected(), "{}", report::table(&o));
    let first = &o.steps[0];
    let passes = |kind: &str| {
        first
            .evidence
            .iter()
            .any(|e| e.passes && e.effect.is_some_and(|x| x.kind() == kind))
    };
    assert!(
        passes("gauss_markov") && !passes("sinusoid"),
        "{}",
        report::table(&o)
    );
    assert_eq!(first.effect.kind(), "sinusoid", "{}", report::table(&o));
    let (process, line) = process_and_line_gaps(first);
    assert!(line < process && process.is_finite(), "{:?}", first.rivals);
    // Standing in for a random term, it had to bring the simulations closer to stay.
    assert!(first.must_close_gap() && first.gap_after < first.gap_before);
    assert!(
        first.description.contains("in place of"),
        "{}",
        first.description
    );
    let json = report::document(&o);
    let rivals = json["steps"][0]["rivals"].as_array().map_or(0, Vec::len);
    assert_eq!(rivals, first.rivals.len(), "{}", json["steps"][0]);
}

/// A slow line named before a Gauss-Markov process is tested again once the process is in
/// the model and dropped ([`super::recheck`]): the strongest slow line of a process record
/// (CI size, seed 3, where the process alone is named), as the low-frequency view found it
/// beside the process, put in the model before the process (measured: p = 0.29 without it,
/// needing 0.01; Allan gap 0.63 without it, 0.57 with it).
#[test]
fn a_slow_line_named_before_the_process_that_explains_it_is_dropped() {
    let hidden = families::generate(Kind::GaussMarkov, CI_SHAPE, 3);
    let o = run(&hidden.record, Some("gx"), None, &settings()).unwrap();
    let kinds: Vec<&str> = o.steps.iter().map(|s| s.effect.kind()).collect();
    assert_eq!(kinds, ["gauss_markov"], "{}", report::table(&o));
    let process = o.steps[0].clone();
    let line = process
        .evidence
        .iter()
        .find(|e| e.view == View::LowSpectrum)
        .and_then(|e| e.effect)
        .expect("the low-frequency view finds a slow line on every record");
    let channel = hidden.record.channel("gx").expect("the families write gx");
    let data = Data {
        rate: &channel.values,
        rate_hz: hidden.record.rate_hz,
        temperature: None,
        measured: o.measured.clone(),
        settings: settings(),
        lines: &detect_lines,
        losses: restore::Losses::default(),
    };
    let mut removal = Removal::default();
    let sd_ln = simulate_round(&data, &process.model, &removal, None).sd_ln;
    let with_line = candidates::add(
        &data,
        &process.model,
        &mut removal,
        (Probe::SlowLine, line),
        &sd_ln,
        None,
    );
    assert_eq!((with_line.lines.len(), removal.tones.len()), (1, 1));
    let line_step = Step {
        effect: line,
        at_naming: line,
        view: View::LowSpectrum,
        stands_in: false,
        ..process.clone()
    };
    let mut steps = vec![
        line_step,
        Step {
            model: with_line.clone(),
            ..process
        },
    ];
    let round = simulate_round(&data, &with_line, &removal, None);
    let (last, seen) = super::recheck::named_before(&data, &mut steps, &mut removal, round);
    assert_eq!(seen.len(), 1, "{seen:?}");
    let r = seen[0];
    eprintln!("{}", r.describe(o.unit));
    assert!(
        r.effect == line
            && r.dropped
            && !r.passes
            && r.other_passes == Some(false)
            && r.p_value > r.p_needed,
        "{r:?}"
    );
    let kinds: Vec<&str> = steps.iter().map(|s| s.effect.kind()).collect();
    assert_eq!(kinds, ["gauss_markov"]);
    assert!(steps[0].model.lines.is_empty() && removal.tones.is_empty());
    assert!(steps[0].model.terms.gauss_markov.is_some());
    assert_eq!(steps[0].comparison.gap, last.comparison.gap);
    assert!(!last.evidence.iter().any(|e| e.passes));
}

/// A slow sinusoid named before a Gauss-Markov process is tested again once the process is
/// in the model ([`super::recheck`]) and kept: its own test still passes. The record of
/// `a_slow_line_named_before_the_process_that_explains_it_is_dropped` with a sinusoid of 6.5
/// cycles added, its power in one periodogram bin 400 times the process's and the white
/// noise's there.
#[test]
fn a_sinusoid_named_before_a_process_is_kept_where_its_test_still_passes() {
    let mut hidden = families::generate(Kind::GaussMarkov, CI_SHAPE, 3);
    let gm = hidden.terms.gauss_markov.expect("a process record");
    let (rate_hz, t_rec) = (CI_SHAPE.rate_hz, CI_SHAPE.duration_s);
    // One-sided PSD below the process's knee: 4 sigma^2 tau_c, and white 2 N^2.
    let plateau = 4.0 * gm.sigma * gm.sigma * gm.tau_c + 2.0 * hidden.terms.n * hidden.terms.n;
    let amplitude = (2.0 * 400.0 * plateau / t_rec).sqrt();
    let freq_hz = 6.5 / t_rec;
    let gx = hidden
        .record
        .channels
        .iter_mut()
        .find(|c| c.name == "gx")
        .expect("the families write gx");
    for (i, v) in gx.values.iter_mut().enumerate() {
        *v += amplitude * (2.0 * PI * freq_hz * i as f64 / rate_hz).sin();
    }
    let o = run(&hidden.record, Some("gx"), None, &settings()).unwrap();
    let kinds: Vec<&str> = o.steps.iter().map(|s| s.effect.kind()).collect();
    assert_eq!(kinds, ["sinusoid", "gauss_markov"], "{}", report::table(&o));
    assert_eq!(o.rechecked.len(), 1, "{:?}", o.rechecked);
    let r = o.rechecked[0];
    eprintln!("{}", r.describe(o.unit));
    assert!(
        r.effect.kind() == "sinusoid" && r.passes && !r.dropped && r.p_value < r.p_needed,
        "{r:?}"
    );
    let json = report::document(&o);
    assert_eq!(
        json["rechecked"][0]["dropped"], false,
        "{}",
        json["rechecked"]
    );
    assert!(report::table(&o).contains("kept: its test still passes"));
}

/// Every kind on three seeds at CI size (1 h at 20 Hz, shorter and slower than the study's
/// 3 h at 50 Hz, so every effect is weaker against the noise): at least five sixths of the
/// 33 records named exactly right (29 measured: a Gauss-Markov process of 36-108 s is found
/// once in three in an hour, a ramp twice; the full study is the claim), and at most one
/// effect added on the six records
/// without one (the naming rule's family-wise level is 5 % per round, 0.3 expected).
#[test]
fn families_at_ci_size() {
    let results = study(CI_SHAPE, 1..4, &KINDS, &[]);
    let right: usize = results.iter().map(|r| r.1).sum();
    let total: usize = results.iter().map(|r| r.2).sum();
    assert!(right * 6 >= total * 5, "{right}/{total}: {results:?}");
    let clean: usize = results
        .iter()
        .filter(|r| matches!(r.0, Kind::None | Kind::NoneWithTemperature))
        .map(|r| r.2 - r.1)
        .sum();
    assert!(clean <= 1, "{clean} false effects: {results:?}");
}

#[test]
#[ignore = "the full study: 3 h at 50 Hz, 10 seeds per kind; run with --release"]
fn study_families() {
    // STUDY_RATE_HZ=100 STUDY_HOURS=4 STUDY_FIRST_SEED=200 tries the workflow on another
    // shape and other seeds than those it was developed on.
    let number = |name: &str| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.trim().parse::<f64>().ok())
    };
    let shape = Shape {
        rate_hz: number("STUDY_RATE_HZ").unwrap_or(families::STUDY_SHAPE.rate_hz),
        duration_s: number("STUDY_HOURS").map_or(families::STUDY_SHAPE.duration_s, |h| h * 3600.0),
    };
    let first = number("STUDY_FIRST_SEED").map_or(100, |s| s as u64);
    // STUDY_KINDS=GaussMarkov,Tone runs only those kinds (names as in `Kind`'s Debug).
    let only = std::env::var("STUDY_KINDS").unwrap_or_default();
    let kinds: Vec<Kind> = KINDS
        .into_iter()
        .chain(HIDING_PAIRS)
        .chain(COMBS)
        .filter(|k| only.is_empty() || only.split(',').any(|o| o == format!("{k:?}")))
        .collect();
    // STUDY_SEEDS=103,107 runs only those seeds (of the ten from the first).
    let seeds: Vec<u64> = std::env::var("STUDY_SEEDS")
        .unwrap_or_default()
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let results = study(shape, first..first + 10, &kinds, &seeds);
    for (kind, right, total) in &results {
        eprintln!("{kind:?}: {right}/{total}");
    }
    for (kind, right, total) in results {
        assert!(right * 10 >= 9 * total, "{kind:?}: {right}/{total}");
    }
}

/// How many of `records` records with no effect but a temperature channel the rate does not
/// follow (CI size) give the ramp (row 0), temperature (row 1) and Gauss-Markov (row 2)
/// tests a p-value below 0.01, 0.1 and 0.5. Under the model the p-values are uniform; the
/// open noise model and the bootstrap's levels are estimated from each record, so this
/// measures what the estimates cost.
fn null_p_values(records: u64) -> [[usize; 3]; 3] {
    let mut below = [[0usize; 3]; 3];
    for seed in 0..records {
        let record = families::record(Kind::NoneWithTemperature, CI_SHAPE, 5000 + seed);
        let o = run(&record, Some("gx"), None, &settings()).unwrap();
        for (row, candidate) in ["rate_ramp", "temperature", "gauss_markov"]
            .iter()
            .enumerate()
        {
            let e = o
                .initial_evidence
                .iter()
                .find(|e| e.candidate == *candidate)
                .expect("every one is a candidate on a record with a temperature channel");
            for (col, level) in [0.01, 0.1, 0.5].iter().enumerate() {
                below[row][col] += usize::from(e.p_value < *level);
            }
        }
    }
    eprintln!(
        "below 0.01, 0.1, 0.5 of {records}: ramp {:?}, temperature {:?}, Gauss-Markov {:?}",
        below[0], below[1], below[2]
    );
    below
}

/// The regressor and Gauss-Markov tests' p-values on 30 pure-noise records: binomial(30, p)
/// bounds, 0.01 -> at most 2 (P(X > 2) = 0.3 %), 0.5 -> 8..=22 (P(outside) = 1.6 %). Taking
/// the open model's K as known put 11 of 100 ramp p-values below 0.01; drawing the
/// Gauss-Markov null at the levels fitted beside the term put 5 of 100 below 0.01 and 20
/// below 0.1 (docs/guide/model.md).
#[test]
fn null_p_values_are_calibrated_at_ci_size() {
    let below = null_p_values(30);
    for row in below {
        assert!(row[0] <= 2 && (8..=22).contains(&row[2]), "{below:?}");
    }
}

/// The same on 100 records (about 5 min with --release).
#[test]
#[ignore = "a calibration study: 100 records; run with --release"]
fn null_p_values_are_calibrated() {
    let below = null_p_values(100);
    // Binomial(100, p): 0.01 -> at most 4 (P(X > 4) = 0.3 %); 0.1 -> 3..=19; 0.5 -> 35..=65.
    for row in below {
        assert!(
            row[0] <= 4 && (3..=19).contains(&row[1]) && (35..=65).contains(&row[2]),
            "{below:?}"
        );
    }
}

#[test]
fn the_channel_modelled_by_default_is_a_gyro_else_an_accelerometer_else_the_only_one() {
    let record = |names: &[&str]| Record {
        source: "t".into(),
        rate_hz: 10.0,
        channels: names
            .iter()
            .map(|n| Channel::named(*n, vec![0.0; 4]))
            .collect(),
    };
    let picked = |names: &[&str]| pick(&record(names), None).map(|c| c.name.clone());
    assert_eq!(picked(&["temp", "ax", "gy"]).unwrap(), "gy");
    assert_eq!(picked(&["temp", "az", "ax"]).unwrap(), "az");
    assert_eq!(picked(&["temp", "rate"]).unwrap(), "rate");
    let err = picked(&["temp", "rate", "y"]).unwrap_err().to_string();
    assert!(
        err.contains("temp, rate, y") && err.contains("--column"),
        "{err}"
    );
    assert_eq!(pick(&record(&["gx", "ax"]), Some("ax")).unwrap().name, "ax");
}

/// On records with a warm-up and a ramp, every step reports its regressor as the final model
/// holds it (the joint least squares). Where the ramp is named after the warm-up, the
/// temperature coefficient at naming took part of the ramp (seed 2: the wrong sign); the
/// joint one lies within 3 of its standard errors of the truth and nearer than at naming.
#[test]
fn steps_report_the_joint_estimates_of_the_final_model() {
    let mut restated = 0;
    for seed in 1..4 {
        let hidden = families::generate(Kind::RampAndTemperature, CI_SHAPE, seed);
        let o = run(&hidden.record, Some("gx"), None, &settings()).unwrap();
        let last = o.final_model();
        for step in &o.steps {
            match step.effect {
                Effect::RateRamp { slope } => assert_eq!(slope, last.terms.r),
                Effect::Temperature { coeff, rate_coeff } => {
                    assert_eq!(Some(coeff), last.temp_coeff);
                    assert_eq!(Some(rate_coeff), last.temp_rate_coeff);
                    let Effect::Temperature { coeff: named, .. } = step.at_naming else {
                        panic!(
                            "seed {seed}: {:?} named as {:?}",
                            step.effect, step.at_naming
                        );
                    };
                    if named != coeff {
                        restated += 1;
                        let truth = hidden.temp_coeff.expect("a temperature kind");
                        let sd = step.standard_errors["coeff"];
                        assert!(
                            (coeff - truth).abs() <= 3.0 * sd
                                && (coeff - truth).abs() < (named - truth).abs(),
                            "seed {seed}: joint {coeff:.3e} +- {sd:.1e}, at naming {named:.3e}, truth {truth:.3e}"
                        );
                    }
                }
                _ => {}
            }
        }
    }
    assert_eq!(restated, 2);
}

//! Spectral lines on the analyze path: records through the simulated MPU-6050 chain (DLPF,
//! decimation, quantization to counts), the real MPU-6050 record, and the noise fit with a
//! tone in the record (the tone must not become quantization noise).

use imunoise::analysis::lines::{self, LineOptions};
use imunoise::analysis::pipeline::{self, Options};
use imunoise::input::{CountScale, LoadOptions};
use imunoise::record::{Channel, Record};
use imunoise::sim::imu::Imu;
use imunoise::sim::model_file;
use imunoise::sim::noise::{AxisNoise, NoiseTerms, add_line};
use protocol::SensorSettings;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;
use std::path::Path;

/// `seconds` of gyro x through the chip's chain at `rate` Hz output with a `bandwidth` Hz DLPF,
/// quantized to counts at +-250 deg/s, from a model file's `[gyro]` table.
fn chain_record(gyro: &str, rate: f64, bandwidth: f64, seconds: f64, seed: u64) -> Vec<f64> {
    let model = model_file::parse(&format!("[gyro]\n{gyro}\n"), Path::new("lines.toml")).unwrap();
    let settings = SensorSettings::for_rate_and_bandwidth(rate, bandwidth).unwrap();
    let mut imu = Imu::new(&model, settings, seed, seconds);
    (0..(seconds * rate) as usize)
        .map(|_| imu.next_si().gyro[0])
        .collect()
}

/// White noise, random walk and flicker through the chain at 200 Hz, DLPF settings from 5 to
/// 98 Hz, quantized to counts: no line in 10 records (the family-wise false-alarm probability
/// is 1 % per record; 1 in 10 would already be unlikely, p ~ 0.1).
#[test]
fn filtered_quantized_records_without_lines_have_none() {
    let mut alarms = Vec::new();
    for (seed, bandwidth) in [5.0, 10.0, 20.0, 42.0, 98.0, 5.0, 10.0, 20.0, 42.0, 98.0]
        .into_iter()
        .enumerate()
    {
        let y = chain_record(
            "noise_density = 1.5e-4\nrate_random_walk = 2e-5\nbias_instability = 3e-5",
            200.0,
            bandwidth,
            300.0,
            seed as u64,
        );
        let found = lines::detect(&y, 200.0, &LineOptions::default()).unwrap();
        if !found.is_empty() {
            alarms.push(format!("{bandwidth} Hz DLPF, seed {seed}: {found:?}"));
        }
    }
    assert!(alarms.len() <= 1, "{}", alarms.join("\n"));
}

/// A sinusoid through the same chain: found at its frequency with the amplitude the filter
/// passes (|H(f)| A), in each of 10 records. The tone is 20 times the background's power per
/// bin at the least (d >= 20 x the ~20 that the search needs; see the detector's tests), so its
/// least-squares amplitude is within 6 / sqrt(2 d) < 10 % and its frequency within a bin.
#[test]
fn tones_through_the_filtered_chain_are_found() {
    use imunoise::sim::dlpf::{DlpfDesign, Sensor};
    let (rate, seconds) = (200.0, 300.0);
    for seed in 0..10u64 {
        let f = 1.0 + 9.0 * seed as f64;
        let bandwidth = if seed % 2 == 0 { 42.0 } else { 98.0 };
        let settings = SensorSettings::for_rate_and_bandwidth(rate, bandwidth).unwrap();
        let design = DlpfDesign::for_setting(settings.dlpf, Sensor::Gyro);
        let gain = design.response(f).norm();
        let amplitude = 3e-4 / gain;
        let y = chain_record(
            &format!(
                "noise_density = 1.5e-4\nrate_random_walk = 2e-5\nsinusoid = {{ amplitude = {amplitude}, freq_hz = {f} }}"
            ),
            rate,
            bandwidth,
            seconds,
            100 + seed,
        );
        let found = lines::detect(&y, rate, &LineOptions::default()).unwrap();
        let df = 1.0 / seconds;
        let line = found
            .iter()
            .find(|l| (l.freq_hz - f).abs() < df)
            .unwrap_or_else(|| panic!("{f} Hz through {bandwidth} Hz: {found:?}"));
        assert!(
            (line.amplitude / 3e-4 - 1.0).abs() < 0.1,
            "{f} Hz: {line:?}"
        );
        assert_eq!(line.width_hz, 0.0, "{line:?}");
    }
}

/// The real MPU-6050 record (tests/data/mpu6050_static_100hz, 449 s at 100 Hz): the gyro's z
/// axis carries a tone at 31.00 Hz and its y axis one at 37.99 Hz (amplitudes ~1.2e-4 and
/// ~2.7e-4 rad/s, a few 1e-9 and 4e-8 (rad/s)^2, tens of standard deviations above the
/// background); the accelerometer axes carry none.
#[test]
fn the_real_record_has_two_gyro_tones() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/mpu6050_static_100hz/example_data_tinit_calc.csv");
    let options = LoadOptions {
        counts: Some(CountScale {
            rad_s_per_lsb: (250.0f64 / 32768.0).to_radians(),
            m_s2_per_lsb: 2.0 * 9.80665 / 32768.0,
        }),
        ..LoadOptions::default()
    };
    let record = imunoise::input::load(&path, &options).unwrap().record;
    let found = |name: &str| {
        let c = record.channel(name).unwrap();
        lines::detect(&c.values, record.rate_hz, &LineOptions::default()).unwrap()
    };
    for name in ["ax", "ay", "az"] {
        assert!(found(name).is_empty(), "{name}: {:?}", found(name));
    }
    for (name, f) in [("gz", 31.0), ("gy", 37.99)] {
        let lines = found(name);
        assert!(
            lines
                .iter()
                .any(|l| (l.freq_hz - f).abs() < 0.02 && l.statistic > 10.0),
            "{name}: {lines:?}"
        );
    }
}

/// A tone in the record does not become quantization noise. White noise and rate random walk
/// at 100 Hz for 10 min with a 31 Hz tone 50 times the white PSD (the MPU-6050 case;
/// a tone's AVAR falls as 1/tau^2 at the shortest taus, like quantization's): with the line
/// search the fit matches that of the same noise without the tone: the tone is found, Q not
/// claimed, N within its interval.
#[test]
fn a_tone_does_not_become_quantization() {
    let (rate, n) = (100.0, 60_000);
    let terms = NoiseTerms {
        n: 1e-3,
        k: 2e-5,
        ..NoiseTerms::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let noise = AxisNoise::new(terms, rate, n as f64 / rate, &mut rng).take(n, &mut rng);
    // One-sided white PSD 2 N^2; a tone 50x that in a Welch bin of 0.024 Hz (4096 samples,
    // Hann, noise bandwidth 1.5 bins) has power 50 x 2 N^2 x 1.5 x 0.0244 Hz.
    let power = 50.0 * 2.0 * terms.n * terms.n * 1.5 * rate / 4096.0;
    let amplitude = (2.0 * power).sqrt();
    let with_tone: Vec<f64> = noise
        .iter()
        .enumerate()
        .map(|(t, v)| v + amplitude * (2.0 * PI * 31.0 * t as f64 / rate + 0.3).sin())
        .collect();
    let fit = |values: Vec<f64>| {
        let result = analysed("gx", values, rate);
        (result.fit.unwrap(), result.lines)
    };
    let (clean, clean_lines) = fit(noise);
    let (cleaned, found) = fit(with_tone);
    assert!(clean_lines.is_empty(), "{clean_lines:?}");
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        (found[0].freq_hz - 31.0).abs() < 1e-3
            && (found[0].amplitude / amplitude - 1.0).abs() < 0.05
    );
    assert_eq!(cleaned.q.lo, 0.0, "{:?}", cleaned.q);
    assert!(
        cleaned.n.lo <= clean.n.value && clean.n.value <= cleaned.n.hi,
        "N {:?} vs {:?}",
        cleaned.n,
        clean.n
    );
}

/// Lines do not bias the PSD read-outs: white noise, flicker and a random walk at 100 Hz for
/// 1 h with the comb of narrow lines a real ADIS16405's accelerometers show (0.46-1.79 Hz,
/// inside the band the read-outs fit, the strongest some 100 times the white PSD in a Welch
/// bin): N, B and K from the spectrum match those of the same noise without the lines,
/// within the clean record's intervals, and the fit's reduced chi-square stays near the
/// clean record's (fitted with the lines, that record's N came out half again too high at a
/// reduced chi-square in the hundreds). A wide line's far wings, beyond the band its removal
/// flattens, stay in the record for both fits: a line 0.6 Hz wide holding 2.7 times the
/// white power of 1 Hz raises N by about 0.5 %.
#[test]
fn lines_do_not_bias_the_psd_read_outs() {
    let (rate, n) = (100.0, 360_000);
    let terms = NoiseTerms {
        n: 4e-3,
        b: 2.5e-3,
        k: 4e-4,
        ..NoiseTerms::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(405);
    let noise = AxisNoise::new(terms, rate, n as f64 / rate, &mut rng).take(n, &mut rng);
    let mut with_lines = noise.clone();
    // The comb as pure tones (width 0): the real lines are under 0.01 Hz wide.
    for (freq, amplitude) in [
        (0.4625, 1.5e-3),
        (0.564, 9e-3),
        (0.6653, 1.5e-3),
        (1.5893, 1.5e-3),
        (1.6905, 2.5e-3),
        (1.7918, 1.2e-3),
    ] {
        add_line(&mut with_lines, rate, freq, 0.0, amplitude, &mut rng);
    }
    let read_outs = |values: Vec<f64>| {
        let result = analysed("ax", values, rate);
        (result.psd_terms.unwrap(), result.lines)
    };
    let (clean, none) = read_outs(noise);
    let (cleaned, found) = read_outs(with_lines);
    assert!(none.is_empty(), "{none:?}");
    assert!(found.len() >= 5, "{found:?}");
    for (term, a, b) in [
        ("N", cleaned.n, clean.n),
        ("B", cleaned.b, clean.b),
        ("K", cleaned.k, clean.k),
    ] {
        assert!(a.resolved() && b.resolved(), "{term}: {a:?} vs {b:?}");
        assert!(b.lo <= a.value && a.value <= b.hi, "{term}: {a:?} vs {b:?}");
    }
    assert!(
        cleaned.reduced_chi2 < clean.reduced_chi2 + 0.5,
        "reduced chi2 {} with lines removed, {} without lines",
        cleaned.reduced_chi2,
        clean.reduced_chi2
    );
}

/// `values` at `rate` Hz as a one-channel record named `name`, analysed with the default
/// options (the line search on).
fn analysed(name: &str, values: Vec<f64>, rate: f64) -> pipeline::ChannelResult {
    let record = Record {
        source: name.into(),
        rate_hz: rate,
        channels: vec![Channel::named(name, values)],
    };
    pipeline::analyze(&record, &Options::default(), &|| {})
        .unwrap()
        .remove(0)
}

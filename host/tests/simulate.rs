//! `imunoise simulate` as a user runs it: the CSV's header, row count and quantization.

mod common;

use common::{example_model, ok, scratch};
use std::path::PathBuf;

#[test]
fn csv_has_the_header_rows_and_quantized_values() {
    let tmp = scratch();
    let out = tmp.path().join("simulate_200_42.csv");
    let status = common::imunoise()
        .args(["simulate", "--model"])
        .arg(example_model())
        .args([
            "--rate",
            "200",
            "--bandwidth",
            "42",
            "--duration",
            "90s",
            "--seed",
            "1",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("time,gx,gy,gz,ax,ay,az,temp"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 200 * 90);
    // LSB sizes at +/-250 deg/s and +/-2 g; TEMP_OUT counts are 1/340 degC from 36.53.
    let gyro_lsb = std::f64::consts::PI / 180.0 / 131.0;
    let accel_lsb = 9.806_65 / 16384.0;
    let is_count = |v: f64, lsb: f64| ((v / lsb) - (v / lsb).round()).abs() < 1e-6;
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r.len(), 8);
        assert!((r[0] - i as f64 / 200.0).abs() < 1e-9, "time of row {i}");
        assert!(
            r[1..4].iter().all(|&v| is_count(v, gyro_lsb)),
            "row {i}: {r:?}"
        );
        assert!(
            r[4..7].iter().all(|&v| is_count(v, accel_lsb)),
            "row {i}: {r:?}"
        );
        assert!(is_count(r[7] - 36.53, 1.0 / 340.0), "row {i}: {r:?}");
    }
    // At rest, flat: gravity on z, the temperature near 25 degC.
    let mean = |c: usize| rows.iter().map(|r| r[c]).sum::<f64>() / rows.len() as f64;
    assert!((mean(6) - 9.8).abs() < 0.5, "{}", mean(6));
    assert!((mean(7) - 25.5).abs() < 1.0, "{}", mean(7));
    // Reproducible.
    let again = tmp.path().join("simulate_200_42_again.csv");
    let status = common::imunoise()
        .args(["simulate", "--model"])
        .arg(example_model())
        .args([
            "--rate",
            "200",
            "--bandwidth",
            "42",
            "--duration",
            "1.5m",
            "--out",
        ])
        .arg(&again)
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(std::fs::read_to_string(&again).unwrap(), text);
}

#[test]
fn errors_name_what_is_wrong() {
    let tmp = scratch();
    // (model, rate, duration, format)
    let run_with = |model: PathBuf, rate: &str, duration: &str, format: &str| {
        let out = common::imunoise()
            .args(["simulate", "--model"])
            .arg(model)
            .args(["--rate", rate, "--bandwidth", "42", "--duration", duration])
            .args(["--format", format, "--out"])
            .arg(tmp.path().join("simulate_err.csv"))
            .output()
            .unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let run = |rate, duration, format| run_with(example_model(), rate, duration, format);
    assert!(run("200", "1s", "npz").contains("--format npz: unknown format"));
    assert!(run("200", "2d", "csv").contains("--duration"));
    assert!(run("150", "1s", "csv").contains("not reachable"));
    let bad = tmp.path().join("bad_model.toml");
    std::fs::write(&bad, "[gyro]\nnoise_densty = 1\n").unwrap();
    let e = run_with(bad, "200", "1s", "csv");
    assert!(
        e.contains("bad_model.toml") && e.contains("noise_densty"),
        "{e}"
    );
}

/// The same seed written as a capture (the board's framed bytes) and as CSV analyses to the
/// same numbers: the capture carries the settings, and its counts convert to the CSV's SI
/// values exactly.
#[test]
fn a_capture_analyses_like_the_csv_of_the_same_run() {
    let tmp = scratch();
    let model = example_model();
    let model = model.to_str().unwrap();
    let (cap, csv) = (
        tmp.path().join("sim_50_42.imucap"),
        tmp.path().join("sim_50_42.csv"),
    );
    for (path, format) in [(&cap, "capture"), (&csv, "csv")] {
        ok(&[
            "simulate",
            "--model",
            model,
            "--rate",
            "50",
            "--bandwidth",
            "42",
            "--duration",
            "600s",
            "--seed",
            "3",
            "--format",
            format,
            "--out",
            path.to_str().unwrap(),
        ]);
    }
    let bytes = std::fs::read(&cap).unwrap();
    assert_eq!(bytes[0], 0x00, "a capture starts with a frame delimiter");
    let json = |path: &PathBuf| -> serde_json::Value {
        let text = ok(&["analyze", path.to_str().unwrap(), "--json", "-"]);
        serde_json::from_str(&text).unwrap()
    };
    let (a, b) = (json(&cap), json(&csv));
    assert_eq!(a["rate_hz"], 50.0);
    assert_eq!(a["samples"], 30_000);
    for ch in 0..7 {
        let (ca, cb) = (&a["channels"][ch], &b["channels"][ch]);
        assert_eq!(ca["name"], cb["name"]);
        let (da, db) = (
            &ca["deviations"]["oadev"]["dev"],
            &cb["deviations"]["oadev"]["dev"],
        );
        let (da, db) = (da.as_array().unwrap(), db.as_array().unwrap());
        assert_eq!(da.len(), db.len());
        for (x, y) in da.iter().zip(db) {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!((x / y - 1.0).abs() < 1e-9, "{}: {x} vs {y}", ca["name"]);
        }
    }
}

/// `--board gy85`: the ITG-3200 and the ADXL345 at the PSD study's 50 Hz, each in its own
/// counts (14.375 LSB per deg/s; 256 LSB per g) and temperature formula, the white noise
/// where the chains put it: the gyro's N through the 20 Hz filter and the decimation, the
/// accelerometer's sqrt(2) above its 100 Hz density (the same LSB rms at 50 Hz as at 100).
#[test]
fn the_gy85_pair_comes_out_in_its_own_counts_and_noise() {
    let tmp = scratch();
    let out = tmp.path().join("gy85.csv");
    // White noise only, so that N is known exactly.
    let model = tmp.path().join("white.toml");
    std::fs::write(
        &model,
        "[gyro]\nnoise_density = 3.7e-4\n[accel]\nnoise_density = 2.84e-3\n[temperature]\nnoise_density = 0.01\n",
    )
    .unwrap();
    let text = ok(&[
        "simulate",
        "--board",
        "gy85",
        "--model",
        model.to_str().unwrap(),
        "--rate",
        "50",
        "--bandwidth",
        "20",
        "--duration",
        "20m",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(text.is_empty(), "{text}");
    let rows: Vec<Vec<f64>> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 50 * 1200);
    let gyro_lsb = (1.0f64 / 14.375).to_radians();
    let accel_lsb = 9.806_65 / 256.0;
    let is_count = |v: f64, lsb: f64| ((v / lsb) - (v / lsb).round()).abs() < 1e-6;
    for r in rows.iter().take(1000) {
        assert!(r[1..4].iter().all(|&v| is_count(v, gyro_lsb)), "{r:?}");
        assert!(r[4..7].iter().all(|&v| is_count(v, accel_lsb)), "{r:?}");
        assert!(
            is_count(r[7] - 35.0 - 13200.0 / 280.0, 1.0 / 280.0),
            "{r:?}"
        );
    }
    let analysis = common::json(&common::run(&[
        "analyze",
        out.to_str().unwrap(),
        "--json",
        "-",
    ]));
    let n = |name: &str| {
        let c = analysis["channels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == name)
            .unwrap();
        // The PSD read-out: over a band well below both filters' cutoffs, where the
        // spectrum is the flat level the chains set (the Allan fit's short taus also see
        // the filters' shape).
        let t = &c["psd_noise"]["N"];
        (
            t["value"].as_f64().unwrap(),
            t["lo"].as_f64().unwrap(),
            t["hi"].as_f64().unwrap(),
        )
    };
    // The 20 Hz DLPF at 1 kHz decimated by 20 folds a little noise back; the quantization
    // adds (LSB / sqrt(12))^2 per sample.
    let design = imunoise::sim::dlpf::DlpfDesign::for_setting(
        protocol::mpu6050::DlpfCfg::Cfg4,
        imunoise::sim::dlpf::Sensor::Gyro,
    );
    let folding = imunoise::sim::chain::white_noise_inflation(&design, 20);
    let q = |lsb: f64| lsb / 12f64.sqrt() / 50f64.sqrt();
    let gyro_truth = (3.7e-4 * folding).hypot(q(gyro_lsb));
    let accel_truth = (2.84e-3 * 2f64.sqrt()).hypot(q(accel_lsb));
    for (name, truth) in [("gx", gyro_truth), ("ax", accel_truth), ("ay", accel_truth)] {
        let (v, lo, hi) = n(name);
        // Three half-widths of the 68 % interval: about 3 standard errors.
        let slack = 3.0 * (hi - lo) / 2.0;
        assert!(
            (v - truth).abs() < slack,
            "{name}: N {v:.4e} [{lo:.4e}, {hi:.4e}] against {truth:.4e}"
        );
    }
}

//! `imunoise calibrate` on the virtual board: the simulator's known bias, scale factors,
//! misalignment and temperature coefficients are recovered, within tolerances derived from
//! the simulated noise; `--calibrated` then removes them from a new session, while the
//! stored data stay raw.
//!
//! The models have white noise only (N), so every estimate is a mean of independent
//! samples and its standard error follows from N alone: the mean of T seconds has
//! sigma_m = N / sqrt(T). Tolerances are 4 standard errors (each check fails by chance with
//! probability 6e-5; the seed is fixed). The sensor settings, 100 Hz with a 42 Hz DLPF,
//! leave N unchanged at long averaging times (the bandwidth is below Nyquist), and the LSB
//! (6e-4 m/s^2, 1.3e-4 rad/s) is far below the per-sample noise, which dithers it.

mod common;

use common::{TempStore, stderr};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Output;

const G: f64 = 9.80665;
const DEG: f64 = std::f64::consts::PI / 180.0;
/// White noise, two-sided densities of the models below.
const GYRO_N: f64 = 1.5e-4; // rad/s/sqrt(Hz)
const ACCEL_N: f64 = 3e-3; // m/s^2/sqrt(Hz)

const GYRO_BIAS: [f64; 3] = [0.02, -0.01, 0.005];
const GYRO_SCALE: [f64; 3] = [0.01, -0.005, 0.0];
const GYRO_MIS: [[f64; 3]; 3] = [
    [0.0, 0.002, -0.001],
    [0.001, 0.0, 0.002],
    [-0.002, 0.001, 0.0],
];
const ACCEL_BIAS: [f64; 3] = [0.2, -0.1, 0.3];
const ACCEL_SCALE: [f64; 3] = [0.005, 0.003, -0.004];
const ACCEL_MIS: [[f64; 3]; 3] = [
    [0.0, 0.003, -0.002],
    [0.001, 0.0, 0.004],
    [-0.003, 0.002, 0.0],
];
const GYRO_TEMP: f64 = 1e-4; // rad/s/degC
const ACCEL_TEMP: f64 = 1e-3; // m/s^2/degC

/// The model file: at 25 degC (the coupling's reference) unless `warmup`.
fn model(store: &TempStore, warmup: bool) -> PathBuf {
    let m = |x: [[f64; 3]; 3]| format!("{x:?}");
    let text = format!(
        "[gyro]\nnoise_density = {GYRO_N}\nbias = {:?}\nscale_factor = {:?}\nmisalignment = {}\n\
         temperature = {{ bias_coeff = {GYRO_TEMP} }}\n\
         [accel]\nnoise_density = {ACCEL_N}\nbias = {:?}\nscale_factor = {:?}\nmisalignment = {}\n\
         temperature = {{ bias_coeff = {ACCEL_TEMP} }}\n\
         [temperature]\ninitial = 25.0\nreference = 25.0\nnoise_density = 0.01\n{}",
        GYRO_BIAS,
        GYRO_SCALE,
        m(GYRO_MIS),
        ACCEL_BIAS,
        ACCEL_SCALE,
        m(ACCEL_MIS),
        if warmup {
            "warmup = { rise = 6.0, tau = 120.0 }\n"
        } else {
            ""
        }
    );
    let path = store.file(if warmup { "warm.toml" } else { "model.toml" });
    std::fs::write(&path, text).unwrap();
    path
}

/// The simulator's K = (I + M) diag(1 + s) (sim/imu.rs).
fn sim_matrix(scale: [f64; 3], mis: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut k = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            k[i][j] = (f64::from(u8::from(i == j)) + mis[i][j]) * (1.0 + scale[j]);
        }
    }
    k
}

fn json(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

fn vec3(v: &Value) -> [f64; 3] {
    [0, 1, 2].map(|i| v[i].as_f64().unwrap())
}

fn close(what: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol,
        "{what}: {got:e}, truth {want:e}, tolerance {tol:e}"
    );
}

/// Check a stored correction against the simulator's truth.
fn check_correction(c: &Value, bias: [f64; 3], k: [[f64; 3]; 3], tol_b: f64, tol_k: f64) {
    let got_b = vec3(&c["bias"]);
    for i in 0..3 {
        close(&format!("bias[{i}]"), got_b[i], bias[i], tol_b);
        let row = vec3(&c["matrix"][i]);
        for j in 0..3 {
            close(&format!("K[{i}][{j}]"), row[j], k[i][j], tol_k);
        }
    }
}

const SIM: [&str; 6] = ["--port", "sim", "--rate", "100", "--bandwidth", "42"];

#[test]
fn accel_six_positions_and_gyro_rate_table_recover_the_simulator_and_correct_a_session() {
    let store = TempStore::new();
    let model = model(&store, false);
    let model = model.to_str().unwrap();

    // Six positions of 20 s: sigma_m = 3e-3 / sqrt(20) = 6.7e-4 m/s^2. The least-squares
    // bias is the mean of the six readings of an axis (the +-g inputs cancel): sigma_m /
    // sqrt(6) = 2.7e-4; K_ij is the difference of two readings over 2g: sigma_m sqrt(2) /
    // (2g) = 4.8e-5.
    let sigma_m = ACCEL_N / 20f64.sqrt();
    let args = [
        &["calibrate", "accel"][..],
        &SIM,
        &["--model", model, "--seconds", "20", "--json"],
    ]
    .concat();
    let out = store.ok(&args);
    let doc = json(&out);
    let accel = &doc["calibration"]["corrections"][0];
    assert_eq!(accel["sensor"], "accel");
    check_correction(
        accel,
        ACCEL_BIAS,
        sim_matrix(ACCEL_SCALE, ACCEL_MIS),
        4.0 * sigma_m / 6f64.sqrt(),
        4.0 * sigma_m * 2f64.sqrt() / (2.0 * G),
    );
    // The settings study's up/down gives the same diagonal: bias (f_up + f_down)/2 has sigma_m /
    // sqrt(2); the scale factor the same sigma as K_jj.
    for (j, t) in doc["calibration"]["details"]["up_down"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let b = t["bias"].as_f64().unwrap();
        close(
            "up/down bias",
            b,
            ACCEL_BIAS[j],
            4.0 * sigma_m / 2f64.sqrt(),
        );
        let s = t["scale_factor"].as_f64().unwrap();
        close(
            "up/down scale",
            s,
            ACCEL_SCALE[j],
            4.0 * sigma_m * 2f64.sqrt() / (2.0 * G),
        );
    }

    // The same six captures, given back as stored sessions (ids 1..6, in the order taken:
    // +x -x +y -y +z -z), give the same calibration to the last digit.
    let positions = ["+x", "-x", "+y", "-y", "+z", "-z"]
        .iter()
        .enumerate()
        .map(|(i, p)| format!("--position={p}={}", i + 1))
        .collect::<Vec<_>>();
    let mut args = vec!["calibrate", "accel", "--json", "--dry-run"];
    args.extend(positions.iter().map(String::as_str));
    let again = json(&store.ok(&args));
    assert_eq!(again["calibration"], doc["calibration"]);
    assert_eq!(again["board_id"], doc["board_id"]);

    // Rate table at +-100 deg/s, 10 s each: sigma_m = 1.5e-4 / sqrt(10) = 4.7e-5 rad/s; the
    // bias again sigma_m / sqrt(6), K_ij sigma_m sqrt(2) / (2 w).
    let sigma_m = GYRO_N / 10f64.sqrt();
    let w = 100.0 * DEG;
    let args = [
        &["calibrate", "gyro"][..],
        &SIM,
        &[
            "--model",
            model,
            "--table-rate",
            "100",
            "--seconds",
            "10",
            "--json",
        ],
    ]
    .concat();
    let doc = json(&store.ok(&args));
    check_correction(
        &doc["calibration"]["corrections"][0],
        GYRO_BIAS,
        sim_matrix(GYRO_SCALE, GYRO_MIS),
        4.0 * sigma_m / 6f64.sqrt(),
        4.0 * sigma_m * 2f64.sqrt() / (2.0 * w),
    );

    // The rate table as a file of (axis, commanded rate, record) lines naming the six stored
    // sessions (ids 7..12) gives the same calibration.
    let table = store.file("table.txt");
    let lines: String = ["x 100", "x -100", "y 100", "y -100", "z 100", "z -100"]
        .iter()
        .enumerate()
        .map(|(i, l)| format!("{l} {}\n", i + 7))
        .collect();
    std::fs::write(&table, format!("# axis rate_deg_s record\n{lines}")).unwrap();
    let again = json(&store.ok(&[
        "calibrate",
        "gyro",
        "--rate-table",
        table.to_str().unwrap(),
        "--json",
        "--dry-run",
    ]));
    assert_eq!(again["calibration"], doc["calibration"]);

    // Both are listed for the virtual board (board id 0x5349_4d00_0000_0000 | seed 1).
    let list = json(&store.ok(&["calibrations", "--json"]));
    let list = list.as_array().unwrap();
    assert_eq!(list.len(), 2);
    assert!(list.iter().all(|c| c["board_id"] == "0x53494d0000000001"));
    let shown = store.ok(&["calibrations", "show", "1"]);
    let text = String::from_utf8_lossy(&shown.stdout);
    assert!(text.contains("misalignment M (mrad"), "{text}");
    let yaml = store.ok(&["calibrations", "show", "1", "--yaml"]);
    let yaml = String::from_utf8_lossy(&yaml.stdout);
    assert!(yaml.contains("\n      matrix: [["), "{yaml}");
    assert!(yaml.contains("\n      sensor: \"accel\""), "{yaml}");

    // A new 20 s session at rest (z up) from the same board: --calibrated removes bias,
    // scale and misalignment; without it the export is raw. The corrected means then differ
    // from the truth (0, 0, g and zero rate) by the session's own noise plus the
    // calibration's error: sqrt(sigma_session^2 + sigma_bias^2 + (g sigma_K)^2) <
    // 1.2e-3 m/s^2 for the accelerometer and 6e-5 rad/s for the gyro; 4 sigma.
    let args = [
        &["capture"][..],
        &SIM,
        &[
            "--model",
            model,
            "--duration",
            "20s",
            "--speed",
            "max",
            "--name",
            "rest",
        ],
    ]
    .concat();
    store.ok(&args);
    let raw = export_means(&store, false);
    let corrected = export_means(&store, true);
    close(
        "raw ax",
        raw[3],
        ACCEL_BIAS[0] + G * ACCEL_MIS[0][2] * (1.0 + ACCEL_SCALE[2]),
        4.0 * 6.7e-4,
    );
    close("raw gx", raw[0], GYRO_BIAS[0], 4.0 * 3.4e-5);
    for (i, want) in [0.0, 0.0, 0.0, 0.0, 0.0, G].iter().enumerate() {
        let tol = if i < 3 { 4.0 * 6e-5 } else { 4.0 * 1.2e-3 };
        close(&format!("corrected column {i}"), corrected[i], *want, tol);
    }
    // Applied under other settings, the calibration is used with a warning.
    let args = [
        &[
            "capture",
            "--port",
            "sim",
            "--rate",
            "200",
            "--bandwidth",
            "42",
        ][..],
        &[
            "--model",
            model,
            "--duration",
            "5s",
            "--speed",
            "max",
            "--name",
            "fast",
        ],
    ]
    .concat();
    store.ok(&args);
    let out = store.ok(&["export", "fast", "--calibrated"]);
    let err = stderr(&out);
    assert!(
        err.contains("warning: calibration 1 was made at 100 Hz") && err.contains("at 200 Hz"),
        "{err}"
    );
    // analyze applies the same correction (and says so); a file has no board to look up.
    let out = store.ok(&[
        "analyze",
        "rest",
        "--calibrated",
        "--column",
        "gx",
        "--json",
        "-",
    ]);
    assert!(stderr(&out).contains("Gyro corrected"));
    let csv = store.file("rest.csv");
    let csv = csv.to_str().unwrap();
    store.ok(&["export", "rest", "--out", csv]);
    let out = store.run(&["analyze", csv, "--calibrated"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("is a file"));
}

/// Means of gx gy gz ax ay az of the session 'rest', exported raw or `--calibrated`.
fn export_means(store: &TempStore, calibrated: bool) -> [f64; 6] {
    let mut args = vec!["export", "rest"];
    if calibrated {
        args.push("--calibrated");
    }
    let out = store.ok(&args);
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let cols: Vec<usize> = ["gx", "gy", "gz", "ax", "ay", "az"]
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    let mut sums = [0.0; 6];
    let mut n = 0.0;
    for line in lines {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        for (s, &c) in sums.iter_mut().zip(&cols) {
            *s += f[c];
        }
        n += 1.0;
    }
    sums.map(|s| s / n)
}

#[test]
fn temperature_coefficients_are_recovered_from_a_warm_up() {
    let store = TempStore::new();
    let model = model(&store, true);
    let args = [
        &["calibrate", "temperature"][..],
        &SIM,
        &[
            "--model",
            model.to_str().unwrap(),
            "--seconds",
            "600",
            "--json",
        ],
    ]
    .concat();
    let doc = json(&store.ok(&args));
    // The slope's standard error: block noise N / sqrt(1 s) over sqrt(n) blocks times the
    // temperatures' spread, here the profile 25 + 6 (1 - exp(-t / 120 s)) at the 600 blocks.
    let temps: Vec<f64> = (0..600)
        .map(|k| 25.0 + 6.0 * (1.0 - (-(k as f64 + 0.5) / 120.0).exp()))
        .collect();
    let mean = temps.iter().sum::<f64>() / 600.0;
    let spread = (temps.iter().map(|t| (t - mean).powi(2)).sum::<f64>()).sqrt();
    for (i, (n, slope)) in [(GYRO_N, GYRO_TEMP), (ACCEL_N, ACCEL_TEMP)]
        .iter()
        .enumerate()
    {
        let m = &doc["calibration"]["temperature"][i];
        for axis in m["axes"].as_array().unwrap() {
            close(
                "slope",
                axis["c1"].as_f64().unwrap(),
                *slope,
                4.0 * n / spread,
            );
            // The truth is linear: with white noise the F statistic follows F(1, n - 3) and
            // the rule admits a quadratic with probability 0.01 per axis (fixed seed).
            assert_eq!(axis["quadratic"], false, "{axis}");
        }
    }
    assert_eq!(doc["calibration"]["temperature"][1]["sensor"], "accel");
}

#[test]
fn bad_calibration_inputs_are_named() {
    let store = TempStore::new();
    let out = store.run(&["calibrate", "accel", "--position", "+x=a.csv"]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("-x=INPUT") && err.contains("exactly once"),
        "{err}"
    );
    // Refused before the store is opened: none is created.
    assert!(!err.contains("created a new store"), "{err}");
    assert!(!store.path().exists());
    let table = store.file("table.txt");
    std::fs::write(&table, "# axis rate record\nx 100 a.csv\nw 100 b.csv\n").unwrap();
    let out = store.run(&["calibrate", "gyro", "--rate-table", table.to_str().unwrap()]);
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(err.contains("table.txt:2"), "{err}");
    let out = store.run(&["calibrate", "gyro"]);
    assert!(stderr(&out).contains("--port"));
}

#[test]
fn local_gravity_from_latitude_and_height_is_used_as_the_reference() {
    let store = TempStore::new();
    let args = [
        &["calibrate", "accel"][..],
        &SIM,
        &[
            "--latitude",
            "45",
            "--height",
            "100",
            "--seconds",
            "3",
            "--dry-run",
            "--json",
        ],
    ]
    .concat();
    let doc = json(&store.ok(&args));
    // WGS84 normal gravity at 45 deg (9.806199 m/s^2) less the free-air 3.086e-6 s^-2 x 100 m.
    let g = doc["calibration"]["details"]["gravity_m_s2"]
        .as_f64()
        .unwrap();
    close("gravity", g, 9.806199 - 3.086e-4, 2e-6);
    // The virtual board was turned under that gravity: the +x position's truth is +g.
    let truth = &doc["calibration"]["details"]["observations"][0]["truth"];
    assert_eq!(truth[0].as_f64().unwrap(), g);
    let out = store.run(&["calibrate", "accel", "--port", "sim", "--gravity", "1.0"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--gravity 1"));
}

//! `imunoise analyze` as a user runs it: inputs (the real MPU-6050 logger file, CSV with a
//! time column, NumPy), the JSON document's contract, the output files, and the errors.

mod common;

use common::{TempStore, json as json_of, mpu_record, run, scratch, stderr};
use serde_json::Value;
use std::path::Path;

/// A channel's fitted white-noise term N, checked to be in a gyro's or an accelerometer's
/// SI unit.
fn noise_n(channel: &Value, gyro: bool) -> &Value {
    let n = &channel["noise"]["N"];
    let unit = if gyro {
        "rad/s/sqrt(Hz)"
    } else {
        "m/s^2/sqrt(Hz)"
    };
    assert_eq!(n["unit"], unit, "{}", channel["name"]);
    n
}

/// Uniform numbers in [0, 1) from a fixed-seed 64-bit LCG (Knuth's MMIX constants).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// The authors' published white-noise level of the same setup (separate 6-hour log):
/// N = sqrt(R / 100), R from `reference/R_q_<axis>.csv`.
fn published_n(axis: &str) -> f64 {
    let path = format!(
        "{}/../tests/data/mpu6050_static_100hz/reference/R_q_{axis}.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).unwrap();
    let r: f64 = text.lines().next().unwrap().trim().parse().unwrap();
    (r / 100.0).sqrt()
}

#[test]
fn the_real_mpu6050_record_in_raw_counts() {
    let out = run(&["analyze", &mpu_record(), "--counts", "--json", "-"]);
    let doc = json_of(&out);
    assert_eq!(doc["rate_hz"], 100.0); // from the file's `Fs,100` header line
    assert_eq!(doc["samples"], 44930);
    let channels = doc["channels"].as_array().unwrap();
    let names: Vec<&str> = channels
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["ax", "ay", "az", "gx", "gy", "gz"]);
    // gz's 31.003 Hz tone (the record's strongest gyro line), its frequency known to better
    // than 0.05 Hz.
    let tone = channels[5]["lines"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| (l["freq_hz"].as_f64().unwrap() - 31.003).abs() < 0.01)
        .expect("gz's 31 Hz tone");
    assert!(
        tone["standard_errors"]["freq_hz"].as_f64().unwrap() < 0.05,
        "{tone}"
    );
    for c in channels {
        let name = c["name"].as_str().unwrap();
        let gyro = name.starts_with('g');
        assert_eq!(c["unit"], if gyro { "rad/s" } else { "m/s^2" });
        assert_eq!(c["n"], 44930);
        assert_eq!(c["rate_hz"], 100.0);
        let d = &c["deviations"]["oadev"];
        let (tau, dev, lo, hi) = (
            floats(&d["tau"]),
            floats(&d["dev"]),
            floats(&d["lo"]),
            floats(&d["hi"]),
        );
        assert!(tau.len() > 30);
        assert_eq!(tau[0], 0.01);
        // Stable32's term count for oadev: N_phase - 2m = 44931 - 2 at m = 1.
        assert_eq!(d["n"][0], 44929);
        for i in 0..tau.len() {
            assert!(lo[i] < dev[i] && dev[i] < hi[i], "{name} tau {}", tau[i]);
        }
        // The fit's N agrees with the authors' value from a separate, 48 times longer log
        // of the same setup: accelerometers within 10 %, gyros within 30 % (their longer
        // log sees more low-frequency noise in its white-noise variance).
        let n = noise_n(c, gyro);
        let ratio = n["value"].as_f64().unwrap() / published_n(name);
        let tolerance = if gyro { 0.3 } else { 0.1 };
        assert!(
            (ratio - 1.0).abs() < tolerance,
            "{name}: N / published = {ratio}"
        );
        assert!(n["lo"].as_f64().unwrap() <= n["value"].as_f64().unwrap());
        // PSD: one-sided, and its white level agrees with the Allan N (docs/ARCHITECTURE.md, "Units and conventions").
        assert_eq!(c["psd"]["sided"], "one-sided");
        let n_psd = c["psd_noise"]["N"]["value"].as_f64().unwrap();
        assert!(
            (n_psd / n["value"].as_f64().unwrap() - 1.0).abs() < 0.05,
            "{name}"
        );
        // Every spectral line carries its standard errors; a pure tone's width has none.
        for line in c["lines"].as_array().unwrap() {
            let e = &line["standard_errors"];
            for key in ["freq_hz", "amplitude"] {
                let se = e[key].as_f64().unwrap();
                assert!(
                    se > 0.0 && se < line[key].as_f64().unwrap(),
                    "{name}: {line}"
                );
            }
            assert_eq!(
                e["width_hz"].is_null(),
                line["width_hz"] == 0.0,
                "{name}: {line}"
            );
        }
        // Conventional units carry their labels.
        let conventional = &c["noise_conventional"]["N"]["unit"];
        assert_eq!(
            conventional,
            if gyro { "deg/sqrt(h)" } else { "m/s/sqrt(h)" }
        );
    }
    assert!(doc["kalibr"]["gyroscope_noise_density"].as_f64().unwrap() > 0.0);
    assert!(
        doc["conventions"]["psd"]
            .as_str()
            .unwrap()
            .contains("one-sided")
    );
}

#[test]
fn every_estimator_and_grid_on_a_csv_with_a_time_column() {
    let tmp = scratch();
    let path = tmp.path().join("timed.csv");
    let mut text = String::from("# a comment\ntime,gx,temp\n");
    let mut uniform = uniform(12345);
    for i in 0..4000 {
        let u = uniform() - 0.5;
        text.push_str(&format!("{:.3},{u},{}\n", i as f64 * 0.005, 25.0 + u));
    }
    std::fs::write(&path, text).unwrap();
    let path = path.to_str().unwrap();
    let mut args = vec!["analyze", path, "--json", "-", "--taus", "octave"];
    for e in ["oadev", "adev", "mdev", "hdev", "ohdev", "tdev", "totdev"] {
        args.extend(["--estimator", e]);
    }
    let doc = json_of(&run(&args));
    assert_eq!(doc["rate_hz"], 200.0); // from the time column
    let gx = &doc["channels"][0];
    assert_eq!(gx["name"], "gx");
    assert_eq!(doc["channels"][1]["unit"], "degC");
    for e in ["oadev", "adev", "mdev", "hdev", "ohdev", "tdev", "totdev"] {
        let tau = floats(&gx["deviations"][e]["tau"]);
        assert_eq!(tau[0], 0.005, "{e}");
        assert_eq!(tau[1], 0.01, "{e}: octave grid");
    }
}

#[test]
fn phase_input_gives_the_same_allan_deviation_as_rate_input() {
    let tmp = scratch();
    let rate = tmp.path().join("rate.csv");
    let phase = tmp.path().join("phase.csv");
    let (mut r, mut p) = (String::from("gx\n"), String::from("gx\n"));
    let (mut x, mut s) = (0.0f64, 99u64);
    p.push_str("0\n");
    for _ in 0..3000 {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let y = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        x += y * 0.1;
        r.push_str(&format!("{y:e}\n"));
        p.push_str(&format!("{x:e}\n"));
    }
    std::fs::write(&rate, r).unwrap();
    std::fs::write(&phase, p).unwrap();
    let a = json_of(&run(&[
        "analyze",
        rate.to_str().unwrap(),
        "--rate",
        "10",
        "--json",
        "-",
    ]));
    let b = json_of(&run(&[
        "analyze",
        phase.to_str().unwrap(),
        "--rate",
        "10",
        "--data-type",
        "phase",
        "--json",
        "-",
    ]));
    let (da, db) = (
        floats(&a["channels"][0]["deviations"]["oadev"]["dev"]),
        floats(&b["channels"][0]["deviations"]["oadev"]["dev"]),
    );
    assert_eq!(da.len(), db.len());
    for (x, y) in da.iter().zip(&db) {
        assert!((x / y - 1.0).abs() < 1e-9, "{x} vs {y}");
    }
}

#[test]
fn output_files_plot_kalibr_and_report() {
    let tmp = scratch();
    let (svg, png, yaml, html, json) = (
        tmp.path().join("fig.svg"),
        tmp.path().join("fig.png"),
        tmp.path().join("imu.yaml"),
        tmp.path().join("report.html"),
        tmp.path().join("out.json"),
    );
    let out = run(&[
        "analyze",
        &mpu_record(),
        "--counts",
        "--plot",
        svg.to_str().unwrap(),
        "--kalibr",
        yaml.to_str().unwrap(),
        "--report",
        html.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("deg/sqrt(h)") && table.contains("rad/s/sqrt(Hz)"),
        "{table}"
    );
    let svg_text = std::fs::read_to_string(&svg).unwrap();
    assert!(svg_text.contains("Gyroscope") && svg_text.contains("Accelerometer"));
    let out = run(&[
        "analyze",
        &mpu_record(),
        "--counts",
        "--column",
        "gz",
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    let yaml_text = std::fs::read_to_string(&yaml).unwrap();
    for key in [
        "gyroscope_noise_density:",
        "gyroscope_random_walk:",
        "accelerometer_noise_density:",
        "accelerometer_random_walk:",
        "update_rate: 100",
    ] {
        assert!(yaml_text.contains(key), "{key} missing:\n{yaml_text}");
    }
    let html_text = std::fs::read_to_string(&html).unwrap();
    assert!(html_text.contains("<svg") && !html_text.contains("src=\"http"));
    // gz's 31 Hz tone, with its standard errors, in the report and in the table.
    assert!(
        html_text.contains("Spectral lines") && html_text.contains("<td>31.0032 &plusmn; "),
        "{html_text}"
    );
    assert!(table.contains("freq Hz       +-"), "{table}");
    let doc: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["channels"].as_array().unwrap().len(), 6);
}

#[test]
fn numpy_input_with_names() {
    let tmp = scratch();
    let path = tmp.path().join("two.npy");
    let values: Vec<f64> = (0..2000)
        .map(|i| ((i * 7919) % 1000) as f64 * 1e-3)
        .collect();
    imunoise::input::write_npy(Path::new(&path), &values).unwrap();
    let doc = json_of(&run(&[
        "analyze",
        path.to_str().unwrap(),
        "--rate",
        "50",
        "--names",
        "ax",
        "--json",
        "-",
    ]));
    assert_eq!(doc["channels"][0]["name"], "ax");
    assert_eq!(doc["channels"][0]["unit"], "m/s^2");
    assert_eq!(doc["channels"][0]["n"], 2000);
}

/// A record with a channel that never changes (a dead axis, a temperature that never moved a
/// count) is analysed without it, and says so on stderr and in the JSON's input warnings;
/// asked for by name, the channel is an error.
#[test]
fn a_constant_channel_is_left_out_of_the_others_analysis() {
    let tmp = scratch();
    let path = tmp.path().join("dead.csv");
    let mut next = uniform(7);
    let rows: String = (0..400)
        .map(|_| format!("{},0,25.5\n", next() - 0.5))
        .collect();
    std::fs::write(&path, format!("gx,ax,temp\n{rows}")).unwrap();
    let out = run(&[
        "analyze",
        path.to_str().unwrap(),
        "--rate",
        "10",
        "--json",
        "-",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc = json_of(&out);
    let names: Vec<&str> = doc["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["gx"]);
    let warnings = doc["input"]["warnings"].to_string();
    assert!(
        warnings.contains("'ax' is constant (0 for all 400 samples): left out"),
        "{warnings}"
    );
    assert!(stderr(&out).contains("'temp' is constant (25.5 for all 400 samples)"));
    let named = run(&[
        "analyze",
        path.to_str().unwrap(),
        "--rate",
        "10",
        "--column",
        "ax",
    ]);
    assert!(!named.status.success());
    assert!(
        stderr(&named).contains("channel 'ax' is constant"),
        "{}",
        stderr(&named)
    );
}

#[test]
fn bad_inputs_get_clear_errors() {
    let cases: [(&str, &str, &[&str], &str); 6] = [
        ("norate.csv", "gx\n1\n2\n3\n", &[], "give --rate HZ"),
        (
            "nan.csv",
            "gx\n1\n2\nnan\n",
            &["--rate", "10"],
            "nan.csv:4: column 'gx': a missing value ('nan'); --longest-run analyses the longest \
             run of complete rows",
        ),
        (
            "const.csv",
            &format!("gx\n{}", "1.5\n".repeat(40)),
            &["--rate", "10"],
            "constant",
        ),
        (
            "short.csv",
            "gx\n1\n2\n3\n",
            &["--rate", "10"],
            "3 samples; at least 16",
        ),
        ("empty.csv", "gx\n", &["--rate", "10"], "no data lines"),
        (
            "col.csv",
            &format!("gx\n{}", "1\n2\n".repeat(20)),
            &["--rate", "10", "--column", "gy"],
            "--column gy: no such channel",
        ),
    ];
    let tmp = scratch();
    for (name, text, extra, expected) in cases {
        let path = tmp.path().join(name);
        std::fs::write(&path, text).unwrap();
        let mut args = vec!["analyze", path.to_str().unwrap()];
        args.extend_from_slice(extra);
        let out = run(&args);
        assert_eq!(out.status.code(), Some(1), "{name}");
        let err = stderr(&out);
        assert!(err.contains(expected), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
    let out = run(&["analyze", "/nonexistent/x.csv", "--rate", "1"]);
    assert!(stderr(&out).contains("/nonexistent/x.csv"));
    let out = run(&["analyze", &mpu_record(), "--counts", "--estimator", "avar"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("unknown estimator 'avar'"));
}

/// A capture with a gap is refused with the count, and analysed over its longest gap-free
/// run on request, with every loss reported.
#[test]
fn gapped_captures_are_refused_or_cut_to_their_longest_run() {
    let tmp = scratch();
    use imunoise::capture::CaptureWriter;
    use protocol::{
        DeviceInfo, DeviceMessage, FirmwareVersion, PROTOCOL_VERSION, RawSample, SampleBatch,
    };
    let settings = protocol::SensorSettings::for_rate_and_bandwidth(100.0, 42.0).unwrap();
    let mut w = CaptureWriter::new(Vec::new());
    w.message(&DeviceMessage::Info(DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 1,
        who_am_i: 0x68,
        settings,
        streaming: true,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    }))
    .unwrap();
    let mut s = 5u64;
    // Indices 0..3200 then, after a 64-sample gap, 3264..3904.
    for first in (0..3200).step_by(32).chain((3264..3904).step_by(32)) {
        let samples = (0..32)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                RawSample {
                    gyro: [(s >> 58) as i16, 0, 0],
                    accel: [0, 0, 16384],
                    temp: 0,
                }
            })
            .collect();
        w.message(&DeviceMessage::Samples(SampleBatch {
            first_index: first,
            first_timestamp_us: first * 10_000,
            samples,
        }))
        .unwrap();
    }
    let path = tmp.path().join("gapped.imucap");
    std::fs::write(&path, w.into_inner()).unwrap();
    let path = path.to_str().unwrap();
    let out = run(&["analyze", path, "--column", "gx"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("64 samples lost in 1 gap(s) (first at index 3200)"),
        "{}",
        stderr(&out)
    );
    let out = run(&[
        "analyze",
        path,
        "--column",
        "gx",
        "--longest-run",
        "--json",
        "-",
    ]);
    assert!(stderr(&out).contains("note: capture: 64 samples lost in 1 gap(s); analysing the longest gap-free run, 3200 samples"), "{}", stderr(&out));
    let doc = json_of(&out);
    assert_eq!(doc["samples"], 3200);
    assert_eq!(doc["rate_hz"], 100.0);
}

/// A gzip file of `text`.
fn gzipped(text: &str) -> Vec<u8> {
    use std::io::Write;
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(text.as_bytes()).unwrap();
    z.finish().unwrap()
}

/// A host-stamped log as an Arduino or a ROS node writes it: `rows` samples of a sensor whose
/// clock runs at `rate_hz`, stamped on arrival in epoch seconds with +-100 us of uniform
/// latency, and every sample in `bursts` (ranges of rows) stamped when the last one of its
/// range arrived. Unit-suffixed columns: white noise of 0.05 deg/s on the gyro axes and
/// 2 mg on the accelerometer axes (1 g on z), and the temperature.
fn host_stamped_log(rows: usize, rate_hz: f64, bursts: &[std::ops::Range<usize>]) -> String {
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
    let gyro = Normal::new(0.0, GYRO_DPS).unwrap();
    let accel = Normal::new(0.0, ACCEL_G).unwrap();
    let mut stamps: Vec<f64> = (0..rows)
        .map(|i| 1.7e9 + i as f64 / rate_hz + rng.random_range(-100e-6..=100e-6))
        .collect();
    for burst in bursts {
        let last = stamps[burst.end - 1];
        stamps[burst.clone()].iter_mut().for_each(|t| *t = last);
    }
    let mut text = String::from("timestamp,gx_dps,gy_dps,gz_dps,ax_g,ay_g,az_g,temp_C\n");
    for t in stamps {
        let [gx, gy, gz] = [(); 3].map(|_| gyro.sample(&mut rng));
        let [ax, ay, az] = [(); 3].map(|_| accel.sample(&mut rng));
        let temp = 31.5 + 0.01 * rng.random_range(-1.0..1.0);
        text.push_str(&format!(
            "{t:.6},{gx:.7},{gy:.7},{gz:.7},{ax:.8},{ay:.8},{:.8},{temp:.3}\n",
            1.0 + az
        ));
    }
    text
}

const GYRO_DPS: f64 = 0.05;
const ACCEL_G: f64 = 0.002;

/// `imunoise analyze PATH --confidence 0.997 --json -`: its document and its output.
fn analysed_at_997(path: &Path) -> (Value, std::process::Output) {
    let out = run(&[
        "analyze",
        path.to_str().unwrap(),
        "--confidence",
        "0.997",
        "--json",
        "-",
    ]);
    (json_of(&out), out)
}

/// The channel's N interval holds `truth`.
fn n_covers(channel: &Value, gyro: bool, truth: f64) {
    let n = noise_n(channel, gyro);
    let (lo, hi) = (n["lo"].as_f64().unwrap(), n["hi"].as_f64().unwrap());
    assert!(
        lo <= truth && truth <= hi,
        "{}: {truth} not in [{lo}, {hi}]",
        channel["name"]
    );
}

/// The done-means case: ten minutes of a 100 Hz sensor whose clock runs 0.13 % slow, logged
/// by a host with jitter and two USB bursts, unit-suffixed and gzipped, analyses as it is.
/// The rate comes out within 0.1 % of the sensor's (the nominal 100 Hz would not), and N in
/// SI within its interval: N = sigma / sqrt(rate) for white noise of standard deviation
/// sigma per sample. The intervals are 99.7 % ones, so all six hold the truth with
/// probability 0.98 and a unit error (57x for deg/s, 9.8x for g) lies far outside them.
#[test]
fn a_host_stamped_gzipped_log_with_units_analyses_with_no_preparation() {
    let tmp = scratch();
    let rate = 99.87;
    let text = host_stamped_log(60_000, rate, &[20_000..20_012, 45_000..45_020]);
    let path = tmp.path().join("arduino.csv.gz");
    std::fs::write(&path, gzipped(&text)).unwrap();
    let (doc, out) = analysed_at_997(&path);
    let got = doc["rate_hz"].as_f64().unwrap();
    assert!((got / rate - 1.0).abs() < 1e-3, "{got} Hz");
    assert_eq!(doc["samples"], 60_000);
    assert_eq!(doc["input"]["compression"], "gzip");
    assert_eq!(doc["input"]["timing"]["column"], "timestamp");
    assert_eq!(doc["input"]["units"].as_array().unwrap().len(), 7);
    assert!(
        stderr(&out).contains("warning: time column 'timestamp'"),
        "{}",
        stderr(&out)
    );
    let channels = doc["channels"].as_array().unwrap();
    let names: Vec<&str> = channels
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["gx", "gy", "gz", "ax", "ay", "az", "temp"]);
    for c in &channels[..6] {
        let gyro = c["name"].as_str().unwrap().starts_with('g');
        let sigma = if gyro {
            GYRO_DPS.to_radians()
        } else {
            ACCEL_G * 9.80665
        };
        n_covers(c, gyro, sigma / rate.sqrt());
    }
    assert_eq!(channels[6]["unit"], "degC");
}

/// Exports written by other people's tools analyse as they are: a phone app's CSV (a
/// byte-order mark, quoted names with bracketed units, CRLF) and `rostopic echo -p` output
/// (stamps in nanoseconds, a sequence number, ROS field names). The rate comes from the
/// stamps, deg/s is converted, the counter and the second stamp are set aside and said so,
/// and N in SI lies in its 99.7 % interval (both files: probability 0.99).
#[test]
fn phone_app_and_rostopic_exports_analyse_as_they_are() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let tmp = scratch();
    let (rate, rows) = (200.0, 40_000);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
    let gyro = Normal::new(0.0, GYRO_DPS).unwrap();
    let mut phone =
        String::from("\u{feff}\"Time (s)\",\"Gyroscope x (deg/s)\",\"Gyroscope y (deg/s)\"\r\n");
    let mut ros =
        String::from("%time,field.header.seq,field.header.stamp,field.angular_velocity.x\n");
    for i in 0..rows {
        let t = i as f64 / rate;
        let (x, y) = (gyro.sample(&mut rng), gyro.sample(&mut rng));
        phone.push_str(&format!("\"{t:.4}\",\"{x:.7}\",\"{y:.7}\"\r\n"));
        let ns = 1_700_000_000_000_000_000u64 + i as u64 * 5_000_000;
        ros.push_str(&format!("{ns},{i},{ns},{:.9}\n", x.to_radians()));
    }
    let cases = [
        (
            "phone.csv",
            phone,
            "Time (s)",
            "s, by its name",
            vec!["Gyroscope x", "Gyroscope y"],
        ),
        (
            "rostopic.csv",
            ros,
            "%time",
            "ns, by its name",
            vec!["field.angular_velocity.x"],
        ),
    ];
    for (file, text, column, unit, names) in cases {
        let path = tmp.path().join(file);
        std::fs::write(&path, text).unwrap();
        let doc = analysed_at_997(&path).0;
        let timing = &doc["input"]["timing"];
        assert_eq!(timing["column"], column, "{file}");
        assert_eq!(timing["unit"], unit, "{file}");
        assert!(
            (doc["rate_hz"].as_f64().unwrap() - rate).abs() < 1e-3,
            "{file}"
        );
        let channels = doc["channels"].as_array().unwrap();
        let got: Vec<&str> = channels
            .iter()
            .map(|c| c["name"].as_str().unwrap())
            .collect();
        assert_eq!(got, names, "{file}");
        for c in channels {
            n_covers(c, true, GYRO_DPS.to_radians() / rate.sqrt());
        }
    }
    let out = run(&["analyze", tmp.path().join("rostopic.csv").to_str().unwrap()]);
    let shown = String::from_utf8_lossy(&out.stdout).to_string() + &stderr(&out);
    assert!(
        shown.contains("not analysed (further time stamps, sample counters): 'field.header.seq', 'field.header.stamp'"),
        "{shown}"
    );
}

/// `--rate` overrides a time column with a warning stating both; a real gap is refused by
/// line, time and count; `--longest-run` keeps the longest run between gaps; `--ignore-time`
/// takes the rows as they are, also for an import.
#[test]
fn rate_overrides_and_ignore_time_sets_aside_a_time_column() {
    let tmp = scratch();
    let mut text = String::from("t,gx_dps\n");
    for i in 0..3000 {
        if !(1000..1005).contains(&i) {
            text.push_str(&format!(
                "{:.6},{}\n",
                i as f64 / 100.5,
                (i * 7919 % 1000) as f64 * 1e-3
            ));
        }
    }
    let gapped = tmp.path().join("gapped.txt.gz");
    std::fs::write(&gapped, gzipped(&text)).unwrap();
    let gapped = gapped.to_str().unwrap();
    let out = run(&["analyze", gapped, "--rate", "100"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains(&format!(
            "{gapped}: time column 't': 5 sample(s) missing in 1 gap(s) that the fitted period \
             (9.9502 ms) cannot absorb: line 1002 (t = 10 s): 5 sample(s) missing"
        )),
        "{}",
        stderr(&out)
    );
    let out = run(&["analyze", gapped, "--rate", "100", "--ignore-time"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(
        shown.contains("time column 't' ignored (--ignore-time)"),
        "{shown}"
    );
    assert!(
        shown.contains("units from column names: gx_dps: deg/s -> rad/s x 0.0174533"),
        "{shown}"
    );
    assert!(shown.contains("2995 samples at 100.000 Hz"), "{shown}");
    // --longest-run keeps the 1995 rows after the gap, at the stamps' own rate.
    let out = run(&["analyze", gapped, "--longest-run", "--json", "-"]);
    assert!(
        stderr(&out).contains(
            "note: time column 't': 5 sample(s) missing in 1 gap(s); analysed the longest \
             gap-free run (--longest-run): lines 1002 to 2996, 1995 of 2995 rows"
        ),
        "{}",
        stderr(&out)
    );
    let doc = json_of(&out);
    assert_eq!(doc["samples"], 1995);
    assert!((doc["rate_hz"].as_f64().unwrap() - 100.5).abs() < 1e-3);

    let whole = tmp.path().join("whole.csv");
    let mut text = String::from("t,gx\n");
    for i in 0..3000 {
        text.push_str(&format!(
            "{:.6},{}\n",
            i as f64 / 100.5,
            (i * 7919 % 1000) as f64 * 1e-3
        ));
    }
    std::fs::write(&whole, text).unwrap();
    let out = run(&[
        "analyze",
        whole.to_str().unwrap(),
        "--rate",
        "100",
        "--json",
        "-",
    ]);
    assert_eq!(json_of(&out)["rate_hz"], 100.0);
    assert!(
        stderr(&out).contains(
            "warning: --rate 100 Hz overrides the time column 't' (100.5 Hz by least squares), -0.498 % apart"
        ),
        "{}",
        stderr(&out)
    );

    // An import keeps --ignore-time for every later read.
    let store = TempStore::new();
    store.ok(&["import", gapped, "--rate", "100", "--ignore-time"]);
    let doc = json_of(&store.run(&["analyze", "1", "--json", "-"]));
    assert_eq!(doc["samples"], 2995);
    assert_eq!(doc["input"]["ignored_time_column"], "t");
}

/// Outputs that cannot be written and options out of range fail before the analysis: exit 1
/// and nothing on stdout (not a whole table, then the error). The PSD segment is checked
/// against the record (2000 samples), never dropped in silence.
#[test]
fn bad_outputs_and_ranges_fail_before_anything_is_printed() {
    let tmp = scratch();
    let path = tmp.path().join("outputs.csv");
    let mut text = String::from("gx\n");
    let mut uniform = uniform(99);
    for _ in 0..2000 {
        text.push_str(&format!("{}\n", uniform()));
    }
    std::fs::write(&path, text).unwrap();
    let path = path.to_str().unwrap();
    let jpg = tmp.path().join("x.jpg");
    let cases: [(&[&str], String); 7] = [
        (
            &["--plot", jpg.to_str().unwrap()],
            format!(
                "--plot {}: plots are written as .svg or .png",
                jpg.display()
            ),
        ),
        (
            &["--report", "/nonexistent/x.html"],
            "--report /nonexistent/x.html: the folder /nonexistent does not exist".into(),
        ),
        (
            &["--filter-period", "0"],
            "--filter-period 0: the filter period must be a positive number of seconds, not 0"
                .into(),
        ),
        (
            &["--filter", "noise.txt"],
            "--filter noise.txt: the file name must end in .json, .yaml or .yml".into(),
        ),
        (
            &["--psd-segment", "0"],
            "--psd-segment 0: a segment length in samples, from 2 to the record's length".into(),
        ),
        (
            &["--psd-segment", "1"],
            "--psd-segment 1: a segment length in samples, from 2 to".into(),
        ),
        (
            &["--psd-segment", "2001"],
            "--psd-segment 2001: a segment length in samples, from 2 to 2000, the record's length"
                .into(),
        ),
    ];
    for (extra, expected) in cases {
        let mut args = vec!["analyze", path, "--rate", "100"];
        args.extend_from_slice(extra);
        let out = run(&args);
        assert_eq!(out.status.code(), Some(1), "{extra:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains(&expected),
            "{extra:?}: {}",
            stderr(&out)
        );
        assert!(out.stdout.is_empty(), "{extra:?} printed before failing");
        assert!(!jpg.exists());
    }
    // The whole record is a valid segment: the PSD has one.
    let doc = json_of(&run(&[
        "analyze",
        path,
        "--rate",
        "100",
        "--psd-segment",
        "2000",
        "--json",
        "-",
    ]));
    assert_eq!(doc["channels"][0]["psd"]["segments"], 1);
    // A sweep checks its outputs before it captures for hours.
    let store = tmp.path().join("sweep-store");
    let out = run(&[
        "--store",
        store.to_str().unwrap(),
        "sweep",
        "--port",
        "sim",
        "--plot",
        "x.jpg",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--plot x.jpg: plots are written as .svg or .png"));
    assert!(!store.exists());
}

/// A 2-D C-order float64 `.npy` of `rows` rows (one column per channel).
fn write_npy_2d(path: &Path, columns: &[Vec<f64>]) {
    let rows = columns[0].len();
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, {}), }}",
        columns.len()
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for r in 0..rows {
        for c in columns {
            bytes.extend_from_slice(&c[r].to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// White noise plus a random walk, from a fixed seed.
fn white_and_walk(n: usize, seed: u64) -> Vec<f64> {
    let mut u = uniform(seed);
    let mut walk = 0.0;
    (0..n)
        .map(|_| {
            walk += 2e-4 * (u() - 0.5);
            0.01 * (u() - 0.5) + walk
        })
        .collect()
}

/// An .npy larger than `--memory-budget` is analysed streamed: the same oadev at every
/// exact tau (1e-9 relative: rounding), N within the in-memory interval, the computation
/// stated in the text, the JSON and on stderr; a NaN is the in-memory path's error.
#[test]
fn npy_beyond_the_memory_budget_is_streamed() {
    let store = TempStore::new();
    let path = store.file("big.npy");
    let columns = [white_and_walk(200_000, 1), white_and_walk(200_000, 2)];
    write_npy_2d(&path, &columns);
    let file = path.to_str().unwrap();
    let common = [
        "analyze",
        file,
        "--rate",
        "100",
        "--names",
        "gx,gy",
        "--bandwidth",
        "off",
    ];
    let analyse = |budget: &str, json: bool| {
        let mut args = common.to_vec();
        args.extend(["--memory-budget", budget]);
        if json {
            args.extend(["--json", "-"]);
        }
        common::run_in(&store.path(), &args)
    };
    let streamed = analyse("1", true);
    assert!(
        stderr(&streamed).contains("more than the memory budget (1 MB): analysed streamed"),
        "{}",
        stderr(&streamed)
    );
    let (s, w) = (json_of(&streamed), json_of(&analyse("1000", true)));
    assert_eq!(s["samples"], 200_000);
    for (sc, wc) in s["channels"]
        .as_array()
        .unwrap()
        .iter()
        .zip(w["channels"].as_array().unwrap())
    {
        let note = sc["computation"].as_str().unwrap();
        assert!(
            note.starts_with("streamed: oadev exact for m <= 16384 ("),
            "{note}"
        );
        assert!(wc.get("computation").is_none());
        let (sd, wd) = (&sc["deviations"]["oadev"], &wc["deviations"]["oadev"]);
        let (sm, wm) = (floats(&sd["m"]), floats(&wd["m"]));
        let (sdev, wdev) = (floats(&sd["dev"]), floats(&wd["dev"]));
        let exact = wm.iter().filter(|&&m| m <= 16384.0).count();
        assert!(exact > 30);
        assert_eq!(sm[..exact], wm[..exact]);
        for k in 0..exact {
            assert!((sdev[k] / wdev[k] - 1.0).abs() < 1e-9, "m {}", wm[k]);
        }
        let (sn, wn) = (noise_n(sc, true), noise_n(wc, true));
        let value = sn["value"].as_f64().unwrap();
        assert!(wn["lo"].as_f64().unwrap() <= value && value <= wn["hi"].as_f64().unwrap());
        assert!(
            sc["psd_noise"]["error"]
                .as_str()
                .unwrap()
                .starts_with("not computed")
        );
    }
    let text = common::stdout(&analyse("1", false));
    assert!(
        text.contains("\nstreamed: oadev exact for m <= 16384 ("),
        "{text}"
    );
    // --bandwidth off states the filter, so no roll-off detection is missing.
    assert!(
        text.contains("taus); no line search; PSD by Welch only\n"),
        "{text}"
    );

    let mut bad = columns.clone();
    bad[1][123_456] = f64::NAN;
    write_npy_2d(&path, &bad);
    let (s, w) = (analyse("1", false), analyse("1000", false));
    assert!(!s.status.success() && !w.status.success());
    assert!(
        stderr(&w).contains("element [123456, 1] is NaN"),
        "{}",
        stderr(&w)
    );
    assert_eq!(
        stderr(&s).lines().last(),
        stderr(&w).lines().last(),
        "{}",
        stderr(&s)
    );
}

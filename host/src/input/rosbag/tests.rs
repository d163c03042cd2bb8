//! Bags written by [`super::write`] in every container, read back through [`crate::input::load`].

use super::write::{self, Container, ImuSample, Ros1Compression};
use crate::analysis::pipeline;
use crate::input::{LoadOptions, load};
use crate::record::Record;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::{Path, PathBuf};

const RATE_HZ: f64 = 200.0;
/// The gyro's white noise density, rad/s/sqrt(Hz), and the accelerometer's, m/s^2/sqrt(Hz).
const GYRO_N: f64 = 2e-4;
const ACCEL_N: f64 = 2e-3;
/// 2023-11-14, in ns: stamps as large as a real bag's.
const EPOCH_NS: i64 = 1_700_000_000_000_000_000;
const PERIOD_NS: i64 = 5_000_000;

/// `n` messages of white noise at 200 Hz, stamped on the sensor's clock; received 1 ms later
/// with up to `jitter_ns` more.
fn record(n: usize, jitter_ns: i64, seed: u64) -> Vec<ImuSample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // White noise of density N sampled at rate f has standard deviation N sqrt(f).
    let mut white = |density: f64| density * RATE_HZ.sqrt() * rng.sample::<f64, _>(StandardNormal);
    (0..n)
        .map(|i| {
            let stamp = EPOCH_NS + i as i64 * PERIOD_NS;
            ImuSample {
                stamp_ns: stamp,
                received_ns: stamp + 1_000_000,
                gyro: [white(GYRO_N), white(GYRO_N), white(GYRO_N)],
                accel: [white(ACCEL_N), white(ACCEL_N), 9.81 + white(ACCEL_N)],
            }
        })
        .map(|mut s| {
            if jitter_ns > 0 {
                s.stamp_ns += ChaCha8Rng::seed_from_u64(s.stamp_ns as u64)
                    .random_range(-jitter_ns..=jitter_ns);
            }
            s
        })
        .collect()
}

fn bag(dir: &Path, container: Container, name: &str, topics: &[(&str, &[ImuSample])]) -> PathBuf {
    let path = dir.join(name);
    write::write(container, &path, topics).unwrap();
    path
}

fn topic(t: &str) -> LoadOptions {
    LoadOptions {
        topic: Some(t.into()),
        ..LoadOptions::default()
    }
}

const CONTAINERS: [(Container, &str); 5] = [
    (Container::Ros1(Ros1Compression::None), "plain.bag"),
    (Container::Ros1(Ros1Compression::Bz2), "bz2.bag"),
    (Container::Ros1(Ros1Compression::Lz4), "lz4.bag"),
    (Container::Mcap, "imu.mcap"),
    (Container::Db3, "rosbag2_dir"),
];

/// The same 2-minute 200 Hz record in a ROS 1 bag (each chunk compression), an MCAP file and
/// a rosbag2 SQLite3 directory: every sample, the values as written, the rate from the stamps,
/// and N from the analysis within its interval.
#[test]
fn the_same_record_reads_alike_from_every_container() {
    let dir = tempfile::tempdir().unwrap();
    let samples = record(24_000, 0, 1);
    for (container, name) in CONTAINERS {
        let path = bag(dir.path(), container, name, &[("/imu/data", &samples)]);
        let loaded = load(&path, &LoadOptions::default()).unwrap();
        let r = &loaded.record;
        assert_eq!(r.names(), ["gx", "gy", "gz", "ax", "ay", "az"], "{name}");
        assert_eq!(r.len(), samples.len(), "{name}");
        assert_eq!(r.channels[1].values[777], samples[777].gyro[1], "{name}");
        assert_eq!(
            r.channels[5].values[23_999], samples[23_999].accel[2],
            "{name}"
        );
        // Stamps in whole ns at exactly 5 ms: the rate to rounding, far within 0.1 %.
        assert!(
            (r.rate_hz / RATE_HZ - 1.0).abs() < 1e-6,
            "{name}: {}",
            r.rate_hz
        );
        let bag = loaded.report.bag.as_ref().unwrap();
        assert_eq!((bag.topic.as_str(), bag.messages), ("/imu/data", 24_000));
        assert_eq!(bag.time_base, "header.stamp");
        assert!(loaded.report.timing.as_ref().unwrap().uniform);
        assert!(
            loaded.report.warnings.is_empty(),
            "{:?}",
            loaded.report.warnings
        );
        if name == "plain.bag" {
            check_white_noise_density(r);
        }
    }
}

/// N of gx and ax from the pipeline: within three of the fit's 68 % half-widths of the
/// density written (the interval is about one standard error either side).
fn check_white_noise_density(r: &Record) {
    for (channel, density) in [("gx", GYRO_N), ("ax", ACCEL_N)] {
        let one = r.clone().select(&[channel.to_string()]).unwrap();
        let results = pipeline::analyze(&one, &Default::default(), &|| {}).unwrap();
        let fit = results[0].fit.as_ref().unwrap();
        let half = (fit.n.hi - fit.n.lo) / 2.0;
        assert!(
            (fit.n.value - density).abs() < 3.0 * half,
            "{channel}: N {} [{}, {}] vs {density}",
            fit.n.value,
            fit.n.lo,
            fit.n.hi
        );
    }
}

/// Stamps jittered by up to 0.5 ms (10 % of the period): accepted, reported, and the rate
/// still within 0.1 % (regression over 20000 stamps: sigma_T / T ~ 3e-8).
#[test]
fn jittery_stamps_are_reported_and_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let samples = record(20_000, 500_000, 2);
    let path = bag(
        dir.path(),
        Container::Mcap,
        "jitter.mcap",
        &[("/imu", &samples)],
    );
    let loaded = load(&path, &LoadOptions::default()).unwrap();
    assert!((loaded.record.rate_hz / RATE_HZ - 1.0).abs() < 1e-3);
    let timing = loaded.report.timing.unwrap();
    assert!(!timing.uniform);
    assert!(timing.worst_step.line >= 1 && timing.worst_step.line <= 20_000);
    assert!(
        loaded.report.warnings[0].contains("time column '/imu header.stamp'"),
        "{:?}",
        loaded.report.warnings
    );
}

/// Three messages dropped after the 5000th: refused as the text path refuses a gap, by
/// message number; --ignore-time --rate takes them as contiguous.
#[test]
fn a_dropped_message_gap_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut samples = record(12_000, 0, 3);
    samples.drain(5_000..5_003);
    let path = bag(
        dir.path(),
        Container::Ros1(Ros1Compression::None),
        "gap.bag",
        &[("/imu", &samples)],
    );
    let err = load(&path, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.starts_with(&path.display().to_string()), "{err}");
    assert!(
        err.contains("3 sample(s) missing in 1 gap(s)")
            && err.contains("message 5001 (t = 25.015 s): 3 sample(s) missing"),
        "{err}"
    );
    let options = LoadOptions {
        ignore_time: true,
        rate_hz: Some(RATE_HZ),
        ..LoadOptions::default()
    };
    let loaded = load(&path, &options).unwrap();
    assert_eq!(loaded.record.len(), 11_997);
    assert_eq!(
        loaded.report.ignored_time_column.as_deref(),
        Some("/imu header.stamp")
    );
}

/// Two IMU topics: without --topic the error lists both with their counts; --topic reads one.
#[test]
fn several_imu_topics_are_listed_until_one_is_chosen() {
    let dir = tempfile::tempdir().unwrap();
    let a = record(3_000, 0, 4);
    let b = record(2_000, 0, 5);
    for (container, name) in CONTAINERS {
        let path = bag(
            dir.path(),
            container,
            name,
            &[("/imu/a", &a), ("/imu/b", &b)],
        );
        let err = load(&path, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("2 IMU topics: /imu/a (sensor_msgs")
                && err.contains("3000 messages), /imu/b (")
                && err.contains("2000 messages); choose one with --topic"),
            "{name}: {err}"
        );
        let loaded = load(&path, &topic("/imu/b")).unwrap();
        assert_eq!(loaded.record.len(), 2_000, "{name}");
        assert_eq!(loaded.record.channels[0].values[10], b[10].gyro[0]);
        let err = load(&path, &topic("/nope")).unwrap_err().to_string();
        assert!(
            err.contains("no topic '/nope'; the bag has /imu/a"),
            "{err}"
        );
    }
}

/// Unset header stamps: the receive times give the rate, and the report says so.
#[test]
fn zero_stamps_fall_back_to_receive_times() {
    let dir = tempfile::tempdir().unwrap();
    let mut samples = record(2_000, 0, 6);
    samples.iter_mut().for_each(|s| s.stamp_ns = 0);
    let path = bag(dir.path(), Container::Db3, "bag", &[("/imu", &samples)]);
    let loaded = load(&path, &LoadOptions::default()).unwrap();
    let bag = loaded.report.bag.unwrap();
    assert_eq!(bag.time_base, "receive time");
    assert!(
        bag.to_string()
            .ends_with("times from receive time (the header stamp is unset in 2000 of them)"),
        "{bag}"
    );
    assert!((loaded.record.rate_hz / RATE_HZ - 1.0).abs() < 1e-6);
}

/// An MCAP file of ROS 1 messages (`message_encoding` ros1, as `mcap convert` makes from a
/// ROS 1 bag), uncompressed, read like any other.
#[test]
fn mcap_with_ros1_messages_reads() {
    use super::imu::encode;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ros1.mcap");
    let samples = record(1_000, 0, 8);
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut writer = ::mcap::WriteOptions::new()
        .compression(None)
        .profile("ros1")
        .create(file)
        .unwrap();
    let schema = writer
        .add_schema("sensor_msgs/Imu", "ros1msg", b"")
        .unwrap();
    let channel = writer
        .add_channel(schema, "/imu", "ros1", &Default::default())
        .unwrap();
    for (i, s) in samples.iter().enumerate() {
        let imu = encode::Imu {
            seq: i as u32,
            stamp_ns: s.stamp_ns,
            frame_id: "imu",
            gyro: s.gyro,
            accel: s.accel,
        };
        let header = ::mcap::records::MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time: s.received_ns as u64,
            publish_time: s.received_ns as u64,
        };
        writer
            .write_to_known_channel(&header, &encode::ros1(&imu))
            .unwrap();
    }
    writer.finish().unwrap();
    let loaded = load(&path, &LoadOptions::default()).unwrap();
    assert_eq!(loaded.record.len(), 1_000);
    assert_eq!(loaded.record.channels[2].values[500], samples[500].gyro[2]);
    assert_eq!(loaded.report.bag.unwrap().message_type, "sensor_msgs/Imu");
}

/// Damaged bags give an error naming the file and the fault, never a panic.
#[test]
fn malformed_bags_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let samples = record(2_000, 0, 7);
    let cases: [(Container, &str, &str); 3] = [
        (
            Container::Ros1(Ros1Compression::Lz4),
            "cut.bag",
            "ROS 1 bag, record at byte",
        ),
        (Container::Mcap, "cut.mcap", "MCAP"),
        (Container::Db3, "cut", "rosbag2 SQLite3"),
    ];
    for (container, name, says) in cases {
        let path = bag(dir.path(), container, name, &[("/imu", &samples)]);
        let file = super::storage_file(&path).unwrap();
        let bytes = std::fs::read(&file).unwrap();
        for cut in [bytes.len() / 2, 100, 20] {
            std::fs::write(&file, &bytes[..cut]).unwrap();
            let err = load(&path, &LoadOptions::default())
                .unwrap_err()
                .to_string();
            assert!(err.starts_with(&file.display().to_string()), "{err}");
            assert!(
                err.contains(says) || err.contains("no sensor_msgs/Imu"),
                "{name} cut at {cut}: {err}"
            );
        }
    }
    // A message too short for an Imu, in an otherwise sound bag.
    let path = dir.path().join("short.bag");
    let mut writer = write::create(Container::Ros1(Ros1Compression::None), &path).unwrap();
    let key = writer.topic("/imu").unwrap();
    writer.write(key, &samples[0]).unwrap();
    writer.finish().unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.windows(8).position(|w| w == b"imu_link").unwrap();
    bytes[at - 4] = 200;
    std::fs::write(&path, &bytes).unwrap();
    let err = load(&path, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("/imu message 1: ROS 1 message ends at byte"),
        "{err}"
    );
    let split = dir.path().join("split");
    std::fs::create_dir(&split).unwrap();
    let err = load(&split, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no rosbag2 storage file (.mcap or .db3)"),
        "{err}"
    );
    for name in ["b_1.db3", "b_0.db3"] {
        std::fs::write(split.join(name), b"").unwrap();
    }
    let err = load(&split, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("split into 2 storage files (b_0.db3, b_1.db3)"),
        "{err}"
    );
}

#[test]
fn topic_on_a_table_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("a.csv");
    std::fs::write(&csv, "t,gx\n0,1\n0.01,2\n").unwrap();
    let err = load(&csv, &topic("/imu")).unwrap_err().to_string();
    assert!(err.contains("--topic /imu: not a ROS bag"), "{err}");
}

//! ROS bags through the `imunoise` binary: `import` with and without `--topic`, the stored
//! session analysed and exported again, `analyze` on a bag directly, `--kalibr` from a bag;
//! the same record imported from each container to sessions with the same samples and N.

mod common;

use common::{TempStore, json, stderr, stdout};
use imunoise::input::rosbag::write::{self, Container, ImuSample, Ros1Compression};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// `n` messages at 100 Hz, stamped exactly; the values a ramp, to compare.
fn samples(n: usize, offset: f64) -> Vec<ImuSample> {
    (0..n)
        .map(|i| {
            let stamp = 1_600_000_000_000_000_000 + i as i64 * 10_000_000;
            let v = offset + (i % 7) as f64 * 1e-3;
            ImuSample {
                stamp_ns: stamp,
                received_ns: stamp + 2_000_000,
                gyro: [v, -v, 2.0 * v],
                accel: [v, v, 9.81 + v],
            }
        })
        .collect()
}

#[test]
fn a_bag_imports_to_a_session_that_reads_the_same_topic_again() {
    let store = TempStore::new();
    let bag = store.file("two.mcap");
    let a = samples(3_000, 0.0);
    let b = samples(1_500, 0.5);
    write::write(Container::Mcap, &bag, &[("/imu/a", &a), ("/imu/b", &b)]).unwrap();
    let bag_arg = bag.to_str().unwrap();

    let out = store.run(&["import", bag_arg]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("2 IMU topics: /imu/a (sensor_msgs/msg/Imu, 3000 messages), /imu/b (sensor_msgs/msg/Imu, 1500 messages); choose one with --topic"),
        "{e}"
    );

    let out = store.ok(&["import", bag_arg, "--topic", "/imu/b", "--name", "bag-b"]);
    let text = stdout(&out);
    assert!(text.contains("1500 samples at 100 Hz"), "{text}");
    assert!(stderr(&out).contains("MCAP: topic /imu/b (sensor_msgs/msg/Imu), 1500 messages"));

    // Read again from the store: the topic kept with the session.
    let csv = stdout(&store.ok(&["export", "bag-b"]));
    assert_eq!(csv.lines().count(), 1501);
    let doc = json(&store.ok(&["analyze", "bag-b", "--json", "-"]));
    assert_eq!(doc["input"]["bag"]["topic"], "/imu/b");
    assert_eq!(doc["rate_hz"], 100.0);
    assert_eq!(doc["channels"].as_array().unwrap().len(), 6);
}

#[test]
fn analyze_reads_a_rosbag2_directory_and_writes_kalibr_yaml() {
    let store = TempStore::new();
    let dir = store.file("rosbag2_imu");
    write::write(Container::Db3, &dir, &[("/imu/data", &samples(4_000, 0.0))]).unwrap();
    let yaml = store.file("imu.yaml");
    let out = store.ok(&[
        "analyze",
        dir.to_str().unwrap(),
        "--kalibr",
        yaml.to_str().unwrap(),
    ]);
    let text = stdout(&out);
    assert!(
        text.contains("rosbag2 SQLite3: topic /imu/data (sensor_msgs/msg/Imu), 4000 messages, times from header.stamp"),
        "{text}"
    );
    let written = std::fs::read_to_string(&yaml).unwrap();
    assert!(written.contains("gyroscope_noise_density"), "{written}");
    assert!(written.contains("update_rate: 100"), "{written}");
}

/// White-noise densities of the record below: gyro rad/s/sqrt(Hz), accel m/s^2/sqrt(Hz).
const GYRO_N: f64 = 2e-4;
const ACCEL_N: f64 = 2e-3;

/// Two minutes at 200 Hz of white noise of known density (standard deviation N sqrt(rate)).
fn white_record() -> Vec<ImuSample> {
    let rate: f64 = 200.0;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut white = |n: f64| n * rate.sqrt() * rng.sample::<f64, _>(StandardNormal);
    (0..24_000)
        .map(|i| {
            let stamp = 1_700_000_000_000_000_000 + i as i64 * 5_000_000;
            ImuSample {
                stamp_ns: stamp,
                received_ns: stamp + 1_000_000,
                gyro: [white(GYRO_N), white(GYRO_N), white(GYRO_N)],
                accel: [white(ACCEL_N), white(ACCEL_N), 9.81 + white(ACCEL_N)],
            }
        })
        .collect()
}

/// The same 200 Hz record as a ROS 1 bag, an MCAP file and a rosbag2 SQLite3 directory,
/// imported: every sample, the rate within 0.1 % (exact stamps give it to rounding), and N of
/// gx and ax from the session's analysis within three of its 68 % half-widths of the truth
/// (the interval spans about one standard error either side).
#[test]
fn the_same_record_imports_alike_from_ros1_mcap_and_sqlite3() {
    let store = TempStore::new();
    let samples = white_record();
    let containers = [
        (Container::Ros1(Ros1Compression::Bz2), "imu.bag", "ros1"),
        (Container::Mcap, "imu.mcap", "mcap"),
        (Container::Db3, "rosbag2_imu", "sqlite3"),
    ];
    for (container, file, name) in containers {
        let path = store.file(file);
        write::write(container, &path, &[("/imu/data", &samples)]).unwrap();
        store.ok(&["import", path.to_str().unwrap(), "--name", name]);
        let shown = json(&store.ok(&["show", name, "--json"]));
        assert_eq!(
            shown["session"]["counts"]["samples_received"], 24_000,
            "{name}"
        );
        let rate = shown["session"]["rate_hz"].as_f64().unwrap();
        assert!((rate / 200.0 - 1.0).abs() < 1e-3, "{name}: {rate}");
        let doc = json(&store.ok(&[
            "analyze", name, "--json", "-", "--column", "gx", "--column", "ax",
        ]));
        for (channel, truth) in doc["channels"]
            .as_array()
            .unwrap()
            .iter()
            .zip([GYRO_N, ACCEL_N])
        {
            let n = &channel["noise"]["N"];
            let (value, lo, hi) = (
                n["value"].as_f64().unwrap(),
                n["lo"].as_f64().unwrap(),
                n["hi"].as_f64().unwrap(),
            );
            assert!(
                (value - truth).abs() < 1.5 * (hi - lo),
                "{name} {}: N {value} [{lo}, {hi}] vs {truth}",
                channel["name"]
            );
        }
    }
}

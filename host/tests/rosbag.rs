//! ROS bags through the `imunoise` binary: `import` with and without `--topic`, the stored
//! session analysed and exported again, `analyze` on a bag directly, `--kalibr` from a bag.

mod common;

use common::{TempStore, json, stderr, stdout};
use imunoise::input::rosbag::write::{self, Container, ImuSample};

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

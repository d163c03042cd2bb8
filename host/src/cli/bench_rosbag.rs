//! `imunoise bench`, section 7: a generated ROS 1 bag of `sensor_msgs/Imu` at 200 Hz imported
//! and analysed by the `imunoise` binary (two child processes, timed from outside), beside
//! the time allan_variance_ros is reported to need for an 8-hour bag.

use anyhow::{Context, Result, bail};
use imunoise::input::rosbag::write::{self, Container, ImuSample, Ros1Compression};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

const RATE_HZ: f64 = 200.0;

/// allan_variance_ros on an 8-hour bag: 215 s on a Ryzen 9 3950X (16 cores), a Release build
/// (ori-drs/allan_variance_ros issue #15, comment of 2022-08-30).
const ALLAN_VARIANCE_ROS_S: f64 = 215.0;

/// Section 7: write the bag into a temporary directory, import it into a store there, analyse
/// the session; print the times and their ratio to allan_variance_ros's.
pub fn run(hours: f64) -> Result<()> {
    let n = (hours * 3600.0 * RATE_HZ).round() as usize;
    if n < 1000 {
        bail!("--bag-hours {hours}: too short");
    }
    println!(
        "\n7. ROS bag: {hours} h of sensor_msgs/Imu at {RATE_HZ} Hz ({n} messages) in a ROS 1 bag, imported and analysed"
    );
    let dir = std::env::temp_dir().join(format!("imunoise-bench-bag-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let result = measure(&dir, n, hours);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn measure(dir: &Path, n: usize, hours: f64) -> Result<()> {
    let bag = dir.join("imu.bag");
    let start = Instant::now();
    generate(&bag, n)?;
    let size = std::fs::metadata(&bag)?.len() as f64;
    println!(
        "   written:  {:>8.3} s ({:.0} MB, uncompressed chunks)",
        start.elapsed().as_secs_f64(),
        size / 1e6
    );
    let store = dir.join("store");
    let import = timed(&store, &["import", &bag.to_string_lossy(), "--name", "bag"])?;
    println!("   import:   {import:>8.3} s (read, timing judged, copied into the store)");
    let json = dir.join("analysis.json");
    let analyze = timed(
        &store,
        &["analyze", "bag", "--json", &json.to_string_lossy()],
    )?;
    println!(
        "   analyze:  {analyze:>8.3} s (the session read again; six channels: line search, oadev with CIs, PSD, fit)"
    );
    let total = import + analyze;
    let scaled = ALLAN_VARIANCE_ROS_S * hours / 8.0;
    println!(
        "   total:    {total:>8.3} s on {} threads; allan_variance_ros: {ALLAN_VARIANCE_ROS_S} s for an 8 h bag on 16 cores \
         (its issue #15{}): {:.0} x faster",
        rayon::current_num_threads(),
        if hours == 8.0 {
            String::new()
        } else {
            format!("; {scaled:.0} s scaled to {hours} h")
        },
        scaled / total
    );
    Ok(())
}

/// `n` messages of white noise (gyro 1e-3 rad/s, accel 1e-2 m/s^2 per sample), stamped every
/// 5 ms and received 1 ms later.
fn generate(path: &Path, n: usize) -> Result<()> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut writer = write::create(Container::Ros1(Ros1Compression::None), path)?;
    let topic = writer.topic("/imu/data")?;
    let period_ns = (1e9 / RATE_HZ) as i64;
    let mut white = |sd: f64| sd * rng.sample::<f64, _>(StandardNormal);
    for i in 0..n as i64 {
        let stamp = 1_700_000_000_000_000_000 + i * period_ns;
        let sample = ImuSample {
            stamp_ns: stamp,
            received_ns: stamp + 1_000_000,
            gyro: [white(1e-3), white(1e-3), white(1e-3)],
            accel: [white(1e-2), white(1e-2), 9.81 + white(1e-2)],
        };
        writer.write(topic, &sample)?;
    }
    writer.finish()?;
    Ok(())
}

/// Seconds `imunoise --store STORE ARGS` takes; an error with its stderr if it fails.
fn timed(store: &Path, args: &[&str]) -> Result<f64> {
    let exe = std::env::current_exe().context("finding the imunoise executable")?;
    let start = Instant::now();
    let out = Command::new(exe)
        .arg("--store")
        .arg(store)
        .args(args)
        .stdout(std::process::Stdio::null())
        .output()
        .with_context(|| format!("running imunoise {}", args[0]))?;
    let seconds = start.elapsed().as_secs_f64();
    if !out.status.success() {
        bail!(
            "imunoise {} failed: {}",
            args[0],
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(seconds)
}

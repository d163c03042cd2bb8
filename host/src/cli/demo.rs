//! `imunoise demo`: the whole chain with no hardware — the four sensor settings of the
//! MPU-6050 settings study this project follows (docs/signal_chain.md, Sources); a stream of
//! sample batches framed exactly as the board frames them, damaged on the way, decoded and
//! accounted for to the last sample; and the study's experiment on the virtual board
//! (capture at each setting, stored sessions, the sweep table, the study's Table 2 beside
//! the folding prediction, an HTML report).

use crate::cli::simulate::parse_duration;
use crate::cli::stored::open_store;
use crate::cli::sweep::run_sweep;
use anyhow::{Context, Result};
use imunoise::analysis::units::arw_to_deg_per_sqrt_h;
use imunoise::experiment::sweep;
use imunoise::link::PortSpec;
use imunoise::link::accounting::SampleAccounting;
use imunoise::link::replay::Speed;
use imunoise::report::sig;
use imunoise::sim::model_file;
use imunoise::store::Store;
use imunoise::store::clock::compact;
use protocol::frame::{self, FrameDecoder, MAX_WIRE_LEN};
use protocol::mpu6050::SensorSettings;
use protocol::{DeviceMessage, MAX_SAMPLES_PER_BATCH, RawSample, SampleBatch};
use std::time::SystemTime;

#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Seconds of generated samples to frame
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Simulated static data per setting for the settings study's experiment (long enough to see
    /// bias instability and rate random walk)
    #[arg(long, default_value = "2h")]
    pub duration: String,
}

pub fn run(args: &DemoArgs, store: Option<&std::path::Path>) -> Result<()> {
    println!(
        "imunoise demo: the settings study's experiment on the simulated MPU-6050, and the protocol layer\n"
    );
    println!("1. The settings study's four sensor settings on the MPU-6050:");
    for (rate, bandwidth, _) in sweep::PAPER_TABLE_2 {
        let s = SensorSettings::for_rate_and_bandwidth(rate, bandwidth)
            .map_err(|e| anyhow::anyhow!("{rate} Hz / {bandwidth} Hz: {e}"))?;
        println!(
            "   {rate:>5} Hz, {bandwidth:>3} Hz bandwidth -> DLPF_CFG {}, SMPLRT_DIV {:>3}{}",
            s.dlpf.bits(),
            s.smplrt_div,
            if s.aliases() {
                "   (bandwidth > rate/2: noise folds back)"
            } else {
                ""
            }
        );
    }

    let settings =
        SensorSettings::for_rate_and_bandwidth(200.0, 42.0).map_err(|e| anyhow::anyhow!("{e}"))?;
    let samples = (args.seconds * settings.output_rate_hz()).round();
    anyhow::ensure!(
        (1.0..=1e8).contains(&samples),
        "--seconds {}: between one sample and 1e8 samples, please",
        args.seconds
    );
    let samples = samples as u64;
    let batches = generate_batches(samples, settings.sample_interval_s());
    let mut wire = Vec::new();
    let mut frame_starts = Vec::new();
    let mut buf = [0u8; MAX_WIRE_LEN];
    for batch in &batches {
        let n = frame::encode(&DeviceMessage::Samples(batch.clone()), &mut buf)
            .context("encoding a sample batch")?;
        frame_starts.push(wire.len());
        wire.extend_from_slice(&buf[..n]);
    }
    let clean_len = wire.len();

    // Damage the line as a real one can be damaged: a flipped bit, a frame cut short (board
    // reset mid-frame), a burst of noise.
    let damage = damage_stream(&mut wire, &frame_starts);

    let mut decoder = FrameDecoder::new();
    let mut accounting = SampleAccounting::new();
    for chunk in wire.chunks(64) {
        decoder.feed::<DeviceMessage>(chunk, |message| {
            if let Ok(DeviceMessage::Samples(batch)) = message {
                // Out-of-order batches cannot occur in this stream; accounting counts them.
                let _ = accounting.batch(batch.first_index, batch.samples.len());
            }
        });
    }
    accounting.close(samples);
    let stats = decoder.stats();

    println!(
        "\n2. {samples} samples ({} s at {} Hz) in {} batches of up to {MAX_SAMPLES_PER_BATCH}, framed as the board frames them:",
        args.seconds,
        settings.output_rate_hz(),
        batches.len()
    );
    println!(
        "   {clean_len} bytes on the wire, {:.2} bytes per sample (14 in the sensor's FIFO)",
        clean_len as f64 / samples as f64
    );
    println!("   damage injected: {damage}");
    println!(
        "   frames decoded: {}; rejected: {} (CRC {}, COBS {}, too short {}, over-long {}, malformed {}; {} bytes discarded)",
        stats.frames_ok,
        stats.rejected(),
        stats.crc_errors,
        stats.cobs_errors,
        stats.too_short,
        stats.overlong,
        stats.malformed,
        stats.bytes_discarded
    );
    println!(
        "   samples: {} numbered by the board, {} received, {} lost in {} gaps {:?}",
        accounting.expected(),
        accounting.received(),
        accounting.lost(),
        accounting.gaps().len(),
        accounting.gaps()
    );
    paper_experiment(&args.duration, &open_store(store)?)
}

/// The settings study's experiment on the virtual board: each setting captured (the
/// firmware's own code on the simulated MPU-6050, at maximum speed), stored as a session,
/// analysed; the sweep table with the study's Table 2 beside the gyro's N and the folding
/// prediction, and an HTML report.
fn paper_experiment(duration: &str, store: &Store) -> Result<()> {
    let seconds = parse_duration(duration).map_err(|e| anyhow::anyhow!("--duration: {e}"))?;
    let model = model_file::example();
    let n0 = model.gyro.noise.n;
    println!(
        "\n3. The settings study's experiment on the virtual board: {duration} of static data per setting \
         (the firmware's code on the\n   simulated MPU-6050 of examples/mpu6050.toml, gyro N0 = {} \
         deg/sqrt(h)), captured into the store {}",
        sig(arw_to_deg_per_sqrt_h(n0), 3),
        store.dir().display()
    );
    let settings: Vec<SensorSettings> = sweep::PAPER_TABLE_2
        .iter()
        .map(|&(rate, bw, _)| SensorSettings::for_rate_and_bandwidth(rate, bw))
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let spec = PortSpec {
        board: imunoise::link::setup::SimulatedBoard::Mpu6050,
        port: "sim",
        speed: Speed::Max,
        model: None,
        seed: 1,
    };
    let rows = run_sweep(store, &spec, &settings, (seconds, None), "demo")?;
    print!("{}", sweep::table(&rows));
    let reports = store.dir().join("reports");
    std::fs::create_dir_all(&reports).with_context(|| format!("creating {}", reports.display()))?;
    let path = reports.join(format!("demo-{}.html", compact(SystemTime::now())));
    std::fs::write(&path, sweep::html(&rows, "imunoise demo")?)
        .with_context(|| format!("writing {}", path.display()))?;
    println!("\nreport: {}", path.display());
    println!(
        "sessions: `imunoise sessions`, `imunoise show demo-200hz-42hz`, `imunoise analyze demo-50hz-256hz --plot a.svg`"
    );
    Ok(())
}

/// Batches of generated raw samples: a level sensor (1 g on Z at +/-2 g, 25 degC) with a
/// few counts of noise from a fixed-seed xorshift generator.
fn generate_batches(samples: u64, interval_s: f64) -> Vec<SampleBatch> {
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 9) as i16 - 4
    };
    let mut batches = Vec::new();
    let mut index = 0;
    while index < samples {
        let len = (samples - index).min(MAX_SAMPLES_PER_BATCH as u64);
        let mut batch = SampleBatch {
            first_index: index,
            first_timestamp_us: (index as f64 * interval_s * 1e6) as u64,
            samples: heapless::Vec::new(),
        };
        for _ in 0..len {
            let sample = RawSample {
                accel: [noise(), noise(), 16384 + noise()],
                temp: -3740 + noise(),
                gyro: [noise(), noise(), noise()],
            };
            // Cannot fail: len <= MAX_SAMPLES_PER_BATCH.
            let _ = batch.samples.push(sample);
        }
        batches.push(batch);
        index += len;
    }
    batches
}

/// Flip a bit in one frame, cut another short, and put noise between two others; returns a
/// description. Frames are chosen at fixed fractions of the stream.
fn damage_stream(wire: &mut Vec<u8>, frame_starts: &[usize]) -> String {
    let n = frame_starts.len();
    if n < 8 {
        return "none (fewer than 8 frames)".into();
    }
    // Work from the end so earlier offsets stay valid.
    let garbage_at = frame_starts[3 * n / 4];
    let garbage: Vec<u8> = (0..37u8)
        .map(|i| i.wrapping_mul(97).wrapping_add(1))
        .collect();
    wire.splice(garbage_at..garbage_at, garbage.iter().copied());
    let cut = frame_starts[n / 2];
    let cut_len = (frame_starts[n / 2 + 1] - cut) / 2;
    wire.drain(cut + cut_len..frame_starts[n / 2 + 1]);
    wire[frame_starts[n / 4] + 5] ^= 0x10;
    format!(
        "1 bit flipped in frame {}, frame {} cut to half its length, {} bytes of noise before frame {}",
        n / 4,
        n / 2,
        garbage.len(),
        3 * n / 4
    )
}

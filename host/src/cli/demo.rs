//! `imunoise demo`: a tour of what works today, on generated data — the sensor settings of
//! the paper this project follows, and a stream of sample batches framed exactly as the
//! board frames them, damaged on the way, decoded and accounted for to the last sample.

use crate::analysis::pipeline::{self, Options};
use crate::analysis::units::arw_to_deg_per_sqrt_h;
use crate::cli::settings::aliases;
use crate::link::accounting::SampleAccounting;
use crate::record::{Channel, Quantity, Record};
use crate::report::sig;
use crate::sim::chain::white_noise_inflation;
use crate::sim::dlpf::{DlpfDesign, Sensor};
use crate::sim::imu::{Imu, ImuModel};
use crate::sim::model_file;
use anyhow::{Context, Result};
use protocol::frame::{self, FrameDecoder, MAX_WIRE_LEN};
use protocol::mpu6050::SensorSettings;
use protocol::{DeviceMessage, MAX_SAMPLES_PER_BATCH, RawSample, SampleBatch};

#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Seconds of generated samples to frame
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Minutes of simulated static data per setting for the paper's experiment
    #[arg(long, default_value_t = 10.0)]
    pub minutes: f64,
}

/// The four settings compared in the paper: (output rate Hz, gyro bandwidth Hz).
pub const PAPER_SETTINGS: [(f64, f64); 4] =
    [(200.0, 256.0), (200.0, 42.0), (50.0, 256.0), (50.0, 42.0)];

pub fn run(args: &DemoArgs) -> Result<()> {
    println!(
        "imunoise demo: the paper's experiment on the simulated MPU-6050, and the protocol layer\n(the virtual board that ties them together comes next)\n"
    );
    println!("1. The paper's four sensor settings on the MPU-6050:");
    for (rate, bandwidth) in PAPER_SETTINGS {
        let s = SensorSettings::for_rate_and_bandwidth(rate, bandwidth)
            .map_err(|e| anyhow::anyhow!("{rate} Hz / {bandwidth} Hz: {e}"))?;
        println!(
            "   {rate:>5} Hz, {bandwidth:>3} Hz bandwidth -> DLPF_CFG {}, SMPLRT_DIV {:>3}{}",
            s.dlpf.bits(),
            s.smplrt_div,
            if aliases(&s) {
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
    paper_experiment(args.minutes)
}

/// The paper's experiment: static data at its four settings through the simulated chip's
/// signal chain, analysed; the gyro's white-noise coefficient next to the model's and to
/// what the chain predicts (noise above half the output rate folds back).
fn paper_experiment(minutes: f64) -> Result<()> {
    anyhow::ensure!(
        (0.5..=600.0).contains(&minutes),
        "--minutes {minutes}: between 0.5 and 600, please"
    );
    let model = model_file::example();
    let n0 = model.gyro.noise.n;
    println!(
        "\n3. The paper's experiment, simulated: {minutes} min of static data per setting from \
         examples/mpu6050.toml\n   (gyro N0 = {} deg/sqrt(h)), through the MPU-6050's DLPF, \
         decimation without anti-aliasing and LSB rounding,\n   then analysed (IEEE-952 fit to \
         the overlapping Allan variance, 68.3 % intervals):",
        sig(arw_to_deg_per_sqrt_h(n0), 3)
    );
    println!(
        "   {:>14}  {:>26}  {:>8}  {:>9}",
        "setting", "gyro N, mean of x y z", "N / N0", "predicted"
    );
    for (i, (rate, bandwidth)) in PAPER_SETTINGS.into_iter().enumerate() {
        let settings = SensorSettings::for_rate_and_bandwidth(rate, bandwidth)
            .map_err(|e| anyhow::anyhow!("{rate} Hz / {bandwidth} Hz: {e}"))?;
        let seconds = minutes * 60.0;
        let record = simulate(&model, settings, seconds, i as u64 + 1);
        let results = pipeline::analyze(&record, &Options::default(), &|| {})?;
        let gyro: Vec<_> = results
            .iter()
            .filter(|r| r.quantity == Quantity::AngularRate)
            .filter_map(|r| r.fit.as_ref().ok())
            .collect();
        let mean = |f: &dyn Fn(&crate::analysis::fit::NoiseFit) -> f64| {
            gyro.iter().map(|g| f(g)).sum::<f64>() / gyro.len().max(1) as f64
        };
        let (n, lo, hi) = (mean(&|g| g.n.value), mean(&|g| g.n.lo), mean(&|g| g.n.hi));
        let design = DlpfDesign::for_setting(settings.dlpf, Sensor::Gyro);
        let predicted = white_noise_inflation(&design, 1 + usize::from(settings.smplrt_div));
        println!(
            "   {rate:>5} Hz/{bandwidth:>3} Hz  {:>7} [{} .. {}] deg/sqrt(h)  {:>8.3}  {:>9.3}{}",
            sig(arw_to_deg_per_sqrt_h(n), 3),
            sig(arw_to_deg_per_sqrt_h(lo), 3),
            sig(arw_to_deg_per_sqrt_h(hi), 3),
            n / n0,
            predicted,
            if aliases(&settings) {
                "  folds back"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// `seconds` of the model at `settings`, as a record in SI units.
fn simulate(model: &ImuModel, settings: SensorSettings, seconds: f64, seed: u64) -> Record {
    let mut imu = Imu::new(model, settings, seed, seconds);
    let rows = (seconds * settings.output_rate_hz()).floor() as usize;
    let mut columns: [Vec<f64>; 7] = std::array::from_fn(|_| Vec::with_capacity(rows));
    for _ in 0..rows {
        let s = imu.next_si();
        let values = [
            s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.temp,
        ];
        for (column, v) in columns.iter_mut().zip(values) {
            column.push(v);
        }
    }
    let names = ["gx", "gy", "gz", "ax", "ay", "az", "temp"];
    Record {
        source: format!("simulated {settings}"),
        rate_hz: settings.output_rate_hz(),
        channels: names
            .iter()
            .zip(columns)
            .map(|(name, values)| Channel::named(*name, values))
            .collect(),
    }
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

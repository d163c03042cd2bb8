//! `imunoise simulate`: a simulated MPU-6050 (or the GY-85's ITG-3200 and ADXL345) at rest,
//! through the chips' signal chains (DLPF, decimation without anti-aliasing, LSB
//! quantization), written as CSV in SI units.

use crate::cli::settings::{accel_range, gyro_range};
use anyhow::{Context, Result, bail};
use imunoise::capture::CaptureWriter;
use imunoise::link::plan::Request;
use imunoise::link::setup::SIMULATED_BOARD_ID;
use imunoise::sim::imu::{Imu, SiSample};
use imunoise::sim::{gy85, model_file};
use indicatif::ProgressBar;
use protocol::mpu6050::{GyroRange, SensorSettings};
use protocol::{
    DeviceInfo, DeviceMessage, MAX_SAMPLES_PER_BATCH, PROTOCOL_VERSION, SampleBatch, Status,
};
use std::io::{BufWriter, Write};
use std::path::PathBuf;

pub use imunoise::link::setup::SimulatedBoard as Board;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// The board: an MPU-6050, or a GY-85 whose gyro takes --rate and --bandwidth and whose
    /// accelerometer runs at the same rate
    #[arg(long, value_enum, default_value_t = Board::Mpu6050)]
    pub board: Board,
    /// The noise model (TOML; see examples/mpu6050.toml)
    #[arg(long)]
    pub model: PathBuf,
    /// Output sample rate in Hz (must be exactly internal rate / (1 + SMPLRT_DIV))
    #[arg(long, allow_negative_numbers = true)]
    pub rate: f64,
    /// DLPF bandwidth in Hz, gyro (256 188 98 42 20 10 5) or accel (260 184 94 44 21 10 5)
    #[arg(long)]
    pub bandwidth: f64,
    /// Length of the record: 2h, 30m, 90s, 1.5h (a bare number is seconds)
    #[arg(long)]
    pub duration: String,
    /// Random seed: the same seed and arguments give the same file
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file
    #[arg(long)]
    pub out: PathBuf,
    /// Output format: csv (time,gx,gy,gz,ax,ay,az,temp in s, rad/s, m/s^2, degC) or capture
    /// (the framed bytes a board would send: Info, sample batches, Status)
    #[arg(long, default_value = "csv")]
    pub format: String,
    /// Gyro full scale in deg/s: 250, 500, 1000 or 2000
    #[arg(long, default_value_t = 250)]
    pub gyro_range: u32,
    /// Accel full scale in g: 2, 4, 8 or 16
    #[arg(long, default_value_t = 2)]
    pub accel_range: u32,
}

/// "2h", "30m", "90s", "1.5h", "250ms" or a bare number of seconds, to seconds.
pub fn parse_duration(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, scale) = [("ms", 1e-3), ("h", 3600.0), ("m", 60.0), ("s", 1.0)]
        .iter()
        .find_map(|(suffix, scale)| t.strip_suffix(suffix).map(|n| (n, *scale)))
        .unwrap_or((t, 1.0));
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(format!(
            "duration '{text}' is not a positive number with an optional unit h, m, s or ms (e.g. 2h, 30m, 90s, 1.5h)"
        )),
    }
}

pub fn run(args: &SimulateArgs) -> Result<()> {
    let format = match args.format.as_str() {
        "csv" => Format::Csv,
        "capture" => Format::Capture,
        other => bail!("--format {other}: unknown format; available: csv, capture"),
    };
    let seconds = parse_duration(&args.duration).map_err(|e| anyhow::anyhow!("--duration: {e}"))?;
    if args.board == Board::Gy85 {
        return run_gy85(args, format, seconds);
    }
    let settings = SensorSettings::for_rate_and_bandwidth(args.rate, args.bandwidth)
        .map_err(|e| anyhow::anyhow!("--rate {} --bandwidth {}: {e}", args.rate, args.bandwidth))?
        .with_ranges(gyro_range(args.gyro_range)?, accel_range(args.accel_range)?);
    let model = model_file::load(&args.model)?;
    let rate = settings.output_rate_hz();
    // Rows = rate x duration, rounded down (with a little slack for decimal input).
    let rows = (rate * seconds + 1e-6).floor() as u64;
    let mut imu = Imu::new(&model, settings, args.seed, seconds);
    write_out(&args.out, rows, |w, bar| match format {
        Format::Csv => write_csv(w, || imu.next_si(), rows, bar),
        Format::Capture => write_capture(w, &mut imu, rows, args.seed, bar),
    })?;
    eprintln!(
        "wrote {rows} samples ({seconds} s at {} Hz, {settings}) to {}",
        protocol::mpu6050::Hz(rate),
        args.out.display()
    );
    Ok(())
}

/// Create `out`, write `rows` samples into it with `write` under a progress bar, flush.
fn write_out(
    out: &std::path::Path,
    rows: u64,
    write: impl FnOnce(&mut BufWriter<std::fs::File>, &ProgressBar) -> std::io::Result<()>,
) -> Result<()> {
    let file = std::fs::File::create(out)
        .with_context(|| format!("--out {}: cannot create", out.display()))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let bar = crate::cli::progress::bar(rows, "simulating");
    let write_err = || format!("--out {}: write failed", out.display());
    write(&mut w, &bar).with_context(write_err)?;
    w.flush().with_context(write_err)?;
    bar.finish_and_clear();
    Ok(())
}

/// `--board gy85`: the pair from its data-sheet settings, as CSV.
fn run_gy85(args: &SimulateArgs, format: Format, seconds: f64) -> Result<()> {
    if matches!(format, Format::Capture) {
        bail!(
            "--board gy85 --format capture: a GY-85 capture comes from the virtual board (`imunoise capture --port sim --board gy85`); use --format csv here"
        );
    }
    let context = || {
        format!(
            "--board gy85 --rate {} --bandwidth {}",
            args.rate, args.bandwidth
        )
    };
    let request = Request {
        rate_hz: args.rate,
        bandwidth_hz: args.bandwidth,
        gyro_range: GyroRange::Dps2000,
        accel_range: accel_range(args.accel_range)?,
    };
    let gyro = request.itg3200().with_context(context)?;
    let accel = request
        .adxl345(Some(gyro.output_rate_hz()))
        .with_context(context)?;
    let model = model_file::load(&args.model)?;
    let mut pair = gy85::Gy85::new(&model, &gyro, &accel, args.seed, seconds);
    let rows = (pair.output_rate_hz() * seconds + 1e-6).floor() as u64;
    write_out(&args.out, rows, |w, bar| {
        write_csv(w, || pair.next_si(), rows, bar)
    })?;
    eprintln!(
        "wrote {rows} samples ({seconds} s; {gyro}; {accel}) to {}",
        args.out.display()
    );
    Ok(())
}

enum Format {
    Csv,
    Capture,
}

/// `rows` samples from `next` as CSV in SI units.
fn write_csv(
    w: &mut impl Write,
    mut next: impl FnMut() -> SiSample,
    rows: u64,
    bar: &ProgressBar,
) -> std::io::Result<()> {
    writeln!(w, "time,gx,gy,gz,ax,ay,az,temp")?;
    for i in 0..rows {
        let s = next();
        writeln!(
            w,
            "{},{},{},{},{},{},{},{}",
            s.time, s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.temp
        )?;
        if i % 65_536 == 0 {
            bar.set_position(i);
        }
    }
    Ok(())
}

/// The bytes a board would send for this run (imunoise::capture): its Info with the settings,
/// the samples in full batches with their indices and timestamps, and a final Status.
fn write_capture(
    w: &mut impl Write,
    imu: &mut Imu,
    rows: u64,
    seed: u64,
    bar: &ProgressBar,
) -> std::io::Result<()> {
    let settings = *imu.settings();
    let period_us = 1e6 / imu.output_rate_hz();
    let mut out = CaptureWriter::new(w);
    out.message(&DeviceMessage::Info(DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: firmware::FIRMWARE_VERSION,
        // "SIM" and the seed: a simulated board is never mistaken for a real one.
        board_id: SIMULATED_BOARD_ID | seed,
        who_am_i: protocol::mpu6050::WHO_AM_I_VALUE,
        settings,
        streaming: true,
        max_samples_per_batch: MAX_SAMPLES_PER_BATCH as u16,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::mpu6050(
            protocol::mpu6050::DEFAULT_ADDRESS,
            protocol::mpu6050::WHO_AM_I_VALUE,
            settings,
        ),
    }))?;
    let mut index = 0u64;
    while index < rows {
        let len = (rows - index).min(MAX_SAMPLES_PER_BATCH as u64);
        let samples = (0..len).map(|_| imu.next_raw()).collect();
        out.message(&DeviceMessage::Samples(SampleBatch {
            first_index: index,
            first_timestamp_us: (index as f64 * period_us).round() as u64,
            samples,
        }))?;
        index += len;
        if index % (1 << 16) < len {
            bar.set_position(index);
        }
    }
    out.message(&DeviceMessage::Status(Status {
        streaming: false,
        uptime_us: (rows as f64 * period_us).round() as u64,
        samples_acquired: rows,
        ..Status::default()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(parse_duration("2h"), Ok(7200.0));
        assert_eq!(parse_duration("30m"), Ok(1800.0));
        assert_eq!(parse_duration("90s"), Ok(90.0));
        assert_eq!(parse_duration("1.5h"), Ok(5400.0));
        assert_eq!(parse_duration("250ms"), Ok(0.25));
        assert_eq!(parse_duration("12"), Ok(12.0));
        for bad in ["", "h", "-1s", "2d", "nan", "0"] {
            assert!(parse_duration(bad).is_err(), "{bad}");
        }
    }
}

//! `imunoise simulate`: a simulated MPU-6050 at rest, through the chip's signal chain
//! (DLPF, decimation without anti-aliasing, LSB quantization), written as CSV in SI units.

use crate::cli::settings::{accel_range, gyro_range};
use crate::report;
use crate::sim::{imu::Imu, model_file};
use anyhow::{Context, Result, bail};
use protocol::mpu6050::SensorSettings;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// The noise model (TOML; see examples/mpu6050.toml)
    #[arg(long)]
    pub model: PathBuf,
    /// Output sample rate in Hz (must be exactly internal rate / (1 + SMPLRT_DIV))
    #[arg(long)]
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
    /// Output format: csv (time,gx,gy,gz,ax,ay,az,temp in s, rad/s, m/s^2, degC); capture is not available yet
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
    match args.format.as_str() {
        "csv" => {}
        "capture" => bail!(
            "--format capture: the capture file format is not available yet (it comes with the session store); use --format csv"
        ),
        other => bail!("--format {other}: unknown format; available: csv"),
    }
    let seconds = parse_duration(&args.duration).map_err(|e| anyhow::anyhow!("--duration: {e}"))?;
    let settings = SensorSettings::for_rate_and_bandwidth(args.rate, args.bandwidth)
        .map_err(|e| anyhow::anyhow!("--rate {} --bandwidth {}: {e}", args.rate, args.bandwidth))?
        .with_ranges(gyro_range(args.gyro_range)?, accel_range(args.accel_range)?);
    let model = model_file::load(&args.model)?;
    let rate = settings.output_rate_hz();
    // Rows = rate x duration, rounded down (with a little slack for decimal input).
    let rows = (rate * seconds + 1e-6).floor() as u64;
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("--out {}: cannot create", args.out.display()))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let mut imu = Imu::new(&model, settings, args.seed, seconds);
    let bar = report::progress::bar(rows, "simulating");
    let write_err = || format!("--out {}: write failed", args.out.display());
    writeln!(w, "time,gx,gy,gz,ax,ay,az,temp").with_context(write_err)?;
    for i in 0..rows {
        let s = imu.next_si();
        writeln!(
            w,
            "{},{},{},{},{},{},{},{}",
            s.time, s.gyro[0], s.gyro[1], s.gyro[2], s.accel[0], s.accel[1], s.accel[2], s.temp
        )
        .with_context(write_err)?;
        if i % 65_536 == 0 {
            bar.set_position(i);
        }
    }
    w.flush().with_context(write_err)?;
    bar.finish_and_clear();
    eprintln!(
        "wrote {rows} samples ({seconds} s at {} Hz, {settings}) to {}",
        protocol::mpu6050::Hz(rate),
        args.out.display()
    );
    Ok(())
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

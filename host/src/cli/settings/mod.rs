//! `imunoise settings`: a sensor's settings table, or the exact register values for an output
//! rate (and a bandwidth), with the nearest valid choices when there are none. One module per
//! sensor; the register values go into JSON under `registers` by their datasheet names.

mod adxl345;
mod itg3200;
mod mpu6050;

pub use mpu6050::{accel_range, gyro_range};

use anyhow::{Result, bail};

/// The sensors whose settings models the protocol holds.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// InvenSense MPU-6050 (and the chips sold as it): gyro and accelerometer
    Mpu6050,
    /// InvenSense ITG-3200 / ITG-3205 gyro (GY-85 boards)
    Itg3200,
    /// Analog Devices ADXL345 accelerometer (GY-85 boards)
    Adxl345,
}

#[derive(clap::Args, Debug)]
pub struct SettingsArgs {
    /// Which sensor's settings
    #[arg(long, value_enum, default_value_t = Sensor::Mpu6050)]
    pub sensor: Sensor,
    /// Output sample rate in Hz (e.g. 200); resolves to register values (the MPU-6050 and the
    /// ITG-3200 also need --bandwidth)
    #[arg(long, allow_negative_numbers = true)]
    pub rate: Option<f64>,
    /// Filter bandwidth in Hz. MPU-6050: gyro (256 188 98 42 20 10 5) or accel (260 184 94
    /// 44 21 10 5); ITG-3200: the gyro ones; ADXL345: half the rate, checked
    #[arg(long, requires = "rate")]
    pub bandwidth: Option<f64>,
    /// MPU-6050 gyro full scale in deg/s: 250, 500, 1000 or 2000
    #[arg(long, default_value_t = 250)]
    pub gyro_range: u32,
    /// Accel full scale in g: 2, 4, 8 or 16 (MPU-6050 and ADXL345)
    #[arg(long, default_value_t = 2)]
    pub accel_range: u32,
    /// ADXL345 low-power mode (12.5 to 400 Hz, more noise)
    #[arg(long)]
    pub low_power: bool,
    /// Print JSON instead of a table
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &SettingsArgs) -> Result<()> {
    if args.low_power && args.sensor != Sensor::Adxl345 {
        bail!("--low-power is an ADXL345 setting (--sensor adxl345)");
    }
    let text = match args.sensor {
        Sensor::Mpu6050 => mpu6050::run(args)?,
        Sensor::Itg3200 => itg3200::run(args)?,
        Sensor::Adxl345 => adxl345::run(args)?,
    };
    print!("{text}");
    Ok(())
}

/// The bandwidth a sensor with a DLPF table needs beside `--rate`.
fn required_bandwidth(args: &SettingsArgs, table: &str) -> Result<Option<(f64, f64)>> {
    match (args.rate, args.bandwidth) {
        (Some(rate), Some(bandwidth)) => Ok(Some((rate, bandwidth))),
        (Some(rate), None) => bail!(
            "--rate {rate} needs --bandwidth with --sensor {}: one of {table} Hz",
            clap::ValueEnum::to_possible_value(&args.sensor)
                .map(|v| v.get_name().to_string())
                .unwrap_or_default()
        ),
        _ => Ok(None),
    }
}

/// A JSON document as printed: pretty, with a final newline.
fn json_text(v: &serde_json::Value) -> String {
    format!("{v:#}\n")
}

/// Lines as printed, each with its newline.
fn lines(lines: Vec<String>) -> String {
    lines.into_iter().map(|l| l + "\n").collect()
}

/// The warning for a gyro bandwidth above half the output rate.
fn aliasing_note(aliases: bool, rate_hz: f64) -> Option<String> {
    aliases.then(|| {
        format!(
            "note: the gyro bandwidth exceeds half the output rate ({} Hz): noise above it folds back (aliasing), which inflates the angle random walk",
            rate_hz / 2.0
        )
    })
}

/// The output rates SMPLRT_DIV 255..0 give at an internal rate, Hz: (slowest, fastest).
fn rate_span(internal_hz: f64) -> (f64, f64) {
    (internal_hz / 256.0, internal_hz)
}

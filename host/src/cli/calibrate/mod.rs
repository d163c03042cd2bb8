//! `imunoise calibrate accel|gyro|temperature`: the deterministic calibration, from a board
//! (`--port PORT`, or `--port sim` turned by script) or from files and sessions; the result
//! is printed (table, `--json`) and stored for the board (`imunoise calibrations`).

mod accel;
mod bench;
mod gyro;
mod rate_table;
mod temperature;

use crate::cli::capture::VirtualBoardArgs;
use crate::cli::stored;
use anyhow::{Result, anyhow, bail};
use imunoise::calibration::{Calibration, Sensor, Vec3};
use imunoise::input::LoadOptions;
use imunoise::link::replay::Speed;
use imunoise::record::Record;
use imunoise::store::{Board, CalibrationSettings, Store};
use std::path::Path;

/// One degree in radians.
pub const DEG: f64 = std::f64::consts::PI / 180.0;
/// rad/s to deg/h.
pub const DEG_H: f64 = 3600.0 / DEG;

#[derive(clap::Args, Debug)]
pub struct CalibrateArgs {
    #[command(subcommand)]
    pub procedure: Procedure,
}

#[derive(clap::Subcommand, Debug)]
pub enum Procedure {
    /// Accelerometer: six static positions (each axis up, then down): the paper's up/down
    /// bias and scale factor, and the least-squares bias, scale factors and misalignment
    Accel(accel::AccelArgs),
    /// Gyroscope: static bias with its Allan uncertainty, or bias, scale factors and
    /// misalignment from a rate table (clockwise and anticlockwise about each axis)
    Gyro(gyro::GyroArgs),
    /// Bias against TEMP_OUT from a warm-up or cool-down record at rest
    Temperature(temperature::TemperatureArgs),
}

/// The board to drive and how; shared by the three procedures.
#[derive(clap::Args, Debug)]
pub struct BoardArgs {
    /// The board: a serial port (`imunoise ports`), or `sim` for the virtual board, which is
    /// turned by script
    #[arg(long)]
    pub port: Option<String>,
    /// Output rate in Hz
    #[arg(long, default_value_t = 100.0, allow_negative_numbers = true)]
    pub rate: f64,
    /// DLPF bandwidth in Hz
    #[arg(long, default_value_t = 42.0)]
    pub bandwidth: f64,
    /// Gyro full scale in deg/s: 250, 500, 1000 or 2000
    #[arg(long, default_value_t = 250)]
    pub gyro_range: u32,
    /// Accel full scale in g: 2, 4, 8 or 16
    #[arg(long, default_value_t = 2)]
    pub accel_range: u32,
    /// Speed of the virtual board: max, or a factor (1 = real time)
    #[arg(long, default_value = "max")]
    pub speed: Speed,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
}

/// What every procedure prints and stores.
#[derive(clap::Args, Debug)]
pub struct OutputArgs {
    /// The board id for a calibration made from files (a session carries its own), as
    /// `imunoise show` prints it
    #[arg(long)]
    pub board: Option<String>,
    /// Print the calibration as JSON
    #[arg(long)]
    pub json: bool,
    /// Compute and print, but do not store the calibration
    #[arg(long)]
    pub dry_run: bool,
}

pub fn run(args: &CalibrateArgs, store: Option<&Path>) -> Result<()> {
    match &args.procedure {
        Procedure::Accel(a) => accel::run(a, store),
        Procedure::Gyro(a) => gyro::run(a, store),
        Procedure::Temperature(a) => temperature::run(a, store),
    }
}

/// Where a calibration's data came from: the board (and its settings) and the sessions or
/// files, for the catalog.
#[derive(Default)]
pub struct Provenance {
    pub board: Option<Board>,
    pub sources: Vec<String>,
    pub rate_hz: f64,
}

impl Provenance {
    /// Read a file or stored session (`imunoise analyze`'s inputs) and note where it came
    /// from; the first session with a board gives the board.
    pub fn load(&mut self, input: &Path, store: Option<&Path>) -> Result<Record> {
        let stored::Input { loaded, session } =
            stored::load(input, &LoadOptions::default(), store)?;
        stored::print_notes(&loaded.notes);
        if let Some((_, s)) = &session {
            self.board = self.board.take().or_else(|| s.board.clone());
        }
        self.sources.push(input.display().to_string());
        self.rate_hz = loaded.record.rate_hz;
        Ok(loaded.record)
    }

    /// From a board's captures.
    pub fn of_bench(bench: &bench::Bench, rate_hz: f64) -> Provenance {
        Provenance {
            board: bench.board().cloned(),
            sources: bench.sessions().to_vec(),
            rate_hz,
        }
    }
}

/// Print the calibration (`text`, or the JSON document) and store it unless `--dry-run`.
pub fn finish(
    store: &Store,
    out: &OutputArgs,
    provenance: &Provenance,
    calibration: &Calibration,
    text: &str,
) -> Result<()> {
    let (board_id, settings) = match (&out.board, &provenance.board) {
        (Some(id), _) => (
            id.clone(),
            provenance.board.as_ref().map_or(
                CalibrationSettings::rate_only(provenance.rate_hz),
                CalibrationSettings::of,
            ),
        ),
        (None, Some(b)) => (b.board_id.clone(), CalibrationSettings::of(b)),
        (None, None) if out.dry_run => (
            String::new(),
            CalibrationSettings::rate_only(provenance.rate_hz),
        ),
        (None, None) => bail!(
            "the inputs are files without a board id: give --board ID (or --dry-run to only print)"
        ),
    };
    let id = if out.dry_run {
        None
    } else {
        Some(store.add_calibration(&board_id, &settings, &provenance.sources, calibration)?)
    };
    if out.json {
        let doc = serde_json::json!({
            "id": id,
            "board_id": board_id,
            "settings": settings,
            "sources": provenance.sources,
            "calibration": calibration,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{text}");
    }
    match id {
        Some(id) => eprintln!(
            "stored calibration {id} for board {board_id} ({settings}); `imunoise calibrations show {id}`"
        ),
        None => eprintln!("--dry-run: not stored"),
    }
    Ok(())
}

/// The mean of each of a sensor's three channels, naming a missing one.
pub fn means(record: &Record, sensor: Sensor) -> Result<Vec3> {
    let mean = |v: &[f64]| imunoise::analysis::neumaier_sum(v.iter().copied()) / v.len() as f64;
    Ok(columns(record, sensor)?.map(mean))
}

/// The mean TEMP_OUT, degC; NaN when the record has no `temp` channel.
pub fn mean_temperature(record: &Record) -> f64 {
    record.channel("temp").map_or(f64::NAN, |c| {
        c.values.iter().sum::<f64>() / c.values.len() as f64
    })
}

/// A sensor's channel values, naming a missing one.
pub fn columns<'a>(record: &'a Record, sensor: Sensor) -> Result<[&'a [f64]; 3]> {
    let get = |name: &str| -> Result<&'a [f64]> {
        record
            .channel(name)
            .map(|c| c.values.as_slice())
            .ok_or_else(|| {
                anyhow!(
                    "{}: no channel '{name}' (it has {})",
                    record.source,
                    record.names().join(", ")
                )
            })
    };
    let [x, y, z] = sensor.channels();
    Ok([get(x)?, get(y)?, get(z)?])
}

/// `--port` or the file inputs, exactly one of them.
pub fn board_or_files<'a>(
    port: &'a Option<String>,
    files: bool,
    what: &str,
) -> Result<Option<&'a str>> {
    match (port.as_deref(), files) {
        (Some(p), false) => Ok(Some(p)),
        (None, true) => Ok(None),
        (Some(_), true) => bail!("give either --port or {what}, not both"),
        (None, false) => bail!("give --port PORT (or sim) to drive a board, or {what}"),
    }
}

//! `imunoise calibrate temperature`: bias against TEMP_OUT from a warm-up or cool-down
//! record at rest ([`imunoise::calibration::temperature`]), for the gyro and the accelerometer.

use super::bench::Bench;
use super::{BoardArgs, OutputArgs, Provenance, board_or_files, columns, finish};
use crate::cli::calibrations::describe_calibration;
use crate::cli::stored::open_store;
use anyhow::{Context, Result, anyhow};
use imunoise::calibration::temperature::{BLOCK_S, QUADRATIC_P, fit};
use imunoise::calibration::{Calibration, Kind, Sensor};
use imunoise::record::Record;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct TemperatureArgs {
    #[command(flatten)]
    pub board: BoardArgs,
    /// Capture time, s: start right after power-on (a warm-up) or in a cooling room
    #[arg(long, default_value_t = 1800.0)]
    pub seconds: f64,
    /// The record from a file or stored session instead of a board
    #[arg(long, value_name = "INPUT")]
    pub from: Option<PathBuf>,
    #[command(flatten)]
    pub output: OutputArgs,
}

pub fn run(args: &TemperatureArgs, store: Option<&Path>) -> Result<()> {
    let port = board_or_files(&args.board.port, args.from.is_some(), "--from INPUT")?;
    let catalog = open_store(store)?;
    let mut provenance = Provenance::default();
    let record = match (port, &args.from) {
        (Some(port), _) => {
            let mut bench = Bench::open(port, &args.board)?;
            let record = bench.measure_at_rest(
                &catalog,
                args.seconds,
                "leave the board at rest while it warms up (start right after power-on)",
            )?;
            provenance = Provenance::of_bench(&bench, record.rate_hz);
            record
        }
        (None, Some(input)) => provenance.load(input, store)?,
        (None, None) => unreachable!("board_or_files requires one"),
    };
    let calibration = solve(&record)?;
    let text = format!(
        "bias against TEMP_OUT, {:.0} s record, block means of {BLOCK_S} s; quadratic only where the F-test gives p < {QUADRATIC_P}\n{}",
        record.duration_s(),
        describe_calibration(&calibration)
    );
    finish(&catalog, &args.output, &provenance, &calibration, &text)
}

fn solve(record: &Record) -> Result<Calibration> {
    let temp = record
        .channel("temp")
        .ok_or_else(|| anyhow!("{}: no temp channel (TEMP_OUT, degC)", record.source))?;
    let mut models = Vec::new();
    for sensor in [Sensor::Gyro, Sensor::Accel] {
        // A record with only one sensor's channels calibrates that one.
        let Ok(values) = columns(record, sensor) else {
            continue;
        };
        let model = fit(sensor, &temp.values, values, record.rate_hz)
            .with_context(|| record.source.clone())?;
        models.push(model);
    }
    if models.is_empty() {
        return Err(anyhow!(
            "{}: neither gx gy gz nor ax ay az: nothing to calibrate",
            record.source
        ));
    }
    Ok(Calibration {
        kind: Kind::Temperature,
        corrections: vec![],
        temperature: models,
        details: serde_json::json!({ "record_s": record.duration_s() }),
    })
}

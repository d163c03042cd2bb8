//! `imunoise calibrate gyro`: the static bias with its Allan uncertainty
//! ([`imunoise::calibration::static_bias`]), or a rate table ([`super::rate_table`]).

use super::bench::Bench;
use super::rate_table;
use super::{
    BoardArgs, DEG_H, OutputArgs, Provenance, board_or_files, columns, finish, mean_temperature,
};
use crate::cli::stored::open_store;
use anyhow::{Result, anyhow, bail};
use imunoise::calibration::static_bias::{StaticBias, static_bias};
use imunoise::calibration::{AXES, Calibration, Correction, Kind, Sensor};
use imunoise::record::Record;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct GyroArgs {
    #[command(flatten)]
    pub board: BoardArgs,
    /// Capture time, s: of the static record, or of each rate of a rate table
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Static bias from this file or stored session instead of a board
    #[arg(long, value_name = "INPUT", conflicts_with = "rate_table")]
    pub from: Option<PathBuf>,
    /// Rate table with the board: +RATE and -RATE deg/s about each axis in turn (the
    /// virtual board is spun by script; a person sets a real table)
    #[arg(long, value_name = "DEG_S", requires = "port")]
    pub table_rate: Option<f64>,
    /// Rate table from records: a text file of lines `AXIS RATE_DEG_S INPUT` (x|y|z, the
    /// commanded rate, signed by the right-hand rule, and a file or stored session)
    #[arg(long, value_name = "FILE")]
    pub rate_table: Option<PathBuf>,
    #[command(flatten)]
    pub output: OutputArgs,
}

pub fn run(args: &GyroArgs, store: Option<&Path>) -> Result<()> {
    let files = args.from.is_some() || args.rate_table.is_some();
    let port = board_or_files(&args.board.port, files, "--from INPUT or --rate-table FILE")?;
    let catalog = open_store(store)?;
    let mut provenance = Provenance::default();
    let (calibration, text) = match (port, args.table_rate) {
        (Some(port), None) => {
            let mut bench = Bench::open(port, &args.board)?;
            let record = bench.measure_at_rest(
                &catalog,
                args.seconds,
                "put the board at rest (any orientation)",
            )?;
            provenance = Provenance::of_bench(&bench, record.rate_hz);
            solve_static(&record)?
        }
        (Some(port), Some(rate)) => {
            let mut bench = Bench::open(port, &args.board)?;
            let spins = rate_table::spin_on_bench(&mut bench, &catalog, args.seconds, rate)?;
            provenance = Provenance::of_bench(&bench, spins[0].record.rate_hz);
            rate_table::solve_table(&spins)?
        }
        (None, _) => match (&args.from, &args.rate_table) {
            (Some(input), _) => solve_static(&provenance.load(input, store)?)?,
            (None, Some(table)) => {
                let spins = rate_table::read_table(table, &mut provenance, store)?;
                rate_table::solve_table(&spins)?
            }
            (None, None) => bail!("give --from INPUT or --rate-table FILE"),
        },
    };
    finish(&catalog, &args.output, &provenance, &calibration, &text)
}

fn solve_static(record: &Record) -> Result<(Calibration, String)> {
    let values = columns(record, Sensor::Gyro)?;
    let biases: Vec<StaticBias> = values
        .iter()
        .zip(Sensor::Gyro.channels())
        .map(|(v, name)| {
            static_bias(v, record.rate_hz)
                .ok_or_else(|| anyhow!("{}: {name} has under 16 samples", record.source))
        })
        .collect::<Result<_>>()?;
    let temperature_c = mean_temperature(record);
    let correction = Correction::bias_only(
        Sensor::Gyro,
        [0, 1, 2].map(|i| biases[i].bias),
        temperature_c,
    );
    let mut text = format!(
        "gyro static bias over {:.1} s at {temperature_c:.2} degC; uncertainty (1 sigma) = the Allan deviation at tau = the record length (IEEE-952 fit)\n",
        biases[0].record_s
    );
    for (axis, b) in AXES.iter().zip(&biases) {
        let _ = writeln!(
            text,
            "  {axis}: bias {:+.5e} rad/s ({:+.2} deg/h) +- {:.2e} rad/s ({:.3} deg/h); the Allan minimum {:.2e} rad/s ({:.3} deg/h) at tau {:.1} s",
            b.bias,
            b.bias * DEG_H,
            b.uncertainty,
            b.uncertainty * DEG_H,
            b.best_adev,
            b.best_adev * DEG_H,
            b.best_tau_s
        );
    }
    let calibration = Calibration {
        kind: Kind::Gyro,
        corrections: vec![correction],
        temperature: vec![],
        details: serde_json::json!({ "static_bias_rad_s": biases }),
    };
    Ok((calibration, text))
}

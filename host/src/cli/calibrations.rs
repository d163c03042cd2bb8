//! `imunoise calibrations [--board ID] [--json]` and `imunoise calibrations show ID`: the
//! stored calibrations; and [`apply_latest`], the `--calibrated` of `export` and `analyze`.

use crate::cli::stored::{print_listing, read_store};
use anyhow::{Result, anyhow};
use imunoise::calibration::apply::{self, LatestError};
use imunoise::calibration::{AXES, Calibration, Correction};
use imunoise::record::Record;
use imunoise::report;
use imunoise::store::{Session, Store, StoredCalibration};
use std::fmt::Write as _;
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct CalibrationsArgs {
    #[command(subcommand)]
    pub command: Option<CalibrationsCommand>,
    /// Only this board's (its id as `sessions`/`show` print it, e.g. 0x53494d0000000001)
    #[arg(long)]
    pub board: Option<String>,
    /// Print as JSON
    #[arg(long, global = true)]
    pub json: bool,
    /// `show`: print as YAML
    #[arg(long, global = true, conflicts_with = "json")]
    pub yaml: bool,
}

#[derive(clap::Subcommand, Debug)]
pub enum CalibrationsCommand {
    /// Everything about one calibration: bias, scale factors, misalignment, temperature model
    Show { id: i64 },
}

pub fn run(args: &CalibrationsArgs, store: Option<&Path>) -> Result<()> {
    let store = read_store(store)?;
    match &args.command {
        Some(CalibrationsCommand::Show { id }) => {
            let c = store
                .calibration(*id)?
                .ok_or_else(|| anyhow!("no calibration {id} in {}", store.dir().display()))?;
            if args.json {
                println!("{}", serde_json::to_string_pretty(&c)?);
            } else if args.yaml {
                let header = [
                    format!("imunoise calibration {} ({}), board {}", c.id, c.calibration.kind.name(), c.board_id),
                    "f_meas = matrix f_true + bias (+ temperature part); matrix = I + S + M (row: measured axis)".into(),
                    "units: gyro rad/s, accel m/s^2, temperatures degC, c1 u/degC, c2 u/degC^2".into(),
                ];
                print!(
                    "{}",
                    report::yaml::document(&header, &serde_json::to_value(&c)?)
                );
            } else {
                print!("{}", describe(&c));
            }
        }
        None => {
            let list = store.calibrations(args.board.as_deref())?;
            print_listing(&list, args.json, &store, "calibrations", table)?;
        }
    }
    Ok(())
}

fn table(list: &[StoredCalibration]) -> String {
    let header = [
        "id",
        "board",
        "created (UTC)",
        "kind",
        "settings",
        "sources",
    ];
    let rows: Vec<Vec<String>> = list
        .iter()
        .map(|c| {
            vec![
                c.id.to_string(),
                c.board_id.clone(),
                c.created_at
                    .get(..19)
                    .unwrap_or(&c.created_at)
                    .replace('T', " "),
                c.calibration.kind.name().to_string(),
                c.settings.to_string(),
                c.sources.join(" "),
            ]
        })
        .collect();
    imunoise::report::table::aligned(&header, &rows)
}

/// One calibration in words and numbers (units in every line).
pub fn describe(c: &StoredCalibration) -> String {
    let mut out = format!(
        "calibration {} ({}), board {}, {}\nsettings: {}\nsources: {}\n",
        c.id,
        c.calibration.kind.name(),
        c.board_id,
        c.created_at,
        c.settings,
        c.sources.join(", ")
    );
    out += &describe_calibration(&c.calibration);
    out
}

/// The applied part of a calibration: per sensor bias, scale factors, misalignment, and the
/// temperature models.
pub fn describe_calibration(cal: &Calibration) -> String {
    let mut out = String::new();
    for k in &cal.corrections {
        out += &describe_correction(k);
    }
    for t in &cal.temperature {
        let _ = writeln!(
            out,
            "{:?} bias against temperature (T_ref {:.2} degC, fitted over {:.2}..{:.2} degC, {} blocks of 1 s):",
            t.sensor, t.reference_c, t.min_c, t.max_c, t.blocks
        );
        let unit = t.sensor.unit();
        for (axis, a) in AXES.iter().zip(&t.axes) {
            let _ = writeln!(
                out,
                "  {axis}: {:+.4e} {unit}/degC{}  residual RMS {:.3e} {unit}  ({}, F {:.1}, p {:.2e})",
                a.c1,
                if a.quadratic {
                    format!(" {:+.3e} {unit}/degC^2", a.c2)
                } else {
                    String::new()
                },
                a.residual_rms,
                if a.quadratic { "quadratic" } else { "linear" },
                a.f_statistic,
                a.p_value
            );
        }
    }
    out
}

fn describe_correction(k: &Correction) -> String {
    let unit = k.sensor.unit();
    let mut out = format!(
        "{:?} (f_meas = (I + S + M) f_true + b, at {:.2} degC):\n",
        k.sensor, k.temperature_c
    );
    let _ = writeln!(
        out,
        "  bias b:           x {:+.5e}  y {:+.5e}  z {:+.5e} {unit}",
        k.bias[0], k.bias[1], k.bias[2]
    );
    let (Some(s), Some(m)) = (k.scale_factors(), k.misalignment()) else {
        out += "  scale factor and misalignment: not measured (bias only)\n";
        return out;
    };
    let _ = writeln!(
        out,
        "  scale factor S:   x {:+.1}  y {:+.1}  z {:+.1} ppm",
        s[0] * 1e6,
        s[1] * 1e6,
        s[2] * 1e6
    );
    let _ = writeln!(
        out,
        "  misalignment M (mrad; row = measured axis, column = true axis):"
    );
    for (axis, row) in AXES.iter().zip(m) {
        let _ = writeln!(
            out,
            "    {axis}: {:+8.3} {:+8.3} {:+8.3}",
            row[0] * 1e3,
            row[1] * 1e3,
            row[2] * 1e3
        );
    }
    out
}

/// `--calibrated`: correct a session's record in memory with the newest calibrations of its
/// board (the stored data are not touched); warns when they were made under other settings.
pub fn apply_latest(store: &Store, session: &Session, record: &mut Record) -> Result<()> {
    let (applied, warnings) = apply::latest(store, session).map_err(|e| match e {
        LatestError::Store(e) => anyhow::Error::from(e),
        e => anyhow!("--calibrated: {e}"),
    })?;
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
    for note in apply::apply(record, &applied).map_err(anyhow::Error::msg)? {
        eprintln!("note: {note}");
    }
    Ok(())
}

//! `imunoise export ID --format csv`: a session's samples in SI units as CSV, or with
//! `--units counts` a capture's raw sensor counts ([`imunoise::report::csv`]: gaps are
//! marked, never bridged), optionally corrected with the board's calibrations.

use crate::cli::calibrations::apply_latest;
use crate::cli::output;
use crate::cli::stored::{load_session, read_store};
use anyhow::{Context, Result, bail};
use imunoise::input::LoadOptions;
use imunoise::record::Record;
use imunoise::report::csv;
use imunoise::store::{Kind, Session};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// The session's id or name
    pub session: String,
    /// Output format (csv)
    #[arg(long, default_value = "csv")]
    pub format: String,
    /// Output file (default: stdout)
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Correct the samples with the board's newest calibrations (in memory; the stored data
    /// are not altered)
    #[arg(long)]
    pub calibrated: bool,
    /// Values in SI units (rad/s, m/s^2, degC) or the sensor's raw counts (captures only)
    #[arg(long, value_enum, default_value = "si")]
    pub units: Units,
}

/// What the exported values are.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    Si,
    Counts,
}

pub fn run(args: &ExportArgs, store: Option<&Path>) -> Result<()> {
    if args.format != "csv" {
        bail!("--format {}: unknown format; available: csv", args.format);
    }
    let store = read_store(store)?;
    let session = store.find(&args.session)?;
    if let Some(path) = &args.out {
        output::check(path, "--out", Some(store.dir()), &[&session.file])?;
    }
    let (out, what): (Box<dyn Write>, String) = match &args.out {
        Some(path) => (
            Box::new(
                std::fs::File::create(path)
                    .with_context(|| format!("--out {}: cannot create", path.display()))?,
            ),
            format!("--out {}", path.display()),
        ),
        None => (Box::new(std::io::stdout().lock()), "stdout".to_string()),
    };
    let mut out = BufWriter::with_capacity(1 << 20, out);
    let units = match args.units {
        Units::Si => csv::Units::Si,
        Units::Counts => csv::Units::Counts,
    };
    if args.calibrated && units == csv::Units::Counts {
        bail!(
            "--calibrated --units counts: raw counts are never corrected; export SI units to apply a calibration"
        );
    }
    let correct = |record: &mut Record| -> Result<()> {
        if args.calibrated {
            apply_latest(&store, &session, record)?;
        }
        Ok(())
    };
    write(&session, units, &mut out, &correct)
        .and_then(|()| Ok(out.flush()?))
        .with_context(|| format!("exporting session {} to {what}", session.id))
}

/// A correction of each record before it is written (`--calibrated`), or nothing.
type Correct<'a> = &'a dyn Fn(&mut Record) -> Result<()>;

fn write(
    session: &Session,
    units: csv::Units,
    out: &mut impl Write,
    correct: Correct,
) -> Result<()> {
    match session.kind {
        Kind::Capture => {
            let capture = csv::read_capture(&session.file)?;
            csv::write_capture(&capture, units, out, correct)
        }
        Kind::Imported if units == csv::Units::Counts => bail!(
            "--units counts: session {} was imported from a file; raw counts exist only for captures",
            session.id
        ),
        Kind::Imported => {
            let mut loaded = load_session(session, &LoadOptions::default())?;
            correct(&mut loaded.record)?;
            Ok(csv::write_record(&loaded.record, out)?)
        }
    }
}

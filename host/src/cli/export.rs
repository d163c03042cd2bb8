//! `imunoise export ID --format csv`: a session's samples in SI units as CSV
//! (`time,gx,gy,gz,ax,ay,az,temp`, time = sample index / rate from 0), or with
//! `--units counts` a capture's raw sensor counts (`index,gx,...,temp`, the MPU-6050's
//! register values, exactly as the board sent them).
//!
//! Gaps are never bridged: lost samples have no row, and a `# gap: N samples lost at index
//! I` comment marks where they were (a board restart likewise gets a `# restart` line), so
//! the time column stays true to each sample's index.

use crate::capture::Capture;
use crate::cli::calibrations::apply_latest;
use crate::cli::output;
use crate::cli::stored::{load_session, read_store};
use crate::input::LoadOptions;
use crate::record::Record;
use crate::store::{Kind, Session};
use anyhow::{Context, Result, bail};
use protocol::RawSample;
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
    if args.calibrated && args.units == Units::Counts {
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
    write(&session, args.units, &mut out, &correct)
        .and_then(|()| Ok(out.flush()?))
        .with_context(|| format!("exporting session {} to {what}", session.id))
}

/// A correction of each record before it is written (`--calibrated`), or nothing.
type Correct<'a> = &'a dyn Fn(&mut Record) -> Result<()>;

fn write(session: &Session, units: Units, out: &mut impl Write, correct: Correct) -> Result<()> {
    match session.kind {
        Kind::Capture => {
            let bytes = std::fs::read(&session.file)
                .with_context(|| format!("{}", session.file.display()))?;
            let capture =
                Capture::decode(&bytes).with_context(|| format!("{}", session.file.display()))?;
            write_capture(&capture, units, out, correct)
        }
        Kind::Imported if units == Units::Counts => bail!(
            "--units counts: session {} was imported from a file; raw counts exist only for captures",
            session.id
        ),
        Kind::Imported => {
            let mut loaded = load_session(session, &LoadOptions::default())?;
            correct(&mut loaded.record)?;
            header(&loaded.record, out)?;
            Ok(rows(&loaded.record, 0, out)?)
        }
    }
}

/// Runs in order, a comment for each gap and restart between them.
pub fn write_capture(
    capture: &Capture,
    units: Units,
    out: &mut impl Write,
    correct: Correct,
) -> Result<()> {
    let mut next = 0u64;
    for (k, run) in capture.runs.iter().enumerate() {
        let mut record = capture.run_record(run, "");
        correct(&mut record)?;
        if k == 0 {
            match units {
                Units::Si => header(&record, out)?,
                Units::Counts => writeln!(out, "index,gx,gy,gz,ax,ay,az,temp")?,
            }
        }
        for r in capture
            .restarts
            .iter()
            .filter(|&&r| (next..=run.first_index).contains(&r))
        {
            writeln!(out, "# restart: the board restarted at index {r}")?;
        }
        if run.first_index > next {
            writeln!(
                out,
                "# gap: {} samples lost at index {next}",
                run.first_index - next
            )?;
        }
        match units {
            Units::Si => rows(&record, run.first_index, out)?,
            Units::Counts => count_rows(&run.samples, run.first_index, out)?,
        }
        next = run.first_index + run.samples.len() as u64;
    }
    Ok(())
}

/// One line per sample: its index, then the raw counts in the SI columns' order.
fn count_rows(
    samples: &[RawSample],
    first_index: u64,
    out: &mut impl Write,
) -> std::io::Result<()> {
    for (i, r) in samples.iter().enumerate() {
        let [gx, gy, gz] = r.gyro;
        let [ax, ay, az] = r.accel;
        let index = first_index + i as u64;
        writeln!(out, "{index},{gx},{gy},{gz},{ax},{ay},{az},{}", r.temp)?;
    }
    Ok(())
}

fn header(record: &Record, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "time,{}", record.names().join(","))
}

/// One line per sample: its time from its index, then the channels (shortest round-trip).
fn rows(record: &Record, first_index: u64, out: &mut impl Write) -> std::io::Result<()> {
    let mut line = String::new();
    for i in 0..record.len() {
        line.clear();
        let time = (first_index + i as u64) as f64 / record.rate_hz;
        line.push_str(&time.to_string());
        for c in &record.channels {
            line.push(',');
            line.push_str(&c.values[i].to_string());
        }
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    Ok(())
}

//! Samples as CSV: a record in SI units (`time,gx,gy,gz,ax,ay,az,temp`, time = sample index
//! / rate from 0), or a capture's raw sensor counts (`index,gx,...,temp`, the MPU-6050's
//! register values, exactly as the board sent them).
//!
//! Gaps are never bridged: lost samples have no row, and a `# gap: N samples lost at index
//! I` comment marks where they were (a board restart likewise gets a `# restart` line), so
//! the time column stays true to each sample's index.

use crate::capture::{Capture, CaptureError, SensorCapture};
use crate::record::Record;
use protocol::{RawSample, SensorKind};
use std::io::Write;
use std::path::{Path, PathBuf};

/// What the written values are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// rad/s, m/s^2, degC, with a time column.
    Si,
    /// The sensor's raw counts, with an index column (captures only).
    Counts,
}

/// A capture file that could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    #[error("{}", .path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}", .path.display())]
    Decode { path: PathBuf, source: CaptureError },
}

/// The capture file at `path`, decoded.
pub fn read_capture(path: &Path) -> Result<Capture, CsvError> {
    let bytes = std::fs::read(path).map_err(|source| CsvError::Read {
        path: path.to_owned(),
        source,
    })?;
    Capture::decode(&bytes).map_err(|source| CsvError::Decode {
        path: path.to_owned(),
        source,
    })
}

/// A capture's runs in order, a comment for each gap and restart between them; `correct`
/// is applied to each run's record before it is written (SI units only matter to it). A
/// board with several sensors gives each sensor's runs in turn, each sensor's after a
/// comment naming it and a header of its own columns (they number their samples apart).
pub fn write_capture<E: From<std::io::Error>>(
    capture: &Capture,
    units: Units,
    out: &mut impl Write,
    correct: &dyn Fn(&mut Record) -> Result<(), E>,
) -> Result<(), E> {
    let several = capture.sensors.len() > 1;
    for (number, sensor) in capture.sensors.iter().enumerate() {
        if several {
            writeln!(out, "# sensor {number}: {}", sensor.sensor.kind)?;
        }
        write_sensor(capture, sensor, units, out, correct)?;
    }
    Ok(())
}

fn write_sensor<E: From<std::io::Error>>(
    capture: &Capture,
    sensor: &SensorCapture,
    units: Units,
    out: &mut impl Write,
    correct: &dyn Fn(&mut Record) -> Result<(), E>,
) -> Result<(), E> {
    let mut next = 0u64;
    for (k, run) in sensor.runs.iter().enumerate() {
        let mut record = capture.run_record(sensor, run, "");
        correct(&mut record)?;
        if k == 0 {
            match units {
                Units::Si => header(&record, out)?,
                Units::Counts => writeln!(out, "index,{}", record.names().join(","))?,
            }
        }
        for r in sensor
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
            Units::Counts => count_rows(&run.samples, sensor.sensor.kind, run.first_index, out)?,
        }
        next = run.first_index + run.samples.len() as u64;
    }
    Ok(())
}

/// A record without gaps, in SI units: the header line, then one line per sample.
pub fn write_record(record: &Record, out: &mut impl Write) -> std::io::Result<()> {
    header(record, out)?;
    rows(record, 0, out)
}

/// One line per sample: its index, then the raw counts the sensor fills, in the SI
/// columns' order.
fn count_rows(
    samples: &[RawSample],
    kind: SensorKind,
    first_index: u64,
    out: &mut impl Write,
) -> std::io::Result<()> {
    let fills = kind.fills();
    for (i, r) in samples.iter().enumerate() {
        write!(out, "{}", first_index + i as u64)?;
        let parts = [
            (fills.gyro, &r.gyro[..]),
            (fills.accel, &r.accel[..]),
            (fills.temp, std::slice::from_ref(&r.temp)),
        ];
        for (_, counts) in parts.iter().filter(|(filled, _)| *filled) {
            for c in counts.iter() {
                write!(out, ",{c}")?;
            }
        }
        writeln!(out)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Channel;

    #[test]
    fn a_record_is_a_header_and_a_line_per_sample_timed_by_index() {
        let record = Record {
            source: String::new(),
            rate_hz: 4.0,
            channels: vec![
                Channel::named("gx", vec![0.5, -1.0]),
                Channel::named("temp", vec![25.0, 25.25]),
            ],
        };
        let mut out = Vec::new();
        write_record(&record, &mut out).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "time,gx,temp\n0,0.5,25\n0.25,-1,25.25\n"
        );
    }

    #[test]
    fn an_unreadable_capture_names_its_file() {
        let e = read_capture(Path::new("/nonexistent/x.imucap")).unwrap_err();
        assert!(matches!(e, CsvError::Read { .. }));
        assert_eq!(e.to_string(), "/nonexistent/x.imucap");
    }
}

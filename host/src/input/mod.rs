//! Reading records from files: text/CSV tables and NumPy `.npy` arrays, with the conversions a
//! user may ask for on the way (raw MPU-6050 counts to SI, a factor per column).
//!
//! Every error names the file and, where there is one, the line and column at fault.

mod npy;
mod text;

pub use npy::write_f64 as write_npy;

use crate::capture::{self, Capture};
use crate::record::{Channel, Quantity, Record};
use protocol::mpu6050::SensorSettings;
use std::path::{Path, PathBuf};

/// How to turn a file into a record.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Sample rate in Hz; required when the file has neither a time column nor a rate in its
    /// header, and checked against them when it has.
    pub rate_hz: Option<f64>,
    /// Channel names for inputs without a header (NumPy arrays, headerless text); replaces a
    /// header's names when given.
    pub names: Vec<String>,
    /// The values are raw MPU-6050 register counts: convert rates, accelerations and the
    /// temperature to SI with these sensitivities.
    pub counts: Option<CountScale>,
    /// Multiply the named channel by a factor (after any counts conversion).
    pub scales: Vec<(String, f64)>,
    /// A capture with gaps: analyse its longest gap-free run instead of refusing.
    pub longest_run: bool,
}

/// A record and what the reader has to say about where it came from (losses in a capture,
/// the run chosen): shown to the user, never dropped.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub record: Record,
    pub notes: Vec<String>,
    /// The sensor settings the samples were taken with, when the input states them (a
    /// capture's Info for the run read).
    pub settings: Option<SensorSettings>,
}

/// Sensitivities for raw counts; see `protocol::mpu6050` for where they come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountScale {
    pub rad_s_per_lsb: f64,
    pub m_s2_per_lsb: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {message}")]
    Line {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
}

impl InputError {
    fn file(path: &Path, message: impl Into<String>) -> InputError {
        InputError::File {
            path: path.to_owned(),
            message: message.into(),
        }
    }

    fn line(path: &Path, line: usize, message: impl Into<String>) -> InputError {
        InputError::Line {
            path: path.to_owned(),
            line,
            message: message.into(),
        }
    }
}

/// What a file reader found before the options are applied: channels, and a sample interval
/// if the file states one (a time column or a rate in its header).
#[derive(Debug)]
struct Table {
    channels: Vec<(String, Vec<f64>)>,
    rate_hz: Option<RateSource>,
}

/// A sample rate the file itself states, and how it says it (for error messages).
#[derive(Debug)]
struct RateSource {
    hz: f64,
    from: String,
}

/// Read a record from `path`: a capture (the board's framed bytes, recognised by its leading
/// frame delimiter), `.npy` as a NumPy array, anything else as a text table.
pub fn load(path: &Path, options: &LoadOptions) -> Result<Loaded, InputError> {
    let bytes = std::fs::read(path).map_err(|source| InputError::Io {
        path: path.to_owned(),
        source,
    })?;
    let is_npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let mut notes = Vec::new();
    let mut settings = None;
    let table = if capture::looks_like_capture(&bytes) {
        let (table, s) = capture_table(path, &bytes, options, &mut notes)?;
        settings = Some(s);
        table
    } else if is_npy {
        npy::parse(path, &bytes)?
    } else {
        text::parse(path, &bytes)?
    };
    let record = build_record(path, table, options)?;
    Ok(Loaded {
        record,
        notes,
        settings,
    })
}

/// A capture's samples in SI (with the board's own settings), and notes on every loss; with
/// the settings of the run read.
fn capture_table(
    path: &Path,
    bytes: &[u8],
    options: &LoadOptions,
    notes: &mut Vec<String>,
) -> Result<(Table, SensorSettings), InputError> {
    if options.counts.is_some() {
        return Err(InputError::file(
            path,
            "--counts: a capture is converted with the board's own settings; drop --counts",
        ));
    }
    let capture = Capture::decode(bytes).map_err(|e| InputError::file(path, e.to_string()))?;
    let record = capture
        .to_record(&path.display().to_string(), options.longest_run)
        .map_err(|e| InputError::file(path, e.to_string()))?;
    notes.extend(capture_notes(&capture, record.len()));
    // The run `to_record` read: the longest.
    let settings = capture
        .runs
        .iter()
        .max_by_key(|r| r.samples.len())
        .and_then(|r| r.settings)
        .unwrap_or(capture.info.settings);
    let table = Table {
        rate_hz: Some(RateSource {
            hz: record.rate_hz,
            from: format!("board's settings ({})", capture.info.settings),
        }),
        channels: record
            .channels
            .into_iter()
            .map(|c| (c.name, c.values))
            .collect(),
    };
    Ok((table, settings))
}

/// What a capture lost, in words: gaps, damaged frames, the board's own loss counters.
fn capture_notes(capture: &Capture, analysed: usize) -> Vec<String> {
    let mut notes = Vec::new();
    let lost = capture.accounting.lost();
    if lost > 0 {
        notes.push(format!(
            "capture: {lost} samples lost in {} gap(s); analysing the longest gap-free run, {analysed} samples",
            capture.gaps().len()
        ));
    }
    let rejected = capture.decoder.rejected();
    if rejected > 0 {
        notes.push(format!(
            "capture: {rejected} damaged frame(s) rejected on the line"
        ));
    }
    if let Some(s) = &capture.status
        && (s.samples_lost > 0 || s.samples_dropped > 0 || s.i2c_errors > 0)
    {
        notes.push(format!(
            "board status: {} samples lost to FIFO overflows ({} overflows), {} dropped for USB back-pressure, {} I2C errors",
            s.samples_lost, s.fifo_overflows, s.samples_dropped, s.i2c_errors
        ));
    }
    notes
}

fn build_record(path: &Path, table: Table, options: &LoadOptions) -> Result<Record, InputError> {
    let rate_hz = resolve_rate(path, table.rate_hz, options.rate_hz)?;
    let mut channels = table.channels;
    if !options.names.is_empty() {
        if options.names.len() != channels.len() {
            return Err(InputError::file(
                path,
                format!(
                    "--names gives {} names but the file has {} channels",
                    options.names.len(),
                    channels.len()
                ),
            ));
        }
        for ((name, _), new) in channels.iter_mut().zip(&options.names) {
            *name = new.clone();
        }
    }
    let mut channels: Vec<Channel> = channels
        .into_iter()
        .map(|(name, values)| Channel::named(name, values))
        .collect();
    if let Some(scale) = options.counts {
        channels.iter_mut().for_each(|c| counts_to_si(c, scale));
    }
    for (name, factor) in &options.scales {
        let channel = channels
            .iter_mut()
            .find(|c| &c.name == name)
            .ok_or_else(|| {
                InputError::file(
                    path,
                    format!("--scale {name}={factor}: no channel '{name}'"),
                )
            })?;
        channel.values.iter_mut().for_each(|v| *v *= factor);
    }
    Ok(Record {
        source: path.display().to_string(),
        rate_hz,
        channels,
    })
}

/// The rate is the file's (time column or header) or `--rate`; both present must agree to
/// 0.1 %, and neither is an error saying what to add.
fn resolve_rate(
    path: &Path,
    stated: Option<RateSource>,
    given: Option<f64>,
) -> Result<f64, InputError> {
    if let Some(hz) = given
        && !(hz.is_finite() && hz > 0.0)
    {
        return Err(InputError::file(
            path,
            format!("--rate {hz}: a positive number of Hz"),
        ));
    }
    match (stated, given) {
        (Some(s), Some(hz)) if ((s.hz - hz) / hz).abs() > 1e-3 => Err(InputError::file(
            path,
            format!("--rate {hz} Hz disagrees with the {} ({} Hz)", s.from, s.hz),
        )),
        (Some(s), _) => Ok(s.hz),
        (None, Some(hz)) => Ok(hz),
        (None, None) => Err(InputError::file(
            path,
            "no time column and no rate in the file: give --rate HZ",
        )),
    }
}

/// Raw MPU-6050 counts to SI: gyro counts times rad/s per LSB, accel counts times m/s^2 per
/// LSB, TEMP_OUT by the datasheet's `counts / 340 + 36.53` (register map rev 4.2, 4.18).
fn counts_to_si(channel: &mut Channel, scale: CountScale) {
    let convert: Box<dyn Fn(f64) -> f64> = match channel.quantity {
        Quantity::AngularRate => Box::new(move |c| c * scale.rad_s_per_lsb),
        Quantity::Acceleration => Box::new(move |c| c * scale.m_s2_per_lsb),
        Quantity::Temperature => Box::new(|c| c / 340.0 + 36.53),
        Quantity::Other => return,
    };
    channel.values.iter_mut().for_each(|v| *v = convert(*v));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(rate: Option<f64>) -> Table {
        Table {
            channels: vec![
                ("ax".into(), vec![16384.0, 0.0]),
                ("gz".into(), vec![131.0, -131.0]),
                ("temp".into(), vec![-12419.0, 0.0]),
                ("x".into(), vec![1.0, 2.0]),
            ],
            rate_hz: rate.map(|hz| RateSource {
                hz,
                from: "header".into(),
            }),
        }
    }

    #[test]
    fn counts_become_si() {
        let scale = CountScale {
            rad_s_per_lsb: (1.0f64 / 131.0).to_radians(),
            m_s2_per_lsb: 9.80665 / 16384.0,
        };
        let options = LoadOptions {
            counts: Some(scale),
            scales: vec![("x".into(), 10.0)],
            ..LoadOptions::default()
        };
        let r = build_record(Path::new("f"), table(Some(100.0)), &options).unwrap();
        assert_eq!(r.rate_hz, 100.0);
        assert!((r.channels[0].values[0] - 9.80665).abs() < 1e-12);
        assert!((r.channels[1].values[1] + 1f64.to_radians()).abs() < 1e-12);
        assert_eq!(r.channels[2].values[0], -12419.0 / 340.0 + 36.53);
        assert_eq!(r.channels[3].values, [10.0, 20.0]);
    }

    #[test]
    fn rate_conflicts_and_absence_are_errors() {
        let path = Path::new("f.csv");
        let opts = |rate| LoadOptions {
            rate_hz: rate,
            ..LoadOptions::default()
        };
        let err = build_record(path, table(Some(100.0)), &opts(Some(200.0))).unwrap_err();
        assert!(
            err.to_string()
                .contains("--rate 200 Hz disagrees with the header (100 Hz)")
        );
        let err = build_record(path, table(None), &opts(None)).unwrap_err();
        assert!(err.to_string().contains("give --rate HZ"), "{err}");
        let r = build_record(path, table(None), &opts(Some(50.0))).unwrap();
        assert_eq!(r.rate_hz, 50.0);
        let err = build_record(path, table(None), &opts(Some(-1.0))).unwrap_err();
        assert!(err.to_string().contains("positive"), "{err}");
    }

    #[test]
    fn names_replace_and_must_match_the_channel_count() {
        let opts = LoadOptions {
            rate_hz: Some(1.0),
            names: vec!["gx".into(), "gy".into()],
            ..LoadOptions::default()
        };
        let err = build_record(Path::new("f"), table(None), &opts).unwrap_err();
        assert!(
            err.to_string()
                .contains("--names gives 2 names but the file has 4")
        );
    }
}

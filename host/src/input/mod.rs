//! Reading records from files: text/CSV tables and NumPy `.npy` arrays, either of them
//! gzip-compressed, and the IMU topics of ROS bags ([`rosbag`]), with the conversions a user may ask for on the way (raw MPU-6050 counts
//! to SI, units from column-name suffixes, a factor per column) and the time base a time
//! column gives ([`timing`]).
//!
//! Every error names the file and, where there is one, the line and column at fault.

mod names;
mod npy;
pub mod rosbag;
mod text;
pub mod timing;
mod units;

pub use npy::{NpyChunks, NpyError, write_f64 as write_npy};
pub use timing::Timing;
pub use units::UnitConversion;

use crate::analysis::pipeline::KnownFilters;
use crate::capture::{self, Capture, SensorRecord};
use crate::record::{Channel, Quantity, Record};
use protocol::SensorConfig;
use serde::Serialize;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// How to turn a file into a record.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Sample rate in Hz; required when the file has neither a time column nor a rate in its
    /// header. It overrides a time column (with a warning when they disagree) and must agree
    /// with a header's or a capture's rate.
    pub rate_hz: Option<f64>,
    /// Ignore the file's time column: the rows are samples at `rate_hz` (or the header's rate)
    /// whatever their stamps say.
    pub ignore_time: bool,
    /// Channel names for inputs without a header (NumPy arrays, headerless text); replaces a
    /// header's names when given.
    pub names: Vec<String>,
    /// The values are raw MPU-6050 register counts: convert rates, accelerations and the
    /// temperature to SI with these sensitivities.
    pub counts: Option<CountScale>,
    /// Multiply the named channel by a factor (after any counts conversion).
    pub scales: Vec<(String, f64)>,
    /// A capture with gaps, or a time column with samples missing: analyse the longest
    /// gap-free run instead of refusing (the losses are reported).
    pub longest_run: bool,
    /// The topic to read from a ROS bag (needed when it has several IMU topics).
    pub topic: Option<String>,
}

/// A record and what the reader has to say about where it came from (losses in a capture,
/// the run chosen): shown to the user, never dropped.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub record: Record,
    pub notes: Vec<String>,
    /// The sensor settings the samples were taken with, when the input states them (a
    /// capture's Info for the run read).
    pub settings: Option<KnownFilters>,
    /// How the file was read: compression, time base, unit conversions, warnings.
    pub report: ReadReport,
}

/// What reading a file involved, for the analysis output and its JSON document.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ReadReport {
    /// The bag, topic and time base, when the input is a ROS bag.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bag: Option<rosbag::BagRead>,
    /// `gzip` when the file was compressed.
    pub compression: Option<&'static str>,
    /// The time column's rate and jitter, when one was used.
    pub timing: Option<Timing>,
    /// A time column `--ignore-time` set aside.
    pub ignored_time_column: Option<String>,
    /// Columns that are neither the time base nor signals: further time stamps and sample
    /// counters (ROS's `field.header.stamp` and `field.header.seq`), by name.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub set_aside_columns: Vec<String>,
    /// Units taken from column-name suffixes.
    pub units: Vec<UnitConversion>,
    /// What the user should know before trusting the result (jitter, an overridden rate).
    pub warnings: Vec<String>,
}

impl ReadReport {
    /// The report as lines of text (empty for a plain file read as it is).
    pub fn lines(&self) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(b) = &self.bag {
            lines.push(b.to_string());
        }
        if let Some(c) = self.compression {
            lines.push(format!("input: {c}-compressed"));
        }
        if let Some(t) = &self.timing {
            lines.push(t.to_string());
        }
        if let Some(name) = &self.ignored_time_column {
            lines.push(format!("time column '{name}' ignored (--ignore-time)"));
        }
        if !self.set_aside_columns.is_empty() {
            let named: Vec<String> = self
                .set_aside_columns
                .iter()
                .map(|n| format!("'{n}'"))
                .collect();
            lines.push(format!(
                "not analysed (further time stamps, sample counters): {}",
                named.join(", ")
            ));
        }
        if !self.units.is_empty() {
            let units: Vec<String> = self.units.iter().map(|u| u.to_string()).collect();
            lines.push(format!("units from column names: {}", units.join("; ")));
        }
        lines
    }
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
    #[error("{path}: {source}")]
    Npy {
        path: PathBuf,
        source: npy::NpyError,
    },
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
    /// A time column's fit (its rate, jitter and lines).
    timing: Option<Timing>,
    /// A time column `--ignore-time` set aside, by name.
    ignored_time: Option<String>,
    /// Further time columns and sample counters, by name.
    set_aside: Vec<String>,
}

/// A sample rate the file itself states, and how it says it (for error messages).
#[derive(Debug)]
struct RateSource {
    hz: f64,
    from: String,
}

/// The two bytes every gzip member starts with (RFC 1952, 2.3.1).
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// Read a record from `path`, gunzipped first if it starts with gzip's magic bytes: a ROS bag
/// or a rosbag2 directory (the Imu topic `options.topic`, [`rosbag`]), a capture (the board's
/// framed bytes, recognised by its leading frame delimiter), a NumPy array (its magic bytes,
/// or a name ending `.npy`), anything else as a text table.
pub fn load(path: &Path, options: &LoadOptions) -> Result<Loaded, InputError> {
    let path = &rosbag::storage_file(path)?;
    let io = |source| InputError::Io {
        path: path.to_owned(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut report = ReadReport::default();
    let mut magic = Vec::with_capacity(rosbag::MAGIC_LEN);
    (&mut file)
        .take(rosbag::MAGIC_LEN as u64)
        .read_to_end(&mut magic)
        .map_err(io)?;
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    let mut notes = Vec::new();
    let mut settings = None;
    let table = if let Some(format) = rosbag::Format::of(&magic) {
        drop(file);
        let (table, bag) =
            rosbag::table(path, format, options.topic.as_deref(), options.ignore_time)?;
        report.bag = Some(bag);
        table
    } else if let Some(topic) = &options.topic {
        return Err(InputError::file(
            path,
            format!("--topic {topic}: not a ROS bag (ROS 1 .bag, MCAP or rosbag2 .db3)"),
        ));
    } else if magic.starts_with(npy::MAGIC) {
        // An uncompressed array is read straight into its channels.
        let len = file.metadata().map_err(io)?.len();
        npy::parse_reader(path, std::io::BufReader::new(file), len)?
    } else {
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io)?;
        if bytes.starts_with(&GZIP_MAGIC) {
            bytes = gunzip(path, &bytes)?;
            report.compression = Some("gzip");
        }
        let is_npy = bytes.starts_with(npy::MAGIC)
            || path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if capture::looks_like_capture(&bytes) {
            let (table, s) = capture_table(path, &bytes, options, &mut notes)?;
            settings = Some(s);
            table
        } else if is_npy {
            npy::parse(path, &bytes)?
        } else {
            let time = text::TimeOptions {
                ignore_time: options.ignore_time,
                longest_run: options.longest_run,
            };
            text::parse(path, &bytes, time, &mut notes)?
        }
    };
    let record = build_record(path, table, options, &mut report)?;
    Ok(Loaded {
        record,
        notes,
        settings,
        report,
    })
}

/// An uncompressed `.npy` input opened to be read a block of rows at a time ([`open_npy`]):
/// for records larger than memory.
pub struct NpyStream {
    /// The record's source, rate and channels, the channels without samples.
    pub record: Record,
    /// How the file is read (units from column names, warnings).
    pub report: ReadReport,
    chunks: NpyChunks<std::io::BufReader<std::fs::File>>,
    /// Per channel: the unit suffix's factor to SI and the `--scale` factor.
    factors: Vec<(f64, f64)>,
    counts: Option<CountScale>,
}

impl NpyStream {
    /// Samples per channel.
    pub fn rows(&self) -> usize {
        self.chunks.rows()
    }

    /// Replace `columns` (one per channel of [`NpyStream::record`]) with the next rows, at
    /// most `max_rows`, converted as [`load`] converts them; the count read, 0 at the end.
    pub fn next_rows(
        &mut self,
        max_rows: usize,
        columns: &mut [Vec<f64>],
    ) -> Result<usize, InputError> {
        let got = self.chunks.next_rows(max_rows, columns)?;
        for ((column, channel), &(unit, scale)) in columns
            .iter_mut()
            .zip(&self.record.channels)
            .zip(&self.factors)
        {
            if unit != 1.0 {
                column.iter_mut().for_each(|v| *v *= unit);
            }
            if let Some(counts) = self.counts {
                let mut converted = Channel {
                    name: String::new(),
                    quantity: channel.quantity,
                    values: std::mem::take(column),
                };
                counts_to_si(&mut converted, counts);
                *column = converted.values;
            }
            if scale != 1.0 {
                column.iter_mut().for_each(|v| *v *= scale);
            }
        }
        Ok(got)
    }
}

/// `path` opened as an [`NpyStream`] when it is an uncompressed `.npy` file (`None`
/// otherwise): its header read, and the names, units, rate and conversions of `options`
/// resolved as [`load`] resolves them.
pub fn open_npy(path: &Path, options: &LoadOptions) -> Result<Option<NpyStream>, InputError> {
    let io = |source| InputError::Io {
        path: path.to_owned(),
        source,
    };
    let mut magic = [0u8; 6];
    let mut file = std::fs::File::open(path).map_err(io)?;
    match file.read_exact(&mut magic) {
        Ok(()) if magic == npy::MAGIC => {}
        Ok(()) => return Ok(None),
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(io(e)),
    }
    drop(file);
    let chunks = NpyChunks::open(path)?;
    let table = Table {
        channels: (0..chunks.cols())
            .map(|c| (format!("c{c}"), Vec::new()))
            .collect(),
        rate_hz: None,
        timing: None,
        ignored_time: None,
        set_aside: Vec::new(),
    };
    let mut report = ReadReport::default();
    let record = build_record(path, table, options, &mut report)?;
    let factors = record
        .channels
        .iter()
        .map(|c| {
            let unit = report
                .units
                .iter()
                .find(|u| u.channel == c.name)
                .map_or(1.0, |u| u.factor);
            let scale = options
                .scales
                .iter()
                .filter(|(name, _)| *name == c.name)
                .map(|(_, f)| f)
                .product();
            (unit, scale)
        })
        .collect();
    Ok(Some(NpyStream {
        record,
        report,
        chunks,
        factors,
        counts: options.counts,
    }))
}

/// The uncompressed bytes of a gzip file (every member of a concatenated one).
fn gunzip(path: &Path, bytes: &[u8]) -> Result<Vec<u8>, InputError> {
    let mut out = Vec::with_capacity(bytes.len().saturating_mul(4));
    flate2::read::MultiGzDecoder::new(bytes)
        .read_to_end(&mut out)
        .map_err(|e| InputError::file(path, format!("gzip: {e}")))?;
    Ok(out)
}

/// A capture's samples in SI (with the board's own settings), and notes on every loss; with
/// the settings of the run read.
fn capture_table(
    path: &Path,
    bytes: &[u8],
    options: &LoadOptions,
    notes: &mut Vec<String>,
) -> Result<(Table, KnownFilters), InputError> {
    if options.counts.is_some() {
        return Err(InputError::file(
            path,
            "--counts: a capture is converted with the board's own settings; drop --counts",
        ));
    }
    let capture = Capture::decode(bytes).map_err(|e| InputError::file(path, e.to_string()))?;
    let (record, used) = capture
        .to_record_with(&path.display().to_string(), options.longest_run)
        .map_err(|e| InputError::file(path, e.to_string()))?;
    notes.extend(capture_notes(&capture, &used));
    // The runs `to_record` read: the longest of each sensor.
    let configs: Vec<SensorConfig> = capture
        .sensors
        .iter()
        .filter_map(|s| s.longest_run().map(|run| s.config_of(run)))
        .collect();
    let settings = KnownFilters::of(&configs);
    let table = Table {
        rate_hz: Some(RateSource {
            hz: record.rate_hz,
            from: format!("board's settings ({})", describe_configs(&configs)),
        }),
        timing: None,
        ignored_time: None,
        set_aside: Vec::new(),
        channels: record
            .channels
            .into_iter()
            .map(|c| (c.name, c.values))
            .collect(),
    };
    Ok((table, settings))
}

/// Each sensor's settings, in words.
fn describe_configs(configs: &[SensorConfig]) -> String {
    let described: Vec<String> = configs.iter().map(SensorConfig::to_string).collect();
    described.join("; ")
}

/// What a capture lost, in words: gaps, samples left out to line sensors up, damaged
/// frames, the board's own loss counters.
fn capture_notes(capture: &Capture, used: &[SensorRecord]) -> Vec<String> {
    let mut notes = Vec::new();
    let several = capture.sensors.len() > 1;
    for (sensor, part) in capture.sensors.iter().zip(used) {
        let name = match several {
            true => format!("capture, {}", part.kind),
            false => "capture".to_string(),
        };
        let lost = sensor.accounting.lost();
        if lost > 0 {
            notes.push(format!(
                "{name}: {lost} samples lost in {} gap(s); analysing the longest gap-free run, {} samples",
                sensor.gaps().len(),
                part.used + part.trimmed
            ));
        }
        if part.trimmed > 0 {
            notes.push(format!(
                "{name}: {} samples outside the time all sensors cover left out; {} analysed",
                part.trimmed, part.used
            ));
        }
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

/// The record a table makes with the options applied; what was done goes into `report`.
fn build_record(
    path: &Path,
    table: Table,
    options: &LoadOptions,
    report: &mut ReadReport,
) -> Result<Record, InputError> {
    let rate_hz = resolve_rate(
        path,
        table.rate_hz,
        table.timing.as_ref(),
        options,
        &mut report.warnings,
    )?;
    report.ignored_time_column = table.ignored_time;
    report.set_aside_columns = table.set_aside;
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
    let (mut channels, conversions) = units::channels(path, channels)?;
    if let (Some(_), Some(u)) = (options.counts, conversions.first()) {
        return Err(InputError::file(
            path,
            format!(
                "--counts: column '{}' states its unit ({}); drop --counts",
                u.column, u.from
            ),
        ));
    }
    report.units = conversions;
    if let Some(t) = table.timing.as_ref().filter(|t| !t.uniform) {
        report.warnings.push(t.to_string());
    }
    report.timing = table.timing;
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
    if options.counts.is_none() && options.scales.is_empty() {
        let stated: Vec<&str> = report.units.iter().map(|u| u.column.as_str()).collect();
        report.warnings.extend(
            channels
                .iter()
                .filter(|c| !stated.contains(&c.name.as_str()))
                .filter_map(looks_like_counts),
        );
    }
    Ok(Record {
        source: path.display().to_string(),
        rate_hz,
        channels,
    })
}

/// Two rates further apart than this (relative) disagree.
const RATE_AGREEMENT: f64 = 1e-3;

fn disagree(a: f64, b: f64) -> bool {
    ((a - b) / b).abs() > RATE_AGREEMENT
}

/// The rate: `--rate` if given, else a time column's fit, else the header's (or a capture's
/// settings). A stated rate (header, capture) is a fact about the file and must agree with
/// `--rate` and with the time column to 0.1 %; a time column is a measurement that `--rate`
/// overrides, with a warning when they disagree. No rate at all is an error saying what to
/// add.
fn resolve_rate(
    path: &Path,
    stated: Option<RateSource>,
    timing: Option<&Timing>,
    options: &LoadOptions,
    warnings: &mut Vec<String>,
) -> Result<f64, InputError> {
    let given = options.rate_hz;
    if let Some(hz) = given
        && !(hz.is_finite() && hz > 0.0)
    {
        return Err(InputError::file(
            path,
            format!("--rate {hz}: a positive number of Hz"),
        ));
    }
    if let (Some(s), Some(hz)) = (&stated, given)
        && disagree(s.hz, hz)
    {
        return Err(InputError::file(
            path,
            format!("--rate {hz} Hz disagrees with the {} ({} Hz)", s.from, s.hz),
        ));
    }
    match (given, timing, &stated) {
        (Some(hz), Some(t), _) => {
            if disagree(t.rate_hz, hz) {
                warnings.push(format!(
                    "--rate {hz} Hz overrides the time column '{}' ({} Hz by least squares), {:.3} % apart",
                    t.column,
                    t.rate_hz,
                    (hz / t.rate_hz - 1.0) * 100.0
                ));
            }
            Ok(hz)
        }
        (Some(hz), None, _) => Ok(hz),
        (None, Some(t), Some(s)) if disagree(s.hz, t.rate_hz) => Err(InputError::file(
            path,
            format!(
                "the {} ({} Hz) disagrees with the time column '{}' ({} Hz by least squares): \
                 choose with --rate HZ, or --ignore-time to use the {}",
                s.from, s.hz, t.column, t.rate_hz, s.from
            ),
        )),
        (None, Some(t), _) => Ok(t.rate_hz),
        (None, None, Some(s)) => Ok(s.hz),
        (None, None, None) if options.ignore_time => Err(InputError::file(
            path,
            "--ignore-time and no rate in the file: give --rate HZ",
        )),
        (None, None, None) => Err(InputError::file(
            path,
            "no time column and no rate in the file: give --rate HZ",
        )),
    }
}

/// Raw MPU-6050 counts to SI: gyro counts times rad/s per LSB, accel counts times m/s^2 per
/// LSB, TEMP_OUT by the datasheet's `counts / 340 + 36.53` (register map rev 4.2, 4.18).
/// The largest magnitude an IMU channel can have in SI: the widest full scale of the
/// sensors this tool knows (MPU-6050 +-2000 deg/s and +-16 g; `protocol::mpu6050`), with a
/// margin of two for other parts.
fn si_ceiling(quantity: Quantity) -> Option<f64> {
    use protocol::mpu6050::{AccelRange, GyroRange};
    match quantity {
        Quantity::AngularRate => Some(2.0 * GyroRange::Dps2000.full_scale_dps().to_radians()),
        Quantity::Acceleration => {
            Some(2.0 * AccelRange::G16.full_scale_g() * units::STANDARD_GRAVITY)
        }
        Quantity::Temperature | Quantity::Other => None,
    }
}

/// A warning when a rate or acceleration channel read as SI holds only whole numbers beyond
/// any sensor's full scale: raw register counts given without `--counts`, which would
/// otherwise be analysed as rad/s or m/s^2 and give noise terms thousands of times too large.
fn looks_like_counts(channel: &Channel) -> Option<String> {
    let ceiling = si_ceiling(channel.quantity)?;
    let largest = channel.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let whole = channel.values.iter().all(|v| v.fract() == 0.0);
    (whole && largest > ceiling).then(|| {
        format!(
            "{}: whole numbers up to {largest} cannot be {unit} (no sensor reads beyond {ceiling:.0} {unit}): \
             raw counts? give --counts (MPU-6050 register counts) or --scale {}=FACTOR",
            channel.name,
            channel.name,
            unit = channel.unit(),
        )
    })
}

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

    /// Raw counts read as SI are flagged (an MPU-6050 at rest: az near 16384 LSB, a gyro bias
    /// of a few hundred LSB); SI values, fractional or within any full scale, are not.
    #[test]
    fn whole_numbers_beyond_full_scale_are_flagged_as_counts() {
        let flagged =
            |name: &str, values: Vec<f64>| looks_like_counts(&Channel::named(name, values));
        let az = flagged("az", vec![15708.0, 14772.0, 14432.0]).unwrap();
        assert!(az.contains("--counts") && az.contains("m/s^2"), "{az}");
        assert!(flagged("gx", vec![-480.0, -439.0, -386.0]).is_some());
        assert!(flagged("az", vec![9.0, 10.0, 9.0]).is_none());
        assert!(flagged("gx", vec![-480.5, -439.0]).is_none());
        assert!(flagged("gx", vec![0.01, -0.02]).is_none());
        assert!(flagged("temp", vec![12000.0]).is_none());
    }

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
            timing: None,
            ignored_time: None,
            set_aside: Vec::new(),
        }
    }

    fn build(table: Table, options: &LoadOptions) -> Result<(Record, ReadReport), InputError> {
        let mut report = ReadReport::default();
        let record = build_record(Path::new("f.csv"), table, options, &mut report)?;
        Ok((record, report))
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
        let (r, _) = build(table(Some(100.0)), &options).unwrap();
        assert_eq!(r.rate_hz, 100.0);
        assert!((r.channels[0].values[0] - 9.80665).abs() < 1e-12);
        assert!((r.channels[1].values[1] + 1f64.to_radians()).abs() < 1e-12);
        assert_eq!(r.channels[2].values[0], -12419.0 / 340.0 + 36.53);
        assert_eq!(r.channels[3].values, [10.0, 20.0]);
    }

    #[test]
    fn rate_conflicts_and_absence_are_errors() {
        let opts = |rate| LoadOptions {
            rate_hz: rate,
            ..LoadOptions::default()
        };
        let err = build(table(Some(100.0)), &opts(Some(200.0))).unwrap_err();
        assert!(
            err.to_string()
                .contains("--rate 200 Hz disagrees with the header (100 Hz)")
        );
        let err = build(table(None), &opts(None)).unwrap_err();
        assert!(err.to_string().contains("give --rate HZ"), "{err}");
        let (r, _) = build(table(None), &opts(Some(50.0))).unwrap();
        assert_eq!(r.rate_hz, 50.0);
        let err = build(table(None), &opts(Some(-1.0))).unwrap_err();
        assert!(err.to_string().contains("positive"), "{err}");
        let ignoring = LoadOptions {
            ignore_time: true,
            ..LoadOptions::default()
        };
        let err = build(table(None), &ignoring).unwrap_err();
        assert!(
            err.to_string()
                .contains("--ignore-time and no rate in the file: give --rate HZ"),
            "{err}"
        );
    }

    /// A table whose time column was fitted to `hz`, with a header rate `header`.
    fn timed(hz: f64, header: Option<f64>) -> Table {
        let times: Vec<f64> = (0..100).map(|i| i as f64 / hz).collect();
        let mut t = table(header);
        // SI values, so the only warnings are about the rate.
        t.channels.retain(|(name, _)| name == "x");
        t.timing = Some(timing::analyse("t", &times).unwrap());
        t
    }

    #[test]
    fn rate_overrides_a_time_column_with_a_warning() {
        let opts = |rate| LoadOptions {
            rate_hz: rate,
            ..LoadOptions::default()
        };
        let (r, report) = build(timed(100.5, None), &opts(Some(100.0))).unwrap();
        assert_eq!(r.rate_hz, 100.0);
        assert_eq!(
            report.warnings,
            [
                "--rate 100 Hz overrides the time column 't' (100.5 Hz by least squares), -0.498 % apart"
            ]
        );
        // Within 0.1 %: no warning.
        let (r, report) = build(timed(100.05, None), &opts(Some(100.0))).unwrap();
        assert_eq!(r.rate_hz, 100.0);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        // Without --rate the column's rate, and a header that disagrees with it is an error.
        let (r, report) = build(timed(100.5, None), &opts(None)).unwrap();
        assert_eq!(r.rate_hz, 100.5);
        assert_eq!(report.timing.unwrap().rate_hz, 100.5);
        let err = build(timed(100.5, Some(100.0)), &opts(None)).unwrap_err();
        assert!(
            err.to_string().contains(
                "the header (100 Hz) disagrees with the time column 't' (100.5 Hz by least squares)"
            ),
            "{err}"
        );
    }

    #[test]
    fn unit_suffixes_and_counts_exclude_each_other() {
        let mut t = table(Some(100.0));
        t.channels[0].0 = "ax_g".into();
        let opts = LoadOptions {
            counts: Some(CountScale {
                rad_s_per_lsb: 1.0,
                m_s2_per_lsb: 1.0,
            }),
            ..LoadOptions::default()
        };
        let err = build(t, &opts).unwrap_err();
        assert_eq!(
            err.to_string(),
            "f.csv: --counts: column 'ax_g' states its unit (g); drop --counts"
        );
    }

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        use std::io::Write;
        let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(bytes).unwrap();
        z.finish().unwrap()
    }

    /// Gzip is recognised by its magic bytes whatever the name, and the table inside reads as
    /// if uncompressed; errors name the compressed file and the line inside.
    #[test]
    fn gzip_inputs_read_as_their_contents() {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("log.csv.gz");
        std::fs::write(&csv, gzip(b"t,gx_dps\n0,1\n0.01,2\n0.02,3\n")).unwrap();
        let loaded = load(&csv, &LoadOptions::default()).unwrap();
        assert_eq!(loaded.record.rate_hz, 100.0);
        assert_eq!(loaded.record.channels[0].name, "gx");
        assert_eq!(loaded.record.channels[0].values[2], 3f64.to_radians());
        assert_eq!(loaded.report.compression, Some("gzip"));
        let lines = loaded.report.lines();
        assert_eq!(lines[0], "input: gzip-compressed");
        assert!(
            lines[2].contains("gx_dps: deg/s -> rad/s x 0.0174533"),
            "{lines:?}"
        );

        let npy = dir.path().join("a.dat");
        write_npy(&dir.path().join("a.npy"), &[1.0, 2.0]).unwrap();
        std::fs::write(
            &npy,
            gzip(&std::fs::read(dir.path().join("a.npy")).unwrap()),
        )
        .unwrap();
        let opts = LoadOptions {
            rate_hz: Some(10.0),
            names: vec!["az_mg".into()],
            ..LoadOptions::default()
        };
        let loaded = load(&npy, &opts).unwrap();
        assert_eq!(loaded.record.channels[0].name, "az");
        assert_eq!(
            loaded.record.channels[0].values,
            [9.80665e-3, 2.0 * 9.80665e-3]
        );

        let bad = dir.path().join("bad.txt.gz");
        std::fs::write(&bad, gzip(b"gx gy\n1 2\n3 x\n")).unwrap();
        let err = load(&bad, &opts).unwrap_err().to_string();
        assert_eq!(
            err,
            format!("{}:3: column 'gy': 'x' is not a number", bad.display())
        );
        let cut = dir.path().join("cut.csv.gz");
        let whole = gzip(&b"gx\n1\n".repeat(1000));
        std::fs::write(&cut, &whole[..whole.len() / 2]).unwrap();
        let err = load(&cut, &opts).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!("{}: gzip: ", cut.display())),
            "{err}"
        );
    }

    #[test]
    fn names_replace_and_must_match_the_channel_count() {
        let opts = LoadOptions {
            rate_hz: Some(1.0),
            names: vec!["gx".into(), "gy".into()],
            ..LoadOptions::default()
        };
        let err = build(table(None), &opts).unwrap_err();
        assert!(
            err.to_string()
                .contains("--names gives 2 names but the file has 4")
        );
    }
}

//! `imunoise analyze INPUT`: Allan family with confidence intervals, PSD and IEEE-952 noise
//! terms for every channel of a record; a table on stdout, and on request JSON, a plot,
//! Kalibr's IMU YAML and a self-contained HTML report.

use crate::cli::output;
use crate::cli::settings::{accel_range, gyro_range};
use crate::cli::stored;
use anyhow::{Context, Result};
use imunoise::analysis::bounded::Bounded;
use imunoise::analysis::filter;
use imunoise::analysis::pipeline::{self, Bandwidth, ChannelResult, Options, Request};
use imunoise::analysis::psd::Window;
use imunoise::analysis::taus::TauGrid;
use imunoise::analysis::{DataType, Estimator};
use imunoise::input::{self, CountScale, LoadOptions, Loaded, NpyStream, ReadReport};
use imunoise::record::{Quantity, Record};
use imunoise::report;
use imunoise::report::filter::FilterFileError;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct AnalyzeArgs {
    /// A capture file, a text/CSV table (optional header, `#` comments, optional time column)
    /// or a NumPy .npy, either gzipped; a ROS bag (.bag, .mcap, a rosbag2 directory or its
    /// .db3; see --topic); or a stored session's id or name (an existing path wins)
    pub input: PathBuf,
    /// Correct a stored session with its board's newest calibrations first (in memory; the
    /// stored data are not altered)
    #[arg(long)]
    pub calibrated: bool,
    /// Memory the analysis may use, MB: an uncompressed .npy whose whole read would need
    /// more (about 5 times its samples' 8 bytes each) is analysed streamed, in bounded memory
    /// (oadev/ohdev, noise fit, Welch PSD; no line search). Default: half of the memory
    /// available
    #[arg(long, value_name = "MB")]
    pub memory_budget: Option<f64>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
}

/// How to read and analyse a record, and where to put the results: shared by `analyze` and
/// `replay`.
#[derive(clap::Args, Debug)]
pub struct AnalysisArgs {
    #[command(flatten)]
    pub read: ReadArgs,
    /// Whether the samples are rates (rad/s, m/s^2) or phase (integrated: rad, m/s)
    #[arg(long, value_enum, default_value_t = DataTypeArg::Rate)]
    pub data_type: DataTypeArg,
    /// Analyse only this channel (repeatable); default: every channel
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// Estimator (repeatable): oadev adev mdev hdev ohdev tdev totdev; default oadev
    #[arg(long = "estimator", value_name = "NAME")]
    pub estimators: Vec<Estimator>,
    /// Tau grid: octave, decade, all, or per-decade:K
    #[arg(long, default_value = "per-decade:10")]
    pub taus: TauGrid,
    /// Confidence of the intervals (two-sided)
    #[arg(long, default_value_t = 0.683)]
    pub confidence: f64,
    /// Shortest tau of the noise fit in seconds (default: every tau; with a low-pass fitted
    /// to the spectrum, from where its shape is reliable)
    #[arg(long, value_name = "SECONDS")]
    pub fit_tau_min: Option<f64>,
    /// The sensor's low-pass -3 dB bandwidth in Hz, modelled in the noise fit: an MPU-6050
    /// DLPF bandwidth at a rate the chip makes is its exact chain, any other a generic
    /// two-pole; `off` for none. Default: a capture's own settings, else fitted to the
    /// spectrum
    #[arg(long, value_name = "HZ|off", value_parser = parse_bandwidth)]
    pub bandwidth: Option<Bandwidth>,
    /// Welch segment length in samples (default: chosen from the record length)
    #[arg(long)]
    pub psd_segment: Option<usize>,
    /// Welch window: hann, hamming, blackman, rectangular
    #[arg(long, default_value = "hann")]
    pub psd_window: Window,
    /// Write the results as JSON to PATH (`-` for stdout, which then carries only the JSON)
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write the figures (Allan deviation and PSD, one row per sensor) to PATH.svg or PATH.png
    #[arg(long, value_name = "PATH")]
    pub plot: Option<PathBuf>,
    /// Write Kalibr's IMU noise YAML to PATH
    #[arg(long, value_name = "PATH")]
    pub kalibr: Option<PathBuf>,
    /// Write a self-contained HTML report to PATH
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
    /// Filter period dt in seconds: print continuous- and discrete-time process noise for a
    /// Kalman filter at that period (default with --filter: the sample period)
    #[arg(long, value_name = "SECONDS")]
    pub filter_period: Option<f64>,
    /// Write the filter noise parameters to PATH.json or PATH.yaml (repeatable)
    #[arg(long = "filter", value_name = "PATH")]
    pub filter: Vec<PathBuf>,
}

/// `--bandwidth`'s parser (a bandwidth in Hz or `off`).
pub fn parse_bandwidth(s: &str) -> Result<Bandwidth, String> {
    s.parse()
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum DataTypeArg {
    Rate,
    Phase,
}

fn parse_scale(s: &str) -> Result<(String, f64), String> {
    let (name, factor) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}': expected NAME=FACTOR, e.g. gx=0.001"))?;
    let factor: f64 = factor
        .parse()
        .map_err(|_| format!("'{s}': '{factor}' is not a number"))?;
    if !factor.is_finite() {
        return Err(format!("'{s}': the factor must be finite"));
    }
    Ok((name.to_string(), factor))
}

pub fn run(args: &AnalyzeArgs, store: Option<&Path>) -> Result<()> {
    args.analysis.check()?;
    let store_dir = imunoise::store::locate(store).ok();
    for (path, flag) in args.analysis.outputs() {
        output::check(path, flag, store_dir.as_deref(), &[&args.input])?;
    }
    if let Some(stream) = too_large(args)? {
        analyse_streamed(stream, &args.analysis)?;
        return Ok(());
    }
    let stored::Input {
        mut loaded,
        session,
    } = stored::load(&args.input, &args.analysis.read.load_options()?, store)?;
    if let Some((_, session)) = &session {
        for (path, flag) in args.analysis.outputs() {
            output::check(path, flag, None, &[&session.file])?;
        }
    }
    stored::print_notes(&loaded.notes);
    if args.calibrated {
        let Some((store, session)) = &session else {
            anyhow::bail!(
                "--calibrated: {} is a file; calibrations are kept per board and apply to stored sessions",
                args.input.display()
            );
        };
        crate::cli::calibrations::apply_latest(store, session, &mut loaded.record)?;
    }
    let analysed = analyse(loaded, &args.analysis)?;
    stored::keep_analysis(session.as_ref(), &analysed.options, &analysed.document)
}

/// Rows of a streamed record read at a time: about 1 MiB of samples.
const BLOCK_BYTES: usize = 1 << 20;

/// `--memory-budget` when not given: half of the memory available (MemAvailable in
/// /proc/meminfo), or 4096 MB where that cannot be read.
fn default_budget_mb() -> f64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
            let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kb / 1024.0 / 2.0)
        })
        .unwrap_or(4096.0)
}

/// Peak resident memory of a whole read and analysis over its samples' bytes, for the record
/// with the most lines: the analysis works in the samples' buffer, 1.48 measured on 10^7
/// samples of noise (`bench` section 1), but a record in which the line search finds
/// something is searched again on a copy and keeps its line-free copy beside it (3.3 measured
/// on 10^7 samples with one tone).
const WHOLE_READ_FACTOR: f64 = 4.0;

/// The input opened for streaming when it is an uncompressed .npy file whose whole read
/// ([`WHOLE_READ_FACTOR`] times its samples, 8 bytes each) would exceed the memory budget;
/// `None` reads it whole.
fn too_large(args: &AnalyzeArgs) -> Result<Option<NpyStream>> {
    let budget = args.memory_budget.unwrap_or_else(default_budget_mb);
    anyhow::ensure!(
        budget.is_finite() && budget > 0.0,
        "--memory-budget {budget}: a positive number of MB"
    );
    if args.calibrated || !args.input.is_file() {
        return Ok(None);
    }
    let Some(stream) = input::open_npy(&args.input, &args.analysis.read.load_options()?)? else {
        return Ok(None);
    };
    let mb = (stream.rows() * stream.record.channels.len()) as f64 * 8.0 / 1e6;
    let whole = mb * WHOLE_READ_FACTOR;
    if whole <= budget {
        return Ok(None);
    }
    eprintln!(
        "note: {}: the samples take {mb:.0} MB, and reading them whole about {whole:.0} MB, more than the memory budget ({budget:.0} MB): \
         analysed streamed, in bounded memory (a larger --memory-budget MB reads it whole)",
        args.input.display()
    );
    Ok(Some(stream))
}

/// [`analyse`] for a record read a block of rows at a time ([`bounded`]).
fn analyse_streamed(mut stream: NpyStream, args: &AnalysisArgs) -> Result<Analysed> {
    let rows = stream.rows();
    let all = stream
        .record
        .names()
        .iter()
        .map(|n| n.to_string())
        .collect::<Vec<_>>();
    let record = stream
        .record
        .clone()
        .select(&args.columns)
        .map_err(anyhow::Error::msg)?;
    let picked: Vec<usize> = record
        .channels
        .iter()
        .filter_map(|c| all.iter().position(|n| *n == c.name))
        .collect();
    if let Some(segment) = args.psd_segment {
        check_psd_segment(segment, Some(rows))?;
    }
    let options = request(args).options(None);
    let channels: Vec<(String, Quantity)> = record
        .channels
        .iter()
        .map(|c| (c.name.clone(), c.quantity))
        .collect();
    let mut analysis = Bounded::new(&channels, rows, record.rate_hz, &options)
        .with_context(|| record.source.clone())?;
    let block = (BLOCK_BYTES / (8 * all.len())).max(1);
    let mut columns = vec![Vec::new(); all.len()];
    let bar = crate::cli::progress::bar(rows as u64, "analysing");
    while stream.next_rows(block, &mut columns)? > 0 {
        let picked: Vec<&[f64]> = picked.iter().map(|&i| &columns[i][..]).collect();
        analysis
            .feed(&picked)
            .with_context(|| record.source.clone())?;
        bar.inc(columns[0].len() as u64);
    }
    let mut report = stream.report.clone();
    if args.columns.is_empty() {
        warn_left_out(analysis.leave_out_constant(), &mut report);
    }
    let results = analysis.finish().with_context(|| record.source.clone())?;
    bar.finish_and_clear();
    write_outputs(&record, options, &results, &report, args)
}

/// How to read a record: shared by every command that takes one (analyze, replay, model).
#[derive(clap::Args, Debug)]
pub struct ReadArgs {
    /// Sample rate in Hz (needed when the file has no time column and no rate in its header;
    /// overrides a time column)
    #[arg(long)]
    pub rate: Option<f64>,
    /// Ignore the file's time column: the rows are uniformly sampled at --rate
    #[arg(long)]
    pub ignore_time: bool,
    /// Channel names, comma-separated, for inputs without a header (e.g. gx,gy,gz,ax,ay,az)
    #[arg(long, value_delimiter = ',')]
    pub names: Vec<String>,
    /// The values are raw MPU-6050 counts: convert with --gyro-range and --accel-range
    #[arg(long)]
    pub counts: bool,
    /// Gyro full scale of the raw counts, deg/s (250, 500, 1000, 2000)
    #[arg(long, default_value_t = 250, requires = "counts")]
    pub gyro_range: u32,
    /// Accel full scale of the raw counts, g (2, 4, 8, 16)
    #[arg(long, default_value_t = 2, requires = "counts")]
    pub accel_range: u32,
    /// Multiply a channel by a factor, e.g. gx=0.001 (repeatable)
    #[arg(long, value_name = "NAME=FACTOR", value_parser = parse_scale)]
    pub scale: Vec<(String, f64)>,
    /// A capture with gaps, or a time column with samples missing: analyse the longest
    /// gap-free run (the losses are reported)
    #[arg(long)]
    pub longest_run: bool,
    /// A ROS bag's sensor_msgs/Imu topic (needed when the bag has several)
    #[arg(long)]
    pub topic: Option<String>,
}

impl ReadArgs {
    /// How to read the input, from the reading options.
    pub fn load_options(&self) -> Result<LoadOptions> {
        let counts = if self.counts {
            Some(CountScale {
                rad_s_per_lsb: gyro_range(self.gyro_range)?.rad_s_per_lsb(),
                m_s2_per_lsb: accel_range(self.accel_range)?.m_s2_per_lsb(),
            })
        } else {
            None
        };
        Ok(LoadOptions {
            rate_hz: self.rate,
            ignore_time: self.ignore_time,
            names: self.names.clone(),
            counts,
            scales: self.scale.clone(),
            longest_run: self.longest_run,
            topic: self.topic.clone(),
        })
    }
}

impl AnalysisArgs {
    /// The files the analysis writes, with their flags (`--json -` is stdout, not a file).
    pub fn outputs(&self) -> Vec<(&Path, &'static str)> {
        let mut out = Vec::new();
        if let Some(p) = self.json.as_deref().filter(|p| p.as_os_str() != "-") {
            out.push((p, "--json"));
        }
        let flags = [
            (&self.plot, "--plot"),
            (&self.kalibr, "--kalibr"),
            (&self.report, "--report"),
        ];
        out.extend(
            flags
                .into_iter()
                .filter_map(|(p, f)| p.as_deref().map(|p| (p, f))),
        );
        out.extend(self.filter.iter().map(|p| (p.as_path(), "--filter")));
        out
    }

    /// What can be checked before reading and analysing anything: every output's folder
    /// exists and its name picks a format this writes, the filter period and the PSD
    /// segment are in range (the segment against the record: [`check_psd_segment`]).
    pub fn check(&self) -> Result<()> {
        for (path, flag) in self.outputs() {
            output::check_folder(path, flag)?;
        }
        if let Some(path) = &self.plot {
            check_plot(path)?;
        }
        for path in &self.filter {
            report::filter::check_format(path).map_err(filter_error)?;
        }
        if let Some(period) = self.filter_period {
            filter::check_period(period)
                .map_err(|e| anyhow::anyhow!("--filter-period {period}: {e}"))?;
        }
        if let Some(segment) = self.psd_segment {
            check_psd_segment(segment, None)?;
        }
        Ok(())
    }
}

/// `--plot PATH`: its folder exists and its extension names a format the figures are
/// written in.
pub fn check_plot(path: &Path) -> Result<()> {
    output::check_folder(path, "--plot")?;
    report::plot::check_format(path).map_err(|e| anyhow::anyhow!("--plot {e}"))?;
    Ok(())
}

/// `--psd-segment`: a Welch segment holds at least 2 samples and at most the record's
/// (`samples`, when known).
pub fn check_psd_segment(segment: usize, samples: Option<usize>) -> Result<()> {
    let most = samples.map_or(String::new(), |n| format!("{n}, "));
    anyhow::ensure!(
        segment >= 2 && samples.is_none_or(|n| segment <= n),
        "--psd-segment {segment}: a segment length in samples, from 2 to {most}the record's length"
    );
    Ok(())
}

/// An analysis done: its JSON document and the options that made it (kept with a session).
pub struct Analysed {
    pub document: serde_json::Value,
    pub options: Options,
}

/// Analyse a record as `args` ask and write every requested output; returns the JSON
/// document (whether or not it was written). The input's sensor settings (a capture's) give
/// the low-pass filter the fit models unless `--bandwidth` says otherwise; how it was read
/// (time base, units) is shown with the results.
pub fn analyse(loaded: Loaded, args: &AnalysisArgs) -> Result<Analysed> {
    let Loaded {
        record,
        settings,
        report: mut read,
        ..
    } = loaded;
    let mut record = record.select(&args.columns).map_err(anyhow::Error::msg)?;
    if args.columns.is_empty() {
        warn_left_out(record.leave_out_constant(), &mut read);
    }
    if let Some(segment) = args.psd_segment {
        check_psd_segment(segment, Some(record.len()))?;
    }
    let options = request(args).options(settings);
    let steps = record.channels.len() * pipeline::steps_per_channel(&options);
    let bar = crate::cli::progress::bar(steps as u64, "analysing");
    // The samples are given up to the analysis, which works in their buffers; the outputs
    // need only the record's name and rate.
    let results = pipeline::analyze_taking(&mut record, &options, &|| bar.inc(1))
        .with_context(|| record.source.clone())?;
    bar.finish_and_clear();
    write_outputs(&record, options, &results, &read, args)
}

/// The warnings for channels left out of an analysis: on stderr now, and in the read
/// report the outputs carry.
fn warn_left_out(left_out: Vec<String>, report: &mut ReadReport) {
    stored::print_warnings(&left_out);
    report.warnings.extend(left_out);
}

/// Print and write everything `args` ask for from `results`; the JSON document.
fn write_outputs(
    record: &Record,
    options: Options,
    results: &[ChannelResult],
    read: &ReadReport,
    args: &AnalysisArgs,
) -> Result<Analysed> {
    for warning in report::table::fit_warnings(results) {
        eprintln!("warning: {warning}");
    }
    let mut document = report::json::document(record, &options, results);
    document["input"] = serde_json::to_value(read)?;
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    if !json_to_stdout {
        read.lines().iter().for_each(|line| println!("{line}"));
        print!("{}", report::table::render(record, &options, results));
    }
    if args.filter_period.is_some() || !args.filter.is_empty() {
        let period = args.filter_period.unwrap_or(1.0 / record.rate_hz);
        let filters = filter::for_channels(results, period)
            .map_err(|e| anyhow::anyhow!("--filter-period {period}: {e}"))?;
        let filter_document = report::filter::document(record, &filters);
        if !json_to_stdout {
            print!("{}", report::filter::render(&filters));
        }
        for path in &args.filter {
            let text = report::filter::file_text(path, &filter_document).map_err(filter_error)?;
            write(path, &text)?;
            note(json_to_stdout, path, "filter noise parameters");
        }
        document["filter"] = filter_document;
    }
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&document)?;
        if json_to_stdout {
            println!("{text}");
        } else {
            write(path, &text)?;
        }
    }
    if let Some(path) = &args.plot {
        report::plot::write(path, &report::figures::figures(results))?;
        note(json_to_stdout, path, "figures");
    }
    if let Some(path) = &args.kalibr {
        let yaml = report::kalibr::yaml(record, results).map_err(anyhow::Error::msg)?;
        write(path, &yaml)?;
        note(json_to_stdout, path, "Kalibr IMU YAML");
    }
    if let Some(path) = &args.report {
        write(path, &report::html::page(record, &options, results)?)?;
        note(json_to_stdout, path, "HTML report");
    }
    Ok(Analysed { document, options })
}

/// The library's request for the analysis `args` ask for.
fn request(args: &AnalysisArgs) -> Request {
    Request {
        data_type: match args.data_type {
            DataTypeArg::Rate => DataType::Rate,
            DataTypeArg::Phase => DataType::Phase,
        },
        estimators: args.estimators.clone(),
        taus: args.taus,
        confidence: args.confidence,
        fit_tau_min: args.fit_tau_min,
        bandwidth: args.bandwidth,
        psd_segment: args.psd_segment,
        psd_window: args.psd_window,
    }
}

/// A `--filter` file's error, the flag named where the file name is at fault.
fn filter_error(e: FilterFileError) -> anyhow::Error {
    match e {
        FilterFileError::Format(_) => anyhow::anyhow!("--filter {e}"),
        e => e.into(),
    }
}

fn write(path: &std::path::Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Say where an output went (stderr when stdout carries JSON).
fn note(to_stderr: bool, path: &std::path::Path, what: &str) {
    let line = format!("wrote {what}: {}", path.display());
    if to_stderr {
        eprintln!("{line}");
    } else {
        println!("{line}");
    }
}

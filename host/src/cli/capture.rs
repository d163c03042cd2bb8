//! `imunoise capture`: record a session from a board's byte stream into the store, with a
//! live count of samples and losses and a live view of the noise ([`super::live_view`]);
//! Ctrl-C ends it cleanly, and `--until` ends it once the noise terms are known well enough.
//!
//! The source is a [`Link`]; `open_link` is the one place a source plugs in: a serial port
//! (`--port /dev/ttyACM0`), the virtual board (`--port sim`: the firmware's own code on the
//! simulated MPU-6050), or a capture file replayed (`--from-file`). A board is handshaken
//! (protocol version), configured and started; the file then holds its `Info`, the acks and
//! every sample batch, exactly as they arrived.

use crate::cli::live_view::{LiveView, Mode};
use crate::cli::settings::{accel_range, gyro_range};
use crate::cli::simulate::parse_duration;
use crate::cli::stored::open_store;
use anyhow::{Context, Result, anyhow, bail};
use imunoise::analysis::precision::StopRule;
use imunoise::link::board::{Board, BoardError};
use imunoise::link::plan::streamable;
use imunoise::link::plan::{Plan, PlanError, Request};
use imunoise::link::replay::{ReplayLink, Speed};
use imunoise::link::setup::{SimulatedBoard, StartError, VIRTUAL_PORT, start_board_for};
use imunoise::link::{self, Link, Opened, PortSpec};
use imunoise::recorder::live::{LiveOptions, RuleAxes};
use imunoise::recorder::{self, Ending, Progress, RecordOptions};
use indicatif::{ProgressBar, ProgressStyle};
use protocol::SensorSettings;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(clap::Args, Debug)]
pub struct CaptureArgs {
    /// The board: a serial port (`imunoise ports` lists them) or `sim` for the virtual board
    #[arg(
        long,
        required_unless_present = "from_file",
        conflicts_with = "from_file"
    )]
    pub port: Option<String>,
    /// Replay this capture file as if a board were sending it (demos, tests)
    #[arg(long, value_name = "FILE")]
    pub from_file: Option<PathBuf>,
    /// Output rate in Hz (with --port), e.g. 200
    #[arg(
        long,
        requires = "port",
        required_unless_present = "from_file",
        allow_negative_numbers = true
    )]
    pub rate: Option<f64>,
    /// DLPF bandwidth in Hz (with --port): gyro 256 188 98 42 20 10 5 or accel 260 184 94 44 21 10 5
    #[arg(long, requires = "port", required_unless_present = "from_file")]
    pub bandwidth: Option<f64>,
    /// Gyro full scale in deg/s: 250, 500, 1000 or 2000
    #[arg(long, default_value_t = 250)]
    pub gyro_range: u32,
    /// Accel full scale in g: 2, 4, 8 or 16
    #[arg(long, default_value_t = 2)]
    pub accel_range: u32,
    /// Speed of the virtual board or of a replay: max, or a factor (1 = real time)
    #[arg(long, default_value = "1")]
    pub speed: Speed,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
    #[command(flatten)]
    pub sim_board: SimBoardArgs,
    /// Session name (default: YYYYmmdd-HHMMSS-<rate>hz-<bandwidth>hz, UTC)
    #[arg(long)]
    pub name: Option<String>,
    /// A note kept with the session
    #[arg(long)]
    pub note: Option<String>,
    /// Stop after this much data: 2h, 30m, 90s (default: until the source ends or Ctrl-C)
    #[arg(long)]
    pub duration: Option<String>,
    #[command(flatten)]
    pub stop: StopRuleArgs,
    /// Live view as JSON lines on stdout (one object per update, and one at the end)
    #[arg(long)]
    pub json_progress: bool,
}

/// The stop rule and the live view's confidence, shared by `capture` and `sweep`.
#[derive(clap::Args, Debug)]
pub struct StopRuleArgs {
    /// Stop once each named term's interval half-width on every axis of --until-axes is
    /// within this fraction of its value, as `analyze` computes it: N:1%,B:20%,K:30%
    /// (--duration stays the cap; in a sweep, per setting)
    #[arg(long, value_name = "RULE")]
    pub until: Option<StopRule>,
    /// The axes the stop rule applies to: gyro, accel, all, or a list such as gz,az
    #[arg(long, value_name = "AXES", default_value = "gyro", requires = "until")]
    pub until_axes: RuleAxes,
    /// Confidence of the intervals the stop rule and the live view use (as analyze's)
    #[arg(long, default_value_t = 0.683)]
    pub confidence: f64,
}

impl StopRuleArgs {
    /// The live view's options: the rule on its axes, its confidence, and the Allan
    /// ladder's end (the cap `duration_s`, or a week).
    pub fn live_options(&self, duration_s: Option<f64>) -> Result<LiveOptions> {
        let confidence = self.confidence;
        if !(confidence > 0.0 && confidence < 1.0) {
            bail!("--confidence {confidence}: between 0 and 1 (e.g. 0.683, 0.95)");
        }
        Ok(LiveOptions {
            rule: self.until.clone(),
            rule_axes: self.until_axes.clone(),
            confidence,
            longest_s: duration_s.unwrap_or(7.0 * 86400.0),
        })
    }
}

/// Which sensors the virtual board carries (`--port sim`): `capture`, `sweep` and `info`
/// (the calibration commands are the MPU-6050's).
#[derive(clap::Args, Debug)]
pub struct SimBoardArgs {
    /// The virtual board's sensors: an MPU-6050, or a GY-85 (ITG-3200 + ADXL345) whose gyro
    /// takes --rate and --bandwidth and whose accelerometer runs at the same rate
    #[arg(long, value_enum, default_value_t = SimulatedBoard::Mpu6050)]
    pub board: SimulatedBoard,
}

/// The virtual board's options (`--port sim`), shared by `capture` and `sweep`.
#[derive(clap::Args, Debug)]
pub struct VirtualBoardArgs {
    /// The virtual board's noise model (default: the built-in examples/mpu6050.toml)
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// The virtual board's random seed
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Open a board's port (a serial port, or `sim` for the virtual board); the virtual
/// board's sensor failing to start is said, as the board's own log would.
pub fn open_port(spec: &PortSpec) -> Result<Opened> {
    let opened = link::open(spec)?;
    if let Some(e) = opened.boot_error {
        eprintln!("note: the virtual board's sensor did not start: {e}");
    }
    Ok(opened)
}

/// The link the arguments name.
fn open_link(args: &CaptureArgs) -> Result<Box<dyn Link>> {
    match (&args.port, &args.from_file) {
        (Some(port), _) => Ok(open_port(&PortSpec {
            port,
            board: args.sim_board.board,
            speed: args.speed,
            model: args.virtual_board.model.as_deref(),
            seed: args.virtual_board.seed,
        })?
        .link),
        (None, Some(path)) => Ok(Box::new(
            ReplayLink::open(path, args.speed)
                .with_context(|| format!("--from-file {}", path.display()))?,
        )),
        (None, None) => bail!("give a source: --port PORT (or sim) or --from-file FILE"),
    }
}

/// The settings a board is asked for (`--rate`, `--bandwidth`, `--gyro-range`,
/// `--accel-range`): the sensor's registers for them, within what the firmware streams.
pub fn board_settings(
    rate_hz: f64,
    bandwidth_hz: f64,
    gyro_range_dps: u32,
    accel_range_g: u32,
) -> Result<SensorSettings> {
    let settings = SensorSettings::for_rate_and_bandwidth(rate_hz, bandwidth_hz)
        .map_err(|e| anyhow!("--rate {rate_hz} --bandwidth {bandwidth_hz}: {e}"))?;
    streamable(settings.output_rate_hz()).map_err(|e| anyhow!("--rate {rate_hz}: {e}"))?;
    Ok(settings.with_ranges(gyro_range(gyro_range_dps)?, accel_range(accel_range_g)?))
}

/// Stop a board after a capture; a board that is gone is reported, not an error (the
/// session already says how it ended).
pub fn stop_board(link: &mut dyn Link) {
    if let Err(e) = Board::new(link).stop() {
        stop_failed(&e);
    }
}

/// What a board that did not take Stop after a capture is told as.
pub fn stop_failed(e: &BoardError) {
    eprintln!("note: could not stop the board: {e}");
}

/// A flag that Ctrl-C raises instead of killing the process: the capture loop then ends its
/// session cleanly (complete, "interrupted by the user"). Once per process.
pub fn stop_on_ctrl_c() -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    Ok(stop)
}

pub fn run(args: &CaptureArgs, store: Option<&Path>) -> Result<()> {
    let duration_s = args
        .duration
        .as_deref()
        .map(parse_duration)
        .transpose()
        .map_err(|e| anyhow!("--duration: {e}"))?;
    let live = args.stop.live_options(duration_s)?;
    let request = match (args.rate, args.bandwidth) {
        (Some(rate_hz), Some(bandwidth_hz)) => Some(Request {
            rate_hz,
            bandwidth_hz,
            gyro_range: gyro_range(args.gyro_range)?,
            accel_range: accel_range(args.accel_range)?,
        }),
        _ => None,
    };
    // The virtual board's sensors are known: its settings are checked before anything opens.
    if let (Some(request), Some(port)) = (&request, &args.port)
        && port == VIRTUAL_PORT
    {
        Plan::for_kinds(request, args.sim_board.board.sensors())
            .map_err(|e| request_error(request, e))?;
    }
    let mut link = open_link(args)?;
    let mut watch = None;
    // A real board says what it carries when asked: the store opens once it took its
    // settings, so that a refused request leaves nothing behind.
    if let Some(request) = request {
        let (info, plan) = start_board_for(link.as_mut(), &request).map_err(|e| match e {
            StartError::Plan { source, .. } => request_error(&request, source),
            e => e.into(),
        })?;
        eprintln!(
            "{}: board {:016x}, firmware {}, protocol {}, {}; capturing {plan}",
            link.describe(),
            info.board_id,
            info.firmware_version,
            info.protocol_version,
            sensor_names(&info.sensor_list())
        );
        watch = args.port.is_some().then_some(plan);
    }
    let store = match open_store(store) {
        Ok(store) => store,
        Err(e) => {
            if args.port.is_some() {
                stop_board(link.as_mut());
            }
            return Err(e);
        }
    };
    let stop = stop_on_ctrl_c()?;
    let options = RecordOptions {
        name: args.name.clone(),
        notes: args.note.clone(),
        duration_s,
        keep_samples: false,
        watch,
        live: Some(live),
    };
    let mode = Mode::choose(args.json_progress);
    let (mut view, bar) = LiveView::new(mode, &progress_bar());
    let outcome = recorder::record(link.as_mut(), &store, &options, &stop, &mut |p| {
        show(&bar, p);
        if let Some(s) = &p.live {
            view.show(s);
        }
    });
    view.finish();
    bar.finish_and_clear();
    if args.port.is_some() {
        stop_board(link.as_mut());
    }
    let outcome = outcome?;
    let session = store
        .get(outcome.session_id)?
        .ok_or_else(|| anyhow!("session {} vanished from the catalog", outcome.session_id))?;
    let c = &outcome.counts;
    if mode == Mode::Json {
        let end = serde_json::json!({
            "event": "end",
            "session": session.id,
            "name": session.name,
            "state": session.state.as_str(),
            "end_reason": session.end_reason,
            "counts": c,
        });
        println!("{end}");
    }
    let summary = format!(
        "session {} '{}' {}: {} samples received, {} lost in {} gap(s), {} restart(s), {} damaged frame(s); {} bytes in {}",
        session.id,
        session.name,
        session.state_text(),
        c.samples_received,
        c.samples_lost,
        c.gaps,
        c.restarts,
        c.frames_rejected,
        c.bytes,
        session.file.display()
    );
    // With JSON lines on stdout, the human summary goes to stderr.
    if mode == Mode::Json {
        eprintln!("{summary}");
    } else {
        println!("{summary}");
    }
    let board_errors = outcome.capture.as_ref().map_or(0, |c| c.board_errors.len());
    let recoveries = outcome
        .capture
        .as_ref()
        .map_or(0, |c| c.recoveries().count());
    if board_errors > 0 {
        println!(
            "the board reported {board_errors} error(s) and recovered {recoveries} time(s): `imunoise show {}` lists them",
            session.id
        );
    }
    match outcome.ending {
        Ending::LinkFailed(e) => Err(anyhow!(
            "{}: {e}; session {} kept as incomplete",
            link.describe(),
            session.id
        )),
        _ => Ok(()),
    }
}

/// A request a board's sensors cannot take, named by the options that made it.
fn request_error(request: &Request, e: PlanError) -> anyhow::Error {
    match e {
        PlanError::NotStreamable { .. } => anyhow!("--rate {}: {e}", request.rate_hz),
        e => anyhow!(
            "--rate {} --bandwidth {}: {e}",
            request.rate_hz,
            request.bandwidth_hz
        ),
    }
}

/// The sensors a board lists, in words: "MPU-6050", "ITG-3200 + ADXL345".
pub fn sensor_names(sensors: &protocol::SensorList) -> String {
    let names: Vec<&str> = sensors.iter().map(|s| s.kind.name()).collect();
    match names.is_empty() {
        true => "no sensor found".to_string(),
        false => names.join(" + "),
    }
}

pub(crate) fn progress_bar() -> ProgressBar {
    let bar = ProgressBar::new(0);
    if let Ok(style) =
        ProgressStyle::with_template("capturing [{bar:30}] {elapsed} (eta {eta}) {msg}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Elapsed and remaining time, samples, losses and data rate; the board's errors and
/// recoveries and a catalog warning above the bar as they come.
pub(crate) fn show(bar: &ProgressBar, p: &Progress) {
    for e in &p.new_board_errors {
        bar.println(format!("board: {e}"));
    }
    for r in &p.new_recoveries {
        bar.println(format!("board: {r}"));
    }
    if let Some(w) = &p.catalog_warning {
        bar.println(format!("warning: {w}"));
    }
    if let Some(wanted) = p.samples_wanted {
        bar.set_length(wanted);
    }
    bar.set_position(p.samples_expected);
    let secs = p.elapsed.as_secs_f64().max(1e-3);
    bar.set_message(format!(
        "{} samples, {} lost, {} damaged frames, {:.1} kB/s",
        p.counts.samples_received,
        p.counts.samples_lost,
        p.counts.frames_rejected,
        p.counts.bytes as f64 / secs / 1e3
    ));
}

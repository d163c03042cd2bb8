//! The live view and the stop rule while recording: the samples the decoder takes
//! ([`StreamDecoder::tap`]) are fed, in SI units, into [`Live`] accumulators for the six
//! axes, in memory that does not grow with the capture; snapshots go out with the progress
//! reports; and when a snapshot says the stop rule is met on every axis it applies to (the
//! gyro's by default, [`RuleAxes`]), `analyze`'s
//! own pipeline confirms it on the session file's current run before the capture stops, so
//! the stored session shows the precision asked for.
//!
//! A gap or a board restart begins a new run: the accumulators start over with it, as
//! `analyze` of a session with gaps works on one gap-free run.

use crate::analysis::fit::FitOptions;
use crate::analysis::live::{Live, Snapshot};
use crate::analysis::low_pass::LowPass;
use crate::analysis::pipeline::{self, KnownFilters, LowPassChoice, Options};
use crate::analysis::precision::{Status, StopRule};
use crate::capture::{Capture, StreamDecoder};
use crate::record::Record;
use crate::sim::dlpf::Sensor;
use protocol::{RawSample, SensorConfig};
use std::path::Path;
use std::time::{Duration, Instant};

/// The axes the accumulators follow, in [`crate::capture`]'s record order.
pub const AXES: [&str; 6] = ["gx", "gy", "gz", "ax", "ay", "az"];

/// One sensor's accumulators: the axes it measures, in SI units, with its own filter.
struct SensorLive {
    /// The run the accumulators follow (its number, [`StreamDecoder::take_tapped_of`]).
    run: usize,
    live: Option<Live>,
}

impl SensorLive {
    fn feed(&mut self, config: &SensorConfig, run: usize, samples: &[RawSample], longest_s: f64) {
        let axes = LiveAxes::of(config);
        if run != self.run || self.live.is_none() {
            let tau0 = 1.0 / config.output_rate_hz();
            self.live = Live::new(&axes.names, tau0, longest_s).ok();
            if let Some(live) = self.live.as_mut() {
                let filters = KnownFilters::of(&[*config]);
                for (i, name) in axes.names.iter().enumerate() {
                    let (settings, sensor) = match name.starts_with('g') {
                        true => (filters.gyro, Sensor::Gyro),
                        false => (filters.accel, Sensor::Accel),
                    };
                    live.set_low_pass(i, settings.and_then(|s| LowPass::mpu6050(&s, sensor)));
                }
            }
            self.run = run;
        }
        let Some(live) = self.live.as_mut() else {
            return;
        };
        let mut values = [0.0; AXES.len()];
        for s in samples {
            let n = axes.values(s, &mut values);
            live.push(&values[..n]);
        }
    }
}

/// What a sensor gives the live view: its axes' names and values in SI units. Their
/// filters are the board's DLPF, as `analyze` models it for a stored session.
struct LiveAxes {
    names: Vec<&'static str>,
    /// Per axis: gyro (true) or accel, the axis (0..3), SI units per count.
    scales: Vec<(bool, usize, f64)>,
}

impl LiveAxes {
    fn of(config: &SensorConfig) -> LiveAxes {
        let (gyro_lsb, accel_lsb) = match config {
            SensorConfig::Mpu6050(s) => (
                Some(s.gyro_range.rad_s_per_lsb()),
                Some(s.accel_range.m_s2_per_lsb()),
            ),
            SensorConfig::Itg3200(_) => (Some(protocol::itg3200::rad_s_per_lsb()), None),
            SensorConfig::Adxl345(_) => (None, Some(protocol::adxl345::m_s2_per_lsb())),
        };
        let gyro = gyro_lsb.map(|lsb| (true, &AXES[..3], lsb));
        let accel = accel_lsb.map(|lsb| (false, &AXES[3..], lsb));
        let mut axes = LiveAxes {
            names: Vec::new(),
            scales: Vec::new(),
        };
        for (is_gyro, names, lsb) in gyro.into_iter().chain(accel) {
            for (i, name) in names.iter().enumerate() {
                axes.names.push(name);
                axes.scales.push((is_gyro, i, lsb));
            }
        }
        axes
    }

    /// One sample's axes in SI units into `out`; how many there are.
    fn values(&self, r: &RawSample, out: &mut [f64; AXES.len()]) -> usize {
        for (v, &(is_gyro, i, lsb)) in out.iter_mut().zip(&self.scales) {
            let counts = if is_gyro { r.gyro[i] } else { r.accel[i] };
            *v = f64::from(counts) * lsb;
        }
        self.scales.len()
    }
}

/// The axes a stop rule applies to: `gyro` (gx, gy, gz; the default), `accel` (ax, ay, az),
/// `all`, or a comma-separated list of axes (`gz,az`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RuleAxes(Vec<&'static str>);

impl Default for RuleAxes {
    fn default() -> Self {
        RuleAxes(AXES[..3].to_vec())
    }
}

impl RuleAxes {
    pub fn contains(&self, axis: &str) -> bool {
        self.0.contains(&axis)
    }

    pub fn names(&self) -> &[&'static str] {
        &self.0
    }
}

/// A `--until-axes` value that names no axis.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}': axes are gyro, accel, all or a list of gx, gy, gz, ax, ay, az (e.g. gz,az)")]
pub struct RuleAxesError(pub String);

impl std::str::FromStr for RuleAxes {
    type Err = RuleAxesError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let axes: Vec<&'static str> = match s.trim() {
            "gyro" => AXES[..3].to_vec(),
            "accel" => AXES[3..].to_vec(),
            "all" => AXES.to_vec(),
            list => {
                let mut axes = Vec::new();
                for part in list.split(',').map(str::trim) {
                    let axis = AXES
                        .iter()
                        .find(|a| **a == part)
                        .ok_or_else(|| RuleAxesError(part.to_string()))?;
                    if !axes.contains(axis) {
                        axes.push(*axis);
                    }
                }
                axes
            }
        };
        Ok(RuleAxes(axes))
    }
}

impl std::fmt::Display for RuleAxes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0.join(","))
    }
}

/// Snapshots at least this often on the host's clock, so a real-time view updates.
const WALL_EVERY: Duration = Duration::from_secs(3);
/// And whenever the sample time has grown by this fraction (at least [`SAMPLE_EVERY_S`]),
/// so a capture at full speed is checked often enough to stop within 2 % of the length
/// the rule needs.
const SAMPLE_GROWTH: f64 = 0.02;
const SAMPLE_EVERY_S: f64 = 10.0;
/// After `analyze`'s pipeline disagreed with a snapshot, the next confirmation waits until
/// the record has grown by this fraction: the pipeline reads the whole session file.
const CONFIRM_GROWTH: f64 = 0.1;

/// What to watch.
#[derive(Debug, Clone)]
pub struct LiveOptions {
    /// Stop when every target is met on every axis of `rule_axes`.
    pub rule: Option<StopRule>,
    pub rule_axes: RuleAxes,
    /// Confidence of the intervals (as `analyze --confidence`).
    pub confidence: f64,
    /// The longest record expected (the capture's duration cap), s: the Allan ladder's end.
    pub longest_s: f64,
}

/// Why the rule stopped the capture: each rule axis's targets as `analyze` computed them.
#[derive(Debug, Clone)]
pub struct RuleMet {
    pub rule: StopRule,
    pub axes: Vec<(String, Vec<Status>)>,
}

impl RuleMet {
    /// One line for the session's end reason: `stop rule N:1% met (gx N 0.93 %, ...)`.
    pub fn describe(&self) -> String {
        let axes: Vec<String> = self
            .axes
            .iter()
            .map(|(axis, statuses)| axis_text(axis, statuses))
            .collect();
        format!("stop rule {} met ({})", self.rule, axes.join("; "))
    }
}

/// The end reason of a capture whose duration came before its stop rule was met: the
/// precision the last snapshot showed on each axis of the rule.
pub fn unmet(rule: &StopRule, last: Option<&Snapshot>) -> String {
    let axes: Vec<String> = last
        .map(|s| {
            s.channels
                .iter()
                .filter(|c| !c.targets.is_empty())
                .map(|c| {
                    let statuses: Vec<Status> = c.targets.iter().map(|t| t.status).collect();
                    axis_text(&c.name, &statuses)
                })
                .collect()
        })
        .unwrap_or_default();
    if axes.is_empty() {
        format!("duration reached before stop rule {rule} was met")
    } else {
        format!(
            "duration reached before stop rule {rule} was met ({})",
            axes.join("; ")
        )
    }
}

/// `gx N 0.930 % B 18.700 %`: the precision reached per term on one axis.
fn axis_text(axis: &str, statuses: &[Status]) -> String {
    let terms: Vec<String> = statuses
        .iter()
        .map(|s| {
            let reached = if s.reached.is_finite() {
                format!("{:.3} %", 100.0 * s.reached)
            } else {
                "undetected".to_string()
            };
            format!("{} {reached}", s.target.term)
        })
        .collect();
    format!("{axis} {}", terms.join(" "))
}

pub(super) struct Watcher {
    options: LiveOptions,
    fit: FitOptions,
    /// One per sensor of the board, by number.
    sensors: Vec<SensorLive>,
    next_sample_s: f64,
    last_wall: Instant,
    /// No confirmation before this much sample time (see [`CONFIRM_GROWTH`]).
    next_confirm_s: f64,
}

impl Watcher {
    pub(super) fn new(options: LiveOptions) -> Watcher {
        let fit = FitOptions {
            confidence: options.confidence,
            ..FitOptions::default()
        };
        Watcher {
            options,
            fit,
            sensors: Vec::new(),
            next_sample_s: SAMPLE_EVERY_S,
            last_wall: Instant::now(),
            next_confirm_s: 0.0,
        }
    }

    /// Feed what the decoder took since the last call; a snapshot when one is due.
    pub(super) fn after_feed(&mut self, decoder: &mut StreamDecoder) -> Option<Snapshot> {
        let configs = decoder.configs();
        self.sensors
            .resize_with(configs.len(), || SensorLive { run: 0, live: None });
        for (k, (sensor, config)) in self.sensors.iter_mut().zip(configs).enumerate() {
            let (Some(config), Some((number, samples))) = (config, decoder.take_tapped_of(k))
            else {
                continue;
            };
            sensor.feed(&config, number, &samples, self.options.longest_s);
        }
        let lives: Vec<&Live> = self
            .sensors
            .iter()
            .filter_map(|s| s.live.as_ref())
            .collect();
        let elapsed = lives.iter().map(|l| l.elapsed_s()).reduce(f64::min)?;
        if elapsed < self.next_sample_s && self.last_wall.elapsed() < WALL_EVERY {
            return None;
        }
        self.next_sample_s = (elapsed * (1.0 + SAMPLE_GROWTH)).max(elapsed + SAMPLE_EVERY_S);
        self.last_wall = Instant::now();
        let rule = self.options.rule.as_ref();
        let axes = self.options.rule_axes.names();
        let mut snapshots = lives.iter().map(|l| l.snapshot(rule, axes, &self.fit));
        let mut all = snapshots.next()?;
        for other in snapshots {
            all.elapsed_s = all.elapsed_s.min(other.elapsed_s);
            all.channels.extend(other.channels);
        }
        all.channels
            .sort_by_key(|c| AXES.iter().position(|a| *a == c.name));
        Some(all)
    }

    /// Whether `snapshot` meets the rule and a confirmation is due (see [`CONFIRM_GROWTH`]):
    /// the caller then flushes the session file for [`Watcher::confirm`].
    pub(super) fn wants_confirmation(&self, snapshot: &Snapshot) -> bool {
        self.options.rule.is_some()
            && snapshot.rule_met()
            && snapshot.elapsed_s >= self.next_confirm_s
    }

    /// After [`Watcher::wants_confirmation`]: `analyze`'s pipeline on the rule's axes of the
    /// last gap-free run in the session file at `path` (flushed), with the options `analyze`
    /// uses for a stored session (the board's own filter, 10 factors per decade, spectral
    /// lines removed), and the verdict if it agrees.
    pub(super) fn confirm(&mut self, snapshot: &Snapshot, path: &Path) -> Option<RuleMet> {
        let rule = self.options.rule.as_ref()?;
        self.next_confirm_s = snapshot.elapsed_s * (1.0 + CONFIRM_GROWTH);
        let capture = Capture::decode(&std::fs::read(path).ok()?).ok()?;
        // The sensor that measures the rule's axes (the gyro on every board we know).
        let (sensor, run, full) = capture
            .sensors
            .iter()
            .filter_map(|s| {
                let run = s.runs.last()?;
                Some((s, run, capture.run_record(s, run, "capture")))
            })
            .max_by_key(|(_, _, r)| {
                r.channels
                    .iter()
                    .filter(|c| self.options.rule_axes.contains(&c.name))
                    .count()
            })?;
        let settings = KnownFilters::of(&[sensor.config_of(run)]);
        let record = Record {
            channels: full
                .channels
                .into_iter()
                .filter(|c| self.options.rule_axes.contains(&c.name))
                .collect(),
            ..full
        };
        let options = Options {
            confidence: self.options.confidence,
            low_pass: LowPassChoice::Sensor(settings),
            ..Options::default()
        };
        let results = pipeline::analyze(&record, &options, &|| {}).ok()?;
        let mut axes = Vec::new();
        for r in &results {
            let fit = r.fit.as_ref().ok()?;
            let statuses = rule.status(fit);
            if !statuses.iter().all(|s| s.met) {
                return None;
            }
            axes.push((r.name.clone(), statuses));
        }
        Some(RuleMet {
            rule: rule.clone(),
            axes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{RuleAxes, RuleAxesError};

    #[test]
    fn rule_axes_parse_by_sensor_and_by_name() {
        let names = |s: &str| s.parse::<RuleAxes>().map(|a| a.names().to_vec());
        assert_eq!(names("gyro"), Ok(vec!["gx", "gy", "gz"]));
        assert_eq!(names("accel"), Ok(vec!["ax", "ay", "az"]));
        assert_eq!(names("all").unwrap().len(), 6);
        assert_eq!(names("gz, az,gz"), Ok(vec!["gz", "az"]));
        assert_eq!(RuleAxes::default().to_string(), "gx,gy,gz");
        assert_eq!(names("gz,temp"), Err(RuleAxesError("temp".into())));
        assert_eq!(names(""), Err(RuleAxesError(String::new())));
    }
}

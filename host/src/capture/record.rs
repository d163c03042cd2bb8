//! A capture's samples as a [`Record`] in SI units: each sensor's counts converted with its
//! own settings and chip, and the sensors of a board side by side.
//!
//! **Channels by sensor kind.** An MPU-6050 gives `gx gy gz ax ay az temp`; an ITG-3200
//! `gx gy gz temp`; an ADXL345 `ax ay az`. A GY-85 board's record is `gx gy gz ax ay az
//! temp` like an MPU-6050's.
//!
//! **Several sensors, one record.** A record has one rate and rows of simultaneous samples,
//! but each sensor runs on its own clock and numbers its own samples. So the sensors must
//! have the same nominal output rate (else [`CaptureError::RatesDiffer`]). Of the run read of
//! each (all of it, or its longest gap-free run), row `k` pairs the samples made nearest one
//! moment: each sensor's first row is its sample nearest (within half a period of) the
//! latest first sample of them all, and the rows end where the shortest run does. What that
//! leaves out is counted ([`SensorRecord::trimmed`]) and shown by the readers, never dropped
//! silently. The chips' clocks differ by up to their tolerance (a few 0.1 %), so the pairs
//! drift apart by that fraction of the record's length: immaterial for the noise terms (each
//! channel is analysed alone) and for a temperature regression on slow drift.

use super::stream::{Run, SensorCapture};
use super::{Capture, CaptureError};
use crate::record::{Channel, Record};
use protocol::mpu6050::{SensorSettings, chip_or_mpu6050};
use protocol::{RawSample, SensorConfig, SensorKind, adxl345, itg3200};

/// The canonical order of a board's channels.
const ORDER: [&str; 7] = ["gx", "gy", "gz", "ax", "ay", "az", "temp"];

/// What one sensor gave a record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorRecord {
    pub kind: SensorKind,
    /// Samples of the run read that the record holds.
    pub used: usize,
    /// Samples of the run read left out to line the sensors up (0 for one sensor).
    pub trimmed: usize,
}

impl Capture {
    /// The samples as a record in SI units ([`record`](crate::capture::record)'s docs): all of them if
    /// no sensor has a gap or a restart, else an error (or, with `longest_run`, each
    /// sensor's longest gap-free run).
    pub fn to_record(&self, source: &str, longest_run: bool) -> Result<Record, CaptureError> {
        self.to_record_with(source, longest_run).map(|(r, _)| r)
    }

    /// [`Capture::to_record`], and what each sensor gave.
    pub fn to_record_with(
        &self,
        source: &str,
        longest_run: bool,
    ) -> Result<(Record, Vec<SensorRecord>), CaptureError> {
        let several = self.sensors.len() > 1;
        let runs = self
            .sensors
            .iter()
            .enumerate()
            .map(|(k, sensor)| {
                run_to_read(sensor, longest_run).map_err(|e| match several {
                    true => CaptureError::InSensor {
                        sensor: k,
                        kind: sensor.sensor.kind,
                        source: Box::new(e),
                    },
                    false => e,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let rates: Vec<f64> = self
            .sensors
            .iter()
            .zip(&runs)
            .map(|(s, run)| s.config_of(run).output_rate_hz())
            .collect();
        if rates.iter().any(|r| *r != rates[0]) {
            return Err(CaptureError::RatesDiffer {
                rates: self
                    .sensors
                    .iter()
                    .zip(&rates)
                    .map(|(s, r)| format!("{} {r} Hz", s.sensor.kind))
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        let spans: Vec<Span> = self
            .sensors
            .iter()
            .zip(&runs)
            .map(|(s, run)| Span::of(run, s.config_of(run).period_us()))
            .collect();
        let from_us = spans.iter().map(|s| s.start_us).max().unwrap_or(0);
        let skips: Vec<usize> = spans.iter().map(|s| s.nearest(from_us)).collect();
        let len = spans
            .iter()
            .zip(&skips)
            .map(|(s, skip)| s.len - skip)
            .min()
            .unwrap_or(0);
        let parts: Vec<(usize, usize)> = skips.iter().map(|&skip| (skip, len)).collect();
        let mut channels = Vec::new();
        let mut used = Vec::new();
        for ((sensor, run), (skip, take)) in self.sensors.iter().zip(&runs).zip(&parts) {
            let samples = &run.samples[*skip..*skip + *take];
            channels.extend(channels_of(
                &sensor.config_of(run),
                sensor.sensor.id,
                samples,
            ));
            used.push(SensorRecord {
                kind: sensor.sensor.kind,
                used: *take,
                trimmed: run.samples.len() - *take,
            });
        }
        // Two sensors giving the same channel (never on the boards we know): the first kept.
        channels.sort_by_key(|c| ORDER.iter().position(|n| *n == c.name));
        channels.dedup_by(|b, a| a.name == b.name);
        Ok((
            Record {
                source: source.to_string(),
                rate_hz: rates[0],
                channels,
            },
            used,
        ))
    }

    /// One run of one sensor in SI units, with the settings the board announced for it.
    pub fn run_record(&self, sensor: &SensorCapture, run: &Run, source: &str) -> Record {
        let config = sensor.config_of(run);
        Record {
            source: source.to_string(),
            rate_hz: config.output_rate_hz(),
            channels: channels_of(&config, sensor.sensor.id, &run.samples),
        }
    }
}

/// The run a record reads: the only one, or with `longest_run` the longest; an error naming
/// the gaps or restarts otherwise.
fn run_to_read(sensor: &SensorCapture, longest_run: bool) -> Result<&Run, CaptureError> {
    let longest = sensor.longest_run().ok_or(CaptureError::NoSamples)?;
    if !longest_run {
        if let Some(first) = sensor.gaps().first() {
            return Err(CaptureError::Gaps {
                lost: sensor.accounting.lost(),
                gaps: sensor.gaps().len(),
                first_gap: first.start,
                longest: longest.samples.len(),
            });
        }
        if let Some(&first) = sensor.restarts.first() {
            return Err(CaptureError::Restarts {
                restarts: sensor.restarts.len(),
                first,
                longest: longest.samples.len(),
            });
        }
    }
    Ok(longest)
}

/// A run's board-time span: its first sample's time and its samples' period.
#[derive(Debug, Clone, Copy)]
struct Span {
    start_us: u64,
    period_us: u64,
    len: usize,
}

impl Span {
    fn of(run: &Run, period_us: u32) -> Span {
        Span {
            start_us: run.first_timestamp_us,
            period_us: u64::from(period_us.max(1)),
            len: run.samples.len(),
        }
    }

    /// The index of the sample made nearest `t_us` (at or after the span's start).
    fn nearest(&self, t_us: u64) -> usize {
        let after = t_us.saturating_sub(self.start_us);
        let index = (after + self.period_us / 2) / self.period_us;
        (index as usize).min(self.len)
    }
}

/// A sensor's samples in SI units, by its kind (module docs).
fn channels_of(config: &SensorConfig, id: u8, samples: &[RawSample]) -> Vec<Channel> {
    let mut channels = Vec::new();
    match config {
        SensorConfig::Mpu6050(s) => {
            let chip = chip_or_mpu6050(id);
            push_axes(
                &mut channels,
                GYRO,
                samples,
                s.gyro_range.rad_s_per_lsb(),
                |r| r.gyro,
            );
            push_axes(
                &mut channels,
                ACCEL,
                samples,
                s.accel_range.m_s2_per_lsb(),
                |r| r.accel,
            );
            push_temp(&mut channels, samples, |c| chip.temperature_celsius(c));
        }
        SensorConfig::Itg3200(_) => {
            push_axes(
                &mut channels,
                GYRO,
                samples,
                itg3200::rad_s_per_lsb(),
                |r| r.gyro,
            );
            push_temp(&mut channels, samples, itg3200::temperature_celsius);
        }
        SensorConfig::Adxl345(_) => {
            push_axes(
                &mut channels,
                ACCEL,
                samples,
                adxl345::m_s2_per_lsb(),
                |r| r.accel,
            );
        }
    }
    channels
}

const GYRO: [&str; 3] = ["gx", "gy", "gz"];
const ACCEL: [&str; 3] = ["ax", "ay", "az"];

/// Three axes of counts times `lsb`.
fn push_axes(
    channels: &mut Vec<Channel>,
    names: [&str; 3],
    samples: &[RawSample],
    lsb: f64,
    axes: impl Fn(&RawSample) -> [i16; 3],
) {
    for (i, name) in names.into_iter().enumerate() {
        let values = samples
            .iter()
            .map(|r| f64::from(axes(r)[i]) * lsb)
            .collect();
        channels.push(Channel::named(name, values));
    }
}

/// The die temperature, degC.
fn push_temp(channels: &mut Vec<Channel>, samples: &[RawSample], celsius: impl Fn(i16) -> f64) {
    let values = samples.iter().map(|r| celsius(r.temp)).collect();
    channels.push(Channel::named("temp", values));
}

/// The MPU-6050 settings whose gyro chain is this ITG-3200's: the same InvenSense DLPF at
/// the same DLPF_CFG and SMPLRT_DIV, and the ITG-3200's fixed +/-2000 deg/s range.
pub fn itg3200_as_mpu6050(s: &itg3200::Itg3200Settings) -> SensorSettings {
    SensorSettings {
        dlpf: s.dlpf,
        smplrt_div: s.smplrt_div,
        gyro_range: protocol::mpu6050::GyroRange::Dps2000,
        ..SensorSettings::default()
    }
}

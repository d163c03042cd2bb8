//! One sensor's samples within a capture (`SensorStream` while decoding, [`SensorCapture`]
//! when done): a board with several sensors numbers each one's samples from 0 at Start, at
//! its own rate, so every sensor has its own runs, loss accounting and segments. Board
//! events (a restart, a silence the host measured) reach every stream.

use super::{RecoveryReport, Segment};
use crate::link::accounting::SampleAccounting;
use protocol::{RawSample, SampleBatch, SensorConfig, SensorInfo};
use std::ops::Range;

/// A run of consecutive sample indices and their samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Index of the run's first sample in the session (see [`SensorCapture::restarts`]:
    /// after a board restart, indices continue past the previous segment instead of starting
    /// at 0).
    pub first_index: u64,
    /// Board time of the run's first sample, microseconds.
    pub first_timestamp_us: u64,
    /// The sensor's settings the board announced before this run (`None` if no Info listed
    /// them; the capture's first Info then applies).
    pub config: Option<SensorConfig>,
    pub samples: Vec<RawSample>,
}

/// One sensor's part of a decoded capture.
#[derive(Debug, Clone)]
pub struct SensorCapture {
    /// The sensor as the board's first Info listed it.
    pub sensor: SensorInfo,
    /// Gap-free runs of samples, in index order.
    pub runs: Vec<Run>,
    /// Every sample by its session index: received, lost (gaps) or out of order.
    pub accounting: SampleAccounting,
    /// Session indices at which the board restarted without the host measuring the silence.
    pub restarts: Vec<u64>,
    /// Faults of this sensor the board recovered from, where streaming resumed.
    pub recoveries: Vec<RecoveryReport>,
    /// Board restarts the host measured and bridged with a counted gap.
    pub segments: Vec<Segment>,
}

impl SensorCapture {
    pub fn gaps(&self) -> &[Range<u64>] {
        self.accounting.gaps()
    }

    /// The longest gap-free run.
    pub fn longest_run(&self) -> Option<&Run> {
        self.runs.iter().max_by_key(|r| r.samples.len())
    }

    /// The settings of `run`: its own, or the sensor's as first listed.
    pub fn config_of(&self, run: &Run) -> SensorConfig {
        run.config.unwrap_or(self.sensor.config)
    }
}

/// What a stream does with its samples.
#[derive(Debug, Clone)]
pub(super) struct Keep {
    /// Keep every sample (a replay, an analysis); a long live capture only counts them.
    pub all: bool,
    /// Keep the samples since the last take (a live view's feed).
    pub tap: Option<Tap>,
}

/// See [`super::StreamDecoder::tap`].
#[derive(Debug, Clone, Default)]
pub(super) struct Tap {
    pub run: usize,
    pub new_run: bool,
    pub samples: Vec<RawSample>,
}

/// One sensor's stream while the capture is decoded.
#[derive(Debug, Clone)]
pub(super) struct SensorStream {
    /// The sensor as the board first listed it, if it did.
    pub listed: Option<SensorInfo>,
    /// Its settings in force: the last Info's.
    pub config: Option<SensorConfig>,
    pub accounting: SampleAccounting,
    pub runs: Vec<Run>,
    pub restarts: Vec<u64>,
    pub recoveries: Vec<RecoveryReport>,
    pub segments: Vec<Segment>,
    /// Session index of the current segment's board index 0.
    segment_base: u64,
    pub samples_in_segment: bool,
    /// Board time of the segment's first batch: a reset restarts the board's clock too.
    segment_start_us: u64,
    new_run: bool,
    pub keep: Keep,
}

impl SensorStream {
    pub fn new(keep_samples: bool) -> Self {
        SensorStream {
            listed: None,
            config: None,
            accounting: SampleAccounting::new(),
            runs: Vec::new(),
            restarts: Vec::new(),
            recoveries: Vec::new(),
            segments: Vec::new(),
            segment_base: 0,
            samples_in_segment: false,
            segment_start_us: 0,
            new_run: true,
            keep: Keep {
                all: keep_samples,
                tap: None,
            },
        }
    }

    /// Session index of board index `index` in the current segment.
    pub fn session_index(&self, index: u64) -> u64 {
        self.segment_base.saturating_add(index)
    }

    /// Samples the sensor makes in `us` microseconds at its announced output rate.
    pub fn samples_in(&self, us: u64) -> u64 {
        let rate_hz = self.config.map_or(0.0, |c| c.output_rate_hz());
        (us as f64 * 1e-6 * rate_hz).round() as u64
    }

    pub fn recovered(&mut self, sensor: u8, attempts: u16, resumed_at_index: u64) {
        self.recoveries.push(RecoveryReport {
            sensor,
            resumed_at_index: self.session_index(resumed_at_index),
            attempts,
        });
    }

    /// A new segment: after a silence the host measured (`silent_us`), its samples are
    /// counted lost and the new indices continue past them; otherwise the restart is
    /// recorded as unmeasured.
    pub fn restart(&mut self, silent_us: Option<u64>) {
        let expected = self.accounting.expected();
        match silent_us {
            Some(silent_us) => {
                let samples_lost = self.samples_in(silent_us);
                self.segment_base = expected.saturating_add(samples_lost);
                self.segments.push(Segment {
                    first_index: self.segment_base,
                    silent_s: silent_us as f64 * 1e-6,
                    samples_lost,
                });
            }
            None => {
                self.segment_base = expected;
                self.restarts.push(expected);
            }
        }
        self.samples_in_segment = false;
        self.new_run = true;
        if let Some(tap) = self.keep.tap.as_mut() {
            tap.new_run = true;
        }
    }

    /// Whether `batch` shows the board restarted with its Info lost on the line: indices
    /// gone back, and the clock before the segment began (or a new index 0 at another time).
    /// A repeated batch keeps its own timestamp, so it is not taken for a restart.
    pub fn restarted_before(&self, batch: &SampleBatch) -> bool {
        let board_next = self.accounting.expected().saturating_sub(self.segment_base);
        let ts = batch.first_timestamp_us;
        self.samples_in_segment
            && batch.first_index < board_next
            && (ts < self.segment_start_us
                || (batch.first_index == 0 && ts != self.segment_start_us))
    }

    /// Account for a batch and keep its samples as asked.
    pub fn batch(&mut self, batch: &SampleBatch) {
        let len = batch.samples.len();
        let index = self.session_index(batch.first_index);
        // Overlapping indices (Err) are counted by the accounting, not stored twice.
        let Ok(gap) = self.accounting.batch(index, len) else {
            return;
        };
        if !self.samples_in_segment {
            self.segment_start_us = batch.first_timestamp_us;
        }
        self.samples_in_segment = true;
        if let Some(tap) = self.keep.tap.as_mut() {
            if gap.is_some() || tap.new_run {
                tap.run += 1;
                tap.samples.clear();
                tap.new_run = false;
            }
            tap.samples.extend_from_slice(&batch.samples);
        }
        if !self.keep.all {
            return;
        }
        match self.runs.last_mut() {
            Some(run) if gap.is_none() && !self.new_run => {
                run.samples.extend_from_slice(&batch.samples)
            }
            _ => self.runs.push(Run {
                first_index: index,
                first_timestamp_us: batch.first_timestamp_us,
                config: self.config,
                samples: batch.samples.to_vec(),
            }),
        }
        self.new_run = false;
    }

    /// The end of the capture: a silence the host measured that no restart ended (the
    /// board never came back) is lost at the tail.
    pub fn close_after_silence(&mut self, silent_us: u64) {
        let lost = self.samples_in(silent_us);
        let expected = self.accounting.expected();
        self.accounting.close(expected.saturating_add(lost));
    }

    /// The board gave up on this sensor: its samples up to board index `ended_at` are
    /// accounted for, those never delivered lost.
    pub fn gave_up_at(&mut self, ended_at: u64) {
        let end = self.session_index(ended_at);
        self.accounting.close(end);
    }

    /// The board listed the sensor (an Info).
    pub fn listed(&mut self, sensor: SensorInfo) {
        self.listed.get_or_insert(sensor);
        self.config = Some(sensor.config);
    }

    /// The stream as decoded, with `fallback` for a sensor no Info listed.
    pub fn finish(self, fallback: SensorInfo) -> SensorCapture {
        SensorCapture {
            sensor: self.listed.unwrap_or(fallback),
            runs: self.runs,
            accounting: self.accounting,
            restarts: self.restarts,
            recoveries: self.recoveries,
            segments: self.segments,
        }
    }
}

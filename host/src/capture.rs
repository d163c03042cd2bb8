//! Capture files: the bytes a board sent during a run, exactly as they arrived on the link —
//! `0x00`-delimited frames of [`DeviceMessage`]s (protocol/src/frame.rs), starting with the
//! board's `Info` (which carries the settings that give the samples their meaning). Keeping
//! the raw bytes means a capture can always be decoded again, by a newer host too, and a
//! replay is the same decoder reading a file instead of a port.
//!
//! Reading a capture accounts for every sample by its index: gaps (FIFO overflows, batches
//! dropped for back-pressure, frames damaged on the line) are counted and listed, never
//! bridged; the analysis refuses gapped data unless asked to take the longest gap-free run.

use crate::link::accounting::SampleAccounting;
use crate::record::{Channel, Record};
use protocol::frame::{self, DecoderStats, FrameDecoder, MAX_WIRE_LEN};
use protocol::mpu6050::temperature_celsius;
use protocol::{DeviceInfo, DeviceMessage, RawSample, Status};
use std::io::Write;
use std::ops::Range;

/// Captures start with a frame delimiter (every frame does), which no text file and no
/// NumPy file does: enough to tell them apart.
pub fn looks_like_capture(bytes: &[u8]) -> bool {
    bytes.first() == Some(&frame::DELIMITER)
}

/// Writes a capture: each message framed exactly as a board frames it.
pub struct CaptureWriter<W: Write> {
    out: W,
    buf: Vec<u8>,
}

impl<W: Write> CaptureWriter<W> {
    pub fn new(out: W) -> Self {
        CaptureWriter {
            out,
            buf: vec![0; MAX_WIRE_LEN],
        }
    }

    pub fn message(&mut self, message: &DeviceMessage) -> std::io::Result<()> {
        let n = frame::encode(message, &mut self.buf)
            .map_err(|e| std::io::Error::other(format!("framing a message: {e:?}")))?;
        self.out.write_all(&self.buf[..n])
    }

    pub fn into_inner(self) -> W {
        self.out
    }
}

/// A run of consecutive sample indices and their samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub first_index: u64,
    /// Board time of the run's first sample, microseconds.
    pub first_timestamp_us: u64,
    pub samples: Vec<RawSample>,
}

/// A decoded capture.
#[derive(Debug, Clone)]
pub struct Capture {
    pub info: DeviceInfo,
    /// Gap-free runs of samples, in index order.
    pub runs: Vec<Run>,
    /// The last status report, if the board sent one.
    pub status: Option<Status>,
    pub accounting: SampleAccounting,
    /// Frames rejected on the line (damaged) and by cause.
    pub decoder: DecoderStats,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CaptureError {
    #[error("not a capture: no board Info message before the first samples")]
    NoInfo,
    #[error("the capture holds no samples")]
    NoSamples,
    #[error(
        "{lost} samples lost in {gaps} gap(s) (first at index {first_gap}); the Allan variance needs uninterrupted samples: use --longest-run to analyse the longest gap-free run ({longest} samples)"
    )]
    Gaps {
        lost: u64,
        gaps: usize,
        first_gap: u64,
        longest: usize,
    },
}

impl Capture {
    /// Decode a capture's bytes.
    pub fn decode(bytes: &[u8]) -> Result<Capture, CaptureError> {
        let mut decoder = FrameDecoder::new();
        let mut info = None;
        let mut status = None;
        let mut accounting = SampleAccounting::new();
        let mut runs: Vec<Run> = Vec::new();
        decoder.feed::<DeviceMessage>(bytes, |message| match message {
            Ok(DeviceMessage::Info(i)) => info = Some(i),
            Ok(DeviceMessage::Status(s)) => status = Some(s),
            Ok(DeviceMessage::Samples(batch)) => {
                let len = batch.samples.len();
                // Overlapping indices (Err) are counted by the accounting, not stored twice.
                if let Ok(gap) = accounting.batch(batch.first_index, len) {
                    let extends = gap.is_none() && !runs.is_empty();
                    if extends && let Some(run) = runs.last_mut() {
                        run.samples.extend_from_slice(&batch.samples);
                    } else {
                        runs.push(Run {
                            first_index: batch.first_index,
                            first_timestamp_us: batch.first_timestamp_us,
                            samples: batch.samples.to_vec(),
                        });
                    }
                }
            }
            // Replies and faults carry no samples; damaged frames are in the decoder's stats.
            Ok(_) | Err(_) => {}
        });
        // Status counters are cumulative since the board powered up, not since Start, so
        // they cannot close the index range; losses after the last batch show in them.
        let info = info.ok_or(CaptureError::NoInfo)?;
        Ok(Capture {
            info,
            runs,
            status,
            accounting,
            decoder: decoder.stats(),
        })
    }

    pub fn gaps(&self) -> &[Range<u64>] {
        self.accounting.gaps()
    }

    /// The samples as a record in SI units, named `gx gy gz ax ay az temp`: all of them if
    /// there is no gap, else an error (or, with `longest_run`, the longest gap-free run).
    pub fn to_record(&self, source: &str, longest_run: bool) -> Result<Record, CaptureError> {
        let longest = self
            .runs
            .iter()
            .max_by_key(|r| r.samples.len())
            .ok_or(CaptureError::NoSamples)?;
        if !self.gaps().is_empty() && !longest_run {
            return Err(CaptureError::Gaps {
                lost: self.accounting.lost(),
                gaps: self.gaps().len(),
                first_gap: self.gaps()[0].start,
                longest: longest.samples.len(),
            });
        }
        Ok(record_of(source, &self.info, &longest.samples))
    }
}

/// Counts to SI with the board's settings (protocol::mpu6050 sensitivities).
fn record_of(source: &str, info: &DeviceInfo, samples: &[RawSample]) -> Record {
    let s = info.settings;
    let (g, a) = (s.gyro_range.rad_s_per_lsb(), s.accel_range.m_s2_per_lsb());
    let column = |f: &dyn Fn(&RawSample) -> f64| samples.iter().map(f).collect::<Vec<_>>();
    let channels = vec![
        Channel::named("gx", column(&|r| f64::from(r.gyro[0]) * g)),
        Channel::named("gy", column(&|r| f64::from(r.gyro[1]) * g)),
        Channel::named("gz", column(&|r| f64::from(r.gyro[2]) * g)),
        Channel::named("ax", column(&|r| f64::from(r.accel[0]) * a)),
        Channel::named("ay", column(&|r| f64::from(r.accel[1]) * a)),
        Channel::named("az", column(&|r| f64::from(r.accel[2]) * a)),
        Channel::named("temp", column(&|r| temperature_celsius(r.temp))),
    ];
    Record {
        source: source.to_string(),
        rate_hz: s.output_rate_hz(),
        channels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::{FirmwareVersion, PROTOCOL_VERSION, SampleBatch, SensorSettings};

    fn info() -> DeviceInfo {
        DeviceInfo {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: FirmwareVersion {
                major: 0,
                minor: 1,
                patch: 0,
            },
            board_id: 7,
            who_am_i: 0x68,
            settings: SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap(),
            streaming: true,
            max_samples_per_batch: 32,
        }
    }

    fn batch(first: u64, n: usize) -> DeviceMessage {
        let samples = (0..n)
            .map(|i| RawSample {
                gyro: [(first + i as u64) as i16, 0, 0],
                ..RawSample::default()
            })
            .collect();
        DeviceMessage::Samples(SampleBatch {
            first_index: first,
            first_timestamp_us: first * 5000,
            samples,
        })
    }

    fn capture(messages: &[DeviceMessage]) -> Vec<u8> {
        let mut w = CaptureWriter::new(Vec::new());
        for m in messages {
            w.message(m).unwrap();
        }
        w.into_inner()
    }

    #[test]
    fn round_trip_without_gaps() {
        let bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 10)]);
        assert!(looks_like_capture(&bytes));
        let c = Capture::decode(&bytes).unwrap();
        assert_eq!(c.runs.len(), 1);
        let r = c.to_record("cap", false).unwrap();
        assert_eq!(r.rate_hz, 200.0);
        assert_eq!(r.len(), 42);
        assert_eq!(r.names(), ["gx", "gy", "gz", "ax", "ay", "az", "temp"]);
        let lsb = SensorSettings::default().gyro_range.rad_s_per_lsb();
        assert_eq!(r.channels[0].values[41], 41.0 * lsb);
    }

    #[test]
    fn gaps_are_counted_and_never_bridged() {
        let status = Status {
            samples_acquired: 70,
            samples_lost: 10,
            ..Status::default()
        };
        let bytes = capture(&[
            DeviceMessage::Info(info()),
            batch(0, 32),
            batch(40, 32),
            DeviceMessage::Status(status),
        ]);
        let c = Capture::decode(&bytes).unwrap();
        assert_eq!(c.gaps(), std::slice::from_ref(&(32..40)));
        assert_eq!(c.accounting.lost(), 8);
        assert_eq!(c.status, Some(status));
        let err = c.to_record("cap", false).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("8 samples lost in 1 gap(s) (first at index 32)")
        );
        let r = c.to_record("cap", true).unwrap();
        assert_eq!(r.len(), 32);
        assert_eq!(
            r.channels[0].values[0],
            40.0 * SensorSettings::default().gyro_range.rad_s_per_lsb()
        );
    }

    #[test]
    fn damaged_frames_are_counted() {
        let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)]);
        let second = bytes.len() - 10;
        bytes[second] ^= 0x40;
        let c = Capture::decode(&bytes).unwrap();
        assert_eq!(c.decoder.rejected(), 1);
        assert_eq!(c.runs[0].samples.len(), 32);
        assert_eq!(
            Capture::decode(&capture(&[batch(0, 3)])).unwrap_err(),
            CaptureError::NoInfo
        );
    }
}

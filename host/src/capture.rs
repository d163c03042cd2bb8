//! Capture files: the bytes a board sent during a run, exactly as they arrived on the link —
//! `0x00`-delimited frames of [`DeviceMessage`]s (protocol/src/frame.rs), starting with the
//! board's `Info` (which carries the settings that give the samples their meaning). Keeping
//! the raw bytes means a capture can always be decoded again, by a newer host too, and a
//! replay is the same decoder reading a file instead of a port.
//!
//! **Host notes.** The one thing the board cannot say is how long it was gone when it
//! restarted (its clock restarts too). The capture loop measures that silence on the host's
//! clock and writes it among the frames as a [`HostNote`]: a frame like the board's, whose
//! body starts with the tag `HOST` (no board message starts with that byte), which older
//! decoders count as one rejected frame and skip.
//!
//! Reading a capture accounts for every sample by its index: gaps (FIFO overflows, batches
//! dropped for back-pressure, frames damaged on the line) are counted and listed, never
//! bridged; the analysis refuses gapped data unless asked to take the longest gap-free run.

use crate::link::accounting::SampleAccounting;
use crate::record::{Channel, Record};
use protocol::frame::{self, DecoderStats, FrameDecoder, MAX_WIRE_LEN};
use protocol::mpu6050::chip_or_mpu6050;
use protocol::{
    DeviceFrame, DeviceInfo, DeviceMessage, ErrorCode, RawSample, SampleBatch, SensorSettings,
    Status,
};
use std::io::Write;
use std::ops::Range;

/// Captures start with a frame delimiter (every frame does), which no text file and no
/// NumPy file does: enough to tell them apart.
pub fn looks_like_capture(bytes: &[u8]) -> bool {
    bytes.first() == Some(&frame::DELIMITER)
}

/// A note the host writes among a capture's frames (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum HostNote {
    /// The board went silent, was found not streaming (it had restarted) and was set up and
    /// started again; `silent_us` is the host's clock from the last bytes received to the
    /// new start. The samples the sensor made in that time are lost, and counted so.
    BoardRestarted { silent_us: u64 },
}

/// First bytes of a [`HostNote`] frame's body.
const HOST_NOTE_TAG: [u8; 4] = *b"HOST";

impl HostNote {
    /// The note in a frame body, if the body is one.
    pub fn decode(body: &[u8]) -> Option<HostNote> {
        let (tag, note): ([u8; 4], HostNote) = postcard::from_bytes(body).ok()?;
        (tag == HOST_NOTE_TAG).then_some(note)
    }

    /// The note as a whole frame (delimiters included), to write among the board's.
    pub fn frame(&self) -> Vec<u8> {
        let mut buf = vec![0u8; MAX_WIRE_LEN];
        // A tag and a varint: always fits.
        let n = frame::encode(&(HOST_NOTE_TAG, *self), &mut buf).unwrap_or(0);
        buf.truncate(n);
        buf
    }
}

/// A frame as the capture decoder reads it.
// One value at a time, on the stack: a box would cost an allocation per frame.
#[allow(clippy::large_enum_variant)]
enum Incoming {
    Frame(DeviceFrame),
    /// A version-2 Status or Info (stored captures).
    StatusV2(Status),
    InfoV2(DeviceInfo),
    Note(HostNote),
}

/// A restart whose silence the host measured: a gap like any other, of estimated length.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Segment {
    /// Session index of the new segment's first sample.
    pub first_index: u64,
    /// The host's measure of the silence, seconds.
    pub silent_s: f64,
    /// Samples counted lost for it: the silence times the output rate, rounded.
    pub samples_lost: u64,
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
    /// Index of the run's first sample in the session (see [`Capture::restarts`]: after a
    /// board restart, indices continue past the previous segment instead of starting at 0).
    pub first_index: u64,
    /// Board time of the run's first sample, microseconds.
    pub first_timestamp_us: u64,
    /// The settings the board announced before this run (`None` if no Info preceded it; the
    /// capture's first Info then applies).
    pub settings: Option<SensorSettings>,
    pub samples: Vec<RawSample>,
}

/// A decoded capture.
#[derive(Debug, Clone)]
pub struct Capture {
    /// The board's first Info.
    pub info: DeviceInfo,
    /// Gap-free runs of samples, in index order.
    pub runs: Vec<Run>,
    /// The last status report, if the board sent one.
    pub status: Option<Status>,
    /// Every sample by its session index: received, lost (gaps) or out of order.
    pub accounting: SampleAccounting,
    /// Session indices at which the board restarted (see [`StreamDecoder`]).
    pub restarts: Vec<u64>,
    /// Frames rejected on the line (damaged) and by cause.
    pub decoder: DecoderStats,
    /// Bytes of a last frame that never got its closing delimiter (a capture cut short).
    pub trailing_bytes: usize,
    /// What the board said went wrong: commands it refused and faults it reported.
    pub board_errors: Vec<BoardReport>,
    /// Faults the board recovered from, where streaming resumed.
    pub recoveries: Vec<RecoveryReport>,
    /// Board restarts the host measured and bridged with a counted gap.
    pub segments: Vec<Segment>,
    /// Device frames missing by the board's frame numbers: damaged on the line (also in
    /// `decoder`) or lost whole after they left the board. A version-2 capture has no
    /// numbers (0).
    pub frames_missing: u64,
}

/// The board brought its sensor back after a fault (protocol `Recovered`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct RecoveryReport {
    /// Session index of the first sample after the recovery; the gap before it is the loss.
    pub resumed_at_index: u64,
    /// Set-up attempts the board made (1: the first worked).
    pub attempts: u16,
}

impl std::fmt::Display for RecoveryReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "recovered after {} attempt(s); samples resume at index {}",
            self.attempts, self.resumed_at_index
        )
    }
}

/// A refusal or fault the board sent, at the session index reached when it arrived (not to
/// be confused with [`crate::link::board::BoardError`], the host failing to command a board).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct BoardReport {
    /// Samples the session had accounted for (received or lost) when it came.
    pub at_index: u64,
    /// The refused command's `seq`, or `None` for a fault (the board recovers from it by
    /// itself, see [`RecoveryReport`], unless the error is `GaveUp`).
    pub refused_seq: Option<u16>,
    pub error: ErrorCode,
}

impl std::fmt::Display for BoardReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.refused_seq {
            Some(seq) => write!(f, "refused command #{seq}: {}", self.error),
            None => write!(f, "fault: {}", self.error),
        }?;
        write!(f, " (at sample {})", self.at_index)
    }
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
    #[error(
        "the board restarted {restarts} time(s) during the capture (first at index {first}); the Allan variance needs one uninterrupted run: use --longest-run to analyse the longest one ({longest} samples)"
    )]
    Restarts {
        restarts: usize,
        first: u64,
        longest: usize,
    },
}

/// Decodes a capture as its bytes arrive, in chunks of any size: the one decoder behind
/// both a live capture and a replay of its file, so both give the same record bit for bit.
///
/// **Board restarts.** A board that resets mid-stream announces itself again (a new Info)
/// and numbers its samples from 0 again. Indices restarting would otherwise look like
/// batches repeating old ones (discarded), so a restart — an Info after samples, or a batch
/// going back in both index and board time — ends the current run, is recorded in
/// [`Capture::restarts`], and the new segment's indices continue past the old segment's
/// (`session index = segment base + board index`). Samples the board never sent between
/// its reset and its new start are unknowable and are not counted as lost.
pub struct StreamDecoder {
    decoder: FrameDecoder,
    first_info: Option<DeviceInfo>,
    settings: Option<SensorSettings>,
    status: Option<Status>,
    accounting: SampleAccounting,
    runs: Vec<Run>,
    restarts: Vec<u64>,
    /// Session index of the current segment's board index 0.
    segment_base: u64,
    samples_in_segment: bool,
    /// Board time of the segment's first batch: a reset restarts the board's clock too.
    segment_start_us: u64,
    new_run: bool,
    keep_samples: bool,
    board_errors: Vec<BoardReport>,
    recoveries: Vec<RecoveryReport>,
    segments: Vec<Segment>,
    /// A [`HostNote::BoardRestarted`] waiting for the restart it measured.
    silent_before_restart_us: Option<u64>,
    /// Samples decoded since [`StreamDecoder::take_tapped`] last took them, when tapped.
    tap: Option<Tap>,
    statuses_seen: u64,
    /// The last frame number seen, and the frames missing by the numbers.
    last_frame: Option<u32>,
    frames_missing: u64,
}

impl Default for StreamDecoder {
    fn default() -> Self {
        Self::new(true)
    }
}

impl StreamDecoder {
    /// `keep_samples: false` counts without keeping the samples (a long live capture, whose
    /// samples are in its file anyway).
    pub fn new(keep_samples: bool) -> Self {
        StreamDecoder {
            decoder: FrameDecoder::new(),
            first_info: None,
            settings: None,
            status: None,
            accounting: SampleAccounting::new(),
            runs: Vec::new(),
            restarts: Vec::new(),
            segment_base: 0,
            samples_in_segment: false,
            segment_start_us: 0,
            new_run: true,
            keep_samples,
            board_errors: Vec::new(),
            recoveries: Vec::new(),
            segments: Vec::new(),
            silent_before_restart_us: None,
            tap: None,
            statuses_seen: 0,
            last_frame: None,
            frames_missing: 0,
        }
    }

    /// Decode a chunk; returns how many Info messages it held (a new Info means new metadata).
    pub fn feed(&mut self, bytes: &[u8]) -> usize {
        let mut decoder = std::mem::take(&mut self.decoder);
        let mut infos = 0;
        let read = |body: &[u8]| {
            DeviceFrame::decode(body)
                .map(Incoming::Frame)
                .or_else(|| Status::decode_v2(body).map(Incoming::StatusV2))
                .or_else(|| DeviceInfo::decode_v2(body).map(Incoming::InfoV2))
                .or_else(|| HostNote::decode(body).map(Incoming::Note))
        };
        decoder.feed_with(bytes, read, |frame| match frame {
            Ok(Incoming::Frame(DeviceFrame { message, counter })) => {
                if let Some(counter) = counter {
                    self.count_frame(counter);
                }
                self.message(message, &mut infos)
            }
            Ok(Incoming::StatusV2(status)) => {
                self.message(DeviceMessage::Status(status), &mut infos)
            }
            Ok(Incoming::InfoV2(info)) => self.message(DeviceMessage::Info(info), &mut infos),
            Ok(Incoming::Note(note)) => self.note(note),
            // Damaged frames are in the decoder's stats.
            Err(_) => {}
        });
        self.decoder = decoder;
        infos
    }

    /// A numbered frame: a jump forward is frames lost after they left the board; a number
    /// going back is the board's restart (it numbers from 0 at power-up).
    fn count_frame(&mut self, counter: u32) {
        if let Some(last) = self.last_frame {
            let jump = counter.wrapping_sub(last);
            if jump > 1 && jump < u32::MAX / 2 {
                self.frames_missing += u64::from(jump - 1);
            }
        }
        self.last_frame = Some(counter);
    }

    fn message(&mut self, message: DeviceMessage, infos: &mut usize) {
        match message {
            DeviceMessage::Info(i) => {
                *infos += 1;
                self.info(i);
            }
            DeviceMessage::Status(s) => {
                self.status = Some(s);
                self.statuses_seen += 1;
            }
            DeviceMessage::Samples(batch) => self.batch(&batch),
            DeviceMessage::Nack { seq, error } => self.board_error(Some(seq), error),
            DeviceMessage::Fault(error) => {
                if let ErrorCode::GaveUp { ended_at, .. } = error {
                    // The run's tail, never delivered: lost, up to where the board stopped.
                    let end = self.segment_base.saturating_add(ended_at);
                    self.accounting.close(end);
                }
                self.board_error(None, error)
            }
            DeviceMessage::Recovered {
                attempts,
                resumed_at_index,
            } => self.recovered(attempts, resumed_at_index),
            // Acks and pongs carry nothing to keep.
            DeviceMessage::Ack { .. } | DeviceMessage::Pong { .. } => {}
            // Sensors past the first are not decoded yet.
            DeviceMessage::SensorSamples { .. }
            | DeviceMessage::SensorFault { .. }
            | DeviceMessage::SensorRecovered { .. } => {}
        }
    }

    fn note(&mut self, note: HostNote) {
        match note {
            // Fruitless restarts write one note each, each measuring the silence since the
            // one before: together they are the time the board was gone.
            HostNote::BoardRestarted { silent_us } => {
                let pending = self.silent_before_restart_us.unwrap_or(0);
                self.silent_before_restart_us = Some(pending.saturating_add(silent_us));
            }
        }
    }

    fn info(&mut self, info: DeviceInfo) {
        if self.samples_in_segment {
            self.restart();
        }
        self.first_info.get_or_insert(info);
        self.settings = Some(info.settings);
    }

    fn board_error(&mut self, refused_seq: Option<u16>, error: ErrorCode) {
        self.board_errors.push(BoardReport {
            at_index: self.accounting.expected(),
            refused_seq,
            error,
        });
    }

    fn recovered(&mut self, attempts: u16, resumed_at_index: u64) {
        self.recoveries.push(RecoveryReport {
            resumed_at_index: self.segment_base.saturating_add(resumed_at_index),
            attempts,
        });
    }

    /// A new segment: after a silence the host measured, its samples are counted lost and
    /// the new indices continue past them; otherwise the restart is recorded as unmeasured.
    fn restart(&mut self) {
        let expected = self.accounting.expected();
        match self.silent_before_restart_us.take() {
            Some(silent_us) => {
                let silent_s = silent_us as f64 * 1e-6;
                let samples_lost = self.samples_in(silent_us);
                self.segment_base = expected.saturating_add(samples_lost);
                self.segments.push(Segment {
                    first_index: self.segment_base,
                    silent_s,
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
        if let Some(tap) = self.tap.as_mut() {
            tap.new_run = true;
        }
    }

    /// Samples the sensor makes in `us` microseconds at the announced output rate.
    fn samples_in(&self, us: u64) -> u64 {
        let rate_hz = self.settings.map_or(0.0, |s| s.output_rate_hz());
        (us as f64 * 1e-6 * rate_hz).round() as u64
    }

    /// Status messages seen so far (a watcher asks for one and waits for the count to move).
    pub fn statuses_seen(&self) -> u64 {
        self.statuses_seen
    }

    fn batch(&mut self, batch: &SampleBatch) {
        // Indices gone back, and the clock before the segment began (or a new index 0 at
        // another time): the board restarted and its Info was lost on the line. A repeated
        // batch keeps its own timestamp, so it is not taken for a restart.
        let board_next = self.accounting.expected().saturating_sub(self.segment_base);
        let ts = batch.first_timestamp_us;
        if self.samples_in_segment
            && batch.first_index < board_next
            && (ts < self.segment_start_us
                || (batch.first_index == 0 && ts != self.segment_start_us))
        {
            self.restart();
        }
        let len = batch.samples.len();
        let index = self.segment_base.saturating_add(batch.first_index);
        // Overlapping indices (Err) are counted by the accounting, not stored twice.
        let Ok(gap) = self.accounting.batch(index, len) else {
            return;
        };
        if !self.samples_in_segment {
            self.segment_start_us = batch.first_timestamp_us;
        }
        self.samples_in_segment = true;
        if let Some(tap) = self.tap.as_mut() {
            if gap.is_some() || tap.new_run {
                tap.run += 1;
                tap.samples.clear();
                tap.new_run = false;
            }
            tap.samples.extend_from_slice(&batch.samples);
        }
        if !self.keep_samples {
            return;
        }
        match self.runs.last_mut() {
            Some(run) if gap.is_none() && !self.new_run => {
                run.samples.extend_from_slice(&batch.samples)
            }
            _ => self.runs.push(Run {
                first_index: index,
                first_timestamp_us: batch.first_timestamp_us,
                settings: self.settings,
                samples: batch.samples.to_vec(),
            }),
        }
        self.new_run = false;
    }

    pub fn info_seen(&self) -> Option<&DeviceInfo> {
        self.first_info.as_ref()
    }

    /// Keep the samples decoded from here on for [`StreamDecoder::take_tapped`], without
    /// keeping the whole capture: a live view's feed.
    pub fn tap(&mut self) {
        self.tap.get_or_insert(Tap {
            run: 0,
            new_run: true,
            samples: Vec::new(),
        });
    }

    /// The samples decoded since the last call, and the number of the gap-free run they
    /// belong to (a new number: a gap or a restart began a new run, and the samples are
    /// that run's first). `None` unless [`StreamDecoder::tap`]ped.
    pub fn take_tapped(&mut self) -> Option<(usize, Vec<RawSample>)> {
        self.tap
            .as_mut()
            .map(|t| (t.run, std::mem::take(&mut t.samples)))
    }

    /// The settings in force for the samples arriving: the last Info's.
    pub fn settings(&self) -> Option<SensorSettings> {
        self.settings
    }
    pub fn accounting(&self) -> &SampleAccounting {
        &self.accounting
    }
    pub fn status(&self) -> Option<&Status> {
        self.status.as_ref()
    }
    pub fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }
    pub fn restarts(&self) -> &[u64] {
        &self.restarts
    }
    /// Refusals and faults so far.
    pub fn board_errors(&self) -> &[BoardReport] {
        &self.board_errors
    }
    /// Recoveries so far.
    pub fn recoveries(&self) -> &[RecoveryReport] {
        &self.recoveries
    }
    /// Bytes of a frame not yet closed by its delimiter.
    pub fn pending(&self) -> usize {
        self.decoder.pending()
    }

    /// The capture so far. Status counters are cumulative since the board powered up, not
    /// since Start, so they cannot close the index range; losses after the last batch show
    /// in them.
    /// End of the capture: a silence the host measured that no restart ended (the board
    /// never came back) is lost at the tail, counted as a gap like any other.
    pub fn settle(&mut self) {
        let Some(silent_us) = self.silent_before_restart_us.take() else {
            return;
        };
        let lost = self.samples_in(silent_us);
        let expected = self.accounting.expected();
        self.accounting.close(expected.saturating_add(lost));
    }

    pub fn finish(mut self) -> Result<Capture, CaptureError> {
        self.settle();
        let info = self.first_info.ok_or(CaptureError::NoInfo)?;
        Ok(Capture {
            info,
            runs: self.runs,
            status: self.status,
            accounting: self.accounting,
            restarts: self.restarts,
            decoder: self.decoder.stats(),
            trailing_bytes: self.decoder.pending(),
            board_errors: self.board_errors,
            recoveries: self.recoveries,
            segments: self.segments,
            frames_missing: self.frames_missing,
        })
    }
}

impl Capture {
    /// Decode a capture's bytes.
    pub fn decode(bytes: &[u8]) -> Result<Capture, CaptureError> {
        let mut decoder = StreamDecoder::new(true);
        decoder.feed(bytes);
        decoder.finish()
    }

    pub fn gaps(&self) -> &[Range<u64>] {
        self.accounting.gaps()
    }

    /// The samples as a record in SI units, named `gx gy gz ax ay az temp`: all of them if
    /// there is no gap and no restart, else an error (or, with `longest_run`, the longest
    /// gap-free run).
    pub fn to_record(&self, source: &str, longest_run: bool) -> Result<Record, CaptureError> {
        let longest = self
            .runs
            .iter()
            .max_by_key(|r| r.samples.len())
            .ok_or(CaptureError::NoSamples)?;
        if !longest_run {
            if let Some(first) = self.gaps().first() {
                return Err(CaptureError::Gaps {
                    lost: self.accounting.lost(),
                    gaps: self.gaps().len(),
                    first_gap: first.start,
                    longest: longest.samples.len(),
                });
            }
            if let Some(&first) = self.restarts.first() {
                return Err(CaptureError::Restarts {
                    restarts: self.restarts.len(),
                    first,
                    longest: longest.samples.len(),
                });
            }
        }
        Ok(self.run_record(longest, source))
    }

    /// One run's samples in SI units, with the settings the board announced for it.
    pub fn run_record(&self, run: &Run, source: &str) -> Record {
        let settings = run.settings.unwrap_or(self.info.settings);
        record_of(source, &settings, self.info.who_am_i, &run.samples)
    }
}

/// Counts to SI with the board's settings and chip (protocol::mpu6050 sensitivities; the
/// temperature scale differs between chips).
fn record_of(source: &str, s: &SensorSettings, who_am_i: u8, samples: &[RawSample]) -> Record {
    let chip = chip_or_mpu6050(who_am_i);
    let (g, a) = (s.gyro_range.rad_s_per_lsb(), s.accel_range.m_s2_per_lsb());
    let column = |f: &dyn Fn(&RawSample) -> f64| samples.iter().map(f).collect::<Vec<_>>();
    let channels = vec![
        Channel::named("gx", column(&|r| f64::from(r.gyro[0]) * g)),
        Channel::named("gy", column(&|r| f64::from(r.gyro[1]) * g)),
        Channel::named("gz", column(&|r| f64::from(r.gyro[2]) * g)),
        Channel::named("ax", column(&|r| f64::from(r.accel[0]) * a)),
        Channel::named("ay", column(&|r| f64::from(r.accel[1]) * a)),
        Channel::named("az", column(&|r| f64::from(r.accel[2]) * a)),
        Channel::named("temp", column(&|r| chip.temperature_celsius(r.temp))),
    ];
    Record {
        source: source.to_string(),
        rate_hz: s.output_rate_hz(),
        channels,
    }
}

/// See [`StreamDecoder::tap`].
#[derive(Debug, Clone)]
struct Tap {
    run: usize,
    new_run: bool,
    samples: Vec<RawSample>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::{FirmwareVersion, PROTOCOL_VERSION};

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
            reset_reason: protocol::ResetReason::Unknown,
            sensors: protocol::SensorList::default(),
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

    #[test]
    fn a_board_restart_ends_the_run_and_is_recorded() {
        let mut restarted = batch(0, 32);
        if let DeviceMessage::Samples(b) = &mut restarted {
            b.first_timestamp_us = 1234; // another boot, another time
        }
        // With its Info (a reset announces itself) and without (the Info lost on the line).
        for with_info in [true, false] {
            let mut messages = vec![DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)];
            if with_info {
                messages.push(DeviceMessage::Info(info()));
            }
            messages.extend([restarted.clone(), batch(32, 32)]);
            let c = Capture::decode(&capture(&messages)).unwrap();
            assert_eq!(c.restarts, [64], "with_info {with_info}");
            assert_eq!(c.runs.len(), 2);
            assert_eq!((c.runs[1].first_index, c.runs[1].samples.len()), (64, 64));
            assert_eq!((c.accounting.received(), c.accounting.lost()), (128, 0));
            let err = c.to_record("cap", false).unwrap_err();
            assert!(err.to_string().contains("restarted 1 time"), "{err}");
            assert_eq!(c.to_record("cap", true).unwrap().len(), 64);
        }
        // A repeated batch (same time) is not a restart.
        let c = Capture::decode(&capture(&[
            DeviceMessage::Info(info()),
            batch(0, 32),
            batch(32, 32),
            batch(0, 32),
        ]))
        .unwrap();
        assert!(c.restarts.is_empty());
        assert_eq!(c.accounting.out_of_order_batches(), 1);
    }

    #[test]
    fn a_restart_the_host_measured_is_a_counted_gap() {
        let mut restarted = batch(0, 32);
        if let DeviceMessage::Samples(b) = &mut restarted {
            b.first_timestamp_us = 1234;
        }
        let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)]);
        // 1.5 s of silence at the info's output rate.
        let rate = info().settings.output_rate_hz();
        bytes.extend(
            HostNote::BoardRestarted {
                silent_us: 1_500_000,
            }
            .frame(),
        );
        bytes.extend(capture(&[
            DeviceMessage::Info(info()),
            restarted,
            batch(32, 32),
        ]));
        let c = Capture::decode(&bytes).unwrap();
        let lost = (1.5 * rate).round() as u64;
        assert!(c.restarts.is_empty());
        assert_eq!(
            c.segments,
            [Segment {
                first_index: 64 + lost,
                silent_s: 1.5,
                samples_lost: lost
            }]
        );
        assert_eq!(c.gaps(), std::slice::from_ref(&(64..64 + lost)));
        assert_eq!((c.accounting.received(), c.accounting.lost()), (128, lost));
        // The note is a good frame, not a damaged one; an older decoder would skip it.
        assert_eq!(c.decoder.rejected(), 0);
        let mut buf = [0u8; 16];
        let pong = postcard::to_slice(&DeviceMessage::Pong { seq: 1 }, &mut buf).unwrap();
        assert_eq!(HostNote::decode(pong), None);
    }

    #[test]
    fn a_version_2_status_in_a_stored_capture_still_decodes() {
        // Variant 4 (Status) and the nine fields version 2 sent.
        let v2 = (
            4u8,
            true,
            1_000_000u64,
            64u64,
            0u32,
            3u64,
            0u32,
            0u32,
            0u64,
            0u32,
        );
        let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32)]);
        let mut buf = vec![0u8; MAX_WIRE_LEN];
        let n = frame::encode(&v2, &mut buf).unwrap();
        bytes.extend_from_slice(&buf[..n]);
        let c = Capture::decode(&bytes).unwrap();
        assert_eq!(c.status.map(|s| s.samples_lost), Some(3));
        assert_eq!(c.decoder.rejected(), 0);
    }

    #[test]
    fn chunked_decoding_equals_whole() {
        let bytes = capture(&[
            DeviceMessage::Info(info()),
            batch(0, 32),
            batch(40, 32),
            batch(72, 5),
        ]);
        let whole = Capture::decode(&bytes).unwrap();
        for chunk in [1, 3, 64, 1000] {
            let mut d = StreamDecoder::new(true);
            bytes.chunks(chunk).for_each(|c| {
                d.feed(c);
            });
            let c = d.finish().unwrap();
            assert_eq!(c.runs, whole.runs);
            assert_eq!(c.accounting, whole.accounting);
        }
    }
}

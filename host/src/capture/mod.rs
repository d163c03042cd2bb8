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

pub mod record;
pub mod stream;

pub use record::{SensorRecord, itg3200_as_mpu6050};
pub use stream::{Run, SensorCapture};

use crate::link::accounting::SampleAccounting;
use protocol::frame::{self, DecoderStats, FrameDecoder, MAX_WIRE_LEN};
use protocol::{
    DeviceFrame, DeviceInfo, DeviceMessage, ErrorCode, RawSample, SampleBatch, SensorConfig,
    SensorInfo, SensorKind, SensorSettings, Status,
};
use std::io::Write;
use stream::{SensorStream, Tap};

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

/// A decoded capture.
#[derive(Debug, Clone)]
pub struct Capture {
    /// The board's first Info.
    pub info: DeviceInfo,
    /// Each sensor's samples and accounting, by sensor number (at least one: a capture
    /// whose Info lists none is a one-MPU-6050 board's, [`DeviceInfo::sensor_list`]).
    pub sensors: Vec<SensorCapture>,
    /// The last status report, if the board sent one.
    pub status: Option<Status>,
    /// Frames rejected on the line (damaged) and by cause.
    pub decoder: DecoderStats,
    /// Bytes of a last frame that never got its closing delimiter (a capture cut short).
    pub trailing_bytes: usize,
    /// What the board said went wrong: commands it refused and faults it reported.
    pub board_errors: Vec<BoardReport>,
    /// Device frames missing by the board's frame numbers: damaged on the line (also in
    /// `decoder`) or lost whole after they left the board. A version-2 capture has no
    /// numbers (0).
    pub frames_missing: u64,
}

/// The board brought its sensor back after a fault (protocol `Recovered`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct RecoveryReport {
    /// The sensor's number (0 on a one-sensor board).
    pub sensor: u8,
    /// Session index of the first sample after the recovery; the gap before it is the loss.
    pub resumed_at_index: u64,
    /// Set-up attempts the board made (1: the first worked).
    pub attempts: u16,
}

impl std::fmt::Display for RecoveryReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.sensor > 0 {
            write!(f, "sensor {}: ", self.sensor)?;
        }
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
    /// The sensor a fault is about (`None` for a refused command).
    pub sensor: Option<u8>,
    /// Samples the session had accounted for (received or lost) when it came: the faulty
    /// sensor's, else sensor 0's.
    pub at_index: u64,
    /// The refused command's `seq`, or `None` for a fault (the board recovers from it by
    /// itself, see [`RecoveryReport`], unless the error is `GaveUp`).
    pub refused_seq: Option<u16>,
    pub error: ErrorCode,
}

impl std::fmt::Display for BoardReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.refused_seq, self.sensor) {
            (Some(seq), _) => write!(f, "refused command #{seq}: {}", self.error),
            (None, Some(sensor)) if sensor > 0 => {
                write!(f, "fault of sensor {sensor}: {}", self.error)
            }
            (None, _) => write!(f, "fault: {}", self.error),
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
    #[error("sensor {sensor} ({kind}): {source}")]
    InSensor {
        sensor: usize,
        kind: SensorKind,
        source: Box<CaptureError>,
    },
    #[error(
        "the sensors ran at different rates ({rates}); a record has one rate: export each sensor's samples (`imunoise export`) and analyse them apart"
    )]
    RatesDiffer { rates: String },
}

/// Decodes a capture as its bytes arrive, in chunks of any size: the one decoder behind
/// both a live capture and a replay of its file, so both give the same record bit for bit.
///
/// **Sensors.** Each sensor the board lists has its own stream ([`stream`]): samples,
/// faults and recoveries go to the sensor they name; Info, Status and the host's notes are
/// the board's. The accessors without a sensor number ([`StreamDecoder::accounting`],
/// [`StreamDecoder::recoveries`] ...) are sensor 0's, which is the whole capture of a
/// one-sensor board; the counts of all sensors together are [`StreamDecoder::totals`].
///
/// **Board restarts.** A board that resets mid-stream announces itself again (a new Info)
/// and numbers its samples from 0 again. Indices restarting would otherwise look like
/// batches repeating old ones (discarded), so a restart — an Info after samples, or a batch
/// going back in both index and board time — ends the current run, is recorded in
/// [`SensorCapture::restarts`], and the new segment's indices continue past the old
/// segment's (`session index = segment base + board index`). Samples the board never sent
/// between its reset and its new start are unknowable and are not counted as lost.
pub struct StreamDecoder {
    decoder: FrameDecoder,
    first_info: Option<DeviceInfo>,
    status: Option<Status>,
    /// By sensor number; sensor 0 always exists.
    streams: Vec<SensorStream>,
    keep_samples: bool,
    board_errors: Vec<BoardReport>,
    /// A [`HostNote::BoardRestarted`] waiting for the restart it measured.
    silent_before_restart_us: Option<u64>,
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

/// Samples of all sensors together ([`StreamDecoder::totals`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Totals {
    pub received: u64,
    pub lost: u64,
    pub gaps: u64,
    pub out_of_order_batches: u64,
}

impl Totals {
    fn of<'a>(accountings: impl Iterator<Item = &'a SampleAccounting>) -> Totals {
        accountings.fold(Totals::default(), |t, a| Totals {
            received: t.received + a.received(),
            lost: t.lost + a.lost(),
            gaps: t.gaps + a.gaps().len() as u64,
            out_of_order_batches: t.out_of_order_batches + a.out_of_order_batches(),
        })
    }
}

impl StreamDecoder {
    /// `keep_samples: false` counts without keeping the samples (a long live capture, whose
    /// samples are in its file anyway).
    pub fn new(keep_samples: bool) -> Self {
        StreamDecoder {
            decoder: FrameDecoder::new(),
            first_info: None,
            status: None,
            streams: vec![SensorStream::new(keep_samples)],
            keep_samples,
            board_errors: Vec::new(),
            silent_before_restart_us: None,
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

    /// Sensor `sensor`'s stream, made when first named (a sensor number is a byte, so at
    /// most 256 streams whatever the bytes say).
    fn stream(&mut self, sensor: u8) -> &mut SensorStream {
        let k = usize::from(sensor);
        while self.streams.len() <= k {
            let mut stream = SensorStream::new(self.keep_samples);
            if self.streams[0].keep.tap.is_some() {
                stream.keep.tap = Some(Tap::default());
            }
            self.streams.push(stream);
        }
        &mut self.streams[k]
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
            DeviceMessage::Samples(batch) => self.batch(0, &batch),
            DeviceMessage::SensorSamples { sensor, batch } => self.batch(sensor, &batch),
            DeviceMessage::Nack { seq, error } => self.board_error(Some(seq), None, error),
            DeviceMessage::Fault(error) => self.fault(0, error),
            DeviceMessage::SensorFault { sensor, error } => self.fault(sensor, error),
            DeviceMessage::Recovered {
                attempts,
                resumed_at_index,
            } => self.recovered(0, attempts, resumed_at_index),
            DeviceMessage::SensorRecovered {
                sensor,
                attempts,
                resumed_at_index,
            } => self.recovered(sensor, attempts, resumed_at_index),
            // Acks and pongs carry nothing to keep.
            DeviceMessage::Ack { .. } | DeviceMessage::Pong { .. } => {}
        }
    }

    fn fault(&mut self, sensor: u8, error: ErrorCode) {
        if let ErrorCode::GaveUp { ended_at, .. } = error {
            // The run's tail, never delivered: lost, up to where the board stopped.
            self.stream(sensor).gave_up_at(ended_at);
        }
        self.board_error(None, Some(sensor), error)
    }

    fn recovered(&mut self, sensor: u8, attempts: u16, resumed_at_index: u64) {
        self.stream(sensor)
            .recovered(sensor, attempts, resumed_at_index);
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
        if self.streams.iter().any(|s| s.samples_in_segment) {
            self.restart();
        }
        self.first_info.get_or_insert(info);
        for (k, sensor) in info.sensor_list().iter().enumerate() {
            // At most MAX_SENSORS entries: the number fits a byte.
            self.stream(k as u8).listed(*sensor);
        }
    }

    fn board_error(&mut self, refused_seq: Option<u16>, sensor: Option<u8>, error: ErrorCode) {
        let at_index = self.stream(sensor.unwrap_or(0)).accounting.expected();
        self.board_errors.push(BoardReport {
            sensor,
            at_index,
            refused_seq,
            error,
        });
    }

    /// The board restarted: a new segment in every sensor's stream.
    fn restart(&mut self) {
        let silent_us = self.silent_before_restart_us.take();
        for stream in &mut self.streams {
            stream.restart(silent_us);
        }
    }

    /// Status messages seen so far (a watcher asks for one and waits for the count to move).
    pub fn statuses_seen(&self) -> u64 {
        self.statuses_seen
    }

    fn batch(&mut self, sensor: u8, batch: &SampleBatch) {
        if self.stream(sensor).restarted_before(batch) {
            self.restart();
        }
        self.stream(sensor).batch(batch);
    }

    pub fn info_seen(&self) -> Option<&DeviceInfo> {
        self.first_info.as_ref()
    }

    /// Keep the samples decoded from here on for [`StreamDecoder::take_tapped`], without
    /// keeping the whole capture: a live view's feed.
    pub fn tap(&mut self) {
        for stream in &mut self.streams {
            stream.keep.tap.get_or_insert_with(Tap::default);
        }
    }

    /// Sensor 0's samples decoded since the last call, and the number of the gap-free run
    /// they belong to (a new number: a gap or a restart began a new run, and the samples are
    /// that run's first). `None` unless [`StreamDecoder::tap`]ped.
    pub fn take_tapped(&mut self) -> Option<(usize, Vec<RawSample>)> {
        self.take_tapped_of(0)
    }

    /// [`StreamDecoder::take_tapped`] for sensor `sensor`.
    pub fn take_tapped_of(&mut self, sensor: usize) -> Option<(usize, Vec<RawSample>)> {
        self.streams
            .get_mut(sensor)?
            .keep
            .tap
            .as_mut()
            .map(|t| (t.run, std::mem::take(&mut t.samples)))
    }

    /// Sensor 0's settings in force for the samples arriving: the last Info's, if it is
    /// an MPU-6050.
    pub fn settings(&self) -> Option<SensorSettings> {
        match self.streams[0].config? {
            SensorConfig::Mpu6050(settings) => Some(settings),
            _ => None,
        }
    }

    /// The settings in force of every sensor listed so far, by number.
    pub fn configs(&self) -> Vec<Option<SensorConfig>> {
        self.streams.iter().map(|s| s.config).collect()
    }

    /// Sensor 0's accounting (the whole capture's on a one-sensor board).
    pub fn accounting(&self) -> &SampleAccounting {
        &self.streams[0].accounting
    }

    /// Sensor `sensor`'s accounting, if the capture has that sensor.
    pub fn accounting_of(&self, sensor: usize) -> Option<&SampleAccounting> {
        self.streams.get(sensor).map(|s| &s.accounting)
    }

    /// The samples of all sensors together.
    pub fn totals(&self) -> Totals {
        Totals::of(self.streams.iter().map(|s| &s.accounting))
    }

    /// Sensor 0's output rate, Hz, once an Info said it.
    pub fn rate_hz(&self) -> Option<f64> {
        self.streams[0].config.map(|c| c.output_rate_hz())
    }

    /// Whether every sensor listed has accounted for (received or lost) `duration_s` of
    /// samples at its own rate: the samples `duration_s * rate`, rounded.
    pub fn covers(&self, duration_s: f64) -> bool {
        self.streams.iter().all(|s| match s.config {
            Some(config) => {
                let wanted = (duration_s * config.output_rate_hz()).round() as u64;
                s.accounting.expected() >= wanted
            }
            None => false,
        })
    }

    pub fn status(&self) -> Option<&Status> {
        self.status.as_ref()
    }
    pub fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }
    /// Sensor 0's session indices where the board restarted unmeasured (every sensor's
    /// stream restarts with the board).
    pub fn restarts(&self) -> &[u64] {
        &self.streams[0].restarts
    }
    /// Refusals and faults so far.
    pub fn board_errors(&self) -> &[BoardReport] {
        &self.board_errors
    }
    /// Sensor 0's recoveries so far.
    pub fn recoveries(&self) -> &[RecoveryReport] {
        &self.streams[0].recoveries
    }
    /// Every sensor's recoveries so far, sensor by sensor.
    pub fn all_recoveries(&self) -> impl Iterator<Item = &RecoveryReport> {
        self.streams.iter().flat_map(|s| s.recoveries.iter())
    }
    /// Bytes of a frame not yet closed by its delimiter.
    pub fn pending(&self) -> usize {
        self.decoder.pending()
    }

    /// End of the capture: a silence the host measured that no restart ended (the board
    /// never came back) is lost at the tail, counted as a gap like any other.
    pub fn settle(&mut self) {
        let Some(silent_us) = self.silent_before_restart_us.take() else {
            return;
        };
        for stream in &mut self.streams {
            stream.close_after_silence(silent_us);
        }
    }

    /// The capture so far. Status counters are cumulative since the board powered up, not
    /// since Start, so they cannot close the index range; losses after the last batch show
    /// in them.
    pub fn finish(mut self) -> Result<Capture, CaptureError> {
        self.settle();
        let info = self.first_info.ok_or(CaptureError::NoInfo)?;
        let listed = info.sensor_list();
        let sensors = self
            .streams
            .into_iter()
            .enumerate()
            .map(|(k, stream)| {
                // A sensor whose samples came but no Info listed: taken for the first
                // listed one's kind, so that its samples are at least kept and counted.
                let fallback = listed.get(k).or(listed.get(0)).copied();
                stream.finish(fallback.unwrap_or(SensorInfo {
                    kind: SensorKind::Mpu6050,
                    address: protocol::mpu6050::DEFAULT_ADDRESS,
                    id: info.who_am_i,
                    config: SensorConfig::Mpu6050(info.settings),
                }))
            })
            .collect();
        Ok(Capture {
            info,
            sensors,
            status: self.status,
            decoder: self.decoder.stats(),
            trailing_bytes: self.decoder.pending(),
            board_errors: self.board_errors,
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

    /// Sensor 0's part: the whole capture of a one-sensor board.
    pub fn first(&self) -> &SensorCapture {
        &self.sensors[0]
    }

    /// The samples of all sensors together.
    pub fn totals(&self) -> Totals {
        Totals::of(self.sensors.iter().map(|s| &s.accounting))
    }

    /// Board restarts the host did not measure (each restarts every sensor's stream).
    pub fn restarts(&self) -> usize {
        self.first().restarts.len()
    }

    /// Every sensor's recoveries, sensor by sensor.
    pub fn recoveries(&self) -> impl Iterator<Item = &RecoveryReport> {
        self.sensors.iter().flat_map(|s| s.recoveries.iter())
    }
}

#[cfg(test)]
mod tests;

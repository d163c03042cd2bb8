//! The board's behaviour as the host sees it: commands in, replies and samples out.
//!
//! [`Firmware`] owns the sensor driver, the clock and the run; the board (or the host's
//! virtual board, or a test) calls two functions and moves bytes:
//!
//! ```text
//! loop {
//!     fw.handle_bytes(&bytes_from_usb, &mut send);   // commands -> replies
//!     fw.poll(&mut send);                            // drain the FIFO when due -> samples
//! }
//! // send(frame) -> bool: queue one whole frame for the host, or return false if it does
//! // not fit right now (USB back-pressure). Never block: a refused sample batch is dropped
//! // and counted (Status::batches_dropped, samples_dropped); a refused reply is kept and
//! // offered again on the next call.
//! ```
//!
//! States: stopped (configure allowed) and streaming. Every command is answered: GetInfo
//! with Info, Ping with Pong, GetStatus with Status, the others with Ack or Nack and the
//! reason ([`ErrorCode`]). Frames that fail COBS or CRC are counted
//! ([`Status::frames_rejected`]) and otherwise ignored; an intact frame that is no known
//! command is counted too and refused by its `seq` ([`ErrorCode::UnknownCommand`]). A fault
//! while streaming (the sensor stops answering, resets itself, or reports an impossible FIFO
//! count) sends [`DeviceMessage::Fault`] and the board sets the sensor up again by itself
//! ([`crate::recovery`]); while it tries, it still counts as streaming. Every
//! [`HEALTH_INTERVAL_US`] a streaming board also reads the sensor's configuration back, so a
//! sensor that reset to its power-on defaults is found even if its FIFO count looks sane.
//! A reply that finds the reply queue full is dropped and counted
//! ([`Status::replies_dropped`]).

use crate::acquire::{Acquisition, Resume, Timeline, check_supported, period_us};
use crate::driver::{BusClear, Mpu6050};
use crate::recovery::{Recovery, STABLE_RUN_US};
use crate::timing::Clock;
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::frame::{FrameDecoder, FrameError, MAX_WIRE_LEN, encode};
use protocol::{
    Command, DeviceInfo, DeviceMessage, ErrorCode, MAX_SAMPLES_PER_BATCH, PROTOCOL_VERSION,
    Request, ResetReason, SampleBatch, SensorConfig, SensorList, SensorSettings, Status,
};

/// Replies waiting for room on the link.
const REPLY_QUEUE: usize = 8;

/// How often a streaming board reads the sensor's configuration back.
pub const HEALTH_INTERVAL_US: u64 = 1_000_000;

/// Board facts the portable code cannot find out itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardConfig {
    /// The sensor's 7-bit I2C address (0x68, or 0x69 with AD0 high).
    pub address: u8,
    /// A unique id of the board (the RP2040's flash unique id).
    pub board_id: u64,
    /// Why the chip last started, as its reset registers say.
    pub reset_reason: ResetReason,
}

/// Every message except sample batches: small, so a few can wait for the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reply {
    Info(DeviceInfo),
    Ack {
        seq: u16,
    },
    Nack {
        seq: u16,
        error: ErrorCode,
    },
    Status(Status),
    Pong {
        seq: u16,
    },
    Fault(ErrorCode),
    Recovered {
        attempts: u16,
        resumed_at_index: u64,
    },
}

impl From<Reply> for DeviceMessage {
    fn from(r: Reply) -> Self {
        match r {
            Reply::Info(i) => DeviceMessage::Info(i),
            Reply::Ack { seq } => DeviceMessage::Ack { seq },
            Reply::Nack { seq, error } => DeviceMessage::Nack { seq, error },
            Reply::Status(s) => DeviceMessage::Status(s),
            Reply::Pong { seq } => DeviceMessage::Pong { seq },
            Reply::Fault(e) => DeviceMessage::Fault(e),
            Reply::Recovered {
                attempts,
                resumed_at_index,
            } => DeviceMessage::Recovered {
                attempts,
                resumed_at_index,
            },
        }
    }
}

/// The portable firmware (module docs).
pub struct Firmware<I2C, C> {
    dev: Mpu6050<I2C>,
    clock: C,
    board_id: u64,
    address: u8,
    reset_reason: ResetReason,
    /// What WHO_AM_I answered last (0: never answered).
    who_am_i: u8,
    settings: SensorSettings,
    /// The sensor holds `settings`, awake, FIFO channels selected.
    ready: bool,
    run: Option<Acquisition>,
    /// A run that ended with a fault and is being brought back.
    recovery: Option<Recovery>,
    /// The last recovery and when its run resumed, until the run has been stable for
    /// [`crate::recovery::STABLE_RUN_US`].
    resumed: Option<(Recovery, u64)>,
    /// When the streaming sensor's configuration is next read back.
    next_health_us: u64,
    /// Counters kept here; uptime, I2C errors and rejected frames are filled in on report.
    counters: Status,
    decoder: FrameDecoder,
    replies: heapless::Deque<Reply, REPLY_QUEUE>,
    /// The number the next frame sent carries (from 0 at power-up).
    frames_sent: u32,
}

impl<I2C: I2c + BusClear, C: Clock> Firmware<I2C, C> {
    pub fn new(i2c: I2C, clock: C, config: BoardConfig) -> Self {
        Firmware {
            dev: Mpu6050::new(i2c, config.address),
            clock,
            board_id: config.board_id,
            address: config.address,
            reset_reason: config.reset_reason,
            who_am_i: 0,
            settings: SensorSettings::default(),
            ready: false,
            run: None,
            recovery: None,
            resumed: None,
            next_health_us: 0,
            counters: Status {
                loss_certain: true,
                ..Status::default()
            },
            decoder: FrameDecoder::new(),
            replies: heapless::Deque::new(),
            frames_sent: 0,
        }
    }

    /// Power-up: device reset (with the datasheet's 100 ms waits), then the default
    /// settings. A sensor that is absent or wrong is not fatal: the error is returned (for
    /// the board's log) and every later Configure or Start tries again and reports it.
    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        self.probe()?;
        self.dev.reset(delay)?;
        let settings = self.settings;
        self.set_up(settings)
    }

    /// The bus, e.g. to move a simulated sensor's clock.
    pub fn i2c_mut(&mut self) -> &mut I2C {
        self.dev.i2c_mut()
    }

    pub fn clock_mut(&mut self) -> &mut C {
        &mut self.clock
    }

    /// Streaming as the host sees it: a run, or a run being recovered.
    pub fn streaming(&self) -> bool {
        self.run.is_some() || self.recovery.is_some()
    }

    pub fn settings(&self) -> SensorSettings {
        self.settings
    }

    /// The counters as the host would receive them now.
    pub fn status(&mut self) -> Status {
        Status {
            streaming: self.streaming(),
            uptime_us: self.clock.now_us(),
            i2c_errors: self.dev.i2c_errors(),
            frames_rejected: u32::try_from(self.decoder.stats().rejected()).unwrap_or(u32::MAX),
            sample_period_ns: match (&self.run, &self.recovery) {
                (Some(run), _) => run.grid().period_ns(),
                (None, Some(r)) => r.timeline.period_ns(),
                (None, None) => self.counters.sample_period_ns,
            },
            ..self.counters
        }
    }

    /// Bytes from the host (any chunking): decode frames, carry out each command, send the
    /// replies. Never blocks.
    pub fn handle_bytes(&mut self, incoming: &[u8], out: &mut impl FnMut(&[u8]) -> bool) {
        for byte in incoming {
            let mut request = None;
            let mut unknown_seq = None;
            self.decoder
                .feed_salvaging::<Request>(core::slice::from_ref(byte), |r| match r {
                    Ok(r) => request = Some(r),
                    // Intact but unreadable: its leading seq (a varint, as in every
                    // Request) names it in the refusal. Damaged frames are only counted.
                    Err((FrameError::Malformed, body)) => {
                        unknown_seq = protocol::peek_request_seq(body)
                    }
                    Err(_) => {}
                });
            if let Some(request) = request {
                self.handle(request, out);
            }
            if let Some(seq) = unknown_seq {
                self.reply(Reply::Nack {
                    seq,
                    error: ErrorCode::UnknownCommand,
                });
            }
        }
        self.flush_replies(out);
    }

    /// The host closed the port (DTR dropped): stop streaming as a Stop would, and forget
    /// the replies nobody will read. The next host starts from a stopped board with the
    /// settings it last had; the counters keep counting.
    pub fn host_left(&mut self) {
        self.replies.clear();
        if let Some(recovery) = self.recovery.take() {
            let now = self.clock.now_us();
            self.count_loss(&recovery.timeline, now, None);
        }
        if self.run.take().is_some() {
            // Best effort: a failure shows at the next Start.
            let _ = self.dev.disable_fifo();
        }
        self.resumed = None;
    }

    /// Drain the FIFO if a drain is due and send the samples; send waiting replies. Call
    /// it as often as possible (every main-loop turn); it returns at once when nothing is due.
    pub fn poll(&mut self, out: &mut impl FnMut(&[u8]) -> bool) {
        self.flush_replies(out);
        let now = self.clock.now_us();
        if self.run.as_ref().is_some_and(|run| run.due(now))
            && let Err(error) = self.drain(out)
        {
            self.fault(error);
        }
        if self.run.is_some() && now >= self.next_health_us {
            self.next_health_us = now.saturating_add(HEALTH_INTERVAL_US);
            // A read that fails is the drains' business (they end the run if it persists).
            if self.dev.check_streaming(&self.settings) == Err(ErrorCode::SensorReset) {
                self.fault(ErrorCode::SensorReset);
            }
        }
        if self.recovery.as_ref().is_some_and(|r| r.due(now)) {
            self.attempt_recovery();
        }
        self.flush_replies(out);
    }

    /// One drain; batches the link refuses are dropped and counted.
    fn drain(&mut self, out: &mut impl FnMut(&[u8]) -> bool) -> Result<(), ErrorCode> {
        let Some(run) = self.run.as_mut() else {
            return Ok(());
        };
        let (mut batches_dropped, mut samples_dropped) = (0u32, 0u64);
        let frames_sent = &mut self.frames_sent;
        let mut deliver = |batch: SampleBatch| {
            let len = batch.samples.len() as u64;
            if !send(out, frames_sent, &DeviceMessage::Samples(batch)) {
                batches_dropped += 1;
                samples_dropped += len;
            }
        };
        let result = run.drain(
            &mut self.dev,
            &mut self.clock,
            &mut self.counters,
            &mut deliver,
        );
        let c = &mut self.counters;
        c.batches_dropped = c.batches_dropped.saturating_add(batches_dropped);
        c.samples_dropped = c.samples_dropped.saturating_add(samples_dropped);
        result.map(|_| ())
    }

    /// The run ended with `error`: report it and start bringing the sensor back.
    fn fault(&mut self, error: ErrorCode) {
        let now = self.clock.now_us();
        let Some(run) = self.run.take() else {
            return;
        };
        self.counters.sample_period_ns = run.grid().period_ns();
        self.ready = false;
        let relapse = self.resumed.take().filter(|(episode, at)| {
            now.saturating_sub(*at) < STABLE_RUN_US && episode.last_error == error
        });
        self.recovery = Some(match relapse {
            Some((episode, _)) => episode.relapse(run.timeline(), error, now),
            None => {
                self.reply(Reply::Fault(error));
                Recovery::new(run.timeline(), error, now)
            }
        });
    }

    /// One recovery attempt: clear the bus, probe, set up, restart the FIFO numbering from
    /// where the old run's grid says the sensor is. A failure waits for the next attempt or,
    /// after [`protocol::GAVE_UP_AFTER_S`], stops streaming.
    fn attempt_recovery(&mut self) {
        let Some(mut recovery) = self.recovery.take() else {
            return;
        };
        recovery.attempts = recovery.attempts.saturating_add(1);
        self.dev.i2c_mut().clear_bus();
        let settings = self.settings;
        let started = self
            .probe()
            .and_then(|()| self.set_up(settings))
            .and_then(|()| self.dev.check_awake())
            .and_then(|()| {
                let resume = Resume {
                    timeline: recovery.timeline.clone(),
                };
                check_supported(&settings)?;
                let period = period_us(&settings);
                Acquisition::start(&mut self.dev, &mut self.clock, period, Some(resume))
            });
        let now = self.clock.now_us();
        match started {
            Ok(run) => {
                self.count_loss(&recovery.timeline, now, Some(run.next_index()));
                self.counters.loss_certain &= run.resume_certain();
                self.reply(Reply::Recovered {
                    attempts: recovery.attempts,
                    resumed_at_index: run.next_index(),
                });
                self.counters.recoveries = self.counters.recoveries.saturating_add(1);
                self.next_health_us = now.saturating_add(HEALTH_INTERVAL_US);
                self.run = Some(run);
                self.resumed = Some((recovery, now));
            }
            Err(error) => {
                if recovery.failed(error, now) {
                    self.recovery = Some(recovery);
                    return;
                }
                self.count_loss(&recovery.timeline, now, None);
                let _ = self.dev.disable_fifo();
                self.reply(Reply::Fault(ErrorCode::GaveUp {
                    attempts: recovery.attempts,
                    last: error.into(),
                    ended_at: recovery.timeline.index_at(now).0,
                }));
            }
        }
    }

    /// Count as lost every sample between the ended run's last delivered one and `now_us`
    /// (or `resumed_at`, the index a resumed run starts at).
    fn count_loss(&mut self, timeline: &Timeline, now_us: u64, resumed_at: Option<u64>) {
        let (at_now, certain) = timeline.index_at(now_us);
        let until = resumed_at.unwrap_or(at_now);
        let lost = until.saturating_sub(timeline.next_index());
        self.counters.samples_lost = self.counters.samples_lost.saturating_add(lost);
        self.counters.loss_certain &= certain || lost == 0;
    }

    fn handle(&mut self, Request { seq, command }: Request, out: &mut impl FnMut(&[u8]) -> bool) {
        let result = match command {
            Command::GetInfo => {
                let info = self.info();
                self.reply(Reply::Info(info));
                return;
            }
            Command::Ping => {
                self.reply(Reply::Pong { seq });
                return;
            }
            Command::GetStatus => {
                let status = self.status();
                self.reply(Reply::Status(status));
                return;
            }
            Command::Configure(settings) => self.configure(settings),
            Command::ConfigureSensor {
                sensor: 0,
                config: SensorConfig::Mpu6050(settings),
            } => self.configure(settings),
            Command::ConfigureSensor { sensor, .. } => Err(ErrorCode::NoSuchSensor { sensor }),
            Command::Start => self.start(),
            Command::Stop => self.stop(out),
        };
        match result {
            Ok(()) => self.reply(Reply::Ack { seq }),
            Err(error) => self.reply(Reply::Nack { seq, error }),
        }
        if command == Command::Stop && result.is_ok() {
            let status = self.status();
            self.reply(Reply::Status(status));
        }
    }

    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: crate::FIRMWARE_VERSION,
            board_id: self.board_id,
            who_am_i: self.who_am_i,
            settings: self.settings,
            streaming: self.streaming(),
            max_samples_per_batch: MAX_SAMPLES_PER_BATCH as u16,
            reset_reason: self.reset_reason,
            sensors: SensorList::mpu6050(self.address, self.who_am_i, self.settings),
        }
    }

    fn configure(&mut self, settings: SensorSettings) -> Result<(), ErrorCode> {
        if self.streaming() {
            return Err(ErrorCode::Busy);
        }
        check_supported(&settings)?;
        self.probe()?;
        self.set_up(settings)
    }

    fn start(&mut self) -> Result<(), ErrorCode> {
        if self.streaming() {
            return Err(ErrorCode::Busy);
        }
        self.resumed = None;
        if !self.ready {
            self.probe()?;
            self.set_up(self.settings)?;
        }
        self.dev.check_awake()?;
        check_supported(&self.settings)?;
        let period = period_us(&self.settings);
        let run = Acquisition::start(&mut self.dev, &mut self.clock, period, None);
        self.run = Some(run?);
        self.next_health_us = self.clock.now_us().saturating_add(HEALTH_INTERVAL_US);
        Ok(())
    }

    /// A last drain (everything made until now reaches the host, before the Ack), then
    /// the FIFO off.
    fn stop(&mut self, out: &mut impl FnMut(&[u8]) -> bool) -> Result<(), ErrorCode> {
        if !self.streaming() {
            return Err(ErrorCode::NotStreaming);
        }
        if let Some(recovery) = self.recovery.take() {
            let now = self.clock.now_us();
            self.count_loss(&recovery.timeline, now, None);
            // Best effort: the sensor is the problem.
            let _ = self.dev.disable_fifo();
            return Ok(());
        }
        self.flush_replies(out);
        if let Err(error) = self.drain(out) {
            self.reply(Reply::Fault(error));
        }
        self.run = None;
        self.dev.disable_fifo()
    }

    fn probe(&mut self) -> Result<(), ErrorCode> {
        self.who_am_i = 0;
        match self.dev.probe() {
            Ok(chip) => {
                self.who_am_i = chip.who_am_i;
                Ok(())
            }
            Err(e) => {
                if let ErrorCode::WrongSensor { who_am_i } = e {
                    self.who_am_i = who_am_i;
                }
                self.ready = false;
                Err(e)
            }
        }
    }

    /// Wake, write `settings`, select the FIFO channels; FIFO off until Start.
    fn set_up(&mut self, settings: SensorSettings) -> Result<(), ErrorCode> {
        self.ready = false;
        self.dev.wake()?;
        self.dev.configure(&settings)?;
        self.dev.enable_fifo()?;
        self.dev.disable_fifo()?;
        self.settings = settings;
        self.ready = true;
        Ok(())
    }

    fn reply(&mut self, reply: Reply) {
        // A host that sends commands without reading replies loses the newest ones, counted.
        if self.replies.push_back(reply).is_err() {
            self.counters.replies_dropped = self.counters.replies_dropped.saturating_add(1);
        }
    }

    fn flush_replies(&mut self, out: &mut impl FnMut(&[u8]) -> bool) {
        while let Some(reply) = self.replies.front().copied() {
            if !send(out, &mut self.frames_sent, &DeviceMessage::from(reply)) {
                return;
            }
            self.replies.pop_front();
        }
    }
}

/// Encode one message as a frame numbered `counter` ([`protocol::DeviceFrame`]) and offer it
/// to the link; the number is used up only if the link takes the frame, so a jump in the
/// numbers the host sees is a frame lost after it left the board.
fn send(out: &mut impl FnMut(&[u8]) -> bool, counter: &mut u32, message: &DeviceMessage) -> bool {
    let mut buf = [0u8; MAX_WIRE_LEN];
    match encode(&(message, *counter), &mut buf) {
        Ok(len) => {
            let taken = out(&buf[..len]);
            if taken {
                *counter = counter.wrapping_add(1);
            }
            taken
        }
        // Cannot happen for our messages (a test checks the largest batch fits).
        Err(_) => false,
    }
}

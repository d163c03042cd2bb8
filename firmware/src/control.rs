//! The board's behaviour as the host sees it: commands in, replies and samples out.
//!
//! [`Firmware`] owns the sensors it found on the bus ([`crate::slot`]), the clock and the
//! replies; the board (or the host's virtual board, or a test) calls two functions and moves
//! bytes:
//!
//! ```text
//! loop {
//!     fw.handle_bytes(&bytes_from_usb, &mut send);   // commands -> replies
//!     fw.poll(&mut send);                            // drain the buffers when due -> samples
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
//! command is counted too and refused by its `seq` ([`ErrorCode::UnknownCommand`]). A reply
//! that finds the reply queue full is dropped and counted ([`Status::replies_dropped`]).
//!
//! Start starts every sensor, each numbering its samples from 0; Stop drains every one, then
//! acknowledges, then sends the Status. Each sensor's faults and recoveries are its own
//! ([`crate::stream`]): the others stream on. Sensor 0's messages are the untagged ones
//! (`Samples`, `Fault`, `Recovered`), so a one-MPU-6050 board's stream is what protocol 3
//! sent. A board that found no sensor probes the bus again on GetInfo, Configure and Start.

use crate::driver::BusClear;
use crate::reply::{Reply, send};
use crate::slot::{Sensors, Slot, probe_bus};
use crate::stream::Outlet;
use crate::timing::Clock;
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::frame::{FrameDecoder, FrameError};
use protocol::{
    Command, DeviceInfo, DeviceMessage, ErrorCode, MAX_SAMPLES_PER_BATCH, PROTOCOL_VERSION,
    Request, ResetReason, SampleBatch, SensorConfig, SensorList, SensorSettings, Status,
};

pub use crate::stream::HEALTH_INTERVAL_US;

/// Replies waiting for room on the link.
const REPLY_QUEUE: usize = 8;

/// Board facts the portable code cannot find out itself (the sensors it finds by probing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardConfig {
    /// A unique id of the board (the RP2040's flash unique id).
    pub board_id: u64,
    /// Why the chip last started, as its reset registers say.
    pub reset_reason: ResetReason,
}

/// The portable firmware (module docs).
pub struct Firmware<I2C: I2c + BusClear, C> {
    /// The bus, cloned for every sensor's driver and for probing.
    bus: I2C,
    clock: C,
    board_id: u64,
    reset_reason: ResetReason,
    sensors: Sensors<I2C>,
    /// Why the last probe found no sensor (its WHO_AM_I shows in Info).
    absent: Option<ErrorCode>,
    decoder: FrameDecoder,
    replies: heapless::Deque<Reply, REPLY_QUEUE>,
    replies_dropped: u32,
    /// The number the next frame sent carries (from 0 at power-up).
    frames_sent: u32,
}

/// The link as the streams see it: samples straight to the host, replies into the queue.
struct Link<'a, F> {
    out: &'a mut F,
    frames_sent: &'a mut u32,
    replies: &'a mut heapless::Deque<Reply, REPLY_QUEUE>,
    replies_dropped: &'a mut u32,
}

impl<F: FnMut(&[u8]) -> bool> Outlet for Link<'_, F> {
    fn samples(&mut self, sensor: u8, batch: SampleBatch) -> bool {
        let message = DeviceMessage::samples_of(sensor, batch);
        send(self.out, self.frames_sent, &message)
    }

    fn reply(&mut self, reply: Reply) {
        queue(self.replies, self.replies_dropped, reply);
    }
}

/// A host that sends commands without reading replies loses the newest ones, counted.
fn queue(replies: &mut heapless::Deque<Reply, REPLY_QUEUE>, dropped: &mut u32, reply: Reply) {
    if replies.push_back(reply).is_err() {
        *dropped = dropped.saturating_add(1);
    }
}

impl<I2C: I2c + BusClear + Clone, C: Clock> Firmware<I2C, C> {
    /// The firmware on `bus` (each sensor's driver gets its own clone: they share the one
    /// bus) with `clock`. Nothing touches the bus before [`Firmware::init`].
    pub fn new(bus: I2C, clock: C, config: BoardConfig) -> Self {
        Firmware {
            bus,
            clock,
            board_id: config.board_id,
            reset_reason: config.reset_reason,
            sensors: Sensors::new(),
            absent: Some(ErrorCode::SensorNotResponding),
            decoder: FrameDecoder::new(),
            replies: heapless::Deque::new(),
            replies_dropped: 0,
            frames_sent: 0,
        }
    }

    /// Power-up: probe the bus, then reset each sensor found and set it up with its default
    /// settings. A board with no sensor, or one that fails, is not fatal: the first error is
    /// returned (for the board's log) and every later Configure or Start tries again and
    /// reports it.
    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        self.probe()?;
        let mut result = Ok(());
        for slot in &mut self.sensors {
            result = result.and(slot.init(delay));
        }
        result
    }

    /// The bus, e.g. to move a simulated sensor's clock.
    pub fn bus_mut(&mut self) -> &mut I2C {
        &mut self.bus
    }

    pub fn clock_mut(&mut self) -> &mut C {
        &mut self.clock
    }

    /// Streaming as the host sees it: some sensor has a run, or a run being recovered.
    pub fn streaming(&self) -> bool {
        self.sensors.iter().any(Slot::streaming)
    }

    /// The sensors found, with their settings.
    pub fn sensors(&self) -> SensorList {
        let mut list = SensorList::default();
        for slot in &self.sensors {
            let _ = list.push(slot.info());
        }
        list
    }

    /// Sensor 0's settings if it is an MPU-6050 (the `settings` of [`DeviceInfo`]), else
    /// the default.
    pub fn settings(&self) -> SensorSettings {
        match self.sensors.first().map(Slot::info) {
            Some(info) => match info.config {
                SensorConfig::Mpu6050(s) => s,
                _ => SensorSettings::default(),
            },
            None => SensorSettings::default(),
        }
    }

    /// The counters as the host would receive them now: each sensor's summed, sensor 0's
    /// sample period, the loss certain only if every sensor's is.
    pub fn status(&mut self) -> Status {
        let mut total = Status {
            streaming: self.streaming(),
            uptime_us: self.clock.now_us(),
            frames_rejected: u32::try_from(self.decoder.stats().rejected()).unwrap_or(u32::MAX),
            replies_dropped: self.replies_dropped,
            loss_certain: true,
            ..Status::default()
        };
        for (number, slot) in self.sensors.iter().enumerate() {
            let c = slot.counters();
            total.samples_acquired = total.samples_acquired.saturating_add(c.samples_acquired);
            total.fifo_overflows = total.fifo_overflows.saturating_add(c.fifo_overflows);
            total.samples_lost = total.samples_lost.saturating_add(c.samples_lost);
            total.i2c_errors = total.i2c_errors.saturating_add(c.i2c_errors);
            total.batches_dropped = total.batches_dropped.saturating_add(c.batches_dropped);
            total.samples_dropped = total.samples_dropped.saturating_add(c.samples_dropped);
            total.recoveries = total.recoveries.saturating_add(c.recoveries);
            total.loss_certain &= c.loss_certain;
            if number == 0 {
                total.sample_period_ns = c.sample_period_ns;
            }
        }
        total
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
        for slot in &mut self.sensors {
            slot.host_left(&mut self.clock);
        }
    }

    /// Drain every sensor whose drain is due and send the samples; send waiting replies.
    /// Call it as often as possible (every main-loop turn); it returns at once when nothing
    /// is due.
    pub fn poll(&mut self, out: &mut impl FnMut(&[u8]) -> bool) {
        self.flush_replies(out);
        let mut link = Link {
            out,
            frames_sent: &mut self.frames_sent,
            replies: &mut self.replies,
            replies_dropped: &mut self.replies_dropped,
        };
        for slot in &mut self.sensors {
            slot.poll(&mut self.clock, &mut link);
        }
        self.flush_replies(out);
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
            Command::ConfigureSensor { sensor, config } => self.configure_sensor(sensor, config),
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

    fn info(&mut self) -> DeviceInfo {
        // A board that found nothing looks again: the sensor may have been plugged in.
        let _ = self.probe();
        let who_am_i = match (self.sensors.first(), self.absent) {
            (Some(slot), _) => slot.info().id,
            (None, Some(ErrorCode::WrongSensor { who_am_i })) => who_am_i,
            (None, _) => 0,
        };
        DeviceInfo {
            protocol_version: PROTOCOL_VERSION,
            firmware_version: crate::FIRMWARE_VERSION,
            board_id: self.board_id,
            who_am_i,
            settings: self.settings(),
            streaming: self.streaming(),
            max_samples_per_batch: MAX_SAMPLES_PER_BATCH as u16,
            reset_reason: self.reset_reason,
            sensors: self.sensors(),
        }
    }

    /// Sensor 0's settings, which must be an MPU-6050's.
    fn configure(&mut self, settings: SensorSettings) -> Result<(), ErrorCode> {
        if self.streaming() {
            return Err(ErrorCode::Busy);
        }
        crate::acquire::check_supported(&settings)?;
        self.probe()?;
        match self.sensors.first_mut() {
            Some(slot @ Slot::Mpu6050(_)) => slot.configure(SensorConfig::Mpu6050(settings)),
            _ => Err(ErrorCode::InvalidSettings),
        }
    }

    fn configure_sensor(&mut self, sensor: u8, config: SensorConfig) -> Result<(), ErrorCode> {
        if self.streaming() {
            return Err(ErrorCode::Busy);
        }
        self.probe()?;
        match self.sensors.get_mut(usize::from(sensor)) {
            Some(slot) => slot.configure(config),
            None => Err(ErrorCode::NoSuchSensor { sensor }),
        }
    }

    /// Start every sensor, or none: one that fails stops those started before it.
    fn start(&mut self) -> Result<(), ErrorCode> {
        if self.streaming() {
            return Err(ErrorCode::Busy);
        }
        self.probe()?;
        let mut failed = None;
        for slot in &mut self.sensors {
            if let Err(e) = slot.start(&mut self.clock) {
                failed = Some(e);
                break;
            }
        }
        match failed {
            Some(error) => {
                for slot in &mut self.sensors {
                    slot.host_left(&mut self.clock);
                }
                Err(error)
            }
            None => Ok(()),
        }
    }

    /// A last drain of every sensor (everything made until now reaches the host, before
    /// the Ack), then their buffers off; the first error is the reply.
    fn stop(&mut self, out: &mut impl FnMut(&[u8]) -> bool) -> Result<(), ErrorCode> {
        if !self.streaming() {
            return Err(ErrorCode::NotStreaming);
        }
        self.flush_replies(out);
        let mut link = Link {
            out,
            frames_sent: &mut self.frames_sent,
            replies: &mut self.replies,
            replies_dropped: &mut self.replies_dropped,
        };
        let mut result = Ok(());
        for slot in &mut self.sensors {
            result = result.and(slot.stop(&mut self.clock, &mut link));
        }
        result
    }

    /// Probe the bus if no sensor is known; the reason if none answers.
    fn probe(&mut self) -> Result<(), ErrorCode> {
        if self.sensors.is_empty() {
            let found = probe_bus(&self.bus);
            self.sensors = found.sensors;
            self.absent = found.absent;
        }
        match self.absent {
            Some(error) if self.sensors.is_empty() => Err(error),
            _ => Ok(()),
        }
    }

    fn reply(&mut self, reply: Reply) {
        queue(&mut self.replies, &mut self.replies_dropped, reply);
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

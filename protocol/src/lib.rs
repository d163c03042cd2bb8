//! The contract between the imunoise board and the host.
//!
//! Read this file as an interface control document: every message that crosses the USB
//! serial link is declared here, in the order its bytes appear on the wire (postcard encodes
//! struct fields in declaration order and enum variants by their index). How a message
//! becomes bytes is in [`frame`]; what a sensor setting means is in [`mpu6050`].
//!
//! `no_std`, no allocation: the firmware and the host share these very types.
//!
//! # Commands and replies
//!
//! The host sends a [`Request`] `{ seq, command }`; every reply that answers it carries the
//! same `seq`. "Since" is the [`PROTOCOL_VERSION`] that introduced the row.
//!
//! | host sends ([`Command`]) | board replies ([`DeviceMessage`]) | refused with ([`ErrorCode`] in `Nack`) | since |
//! | --- | --- | --- | --- |
//! | `GetInfo` | `Info(`[`DeviceInfo`]`)` | never | 1 |
//! | `Configure(`[`SensorSettings`]`)`: sensor 0, an MPU-6050 | `Ack`, or `Nack` | `Busy` while streaming; `InvalidSettings` (also when sensor 0 is no MPU-6050); the sensor's errors (`SensorNotResponding`, `WrongSensor`, `VerifyFailed`, `I2cFailure`) | 1 |
//! | `ConfigureSensor { sensor, config: `[`SensorConfig`]` }` | `Ack`, or `Nack` | as `Configure`; `NoSuchSensor` for a number the board does not list or a config of another kind | 4 |
//! | `Start` | `Ack`, then samples of every sensor until Stop; or `Nack` | `Busy` while streaming; the sensors' errors | 1 |
//! | `Stop` | `Ack`, then a final `Status(`[`Status`]`)`; or `Nack` | `NotStreaming` | 1 |
//! | `Ping` | `Pong` | never | 1 |
//! | `GetStatus` | `Status(`[`Status`]`)` | never | 1 |
//! | an intact frame that is no command | `Nack` | `UnknownCommand` | 2 |
//!
//! Unasked, while streaming, the board also sends `Samples`, `Fault(`[`ErrorCode`]`)` when the
//! sensor fails (since 1) and `Recovered` when samples flow again (since 3); a fault that
//! ends the run is `Fault(GaveUp)` (since 3). Every device frame carries its number
//! ([`DeviceFrame`], since 3).
//!
//! **Several sensors** (since 4). [`DeviceInfo::sensors`] lists what the board found
//! ([`sensors`]). Sensor 0 speaks as a one-sensor board always did (`Samples`, `Fault`,
//! `Recovered`), so an MPU-6050 board's stream is unchanged but for its Info; every other
//! sensor's samples, faults and recoveries come tagged with its number (`SensorSamples`,
//! `SensorFault`, `SensorRecovered`). [`DeviceMessage::samples_of`],
//! [`DeviceMessage::fault_of`] and [`DeviceMessage::recovered_of`] build the right variant
//! for a sensor number; [`DeviceMessage::sensor_samples`] reads either back. Each sensor
//! numbers its own samples from 0 at Start, at its own rate.
#![no_std]
#![forbid(unsafe_code)]
// Nothing on the data path may panic: errors are values sent to the other side.
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod adxl345;
pub mod cobs;
pub mod frame;
pub mod itg3200;
pub mod mpu6050;
pub mod sensors;

use serde::{Deserialize, Serialize};

pub use mpu6050::SensorSettings;
pub use sensors::{MAX_SENSORS, SensorConfig, SensorInfo, SensorKind, SensorList};

/// Version of everything in this crate that shapes bytes on the wire.
///
/// Bump it on any change to a message, the framing or the meaning of a setting. The host
/// refuses a board whose [`DeviceInfo::protocol_version`] differs. To make that refusal
/// possible across versions, two things never change: [`DeviceMessage::Info`] is variant 0
/// and `protocol_version` is the first field of [`DeviceInfo`] (see [`peek_info_version`]).
///
/// History: 1, the first; 2 added [`ErrorCode::UnknownCommand`] (the board now refuses an
/// intact frame it cannot read instead of only counting it); 3 made a fault something the
/// board recovers from ([`DeviceMessage::Recovered`], [`ErrorCode::GaveUp`],
/// [`ErrorCode::SensorReset`]), numbered every device frame ([`DeviceFrame`]), accepted clone
/// chips ([`mpu6050::KNOWN_CHIPS`]) and appended
/// the recovery counters to [`Status`] and the reset reason to [`DeviceInfo`] (a version-2
/// Status or Info still decodes: [`Status::decode_v2`], [`DeviceInfo::decode_v2`]); 4 let a
/// board stream several sensors: [`DeviceInfo::sensors`], [`Command::ConfigureSensor`], the
/// tagged messages and [`ErrorCode::NoSuchSensor`] (a version-3 Info still decodes:
/// [`DeviceInfo::decode_v3`]).
pub const PROTOCOL_VERSION: u16 = 4;

/// Most samples one [`SampleBatch`] carries: 32 samples are 32 ms at 1 kHz, so a batch
/// leaves the board at least every 32 ms at the top rate while one frame stays well under
/// [`frame::MAX_FRAME_LEN`] (checked by a test with worst-case values).
pub const MAX_SAMPLES_PER_BATCH: usize = 32;

// ----------------------------------------------------------------------------------------
// Host -> device
// ----------------------------------------------------------------------------------------

/// One command from the host. `seq` is chosen by the host and echoed in the reply
/// ([`DeviceMessage::Ack`], [`DeviceMessage::Nack`], [`DeviceMessage::Pong`]) so replies can
/// be matched to requests even when sample batches arrive in between.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct Request {
    pub seq: u16,
    pub command: Command,
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// Reply: [`DeviceMessage::Info`].
    GetInfo,
    /// Write these settings to the sensor (only while stopped). Reply: Ack or Nack.
    Configure(SensorSettings),
    /// Reset the FIFO and the sample index, then stream [`DeviceMessage::Samples`].
    /// Reply: Ack or Nack.
    Start,
    /// Stop streaming; a final [`DeviceMessage::Status`] follows the Ack.
    Stop,
    /// Reply: [`DeviceMessage::Pong`] with the same `seq`.
    Ping,
    /// Reply: [`DeviceMessage::Status`].
    GetStatus,
    /// Write `config` to sensor number `sensor` (only while stopped). Reply: Ack or Nack.
    ConfigureSensor { sensor: u8, config: SensorConfig },
}

// ----------------------------------------------------------------------------------------
// Device -> host
// ----------------------------------------------------------------------------------------

/// Everything the board sends.
// Samples is far larger than the other variants; boxing it would need an allocator, which
// the board has not, and the board builds one message at a time anyway.
#[allow(clippy::large_enum_variant)]
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq, Eq)]
pub enum DeviceMessage {
    /// Must stay variant 0 (see [`PROTOCOL_VERSION`]).
    Info(DeviceInfo),
    /// The command with this `seq` was carried out.
    Ack {
        seq: u16,
    },
    /// The command with this `seq` was refused, and why.
    Nack {
        seq: u16,
        error: ErrorCode,
    },
    Samples(SampleBatch),
    Status(Status),
    Pong {
        seq: u16,
    },
    /// Something went wrong that no command asked about (the sensor stopped answering,
    /// reset itself, reported an impossible FIFO count). The board clears the bus and sets
    /// the sensor up again by itself, with backoff, and says [`DeviceMessage::Recovered`]
    /// when samples flow again; only [`ErrorCode::GaveUp`] means streaming has stopped.
    Fault(ErrorCode),
    /// Streaming resumed after a fault. Sample indices kept counting through the time lost,
    /// so the gap before `resumed_at_index` is the loss (also in [`Status::samples_lost`]).
    Recovered {
        /// Set-up attempts it took (1: the first worked).
        attempts: u16,
        /// Index of the first sample of the resumed run.
        resumed_at_index: u64,
    },
    /// `Samples` of sensor number `sensor` (never 0).
    SensorSamples {
        sensor: u8,
        batch: SampleBatch,
    },
    /// `Fault` of sensor number `sensor` (never 0).
    SensorFault {
        sensor: u8,
        error: ErrorCode,
    },
    /// `Recovered` of sensor number `sensor` (never 0).
    SensorRecovered {
        sensor: u8,
        attempts: u16,
        resumed_at_index: u64,
    },
}

impl DeviceMessage {
    /// Sensor `sensor`'s batch as the board sends it: `Samples` for sensor 0, else tagged.
    pub fn samples_of(sensor: u8, batch: SampleBatch) -> DeviceMessage {
        match sensor {
            0 => DeviceMessage::Samples(batch),
            _ => DeviceMessage::SensorSamples { sensor, batch },
        }
    }

    /// Sensor `sensor`'s fault as the board sends it: `Fault` for sensor 0, else tagged.
    pub fn fault_of(sensor: u8, error: ErrorCode) -> DeviceMessage {
        match sensor {
            0 => DeviceMessage::Fault(error),
            _ => DeviceMessage::SensorFault { sensor, error },
        }
    }

    /// Sensor `sensor`'s recovery as the board sends it: `Recovered` for sensor 0, else
    /// tagged.
    pub fn recovered_of(sensor: u8, attempts: u16, resumed_at_index: u64) -> DeviceMessage {
        match sensor {
            0 => DeviceMessage::Recovered {
                attempts,
                resumed_at_index,
            },
            _ => DeviceMessage::SensorRecovered {
                sensor,
                attempts,
                resumed_at_index,
            },
        }
    }

    /// The sensor number and batch of either samples variant.
    pub fn sensor_samples(&self) -> Option<(u8, &SampleBatch)> {
        match self {
            DeviceMessage::Samples(batch) => Some((0, batch)),
            DeviceMessage::SensorSamples { sensor, batch } => Some((*sensor, batch)),
            _ => None,
        }
    }
}

/// A device frame's body as read: the message, and the frame counter that follows it.
///
/// The board numbers the frames it hands to the link (0, 1, 2 ... from power-up, wrapping),
/// and appends the number to each body as a varint after the message. After the message, so
/// that a decoder that reads only the message (any earlier host, [`peek_info_version`])
/// still reads it; the host counts a jump in the numbers as frames lost between the board's
/// link buffer and its own decoder (a lost Status or Fault included), and a number going
/// back as the board restarting. Version-2 bodies have no counter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceFrame {
    pub message: DeviceMessage,
    pub counter: Option<u32>,
}

impl DeviceFrame {
    /// A frame body: the message, then the counter if any is there; `None` if the body is
    /// no message, or something other than one varint follows it.
    pub fn decode(body: &[u8]) -> Option<DeviceFrame> {
        let (message, rest) = match peek_info_version(body) {
            Some(3) => {
                let (info, rest) = DeviceInfo::decode_v3(body)?;
                (DeviceMessage::Info(info), rest)
            }
            _ => postcard::take_from_bytes::<DeviceMessage>(body).ok()?,
        };
        let counter = if rest.is_empty() {
            None
        } else {
            let (counter, rest) = postcard::take_from_bytes::<u32>(rest).ok()?;
            if !rest.is_empty() {
                return None;
            }
            Some(counter)
        };
        Some(DeviceFrame { message, counter })
    }
}

/// Who the board is and what it is doing.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Must stay the first field (see [`PROTOCOL_VERSION`]).
    pub protocol_version: u16,
    pub firmware_version: FirmwareVersion,
    /// A unique id of the board (the RP2040's flash unique id).
    pub board_id: u64,
    /// What the sensor answered to WHO_AM_I (0x68 for an MPU-6050); 0 if it did not answer.
    pub who_am_i: u8,
    /// The settings in force on the sensor.
    pub settings: SensorSettings,
    pub streaming: bool,
    /// [`MAX_SAMPLES_PER_BATCH`] as compiled into this firmware.
    pub max_samples_per_batch: u16,
    /// Why the board last started: a board that rebooted by its watchdog during a night
    /// says so. Defaults when missing from a self-describing format.
    #[serde(default)]
    pub reset_reason: ResetReason,
    /// Every sensor the board found and streams, by number ([`sensors`]). `who_am_i` and
    /// `settings` above are sensor 0's when it is an MPU-6050 (a GY-85 board: the ITG-3200's
    /// WHO_AM_I and the default MPU-6050 settings). Defaults, empty, when missing from a
    /// self-describing format: read [`DeviceInfo::sensor_list`].
    #[serde(default)]
    pub sensors: SensorList,
}

impl DeviceInfo {
    /// The sensors the board streams: [`DeviceInfo::sensors`], or for an Info without a list
    /// (before version 4) the one MPU-6050 that `who_am_i` and `settings` describe.
    pub fn sensor_list(&self) -> SensorList {
        if !self.sensors.is_empty() {
            return self.sensors;
        }
        SensorList::mpu6050(mpu6050::DEFAULT_ADDRESS, self.who_am_i, self.settings)
    }
}

/// Why the board's chip last started (the RP2040's CHIP_RESET and WATCHDOG REASON
/// registers).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ResetReason {
    /// Not known (an emulated or simulated board, or a version-2 Info).
    #[default]
    Unknown,
    /// Power applied, or the supply dipped below the brown-out level.
    PowerOn,
    /// The RUN pin (a reset button).
    RunPin,
    /// The watchdog expired: the firmware hung and was restarted.
    Watchdog,
    /// A debugger or the firmware itself asked for the restart.
    Requested,
}

/// [`DeviceInfo`] as protocol version 2 sent it, kept so that stored version-2 captures
/// still decode.
#[derive(Deserialize)]
struct DeviceInfoV2 {
    protocol_version: u16,
    firmware_version: FirmwareVersion,
    board_id: u64,
    who_am_i: u8,
    settings: SensorSettings,
    streaming: bool,
    max_samples_per_batch: u16,
}

/// [`DeviceInfo`] as protocol version 3 sent it: version 2's fields and the reset reason.
#[derive(Deserialize)]
struct DeviceInfoV3 {
    v2: DeviceInfoV2,
    reset_reason: ResetReason,
}

impl DeviceInfoV2 {
    fn into_info(self, reset_reason: ResetReason) -> DeviceInfo {
        DeviceInfo {
            protocol_version: self.protocol_version,
            firmware_version: self.firmware_version,
            board_id: self.board_id,
            who_am_i: self.who_am_i,
            settings: self.settings,
            streaming: self.streaming,
            max_samples_per_batch: self.max_samples_per_batch,
            reset_reason,
            sensors: SensorList::default(),
        }
    }
}

impl DeviceInfo {
    /// A version-2 Info message body (variant 0, then the seven fields it had), or `None`.
    /// Its sensor is the one MPU-6050 ([`DeviceInfo::sensor_list`]).
    pub fn decode_v2(body: &[u8]) -> Option<DeviceInfo> {
        let (&variant, rest) = body.split_first()?;
        if variant != 0 {
            return None;
        }
        let v2: DeviceInfoV2 = postcard::from_bytes(rest).ok()?;
        (v2.protocol_version == 2).then(|| v2.into_info(ResetReason::Unknown))
    }

    /// A version-3 Info message body (version 2's fields and the reset reason) and what
    /// follows it (its frame number), or `None`. Its sensor is the one MPU-6050.
    /// [`DeviceFrame::decode`] uses it for every version-3 Info: read as version 4, the
    /// frame number would be taken for the sensor list.
    pub fn decode_v3(body: &[u8]) -> Option<(DeviceInfo, &[u8])> {
        let (&variant, rest) = body.split_first()?;
        if variant != 0 {
            return None;
        }
        let (v3, rest): (DeviceInfoV3, _) = postcard::take_from_bytes(rest).ok()?;
        (v3.v2.protocol_version == 3).then(|| (v3.v2.into_info(v3.reset_reason), rest))
    }
}

#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct FirmwareVersion {
    pub major: u16,
    pub minor: u16,
    pub patch: u16,
}

impl core::fmt::Display for FirmwareVersion {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// Consecutive samples as the sensor's FIFO delivered them.
///
/// Sample `k` of `samples` is sample number `first_index + k` since the last
/// [`Command::Start`]. Indices are never reused: samples the board could not deliver leave a
/// gap in the indices, so the host can count every lost sample exactly.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq, Eq)]
pub struct SampleBatch {
    /// Index of `samples[0]` since start (0-based).
    pub first_index: u64,
    /// Board clock (microseconds since boot) at which the sensor made `samples[0]`: the
    /// firmware's sample grid (firmware/src/timing.rs) places every index on the sensor's
    /// own period, phase-locked to the FIFO counts it reads.
    pub first_timestamp_us: u64,
    pub samples: heapless::Vec<RawSample, MAX_SAMPLES_PER_BATCH>,
}

/// One FIFO sample, as the MPU-6050 register counts, in FIFO order: accel X, Y, Z,
/// temperature, gyro X, Y, Z (each a big-endian i16 in the FIFO, 14 bytes in all).
/// [`mpu6050`] converts counts to SI units.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RawSample {
    pub accel: [i16; 3],
    pub temp: i16,
    pub gyro: [i16; 3],
}

impl RawSample {
    /// Bytes per sample in the FIFO with accel, temperature and gyro enabled.
    pub const FIFO_BYTES: usize = 14;

    /// Parse the 14 bytes the FIFO (or the ACCEL_XOUT_H..GYRO_ZOUT_L burst) delivers.
    pub fn from_fifo_bytes(b: &[u8; Self::FIFO_BYTES]) -> Self {
        let word = |i: usize| i16::from_be_bytes([b[2 * i], b[2 * i + 1]]);
        RawSample {
            accel: [word(0), word(1), word(2)],
            temp: word(3),
            gyro: [word(4), word(5), word(6)],
        }
    }

    /// The inverse of [`RawSample::from_fifo_bytes`] (used by the simulated sensor).
    pub fn to_fifo_bytes(&self) -> [u8; Self::FIFO_BYTES] {
        let words = [
            self.accel[0],
            self.accel[1],
            self.accel[2],
            self.temp,
            self.gyro[0],
            self.gyro[1],
            self.gyro[2],
        ];
        let mut out = [0u8; Self::FIFO_BYTES];
        for (chunk, w) in out.chunks_exact_mut(2).zip(words) {
            chunk.copy_from_slice(&w.to_be_bytes());
        }
        out
    }
}

/// Cumulative counters since the board powered up (they never reset, so the host can take
/// differences between any two reports). On a board with several sensors the sample, loss,
/// overflow, I2C, drop and recovery counters are the sums over its sensors, `loss_certain`
/// holds only if it holds for every sensor, and `sample_period_ns` is sensor 0's. The fields
/// version 3 appended default when missing from a self-describing format (a stored JSON copy
/// of a version-2 Status).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status {
    pub streaming: bool,
    /// Board clock, microseconds since boot.
    pub uptime_us: u64,
    /// Samples read from the sensors' buffers and put into batches, all sensors together.
    pub samples_acquired: u64,
    /// Times a sensor's FIFO overflowed (and was reset), all sensors together.
    pub fifo_overflows: u32,
    /// Samples the sensors produced that never reached a batch (FIFO overflows, sensor
    /// faults), counted from elapsed time and each sensor's output rate, all together.
    pub samples_lost: u64,
    /// I2C transactions that failed (each retry that fails counts), all sensors' drivers
    /// together; a probe of an empty address is not counted.
    pub i2c_errors: u32,
    /// Batches discarded because the USB link could not take them (back-pressure), all
    /// sensors together...
    pub batches_dropped: u32,
    /// ...and the samples they held.
    pub samples_dropped: u64,
    /// Frames from the host that were rejected (bad COBS, CRC or content).
    pub frames_rejected: u32,
    /// Replies (Ack, Nack, Status, Pong, Fault, Recovered) dropped because the reply queue
    /// was full: a host that sends commands without reading.
    #[serde(default)]
    pub replies_dropped: u32,
    /// Faults the board recovered from while streaming, all sensors together.
    #[serde(default)]
    pub recoveries: u32,
    /// Whether every loss counted so far is exact, on every sensor: a loss is measured on
    /// the sensor's sample grid, which is certain unless a gap was long and the sensor's
    /// clock not yet measured (see the firmware's timing module).
    #[serde(default)]
    pub loss_certain: bool,
    /// Sensor 0's sample period as measured on the board's clock during the current or last
    /// run, nanoseconds (0: not measured yet).
    #[serde(default)]
    pub sample_period_ns: u32,
}

/// [`Status`] as protocol version 2 sent it (the first nine fields), kept so that stored
/// version-2 captures still decode.
#[derive(Deserialize)]
struct StatusV2 {
    streaming: bool,
    uptime_us: u64,
    samples_acquired: u64,
    fifo_overflows: u32,
    samples_lost: u64,
    i2c_errors: u32,
    batches_dropped: u32,
    samples_dropped: u64,
    frames_rejected: u32,
}

impl Status {
    /// The variant index of [`DeviceMessage::Status`] in a frame body.
    const VARIANT: u8 = 4;

    /// A version-2 Status message body (variant index, then nine fields), or `None`. The
    /// fields version 3 appended are unknown: zero, and `loss_certain` false.
    pub fn decode_v2(body: &[u8]) -> Option<Status> {
        let (&variant, rest) = body.split_first()?;
        if variant != Self::VARIANT {
            return None;
        }
        let v2: StatusV2 = postcard::from_bytes(rest).ok()?;
        Some(Status {
            streaming: v2.streaming,
            uptime_us: v2.uptime_us,
            samples_acquired: v2.samples_acquired,
            fifo_overflows: v2.fifo_overflows,
            samples_lost: v2.samples_lost,
            i2c_errors: v2.i2c_errors,
            batches_dropped: v2.batches_dropped,
            samples_dropped: v2.samples_dropped,
            frames_rejected: v2.frames_rejected,
            ..Status::default()
        })
    }
}

/// Why a command was refused or what fault occurred.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCode {
    /// Configure or Start while streaming: send Stop first.
    Busy,
    /// Stop while not streaming.
    NotStreaming,
    /// The settings are not valid for this sensor (e.g. the reserved DLPF_CFG 7).
    InvalidSettings,
    /// The sensor did not answer on I2C (after retries).
    SensorNotResponding,
    /// The identity register (WHO_AM_I, DEVID) gave a value that is not the expected chip's.
    WrongSensor { who_am_i: u8 },
    /// A register read back a different value than was written.
    VerifyFailed { register: u8, wrote: u8, read: u8 },
    /// I2C errors persisted beyond the retry budget.
    I2cFailure,
    /// FIFO_COUNT reported a byte count the clock rules out (more samples than the sensor
    /// can have made, or none for far too long) while the sensor still reads awake.
    /// Appended last so that the encodings of the other codes stay as they were.
    FifoCountImplausible { count: u16 },
    /// A frame arrived intact (its CRC matched) but is no command this firmware knows: a
    /// host speaking another protocol version, or a bug. Refused by its `seq`. Appended
    /// last, like the one before.
    UnknownCommand,
    /// The sensor's configuration read back as its power-on defaults (or otherwise not as
    /// written) while streaming: it reset itself, and the board sets it up again.
    SensorReset,
    /// Recovery failed `attempts` times in a row over [`GAVE_UP_AFTER_S`] seconds, the last
    /// time with `last`'s reason (a code of its own, so only its name is kept): streaming
    /// has stopped until the host starts it again. The sensor's samples up to (not
    /// including) index `ended_at` are accounted for: those after the last one delivered are
    /// lost, a gap the host counts at the end of the run.
    GaveUp {
        attempts: u16,
        last: FaultKind,
        ended_at: u64,
    },
    /// [`Command::ConfigureSensor`] named a sensor the board does not list, or gave it a
    /// config of another kind. Appended last, like the ones before.
    NoSuchSensor { sensor: u8 },
}

/// How long the board keeps trying to bring a failed sensor back before it stops streaming
/// and says [`ErrorCode::GaveUp`].
pub const GAVE_UP_AFTER_S: u32 = 600;

/// The reason of the last failed recovery attempt, inside [`ErrorCode::GaveUp`] (an
/// [`ErrorCode`] cannot hold itself).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    SensorNotResponding,
    WrongSensor,
    VerifyFailed,
    I2cFailure,
    FifoCountImplausible,
    SensorReset,
    Other,
}

impl From<ErrorCode> for FaultKind {
    fn from(e: ErrorCode) -> Self {
        match e {
            ErrorCode::SensorNotResponding => FaultKind::SensorNotResponding,
            ErrorCode::WrongSensor { .. } => FaultKind::WrongSensor,
            ErrorCode::VerifyFailed { .. } => FaultKind::VerifyFailed,
            ErrorCode::I2cFailure => FaultKind::I2cFailure,
            ErrorCode::FifoCountImplausible { .. } => FaultKind::FifoCountImplausible,
            ErrorCode::SensorReset => FaultKind::SensorReset,
            _ => FaultKind::Other,
        }
    }
}

impl core::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ErrorCode::Busy => f.write_str("the board is streaming; send stop first"),
            ErrorCode::NotStreaming => f.write_str("the board is not streaming"),
            ErrorCode::InvalidSettings => f.write_str("the settings are not valid for the sensor"),
            ErrorCode::SensorNotResponding => f.write_str("the sensor does not answer on I2C"),
            ErrorCode::WrongSensor { who_am_i } => write!(
                f,
                "the identity register reads {who_am_i:#04x}, which is no chip this firmware \
                 knows (MPU-6050 and clones 0x68, 0x70, 0x72, 0x98; ITG-3200 0x68/0x69; \
                 ADXL345 0xE5)"
            ),
            ErrorCode::VerifyFailed {
                register,
                wrote,
                read,
            } => write!(
                f,
                "register {register:#04x} read back {read:#04x} after writing {wrote:#04x}"
            ),
            ErrorCode::I2cFailure => f.write_str("I2C errors persisted after retries"),
            ErrorCode::FifoCountImplausible { count } => write!(
                f,
                "the sensor's FIFO count ({count} bytes) disagrees with its sample rate"
            ),
            ErrorCode::UnknownCommand => {
                f.write_str("an intact frame that is no command this firmware knows")
            }
            ErrorCode::SensorReset => f.write_str(
                "the sensor reset itself (its registers read back as power-on defaults)",
            ),
            ErrorCode::GaveUp { attempts, last, .. } => write!(
                f,
                "gave up after {attempts} recovery attempts over {GAVE_UP_AFTER_S} s \
                 (last: {last:?}); streaming stopped"
            ),
            ErrorCode::NoSuchSensor { sensor } => write!(
                f,
                "the board lists no sensor {sensor} of that kind (see its Info's sensors)"
            ),
        }
    }
}

impl core::error::Error for ErrorCode {}

/// The protocol version inside a frame body that holds a [`DeviceMessage::Info`] of *any*
/// protocol version, or `None` if the body is not an Info message.
///
/// This works across versions because Info is variant 0 and `protocol_version` its first
/// field, so a host can say "board speaks version 3, host speaks 1" instead of failing to
/// decode.
pub fn peek_info_version(body: &[u8]) -> Option<u16> {
    let (variant, rest): (u32, &[u8]) = postcard::take_from_bytes(body).ok()?;
    if variant != 0 {
        return None;
    }
    let (version, _): (u16, &[u8]) = postcard::take_from_bytes(rest).ok()?;
    Some(version)
}

/// The `seq` at the head of a frame body meant as a [`Request`], even when the rest is
/// not a command this version knows (`seq` is the first field, a postcard varint).
pub fn peek_request_seq(body: &[u8]) -> Option<u16> {
    let (seq, _): (u16, &[u8]) = postcard::take_from_bytes(body).ok()?;
    Some(seq)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifo_bytes_are_big_endian_in_fifo_order() {
        // Datasheet order: ACCEL_XOUT_H, ACCEL_XOUT_L, ..., TEMP_OUT_H, TEMP_OUT_L, GYRO_XOUT_H...
        let bytes = [
            0x01, 0x02, 0xFF, 0xFE, 0x40, 0x00, 0xF2, 0x50, 0x00, 0x83, 0x80, 0x00, 0x7F, 0xFF,
        ];
        let s = RawSample::from_fifo_bytes(&bytes);
        assert_eq!(s.accel, [0x0102, -2, 16384]);
        assert_eq!(s.temp, -3504);
        assert_eq!(s.gyro, [131, i16::MIN, i16::MAX]);
        assert_eq!(s.to_fifo_bytes(), bytes);
    }

    #[test]
    fn a_version_2_status_still_decodes() {
        // Variant 4 and the nine fields version 2 sent, in order.
        let v2 = (
            4u8,
            true,
            1_000_000u64,
            5u64,
            1u32,
            7u64,
            2u32,
            3u32,
            96u64,
            4u32,
        );
        let mut buf = [0u8; 64];
        let body = postcard::to_slice(&v2, &mut buf).unwrap();
        let status = Status::decode_v2(body).unwrap();
        assert_eq!(
            status,
            Status {
                streaming: true,
                uptime_us: 1_000_000,
                samples_acquired: 5,
                fifo_overflows: 1,
                samples_lost: 7,
                i2c_errors: 2,
                batches_dropped: 3,
                samples_dropped: 96,
                frames_rejected: 4,
                ..Status::default()
            }
        );
        // A version-3 Status is longer; decode_v2 is only the fallback for what does not
        // decode as version 3, and another variant is not a Status at all.
        assert!(postcard::from_bytes::<DeviceMessage>(body).is_err());
        let pong = postcard::to_slice(&DeviceMessage::Pong { seq: 3 }, &mut buf).unwrap();
        assert_eq!(Status::decode_v2(pong), None);
    }

    #[test]
    fn a_frame_body_is_the_message_then_its_number() {
        let message = DeviceMessage::Pong { seq: 300 };
        let mut buf = [0u8; 32];
        let numbered = postcard::to_slice(&(&message, 70_000u32), &mut buf).unwrap();
        let frame = DeviceFrame::decode(numbered).unwrap();
        assert_eq!(frame.message, message);
        assert_eq!(frame.counter, Some(70_000));
        // Readers of the message alone still read it.
        assert_eq!(
            postcard::from_bytes::<DeviceMessage>(numbered).unwrap(),
            message
        );
        let len = numbered.len();
        // A version-2 body: no number.
        let mut buf2 = [0u8; 32];
        let bare = postcard::to_slice(&message, &mut buf2).unwrap();
        assert_eq!(DeviceFrame::decode(bare).unwrap().counter, None);
        // Anything but one varint after the message is not a frame of ours.
        let mut longer = [0u8; 33];
        longer[..len].copy_from_slice(&buf[..len]);
        longer[len] = 5;
        assert_eq!(DeviceFrame::decode(&longer[..len + 1]), None);
    }

    #[test]
    fn a_version_2_info_still_decodes() {
        let settings = SensorSettings::default();
        // Variant 0 and the seven fields version 2 sent.
        let v2 = (
            0u8,
            2u16,
            (0u16, 1u16, 0u16),
            7u64,
            0x68u8,
            settings,
            false,
            32u16,
        );
        let mut buf = [0u8; 64];
        let body = postcard::to_slice(&v2, &mut buf).unwrap();
        let info = DeviceInfo::decode_v2(body).unwrap();
        assert_eq!((info.protocol_version, info.board_id), (2, 7));
        assert_eq!(info.settings, settings);
        assert_eq!(info.reset_reason, ResetReason::Unknown);
        assert!(postcard::from_bytes::<DeviceMessage>(body).is_err());
    }

    #[test]
    fn a_version_3_info_still_decodes_with_its_frame_number() {
        let settings = SensorSettings::default();
        // Variant 0, the seven fields of version 2, the reset reason (Watchdog is 3), then
        // a frame number whose first byte would read as a sensor count.
        let v3 = (
            0u8,
            3u16,
            (0u16, 2u16, 0u16),
            7u64,
            0x68u8,
            settings,
            true,
            32u16,
            3u8,
            2u32,
        );
        let mut buf = [0u8; 64];
        let body = postcard::to_slice(&v3, &mut buf).unwrap();
        let frame = DeviceFrame::decode(body).unwrap();
        assert_eq!(frame.counter, Some(2));
        let DeviceMessage::Info(info) = frame.message else {
            panic!("not an Info: {:?}", frame.message);
        };
        assert_eq!((info.protocol_version, info.board_id), (3, 7));
        assert_eq!(info.reset_reason, ResetReason::Watchdog);
        let list = info.sensor_list();
        assert_eq!(list.len(), 1);
        let sensor = list.get(0).unwrap();
        assert_eq!(sensor.kind, SensorKind::Mpu6050);
        assert_eq!(sensor.config, SensorConfig::Mpu6050(settings));
    }

    #[test]
    fn sensor_0_speaks_untagged_and_the_others_tagged() {
        let batch = SampleBatch {
            first_index: 5,
            first_timestamp_us: 9,
            samples: heapless::Vec::new(),
        };
        let zero = DeviceMessage::samples_of(0, batch.clone());
        assert_eq!(zero, DeviceMessage::Samples(batch.clone()));
        let one = DeviceMessage::samples_of(1, batch.clone());
        assert_eq!(one.sensor_samples(), Some((1, &batch)));
        assert_eq!(zero.sensor_samples(), Some((0, &batch)));
        assert_eq!(
            DeviceMessage::fault_of(1, ErrorCode::I2cFailure),
            DeviceMessage::SensorFault {
                sensor: 1,
                error: ErrorCode::I2cFailure
            }
        );
        assert_eq!(
            DeviceMessage::recovered_of(0, 2, 40),
            DeviceMessage::Recovered {
                attempts: 2,
                resumed_at_index: 40
            }
        );
        // Appended variants keep the earlier ones' indices: Samples is still 3.
        let mut buf = [0u8; 64];
        let body = postcard::to_slice(&zero, &mut buf).unwrap();
        assert_eq!(body[0], 3);
        let body = postcard::to_slice(&one, &mut buf).unwrap();
        assert_eq!(body[0], 8);
    }

    #[test]
    fn info_version_can_be_read_without_decoding_the_rest() {
        let info = DeviceMessage::Info(DeviceInfo {
            protocol_version: 0x1234,
            firmware_version: FirmwareVersion {
                major: 1,
                minor: 2,
                patch: 3,
            },
            board_id: 7,
            who_am_i: 0x68,
            settings: SensorSettings::default(),
            streaming: false,
            max_samples_per_batch: 32,
            reset_reason: ResetReason::Watchdog,
            sensors: SensorList::default(),
        });
        let mut buf = [0u8; 64];
        let body = postcard::to_slice(&info, &mut buf).unwrap();
        assert_eq!(peek_info_version(body), Some(0x1234));
        // A body from a future version with extra fields after the version still peeks.
        let future = [0u8, 0x05, 0xAA, 0xBB, 0xCC];
        assert_eq!(peek_info_version(&future), Some(5));
        let pong = postcard::to_slice(&DeviceMessage::Pong { seq: 3 }, &mut buf).unwrap();
        assert_eq!(peek_info_version(pong), None);
    }
}

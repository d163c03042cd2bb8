//! A simulated MPU-6050 on an I2C bus, at register level, behind `embedded_hal::i2c::I2c`
//! (1.0), so that the firmware's portable driver runs against it unchanged.
//!
//! What is modelled (register numbers from RM-MPU-6000A rev. 4.2, [`protocol::mpu6050::reg`]):
//! - WHO_AM_I (0x75) reads 0x68; the chip powers up asleep (PWR_MGMT_1 = 0x40) and makes no
//!   samples until bit 6 (SLEEP) is cleared; bit 7 (DEVICE_RESET) restores every register to
//!   its reset value (asleep, FIFO empty) and clears itself.
//! - SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG set the signal chain ([`super::imu`]); a
//!   change while awake restarts sampling with the new settings (the noise processes restart).
//! - Samples come at the output rate of the clock the caller drives ([`SimMpu6050::advance`],
//!   [`SimMpu6050::set_time_us`]): sample k of a run (k = 1, 2, ...) at `start + k / f_s`.
//!   Each updates the data registers ACCEL_XOUT_H..GYRO_ZOUT_L (big-endian i16), sets
//!   INT_STATUS bit 0 (DATA_RDY) if INT_ENABLE bit 0 is set, and, if USER_CTRL bit 6
//!   (FIFO_EN) is set, appends the channels enabled in FIFO_EN (0x23: bit 3 accel xyz 6 bytes,
//!   bit 7 temperature 2, bits 6/5/4 gyro x/y/z 2 each) in the datasheet's order accel, temp,
//!   gyro x, y, z.
//! - The FIFO holds 1024 bytes; when a sample does not fit, the oldest bytes are dropped
//!   (byte-wise: the head may then be mid-sample, as on the chip), the new ones written, and
//!   INT_STATUS bit 4 (FIFO_OFLOW) set if INT_ENABLE bit 4 is set. USER_CTRL bit 2
//!   (FIFO_RESET) empties the FIFO and clears itself.
//! - INT_STATUS clears when read. Status bits latch only for sources enabled in INT_ENABLE
//!   (the register map: a bit sets "when an interrupt has been generated"); a driver that
//!   polls must enable them.
//! - FIFO_COUNT_H/L (0x72-0x73) is the byte count, big-endian. Reading FIFO_R_W (0x74) pops a
//!   byte (an empty FIFO repeats the last byte read); writing it pushes one.
//! - The register pointer is the first byte of a write; reads and further written bytes
//!   auto-increment it, except at FIFO_R_W, which stays. Writes to read-only registers
//!   (data, INT_STATUS, FIFO_COUNT, WHO_AM_I) are ignored.
//! - Faults ([`Faults`]): NACK of the address or of written data, bus errors, a wrong
//!   WHO_AM_I, a stuck FIFO count, a device reset at a given time.
//!
//! Not modelled: the DMP, the auxiliary I2C master, self-test, interrupt pin configuration,
//! FIFO_EN's SLV bits, clock source selection, low-power cycle mode.

use super::imu::{Imu, ImuModel, RawSample, TrueInput};
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};
use protocol::mpu6050::{
    DEFAULT_ADDRESS, FIFO_SIZE, RegisterValues, SensorSettings, WHO_AM_I_VALUE, reg,
};
use std::collections::VecDeque;
use std::time::Duration;

/// PWR_MGMT_1 bits.
pub const DEVICE_RESET: u8 = 1 << 7;
pub const SLEEP: u8 = 1 << 6;
/// USER_CTRL bits.
pub const USER_FIFO_EN: u8 = 1 << 6;
pub const FIFO_RESET: u8 = 1 << 2;
pub const SIG_COND_RESET: u8 = 1 << 0;
/// INT_ENABLE / INT_STATUS bits.
pub const DATA_RDY: u8 = 1 << 0;
pub const FIFO_OFLOW: u8 = 1 << 4;
/// FIFO_EN bits.
pub const TEMP_FIFO_EN: u8 = 1 << 7;
pub const XG_FIFO_EN: u8 = 1 << 6;
pub const YG_FIFO_EN: u8 = 1 << 5;
pub const ZG_FIFO_EN: u8 = 1 << 4;
pub const ACCEL_FIFO_EN: u8 = 1 << 3;

/// The bus errors the simulated device produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SimI2cError {
    #[error("simulated MPU-6050: no acknowledge ({0:?})")]
    NoAcknowledge(NoAcknowledgeSource),
    #[error("simulated MPU-6050: bus error")]
    Bus,
}

impl embedded_hal::i2c::Error for SimI2cError {
    fn kind(&self) -> ErrorKind {
        match *self {
            SimI2cError::NoAcknowledge(s) => ErrorKind::NoAcknowledge(s),
            SimI2cError::Bus => ErrorKind::Bus,
        }
    }
}

/// Injected faults. The counts are numbers of coming transactions affected (`u32::MAX`:
/// all of them); each affected transaction fails without any effect on the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Faults {
    /// The address byte is not acknowledged.
    pub nack_address: u32,
    /// The first written byte is not acknowledged (transactions without a write are not
    /// affected and do not consume the count).
    pub nack_data: u32,
    /// The transaction ends in a bus error.
    pub bus_error: u32,
    /// WHO_AM_I reads this instead of 0x68.
    pub who_am_i: Option<u8>,
    /// FIFO_COUNT reads this whatever the FIFO holds.
    pub stuck_fifo_count: Option<u16>,
    /// A device reset (as by PWR_MGMT_1 bit 7) when the clock passes this time, us.
    pub reset_at_us: Option<u64>,
}

/// The simulated MPU-6050 (module documentation).
#[derive(Debug, Clone)]
pub struct SimMpu6050 {
    address: u8,
    regs: [u8; 128],
    pointer: u8,
    fifo: VecDeque<u8>,
    fifo_last_read: u8,
    model: ImuModel,
    seed: u64,
    /// Run length the noise processes are built for (their flicker band), s.
    duration_hint_s: f64,
    /// Sampling state while awake.
    run: Option<Run>,
    runs_started: u64,
    time_us: u64,
    faults: Faults,
    resets: u32,
    /// The scripted input ([`Imu::set_input`]), kept across runs.
    input: Option<TrueInput>,
    /// Byte-level bus state: the next written byte is a register pointer.
    expect_pointer: bool,
    /// Byte-level bus state: a byte was written since the last (non-repeated) start.
    written_since_start: bool,
    /// What the device did, when asked to keep a journal ([`SimMpu6050::keep_journal`]).
    journal: Option<Vec<JournalEntry>>,
}

/// An event in the device's journal: the truth a test compares a capture with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JournalEntry {
    /// The FIFO was emptied (USER_CTRL bit 2, or a device reset) at this time, us.
    FifoReset { time_us: u64 },
    /// A sample was made at this time, us; `in_fifo` if it was appended to the FIFO.
    Sample {
        time_us: u64,
        raw: RawSample,
        in_fifo: bool,
    },
}

#[derive(Debug, Clone)]
struct Run {
    imu: Imu,
    start_us: u64,
    samples: u64,
}

impl Run {
    /// Time of the next sample, us (fractional).
    fn next_us(&self) -> f64 {
        self.start_us as f64 + (self.samples + 1) as f64 * 1e6 / self.imu.output_rate_hz()
    }
}

impl SimMpu6050 {
    /// A device at address 0x68 simulating `model`, seeded by `seed`, at time 0, in its reset
    /// state (asleep).
    pub fn new(model: ImuModel, seed: u64) -> Self {
        let mut dev = SimMpu6050 {
            address: DEFAULT_ADDRESS,
            regs: [0; 128],
            pointer: 0,
            fifo: VecDeque::with_capacity(FIFO_SIZE),
            fifo_last_read: 0,
            model,
            seed,
            duration_hint_s: 3600.0,
            run: None,
            runs_started: 0,
            time_us: 0,
            faults: Faults::default(),
            resets: 0,
            expect_pointer: true,
            written_since_start: false,
            journal: None,
            input: None,
        };
        dev.device_reset();
        dev.resets = 0;
        dev
    }

    /// The same at another 7-bit address (0x69 with AD0 high).
    pub fn with_address(mut self, address: u8) -> Self {
        self.address = address;
        self
    }

    /// Build noise processes for runs of about `seconds` (default one hour).
    pub fn with_duration_hint(mut self, seconds: f64) -> Self {
        self.duration_hint_s = seconds;
        self
    }

    /// Turn and rotate the sensor (scripted procedures such as calibration): what it senses
    /// from now on, in this run and the next ones; `None` puts it back at rest.
    pub fn set_input(&mut self, input: Option<TrueInput>) {
        self.input = input;
        if let Some(run) = &mut self.run {
            run.imu.set_input(input);
        }
    }

    pub fn faults_mut(&mut self) -> &mut Faults {
        &mut self.faults
    }

    /// Start keeping a journal of FIFO resets and samples made (see [`JournalEntry`]).
    pub fn keep_journal(&mut self) {
        self.journal.get_or_insert_with(Vec::new);
    }

    /// The journal's entries since the last call (empty if no journal is kept).
    pub fn take_journal(&mut self) -> Vec<JournalEntry> {
        self.journal
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    fn note(&mut self, entry: JournalEntry) {
        if let Some(journal) = &mut self.journal {
            journal.push(entry);
        }
    }

    /// The current time, us.
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// Device resets so far (commanded or injected), after construction.
    pub fn resets(&self) -> u32 {
        self.resets
    }

    /// Bytes in the FIFO (the truth, whatever the faults).
    pub fn fifo_len(&self) -> usize {
        self.fifo.len()
    }

    /// A register's stored value, without side effects (for tests and inspection).
    pub fn peek(&self, register: u8) -> u8 {
        self.regs[usize::from(register & 0x7F)]
    }

    /// The settings the registers hold.
    pub fn settings(&self) -> SensorSettings {
        SensorSettings::from_registers(RegisterValues {
            smplrt_div: self.regs[usize::from(reg::SMPLRT_DIV)],
            config: self.regs[usize::from(reg::CONFIG)],
            gyro_config: self.regs[usize::from(reg::GYRO_CONFIG)],
            accel_config: self.regs[usize::from(reg::ACCEL_CONFIG)],
        })
    }

    /// Advance the clock by `dt`, producing the samples due.
    pub fn advance(&mut self, dt: Duration) {
        let dt = u64::try_from(dt.as_micros()).unwrap_or(u64::MAX);
        self.set_time_us(self.time_us.saturating_add(dt));
    }

    /// Move the clock to `t_us` (a time in the past is ignored), producing the samples due
    /// and any injected reset on the way.
    pub fn set_time_us(&mut self, t_us: u64) {
        if t_us <= self.time_us {
            return;
        }
        loop {
            let reset = self.faults.reset_at_us.filter(|&r| r <= t_us);
            let sample = self
                .run
                .as_ref()
                .map(Run::next_us)
                .filter(|&s| s <= t_us as f64);
            match (sample, reset) {
                (Some(s), r) if r.is_none_or(|r| s < r as f64) => {
                    self.time_us = self.time_us.max(s as u64);
                    self.sample();
                }
                (_, Some(r)) => {
                    self.time_us = self.time_us.max(r);
                    self.faults.reset_at_us = None;
                    self.device_reset();
                }
                _ => break,
            }
        }
        self.time_us = t_us;
    }

    fn device_reset(&mut self) {
        self.regs = [0; 128];
        self.regs[usize::from(reg::PWR_MGMT_1)] = SLEEP;
        self.regs[usize::from(reg::WHO_AM_I)] = WHO_AM_I_VALUE;
        self.clear_fifo();
        self.fifo_last_read = 0;
        self.pointer = 0;
        self.run = None;
        self.resets += 1;
    }

    fn awake(&self) -> bool {
        self.regs[usize::from(reg::PWR_MGMT_1)] & SLEEP == 0
    }

    /// (Re)start sampling with the current settings, or stop when asleep.
    fn restart(&mut self) {
        self.run = if self.awake() {
            self.runs_started += 1;
            let seed = self
                .seed
                .wrapping_add(self.runs_started.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let mut imu = Imu::new(&self.model, self.settings(), seed, self.duration_hint_s);
            imu.set_input(self.input);
            Some(Run {
                imu,
                start_us: self.time_us,
                samples: 0,
            })
        } else {
            None
        };
    }

    /// One output sample: data registers, DATA_RDY, FIFO.
    fn sample(&mut self) {
        let Some(run) = &mut self.run else { return };
        let raw = run.imu.next_raw();
        run.samples += 1;
        let bytes = RawSample::to_fifo_bytes(&raw);
        self.regs[usize::from(reg::ACCEL_XOUT_H)..][..14].copy_from_slice(&bytes);
        let enable = self.regs[usize::from(reg::INT_ENABLE)];
        self.regs[usize::from(reg::INT_STATUS)] |= enable & DATA_RDY;
        let in_fifo = self.regs[usize::from(reg::USER_CTRL)] & USER_FIFO_EN != 0;
        let time_us = self.time_us;
        self.note(JournalEntry::Sample {
            time_us,
            raw,
            in_fifo,
        });
        if in_fifo {
            let en = self.regs[usize::from(reg::FIFO_EN)];
            let channels = [
                (ACCEL_FIFO_EN, 0..6),
                (TEMP_FIFO_EN, 6..8),
                (XG_FIFO_EN, 8..10),
                (YG_FIFO_EN, 10..12),
                (ZG_FIFO_EN, 12..14),
            ];
            for (bit, range) in channels {
                if en & bit != 0 {
                    for &b in &bytes[range] {
                        self.push_fifo(b);
                    }
                }
            }
        }
    }

    fn clear_fifo(&mut self) {
        self.fifo.clear();
        let time_us = self.time_us;
        self.note(JournalEntry::FifoReset { time_us });
    }

    /// Append one byte, dropping the oldest when full (and flagging the overflow).
    fn push_fifo(&mut self, byte: u8) {
        if self.fifo.len() >= FIFO_SIZE {
            self.fifo.pop_front();
            let enable = self.regs[usize::from(reg::INT_ENABLE)];
            self.regs[usize::from(reg::INT_STATUS)] |= enable & FIFO_OFLOW;
        }
        self.fifo.push_back(byte);
    }

    fn read_register(&mut self, r: u8) -> u8 {
        let count = || {
            self.faults
                .stuck_fifo_count
                .unwrap_or(self.fifo.len() as u16)
        };
        match r {
            reg::INT_STATUS => std::mem::take(&mut self.regs[usize::from(r)]),
            reg::FIFO_COUNT_H => count().to_be_bytes()[0],
            FIFO_COUNT_L => count().to_be_bytes()[1],
            reg::FIFO_R_W => {
                if let Some(b) = self.fifo.pop_front() {
                    self.fifo_last_read = b;
                }
                self.fifo_last_read
            }
            reg::WHO_AM_I => self.faults.who_am_i.unwrap_or(WHO_AM_I_VALUE),
            _ => self.regs[usize::from(r & 0x7F)],
        }
    }

    fn write_register(&mut self, r: u8, value: u8) {
        let i = usize::from(r & 0x7F);
        match r {
            reg::PWR_MGMT_1 if value & DEVICE_RESET != 0 => self.device_reset(),
            reg::PWR_MGMT_1 => {
                let was_awake = self.awake();
                self.regs[i] = value;
                if was_awake != self.awake() {
                    self.restart();
                }
            }
            reg::SMPLRT_DIV | reg::CONFIG | reg::GYRO_CONFIG | reg::ACCEL_CONFIG => {
                let before = self.settings();
                self.regs[i] = value;
                if self.run.is_some() && self.settings() != before {
                    self.restart();
                }
            }
            reg::USER_CTRL => {
                if value & FIFO_RESET != 0 {
                    self.clear_fifo();
                }
                self.regs[i] = value & !(FIFO_RESET | SIG_COND_RESET);
            }
            reg::FIFO_R_W => self.push_fifo(value),
            reg::INT_STATUS | reg::FIFO_COUNT_H | FIFO_COUNT_L | reg::WHO_AM_I => {}
            r if (reg::ACCEL_XOUT_H..reg::ACCEL_XOUT_H + 14).contains(&r) => {}
            _ => self.regs[i] = value,
        }
    }

    fn step_pointer(&mut self) {
        if self.pointer != reg::FIFO_R_W {
            self.pointer = (self.pointer + 1) & 0x7F;
        }
    }

    /// Consume one count of a fault, if set.
    fn take(count: &mut u32) -> bool {
        if *count == 0 {
            return false;
        }
        if *count != u32::MAX {
            *count -= 1;
        }
        true
    }
}

const FIFO_COUNT_L: u8 = reg::FIFO_COUNT_H + 1;

impl ErrorType for SimMpu6050 {
    type Error = SimI2cError;
}

impl I2c for SimMpu6050 {
    /// A transaction is its bus events in order ([`SimMpu6050::bus_start`] ...): a write
    /// after a read is a repeated start, so its first byte is a new register pointer;
    /// adjacent writes (or reads) continue one another.
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        self.bus_start(address, false)?;
        for op in operations {
            match op {
                Operation::Write(bytes) => {
                    for &b in bytes.iter() {
                        self.bus_write(b)?;
                    }
                }
                // A read phase clocks at least one byte (the master ends it with a NACK on
                // the last byte), so a zero-byte read cannot happen on a bus; rp2040-hal
                // refuses one with an abort. Failing it here finds drivers that ask for it.
                Operation::Read([]) => {
                    self.bus_stop();
                    return Err(SimI2cError::Bus);
                }
                Operation::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.bus_read();
                    }
                }
            }
        }
        self.bus_stop();
        Ok(())
    }
}

/// The bus seen byte by byte, as a bus model that reports each event drives it (the
/// emulated RP2040's I2C controller through `imunoise sim-device`). [`I2c::transaction`] is
/// these events in order, so both paths are one device.
impl SimMpu6050 {
    /// A start (or, with `repeated`, a repeated start) addressed to `address`: acknowledged
    /// if it is this device's, unless an address NACK or a bus error is injected (those are
    /// counted per transaction, so a repeated start does not consume them).
    pub fn bus_start(&mut self, address: u8, repeated: bool) -> Result<(), SimI2cError> {
        if address != self.address || (!repeated && Self::take(&mut self.faults.nack_address)) {
            return Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        if !repeated {
            if Self::take(&mut self.faults.bus_error) {
                return Err(SimI2cError::Bus);
            }
            self.written_since_start = false;
        }
        self.expect_pointer = true;
        Ok(())
    }

    /// A written byte: the register pointer if it is the first since a start or a read,
    /// else a register write (the pointer then advances). The first written byte of a
    /// transaction is refused, without effect, while a data NACK is injected.
    pub fn bus_write(&mut self, byte: u8) -> Result<(), SimI2cError> {
        if !self.written_since_start && Self::take(&mut self.faults.nack_data) {
            return Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Data));
        }
        self.written_since_start = true;
        if self.expect_pointer {
            self.pointer = byte & 0x7F;
            self.expect_pointer = false;
        } else {
            self.write_register(self.pointer, byte);
            self.step_pointer();
        }
        Ok(())
    }

    /// A read byte: the register at the pointer (which then advances). A write after reads
    /// starts with a new pointer, as after a repeated start.
    pub fn bus_read(&mut self) -> u8 {
        let b = self.read_register(self.pointer);
        self.step_pointer();
        self.expect_pointer = true;
        b
    }

    /// A stop: the transaction ends.
    pub fn bus_stop(&mut self) {
        self.expect_pointer = true;
        self.written_since_start = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::noise::NoiseTerms;

    const ADDR: u8 = DEFAULT_ADDRESS;

    fn device() -> SimMpu6050 {
        let mut model = ImuModel::default();
        model.gyro.noise = NoiseTerms {
            n: 1e-3,
            ..Default::default()
        };
        model.accel.noise = NoiseTerms {
            n: 1e-2,
            ..Default::default()
        };
        SimMpu6050::new(model, 42)
    }

    fn read(dev: &mut SimMpu6050, r: u8, n: usize) -> Vec<u8> {
        let mut buf = vec![0; n];
        dev.write_read(ADDR, &[r], &mut buf).unwrap();
        buf
    }

    #[test]
    fn a_zero_byte_read_is_a_bus_error() {
        let mut dev = device();
        assert_eq!(
            dev.write_read(ADDR, &[reg::FIFO_R_W], &mut []),
            Err(SimI2cError::Bus)
        );
        assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68, "the bus recovers");
    }

    fn read1(dev: &mut SimMpu6050, r: u8) -> u8 {
        read(dev, r, 1)[0]
    }

    fn write(dev: &mut SimMpu6050, r: u8, v: u8) {
        dev.write(ADDR, &[r, v]).unwrap();
    }

    fn fifo_count(dev: &mut SimMpu6050) -> u16 {
        let b = read(dev, reg::FIFO_COUNT_H, 2);
        u16::from_be_bytes([b[0], b[1]])
    }

    /// Awake at 100 Hz / 42 Hz, FIFO on with everything: 14 bytes per sample.
    fn running() -> SimMpu6050 {
        let mut dev = device();
        write(&mut dev, reg::PWR_MGMT_1, 0x01);
        // Burst write SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG (auto-increment).
        dev.write(ADDR, &[reg::SMPLRT_DIV, 9, 3, 0, 0]).unwrap();
        write(&mut dev, reg::FIFO_EN, 0xF8);
        write(&mut dev, reg::USER_CTRL, USER_FIFO_EN);
        dev
    }

    #[test]
    fn identity_and_power_up_asleep() {
        let mut dev = device();
        assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68);
        assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
        write(&mut dev, reg::FIFO_EN, 0xF8);
        write(&mut dev, reg::USER_CTRL, USER_FIFO_EN);
        write(&mut dev, reg::INT_ENABLE, DATA_RDY);
        dev.advance(Duration::from_secs(1));
        assert_eq!(fifo_count(&mut dev), 0, "asleep: no samples");
        assert_eq!(read1(&mut dev, reg::INT_STATUS), 0);
        assert_eq!(read(&mut dev, reg::ACCEL_XOUT_H, 14), vec![0; 14]);
    }

    #[test]
    fn burst_writes_and_reads_auto_increment() {
        let mut dev = running();
        assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![9, 3, 0, 0]);
        assert_eq!(dev.settings().output_rate_hz(), 100.0);
        // A transaction of several operations: pointer, then a continued write, then a read
        // after a repeated start that sets a new pointer.
        let mut out = [0u8; 2];
        dev.transaction(
            ADDR,
            &mut [
                Operation::Write(&[reg::SMPLRT_DIV]),
                Operation::Write(&[4, 3]),
                Operation::Read(&mut out),
            ],
        )
        .unwrap();
        // The read continues at SMPLRT_DIV + 2 (the pointer after two written bytes).
        assert_eq!(out, [0, 0]);
        assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 2), vec![4, 3]);
    }

    #[test]
    fn data_registers_and_data_ready() {
        let mut dev = running();
        write(&mut dev, reg::INT_ENABLE, DATA_RDY);
        dev.advance(Duration::from_micros(9_999));
        assert_eq!(
            read1(&mut dev, reg::INT_STATUS),
            0,
            "no sample before 10 ms"
        );
        dev.advance(Duration::from_micros(1));
        assert_eq!(read1(&mut dev, reg::INT_STATUS), DATA_RDY);
        assert_eq!(read1(&mut dev, reg::INT_STATUS), 0, "cleared on read");
        let d = read(&mut dev, reg::ACCEL_XOUT_H, 14);
        let word = |i: usize| i16::from_be_bytes([d[2 * i], d[2 * i + 1]]);
        assert!((word(2) - 16384).abs() < 50, "1 g on z: {}", word(2));
        assert!(word(0).abs() < 50 && word(4).abs() < 50);
        // 25 degC: (25 - 36.53) * 340 = -3920.
        assert_eq!(word(3), -3920);
    }

    #[test]
    fn fifo_fills_in_order_and_pops() {
        let mut dev = running();
        dev.advance(Duration::from_millis(100));
        assert_eq!(fifo_count(&mut dev), 140, "10 samples of 14 bytes");
        let regs = read(&mut dev, reg::ACCEL_XOUT_H, 14);
        let all = read(&mut dev, reg::FIFO_R_W, 140);
        assert_eq!(
            &all[126..],
            &regs[..],
            "newest FIFO sample = data registers"
        );
        assert_eq!(fifo_count(&mut dev), 0);
        // Reading an empty FIFO repeats the last byte.
        assert_eq!(read1(&mut dev, reg::FIFO_R_W), all[139]);
        // Only gyro z: 2 bytes per sample.
        write(&mut dev, reg::FIFO_EN, ZG_FIFO_EN);
        dev.advance(Duration::from_millis(50));
        assert_eq!(fifo_count(&mut dev), 10);
        let z = read(&mut dev, reg::FIFO_R_W, 10);
        assert_eq!(&z[8..], &read(&mut dev, reg::GYRO_XOUT_H + 4, 2)[..]);
    }

    #[test]
    fn fifo_overflow_drops_oldest_and_flags() {
        let mut dev = running();
        write(&mut dev, reg::INT_ENABLE, FIFO_OFLOW);
        dev.advance(Duration::from_millis(730)); // 73 samples = 1022 bytes: fits
        assert_eq!(fifo_count(&mut dev), 1022);
        assert_eq!(read1(&mut dev, reg::INT_STATUS), 0);
        dev.advance(Duration::from_secs(2));
        assert_eq!(fifo_count(&mut dev), 1024);
        assert_eq!(read1(&mut dev, reg::INT_STATUS), FIFO_OFLOW);
        let regs = read(&mut dev, reg::ACCEL_XOUT_H, 14);
        let all = read(&mut dev, reg::FIFO_R_W, 1024);
        // Kept the newest bytes; 1024 = 73 * 14 + 2, so the head is mid-sample.
        assert_eq!(&all[1010..], &regs[..]);
        // FIFO reset empties it and the bit clears itself.
        dev.advance(Duration::from_millis(100));
        write(&mut dev, reg::USER_CTRL, USER_FIFO_EN | FIFO_RESET);
        assert_eq!(fifo_count(&mut dev), 0);
        assert_eq!(read1(&mut dev, reg::USER_CTRL), USER_FIFO_EN);
    }

    #[test]
    fn device_reset_restores_defaults() {
        let mut dev = running();
        dev.advance(Duration::from_millis(100));
        write(&mut dev, reg::PWR_MGMT_1, DEVICE_RESET);
        assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
        assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![0; 4]);
        assert_eq!(fifo_count(&mut dev), 0);
        dev.advance(Duration::from_millis(100));
        assert_eq!(fifo_count(&mut dev), 0, "asleep after reset");
        assert_eq!(dev.resets(), 1);
    }

    #[test]
    fn faults() {
        let mut dev = running();
        let mut buf = [0u8; 1];
        assert_eq!(
            dev.write_read(0x69, &[reg::WHO_AM_I], &mut buf),
            Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))
        );
        dev.faults_mut().nack_address = 1;
        assert!(matches!(
            dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf),
            Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))
        ));
        assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68, "one transaction only");
        dev.faults_mut().nack_data = 1;
        let mut fifo = [0u8; 2];
        dev.read(ADDR, &mut fifo).unwrap(); // a plain read does not consume nack_data
        assert_eq!(
            dev.write(ADDR, &[reg::SMPLRT_DIV, 1]),
            Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Data))
        );
        assert_eq!(
            read1(&mut dev, reg::SMPLRT_DIV),
            9,
            "NACKed write had no effect"
        );
        dev.faults_mut().bus_error = 2;
        assert_eq!(
            dev.write(ADDR, &[reg::SMPLRT_DIV, 1]),
            Err(SimI2cError::Bus)
        );
        assert!(dev.read(ADDR, &mut buf).is_err());
        use embedded_hal::i2c::Error;
        assert_eq!(SimI2cError::Bus.kind(), ErrorKind::Bus);
        dev.faults_mut().who_am_i = Some(0x72);
        assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x72);
        dev.faults_mut().stuck_fifo_count = Some(0x0200);
        dev.advance(Duration::from_millis(100));
        assert_eq!(fifo_count(&mut dev), 0x0200);
        assert_eq!(dev.fifo_len(), 140);
        dev.faults_mut().stuck_fifo_count = None;
        // A reset in the middle of the run: samples stop at 150 ms.
        let now = dev.time_us();
        dev.faults_mut().reset_at_us = Some(now + 50_000);
        dev.advance(Duration::from_millis(200));
        assert_eq!(dev.resets(), 1);
        assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
        assert_eq!(fifo_count(&mut dev), 0);
    }

    #[test]
    fn reproducible_and_clock_driven() {
        let run = || {
            let mut dev = running();
            dev.set_time_us(250_000);
            dev.set_time_us(100); // the past is ignored
            read(&mut dev, reg::FIFO_R_W, 350)
        };
        let a = run();
        assert_eq!(a, run());
        assert_ne!(&a[..14], &a[14..28], "noise varies sample to sample");
    }
}

//! A simulated MPU-6050 on an I2C bus, at register level, behind `embedded_hal::i2c::I2c`
//! (1.0), so that the firmware's portable driver runs against it unchanged.
//!
//! What is modelled (register numbers from RM-MPU-6000A rev. 4.2, [`protocol::mpu6050::reg`]):
//! - WHO_AM_I (0x75) reads 0x68; the chip powers up asleep (PWR_MGMT_1 = 0x40) and makes no
//!   samples until bit 6 (SLEEP) is cleared; bit 7 (DEVICE_RESET) restores every register to
//!   its reset value (asleep, FIFO empty) and clears itself.
//! - SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG set the signal chain ([`super::imu`]); a
//!   change while awake restarts sampling with the new settings (the noise processes restart).
//! - Samples come at the output rate of the sensor's own oscillator, against the clock the
//!   caller drives (the board's: [`SimMpu6050::advance`], [`SimMpu6050::set_time_us`]).
//!   With an ideal oscillator sample k of a run (k = 1, 2, ...) is at `start + k / f_s`;
//!   with [`SensorClock`] the oscillator runs at `1 + (ppm + drift * t_hours) * 1e-6` of
//!   nominal, and sample k is where the integral of that rate from `start` reaches `k / f_s`
//!   (solved in closed form per sample, so no error accumulates over a night).
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
//! - Faults ([`Faults`]): NACK of the address or of written data (counted transactions),
//!   bus errors, a wrong WHO_AM_I (a clone chip), a stuck FIFO count, the sample clock's
//!   offset and linear drift ([`SensorClock`]), I2C outages (time windows in which every
//!   transaction is NACKed at the address while sampling and the FIFO go on, so the FIFO
//!   overflows as on the chip), and device resets at listed times (registers back to their
//!   power-on values, asleep, FIFO empty). Times are the caller's clock, us.
//!
//! Not modelled: the DMP, the auxiliary I2C master, self-test, interrupt pin configuration,
//! FIFO_EN's SLV bits, clock source selection, low-power cycle mode.

use super::imu::{Imu, ImuModel, RawSample, TrueInput};
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};
use protocol::mpu6050::reg::bits::{
    ACCEL_FIFO_EN, DATA_RDY, DEVICE_RESET, FIFO_OFLOW, FIFO_RESET, SIG_COND_RESET, SLEEP,
    TEMP_FIFO_EN, USER_FIFO_EN, XG_FIFO_EN, YG_FIFO_EN, ZG_FIFO_EN,
};
use protocol::mpu6050::{
    DEFAULT_ADDRESS, FIFO_SIZE, RegisterValues, SensorSettings, WHO_AM_I_VALUE, chip_or_mpu6050,
    reg,
};
use std::collections::VecDeque;
use std::time::Duration;

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

/// The sensor's sample oscillator against the caller's (the board's) clock: its rate is
/// `1 + (ppm + drift_ppm_per_hour * t_hours) * 1e-6` of nominal at board time `t_hours`
/// (hours since time 0). The default is an ideal oscillator.
///
/// The rate must stay positive: `ppm > -1e6`; with a negative drift, once the rate would
/// reach zero the sensor makes no more samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorClock {
    /// Constant frequency offset, ppm (+3000: 0.3 % fast).
    pub ppm: f64,
    /// Linear change of the offset, ppm per hour of board time.
    pub drift_ppm_per_hour: f64,
}

impl SensorClock {
    /// Linear and quadratic coefficients of the phase in us: `phase(t) = c1 t + c2 t^2`.
    fn coefficients(&self) -> (f64, f64) {
        let c1 = 1.0 + self.ppm * 1e-6;
        let c2 = self.drift_ppm_per_hour * 1e-6 / (2.0 * 3600e6);
        (c1, c2)
    }

    /// The oscillator's phase at board time `t_us`: nominal microseconds elapsed on the
    /// sensor since board time 0 (the integral of the rate).
    pub fn phase_us(&self, t_us: f64) -> f64 {
        let (c1, c2) = self.coefficients();
        c1 * t_us + c2 * t_us * t_us
    }

    /// The board time at which the phase reaches `phase_us` (the inverse of
    /// [`SensorClock::phase_us`] on its rising branch); infinity if it never does.
    pub fn time_at_phase_us(&self, phase_us: f64) -> f64 {
        let (c1, c2) = self.coefficients();
        let t = if c2 == 0.0 {
            phase_us / c1
        } else {
            // The root of c2 t^2 + c1 t - phase = 0 on the rising branch, in the form that
            // keeps its precision when c2 t is small against c1.
            let disc = c1 * c1 + 4.0 * c2 * phase_us;
            if disc < 0.0 {
                return f64::INFINITY;
            }
            2.0 * phase_us / (c1 + disc.sqrt())
        };
        if t.is_finite() && t >= 0.0 {
            t
        } else {
            f64::INFINITY
        }
    }
}

/// A window of board time in which the device does not answer at all, us.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Outage {
    pub at_us: u64,
    pub for_us: u64,
}

impl Outage {
    pub fn contains(&self, t_us: u64) -> bool {
        t_us >= self.at_us && t_us - self.at_us < self.for_us
    }
}

/// Injected faults. The counts are numbers of coming transactions affected (`u32::MAX`:
/// all of them); each affected transaction fails without any effect on the device.
#[derive(Debug, Clone, PartialEq, Default)]
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
    /// The sample oscillator's offset and drift. A change while sampling keeps the
    /// progress towards the next sample (the phase is continuous).
    pub clock: SensorClock,
    /// Windows in which every transaction is NACKed at the address (the count
    /// `nack_address` is not consumed); sampling and the FIFO go on.
    pub i2c_outages: Vec<Outage>,
    /// Device resets (as by PWR_MGMT_1 bit 7), each once when the clock passes its time, us;
    /// any order (they are sorted when the clock moves), removed as they happen. A time
    /// already past fires at the next clock move. [`SimMpu6050::schedule_reset`] adds one.
    pub resets_at_us: Vec<u64>,
}

impl Faults {
    /// Whether `t_us` falls in one of the outages.
    pub fn in_outage(&self, t_us: u64) -> bool {
        self.i2c_outages.iter().any(|o| o.contains(t_us))
    }
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
    samples_made: u64,
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
    /// The oscillator's phase at which the run's sample 0 would be (its start), us, under
    /// `clock`.
    phase_origin_us: f64,
    clock: SensorClock,
    samples: u64,
}

impl Run {
    /// Board time of the next sample, us (fractional): where the oscillator's phase reaches
    /// the origin plus (k + 1) nominal sample periods. Each sample's time is computed from
    /// the origin, so rounding does not accumulate.
    fn next_us(&self) -> f64 {
        let phase =
            self.phase_origin_us + (self.samples + 1) as f64 * 1e6 / self.imu.output_rate_hz();
        self.clock.time_at_phase_us(phase)
    }

    /// Continue under `clock` from board time `t_us` with the same progress towards the
    /// next sample.
    fn rebase(&mut self, clock: SensorClock, t_us: f64) {
        let elapsed = self.clock.phase_us(t_us) - self.phase_origin_us;
        self.phase_origin_us = clock.phase_us(t_us) - elapsed;
        self.clock = clock;
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
            samples_made: 0,
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

    pub fn faults(&self) -> &Faults {
        &self.faults
    }

    pub fn faults_mut(&mut self) -> &mut Faults {
        &mut self.faults
    }

    /// A device reset when the clock passes `t_us` (see [`Faults::resets_at_us`]).
    pub fn schedule_reset(&mut self, t_us: u64) {
        self.faults.resets_at_us.push(t_us);
        self.faults.resets_at_us.sort_unstable();
    }

    /// Samples made so far, all runs together (whether or not they reached the FIFO).
    pub fn samples_made(&self) -> u64 {
        self.samples_made
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
    /// and the injected resets on the way.
    pub fn set_time_us(&mut self, t_us: u64) {
        if t_us <= self.time_us {
            return;
        }
        let clock = self.faults.clock;
        if let Some(run) = self.run.as_mut().filter(|run| run.clock != clock) {
            run.rebase(clock, self.time_us as f64);
        }
        self.faults.resets_at_us.sort_unstable();
        loop {
            let reset = self
                .faults
                .resets_at_us
                .first()
                .copied()
                .filter(|&r| r <= t_us);
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
                    self.faults.resets_at_us.remove(0);
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
            let chip = chip_or_mpu6050(self.faults.who_am_i.unwrap_or(WHO_AM_I_VALUE));
            let mut imu =
                Imu::new(&self.model, self.settings(), seed, self.duration_hint_s).with_chip(chip);
            imu.set_input(self.input);
            let clock = self.faults.clock;
            Some(Run {
                imu,
                phase_origin_us: clock.phase_us(self.time_us as f64),
                clock,
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
        self.samples_made += 1;
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
    /// if it is this device's, unless the time is in an outage or an address NACK or a bus
    /// error is injected (those are counted per transaction, so a repeated start does not
    /// consume them).
    pub fn bus_start(&mut self, address: u8, repeated: bool) -> Result<(), SimI2cError> {
        if address != self.address
            || self.faults.in_outage(self.time_us)
            || (!repeated && Self::take(&mut self.faults.nack_address))
        {
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
        dev.schedule_reset(now + 50_000);
        dev.advance(Duration::from_millis(200));
        assert_eq!(dev.resets(), 1);
        assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
        assert_eq!(fifo_count(&mut dev), 0);
    }

    /// Awake at 1 kHz (DLPF on, divider 0), FIFO off, under `clock`, from `start_us`.
    fn at_1khz(clock: SensorClock, start_us: u64) -> SimMpu6050 {
        let mut dev = device();
        dev.faults_mut().clock = clock;
        dev.set_time_us(start_us);
        dev.write(ADDR, &[reg::SMPLRT_DIV, 0, 1, 0, 0]).unwrap();
        write(&mut dev, reg::PWR_MGMT_1, 0x01);
        assert_eq!(dev.settings().output_rate_hz(), 1000.0);
        dev
    }

    fn sample_times(dev: &mut SimMpu6050) -> Vec<u64> {
        dev.take_journal()
            .iter()
            .filter_map(|e| match e {
                JournalEntry::Sample { time_us, .. } => Some(*time_us),
                JournalEntry::FifoReset { .. } => None,
            })
            .collect()
    }

    #[test]
    fn a_clock_offset_changes_the_sample_count() {
        for (ppm, expected) in [
            (0.0, 60_000),
            (3000.0, 60_180),
            (10_000.0, 60_600),
            (-10_000.0, 59_400),
        ] {
            let clock = SensorClock {
                ppm,
                drift_ppm_per_hour: 0.0,
            };
            let mut dev = at_1khz(clock, 0);
            dev.advance(Duration::from_secs(60));
            let n = dev.samples_made();
            assert!(n.abs_diff(expected) <= 1, "{ppm} ppm: {n} samples");
        }
        // The ideal clock keeps sample k at exactly k ms.
        let mut dev = at_1khz(SensorClock::default(), 0);
        dev.keep_journal();
        dev.advance(Duration::from_millis(5));
        assert_eq!(sample_times(&mut dev), [1000, 2000, 3000, 4000, 5000]);
    }

    #[test]
    fn a_drifting_clock_follows_the_integral_of_its_rate() {
        // From 1 h to 1 h + 60 s, rate 1 + (2000 - 5000 t_h) 1e-6: the sensor's elapsed time
        // is the integral, 60 s + 1e-6 (2000 * 60 - 5000 (3660^2 - 3600^2) / 7200) s.
        let clock = SensorClock {
            ppm: 2000.0,
            drift_ppm_per_hour: -5000.0,
        };
        let (t0, t1) = (3600.0_f64, 3660.0_f64);
        let integral = |a: f64, b: f64| {
            (b - a) + 1e-6 * (2000.0 * (b - a) - 5000.0 * (b * b - a * a) / 7200.0)
        };
        assert!((integral(t0, t1) - 59.8175).abs() < 1e-9);
        let mut dev = at_1khz(clock, 3_600_000_000);
        dev.keep_journal();
        dev.advance(Duration::from_secs(60));
        let times = sample_times(&mut dev);
        let expected = (integral(t0, t1) * 1000.0).floor() as u64;
        assert_eq!(expected, 59_817);
        assert!(dev.samples_made().abs_diff(expected) <= 1);
        assert_eq!(times.len() as u64, dev.samples_made());
        // Each sample k at the first whole us where the integral has reached k ms.
        for (k, &t) in times.iter().enumerate().step_by(997) {
            let due = (k + 1) as f64 * 1e-3;
            let t = t as f64 * 1e-6;
            assert!(integral(t0, t) <= due + 1e-9, "sample {k} early");
            assert!(integral(t0, t + 1e-6) > due - 1e-9, "sample {k} late");
        }
    }

    #[test]
    fn the_clock_model_inverts_exactly_over_a_night() {
        for (ppm, drift) in [(10_000.0, 0.0), (-10_000.0, 500.0), (3000.0, -800.0)] {
            let clock = SensorClock {
                ppm,
                drift_ppm_per_hour: drift,
            };
            for hours in [0.001, 1.0, 8.0, 14.0] {
                let phase = hours * 3600e6;
                let t = clock.time_at_phase_us(phase);
                assert!(
                    (clock.phase_us(t) - phase).abs() < 1e-3,
                    "{ppm} {drift} {hours}"
                );
                // The rate is what the model says: 1 + (ppm + drift t_h) 1e-6 (a central
                // difference is exact for a quadratic; a wide one keeps rounding small).
                let h = 1e6;
                let rate = (clock.phase_us(t + h) - clock.phase_us(t - h)) / (2.0 * h);
                let expected = 1.0 + (ppm + drift * t / 3600e6) * 1e-6;
                assert!((rate - expected).abs() < 1e-8, "{rate} {expected}");
            }
        }
        // A falling rate that reaches zero: the phase never gets past its maximum.
        let stopping = SensorClock {
            ppm: 0.0,
            drift_ppm_per_hour: -1e6,
        };
        assert_eq!(stopping.time_at_phase_us(1e10), f64::INFINITY);
    }

    #[test]
    fn a_clock_change_mid_run_keeps_the_phase() {
        let mut dev = at_1khz(SensorClock::default(), 0);
        dev.keep_journal();
        dev.set_time_us(10_000_500);
        assert_eq!(dev.samples_made(), 10_000);
        // Half a period to go; at 1 % fast it takes 500 / 1.01 = 495.05 us.
        dev.faults_mut().clock.ppm = 10_000.0;
        dev.take_journal();
        dev.set_time_us(10_002_000);
        let times = sample_times(&mut dev);
        assert_eq!(times[0], 10_000_995);
        // The next one a full fast period (990.1 us) later.
        assert_eq!(times[1], 10_001_985);
    }

    #[test]
    fn an_i2c_outage_nacks_everything_while_sampling_goes_on() {
        let mut dev = running();
        write(&mut dev, reg::INT_ENABLE, FIFO_OFLOW);
        dev.faults_mut().i2c_outages = vec![Outage {
            at_us: 100_000,
            for_us: 3_000_000,
        }];
        let nack = Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address));
        let mut buf = [0u8; 1];
        dev.set_time_us(99_999);
        assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68);
        dev.set_time_us(100_000);
        assert_eq!(dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf), nack);
        // Writes have no effect: neither settings nor a FIFO reset.
        assert_eq!(dev.write(ADDR, &[reg::SMPLRT_DIV, 1]), nack);
        assert_eq!(
            dev.write(ADDR, &[reg::USER_CTRL, USER_FIFO_EN | FIFO_RESET]),
            nack
        );
        assert_eq!(dev.read(ADDR, &mut buf), nack);
        let samples_before = dev.samples_made();
        dev.set_time_us(3_099_999);
        assert_eq!(dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf), nack);
        // The chip went on at 100 Hz and its FIFO overflowed.
        assert_eq!(dev.samples_made() - samples_before, 299);
        assert_eq!(dev.fifo_len(), 1024);
        dev.set_time_us(3_100_000);
        assert_eq!(
            read1(&mut dev, reg::WHO_AM_I),
            0x68,
            "back after the window"
        );
        assert_eq!(read1(&mut dev, reg::SMPLRT_DIV), 9);
        assert_eq!(read1(&mut dev, reg::INT_STATUS), FIFO_OFLOW);
        assert_eq!(fifo_count(&mut dev), 1024);
        assert_eq!(dev.faults().nack_address, 0);
        assert_eq!(dev.resets(), 0);
    }

    #[test]
    fn resets_at_listed_times() {
        let mut dev = running();
        dev.keep_journal();
        // Given out of order, partly through the field and partly scheduled.
        dev.faults_mut().resets_at_us = vec![500_000, 150_000];
        dev.schedule_reset(300_000);
        assert_eq!(dev.faults().resets_at_us, [150_000, 300_000, 500_000]);
        dev.set_time_us(149_999);
        assert_eq!(dev.resets(), 0);
        assert_eq!(dev.samples_made(), 14);
        dev.set_time_us(150_000);
        assert_eq!(dev.resets(), 1);
        assert_eq!(dev.fifo_len(), 0);
        assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
        assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![0; 4]);
        let journal = dev.take_journal();
        assert_eq!(
            journal.last(),
            Some(&JournalEntry::FifoReset { time_us: 150_000 })
        );
        // Asleep until woken; woken again, it samples until the next reset.
        dev.set_time_us(200_000);
        assert_eq!(
            dev.samples_made(),
            14,
            "the reset came before the sample at 150 ms"
        );
        write(&mut dev, reg::PWR_MGMT_1, 0x01);
        dev.set_time_us(1_000_000);
        assert_eq!(dev.resets(), 3);
        assert!(dev.faults().resets_at_us.is_empty());
        // The reset settings (divider 0, DLPF off) sample at 8 kHz: 200 ms to 300 ms, the
        // sample due at the reset not made.
        assert_eq!(dev.settings().output_rate_hz(), 8000.0);
        assert_eq!(dev.samples_made(), 14 + 799);
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

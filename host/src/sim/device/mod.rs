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

pub mod adxl345;
mod bus;
mod core;
mod faults;
#[cfg(test)]
mod gy85_tests;
pub mod itg3200;
mod port;
mod sampler;
#[cfg(test)]
mod tests;

pub use adxl345::SimAdxl345;
pub use bus::{BusChip, SimBus};
pub use core::{ChipCore, SimChip};
pub use faults::{Faults, Outage, SensorClock};
pub use itg3200::SimItg3200;
pub use port::{Port, RegisterChip, SimI2cError, transaction};
pub use sampler::{SampledChip, Sampler};

use super::imu::{Imu, ImuModel, RawSample, TrueInput};
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

#[derive(Debug, Clone)]
pub struct SimMpu6050 {
    core: ChipCore,
    regs: [u8; 128],
    fifo: VecDeque<u8>,
    fifo_last_read: u8,
    model: ImuModel,
    /// Sampling state while awake.
    run: Option<Run>,
    /// The scripted input ([`Imu::set_input`]), kept across runs.
    input: Option<TrueInput>,
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
    sampler: Sampler,
}

impl SimMpu6050 {
    /// A device at address 0x68 simulating `model`, seeded by `seed`, at time 0, in its reset
    /// state (asleep).
    pub fn new(model: ImuModel, seed: u64) -> Self {
        let mut dev = SimMpu6050 {
            core: ChipCore::new(DEFAULT_ADDRESS, seed),
            regs: [0; 128],
            fifo: VecDeque::with_capacity(FIFO_SIZE),
            fifo_last_read: 0,
            model,
            run: None,
            input: None,
        };
        dev.device_reset();
        dev.core.resets = 0;
        dev
    }

    /// Turn and rotate the sensor (scripted procedures such as calibration): what it senses
    /// from now on, in this run and the next ones; `None` puts it back at rest.
    pub fn set_input(&mut self, input: Option<TrueInput>) {
        self.input = input;
        if let Some(run) = &mut self.run {
            run.imu.set_input(input);
        }
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
        self.set_time_us(self.core.time_us.saturating_add(dt));
    }

    /// Move the clock to `t_us` (a time in the past is ignored), producing the samples due
    /// and the injected resets on the way.
    pub fn set_time_us(&mut self, t_us: u64) {
        self.advance_to_us(t_us);
    }

    fn device_reset(&mut self) {
        self.regs = [0; 128];
        self.regs[usize::from(reg::PWR_MGMT_1)] = SLEEP;
        self.regs[usize::from(reg::WHO_AM_I)] = WHO_AM_I_VALUE;
        self.clear_fifo();
        self.fifo_last_read = 0;
        self.reset_pointer();
        self.run = None;
        self.core.resets += 1;
    }

    fn awake(&self) -> bool {
        self.regs[usize::from(reg::PWR_MGMT_1)] & SLEEP == 0
    }

    /// (Re)start sampling with the current settings, or stop when asleep.
    fn restart(&mut self) {
        self.run = if self.awake() {
            let seed = self.core.next_run_seed();
            let chip = chip_or_mpu6050(self.core.faults.who_am_i.unwrap_or(WHO_AM_I_VALUE));
            let mut imu = Imu::new(
                &self.model,
                self.settings(),
                seed,
                self.core.duration_hint_s,
            )
            .with_chip(chip);
            imu.set_input(self.input);
            let sampler = Sampler::start(
                self.core.faults.clock,
                self.core.time_us,
                imu.output_rate_hz(),
            );
            Some(Run { imu, sampler })
        } else {
            None
        };
    }

    /// One output sample: data registers, DATA_RDY, FIFO.
    fn sample_registers(&mut self) {
        let Some(run) = &mut self.run else { return };
        let raw = run.imu.next_raw();
        self.core.samples_made += 1;
        let bytes = RawSample::to_fifo_bytes(&raw);
        self.regs[usize::from(reg::ACCEL_XOUT_H)..][..14].copy_from_slice(&bytes);
        let enable = self.regs[usize::from(reg::INT_ENABLE)];
        self.regs[usize::from(reg::INT_STATUS)] |= enable & DATA_RDY;
        let in_fifo = self.regs[usize::from(reg::USER_CTRL)] & USER_FIFO_EN != 0;
        let time_us = self.core.time_us;
        self.core.note(JournalEntry::Sample {
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
        let time_us = self.core.time_us;
        self.core.note(JournalEntry::FifoReset { time_us });
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

    fn read_mpu_register(&mut self, r: u8) -> u8 {
        let count = || {
            self.core
                .faults
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
            reg::WHO_AM_I => self.core.faults.who_am_i.unwrap_or(WHO_AM_I_VALUE),
            _ => self.regs[usize::from(r & 0x7F)],
        }
    }

    fn write_mpu_register(&mut self, r: u8, value: u8) {
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
}

const FIFO_COUNT_L: u8 = reg::FIFO_COUNT_H + 1;

impl SimChip for SimMpu6050 {
    fn core(&self) -> &ChipCore {
        &self.core
    }
    fn core_mut(&mut self) -> &mut ChipCore {
        &mut self.core
    }
}

impl RegisterChip for SimMpu6050 {
    fn read_register(&mut self, register: u8) -> u8 {
        self.read_mpu_register(register)
    }
    fn write_register(&mut self, register: u8, value: u8) {
        self.write_mpu_register(register, value);
    }
    /// FIFO_R_W stays put, so a burst read drains the FIFO.
    fn next_register(&self, register: u8) -> u8 {
        if register == reg::FIFO_R_W {
            register
        } else {
            register.wrapping_add(1) & 0x7F
        }
    }
}

impl SampledChip for SimMpu6050 {
    fn sampler_mut(&mut self) -> Option<&mut Sampler> {
        self.run.as_mut().map(|run| &mut run.sampler)
    }
    fn sample(&mut self) {
        self.sample_registers();
    }
    fn power_on_reset(&mut self) {
        self.device_reset();
    }
}

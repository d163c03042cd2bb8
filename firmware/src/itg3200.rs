//! The ITG-3200 (and ITG-3205) gyro on embedded-hal 1.0 I2C, read through the [`Sensor`]
//! trait.
//!
//! The chip has no FIFO: each sample waits in TEMP_OUT..GYRO_ZOUT until the next replaces
//! it, and INT_STATUS bit 0 (RAW_DATA_RDY, enabled by INT_CFG bit 0) says a new one is there
//! (cleared by reading INT_STATUS). A drain reads INT_STATUS and the eight data bytes after
//! it in one burst (registers 0x1A..0x22 are contiguous), so the flag and the sample it
//! announces come together. The acquisition polls at half the sample period; a sample
//! replaced before it was read is counted lost from the sample grid
//! ([`Sensor::OVERWRITES_SILENTLY`]).
//!
//! Register numbers and bits: [`protocol::itg3200::reg`] (PS-ITG-3200A rev 1.4).

use crate::registers::Registers;
use crate::sensor::{Sensor, Waiting};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::itg3200::reg::bits::{CLK_SEL_PLL_X, H_RESET, RAW_DATA_RDY, RAW_RDY_EN};
use protocol::itg3200::{Itg3200Settings, is_itg3200, reg};
use protocol::{ErrorCode, RawSample};

/// PWR_MGM as we run it: awake, all gyros on, clocked by the X gyro's PLL, which the
/// specification recommends over the internal oscillator \[IT, reg 62\].
pub const PWR_MGM_RUN: u8 = CLK_SEL_PLL_X;
/// INT_CFG as we run it: RAW_DATA_RDY reported; cleared by reading INT_STATUS only.
pub const INT_CFG_RUN: u8 = RAW_RDY_EN;
/// Time after H_RESET before the registers are written: the specification's start-up time
/// of the gyros is 50 ms \[IT, 3.1\].
pub const RESET_DELAY_MS: u32 = 50;

/// Highest output rate streamed from the ITG-3200: it is polled every half period with a
/// nine-byte burst (about 0.3 ms at 400 kHz), so 1 kHz keeps the bus well over half busy.
pub const MAX_RATE_HZ: f64 = 1000.0;

/// The sample period of `settings` if this firmware streams them: a specified DLPF row at
/// no more than [`MAX_RATE_HZ`]; [`ErrorCode::InvalidSettings`] otherwise.
pub fn period_us(settings: &Itg3200Settings) -> Result<u32, ErrorCode> {
    if settings.row().is_none() || settings.output_rate_hz() > MAX_RATE_HZ {
        return Err(ErrorCode::InvalidSettings);
    }
    Ok(settings.period_us())
}

/// The ITG-3200 on an I2C bus.
#[derive(Debug)]
pub struct Itg3200<I2C> {
    regs: Registers<I2C>,
    /// The sample read with the last INT_STATUS: temperature, x, y, z (big-endian).
    latest: [u8; reg::SAMPLE_BYTES],
}

impl<I2C: I2c> Itg3200<I2C> {
    pub fn new(i2c: I2C, address: u8) -> Self {
        Itg3200 {
            regs: Registers::new(i2c, address),
            latest: [0; reg::SAMPLE_BYTES],
        }
    }

    pub fn i2c_mut(&mut self) -> &mut I2C {
        self.regs.i2c_mut()
    }

    /// WHO_AM_I (register 0), checked: the value, or [`ErrorCode::WrongSensor`] unless bits
    /// 6:1 name an ITG-3200.
    pub fn probe(&mut self) -> Result<u8, ErrorCode> {
        let who_am_i = self.regs.read_reg(reg::WHO_AM_I)?;
        if !is_itg3200(who_am_i) {
            return Err(ErrorCode::WrongSensor { who_am_i });
        }
        Ok(who_am_i)
    }

    /// H_RESET: every register at its power-on value.
    pub fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        self.regs.write_reg(reg::PWR_MGM, H_RESET)?;
        delay.delay_ms(RESET_DELAY_MS);
        Ok(())
    }

    /// Awake on the PLL, then SMPLRT_DIV, DLPF_FS and INT_CFG, each whole and verified.
    pub fn configure(&mut self, settings: &Itg3200Settings) -> Result<(), ErrorCode> {
        self.regs.write_verified(reg::PWR_MGM, PWR_MGM_RUN)?;
        self.regs
            .write_verified(reg::SMPLRT_DIV, settings.smplrt_div)?;
        self.regs.write_verified(reg::DLPF_FS, settings.dlpf_fs())?;
        self.regs.write_verified(reg::INT_CFG, INT_CFG_RUN)
    }

    /// The settings the registers hold.
    pub fn read_settings(&mut self) -> Result<Itg3200Settings, ErrorCode> {
        let mut b = [0u8; 2];
        self.regs.read_regs(reg::SMPLRT_DIV, &mut b)?;
        Ok(Itg3200Settings::from_registers(b[0], b[1]))
    }

    /// Whether the chip still holds what streaming set up: [`ErrorCode::SensorReset`] if
    /// anything differs (a chip that reset itself reads its power-on values).
    pub fn check_streaming(&mut self, settings: &Itg3200Settings) -> Result<(), ErrorCode> {
        let mut held = [0u8; 3];
        self.regs.read_regs(reg::SMPLRT_DIV, &mut held)?;
        let power = self.regs.read_reg(reg::PWR_MGM)?;
        if held != [settings.smplrt_div, settings.dlpf_fs(), INT_CFG_RUN] || power != PWR_MGM_RUN {
            return Err(ErrorCode::SensorReset);
        }
        Ok(())
    }
}

impl<I2C: I2c> Sensor for Itg3200<I2C> {
    const SAMPLE_BYTES: usize = reg::SAMPLE_BYTES;
    const OVERWRITES_SILENTLY: bool = true;

    fn i2c_errors(&self) -> u32 {
        self.regs.i2c_errors()
    }

    fn capacity_samples(&self) -> usize {
        1
    }

    /// Read INT_STATUS, clearing it: the next sample flagged is the first of the run.
    fn restart_timed(&mut self, mut now: impl FnMut() -> u64) -> Result<(u64, u64), ErrorCode> {
        let before = now();
        self.regs.read_reg(reg::INT_STATUS)?;
        let after = now();
        Ok((before, after))
    }

    fn waiting(&mut self) -> Result<Waiting, ErrorCode> {
        let mut b = [0u8; 1 + reg::SAMPLE_BYTES];
        self.regs.read_once(reg::INT_STATUS, &mut b)?;
        let ready = u16::from(b[0] & RAW_DATA_RDY != 0);
        self.latest.copy_from_slice(&b[1..]);
        Ok(Waiting {
            samples: ready,
            count: ready,
            full: false,
            impossible: false,
        })
    }

    /// The sample read with the flag (no second transaction).
    fn read_samples(&mut self, buf: &mut [u8]) -> Result<(), ErrorCode> {
        let n = buf.len().min(self.latest.len());
        buf[..n].copy_from_slice(&self.latest[..n]);
        Ok(())
    }

    fn overran(&mut self) -> Result<bool, ErrorCode> {
        Ok(false)
    }

    /// PWR_MGM reads 0 after a power-on reset, PWR_MGM_RUN while we run it.
    fn check_awake(&mut self) -> Result<(), ErrorCode> {
        self.regs.verify(reg::PWR_MGM, PWR_MGM_RUN)
    }

    fn decode(bytes: &[u8]) -> RawSample {
        let word = |i: usize| match bytes.get(2 * i..2 * i + 2) {
            Some(&[hi, lo]) => i16::from_be_bytes([hi, lo]),
            _ => 0,
        };
        RawSample {
            accel: [0; 3],
            temp: word(0),
            gyro: [word(1), word(2), word(3)],
        }
    }
}

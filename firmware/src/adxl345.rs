//! The ADXL345 accelerometer on embedded-hal 1.0 I2C, read through the [`Sensor`] trait.
//!
//! Its 32-sample FIFO runs in stream mode (the newest 32 kept). FIFO_STATUS counts the
//! samples held; each six-byte burst from DATAX0 reads one sample and moves the next into
//! the data registers, so a drain of n samples is n bursts. The chip's OVERRUN bit clears as
//! the data registers are read (data sheet rev. G, "Interrupts"), so it cannot tell a drain
//! that samples were dropped; a full FIFO can, read before the bursts and again after them.
//!
//! Register numbers and bits: [`protocol::adxl345::reg`].

use crate::registers::Registers;
use crate::sensor::{Sensor, Waiting};
use embedded_hal::i2c::I2c;
use protocol::adxl345::reg::bits::{ENTRIES_MASK, FIFO_MODE_STREAM, MEASURE};
use protocol::adxl345::{Adxl345Settings, DEVID_VALUE, FIFO_DEPTH, reg};
use protocol::{ErrorCode, RawSample};

/// Highest output rate streamed from the ADXL345: each sample is its own six-byte burst
/// (about 0.2 ms at 400 kHz), so 800 Hz keeps the bus a sixth busy; 1600 and 3200 Hz would
/// crowd out the other sensor on the bus.
pub const MAX_RATE_HZ: f64 = 800.0;

/// The sample period of `settings` if this firmware streams them: a rate the data sheet
/// offers in that power mode, at no more than [`MAX_RATE_HZ`]; [`ErrorCode::InvalidSettings`]
/// otherwise.
pub fn period_us(settings: &Adxl345Settings) -> Result<u32, ErrorCode> {
    if !settings.is_specified() || settings.output_rate_hz() > MAX_RATE_HZ {
        return Err(ErrorCode::InvalidSettings);
    }
    Ok(settings.period_us())
}

/// The ADXL345 on an I2C bus.
#[derive(Debug)]
pub struct Adxl345<I2C> {
    regs: Registers<I2C>,
}

impl<I2C: I2c> Adxl345<I2C> {
    pub fn new(i2c: I2C, address: u8) -> Self {
        Adxl345 {
            regs: Registers::new(i2c, address),
        }
    }

    pub fn i2c_mut(&mut self) -> &mut I2C {
        self.regs.i2c_mut()
    }

    /// DEVID, checked: the value, or [`ErrorCode::WrongSensor`] unless it reads 0xE5.
    pub fn probe(&mut self) -> Result<u8, ErrorCode> {
        let devid = self.regs.read_reg(reg::DEVID)?;
        if devid != DEVID_VALUE {
            return Err(ErrorCode::WrongSensor { who_am_i: devid });
        }
        Ok(devid)
    }

    /// Standby, then BW_RATE, DATA_FORMAT (full resolution) and the FIFO in stream mode,
    /// each whole and verified, then measuring. The chip has no reset command: standby and
    /// whole writes are what puts it in a known state.
    pub fn configure(&mut self, settings: &Adxl345Settings) -> Result<(), ErrorCode> {
        self.regs.write_verified(reg::POWER_CTL, 0)?;
        self.regs.write_verified(reg::BW_RATE, settings.bw_rate())?;
        self.regs
            .write_verified(reg::DATA_FORMAT, settings.data_format())?;
        self.regs.write_verified(reg::FIFO_CTL, FIFO_MODE_STREAM)?;
        self.regs.write_verified(reg::POWER_CTL, MEASURE)
    }

    /// The settings the registers hold.
    pub fn read_settings(&mut self) -> Result<Adxl345Settings, ErrorCode> {
        let bw_rate = self.regs.read_reg(reg::BW_RATE)?;
        let data_format = self.regs.read_reg(reg::DATA_FORMAT)?;
        Ok(Adxl345Settings::from_registers(bw_rate, data_format))
    }

    /// Whether the chip still holds what streaming set up: [`ErrorCode::SensorReset`] if
    /// anything differs.
    pub fn check_streaming(&mut self, settings: &Adxl345Settings) -> Result<(), ErrorCode> {
        let mut rate_power = [0u8; 2];
        self.regs.read_regs(reg::BW_RATE, &mut rate_power)?;
        let format = self.regs.read_reg(reg::DATA_FORMAT)?;
        let fifo = self.regs.read_reg(reg::FIFO_CTL)?;
        if rate_power != [settings.bw_rate(), MEASURE]
            || format != settings.data_format()
            || fifo != FIFO_MODE_STREAM
        {
            return Err(ErrorCode::SensorReset);
        }
        Ok(())
    }

    /// The FIFO in bypass mode: emptied, keeping nothing until stream mode again.
    pub fn stop_fifo(&mut self) -> Result<(), ErrorCode> {
        self.regs.write_verified(reg::FIFO_CTL, 0)
    }

    fn entries(&mut self) -> Result<u8, ErrorCode> {
        Ok(self.regs.read_reg(reg::FIFO_STATUS)? & ENTRIES_MASK)
    }
}

impl<I2C: I2c> Sensor for Adxl345<I2C> {
    const SAMPLE_BYTES: usize = reg::SAMPLE_BYTES;

    fn i2c_errors(&self) -> u32 {
        self.regs.i2c_errors()
    }

    fn capacity_samples(&self) -> usize {
        FIFO_DEPTH
    }

    /// Bypass mode empties the FIFO; stream mode starts filling it again.
    fn restart_timed(&mut self, mut now: impl FnMut() -> u64) -> Result<(u64, u64), ErrorCode> {
        self.regs.write_reg(reg::FIFO_CTL, 0)?;
        let before = now();
        self.regs.write_reg(reg::FIFO_CTL, FIFO_MODE_STREAM)?;
        let after = now();
        self.regs.verify(reg::FIFO_CTL, FIFO_MODE_STREAM)?;
        Ok((before, after))
    }

    fn waiting(&mut self) -> Result<Waiting, ErrorCode> {
        let entries = self.entries()?;
        let held = usize::from(entries);
        Ok(Waiting {
            samples: u16::from(entries),
            count: u16::from(entries),
            full: held >= FIFO_DEPTH,
            // The FIFO's 32 plus the one in the data registers.
            impossible: held > FIFO_DEPTH + 1,
        })
    }

    fn read_samples(&mut self, buf: &mut [u8]) -> Result<(), ErrorCode> {
        for sample in buf.chunks_exact_mut(Self::SAMPLE_BYTES) {
            self.regs.read_once(reg::DATAX0, sample)?;
        }
        Ok(())
    }

    /// The FIFO filled while the bursts read it: its oldest may have been dropped between
    /// them, so the samples read may not be consecutive.
    fn overran(&mut self) -> Result<bool, ErrorCode> {
        Ok(usize::from(self.entries()?) >= FIFO_DEPTH)
    }

    /// POWER_CTL reads 0 (standby) after a power-on reset.
    fn check_awake(&mut self) -> Result<(), ErrorCode> {
        self.regs.verify(reg::POWER_CTL, MEASURE)
    }

    fn decode(bytes: &[u8]) -> RawSample {
        let word = |i: usize| match bytes.get(2 * i..2 * i + 2) {
            Some(&[lo, hi]) => i16::from_le_bytes([lo, hi]),
            _ => 0,
        };
        RawSample {
            accel: [word(0), word(1), word(2)],
            temp: 0,
            gyro: [0; 3],
        }
    }
}

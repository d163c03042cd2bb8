//! What the board's control logic needs from each sensor chip beyond draining it
//! ([`SensorChip`]): its identity, a reset, setting it up with its own settings type, turning
//! its buffer off, and reading its set-up back. [`crate::stream::SensorStream`] runs the
//! start, stop, drain, fault and recovery of any of them through this trait, once.

use crate::adxl345::{self, Adxl345};
use crate::driver::{BusClear, Mpu6050};
use crate::itg3200::{self, Itg3200};
use crate::sensor::Sensor;
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::adxl345::Adxl345Settings;
use protocol::itg3200::Itg3200Settings;
use protocol::{ErrorCode, SensorConfig, SensorKind, SensorSettings};

/// A sensor chip the board finds, sets up and streams (module documentation).
pub trait SensorChip: Sensor {
    /// The chip's settings, as the host sends them.
    type Settings: Copy + PartialEq + Default;
    const KIND: SensorKind;

    /// Read and check the identity register: the value it answered, or
    /// [`ErrorCode::WrongSensor`] naming it.
    fn probe(&mut self) -> Result<u8, ErrorCode>;

    /// Every register at its power-on value (with the chip's own start-up wait).
    fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode>;

    /// Awake, `settings` written whole and verified, the buffer selected but off until a
    /// run restarts it ([`Sensor::restart_timed`]).
    fn set_up(&mut self, settings: &Self::Settings) -> Result<(), ErrorCode>;

    /// Stop keeping samples (streaming stopped).
    fn stop(&mut self) -> Result<(), ErrorCode>;

    /// Whether the chip still holds what streaming set up: [`ErrorCode::SensorReset`] if it
    /// reads otherwise (a chip that reset itself reads its power-on values).
    fn check_streaming(&mut self, settings: &Self::Settings) -> Result<(), ErrorCode>;

    /// The sample period of `settings` if this firmware streams them, else
    /// [`ErrorCode::InvalidSettings`].
    fn period_us(settings: &Self::Settings) -> Result<u32, ErrorCode>;

    fn config(settings: Self::Settings) -> SensorConfig;

    /// The settings `config` holds if it is for this kind of chip.
    fn settings_in(config: SensorConfig) -> Option<Self::Settings>;

    /// Free the bus the chip is on ([`BusClear`]).
    fn clear_bus(&mut self);
}

impl<I2C: I2c + BusClear> SensorChip for Mpu6050<I2C> {
    type Settings = SensorSettings;
    const KIND: SensorKind = SensorKind::Mpu6050;

    fn probe(&mut self) -> Result<u8, ErrorCode> {
        Mpu6050::probe(self).map(|chip| chip.who_am_i)
    }

    fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        Mpu6050::reset(self, delay)
    }

    fn set_up(&mut self, settings: &SensorSettings) -> Result<(), ErrorCode> {
        self.wake()?;
        self.configure(settings)?;
        self.enable_fifo()?;
        self.disable_fifo()
    }

    fn stop(&mut self) -> Result<(), ErrorCode> {
        self.disable_fifo()
    }

    fn check_streaming(&mut self, settings: &SensorSettings) -> Result<(), ErrorCode> {
        Mpu6050::check_streaming(self, settings)
    }

    fn period_us(settings: &SensorSettings) -> Result<u32, ErrorCode> {
        crate::acquire::check_supported(settings)?;
        Ok(settings.period_us())
    }

    fn config(settings: SensorSettings) -> SensorConfig {
        SensorConfig::Mpu6050(settings)
    }

    fn settings_in(config: SensorConfig) -> Option<SensorSettings> {
        match config {
            SensorConfig::Mpu6050(s) => Some(s),
            _ => None,
        }
    }

    fn clear_bus(&mut self) {
        self.i2c_mut().clear_bus()
    }
}

impl<I2C: I2c + BusClear> SensorChip for Itg3200<I2C> {
    type Settings = Itg3200Settings;
    const KIND: SensorKind = SensorKind::Itg3200;

    fn probe(&mut self) -> Result<u8, ErrorCode> {
        Itg3200::probe(self)
    }

    fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        Itg3200::reset(self, delay)
    }

    fn set_up(&mut self, settings: &Itg3200Settings) -> Result<(), ErrorCode> {
        self.configure(settings)
    }

    /// Nothing to stop: without a FIFO the chip keeps only its latest sample.
    fn stop(&mut self) -> Result<(), ErrorCode> {
        Ok(())
    }

    fn check_streaming(&mut self, settings: &Itg3200Settings) -> Result<(), ErrorCode> {
        Itg3200::check_streaming(self, settings)
    }

    fn period_us(settings: &Itg3200Settings) -> Result<u32, ErrorCode> {
        itg3200::period_us(settings)
    }

    fn config(settings: Itg3200Settings) -> SensorConfig {
        SensorConfig::Itg3200(settings)
    }

    fn settings_in(config: SensorConfig) -> Option<Itg3200Settings> {
        match config {
            SensorConfig::Itg3200(s) => Some(s),
            _ => None,
        }
    }

    fn clear_bus(&mut self) {
        self.i2c_mut().clear_bus()
    }
}

impl<I2C: I2c + BusClear> SensorChip for Adxl345<I2C> {
    type Settings = Adxl345Settings;
    const KIND: SensorKind = SensorKind::Adxl345;

    fn probe(&mut self) -> Result<u8, ErrorCode> {
        Adxl345::probe(self)
    }

    /// The chip has no reset command; [`SensorChip::set_up`] writes every register it uses.
    fn reset(&mut self, _: &mut impl DelayNs) -> Result<(), ErrorCode> {
        Ok(())
    }

    fn set_up(&mut self, settings: &Adxl345Settings) -> Result<(), ErrorCode> {
        self.configure(settings)?;
        self.stop_fifo()
    }

    fn stop(&mut self) -> Result<(), ErrorCode> {
        self.stop_fifo()
    }

    fn check_streaming(&mut self, settings: &Adxl345Settings) -> Result<(), ErrorCode> {
        Adxl345::check_streaming(self, settings)
    }

    fn period_us(settings: &Adxl345Settings) -> Result<u32, ErrorCode> {
        adxl345::period_us(settings)
    }

    fn config(settings: Adxl345Settings) -> SensorConfig {
        SensorConfig::Adxl345(settings)
    }

    fn settings_in(config: SensorConfig) -> Option<Adxl345Settings> {
        match config {
            SensorConfig::Adxl345(s) => Some(s),
            _ => None,
        }
    }

    fn clear_bus(&mut self) {
        self.i2c_mut().clear_bus()
    }
}

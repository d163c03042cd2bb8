//! Register-level MPU-6050 access on embedded-hal 1.0 I2C.
//!
//! Why our own driver: the `mpu6050` crate targets embedded-hal 0.2, has no FIFO, DLPF or
//! divider API and reads accel and gyro in separate transactions; `mpu6050-dmp` is on
//! embedded-hal 1.0 but its setters OR bits into a register without clearing the field
//! first, so changing e.g. FS_SEL from 3 to 1 leaves 3. Here every configuration register
//! is written whole (we own every bit of it) and read back: a register that does not hold
//! what was written is an error the host sees ([`ErrorCode::VerifyFailed`]), never a silent
//! difference between the settings the host asked for and the ones the sensor uses.
//!
//! Register access (retries, counting, verification) is [`Registers`]'; FIFO reads are
//! never retried.

pub use crate::registers::ATTEMPTS;
use crate::registers::Registers;
use crate::sensor::{Sensor, Waiting};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::mpu6050::reg::bits::{
    DATA_RDY, DEVICE_RESET, FIFO_EN_ALL, FIFO_OFLOW, FIFO_RESET, SIGNAL_PATH_RESET_ALL,
    USER_FIFO_EN,
};
use protocol::mpu6050::{Chip, FIFO_SIZE, SensorSettings, chip, reg};
use protocol::{ErrorCode, RawSample};

/// PWR_MGMT_1 as we run it: awake, temperature sensor on, no cycling, clock from the X
/// gyro's PLL (CLKSEL = 1), which the register map recommends over the 8 MHz internal
/// oscillator for stability.
pub const PWR_MGMT_1_RUN: u8 = 0x01;
/// INT_ENABLE as we run it: FIFO_OFLOW must be enabled for INT_STATUS to report it;
/// DATA_RDY drives the optional interrupt pin. Temperature is in the FIFO
/// ([`FIFO_EN_ALL`]) so that every sample carries the temperature it was taken at (the drift
/// analysis needs it).
pub const INT_ENABLE_RUN: u8 = FIFO_OFLOW | DATA_RDY;
/// How long the chip needs after DEVICE_RESET before it answers reliably [RM, reg 107].
pub const RESET_DELAY_MS: u32 = 100;

/// Freeing an I2C bus that a slave holds: a sensor reset or a glitch in the middle of a read
/// can leave it driving SDA low, waiting for clocks that never come, and no transaction can
/// start. The cure (NXP UM10204 rev. 7, 3.1.16 "Bus clear") is up to nine SCL pulses until
/// SDA is released, then a STOP. Only the board can drive the pins, so the bus type does it.
pub trait BusClear {
    /// Pulse SCL (up to nine times) and send a STOP; the bus is usable afterwards.
    fn clear_bus(&mut self);
}

impl<T: BusClear + ?Sized> BusClear for &mut T {
    fn clear_bus(&mut self) {
        (**self).clear_bus()
    }
}

/// The MPU-6050 on an I2C bus.
#[derive(Debug)]
pub struct Mpu6050<I2C> {
    regs: Registers<I2C>,
    /// FIFO size of the chip that answered the last probe.
    fifo_capacity: usize,
}

impl<I2C: I2c> Mpu6050<I2C> {
    pub fn new(i2c: I2C, address: u8) -> Self {
        Mpu6050 {
            regs: Registers::new(i2c, address),
            fifo_capacity: FIFO_SIZE,
        }
    }

    /// The bus (the virtual board uses it to drive the simulated sensor's clock).
    pub fn i2c_mut(&mut self) -> &mut I2C {
        self.regs.i2c_mut()
    }

    pub fn release(self) -> I2C {
        self.regs.release()
    }

    /// Failed I2C attempts so far (every failed retry counts).
    pub fn i2c_errors(&self) -> u32 {
        self.regs.i2c_errors()
    }

    /// WHO_AM_I, checked: [`ErrorCode::WrongSensor`] unless it names an MPU-6050 or a chip
    /// known to share its registers ([`protocol::mpu6050::KNOWN_CHIPS`]).
    pub fn probe(&mut self) -> Result<Chip, ErrorCode> {
        let who_am_i = self.read_reg(reg::WHO_AM_I)?;
        let found = chip(who_am_i).ok_or(ErrorCode::WrongSensor { who_am_i })?;
        self.fifo_capacity = found.fifo_size;
        Ok(found)
    }

    /// FIFO size of the chip found by the last probe, bytes.
    pub fn fifo_capacity(&self) -> usize {
        self.fifo_capacity
    }

    /// Device reset, then signal-path reset: every register at its reset value, asleep.
    pub fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        self.write_reg(reg::PWR_MGMT_1, DEVICE_RESET)?;
        delay.delay_ms(RESET_DELAY_MS);
        self.write_reg(reg::SIGNAL_PATH_RESET, SIGNAL_PATH_RESET_ALL)?;
        delay.delay_ms(RESET_DELAY_MS);
        Ok(())
    }

    /// Wake with the gyro PLL as clock and all six axes on.
    pub fn wake(&mut self) -> Result<(), ErrorCode> {
        self.write_verified(reg::PWR_MGMT_1, PWR_MGMT_1_RUN)?;
        self.write_verified(reg::PWR_MGMT_2, 0)
    }

    /// Whether the chip is still awake with our clock source: a sensor that reset itself
    /// (brown-out, glitch) comes back asleep with PWR_MGMT_1 = 0x40.
    pub fn check_awake(&mut self) -> Result<(), ErrorCode> {
        let read = self.read_reg(reg::PWR_MGMT_1)?;
        if read != PWR_MGMT_1_RUN {
            return Err(ErrorCode::VerifyFailed {
                register: reg::PWR_MGMT_1,
                wrote: PWR_MGMT_1_RUN,
                read,
            });
        }
        Ok(())
    }

    /// Whether the sensor still holds what streaming set up: awake on our clock, `settings`
    /// in registers 25-28, the FIFO enabled and fed every channel. One burst of four and
    /// three single reads. [`ErrorCode::SensorReset`] if anything differs (a chip that reset
    /// itself reads its power-on defaults), the I2C error if a read fails.
    pub fn check_streaming(&mut self, settings: &SensorSettings) -> Result<(), ErrorCode> {
        let r = settings.registers();
        let mut held = [0u8; 4];
        self.read_regs(reg::SMPLRT_DIV, &mut held)?;
        let expected = [r.smplrt_div, r.config, r.gyro_config, r.accel_config];
        let power = self.read_reg(reg::PWR_MGMT_1)?;
        let user = self.read_reg(reg::USER_CTRL)?;
        let fifo_en = self.read_reg(reg::FIFO_EN)?;
        if held != expected
            || power != PWR_MGMT_1_RUN
            || user & USER_FIFO_EN == 0
            || fifo_en != FIFO_EN_ALL
        {
            return Err(ErrorCode::SensorReset);
        }
        Ok(())
    }

    /// Write SMPLRT_DIV, CONFIG (DLPF_CFG, EXT_SYNC off), GYRO_CONFIG (FS_SEL, self-test
    /// off), ACCEL_CONFIG (AFS_SEL, self-test off), each whole and verified.
    pub fn configure(&mut self, settings: &SensorSettings) -> Result<(), ErrorCode> {
        let r = settings.registers();
        self.write_verified(reg::SMPLRT_DIV, r.smplrt_div)?;
        self.write_verified(reg::CONFIG, r.config)?;
        self.write_verified(reg::GYRO_CONFIG, r.gyro_config)?;
        self.write_verified(reg::ACCEL_CONFIG, r.accel_config)
    }

    /// The settings the sensor's registers hold (one burst read of registers 25-28).
    pub fn read_settings(&mut self) -> Result<SensorSettings, ErrorCode> {
        let mut b = [0u8; 4];
        self.read_regs(reg::SMPLRT_DIV, &mut b)?;
        Ok(SensorSettings::from_registers(
            protocol::mpu6050::RegisterValues {
                smplrt_div: b[0],
                config: b[1],
                gyro_config: b[2],
                accel_config: b[3],
            },
        ))
    }

    /// Select the FIFO channels and interrupt sources, then empty and enable the FIFO.
    pub fn enable_fifo(&mut self) -> Result<(), ErrorCode> {
        self.write_verified(reg::FIFO_EN, FIFO_EN_ALL)?;
        self.write_verified(reg::INT_ENABLE, INT_ENABLE_RUN)?;
        self.reset_fifo()
    }

    /// Empty the FIFO and (re)enable it. The register map says FIFO_RESET acts "while
    /// FIFO_EN equals 0", hence three writes: disable, reset, enable (verified). Then read
    /// INT_STATUS: an overflow flag latched before the reset would otherwise condemn the
    /// next, good, drain.
    pub fn reset_fifo(&mut self) -> Result<(), ErrorCode> {
        self.reset_fifo_timed(|| 0).map(|_| ())
    }

    /// [`Mpu6050::reset_fifo`], with `now()` read just before and just after the write that
    /// enables the FIFO again: the first sample the FIFO holds is the first one the sensor
    /// made after that moment, so the two times bracket where the new run's numbering starts.
    pub fn reset_fifo_timed(
        &mut self,
        mut now: impl FnMut() -> u64,
    ) -> Result<(u64, u64), ErrorCode> {
        self.write_reg(reg::USER_CTRL, 0)?;
        self.write_reg(reg::USER_CTRL, FIFO_RESET)?;
        let before = now();
        self.write_reg(reg::USER_CTRL, USER_FIFO_EN)?;
        let after = now();
        self.verify(reg::USER_CTRL, USER_FIFO_EN)?;
        self.int_status()?;
        Ok((before, after))
    }

    /// Stop filling the FIFO (streaming stopped).
    pub fn disable_fifo(&mut self) -> Result<(), ErrorCode> {
        self.write_verified(reg::USER_CTRL, 0)
    }

    /// FIFO_COUNT, bytes in the FIFO (big-endian pair, one burst so the halves match).
    pub fn fifo_count(&mut self) -> Result<u16, ErrorCode> {
        let mut b = [0u8; 2];
        self.read_regs(reg::FIFO_COUNT_H, &mut b)?;
        Ok(u16::from_be_bytes(b))
    }

    /// INT_STATUS (cleared by the read).
    pub fn int_status(&mut self) -> Result<u8, ErrorCode> {
        self.read_reg(reg::INT_STATUS)
    }

    /// Pop `buf.len()` bytes from the FIFO in one burst. Not retried (see module docs).
    pub fn read_fifo(&mut self, buf: &mut [u8]) -> Result<(), ErrorCode> {
        self.regs.read_once(reg::FIFO_R_W, buf)
    }

    fn read_reg(&mut self, register: u8) -> Result<u8, ErrorCode> {
        self.regs.read_reg(register)
    }

    fn read_regs(&mut self, register: u8, buf: &mut [u8]) -> Result<(), ErrorCode> {
        self.regs.read_regs(register, buf)
    }

    fn write_reg(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        self.regs.write_reg(register, value)
    }

    fn write_verified(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        self.regs.write_verified(register, value)
    }

    fn verify(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        self.regs.verify(register, value)
    }
}

/// The FIFO as the acquisition drains it: whole 14-byte samples (accel, temperature, gyro),
/// full at the chip's FIFO size, FIFO_OFLOW as the overrun.
impl<I2C: I2c> Sensor for Mpu6050<I2C> {
    const SAMPLE_BYTES: usize = RawSample::FIFO_BYTES;

    fn i2c_errors(&self) -> u32 {
        self.regs.i2c_errors()
    }

    fn capacity_samples(&self) -> usize {
        self.fifo_capacity / Self::SAMPLE_BYTES
    }

    fn restart_timed(&mut self, now: impl FnMut() -> u64) -> Result<(u64, u64), ErrorCode> {
        self.reset_fifo_timed(now)
    }

    fn waiting(&mut self) -> Result<Waiting, ErrorCode> {
        let count = self.fifo_count()?;
        let bytes = usize::from(count);
        Ok(Waiting {
            samples: count / Self::SAMPLE_BYTES as u16,
            count,
            full: bytes >= self.fifo_capacity,
            impossible: bytes > self.fifo_capacity,
        })
    }

    fn read_samples(&mut self, buf: &mut [u8]) -> Result<(), ErrorCode> {
        self.read_fifo(buf)
    }

    fn overran(&mut self) -> Result<bool, ErrorCode> {
        Ok(self.int_status()? & FIFO_OFLOW != 0)
    }

    fn check_awake(&mut self) -> Result<(), ErrorCode> {
        Mpu6050::check_awake(self)
    }

    fn decode(bytes: &[u8]) -> RawSample {
        let mut sample = [0u8; RawSample::FIFO_BYTES];
        let n = bytes.len().min(sample.len());
        sample[..n].copy_from_slice(&bytes[..n]);
        RawSample::from_fifo_bytes(&sample)
    }
}

#[cfg(test)]
pub(crate) mod mock {
    //! A tiny register-file I2C device for unit tests: 128 registers, auto-increment,
    //! scripted failures and registers that ignore writes.
    use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct MockError(pub ErrorKind);
    impl embedded_hal::i2c::Error for MockError {
        fn kind(&self) -> ErrorKind {
            self.0
        }
    }

    pub struct MockBus {
        pub regs: [u8; 128],
        /// The next this many transactions fail with `fail_kind`.
        pub fail_next: u32,
        pub fail_kind: ErrorKind,
        /// Writes to this register are ignored (a stuck bit, a read-only register).
        pub ignore_writes_to: Option<u8>,
        pub transactions: u32,
        pub bus_clears: u32,
    }

    impl MockBus {
        pub fn new() -> Self {
            let mut regs = [0u8; 128];
            regs[usize::from(protocol::mpu6050::reg::WHO_AM_I)] = 0x68;
            MockBus {
                regs,
                fail_next: 0,
                fail_kind: ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address),
                ignore_writes_to: None,
                transactions: 0,
                bus_clears: 0,
            }
        }
    }

    impl ErrorType for MockBus {
        type Error = MockError;
    }

    impl super::BusClear for MockBus {
        fn clear_bus(&mut self) {
            self.bus_clears += 1;
        }
    }

    impl I2c for MockBus {
        fn transaction(&mut self, _: u8, ops: &mut [Operation<'_>]) -> Result<(), MockError> {
            self.transactions += 1;
            if self.fail_next > 0 {
                self.fail_next -= 1;
                return Err(MockError(self.fail_kind));
            }
            let mut pointer = 0usize;
            for op in ops {
                match op {
                    Operation::Write(bytes) => {
                        pointer = usize::from(bytes[0]);
                        for &b in &bytes[1..] {
                            if self.ignore_writes_to != Some(pointer as u8) {
                                self.regs[pointer] = b;
                            }
                            pointer += 1;
                        }
                    }
                    Operation::Read(buf) => {
                        for b in buf.iter_mut() {
                            *b = self.regs[pointer];
                            pointer += 1;
                        }
                    }
                }
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::mock::MockBus;
    use super::*;
    use embedded_hal::i2c::ErrorKind;
    use protocol::mpu6050::{AccelRange, DlpfCfg, GyroRange};

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _: u32) {}
    }

    #[test]
    fn configure_writes_whole_registers_and_clears_old_fields() {
        let mut bus = MockBus::new();
        // Leftovers a bit-ORing driver would keep: FS_SEL 3, self-test bits, EXT_SYNC.
        bus.regs[usize::from(reg::GYRO_CONFIG)] = 0xF8;
        bus.regs[usize::from(reg::ACCEL_CONFIG)] = 0xFF;
        bus.regs[usize::from(reg::CONFIG)] = 0x3F;
        let mut dev = Mpu6050::new(bus, 0x68);
        let s = SensorSettings {
            dlpf: DlpfCfg::Cfg2,
            smplrt_div: 4,
            gyro_range: GyroRange::Dps500,
            accel_range: AccelRange::G4,
        };
        dev.configure(&s).unwrap();
        assert_eq!(dev.read_settings().unwrap(), s);
        let regs = dev.i2c_mut().regs;
        assert_eq!(regs[usize::from(reg::GYRO_CONFIG)], 0x08);
        assert_eq!(regs[usize::from(reg::ACCEL_CONFIG)], 0x08);
        assert_eq!(regs[usize::from(reg::CONFIG)], 0x02);
    }

    #[test]
    fn a_register_that_does_not_take_the_value_is_reported() {
        let mut bus = MockBus::new();
        bus.ignore_writes_to = Some(reg::CONFIG);
        bus.regs[usize::from(reg::CONFIG)] = 0x01;
        let mut dev = Mpu6050::new(bus, 0x68);
        let err = dev.configure(&SensorSettings::default()).unwrap_err();
        assert_eq!(
            err,
            ErrorCode::VerifyFailed {
                register: reg::CONFIG,
                wrote: 3,
                read: 1
            }
        );
    }

    #[test]
    fn transient_errors_are_retried_and_counted_persistent_ones_reported() {
        let mut bus = MockBus::new();
        bus.fail_next = ATTEMPTS - 1;
        let mut dev = Mpu6050::new(bus, 0x68);
        assert_eq!(dev.probe().map(|c| c.who_am_i), Ok(0x68));
        assert_eq!(dev.i2c_errors(), ATTEMPTS - 1);
        dev.i2c_mut().fail_next = ATTEMPTS;
        assert_eq!(dev.probe(), Err(ErrorCode::SensorNotResponding));
        dev.i2c_mut().fail_next = ATTEMPTS;
        dev.i2c_mut().fail_kind = ErrorKind::Bus;
        assert_eq!(dev.fifo_count(), Err(ErrorCode::I2cFailure));
        assert_eq!(dev.i2c_errors(), 3 * ATTEMPTS - 1);
        // FIFO reads are not retried: one failure, one error.
        dev.i2c_mut().fail_next = 1;
        let before = dev.i2c_mut().transactions;
        assert_eq!(dev.read_fifo(&mut [0; 14]), Err(ErrorCode::I2cFailure));
        assert_eq!(dev.i2c_mut().transactions, before + 1);
    }

    #[test]
    fn clones_are_accepted_unknown_chips_named_and_init_sequence() {
        let mut bus = MockBus::new();
        bus.regs[usize::from(reg::WHO_AM_I)] = 0x70; // an MPU-6500: a 512-byte FIFO
        let mut dev = Mpu6050::new(bus, 0x68);
        assert_eq!(dev.probe().map(|c| c.fifo_size), Ok(512));
        assert_eq!(dev.fifo_capacity(), 512);
        for clone in [0x72, 0x98] {
            dev.i2c_mut().regs[usize::from(reg::WHO_AM_I)] = clone;
            assert_eq!(dev.probe().map(|c| c.who_am_i), Ok(clone));
            assert_eq!(dev.fifo_capacity(), 1024);
        }
        dev.i2c_mut().regs[usize::from(reg::WHO_AM_I)] = 0x71; // an MPU-9250
        assert_eq!(dev.probe(), Err(ErrorCode::WrongSensor { who_am_i: 0x71 }));
        dev.reset(&mut NoDelay).unwrap();
        dev.wake().unwrap();
        dev.enable_fifo().unwrap();
        let regs = dev.i2c_mut().regs;
        assert_eq!(regs[usize::from(reg::PWR_MGMT_1)], PWR_MGMT_1_RUN);
        assert_eq!(regs[usize::from(reg::FIFO_EN)], FIFO_EN_ALL);
        assert_eq!(regs[usize::from(reg::USER_CTRL)], USER_FIFO_EN);
        assert_eq!(dev.check_awake(), Ok(()));
        dev.i2c_mut().regs[usize::from(reg::PWR_MGMT_1)] = 0x40;
        assert!(matches!(
            dev.check_awake(),
            Err(ErrorCode::VerifyFailed { read: 0x40, .. })
        ));
    }
}

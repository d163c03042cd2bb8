//! Register access on embedded-hal 1.0 I2C, shared by every sensor driver: reads and writes
//! retried and counted, writes verified.
//!
//! Errors are [`ErrorCode`]s, the values the host receives. Every failed I2C attempt is
//! counted ([`Registers::i2c_errors`]); idempotent transactions (register reads and writes)
//! are retried up to [`ATTEMPTS`] times, reads that pop a FIFO never
//! ([`Registers::read_once`]: a failed burst may already have popped bytes, so repeating it
//! would silently misalign samples).

use embedded_hal::i2c::{Error as _, ErrorKind, I2c, NoAcknowledgeSource};
use protocol::ErrorCode;

/// Attempts per idempotent transaction before the error is reported.
pub const ATTEMPTS: u32 = 3;

/// One chip's registers on an I2C bus.
#[derive(Debug)]
pub struct Registers<I2C> {
    i2c: I2C,
    address: u8,
    i2c_errors: u32,
}

impl<I2C: I2c> Registers<I2C> {
    pub fn new(i2c: I2C, address: u8) -> Self {
        Registers {
            i2c,
            address,
            i2c_errors: 0,
        }
    }

    /// The bus (the virtual board uses it to drive the simulated sensor's clock).
    pub fn i2c_mut(&mut self) -> &mut I2C {
        &mut self.i2c
    }

    pub fn release(self) -> I2C {
        self.i2c
    }

    pub fn address(&self) -> u8 {
        self.address
    }

    /// Failed I2C attempts so far (every failed retry counts).
    pub fn i2c_errors(&self) -> u32 {
        self.i2c_errors
    }

    pub fn read_reg(&mut self, register: u8) -> Result<u8, ErrorCode> {
        let mut b = [0u8; 1];
        self.read_regs(register, &mut b)?;
        Ok(b[0])
    }

    /// Burst read from `register` on (auto-increment), retried.
    pub fn read_regs(&mut self, register: u8, buf: &mut [u8]) -> Result<(), ErrorCode> {
        let address = self.address;
        self.retry(|i2c| i2c.write_read(address, &[register], buf))
    }

    /// Burst read from `register`, not retried: for reads that pop a FIFO.
    pub fn read_once(&mut self, register: u8, buf: &mut [u8]) -> Result<(), ErrorCode> {
        self.i2c
            .write_read(self.address, &[register], buf)
            .map_err(|e| {
                self.i2c_errors = self.i2c_errors.saturating_add(1);
                classify(e.kind())
            })
    }

    pub fn write_reg(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        let address = self.address;
        self.retry(|i2c| i2c.write(address, &[register, value]))
    }

    /// Write, read back, compare.
    pub fn write_verified(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        self.write_reg(register, value)?;
        self.verify(register, value)
    }

    /// Read `register` back: [`ErrorCode::VerifyFailed`] unless it holds `value`.
    pub fn verify(&mut self, register: u8, value: u8) -> Result<(), ErrorCode> {
        let read = self.read_reg(register)?;
        if read != value {
            return Err(ErrorCode::VerifyFailed {
                register,
                wrote: value,
                read,
            });
        }
        Ok(())
    }

    fn retry<E: embedded_hal::i2c::Error>(
        &mut self,
        mut op: impl FnMut(&mut I2C) -> Result<(), E>,
    ) -> Result<(), ErrorCode> {
        let mut last = ErrorKind::Other;
        for _ in 0..ATTEMPTS {
            match op(&mut self.i2c) {
                Ok(()) => return Ok(()),
                Err(e) => {
                    self.i2c_errors = self.i2c_errors.saturating_add(1);
                    last = e.kind();
                }
            }
        }
        Err(classify(last))
    }
}

/// A sensor that does not acknowledge its address is not there (unplugged, unpowered,
/// wrong address); any other persistent error is a bus problem.
fn classify(kind: ErrorKind) -> ErrorCode {
    match kind {
        ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address) => ErrorCode::SensorNotResponding,
        _ => ErrorCode::I2cFailure,
    }
}

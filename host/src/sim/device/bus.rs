//! The device on the bus: the `embedded_hal` I2C transaction, and the same bus seen byte by
//! byte (start, write, read, stop) for a bus model that reports each event.

use super::SimMpu6050;
use embedded_hal::i2c::{ErrorKind, ErrorType, I2c, NoAcknowledgeSource, Operation};

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

//! What every simulated register-level chip shares on the bus: the register pointer and its
//! auto-increment, the `embedded_hal` I2C transaction seen as bus events (start, write, read,
//! stop), and the injected bus faults. A chip says only what its registers do
//! ([`RegisterChip`]); the bus behaviour is written once, here.

use super::core::SimChip;
use super::faults::take;
use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource, Operation};

/// The bus errors a simulated chip produces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SimI2cError {
    #[error("simulated I2C device: no acknowledge ({0:?})")]
    NoAcknowledge(NoAcknowledgeSource),
    #[error("simulated I2C device: bus error")]
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

/// The bus-side state of a chip: where reads and writes go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Port {
    pointer: u8,
    /// The next written byte is a register pointer.
    expect_pointer: bool,
    /// A byte was written since the last (non-repeated) start.
    written_since_start: bool,
}

impl Default for Port {
    fn default() -> Self {
        Port {
            pointer: 0,
            expect_pointer: true,
            written_since_start: false,
        }
    }
}

/// A chip's registers as the bus reaches them. The provided methods are the bus events; a
/// chip implements its registers' meaning.
pub trait RegisterChip: SimChip {
    /// A register read as the bus does it (with its side effects: a status cleared, a FIFO
    /// popped).
    fn read_register(&mut self, register: u8) -> u8;
    fn write_register(&mut self, register: u8, value: u8);
    /// The register a burst moves to after `register`: the next one, except at a FIFO port
    /// that stays.
    fn next_register(&self, register: u8) -> u8 {
        register.wrapping_add(1) & 0x7F
    }

    /// A start (or, with `repeated`, a repeated start) addressed to `address`: acknowledged
    /// if it is this chip's, unless the time is in an outage or an address NACK or a bus
    /// error is injected (those are counted per transaction, so a repeated start does not
    /// consume them).
    fn bus_start(&mut self, address: u8, repeated: bool) -> Result<(), SimI2cError> {
        let (mine, now) = (address == self.address(), self.time_us());
        let faults = self.faults_mut();
        if !mine || faults.in_outage(now) || (!repeated && take(&mut faults.nack_address)) {
            return Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        if !repeated {
            if take(&mut faults.bus_error) {
                return Err(SimI2cError::Bus);
            }
            self.core_mut().port.written_since_start = false;
        }
        self.core_mut().port.expect_pointer = true;
        Ok(())
    }

    /// A written byte: the register pointer if it is the first since a start or a read,
    /// else a register write (the pointer then advances). The first written byte of a
    /// transaction is refused, without effect, while a data NACK is injected.
    fn bus_write(&mut self, byte: u8) -> Result<(), SimI2cError> {
        if !self.core_mut().port.written_since_start && take(&mut self.faults_mut().nack_data) {
            return Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Data));
        }
        let port = &mut self.core_mut().port;
        port.written_since_start = true;
        if port.expect_pointer {
            port.pointer = byte & 0x7F;
            port.expect_pointer = false;
        } else {
            let register = port.pointer;
            self.write_register(register, byte);
            self.core_mut().port.pointer = self.next_register(register);
        }
        Ok(())
    }

    /// A read byte: the register at the pointer (which then advances). A write after reads
    /// starts with a new pointer, as after a repeated start.
    fn bus_read(&mut self) -> u8 {
        let register = self.core_mut().port.pointer;
        let b = self.read_register(register);
        let next = self.next_register(register);
        let port = &mut self.core_mut().port;
        port.pointer = next;
        port.expect_pointer = true;
        b
    }

    /// A stop: the transaction ends.
    fn bus_stop(&mut self) {
        let port = &mut self.core_mut().port;
        port.expect_pointer = true;
        port.written_since_start = false;
    }

    /// Point the register pointer at 0 (a chip reset).
    fn reset_pointer(&mut self) {
        self.core_mut().port.pointer = 0;
    }
}

/// An `embedded_hal` transaction as its bus events in order: a write after a read is a
/// repeated start, so its first byte is a new register pointer; adjacent writes (or reads)
/// continue one another.
pub fn transaction(
    chip: &mut (impl RegisterChip + ?Sized),
    address: u8,
    operations: &mut [Operation<'_>],
) -> Result<(), SimI2cError> {
    chip.bus_start(address, false)?;
    for op in operations {
        match op {
            Operation::Write(bytes) => {
                for &b in bytes.iter() {
                    chip.bus_write(b)?;
                }
            }
            // A read phase clocks at least one byte (the master ends it with a NACK on the
            // last byte), so a zero-byte read cannot happen on a bus; rp2040-hal refuses one
            // with an abort. Failing it here finds drivers that ask for it.
            Operation::Read([]) => {
                chip.bus_stop();
                return Err(SimI2cError::Bus);
            }
            Operation::Read(buf) => {
                for b in buf.iter_mut() {
                    *b = chip.bus_read();
                }
            }
        }
    }
    chip.bus_stop();
    Ok(())
}

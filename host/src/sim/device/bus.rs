//! The device on the bus: the `embedded_hal` I2C transaction, whose bus events
//! ([`super::RegisterChip`]) a bus model that reports each event drives directly.

use super::{SimI2cError, SimMpu6050, transaction};
use embedded_hal::i2c::{ErrorType, I2c, Operation};

impl ErrorType for SimMpu6050 {
    type Error = SimI2cError;
}

impl I2c for SimMpu6050 {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        transaction(self, address, operations)
    }
}

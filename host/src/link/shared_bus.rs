//! The simulated I2C bus shared by the firmware's drivers (each holds a clone, as on the
//! board, where they share one peripheral), the firmware's clock, and the virtual board that
//! moves time: one type for a board with an MPU-6050 alone and one with the GY-85's pair.

use crate::sim::device::{SimBus, SimI2cError};
use embedded_hal::i2c::{ErrorType, I2c, Operation};
use firmware::Clock;
use std::sync::{Arc, Mutex, MutexGuard};

/// The simulated bus, shared (module documentation).
#[derive(Clone)]
pub struct SharedBus(Arc<Mutex<SimBus>>);

impl SharedBus {
    pub fn new(bus: SimBus) -> Self {
        SharedBus(Arc::new(Mutex::new(bus)))
    }

    /// The bus; a poisoned lock (a panic elsewhere) still yields it, since its state is
    /// plain registers and FIFO bytes.
    pub fn lock(&self) -> MutexGuard<'_, SimBus> {
        self.0
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl ErrorType for SharedBus {
    type Error = SimI2cError;
}

impl I2c for SharedBus {
    fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), SimI2cError> {
        self.lock().transaction(address, ops)
    }
}

/// The simulated chips have no pins to hold low: clearing the bus ends any transaction they
/// are in, which is what nine clocks and a STOP do to real ones.
impl firmware::BusClear for SharedBus {
    fn clear_bus(&mut self) {
        self.lock().bus_stop();
    }
}

impl Clock for SharedBus {
    fn now_us(&mut self) -> u64 {
        self.lock().time_us()
    }
}

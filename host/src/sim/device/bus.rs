//! The chips on the bus: each alone as an `embedded_hal` I2C bus (a board with one sensor),
//! and [`SimBus`], several chips at their own addresses on one bus (a GY-85's ITG-3200 and
//! ADXL345). A transaction's bus events ([`super::RegisterChip`]) go to the chip addressed;
//! an address no chip has is not acknowledged. The bus takes those events one by one too
//! ([`SimBus::bus_start`] ...), for a bus model in another process ([`crate::sim::bus_server`]).

use super::{
    JournalEntry, RegisterChip, SampledChip, SimAdxl345, SimI2cError, SimItg3200, SimMpu6050,
    transaction,
};
use crate::sim::imu::TrueInput;
use embedded_hal::i2c::{ErrorType, I2c, NoAcknowledgeSource, Operation};
use std::time::Duration;

macro_rules! alone_on_the_bus {
    ($($chip:ty),*) => {$(
        impl ErrorType for $chip {
            type Error = SimI2cError;
        }

        impl I2c for $chip {
            fn transaction(
                &mut self,
                address: u8,
                operations: &mut [Operation<'_>],
            ) -> Result<(), Self::Error> {
                transaction(self, address, operations)
            }
        }
    )*};
}

alone_on_the_bus!(SimMpu6050, SimItg3200, SimAdxl345);

/// One simulated chip on a shared bus.
#[derive(Debug, Clone)]
pub enum BusChip {
    Mpu6050(SimMpu6050),
    Itg3200(SimItg3200),
    Adxl345(SimAdxl345),
}

impl BusChip {
    fn chip(&mut self) -> &mut dyn RegisterChip {
        match self {
            BusChip::Mpu6050(c) => c,
            BusChip::Itg3200(c) => c,
            BusChip::Adxl345(c) => c,
        }
    }

    fn chip_ref(&self) -> &dyn RegisterChip {
        match self {
            BusChip::Mpu6050(c) => c,
            BusChip::Itg3200(c) => c,
            BusChip::Adxl345(c) => c,
        }
    }

    fn advance_to_us(&mut self, t_us: u64) {
        match self {
            BusChip::Mpu6050(c) => c.advance_to_us(t_us),
            BusChip::Itg3200(c) => c.advance_to_us(t_us),
            BusChip::Adxl345(c) => c.advance_to_us(t_us),
        }
    }
}

/// Several chips on one bus, sharing its clock.
#[derive(Debug, Clone, Default)]
pub struct SimBus {
    chips: Vec<BusChip>,
    time_us: u64,
    /// The chip that acknowledged the last start: where written and read bytes go until the
    /// next start or the stop.
    addressed: Option<usize>,
}

impl SimBus {
    pub fn new(chips: Vec<BusChip>) -> Self {
        SimBus {
            chips,
            time_us: 0,
            addressed: None,
        }
    }

    /// The chips' addresses, in the bus's order.
    pub fn addresses(&self) -> Vec<u8> {
        self.chips.iter().map(|c| c.chip_ref().address()).collect()
    }

    /// The chip at `address`, if the bus has one.
    pub fn chip_at(&mut self, address: u8) -> Option<&mut dyn RegisterChip> {
        self.chips
            .iter_mut()
            .map(BusChip::chip)
            .find(|c| c.address() == address)
    }

    /// A start (or repeated start) addressed to `address`: the chip there answers it (it may
    /// refuse, in an outage); no chip there, no acknowledge.
    pub fn bus_start(&mut self, address: u8, repeated: bool) -> Result<(), SimI2cError> {
        self.addressed = None;
        let k = self
            .chips
            .iter()
            .position(|c| c.chip_ref().address() == address)
            .ok_or(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))?;
        self.chips[k].chip().bus_start(address, repeated)?;
        self.addressed = Some(k);
        Ok(())
    }

    /// A written byte, to the chip addressed; with none, nobody acknowledges it.
    pub fn bus_write(&mut self, byte: u8) -> Result<(), SimI2cError> {
        match self.addressed {
            Some(k) => self.chips[k].chip().bus_write(byte),
            None => Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Data)),
        }
    }

    /// A read byte, from the chip addressed; with none, the pull-ups' 0xFF.
    pub fn bus_read(&mut self) -> u8 {
        match self.addressed {
            Some(k) => self.chips[k].chip().bus_read(),
            None => 0xFF,
        }
    }

    /// Keep every chip's journal.
    pub fn keep_journals(&mut self) {
        for chip in &mut self.chips {
            chip.chip().keep_journal();
        }
    }

    /// Every chip's journal entries since the last call, each with the chip's address, chip
    /// by chip in the bus's order.
    pub fn take_journals(&mut self) -> Vec<(u8, JournalEntry)> {
        let mut entries = Vec::new();
        for chip in &mut self.chips {
            let chip = chip.chip();
            let address = chip.address();
            entries.extend(chip.take_journal().into_iter().map(|e| (address, e)));
        }
        entries
    }

    /// The bus's time, us.
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// Move every chip's clock to `t_us`, making the samples due.
    pub fn set_time_us(&mut self, t_us: u64) {
        self.time_us = self.time_us.max(t_us);
        for chip in &mut self.chips {
            chip.advance_to_us(t_us);
        }
    }

    /// Let `dt` pass on the bus's clock.
    pub fn advance(&mut self, dt: Duration) {
        let dt = u64::try_from(dt.as_micros()).unwrap_or(u64::MAX);
        self.set_time_us(self.time_us.saturating_add(dt));
    }

    /// End any transaction every chip is in: what nine clocks and a STOP do to real ones.
    pub fn bus_stop(&mut self) {
        self.addressed = None;
        for chip in &mut self.chips {
            chip.chip().bus_stop();
        }
    }

    /// Samples made so far by all the chips together.
    pub fn samples_made(&self) -> u64 {
        self.chips.iter().map(|c| c.chip_ref().samples_made()).sum()
    }

    /// Device resets so far, all the chips together.
    pub fn resets(&self) -> u32 {
        self.chips.iter().map(|c| c.chip_ref().resets()).sum()
    }

    /// Turn and rotate the board: what its MPU-6050 senses from now on (the GY-85's chips
    /// stay at rest).
    pub fn set_input(&mut self, input: Option<TrueInput>) {
        if let Some(mpu) = self.mpu6050_mut() {
            mpu.set_input(input);
        }
    }

    /// The first MPU-6050 on the bus.
    pub fn mpu6050(&self) -> Option<&SimMpu6050> {
        self.chips.iter().find_map(|c| match c {
            BusChip::Mpu6050(c) => Some(c),
            _ => None,
        })
    }

    pub fn mpu6050_mut(&mut self) -> Option<&mut SimMpu6050> {
        self.chips.iter_mut().find_map(|c| match c {
            BusChip::Mpu6050(c) => Some(c),
            _ => None,
        })
    }

    /// The first ITG-3200 on the bus.
    pub fn itg3200_mut(&mut self) -> Option<&mut SimItg3200> {
        self.chips.iter_mut().find_map(|c| match c {
            BusChip::Itg3200(c) => Some(c),
            _ => None,
        })
    }

    /// The first ADXL345 on the bus.
    pub fn adxl345_mut(&mut self) -> Option<&mut SimAdxl345> {
        self.chips.iter_mut().find_map(|c| match c {
            BusChip::Adxl345(c) => Some(c),
            _ => None,
        })
    }
}

impl ErrorType for SimBus {
    type Error = SimI2cError;
}

impl I2c for SimBus {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        let chip = self
            .chips
            .iter_mut()
            .map(BusChip::chip)
            .find(|c| c.address() == address)
            .ok_or(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))?;
        transaction(chip, address, operations)
    }
}

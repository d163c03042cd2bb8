//! I2C0 on GPIO4 (SDA) / GPIO5 (SCL) with the bus clear the portable firmware asks for after
//! a fault ([`firmware::BusClear`]): the peripheral is released, SCL driven by hand for up
//! to nine clocks until the sensor lets SDA go, a STOP sent, and the peripheral set up again.
//! The sensors' drivers share it through [`Shared`] handles.

use core::cell::RefCell;
use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::i2c::{ErrorType, I2c, Operation};
use rp2040_hal as hal;
use hal::fugit::HertzU32;
use hal::gpio::bank0::{Gpio4, Gpio5};
use hal::gpio::{FunctionI2C, FunctionSioInput, FunctionSioOutput, Pin, PullUp};
use hal::pac::{I2C0, RESETS};

type Sda = Pin<Gpio4, FunctionI2C, PullUp>;
type Scl = Pin<Gpio5, FunctionI2C, PullUp>;
type Peripheral = hal::I2C<I2C0, (Sda, Scl)>;

/// Half an SCL period of the hand-driven clock: 5 us, i.e. 100 kHz, which every I2C
/// device accepts.
const HALF_PERIOD_US: u32 = 5;
/// Clocks that free any byte a device may be in the middle of (8 data bits and an ACK).
const CLEAR_CLOCKS: u32 = 9;

pub struct Bus<D> {
    /// `None` only inside [`Bus::clear_bus`].
    i2c: Option<Peripheral>,
    resets: RESETS,
    frequency: HertzU32,
    system_clock: HertzU32,
    delay: D,
}

impl<D: DelayNs> Bus<D> {
    pub fn new(
        i2c: I2C0,
        sda: Sda,
        scl: Scl,
        frequency: HertzU32,
        mut resets: RESETS,
        system_clock: HertzU32,
        delay: D,
    ) -> Self {
        let i2c = hal::I2C::i2c0(i2c, sda, scl, frequency, &mut resets, system_clock);
        Bus {
            i2c: Some(i2c),
            resets,
            frequency,
            system_clock,
            delay,
        }
    }
}

impl<D: DelayNs> firmware::BusClear for Bus<D> {
    fn clear_bus(&mut self) {
        let Some(i2c) = self.i2c.take() else {
            return;
        };
        let (block, (sda, scl)) = i2c.free(&mut self.resets);
        let mut sda = sda.reconfigure::<FunctionSioInput, PullUp>();
        let mut scl = scl.reconfigure::<FunctionSioOutput, PullUp>();
        let d = &mut self.delay;
        for _ in 0..CLEAR_CLOCKS {
            if sda.is_high().unwrap_or(true) {
                break;
            }
            let _ = scl.set_low();
            d.delay_us(HALF_PERIOD_US);
            let _ = scl.set_high();
            d.delay_us(HALF_PERIOD_US);
        }
        // STOP: SDA rises while SCL is high.
        let mut sda = sda.reconfigure::<FunctionSioOutput, PullUp>();
        let _ = scl.set_low();
        let _ = sda.set_low();
        d.delay_us(HALF_PERIOD_US);
        let _ = scl.set_high();
        d.delay_us(HALF_PERIOD_US);
        let _ = sda.set_high();
        d.delay_us(HALF_PERIOD_US);
        let sda = sda.reconfigure::<FunctionI2C, PullUp>();
        let scl = scl.reconfigure::<FunctionI2C, PullUp>();
        self.i2c = Some(hal::I2C::i2c0(
            block,
            sda,
            scl,
            self.frequency,
            &mut self.resets,
            self.system_clock,
        ));
    }
}

impl<D> ErrorType for Bus<D> {
    type Error = hal::i2c::Error;
}

impl<D> I2c for Bus<D> {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        match self.i2c.as_mut() {
            Some(i2c) => i2c.transaction(address, operations),
            // Unreachable outside `clear_bus`; an abort is what a missing bus looks like.
            None => Err(hal::i2c::Error::Abort(0)),
        }
    }
}

/// The one bus shared by every sensor's driver: each holds a copy of this handle. The board
/// is single-threaded and no transaction calls another, so a borrow never meets another;
/// if one did, the transaction fails as an aborted one (an I2C error the firmware counts and
/// retries), never a panic.
pub struct Shared<'a, D>(pub &'a RefCell<Bus<D>>);

impl<D> Clone for Shared<'_, D> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<D> Copy for Shared<'_, D> {}

impl<D> ErrorType for Shared<'_, D> {
    type Error = hal::i2c::Error;
}

impl<D> I2c for Shared<'_, D> {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        match self.0.try_borrow_mut() {
            Ok(mut bus) => bus.transaction(address, operations),
            Err(_) => Err(hal::i2c::Error::Abort(0)),
        }
    }
}

impl<D: DelayNs> firmware::BusClear for Shared<'_, D> {
    fn clear_bus(&mut self) {
        if let Ok(mut bus) = self.0.try_borrow_mut() {
            bus.clear_bus();
        }
    }
}

//! The sensors a board finds on its I2C bus, each in a [`Slot`] of its kind, and the probe
//! that finds them ([`probe_bus`]).
//!
//! The gyro's place is probed first, at 0x68 then 0x69 (AD0 high): an MPU-6050 (or a chip
//! of its family, [`protocol::mpu6050::KNOWN_CHIPS`]) answers its WHO_AM_I at register 0x75;
//! an ITG-3200 keeps its WHO_AM_I at register 0 and answers 0x68/0x69 in bits 6:1
//! ([`protocol::itg3200::is_itg3200`]). The MPU's register is read first because its answer
//! is a full byte that an ITG-3200's undefined register 0x75 has no reason to hold, while an
//! MPU's register 0 is a trim value that could pass the ITG's masked test. The
//! accelerometer's place is probed next, at 0x53 then 0x1D (ALT ADDRESS high), for an
//! ADXL345 (DEVID 0xE5). The gyro-place chip is sensor 0, the ADXL345 the next.

use crate::adxl345::Adxl345;
use crate::chip::SensorChip;
use crate::driver::{BusClear, Mpu6050};
use crate::itg3200::Itg3200;
use crate::stream::{Outlet, SensorStream};
use crate::timing::Clock;
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use protocol::sensors::MAX_SENSORS;
use protocol::{ErrorCode, SensorConfig, SensorInfo, Status};

/// Where a gyro (MPU-6050 or ITG-3200) may answer, in probing order.
pub const GYRO_ADDRESSES: [u8; 2] = [0x68, 0x69];
/// Where an ADXL345 may answer, in probing order.
pub const ACCEL_ADDRESSES: [u8; 2] = [protocol::adxl345::DEFAULT_ADDRESS, 0x1D];

/// The board's sensors, by number.
pub type Sensors<I2C> = heapless::Vec<Slot<I2C>, MAX_SENSORS>;

/// One sensor the board found, as its kind's stream.
pub enum Slot<I2C: I2c + BusClear> {
    Mpu6050(SensorStream<Mpu6050<I2C>>),
    Itg3200(SensorStream<Itg3200<I2C>>),
    Adxl345(SensorStream<Adxl345<I2C>>),
}

/// `$body` with `$s` the slot's stream, whatever its kind.
macro_rules! on_stream {
    ($slot:expr, $s:ident => $body:expr) => {
        match $slot {
            Slot::Mpu6050($s) => $body,
            Slot::Itg3200($s) => $body,
            Slot::Adxl345($s) => $body,
        }
    };
}

impl<I2C: I2c + BusClear> Slot<I2C> {
    pub fn info(&self) -> SensorInfo {
        on_stream!(self, s => s.info())
    }

    pub fn streaming(&self) -> bool {
        on_stream!(self, s => s.streaming())
    }

    pub fn counters(&self) -> Status {
        on_stream!(self, s => s.counters())
    }

    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        on_stream!(self, s => s.init(delay))
    }

    /// Set the sensor up with `config`; [`ErrorCode::NoSuchSensor`] if it is for another
    /// kind of chip.
    pub fn configure(&mut self, config: SensorConfig) -> Result<(), ErrorCode> {
        on_stream!(self, s => configure(s, config))
    }

    pub fn start(&mut self, clock: &mut impl Clock) -> Result<(), ErrorCode> {
        on_stream!(self, s => s.start(clock))
    }

    pub fn poll(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) {
        on_stream!(self, s => s.poll(clock, outlet))
    }

    pub fn stop(
        &mut self,
        clock: &mut impl Clock,
        outlet: &mut dyn Outlet,
    ) -> Result<(), ErrorCode> {
        on_stream!(self, s => s.stop(clock, outlet))
    }

    pub fn host_left(&mut self, clock: &mut impl Clock) {
        on_stream!(self, s => s.host_left(clock))
    }
}

fn configure<S: SensorChip>(
    s: &mut SensorStream<S>,
    config: SensorConfig,
) -> Result<(), ErrorCode> {
    let settings = S::settings_in(config).ok_or(ErrorCode::NoSuchSensor { sensor: s.number() })?;
    s.configure(settings)
}

/// What a probe of the bus found: the sensors, and, if it found none, why the gyro's place
/// gave none (the error the host sees on Configure and Start, and the WHO_AM_I Info shows).
pub struct Found<I2C: I2c + BusClear> {
    pub sensors: Sensors<I2C>,
    pub absent: Option<ErrorCode>,
}

/// Probe the bus (module documentation); every driver gets its own clone of `bus`.
pub fn probe_bus<I2C: I2c + BusClear + Clone>(bus: &I2C) -> Found<I2C> {
    let mut sensors = Sensors::new();
    let mut gyro_error = None;
    for address in GYRO_ADDRESSES {
        match probe_gyro(bus, address) {
            Ok(slot) => {
                // Capacity MAX_SENSORS >= 2: the gyro and the accelerometer.
                let _ = sensors.push(slot);
                break;
            }
            // A chip that answered with the wrong identity says more than an empty address.
            Err(e) => {
                let keep = match gyro_error {
                    None => true,
                    Some(ErrorCode::WrongSensor { .. }) => false,
                    Some(_) => matches!(e, ErrorCode::WrongSensor { .. }),
                };
                if keep {
                    gyro_error = Some(e);
                }
            }
        }
    }
    for address in ACCEL_ADDRESSES {
        let mut dev = Adxl345::new(bus.clone(), address);
        if let Ok(id) = dev.probe() {
            let number = sensors.len() as u8;
            let _ = sensors.push(Slot::Adxl345(SensorStream::new(dev, number, address, id)));
            break;
        }
    }
    let absent = if sensors.is_empty() { gyro_error } else { None };
    Found { sensors, absent }
}

/// An MPU-6050 (register 0x75) or, if something answered but not as one, an ITG-3200
/// (register 0) at `address`.
fn probe_gyro<I2C: I2c + BusClear + Clone>(bus: &I2C, address: u8) -> Result<Slot<I2C>, ErrorCode> {
    let mut mpu = Mpu6050::new(bus.clone(), address);
    let error = match SensorChip::probe(&mut mpu) {
        Ok(id) => return Ok(Slot::Mpu6050(SensorStream::new(mpu, 0, address, id))),
        Err(e) => e,
    };
    if let ErrorCode::WrongSensor { .. } = error {
        let mut itg = Itg3200::new(bus.clone(), address);
        if let Ok(id) = itg.probe() {
            return Ok(Slot::Itg3200(SensorStream::new(itg, 0, address, id)));
        }
    }
    Err(error)
}

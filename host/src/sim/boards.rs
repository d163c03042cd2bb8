//! The simulated boards' buses: which chips each carries, seeded from one seed, with a fault
//! plan's share set on each (the virtual board's and `imunoise sim-device`'s one source).

use super::device::{BusChip, SimAdxl345, SimBus, SimItg3200, SimMpu6050};
use super::imu::ImuModel;
use super::model_file::FaultPlan;

/// How the ADXL345's seed follows from the board's: the two chips draw their own noise.
const ACCEL_SEED: u64 = 0xAD_1345;

/// An MPU-6050 breakout: the chip alone at 0x68, following `model`, with `faults`' share.
pub fn mpu6050(model: ImuModel, seed: u64, faults: &FaultPlan) -> SimBus {
    let mut chip = SimMpu6050::new(model, seed);
    faults.apply_to_sensor(&mut chip);
    SimBus::new(vec![BusChip::Mpu6050(chip)])
}

/// A GY-85: an ITG-3200 at 0x68 following `model`'s `[gyro]` (and temperature) and an
/// ADXL345 at 0x53 following its `[accel]`, each with its own noise from `seed`. `faults`
/// reach both chips (clock, I2C outages and resets; a WHO_AM_I only the ITG-3200's).
pub fn gy85(model: ImuModel, seed: u64, faults: &FaultPlan) -> SimBus {
    let mut gyro = SimItg3200::new(model.clone(), seed);
    let mut accel = SimAdxl345::new(model, seed ^ ACCEL_SEED);
    faults.apply_to_sensor(&mut gyro);
    let accel_faults = FaultPlan {
        who_am_i: None,
        ..faults.clone()
    };
    accel_faults.apply_to_sensor(&mut accel);
    SimBus::new(vec![BusChip::Itg3200(gyro), BusChip::Adxl345(accel)])
}

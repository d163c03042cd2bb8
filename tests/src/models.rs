//! Sensor models the simulated GY-85 chips share across tests.

use imunoise::sim::imu::ImuModel;
use imunoise::sim::noise::NoiseTerms;

/// White noise only, a few counts of each chip: enough to tell every sample from its
/// neighbours, so a sample delivered at the wrong index shows.
pub fn gy85_model() -> ImuModel {
    let mut m = ImuModel::default();
    m.gyro.noise = NoiseTerms {
        n: 5e-3,
        ..Default::default()
    };
    m.accel.noise = NoiseTerms {
        n: 5e-2,
        ..Default::default()
    };
    m
}

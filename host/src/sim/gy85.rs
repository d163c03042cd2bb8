//! The GY-85's pair at its outputs, for `imunoise simulate --board gy85`: the ITG-3200's gyro
//! chain and the ADXL345's accelerometer chain (the simulated chips' own,
//! [`super::device::itg3200::gyro_chain`] and [`super::device::adxl345::AccelChain`]), each
//! counted as its registers hold it and converted back to SI, sample by sample.
//!
//! The pair is set as a board sets it from one rate and one bandwidth
//! ([`crate::link::plan`]): the gyro's DLPF row and divider, the accelerometer at the gyro's
//! output rate.

use super::device::adxl345::{AccelChain, counts};
use super::device::itg3200::gyro_chain;
use super::imu::{Imu, ImuModel, SiSample};
use protocol::adxl345::{self, Adxl345Settings};
use protocol::itg3200::{self, Itg3200Settings};

/// The pair running (module documentation).
#[derive(Debug, Clone)]
pub struct Gy85 {
    gyro: Imu,
    accel: AccelChain,
    accel_format: u8,
    rate_hz: f64,
    n: u64,
}

impl Gy85 {
    /// The pair with `model` (`[gyro]` the ITG-3200's, `[accel]` the ADXL345's at 100 Hz),
    /// seeded by `seed`, for a run of about `duration_s`.
    pub fn new(
        model: &ImuModel,
        gyro: &Itg3200Settings,
        accel: &Adxl345Settings,
        seed: u64,
        duration_s: f64,
    ) -> Gy85 {
        Gy85 {
            gyro: gyro_chain(model, gyro, seed, duration_s),
            accel: AccelChain::new(model, accel, seed ^ 0xAD_1345, duration_s),
            accel_format: accel.data_format(),
            rate_hz: gyro.output_rate_hz(),
            n: 0,
        }
    }

    pub fn output_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The next sample: gyro and temperature from the ITG-3200, acceleration from the ADXL345,
    /// each quantized as its chip does.
    pub fn next_si(&mut self) -> SiSample {
        let time = self.n as f64 / self.rate_hz;
        self.n += 1;
        let g = self.gyro.next_raw();
        let a = self.accel.next_sample();
        SiSample {
            time,
            gyro: g.gyro.map(|c| f64::from(c) * itg3200::rad_s_per_lsb()),
            accel: a.map(|v| f64::from(counts(v, self.accel_format)) * adxl345::m_s2_per_lsb()),
            temp: itg3200::temperature_celsius(g.temp),
        }
    }
}

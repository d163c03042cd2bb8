//! The GY-85's pair at its outputs, for `imunoise simulate --board gy85`: the ITG-3200's gyro
//! chain and the ADXL345's accelerometer chain (the simulated chips' own,
//! [`super::device::itg3200::gyro_chain`] and [`super::device::adxl345::AccelChain`]), each
//! counted as its registers hold it and converted back to SI, sample by sample.
//!
//! The pair is set as a board sets it from one rate and one bandwidth: the gyro's DLPF row
//! and divider exactly, the accelerometer at the output rate nearest the gyro's
//! ([`Adxl345Settings::nearest_rate`]). A record has one time column, so both must then run
//! at the same rate; otherwise the error names the rates they share.

use super::device::adxl345::{AccelChain, counts};
use super::device::itg3200::gyro_chain;
use super::imu::{Imu, ImuModel, SiSample};
use protocol::adxl345::{self, Adxl345Settings};
use protocol::itg3200::{self, Itg3200Settings};
use protocol::mpu6050::{Hz, SettingsError};

/// Why the pair cannot be set as asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Gy85Error {
    #[error("ITG-3200: {0}")]
    Gyro(SettingsError),
    #[error("{}", rates_message(*gyro_hz, *bandwidth_hz))]
    Rates { gyro_hz: f64, bandwidth_hz: f64 },
}

/// The rates both chips have at a gyro bandwidth, for the error.
fn rates_message(gyro_hz: f64, bandwidth_hz: f64) -> String {
    let nearest = Adxl345Settings::nearest_rate(gyro_hz).output_rate_hz();
    let shared: Vec<String> = (0..=protocol::adxl345::settings::TOP_RATE_CODE)
        .map(protocol::adxl345::settings::rate_of_code)
        .filter(|&r| Itg3200Settings::for_rate_and_bandwidth(r, bandwidth_hz).is_ok())
        .map(|r| Hz(r).to_string())
        .collect();
    format!(
        "the ADXL345 has no {} Hz output rate (nearest: {} Hz), and one record needs one rate; with the gyro at {bandwidth_hz} Hz both sensors run at {} Hz",
        Hz(gyro_hz),
        Hz(nearest),
        shared.join(", ")
    )
}

/// The pair's settings for a gyro rate and bandwidth.
pub fn settings(
    rate_hz: f64,
    bandwidth_hz: f64,
) -> Result<(Itg3200Settings, Adxl345Settings), Gy85Error> {
    let gyro =
        Itg3200Settings::for_rate_and_bandwidth(rate_hz, bandwidth_hz).map_err(Gy85Error::Gyro)?;
    let accel = Adxl345Settings::nearest_rate(gyro.output_rate_hz());
    if accel.output_rate_hz() != gyro.output_rate_hz() {
        return Err(Gy85Error::Rates {
            gyro_hz: gyro.output_rate_hz(),
            bandwidth_hz,
        });
    }
    Ok((gyro, accel))
}

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
    /// The pair with `model` ([gyro] the ITG-3200's, [accel] the ADXL345's at 100 Hz),
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

//! The ADXL345's settings model: the accelerometer of GY-85-style boards, which the PSD study
//! logged beside the ITG-3200. Shared by the firmware, the simulator and the host.
//!
//! - [`reg`]: register addresses and bits;
//! - [`settings`]: [`Adxl345Settings`], an output data rate (and the low-power mode and the
//!   range) resolved to BW_RATE and DATA_FORMAT.
//!
//! The chip filters and decimates inside, with a bandwidth of half the output data rate
//! \[AD, table 7\], and keeps up to [`FIFO_DEPTH`] samples in a FIFO; in stream mode the
//! oldest is overwritten when the FIFO is full, so the board drains it well before.
//!
//! Source: \[AD\] Analog Devices "ADXL345 Data Sheet" rev. G: table 1 (full-resolution scale
//! factor 3.9 mg/LSB), tables 7 and 8 (rate codes, bandwidths, low-power rates), "Noise
//! Performance" (0.75 LSB rms on x and y and 1.1 on z at 100 Hz, the same in LSB below
//! 100 Hz, about sqrt(2) more per doubling above; 1.8 and 2.6 LSB rms in low power), table 19
//! (register map: DEVID 0x00, BW_RATE 0x2C, POWER_CTL 0x2D, DATA_FORMAT 0x31, DATAX0 0x32,
//! FIFO_CTL 0x38, FIFO_STATUS 0x39).

pub mod reg;
pub mod settings;
#[cfg(test)]
mod tests;

pub use settings::{Adxl345Error, Adxl345Range, Adxl345Settings};

/// 7-bit I2C address with ALT ADDRESS low (the GY-85's wiring); [`ALT_ADDRESS`] with it high.
pub const DEFAULT_ADDRESS: u8 = 0x53;
pub const ALT_ADDRESS: u8 = 0x1D;

/// DEVID reads 0xE5 \[AD, reg 0x00\].
pub const DEVID_VALUE: u8 = 0xE5;

/// Samples the FIFO holds \[AD, "FIFO"\].
pub const FIFO_DEPTH: usize = 32;

/// Full-resolution sensitivity in every range: 256 LSB per g, 3.9 mg per LSB \[AD, table 1\].
pub const LSB_PER_G: f64 = 256.0;

/// One count in m/s^2 at full resolution.
pub fn m_s2_per_lsb() -> f64 {
    crate::mpu6050::STANDARD_GRAVITY / LSB_PER_G
}

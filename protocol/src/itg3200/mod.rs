//! The ITG-3200's (and the register-compatible ITG-3205's) settings model: the gyro of
//! GY-85-style boards, which the PSD study logged at 50 Hz. Shared by the firmware (which
//! writes the registers), the simulator (which obeys them) and the host.
//!
//! - [`reg`]: register addresses and bits;
//! - [`settings`]: [`Itg3200Settings`], an output rate and a bandwidth resolved to
//!   `SMPLRT_DIV` and `DLPF_FS`.
//!
//! The chip has no FIFO: each sample sits in GYRO_XOUT..GYRO_ZOUT until the next replaces
//! it, and RAW_DATA_RDY in INT_STATUS says a new one is there. The board must read every
//! sample in time, and counts the ones it could not.
//!
//! Source: \[IT\] InvenSense "ITG-3200 Product Specification", PS-ITG-3200A-00-01.4:
//! section 3.1 (sensitivity 14.375 LSB per deg/s; temperature offset -13200 LSB at 35 degC,
//! 280 LSB per degC), section 8 (register map: WHO_AM_I 0, SMPLRT_DIV 21, DLPF_FS 22,
//! INT_CFG 23, INT_STATUS 26, TEMP_OUT 27-28, GYRO_OUT 29-34, PWR_MGM 62). The ITG-3205
//! ("ITG-3205 Product Specification" rev 1.0) has the same map.

pub mod reg;
pub mod settings;
#[cfg(test)]
mod tests;

pub use settings::Itg3200Settings;

use core::f64::consts::PI;

/// 7-bit I2C address with AD0 low (the GY-85's wiring); [`ALT_ADDRESS`] with AD0 high.
pub const DEFAULT_ADDRESS: u8 = 0x68;
pub const ALT_ADDRESS: u8 = 0x69;

/// Bits 6:1 of WHO_AM_I hold the address's upper six bits, 0b110100 at power-on \[IT, reg
/// 0\]; bits 7 and 0 are not part of the id.
pub const WHO_AM_I_MASK: u8 = 0x7E;
pub const WHO_AM_I_VALUE: u8 = 0x68;

/// True when a WHO_AM_I value (register 0) names an ITG-3200/3205.
pub fn is_itg3200(who_am_i: u8) -> bool {
    who_am_i & WHO_AM_I_MASK == WHO_AM_I_VALUE
}

/// The full scale, deg/s: FS_SEL = 3 is the only valid range \[IT, reg 22\].
pub const FULL_SCALE_DPS: f64 = 2000.0;

/// Sensitivity, LSB per deg/s, with FS_SEL = 3 (+/-2000 deg/s, the only valid range) \[IT,
/// 3.1\].
pub const LSB_PER_DPS: f64 = 14.375;

/// One count in rad/s.
pub fn rad_s_per_lsb() -> f64 {
    PI / 180.0 / LSB_PER_DPS
}

/// TEMP_OUT counts to degrees Celsius: `35 + (counts + 13200) / 280` \[IT, 3.1\].
pub fn temperature_celsius(counts: i16) -> f64 {
    35.0 + (f64::from(counts) + 13200.0) / 280.0
}

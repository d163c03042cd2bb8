//! The MPU-6050's settings model: what each register value means, shared by the firmware
//! (which writes them), the simulator (which obeys them) and the host (which analyses the
//! result), so all three agree.
//!
//! - [`reg`]: register addresses and their bits;
//! - [`dlpf`]: the digital low-pass filter's table;
//! - [`range`]: the gyro's and the accelerometer's full-scale ranges;
//! - [`settings`]: [`SensorSettings`], an output rate and a bandwidth resolved to registers.
//!
//! This module holds the chips that answer with this register map and the constants all of
//! them share; the types of the others are re-exported here.
//!
//! Sources (InvenSense):
//! - \[RM\] "MPU-6000 and MPU-6050 Register Map and Descriptions", RM-MPU-6000A-00 rev. 4.2:
//!   register 25 SMPLRT_DIV, 26 CONFIG (the DLPF table), 27 GYRO_CONFIG, 28 ACCEL_CONFIG,
//!   65-66 TEMP_OUT, 117 WHO_AM_I.
//! - \[PS\] "MPU-6000 and MPU-6050 Product Specification", PS-MPU-6000A-00 rev. 3.4, tables 6.1
//!   and 6.2 (sensitivity scale factors).

pub mod dlpf;
pub mod range;
pub mod reg;
pub mod settings;
#[cfg(test)]
mod tests;

pub use dlpf::{DLPF_TABLE, DlpfCfg, DlpfRow};
pub use range::{AccelRange, GyroRange, RangeError};
pub use settings::{Hz, RegisterValues, SensorSettings, SettingsError, neighbouring_rates};

/// WHO_AM_I reads 0x68 on every MPU-6050, whatever its AD0 pin [RM, reg 117].
pub const WHO_AM_I_VALUE: u8 = 0x68;

/// A chip that answers at the MPU-6050's address with the MPU-6050's register map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chip {
    pub who_am_i: u8,
    pub name: &'static str,
    /// FIFO size in bytes: the MPU-6500 family has 512 [PS-MPU-6500A rev 1.1, 6.6].
    pub fifo_size: usize,
    /// TEMP_OUT scale and the temperature at 0 counts: 340 LSB/degC and 36.53 degC on the
    /// MPU-6050 [RM, reg 65-66]; 333.87 LSB/degC and 21 degC on the MPU-6500 [PS-MPU-6500A,
    /// 3.4.2 and RM-MPU-6500A reg 65-66]. The clones publish nothing: the MPU-6050's values
    /// are assumed.
    pub temp_lsb_per_c: f64,
    pub temp_at_zero_c: f64,
}

impl Chip {
    /// TEMP_OUT counts to degrees Celsius on this chip.
    pub fn temperature_celsius(&self, counts: i16) -> f64 {
        f64::from(counts) / self.temp_lsb_per_c + self.temp_at_zero_c
    }
}

/// Chips sold on MPU-6050 breakouts (GY-521 and kin) whose registers 25-28, 35, 56-58,
/// 59-72, 106-107 and 114-116 behave as the MPU-6050's: the genuine part, the MPU-6500
/// (0x70) that many boards carry today, and two clone identities reported by users of
/// widely used Arduino drivers (0x98, accepted by ElectronicCats/mpu6050; 0x72). Any other
/// WHO_AM_I is refused with its value named.
pub const KNOWN_CHIPS: [Chip; 4] = [
    Chip {
        who_am_i: WHO_AM_I_VALUE,
        name: "MPU-6050",
        fifo_size: FIFO_SIZE,
        temp_lsb_per_c: 340.0,
        temp_at_zero_c: 36.53,
    },
    Chip {
        who_am_i: 0x70,
        name: "MPU-6500 (sold as MPU-6050)",
        fifo_size: 512,
        temp_lsb_per_c: 333.87,
        temp_at_zero_c: 21.0,
    },
    Chip {
        who_am_i: 0x72,
        name: "MPU-6050 clone (WHO_AM_I 0x72)",
        fifo_size: FIFO_SIZE,
        temp_lsb_per_c: 340.0,
        temp_at_zero_c: 36.53,
    },
    Chip {
        who_am_i: 0x98,
        name: "MPU-6050 clone (WHO_AM_I 0x98)",
        fifo_size: FIFO_SIZE,
        temp_lsb_per_c: 340.0,
        temp_at_zero_c: 36.53,
    },
];

/// The chip a WHO_AM_I value names, if it is one this project drives.
pub fn chip(who_am_i: u8) -> Option<Chip> {
    KNOWN_CHIPS.iter().copied().find(|c| c.who_am_i == who_am_i)
}

/// The chip a board reported, or the MPU-6050 if it reported none this project knows (a
/// record from before chips were told apart, or a simulated board).
pub fn chip_or_mpu6050(who_am_i: u8) -> Chip {
    chip(who_am_i).unwrap_or(KNOWN_CHIPS[0])
}
/// 7-bit I2C address with AD0 low; [`ALT_ADDRESS`] with AD0 high.
pub const DEFAULT_ADDRESS: u8 = 0x68;
pub const ALT_ADDRESS: u8 = 0x69;
/// FIFO size in bytes [RM, reg 114-115].
pub const FIFO_SIZE: usize = 1024;
/// The accelerometer's internal sample rate: 1 kHz for every DLPF setting [RM, reg 25].
pub const ACCEL_INTERNAL_RATE_HZ: f64 = 1000.0;
/// Standard gravity (CGPM 1901), for converting g to m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.806_65;

/// TEMP_OUT counts to degrees Celsius: `counts / 340 + 36.53` [RM, reg 65-66].
pub fn temperature_celsius(counts: i16) -> f64 {
    f64::from(counts) / 340.0 + 36.53
}

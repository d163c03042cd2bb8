//! The full-scale ranges of the gyro (FS_SEL) and the accelerometer (AFS_SEL), their
//! sensitivities [PS, tables 6.1 and 6.2], and their choice by full scale.

use super::STANDARD_GRAVITY;
use core::f64::consts::PI;
use core::fmt;
use serde::{Deserialize, Serialize};

/// FS_SEL, bits 4:3 of GYRO_CONFIG [RM, reg 27].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum GyroRange {
    Dps250 = 0,
    Dps500 = 1,
    Dps1000 = 2,
    Dps2000 = 3,
}

impl GyroRange {
    pub const ALL: [GyroRange; 4] = [
        GyroRange::Dps250,
        GyroRange::Dps500,
        GyroRange::Dps1000,
        GyroRange::Dps2000,
    ];

    pub fn bits(self) -> u8 {
        self as u8
    }

    pub fn from_bits(bits: u8) -> Option<Self> {
        Self::ALL.get(bits as usize).copied()
    }

    /// Full scale, +/- deg/s.
    pub fn full_scale_dps(self) -> f64 {
        250.0 * f64::from(1u8 << self.bits())
    }

    /// Sensitivity scale factor, LSB per deg/s [PS, table 6.1]. Not exactly 32768/full scale:
    /// the datasheet rounds (131 = 32768/250 rounded; 65.5, 32.8, 16.4).
    pub fn lsb_per_dps(self) -> f64 {
        match self {
            GyroRange::Dps250 => 131.0,
            GyroRange::Dps500 => 65.5,
            GyroRange::Dps1000 => 32.8,
            GyroRange::Dps2000 => 16.4,
        }
    }

    /// One count in rad/s.
    pub fn rad_s_per_lsb(self) -> f64 {
        PI / 180.0 / self.lsb_per_dps()
    }

    /// The range whose full scale is `dps` deg/s (250, 500, 1000 or 2000).
    pub fn from_full_scale_dps(dps: u32) -> Result<Self, RangeError> {
        Self::ALL
            .into_iter()
            .find(|r| r.full_scale_dps() == f64::from(dps))
            .ok_or(RangeError::Gyro { dps })
    }
}

/// AFS_SEL, bits 4:3 of ACCEL_CONFIG [RM, reg 28].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum AccelRange {
    G2 = 0,
    G4 = 1,
    G8 = 2,
    G16 = 3,
}

impl AccelRange {
    pub const ALL: [AccelRange; 4] = [
        AccelRange::G2,
        AccelRange::G4,
        AccelRange::G8,
        AccelRange::G16,
    ];

    pub fn bits(self) -> u8 {
        self as u8
    }

    pub fn from_bits(bits: u8) -> Option<Self> {
        Self::ALL.get(bits as usize).copied()
    }

    /// Full scale, +/- g.
    pub fn full_scale_g(self) -> f64 {
        f64::from(2u8 << self.bits())
    }

    /// Sensitivity scale factor, LSB per g [PS, table 6.2]: 16384, 8192, 4096, 2048.
    pub fn lsb_per_g(self) -> f64 {
        16384.0 / f64::from(1u8 << self.bits())
    }

    /// One count in m/s^2 (with [`STANDARD_GRAVITY`]).
    pub fn m_s2_per_lsb(self) -> f64 {
        STANDARD_GRAVITY / self.lsb_per_g()
    }

    /// The range whose full scale is `g` g (2, 4, 8 or 16).
    pub fn from_full_scale_g(g: u32) -> Result<Self, RangeError> {
        Self::ALL
            .into_iter()
            .find(|r| r.full_scale_g() == f64::from(g))
            .ok_or(RangeError::Accel { g })
    }
}

/// A full scale the chip does not have; the message lists those it has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeError {
    /// No gyro range of `dps` deg/s.
    Gyro { dps: u32 },
    /// No accel range of `g` g.
    Accel { g: u32 },
}

impl fmt::Display for RangeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RangeError::Gyro { .. } => {
                f.write_str("the MPU-6050's gyro ranges are 250, 500, 1000 and 2000 deg/s")
            }
            RangeError::Accel { .. } => {
                f.write_str("the MPU-6050's accel ranges are 2, 4, 8 and 16 g")
            }
        }
    }
}

impl core::error::Error for RangeError {}

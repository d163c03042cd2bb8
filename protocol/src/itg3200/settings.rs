//! What the host can set on the ITG-3200 ([`Itg3200Settings`]): an output rate and a DLPF
//! row, resolved to SMPLRT_DIV and DLPF_FS.
//!
//! The ITG-3200's DLPF_CFG table \[IT, reg 22\] is the MPU-6050's gyro column \[RM, reg 26\]
//! (256 Hz at an 8 kHz internal rate; 188, 98, 42, 20, 10 and 5 Hz at 1 kHz; 7 reserved),
//! the same InvenSense filter, so both chips share [`DLPF_TABLE`] and its errors.

use super::reg::bits;
use crate::mpu6050::dlpf::{DLPF_TABLE, DlpfCfg, DlpfRow};
use crate::mpu6050::settings::{Hz, SettingsError, divider_for, same};
use core::fmt;
use serde::{Deserialize, Serialize};

/// Everything the host can set on the ITG-3200 (the range is fixed at +/-2000 deg/s).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Itg3200Settings {
    pub dlpf: DlpfCfg,
    /// Output rate = internal rate / (1 + SMPLRT_DIV) \[IT, reg 21\].
    pub smplrt_div: u8,
}

impl Default for Itg3200Settings {
    /// 100 Hz with the 42 Hz filter, as the MPU-6050's default.
    fn default() -> Self {
        Itg3200Settings {
            dlpf: DlpfCfg::Cfg3,
            smplrt_div: 9,
        }
    }
}

impl Itg3200Settings {
    /// The output sample rate in Hz.
    pub fn output_rate_hz(&self) -> f64 {
        self.dlpf.gyro_internal_rate_hz() / (1.0 + f64::from(self.smplrt_div))
    }

    /// The sample period in microseconds: 125 or 1000 us times (1 + SMPLRT_DIV), exact.
    pub fn period_us(&self) -> u32 {
        self.dlpf.gyro_internal_period_us() * (1 + u32::from(self.smplrt_div))
    }

    /// The DLPF row, or `None` for the reserved DLPF_CFG 7.
    pub fn row(&self) -> Option<&'static DlpfRow> {
        self.dlpf.row()
    }

    /// The gyro's -3 dB bandwidth in Hz (`None` for the reserved row).
    pub fn bandwidth_hz(&self) -> Option<f64> {
        self.row().map(|r| r.gyro_bandwidth_hz)
    }

    /// True when the bandwidth exceeds half the output rate (noise folds back).
    pub fn aliases(&self) -> bool {
        self.bandwidth_hz()
            .is_some_and(|b| b > self.output_rate_hz() / 2.0)
    }

    /// DLPF_FS: FS_SEL = 3, which the specification requires, and DLPF_CFG \[IT, reg 22\].
    pub fn dlpf_fs(&self) -> u8 {
        bits::FS_SEL_2000 | self.dlpf.bits()
    }

    /// The settings that SMPLRT_DIV and DLPF_FS mean (FS_SEL ignored).
    pub fn from_registers(smplrt_div: u8, dlpf_fs: u8) -> Self {
        Itg3200Settings {
            dlpf: DlpfCfg::ALL[usize::from(dlpf_fs & bits::DLPF_CFG_MASK)],
            smplrt_div,
        }
    }

    /// The settings for an output rate and a gyro bandwidth of the table (256, 188, 98, 42,
    /// 20, 10, 5 Hz). The rate must be exactly `internal / (1 + SMPLRT_DIV)`; otherwise the
    /// error names the nearest rates that are.
    pub fn for_rate_and_bandwidth(rate_hz: f64, bandwidth_hz: f64) -> Result<Self, SettingsError> {
        let row = DLPF_TABLE
            .iter()
            .find(|r| same(r.gyro_bandwidth_hz, bandwidth_hz))
            .ok_or(SettingsError::UnknownBandwidth {
                requested_hz: bandwidth_hz,
                gyro_only: true,
            })?;
        Ok(Itg3200Settings {
            dlpf: row.cfg,
            smplrt_div: divider_for(row, rate_hz)?,
        })
    }
}

impl fmt::Display for Itg3200Settings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ITG-3200: {} Hz output (SMPLRT_DIV {}), DLPF_CFG {}",
            Hz(self.output_rate_hz()),
            self.smplrt_div,
            self.dlpf.bits()
        )?;
        match self.bandwidth_hz() {
            Some(b) => write!(f, " ({b} Hz)")?,
            None => f.write_str(" (reserved)")?,
        }
        f.write_str(", +/-2000 deg/s")
    }
}

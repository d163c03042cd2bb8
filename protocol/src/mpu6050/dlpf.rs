//! DLPF_CFG and the datasheet's table of the digital low-pass filter [RM, reg 26]: each
//! row's bandwidths, delays and the gyro's internal rate that SMPLRT_DIV divides.

use serde::{Deserialize, Serialize};

/// DLPF_CFG, bits 2:0 of CONFIG [RM, reg 26]: the digital low-pass filter of both sensors.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum DlpfCfg {
    Cfg0 = 0,
    Cfg1 = 1,
    Cfg2 = 2,
    Cfg3 = 3,
    Cfg4 = 4,
    Cfg5 = 5,
    Cfg6 = 6,
    /// Reserved by the datasheet (no bandwidth is specified); the gyro runs at 8 kHz.
    Cfg7 = 7,
}

/// One row of the DLPF table [RM, reg 26]. Bandwidths are the filters' -3 dB frequencies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DlpfRow {
    pub cfg: DlpfCfg,
    pub accel_bandwidth_hz: f64,
    pub accel_delay_ms: f64,
    pub gyro_bandwidth_hz: f64,
    pub gyro_delay_ms: f64,
    /// The gyro's internal sample rate, which SMPLRT_DIV divides.
    pub gyro_internal_rate_hz: f64,
}

const fn row(
    cfg: DlpfCfg,
    accel: (f64, f64),
    gyro: (f64, f64),
    gyro_internal_rate_hz: f64,
) -> DlpfRow {
    DlpfRow {
        cfg,
        accel_bandwidth_hz: accel.0,
        accel_delay_ms: accel.1,
        gyro_bandwidth_hz: gyro.0,
        gyro_delay_ms: gyro.1,
        gyro_internal_rate_hz,
    }
}

/// The specified rows, DLPF_CFG 0 to 6 [RM, reg 26]: (accel bandwidth Hz, delay ms),
/// (gyro bandwidth Hz, delay ms), gyro internal rate Hz.
pub const DLPF_TABLE: [DlpfRow; 7] = [
    row(DlpfCfg::Cfg0, (260.0, 0.0), (256.0, 0.98), 8000.0),
    row(DlpfCfg::Cfg1, (184.0, 2.0), (188.0, 1.9), 1000.0),
    row(DlpfCfg::Cfg2, (94.0, 3.0), (98.0, 2.8), 1000.0),
    row(DlpfCfg::Cfg3, (44.0, 4.9), (42.0, 4.8), 1000.0),
    row(DlpfCfg::Cfg4, (21.0, 8.5), (20.0, 8.3), 1000.0),
    row(DlpfCfg::Cfg5, (10.0, 13.8), (10.0, 13.4), 1000.0),
    row(DlpfCfg::Cfg6, (5.0, 19.0), (5.0, 18.6), 1000.0),
];

impl DlpfCfg {
    pub const ALL: [DlpfCfg; 8] = [
        DlpfCfg::Cfg0,
        DlpfCfg::Cfg1,
        DlpfCfg::Cfg2,
        DlpfCfg::Cfg3,
        DlpfCfg::Cfg4,
        DlpfCfg::Cfg5,
        DlpfCfg::Cfg6,
        DlpfCfg::Cfg7,
    ];

    pub fn bits(self) -> u8 {
        self as u8
    }

    /// From the low three bits of CONFIG.
    pub fn from_bits(bits: u8) -> Option<Self> {
        Self::ALL.get(bits as usize).copied()
    }

    /// The datasheet row, or `None` for the reserved DLPF_CFG 7.
    pub fn row(self) -> Option<&'static DlpfRow> {
        DLPF_TABLE.get(self as usize)
    }

    /// 8 kHz with the DLPF off (0) or reserved (7), 1 kHz otherwise [RM, reg 25].
    pub fn gyro_internal_rate_hz(self) -> f64 {
        match self {
            DlpfCfg::Cfg0 | DlpfCfg::Cfg7 => 8000.0,
            _ => 1000.0,
        }
    }

    /// The gyro's internal sample period, microseconds: 125 at 8 kHz, 1000 at 1 kHz (exact).
    pub fn gyro_internal_period_us(self) -> u32 {
        match self {
            DlpfCfg::Cfg0 | DlpfCfg::Cfg7 => 125,
            _ => 1000,
        }
    }
}

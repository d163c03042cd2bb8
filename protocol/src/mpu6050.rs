//! The MPU-6050's settings model: what each register value means, shared by the firmware
//! (which writes them), the simulator (which obeys them) and the host (which analyses the
//! result), so all three agree.
//!
//! Sources (InvenSense):
//! - [RM] "MPU-6000 and MPU-6050 Register Map and Descriptions", RM-MPU-6000A-00 rev. 4.2:
//!   register 25 SMPLRT_DIV, 26 CONFIG (the DLPF table), 27 GYRO_CONFIG, 28 ACCEL_CONFIG,
//!   65-66 TEMP_OUT, 117 WHO_AM_I.
//! - [PS] "MPU-6000 and MPU-6050 Product Specification", PS-MPU-6000A-00 rev. 3.4, tables 6.1
//!   and 6.2 (sensitivity scale factors).

use core::f64::consts::PI;
use core::fmt;
use serde::{Deserialize, Serialize};

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

/// Register addresses [RM].
pub mod reg {
    pub const SMPLRT_DIV: u8 = 0x19;
    pub const CONFIG: u8 = 0x1A;
    pub const GYRO_CONFIG: u8 = 0x1B;
    pub const ACCEL_CONFIG: u8 = 0x1C;
    pub const FIFO_EN: u8 = 0x23;
    pub const INT_PIN_CFG: u8 = 0x37;
    pub const INT_ENABLE: u8 = 0x38;
    pub const INT_STATUS: u8 = 0x3A;
    pub const ACCEL_XOUT_H: u8 = 0x3B;
    pub const TEMP_OUT_H: u8 = 0x41;
    pub const GYRO_XOUT_H: u8 = 0x43;
    pub const SIGNAL_PATH_RESET: u8 = 0x68;
    pub const USER_CTRL: u8 = 0x6A;
    pub const PWR_MGMT_1: u8 = 0x6B;
    pub const PWR_MGMT_2: u8 = 0x6C;
    pub const FIFO_COUNT_H: u8 = 0x72;
    pub const FIFO_R_W: u8 = 0x74;
    pub const WHO_AM_I: u8 = 0x75;
}

/// Bits within the registers of [`reg`], as the register map names them [RM]; shared by the
/// firmware's driver and the host's simulated chip, so both speak of one chip.
pub mod bits {
    /// PWR_MGMT_1 [RM, reg 107]: reset every register (self-clearing); sleep (set after a
    /// reset).
    pub const DEVICE_RESET: u8 = 1 << 7;
    pub const SLEEP: u8 = 1 << 6;
    /// SIGNAL_PATH_RESET [RM, reg 104]: the gyro, accel and temperature signal paths.
    pub const GYRO_RESET: u8 = 1 << 2;
    pub const ACCEL_RESET: u8 = 1 << 1;
    pub const TEMP_RESET: u8 = 1 << 0;
    pub const SIGNAL_PATH_RESET_ALL: u8 = GYRO_RESET | ACCEL_RESET | TEMP_RESET;
    /// USER_CTRL [RM, reg 106]: FIFO_EN (named USER_FIFO_EN here, apart from the FIFO_EN
    /// register), FIFO_RESET and SIG_COND_RESET (both self-clearing).
    pub const USER_FIFO_EN: u8 = 1 << 6;
    pub const FIFO_RESET: u8 = 1 << 2;
    pub const SIG_COND_RESET: u8 = 1 << 0;
    /// INT_ENABLE [RM, reg 56] and INT_STATUS [RM, reg 58]: data ready, FIFO overflow.
    pub const DATA_RDY: u8 = 1 << 0;
    pub const FIFO_OFLOW: u8 = 1 << 4;
    /// FIFO_EN [RM, reg 35]: which sensors' data enter the FIFO.
    pub const TEMP_FIFO_EN: u8 = 1 << 7;
    pub const XG_FIFO_EN: u8 = 1 << 6;
    pub const YG_FIFO_EN: u8 = 1 << 5;
    pub const ZG_FIFO_EN: u8 = 1 << 4;
    pub const ACCEL_FIFO_EN: u8 = 1 << 3;
    /// Temperature, gyro x/y/z and accel: the 14-byte sample of
    /// [`crate::RawSample::from_fifo_bytes`].
    pub const FIFO_EN_ALL: u8 = TEMP_FIFO_EN | XG_FIFO_EN | YG_FIFO_EN | ZG_FIFO_EN | ACCEL_FIFO_EN;
}

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
}

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
}

/// TEMP_OUT counts to degrees Celsius: `counts / 340 + 36.53` [RM, reg 65-66].
pub fn temperature_celsius(counts: i16) -> f64 {
    f64::from(counts) / 340.0 + 36.53
}

/// Everything the host can set on the sensor.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SensorSettings {
    pub dlpf: DlpfCfg,
    /// Output rate = gyro internal rate / (1 + SMPLRT_DIV) [RM, reg 25].
    pub smplrt_div: u8,
    pub gyro_range: GyroRange,
    pub accel_range: AccelRange,
}

impl Default for SensorSettings {
    /// 100 Hz output with the 42 Hz gyro bandwidth (below half the rate, so little noise
    /// folds back), and the most sensitive ranges, which suit static noise tests.
    fn default() -> Self {
        SensorSettings {
            dlpf: DlpfCfg::Cfg3,
            smplrt_div: 9,
            gyro_range: GyroRange::Dps250,
            accel_range: AccelRange::G2,
        }
    }
}

/// The four register values that carry a [`SensorSettings`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegisterValues {
    pub smplrt_div: u8,
    pub config: u8,
    pub gyro_config: u8,
    pub accel_config: u8,
}

impl SensorSettings {
    /// The output (and FIFO) sample rate in Hz.
    pub fn output_rate_hz(&self) -> f64 {
        self.dlpf.gyro_internal_rate_hz() / (1.0 + f64::from(self.smplrt_div))
    }

    /// Seconds between output samples.
    pub fn sample_interval_s(&self) -> f64 {
        1.0 / self.output_rate_hz()
    }

    /// Above 1 kHz output the accelerometer (1 kHz inside) repeats samples [RM, reg 25].
    pub fn accel_repeats_samples(&self) -> bool {
        self.output_rate_hz() > ACCEL_INTERNAL_RATE_HZ
    }

    /// False for the reserved DLPF_CFG 7, which the datasheet does not specify.
    pub fn is_specified(&self) -> bool {
        self.dlpf.row().is_some()
    }

    pub fn with_ranges(self, gyro_range: GyroRange, accel_range: AccelRange) -> Self {
        SensorSettings {
            gyro_range,
            accel_range,
            ..self
        }
    }

    /// The register values that produce these settings (EXT_SYNC_SET and self-test off).
    pub fn registers(&self) -> RegisterValues {
        RegisterValues {
            smplrt_div: self.smplrt_div,
            config: self.dlpf.bits(),
            gyro_config: self.gyro_range.bits() << 3,
            accel_config: self.accel_range.bits() << 3,
        }
    }

    /// The settings that register values mean (other bits ignored).
    pub fn from_registers(r: RegisterValues) -> Self {
        let field = |v: u8| (v >> 3) & 0b11;
        SensorSettings {
            dlpf: DlpfCfg::ALL[usize::from(r.config & 0b111)],
            smplrt_div: r.smplrt_div,
            gyro_range: GyroRange::ALL[usize::from(field(r.gyro_config))],
            accel_range: AccelRange::ALL[usize::from(field(r.accel_config))],
        }
    }

    /// The settings for an output rate and a DLPF bandwidth, with the default ranges.
    ///
    /// `bandwidth_hz` is a gyro bandwidth of the DLPF table (256, 188, 98, 42, 20, 10, 5) or
    /// an accel one (260, 184, 94, 44, 21, 10, 5); both name the same DLPF_CFG row. The rate
    /// must be exactly `internal / (1 + SMPLRT_DIV)` for SMPLRT_DIV in 0..=255; otherwise the
    /// error lists the nearest rates that are.
    pub fn for_rate_and_bandwidth(rate_hz: f64, bandwidth_hz: f64) -> Result<Self, SettingsError> {
        let row = DLPF_TABLE
            .iter()
            .find(|r| {
                same(r.gyro_bandwidth_hz, bandwidth_hz) || same(r.accel_bandwidth_hz, bandwidth_hz)
            })
            .ok_or(SettingsError::UnknownBandwidth {
                requested_hz: bandwidth_hz,
            })?;
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(SettingsError::InvalidRate {
                requested_hz: rate_hz,
            });
        }
        let smplrt_div = exact_divider(row.gyro_internal_rate_hz, rate_hz).ok_or(
            SettingsError::RateNotReachable {
                requested_hz: rate_hz,
                dlpf: row.cfg,
            },
        )?;
        Ok(SensorSettings {
            dlpf: row.cfg,
            smplrt_div,
            ..SensorSettings::default()
        })
    }
}

impl fmt::Display for SensorSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} Hz output (SMPLRT_DIV {}), DLPF_CFG {}",
            Hz(self.output_rate_hz()),
            self.smplrt_div,
            self.dlpf.bits()
        )?;
        match self.dlpf.row() {
            Some(r) => write!(
                f,
                " (gyro {} Hz / {} ms, accel {} Hz / {} ms)",
                r.gyro_bandwidth_hz, r.gyro_delay_ms, r.accel_bandwidth_hz, r.accel_delay_ms
            )?,
            None => f.write_str(" (reserved)")?,
        }
        write!(
            f,
            ", +/-{} deg/s, +/-{} g",
            self.gyro_range.full_scale_dps(),
            self.accel_range.full_scale_g()
        )
    }
}

/// Displays a frequency with at most three decimals and no trailing zeros (166.667, 200,
/// 3.906): exact table values print as the datasheet prints them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hz(pub f64);

impl fmt::Display for Hz {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if !(x.is_finite() && (0.0..1e15).contains(&x)) {
            return write!(f, "{x}");
        }
        let milli = (x * 1000.0 + 0.5) as u64;
        let (whole, mut frac) = (milli / 1000, milli % 1000);
        write!(f, "{whole}")?;
        if frac != 0 {
            let mut digits = 3;
            while frac % 10 == 0 {
                frac /= 10;
                digits -= 1;
            }
            write!(f, ".{frac:0digits$}")?;
        }
        Ok(())
    }
}

/// Relative tolerance when matching a requested frequency to a table value: loose enough
/// for decimal input like 33.333333333333336, tight enough never to pick a wrong divider.
const REL_TOL: f64 = 1e-9;

fn abs(x: f64) -> f64 {
    if x < 0.0 { -x } else { x }
}

fn same(a: f64, b: f64) -> bool {
    abs(a - b) <= REL_TOL * abs(a)
}

/// SMPLRT_DIV with `internal / (1 + div) == rate`, if one exists in 0..=255.
fn exact_divider(internal_hz: f64, rate_hz: f64) -> Option<u8> {
    let quotient = internal_hz / rate_hz;
    let nearest = (quotient + 0.5) as u64; // quotient > 0: truncation of q + 0.5 rounds
    if !(1..=256).contains(&nearest) || abs(quotient - nearest as f64) > REL_TOL * quotient {
        return None;
    }
    u8::try_from(nearest - 1).ok()
}

/// The reachable rates next to `rate_hz` at one internal rate: (just above, just below),
/// each as (rate Hz, SMPLRT_DIV).
pub fn neighbouring_rates(internal_hz: f64, rate_hz: f64) -> [Option<(f64, u8)>; 2] {
    let at = |div: u8| (internal_hz / (1.0 + f64::from(div)), div);
    let quotient = internal_hz / rate_hz;
    if quotient.is_nan() || quotient < 1.0 {
        return [None, Some(at(0))]; // faster than the internal rate (or NaN)
    }
    if quotient >= 256.0 {
        return [Some(at(255)), None];
    }
    let floor = quotient as u64; // 1..=255: rate at div floor-1 is >= rate_hz
    let above = u8::try_from(floor - 1).ok().map(at);
    let below = u8::try_from(floor).ok().map(at);
    [above, below]
}

/// A (rate, bandwidth) request the sensor cannot honour exactly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingsError {
    /// No DLPF row has this bandwidth.
    UnknownBandwidth { requested_hz: f64 },
    /// Not a positive, finite rate.
    InvalidRate { requested_hz: f64 },
    /// No SMPLRT_DIV gives this rate with this DLPF row.
    RateNotReachable { requested_hz: f64, dlpf: DlpfCfg },
}

impl SettingsError {
    /// For an unknown bandwidth, the table's gyro bandwidth closest to it.
    pub fn nearest_bandwidth(&self) -> Option<&'static DlpfRow> {
        let SettingsError::UnknownBandwidth { requested_hz } = *self else {
            return None;
        };
        DLPF_TABLE.iter().min_by(|a, b| {
            let da = abs(a.gyro_bandwidth_hz - requested_hz);
            let db = abs(b.gyro_bandwidth_hz - requested_hz);
            da.total_cmp(&db)
        })
    }

    /// For an unreachable rate, the reachable rates just above and below it at the requested
    /// bandwidth.
    pub fn nearest_rates(&self) -> [Option<(f64, u8)>; 2] {
        match *self {
            SettingsError::RateNotReachable { requested_hz, dlpf } => {
                neighbouring_rates(dlpf.gyro_internal_rate_hz(), requested_hz)
            }
            _ => [None, None],
        }
    }
}

impl fmt::Display for SettingsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SettingsError::UnknownBandwidth { requested_hz } => {
                write!(
                    f,
                    "no DLPF setting has a {requested_hz} Hz bandwidth; gyro bandwidths are"
                )?;
                for r in &DLPF_TABLE {
                    write!(f, " {}", r.gyro_bandwidth_hz)?;
                }
                f.write_str(" Hz (accel:")?;
                for r in &DLPF_TABLE {
                    write!(f, " {}", r.accel_bandwidth_hz)?;
                }
                f.write_str(" Hz)")?;
                if let Some(r) = self.nearest_bandwidth() {
                    write!(
                        f,
                        "; nearest: {} Hz (DLPF_CFG {})",
                        r.gyro_bandwidth_hz,
                        r.cfg.bits()
                    )?;
                }
                Ok(())
            }
            SettingsError::InvalidRate { requested_hz } => {
                write!(
                    f,
                    "the output rate must be a positive number of Hz, not {requested_hz}"
                )
            }
            SettingsError::RateNotReachable { requested_hz, dlpf } => {
                let internal = dlpf.gyro_internal_rate_hz();
                write!(
                    f,
                    "{requested_hz} Hz is not reachable with DLPF_CFG {}: the output rate is {internal} Hz / (1 + SMPLRT_DIV), SMPLRT_DIV 0..255",
                    dlpf.bits()
                )?;
                let [above, below] = self.nearest_rates();
                f.write_str("; nearest:")?;
                let mut sep = " ";
                for (rate, div) in [above, below].into_iter().flatten() {
                    write!(f, "{sep}{} Hz (SMPLRT_DIV {div})", Hz(rate))?;
                    sep = " or ";
                }
                // Other bandwidths whose internal rate does divide to the requested rate.
                let mut first = true;
                for r in DLPF_TABLE
                    .iter()
                    .filter(|r| r.gyro_internal_rate_hz != internal)
                {
                    if exact_divider(r.gyro_internal_rate_hz, requested_hz).is_some() {
                        if first {
                            write!(f, "; bandwidths that give exactly {requested_hz} Hz:")?;
                            first = false;
                        }
                        write!(f, " {} Hz", Hz(r.gyro_bandwidth_hz))?;
                    }
                }
                Ok(())
            }
        }
    }
}

impl core::error::Error for SettingsError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DLPF table as printed in [RM], register 26, restated independently of
    /// `DLPF_TABLE`: DLPF_CFG, accel (bandwidth Hz, delay ms, Fs kHz), gyro (bandwidth Hz,
    /// delay ms, Fs kHz).
    /// (bandwidth Hz, delay ms, sample rate kHz) of one sensor in one row.
    type Filter = (f64, f64, f64);
    const DATASHEET: [(u8, Filter, Filter); 7] = [
        (0, (260.0, 0.0, 1.0), (256.0, 0.98, 8.0)),
        (1, (184.0, 2.0, 1.0), (188.0, 1.9, 1.0)),
        (2, (94.0, 3.0, 1.0), (98.0, 2.8, 1.0)),
        (3, (44.0, 4.9, 1.0), (42.0, 4.8, 1.0)),
        (4, (21.0, 8.5, 1.0), (20.0, 8.3, 1.0)),
        (5, (10.0, 13.8, 1.0), (10.0, 13.4, 1.0)),
        (6, (5.0, 19.0, 1.0), (5.0, 18.6, 1.0)),
    ];

    #[test]
    fn every_dlpf_row_matches_the_datasheet() {
        for (cfg, accel, gyro) in DATASHEET {
            let dlpf = DlpfCfg::from_bits(cfg).unwrap();
            assert_eq!(dlpf.bits(), cfg);
            let r = dlpf.row().unwrap();
            assert_eq!(r.cfg, dlpf);
            assert_eq!(
                (r.accel_bandwidth_hz, r.accel_delay_ms),
                (accel.0, accel.1),
                "cfg {cfg}"
            );
            assert_eq!(
                (r.gyro_bandwidth_hz, r.gyro_delay_ms),
                (gyro.0, gyro.1),
                "cfg {cfg}"
            );
            assert_eq!(r.gyro_internal_rate_hz, gyro.2 * 1000.0, "cfg {cfg}");
            assert_eq!(dlpf.gyro_internal_rate_hz(), gyro.2 * 1000.0, "cfg {cfg}");
            assert_eq!(accel.2 * 1000.0, ACCEL_INTERNAL_RATE_HZ);
        }
        assert!(DlpfCfg::Cfg7.row().is_none());
        assert_eq!(DlpfCfg::Cfg7.gyro_internal_rate_hz(), 8000.0);
        assert_eq!(DlpfCfg::from_bits(8), None);
    }

    #[test]
    fn divider_edges_at_both_internal_rates() {
        let rate = |dlpf, smplrt_div| {
            SensorSettings {
                dlpf,
                smplrt_div,
                ..SensorSettings::default()
            }
            .output_rate_hz()
        };
        assert_eq!(rate(DlpfCfg::Cfg0, 0), 8000.0);
        assert_eq!(rate(DlpfCfg::Cfg0, 1), 4000.0);
        assert_eq!(rate(DlpfCfg::Cfg0, 255), 31.25);
        assert_eq!(rate(DlpfCfg::Cfg7, 7), 1000.0);
        assert_eq!(rate(DlpfCfg::Cfg1, 0), 1000.0);
        assert_eq!(rate(DlpfCfg::Cfg1, 255), 3.906_25);
        assert_eq!(rate(DlpfCfg::Cfg6, 9), 100.0);
        // Above 1 kHz output the 1 kHz accelerometer repeats samples.
        let fast = SensorSettings {
            dlpf: DlpfCfg::Cfg0,
            smplrt_div: 3,
            ..SensorSettings::default()
        };
        assert!(fast.accel_repeats_samples());
        let kilohertz = SensorSettings {
            dlpf: DlpfCfg::Cfg0,
            smplrt_div: 7,
            ..SensorSettings::default()
        };
        assert!(!kilohertz.accel_repeats_samples());
    }

    #[test]
    fn the_papers_four_settings_resolve_exactly() {
        // (rate Hz, bandwidth Hz) -> (DLPF_CFG, SMPLRT_DIV): 8000/(1+39) = 200,
        // 1000/(1+4) = 200, 8000/(1+159) = 50, 1000/(1+19) = 50.
        let expected = [
            ((200.0, 256.0), (0, 39)),
            ((200.0, 42.0), (3, 4)),
            ((50.0, 256.0), (0, 159)),
            ((50.0, 42.0), (3, 19)),
        ];
        for ((rate, bw), (cfg, div)) in expected {
            let s = SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap();
            assert_eq!(
                (s.dlpf.bits(), s.smplrt_div),
                (cfg, div),
                "{rate} Hz / {bw} Hz"
            );
            assert_eq!(s.output_rate_hz(), rate);
            assert_eq!(s.dlpf.row().unwrap().gyro_bandwidth_hz, bw);
        }
    }

    #[test]
    fn accel_bandwidths_name_the_same_rows() {
        for r in &DLPF_TABLE {
            let by_gyro =
                SensorSettings::for_rate_and_bandwidth(50.0, r.gyro_bandwidth_hz).unwrap();
            let by_accel =
                SensorSettings::for_rate_and_bandwidth(50.0, r.accel_bandwidth_hz).unwrap();
            assert_eq!(by_gyro, by_accel);
            assert_eq!(by_gyro.dlpf, r.cfg);
        }
    }

    #[test]
    fn every_exact_rate_resolves_back_to_its_divider() {
        for r in &DLPF_TABLE {
            for div in 0..=255u8 {
                let rate = r.gyro_internal_rate_hz / (1.0 + f64::from(div));
                let s = SensorSettings::for_rate_and_bandwidth(rate, r.gyro_bandwidth_hz).unwrap();
                assert_eq!(s.smplrt_div, div);
            }
        }
    }

    #[test]
    fn unreachable_rates_name_their_neighbours() {
        let err = SensorSettings::for_rate_and_bandwidth(150.0, 42.0).unwrap_err();
        // 1000/6 = 166.67 (div 5) above, 1000/7 = 142.86 (div 6) below.
        let [above, below] = err.nearest_rates();
        assert_eq!(above.unwrap().1, 5);
        assert_eq!(below.unwrap().1, 6);
        // Too fast: only the top rate is a neighbour; too slow: only the bottom one.
        let err = SensorSettings::for_rate_and_bandwidth(2000.0, 42.0).unwrap_err();
        assert_eq!(err.nearest_rates(), [None, Some((1000.0, 0))]);
        let err = SensorSettings::for_rate_and_bandwidth(1.0, 42.0).unwrap_err();
        assert_eq!(err.nearest_rates(), [Some((3.906_25, 255)), None]);
        // 8000 / 3.9 needs SMPLRT_DIV 2050: below the slowest 8 kHz rate, 31.25 Hz.
        let err = SensorSettings::for_rate_and_bandwidth(3.9, 256.0).unwrap_err();
        assert_eq!(err.nearest_rates(), [Some((31.25, 255)), None]);
    }

    #[test]
    fn unknown_bandwidth_names_the_nearest_row() {
        let err = SensorSettings::for_rate_and_bandwidth(100.0, 40.0).unwrap_err();
        assert_eq!(err.nearest_bandwidth().unwrap().cfg, DlpfCfg::Cfg3);
        assert!(matches!(
            SensorSettings::for_rate_and_bandwidth(0.0, 42.0),
            Err(SettingsError::InvalidRate { .. })
        ));
        assert!(matches!(
            SensorSettings::for_rate_and_bandwidth(f64::NAN, 42.0),
            Err(SettingsError::InvalidRate { .. })
        ));
    }

    #[test]
    fn ranges_and_sensitivities_match_the_datasheet() {
        let gyro: [(u8, f64, f64); 4] = [
            (0, 250.0, 131.0),
            (1, 500.0, 65.5),
            (2, 1000.0, 32.8),
            (3, 2000.0, 16.4),
        ];
        for (bits, fs, lsb) in gyro {
            let g = GyroRange::from_bits(bits).unwrap();
            assert_eq!((g.full_scale_dps(), g.lsb_per_dps()), (fs, lsb));
        }
        let accel: [(u8, f64, f64); 4] = [
            (0, 2.0, 16384.0),
            (1, 4.0, 8192.0),
            (2, 8.0, 4096.0),
            (3, 16.0, 2048.0),
        ];
        for (bits, fs, lsb) in accel {
            let a = AccelRange::from_bits(bits).unwrap();
            assert_eq!((a.full_scale_g(), a.lsb_per_g()), (fs, lsb));
        }
        // 131 counts = 1 deg/s; 16384 counts = 1 g.
        assert!(abs(131.0 * GyroRange::Dps250.rad_s_per_lsb() - PI / 180.0) < 1e-15);
        assert!(abs(16384.0 * AccelRange::G2.m_s2_per_lsb() - 9.806_65) < 1e-12);
    }

    #[test]
    fn frequencies_print_like_the_datasheet() {
        extern crate std;
        use std::format;
        assert_eq!(format!("{}", Hz(200.0)), "200");
        assert_eq!(format!("{}", Hz(1000.0 / 6.0)), "166.667");
        assert_eq!(format!("{}", Hz(3.906_25)), "3.906");
        assert_eq!(format!("{}", Hz(0.98)), "0.98");
        assert_eq!(format!("{}", Hz(31.25)), "31.25");
        let err = SensorSettings::for_rate_and_bandwidth(150.0, 42.0).unwrap_err();
        assert_eq!(
            format!("{err}"),
            "150 Hz is not reachable with DLPF_CFG 3: the output rate is 1000 Hz / (1 + SMPLRT_DIV), \
             SMPLRT_DIV 0..255; nearest: 166.667 Hz (SMPLRT_DIV 5) or 142.857 Hz (SMPLRT_DIV 6)"
        );
        // 4000 Hz is beyond the 1 kHz internal rate of 42 Hz, but 8000 / (1 + 1) at 256 Hz.
        let err = SensorSettings::for_rate_and_bandwidth(4000.0, 42.0).unwrap_err();
        assert!(
            format!("{err}").ends_with("bandwidths that give exactly 4000 Hz: 256 Hz"),
            "{err}"
        );
    }

    #[test]
    fn temperature_conversion() {
        assert_eq!(temperature_celsius(0), 36.53);
        assert!(abs(temperature_celsius(-3740) - 25.53) < 1e-12); // -3740/340 = -11
        assert!(abs(temperature_celsius(340) - 37.53) < 1e-12);
        // The MPU-6500: 0 counts is 21 degC, 333.87 counts a degree.
        let mpu6500 = chip_or_mpu6050(0x70);
        assert!(abs(mpu6500.temperature_celsius(0) - 21.0) < 1e-12);
        assert!(abs(mpu6500.temperature_celsius(3339) - (3339.0 / 333.87 + 21.0)) < 1e-12);
        assert_eq!(
            chip_or_mpu6050(0x68).temperature_celsius(340),
            temperature_celsius(340)
        );
        assert_eq!(chip_or_mpu6050(0x01).name, "MPU-6050");
    }

    #[test]
    fn registers_round_trip_and_field_positions() {
        let s = SensorSettings {
            dlpf: DlpfCfg::Cfg5,
            smplrt_div: 77,
            gyro_range: GyroRange::Dps1000,
            accel_range: AccelRange::G16,
        };
        let r = s.registers();
        assert_eq!(
            r,
            RegisterValues {
                smplrt_div: 77,
                config: 0x05,
                gyro_config: 0x10,
                accel_config: 0x18
            }
        );
        assert_eq!(SensorSettings::from_registers(r), s);
        // Bits outside the fields (EXT_SYNC_SET, self-test, ACCEL_HPF) do not change the meaning.
        let noisy = RegisterValues {
            config: 0x05 | 0x38,
            gyro_config: 0x10 | 0xE7,
            accel_config: 0x18 | 0xE7,
            ..r
        };
        assert_eq!(SensorSettings::from_registers(noisy), s);
    }
}

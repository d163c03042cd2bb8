//! What the host can set on the sensor ([`SensorSettings`]): an output rate and a DLPF row,
//! resolved to exact register values, or an error naming the nearest settings that exist.

use super::ACCEL_INTERNAL_RATE_HZ;
use super::dlpf::{DLPF_TABLE, DlpfCfg, DlpfRow};
use super::range::{AccelRange, GyroRange};
use core::fmt;
use serde::{Deserialize, Serialize};

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

    /// The sample period in microseconds: 125 or 1000 us times (1 + SMPLRT_DIV), exact.
    pub fn period_us(&self) -> u32 {
        self.dlpf.gyro_internal_period_us() * (1 + u32::from(self.smplrt_div))
    }

    /// Seconds between output samples.
    pub fn sample_interval_s(&self) -> f64 {
        1.0 / self.output_rate_hz()
    }

    /// Above 1 kHz output the accelerometer (1 kHz inside) repeats samples [RM, reg 25].
    pub fn accel_repeats_samples(&self) -> bool {
        self.output_rate_hz() > ACCEL_INTERNAL_RATE_HZ
    }

    /// True when the gyro bandwidth exceeds half the output rate: noise between the Nyquist
    /// frequency and the bandwidth then folds back into the band, since the chip decimates
    /// without an anti-alias filter.
    pub fn aliases(&self) -> bool {
        self.dlpf
            .row()
            .is_some_and(|r| r.gyro_bandwidth_hz > self.output_rate_hz() / 2.0)
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
                gyro_only: false,
            })?;
        Ok(SensorSettings {
            dlpf: row.cfg,
            smplrt_div: divider_for(row, rate_hz)?,
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

pub(crate) fn abs(x: f64) -> f64 {
    if x < 0.0 { -x } else { x }
}

pub(crate) fn same(a: f64, b: f64) -> bool {
    abs(a - b) <= REL_TOL * abs(a)
}

/// SMPLRT_DIV giving `rate_hz` exactly at `row`'s internal rate, or the error naming the
/// nearest rates that exist.
pub(crate) fn divider_for(row: &DlpfRow, rate_hz: f64) -> Result<u8, SettingsError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(SettingsError::InvalidRate {
            requested_hz: rate_hz,
        });
    }
    exact_divider(row.gyro_internal_rate_hz, rate_hz).ok_or(SettingsError::RateNotReachable {
        requested_hz: rate_hz,
        dlpf: row.cfg,
    })
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
    /// No DLPF row has this bandwidth; `gyro_only` for a chip without the accelerometer's
    /// column (the ITG-3200).
    UnknownBandwidth { requested_hz: f64, gyro_only: bool },
    /// Not a positive, finite rate.
    InvalidRate { requested_hz: f64 },
    /// No SMPLRT_DIV gives this rate with this DLPF row.
    RateNotReachable { requested_hz: f64, dlpf: DlpfCfg },
}

impl SettingsError {
    /// For an unknown bandwidth, the table's gyro bandwidth closest to it.
    pub fn nearest_bandwidth(&self) -> Option<&'static DlpfRow> {
        let SettingsError::UnknownBandwidth { requested_hz, .. } = *self else {
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
            SettingsError::UnknownBandwidth {
                requested_hz,
                gyro_only,
            } => {
                write!(
                    f,
                    "no DLPF setting has a {requested_hz} Hz bandwidth; gyro bandwidths are"
                )?;
                for r in &DLPF_TABLE {
                    write!(f, " {}", r.gyro_bandwidth_hz)?;
                }
                f.write_str(" Hz")?;
                if !gyro_only {
                    f.write_str(" (accel:")?;
                    for r in &DLPF_TABLE {
                        write!(f, " {}", r.accel_bandwidth_hz)?;
                    }
                    f.write_str(" Hz)")?;
                }
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

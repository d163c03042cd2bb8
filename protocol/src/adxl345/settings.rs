//! What the host can set on the ADXL345 ([`Adxl345Settings`]): the output data rate, the
//! low-power mode and the range, resolved to BW_RATE and DATA_FORMAT (full resolution).

use super::reg::bits;
use crate::mpu6050::settings::{Hz, abs};
use core::fmt;
use serde::{Deserialize, Serialize};

/// The top output data rate, rate code 0b1111; each code below halves it \[AD, table 7\].
pub const TOP_RATE_HZ: f64 = 3200.0;
pub const TOP_RATE_CODE: u8 = 0x0F;

/// Rate codes valid in low-power mode: 12.5 Hz (0b0111) to 400 Hz (0b1100) \[AD, table 8\].
pub const LOW_POWER_CODES: core::ops::RangeInclusive<u8> = 0x07..=0x0C;

/// The rate code of 100 Hz, above which the normal-power noise grows: at and below 100 Hz
/// the noise is the same number of LSB rms \[AD, "Noise Performance"\].
const CODE_100_HZ: u8 = 0x0A;

/// The range, DATA_FORMAT bits 1:0 \[AD, reg 0x31\].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Adxl345Range {
    G2 = 0,
    G4 = 1,
    G8 = 2,
    G16 = 3,
}

impl Adxl345Range {
    pub const ALL: [Adxl345Range; 4] = [
        Adxl345Range::G2,
        Adxl345Range::G4,
        Adxl345Range::G8,
        Adxl345Range::G16,
    ];

    /// Full scale, +/- g.
    pub fn full_scale_g(self) -> u32 {
        2 << (self as u32)
    }

    /// The range whose full scale is `g` (2, 4, 8 or 16).
    pub fn from_full_scale_g(g: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.full_scale_g() == g)
    }
}

/// Everything the host can set on the ADXL345.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Adxl345Settings {
    /// BW_RATE bits 3:0: output data rate `3200 Hz / 2^(15 - code)`.
    pub rate_code: u8,
    pub low_power: bool,
    pub range: Adxl345Range,
}

impl Default for Adxl345Settings {
    /// 100 Hz in normal power, +/-2 g: the data sheet's noise reference.
    fn default() -> Self {
        Adxl345Settings {
            rate_code: 0x0A,
            low_power: false,
            range: Adxl345Range::G2,
        }
    }
}

/// The output data rate of a rate code (codes above 15 are read as their low four bits).
pub fn rate_of_code(code: u8) -> f64 {
    let halvings = TOP_RATE_CODE - (code & bits::RATE_MASK);
    TOP_RATE_HZ / f64::from(1u32 << halvings)
}

impl Adxl345Settings {
    /// The output data rate in Hz.
    pub fn output_rate_hz(&self) -> f64 {
        rate_of_code(self.rate_code)
    }

    /// The sample period in microseconds, `10.24 s / 2^code`: exact except at 3200 Hz
    /// (312.5 us, given as 312).
    pub fn period_us(&self) -> u32 {
        10_240_000 >> (self.rate_code & bits::RATE_MASK)
    }

    /// The bandwidth in Hz: half the output data rate \[AD, table 7\].
    pub fn bandwidth_hz(&self) -> f64 {
        self.output_rate_hz() / 2.0
    }

    /// BW_RATE: the low-power bit and the rate code.
    pub fn bw_rate(&self) -> u8 {
        let low_power = if self.low_power { bits::LOW_POWER } else { 0 };
        low_power | (self.rate_code & bits::RATE_MASK)
    }

    /// DATA_FORMAT: full resolution, right-justified, the range.
    pub fn data_format(&self) -> u8 {
        bits::FULL_RES | self.range as u8
    }

    /// The settings that BW_RATE and DATA_FORMAT mean (other bits ignored).
    pub fn from_registers(bw_rate: u8, data_format: u8) -> Self {
        Adxl345Settings {
            rate_code: bw_rate & bits::RATE_MASK,
            low_power: bw_rate & bits::LOW_POWER != 0,
            range: Adxl345Range::ALL[usize::from(data_format & bits::RANGE_MASK)],
        }
    }

    /// False for low power at a rate where the data sheet does not offer it.
    pub fn is_specified(&self) -> bool {
        !self.low_power || LOW_POWER_CODES.contains(&self.rate_code)
    }

    /// The typical noise in LSB rms on x and y (`z_axis` false) or z \[AD, "Noise
    /// Performance"\]: 0.75 and 1.1 at 100 Hz and below, times `sqrt(rate / 100 Hz)` above;
    /// 1.8 and 2.6 at every low-power rate.
    pub fn noise_lsb_rms(&self, z_axis: bool) -> f64 {
        if self.low_power {
            return if z_axis { 2.6 } else { 1.8 };
        }
        let at_100 = if z_axis { 1.1 } else { 0.75 };
        // Rates above 100 Hz are 100 Hz times 2^doublings: the square root is exact.
        let doublings = self.rate_code.saturating_sub(CODE_100_HZ);
        let root = f64::from(1u32 << (doublings / 2));
        at_100
            * if doublings % 2 == 1 {
                root * core::f64::consts::SQRT_2
            } else {
                root
            }
    }

    /// The settings whose output data rate is `rate_hz`: an exact rate `3200 / 2^k`, or the
    /// data sheet's printed value of one (0.10, 0.20, 0.39, 0.78, 1.56, 3.13), within 3 %,
    /// as rates are a factor 2 apart. Otherwise the error names the nearest rates.
    pub fn for_rate(rate_hz: f64, low_power: bool) -> Result<Self, Adxl345Error> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(Adxl345Error::InvalidRate {
                requested_hz: rate_hz,
            });
        }
        let code = (0..=TOP_RATE_CODE)
            .find(|&c| abs(rate_of_code(c) - rate_hz) <= MATCH_TOL * rate_of_code(c))
            .ok_or(Adxl345Error::RateNotAvailable {
                requested_hz: rate_hz,
            })?;
        let settings = Adxl345Settings {
            rate_code: code,
            low_power,
            ..Adxl345Settings::default()
        };
        if !settings.is_specified() {
            return Err(Adxl345Error::NoLowPowerAt {
                requested_hz: rate_hz,
            });
        }
        Ok(settings)
    }

    /// The normal-power settings whose output data rate is nearest `rate_hz` by ratio (the
    /// lower one on a tie): how a board pairs the ADXL345 with another sensor's rate.
    pub fn nearest_rate(rate_hz: f64) -> Self {
        let distance = |c: u8| {
            let r = rate_of_code(c);
            if r > rate_hz {
                r / rate_hz
            } else {
                rate_hz / r
            }
        };
        let code = (0..=TOP_RATE_CODE)
            .min_by(|&a, &b| distance(a).total_cmp(&distance(b)))
            .unwrap_or(TOP_RATE_CODE);
        Adxl345Settings {
            rate_code: code,
            ..Adxl345Settings::default()
        }
    }
}

/// Relative tolerance matching a requested rate to a rate code (see
/// [`Adxl345Settings::for_rate`]).
const MATCH_TOL: f64 = 0.03;

/// The rates of every code, listed in errors.
struct Rates;

impl fmt::Display for Rates {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut sep = "";
        for c in (0..=TOP_RATE_CODE).rev() {
            write!(f, "{sep}{}", Hz(rate_of_code(c)))?;
            sep = " ";
        }
        f.write_str(" Hz")
    }
}

/// A rate the ADXL345 cannot run at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Adxl345Error {
    InvalidRate { requested_hz: f64 },
    RateNotAvailable { requested_hz: f64 },
    NoLowPowerAt { requested_hz: f64 },
}

impl fmt::Display for Adxl345Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Adxl345Error::InvalidRate { requested_hz } => write!(
                f,
                "the output rate must be a positive number of Hz, not {requested_hz}"
            ),
            Adxl345Error::RateNotAvailable { requested_hz } => {
                let nearest = Adxl345Settings::nearest_rate(requested_hz);
                write!(
                    f,
                    "the ADXL345 has no {requested_hz} Hz output rate; rates are {Rates}; nearest: {} Hz (BW_RATE {:#04x})",
                    Hz(nearest.output_rate_hz()),
                    nearest.bw_rate()
                )
            }
            Adxl345Error::NoLowPowerAt { requested_hz } => write!(
                f,
                "the ADXL345's low-power mode runs at {} to {} Hz only, not {requested_hz} Hz",
                Hz(rate_of_code(*LOW_POWER_CODES.start())),
                Hz(rate_of_code(*LOW_POWER_CODES.end()))
            ),
        }
    }
}

impl core::error::Error for Adxl345Error {}

impl fmt::Display for Adxl345Settings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "ADXL345: {} Hz output (bandwidth {} Hz){}, +/-{} g full resolution",
            Hz(self.output_rate_hz()),
            Hz(self.bandwidth_hz()),
            if self.low_power { ", low power" } else { "" },
            self.range.full_scale_g()
        )
    }
}

//! Which sensors a board streams ([`SensorInfo`] in [`crate::DeviceInfo::sensors`]), and the
//! settings of each by its kind ([`SensorConfig`]).
//!
//! A board has up to [`MAX_SENSORS`] sensors, numbered in the order [`crate::DeviceInfo`]
//! lists them. The board probes two places on its I2C bus: the gyro's (0x68, 0x69), where an
//! MPU-6050 and an ITG-3200 are told apart by WHO_AM_I, and the accelerometer's (0x53,
//! 0x1D), where an ADXL345 answers DEVID 0xE5. What it finds first is sensor 0: an MPU-6050
//! board has one sensor, a GY-85 board an ITG-3200 (0) and an ADXL345 (1).

use crate::adxl345::Adxl345Settings;
use crate::itg3200::Itg3200Settings;
use crate::mpu6050::SensorSettings;
use serde::{Deserialize, Serialize};

/// Most sensors one board streams.
pub const MAX_SENSORS: usize = 2;

/// The sensors a board lists, in order (a fixed array, so that [`crate::DeviceInfo`] stays
/// `Copy`: replies wait in a queue of plain values on the board).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SensorList([Option<SensorInfo>; MAX_SENSORS]);

impl SensorList {
    /// A list of the given sensors; `None` if there are more than [`MAX_SENSORS`].
    pub fn of(sensors: &[SensorInfo]) -> Option<SensorList> {
        let mut list = SensorList::default();
        for sensor in sensors {
            list.push(*sensor).ok()?;
        }
        Some(list)
    }

    /// The list of a one-MPU-6050 board.
    pub fn mpu6050(address: u8, who_am_i: u8, settings: SensorSettings) -> SensorList {
        let mut list = SensorList::default();
        list.0[0] = Some(SensorInfo {
            kind: SensorKind::Mpu6050,
            address,
            id: who_am_i,
            config: SensorConfig::Mpu6050(settings),
        });
        list
    }

    /// Append a sensor; `Err` with it if the list is full.
    pub fn push(&mut self, sensor: SensorInfo) -> Result<(), SensorInfo> {
        match self.0.iter_mut().find(|slot| slot.is_none()) {
            Some(slot) => {
                *slot = Some(sensor);
                Ok(())
            }
            None => Err(sensor),
        }
    }

    /// The sensors, by number.
    pub fn iter(&self) -> impl Iterator<Item = &SensorInfo> {
        self.0.iter().map_while(Option::as_ref)
    }

    /// Sensor number `sensor`.
    pub fn get(&self, sensor: usize) -> Option<&SensorInfo> {
        self.iter().nth(sensor)
    }

    pub fn len(&self) -> usize {
        self.iter().count()
    }

    pub fn is_empty(&self) -> bool {
        self.0[0].is_none()
    }
}

/// What a sensor is.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensorKind {
    /// Gyro, accelerometer and temperature ([`crate::mpu6050`]).
    Mpu6050,
    /// Gyro and temperature ([`crate::itg3200`]).
    Itg3200,
    /// Accelerometer ([`crate::adxl345`]).
    Adxl345,
}

impl SensorKind {
    /// The name users know the chip by.
    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Mpu6050 => "MPU-6050",
            SensorKind::Itg3200 => "ITG-3200",
            SensorKind::Adxl345 => "ADXL345",
        }
    }

    /// Which parts of a [`crate::RawSample`] this sensor fills: (accel, temp, gyro). The
    /// others are 0 on the wire and carry nothing.
    pub fn fills(self) -> Fills {
        match self {
            SensorKind::Mpu6050 => Fills {
                accel: true,
                temp: true,
                gyro: true,
            },
            SensorKind::Itg3200 => Fills {
                accel: false,
                temp: true,
                gyro: true,
            },
            SensorKind::Adxl345 => Fills {
                accel: true,
                temp: false,
                gyro: false,
            },
        }
    }
}

impl core::fmt::Display for SensorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// The parts of a [`crate::RawSample`] a sensor fills ([`SensorKind::fills`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fills {
    pub accel: bool,
    pub temp: bool,
    pub gyro: bool,
}

/// One sensor's settings, by its kind.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensorConfig {
    Mpu6050(SensorSettings),
    Itg3200(Itg3200Settings),
    Adxl345(Adxl345Settings),
}

impl SensorConfig {
    pub fn kind(&self) -> SensorKind {
        match self {
            SensorConfig::Mpu6050(_) => SensorKind::Mpu6050,
            SensorConfig::Itg3200(_) => SensorKind::Itg3200,
            SensorConfig::Adxl345(_) => SensorKind::Adxl345,
        }
    }

    /// The sensor's power-on choice in this firmware: each kind's `Default`.
    pub fn default_for(kind: SensorKind) -> SensorConfig {
        match kind {
            SensorKind::Mpu6050 => SensorConfig::Mpu6050(SensorSettings::default()),
            SensorKind::Itg3200 => SensorConfig::Itg3200(Itg3200Settings::default()),
            SensorKind::Adxl345 => SensorConfig::Adxl345(Adxl345Settings::default()),
        }
    }

    /// The output sample rate in Hz.
    pub fn output_rate_hz(&self) -> f64 {
        match self {
            SensorConfig::Mpu6050(s) => s.output_rate_hz(),
            SensorConfig::Itg3200(s) => s.output_rate_hz(),
            SensorConfig::Adxl345(s) => s.output_rate_hz(),
        }
    }

    /// The nominal sample period in microseconds (exact but for the ADXL345's 3200 Hz).
    pub fn period_us(&self) -> u32 {
        match self {
            SensorConfig::Mpu6050(s) => s.period_us(),
            SensorConfig::Itg3200(s) => s.period_us(),
            SensorConfig::Adxl345(s) => s.period_us(),
        }
    }
}

/// The settings in words (the ITG-3200's and ADXL345's texts name their chip; an
/// MPU-6050's, the only one of most boards, does not).
impl core::fmt::Display for SensorConfig {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SensorConfig::Mpu6050(s) => write!(f, "{s}"),
            SensorConfig::Itg3200(s) => write!(f, "{s}"),
            SensorConfig::Adxl345(s) => write!(f, "{s}"),
        }
    }
}

/// One sensor a board found and streams.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorInfo {
    pub kind: SensorKind,
    /// Its 7-bit I2C address.
    pub address: u8,
    /// What its identity register answered (WHO_AM_I; DEVID for the ADXL345).
    pub id: u8,
    /// The settings in force.
    pub config: SensorConfig,
}

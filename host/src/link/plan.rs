//! What each sensor of a board is set to from one request (`--rate`, `--bandwidth` and the
//! ranges): a board says which sensors it has (its Info), and the request means the same on
//! all of them.
//!
//! - An **MPU-6050** gets the DLPF row and divider for the rate and bandwidth, and the
//!   ranges.
//! - An **ITG-3200** gets the same DLPF row and divider (its table is the MPU-6050's gyro
//!   column); its range is fixed at 2000 deg/s.
//! - An **ADXL345** has no bandwidth of its own to choose (it is rate / 2): it gets the
//!   output rate of the board's gyro, which must be one of its rates so that the board's
//!   samples make one record; on a board without a gyro, the rate nearest the request. The
//!   accel range applies.
//!
//! Every setting must also be one the board's firmware streams.

use super::board::{Board, BoardError};
use protocol::adxl345::{Adxl345Range, Adxl345Settings};
use protocol::itg3200::Itg3200Settings;
use protocol::mpu6050::{AccelRange, GyroRange, Hz, SettingsError};
use protocol::{Command, SensorConfig, SensorKind, SensorList, SensorSettings};

/// Highest output rate the board's firmware streams, Hz (its drivers' limit).
pub const MAX_RATE_HZ: f64 = firmware::acquire::MAX_RATE_HZ;

/// One rate, one bandwidth, the ranges: what a user asks of a board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    pub rate_hz: f64,
    pub bandwidth_hz: f64,
    pub gyro_range: GyroRange,
    pub accel_range: AccelRange,
}

impl Request {
    /// The request that gives an MPU-6050 `settings`: their rate, their gyro bandwidth (each
    /// DLPF row's is its own) and ranges. With the DLPF_CFG 7 row reserved, the bandwidth is
    /// that of DLPF_CFG 0, which shares its 8 kHz internal rate.
    pub fn of(settings: &SensorSettings) -> Request {
        Request {
            rate_hz: settings.output_rate_hz(),
            bandwidth_hz: settings.dlpf.row().map_or(256.0, |r| r.gyro_bandwidth_hz),
            gyro_range: settings.gyro_range,
            accel_range: settings.accel_range,
        }
    }

    /// The MPU-6050's settings for the request.
    pub fn mpu6050(&self) -> Result<SensorSettings, PlanError> {
        let settings = SensorSettings::for_rate_and_bandwidth(self.rate_hz, self.bandwidth_hz)
            .map_err(PlanError::Mpu6050)?;
        streamable(settings.output_rate_hz())?;
        Ok(settings.with_ranges(self.gyro_range, self.accel_range))
    }

    /// The ITG-3200's settings for the request.
    pub fn itg3200(&self) -> Result<Itg3200Settings, PlanError> {
        let settings = Itg3200Settings::for_rate_and_bandwidth(self.rate_hz, self.bandwidth_hz)
            .map_err(PlanError::Itg3200)?;
        streamable(settings.output_rate_hz())?;
        Ok(settings)
    }

    /// The ADXL345's settings at `rate_hz` exactly (`None`: the rate nearest the request).
    pub fn adxl345(&self, rate_hz: Option<f64>) -> Result<Adxl345Settings, PlanError> {
        let wanted = rate_hz.unwrap_or(self.rate_hz);
        let mut settings = Adxl345Settings::nearest_rate(wanted);
        if rate_hz.is_some() && settings.output_rate_hz() != wanted {
            return Err(PlanError::Rates {
                gyro_hz: wanted,
                bandwidth_hz: self.bandwidth_hz,
            });
        }
        streamable(settings.output_rate_hz())?;
        // Every MPU-6050 range (2, 4, 8, 16 g) is an ADXL345 range.
        let g = self.accel_range.full_scale_g() as u32;
        settings.range = Adxl345Range::from_full_scale_g(g).unwrap_or(settings.range);
        Ok(settings)
    }
}

/// Why a board cannot be set as asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("MPU-6050: {0}")]
    Mpu6050(SettingsError),
    #[error("ITG-3200: {0}")]
    Itg3200(SettingsError),
    #[error("{}", rates_message(*gyro_hz, *bandwidth_hz))]
    Rates { gyro_hz: f64, bandwidth_hz: f64 },
    #[error(
        "{} Hz is above the board firmware's output-rate limit of {} Hz (the sensor itself can \
         be set to it: `imunoise settings` shows how)",
        Hz(*rate_hz),
        Hz(MAX_RATE_HZ)
    )]
    NotStreamable { rate_hz: f64 },
    #[error("the board lists no sensor")]
    NoSensor,
}

/// The rates an ITG-3200 and an ADXL345 share at a gyro bandwidth, for the error.
fn rates_message(gyro_hz: f64, bandwidth_hz: f64) -> String {
    let nearest = Adxl345Settings::nearest_rate(gyro_hz).output_rate_hz();
    let shared: Vec<String> = (0..=protocol::adxl345::settings::TOP_RATE_CODE)
        .map(protocol::adxl345::settings::rate_of_code)
        .filter(|&r| r <= MAX_RATE_HZ)
        .filter(|&r| Itg3200Settings::for_rate_and_bandwidth(r, bandwidth_hz).is_ok())
        .map(|r| Hz(r).to_string())
        .collect();
    format!(
        "the ADXL345 has no {} Hz output rate (nearest: {} Hz), and one record needs one rate; with the gyro at {bandwidth_hz} Hz both sensors run at {} Hz",
        Hz(gyro_hz),
        Hz(nearest),
        shared.join(", ")
    )
}

/// A setting the board's firmware does not stream.
pub fn streamable(rate_hz: f64) -> Result<(), PlanError> {
    match rate_hz > MAX_RATE_HZ {
        true => Err(PlanError::NotStreamable { rate_hz }),
        false => Ok(()),
    }
}

/// Each listed sensor's settings, by number.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub configs: Vec<SensorConfig>,
}

impl Plan {
    /// The settings of every sensor `sensors` lists, for `request` (module docs).
    pub fn for_sensors(request: &Request, sensors: &SensorList) -> Result<Plan, PlanError> {
        if sensors.is_empty() {
            return Err(PlanError::NoSensor);
        }
        let gyro = |kind| match kind {
            SensorKind::Mpu6050 => request.mpu6050().map(SensorConfig::Mpu6050),
            SensorKind::Itg3200 => request.itg3200().map(SensorConfig::Itg3200),
            SensorKind::Adxl345 => Err(PlanError::NoSensor),
        };
        // The first gyro's rate is the board's, which an accelerometer must share.
        let gyro_hz = match sensors.iter().find(|s| s.kind != SensorKind::Adxl345) {
            Some(sensor) => Some(gyro(sensor.kind)?.output_rate_hz()),
            None => None,
        };
        let configs = sensors
            .iter()
            .map(|sensor| match sensor.kind {
                SensorKind::Adxl345 => request.adxl345(gyro_hz).map(SensorConfig::Adxl345),
                kind => gyro(kind),
            })
            .collect::<Result<_, _>>()?;
        Ok(Plan { configs })
    }

    /// The plan for a board of these sensors (a request checked before a board is asked).
    pub fn for_kinds(request: &Request, kinds: &[SensorKind]) -> Result<Plan, PlanError> {
        let sensors: Vec<protocol::SensorInfo> = kinds
            .iter()
            .map(|&kind| protocol::SensorInfo {
                kind,
                address: 0,
                id: 0,
                config: SensorConfig::default_for(kind),
            })
            .collect();
        let list = SensorList::of(&sensors).ok_or(PlanError::NoSensor)?;
        Plan::for_sensors(request, &list)
    }

    /// A one-MPU-6050 board's plan.
    pub fn mpu6050(settings: SensorSettings) -> Plan {
        Plan {
            configs: vec![SensorConfig::Mpu6050(settings)],
        }
    }

    /// The commands that set the board: `Configure` for an MPU-6050 that is sensor 0 (as
    /// every board understood it), `ConfigureSensor` for the others.
    pub fn commands(&self) -> impl Iterator<Item = Command> + '_ {
        self.configs
            .iter()
            .enumerate()
            .map(|(k, config)| match (k, config) {
                (0, SensorConfig::Mpu6050(settings)) => Command::Configure(*settings),
                _ => Command::ConfigureSensor {
                    // At most MAX_SENSORS sensors: the number fits a byte.
                    sensor: k as u8,
                    config: *config,
                },
            })
    }

    /// Set the board (stopped) to the plan.
    pub fn apply(&self, board: &mut Board) -> Result<(), BoardError> {
        self.commands()
            .try_for_each(|command| board.command(command, "configure"))
    }

    /// The output rate of the board's samples: sensor 0's.
    pub fn rate_hz(&self) -> f64 {
        self.configs
            .first()
            .map_or(0.0, SensorConfig::output_rate_hz)
    }
}

impl std::fmt::Display for Plan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (k, config) in self.configs.iter().enumerate() {
            if k > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{config}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::SensorInfo;

    fn request(rate_hz: f64, bandwidth_hz: f64) -> Request {
        Request {
            rate_hz,
            bandwidth_hz,
            gyro_range: GyroRange::Dps250,
            accel_range: AccelRange::G16,
        }
    }

    fn listed(kinds: &[SensorKind]) -> SensorList {
        let sensors: Vec<SensorInfo> = kinds
            .iter()
            .map(|&kind| SensorInfo {
                kind,
                address: 0,
                id: 0,
                config: SensorConfig::default_for(kind),
            })
            .collect();
        SensorList::of(&sensors).unwrap()
    }

    #[test]
    fn a_gy85_gets_the_gyro_filter_and_the_same_rate_on_the_accelerometer() {
        let gy85 = listed(&[SensorKind::Itg3200, SensorKind::Adxl345]);
        let plan = Plan::for_sensors(&request(50.0, 20.0), &gy85).unwrap();
        let SensorConfig::Itg3200(gyro) = plan.configs[0] else {
            panic!("{plan:?}")
        };
        let SensorConfig::Adxl345(accel) = plan.configs[1] else {
            panic!("{plan:?}")
        };
        assert_eq!((gyro.smplrt_div, gyro.dlpf_fs()), (19, 0x1C));
        assert_eq!((accel.bw_rate(), accel.range), (0x09, Adxl345Range::G16));
        assert_eq!(plan.rate_hz(), 50.0);
        let commands: Vec<Command> = plan.commands().collect();
        assert!(matches!(
            commands[..],
            [
                Command::ConfigureSensor { sensor: 0, .. },
                Command::ConfigureSensor { sensor: 1, .. }
            ]
        ));
        // 250 Hz is no ADXL345 rate: refused, naming the rates both have.
        let e = Plan::for_sensors(&request(250.0, 42.0), &gy85).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the ADXL345 has no 250 Hz output rate (nearest: 200 Hz), and one record needs one \
             rate; with the gyro at 42 Hz both sensors run at 6.25, 12.5, 25, 50, 100, 200 Hz"
        );
    }

    #[test]
    fn an_mpu6050_board_is_configured_as_it_always_was() {
        let plan =
            Plan::for_sensors(&request(200.0, 42.0), &listed(&[SensorKind::Mpu6050])).unwrap();
        let settings = request(200.0, 42.0).mpu6050().unwrap();
        assert_eq!(plan, Plan::mpu6050(settings));
        assert_eq!(
            plan.commands().collect::<Vec<_>>(),
            [Command::Configure(settings)]
        );
        let e = request(2000.0, 256.0).mpu6050().unwrap_err();
        assert!(e.to_string().starts_with("2000 Hz is above"), "{e}");
    }

    #[test]
    fn a_sweep_row_is_the_request_that_gives_it() {
        for dlpf in protocol::mpu6050::DlpfCfg::ALL {
            for smplrt_div in [0u8, 4, 9, 99, 255] {
                let settings = SensorSettings {
                    dlpf,
                    smplrt_div,
                    gyro_range: GyroRange::Dps500,
                    accel_range: AccelRange::G4,
                };
                if !settings.is_specified() {
                    continue;
                }
                let request = Request::of(&settings);
                let again =
                    SensorSettings::for_rate_and_bandwidth(request.rate_hz, request.bandwidth_hz)
                        .unwrap()
                        .with_ranges(request.gyro_range, request.accel_range);
                assert_eq!(again, settings);
            }
        }
    }

    #[test]
    fn an_accelerometer_alone_takes_the_nearest_rate() {
        let plan =
            Plan::for_sensors(&request(90.0, 42.0), &listed(&[SensorKind::Adxl345])).unwrap();
        assert_eq!(plan.rate_hz(), 100.0);
        assert_eq!(
            Plan::for_sensors(&request(90.0, 42.0), &SensorList::default()),
            Err(PlanError::NoSensor)
        );
    }
}

//! The simulator's model file (TOML): one table per group, `[gyro]`, `[accel]`,
//! `[temperature]`, every key optional, SI units (u = rad/s for the gyro, m/s^2 for the
//! accelerometer, degC for the temperature; docs/ARCHITECTURE.md, "Units and conventions"). Example: `examples/mpu6050.toml`.
//!
//! Noise keys (any group; in `[temperature]` they are the TEMP_OUT reading's noise):
//! `noise_density` N (u/sqrt(Hz), the Allan coefficient: two-sided density, = the Allan
//! deviation at 1 s), `bias_instability` B (u), `rate_random_walk` K (u sqrt(Hz)),
//! `rate_ramp` R (u/s), `quantization` Q (u s), `gauss_markov = { sigma, tau_c }` (u, s),
//! `sinusoid = { amplitude, freq_hz }` (u, Hz).
//!
//! `[gyro]` and `[accel]` also take `lines = [{ amplitude, freq_hz, width_hz, shape }, ...]`:
//! spectral lines of peak amplitude `amplitude` (u, `sqrt(2 power)`) at `freq_hz` with full
//! width at half maximum `width_hz` (Hz, default 0: a pure tone), `shape` either
//! `"diffusing_phase"` (default: a constant amplitude whose phase wanders) or `"resonance"`
//! (white noise through a second-order resonance), as [`super::line`] generates them; each is
//! added at the chip's internal rate, before its filter, with an independent phase per axis.
//! They also take `temperature = { bias_coeff, scale_coeff, rate_coeff }` (u/degC, 1/degC,
//! u/(degC/s)), `bias = [x, y, z]` (u), `scale_factor = [x, y, z]` (relative error),
//! `misalignment = [[..3], [..3], [..3]]` (added to the identity); `[accel]` takes
//! `gravity_axis = "z"` (x, y, z, -x, -y, -z; default z).
//!
//! `[temperature]` also takes the profile: `initial` (degC, default 25), `warmup = { rise,
//! tau }`, `ramp` (degC/s), `cycle = { amplitude, period }`, and `reference` (degC, default
//! 25: the temperature at which the coupling is zero).
//!
//! `[faults]` scripts what an overnight run meets, for the simulated sensor and the virtual
//! board ([`FaultPlan`]); times are seconds of board time from power-up, every key optional:
//! - `clock_ppm` (default 0): the sensor's sample clock against the board's, ppm (+3000: the
//!   sensor samples 0.3 % fast), > -1e6;
//! - `clock_drift_ppm_per_hour` (default 0): a linear change of that offset, ppm per hour
//!   (the rate is `1 + (clock_ppm + drift * t_hours) * 1e-6`; sample times follow its
//!   integral exactly);
//! - `i2c_outage = [{ at_s, for_s }, ...]`: windows in which every I2C transfer is NACKed at
//!   the address while the sensor keeps sampling (its FIFO overflows); `for_s` > 0;
//! - `sensor_reset = [t, ...]`: sensor resets (registers back to power-on values, asleep,
//!   FIFO empty);
//! - `board_reset = [t, ...]`: the board reboots (watchdog, brown-out): fresh firmware, unread
//!   USB data lost, not streaming until the host sends Start; the sensor is left as it is;
//! - `who_am_i` (0..=255): what WHO_AM_I reads instead of 0x68 (a clone chip).
//!
//! Commands that only synthesise samples (`simulate`) ignore `[faults]`; the virtual board
//! (`capture --port sim`) applies it.
//!
//! Unknown keys, keys in the wrong group, negative or non-finite values are errors naming the
//! file and the field.

use super::device::{Outage, SensorClock, SimChip};
use super::imu::{GravityAxis, ImuModel, SensorModel, TemperatureModel};
use super::line::{NarrowBand, Shape as LineShape};
use super::noise::{GaussMarkov, NoiseTerms, Sinusoid};
use super::temperature::{Cycle, TempCoupling, TemperatureProfile, Warmup};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Errors reading a model file; each names the file, and the field where there is one.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    #[error("{file}: cannot read: {source}")]
    Read {
        file: PathBuf,
        source: std::io::Error,
    },
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    #[error("{file}: [{group}] {field}: {message}")]
    Field {
        file: PathBuf,
        group: &'static str,
        field: &'static str,
        message: String,
    },
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSpec {
    #[serde(default)]
    gyro: GroupSpec,
    #[serde(default)]
    accel: GroupSpec,
    #[serde(default)]
    temperature: GroupSpec,
    #[serde(default)]
    faults: FaultsSpec,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FaultsSpec {
    clock_ppm: Option<f64>,
    clock_drift_ppm_per_hour: Option<f64>,
    #[serde(default)]
    i2c_outage: Vec<OutageSpec>,
    #[serde(default)]
    sensor_reset: Vec<f64>,
    #[serde(default)]
    board_reset: Vec<f64>,
    who_am_i: Option<i64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OutageSpec {
    at_s: f64,
    for_s: f64,
}

/// A model file's content: the sensor model and the faults to inject.
#[derive(Debug, Clone, Default)]
pub struct ModelFile {
    pub model: ImuModel,
    pub faults: FaultPlan,
}

/// Faults scripted for a run (the `[faults]` table), in board time, us, from power-up.
/// Lists are sorted by time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FaultPlan {
    /// The sensor's sample oscillator against the board's clock.
    pub clock: SensorClock,
    /// Windows in which the sensor answers no transaction.
    pub i2c_outages: Vec<Outage>,
    /// Sensor resets.
    pub sensor_resets_us: Vec<u64>,
    /// Board reboots (the virtual board's, [`crate::link::virtual_board`]).
    pub board_resets_us: Vec<u64>,
    /// WHO_AM_I's value instead of 0x68.
    pub who_am_i: Option<u8>,
}

impl FaultPlan {
    /// Whether the plan injects nothing.
    pub fn is_empty(&self) -> bool {
        *self == FaultPlan::default()
    }

    /// Set the sensor's share of the plan (everything but board resets) on `sensor`: its
    /// clock and WHO_AM_I are replaced, outages and resets added to those it has.
    pub fn apply_to_sensor(&self, sensor: &mut impl SimChip) {
        let faults = sensor.faults_mut();
        faults.clock = self.clock;
        faults.i2c_outages.extend_from_slice(&self.i2c_outages);
        if self.who_am_i.is_some() {
            faults.who_am_i = self.who_am_i;
        }
        for &t in &self.sensor_resets_us {
            sensor.schedule_reset(t);
        }
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct GroupSpec {
    noise_density: Option<f64>,
    bias_instability: Option<f64>,
    rate_random_walk: Option<f64>,
    rate_ramp: Option<f64>,
    quantization: Option<f64>,
    gauss_markov: Option<GaussMarkovSpec>,
    sinusoid: Option<SinusoidSpec>,
    lines: Option<Vec<LineSpec>>,
    temperature: Option<CouplingSpec>,
    bias: Option<[f64; 3]>,
    scale_factor: Option<[f64; 3]>,
    misalignment: Option<[[f64; 3]; 3]>,
    gravity_axis: Option<String>,
    initial: Option<f64>,
    warmup: Option<WarmupSpec>,
    ramp: Option<f64>,
    cycle: Option<CycleSpec>,
    reference: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GaussMarkovSpec {
    sigma: f64,
    tau_c: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SinusoidSpec {
    amplitude: f64,
    freq_hz: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LineSpec {
    amplitude: f64,
    freq_hz: f64,
    #[serde(default)]
    width_hz: f64,
    #[serde(default)]
    shape: LineShapeSpec,
}

#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum LineShapeSpec {
    #[default]
    DiffusingPhase,
    Resonance,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CouplingSpec {
    #[serde(default)]
    bias_coeff: f64,
    #[serde(default)]
    scale_coeff: f64,
    #[serde(default)]
    rate_coeff: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WarmupSpec {
    rise: f64,
    tau: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CycleSpec {
    amplitude: f64,
    period: f64,
}

/// The documented example model (examples/mpu6050.toml), built in so that the demo and the
/// virtual board run anywhere.
pub const EXAMPLE: &str = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/mpu6050.toml"));

/// The GY-85's example model (`examples/gy85.toml`): `[gyro]` the ITG-3200's, `[accel]`
/// the ADXL345's.
pub const EXAMPLE_GY85: &str =
    include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/gy85.toml"));

/// [`EXAMPLE_GY85`], parsed (the default model of the virtual GY-85 board).
pub fn example_gy85() -> ImuModel {
    // Tested like the MPU-6050's (`the_example_model_parses`).
    parse(EXAMPLE_GY85, Path::new("examples/gy85.toml")).unwrap_or_default()
}

/// [`EXAMPLE`], parsed.
pub fn example() -> ImuModel {
    // The example is part of the build and tested (`the_example_model_parses`); a failure here
    // would be a broken build, so fall back to the default model rather than panic.
    parse(EXAMPLE, Path::new("examples/mpu6050.toml")).unwrap_or_default()
}

/// Read and check a model file: its model, `[faults]` checked and left out.
pub fn load(path: &Path) -> Result<ImuModel, ModelFileError> {
    load_file(path).map(|f| f.model)
}

/// Read and check a model file: the model and the fault plan.
pub fn load_file(path: &Path) -> Result<ModelFile, ModelFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| ModelFileError::Read {
        file: path.to_owned(),
        source,
    })?;
    parse_file(&text, path)
}

/// Parse model-file text (its model; `[faults]` checked and left out); `file` names it in
/// errors.
pub fn parse(text: &str, file: &Path) -> Result<ImuModel, ModelFileError> {
    parse_file(text, file).map(|f| f.model)
}

/// Parse model-file text: the model and the fault plan; `file` names it in errors.
pub fn parse_file(text: &str, file: &Path) -> Result<ModelFile, ModelFileError> {
    let spec: FileSpec = toml::from_str(text).map_err(|e| ModelFileError::Parse {
        file: file.to_owned(),
        message: e.to_string().trim_end().to_owned(),
    })?;
    let cx = Checker { file };
    let gyro = cx.sensor("gyro", &spec.gyro)?;
    let accel = cx.sensor("accel", &spec.accel)?;
    let gravity = match &spec.accel.gravity_axis {
        Some(s) => s
            .parse::<GravityAxis>()
            .map_err(|m| cx.error("accel", "gravity_axis", m.to_string()))?,
        None => GravityAxis::default(),
    };
    let temperature = cx.temperature(&spec.temperature)?;
    let faults = cx.faults(&spec.faults)?;
    Ok(ModelFile {
        model: ImuModel {
            gyro,
            accel,
            gravity,
            temperature,
        },
        faults,
    })
}

struct Checker<'a> {
    file: &'a Path,
}

impl Checker<'_> {
    fn error(
        &self,
        group: &'static str,
        field: &'static str,
        message: impl Into<String>,
    ) -> ModelFileError {
        ModelFileError::Field {
            file: self.file.to_owned(),
            group,
            field,
            message: message.into(),
        }
    }

    fn finite(
        &self,
        group: &'static str,
        field: &'static str,
        v: f64,
    ) -> Result<f64, ModelFileError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(group, field, format!("{v} is not a finite number")))
        }
    }

    fn non_negative(
        &self,
        group: &'static str,
        field: &'static str,
        v: f64,
    ) -> Result<f64, ModelFileError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.error(group, field, format!("{v} must be a finite number >= 0")))
        }
    }

    fn positive(
        &self,
        group: &'static str,
        field: &'static str,
        v: f64,
    ) -> Result<f64, ModelFileError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.error(group, field, format!("{v} must be a finite number > 0")))
        }
    }

    /// A time in seconds (>= 0) as whole microseconds.
    fn time_us(&self, field: &'static str, seconds: f64) -> Result<u64, ModelFileError> {
        let s = self.non_negative("faults", field, seconds)?;
        let us = (s * 1e6).round();
        if us < u64::MAX as f64 {
            Ok(us as u64)
        } else {
            Err(self.error("faults", field, format!("{seconds} s is too far")))
        }
    }

    fn faults(&self, f: &FaultsSpec) -> Result<FaultPlan, ModelFileError> {
        let group = "faults";
        let ppm = self.finite(group, "clock_ppm", f.clock_ppm.unwrap_or(0.0))?;
        if ppm <= -1e6 {
            return Err(self.error(
                group,
                "clock_ppm",
                format!("{ppm} must be > -1e6 (the sensor's clock must run)"),
            ));
        }
        let clock = SensorClock {
            ppm,
            drift_ppm_per_hour: self.finite(
                group,
                "clock_drift_ppm_per_hour",
                f.clock_drift_ppm_per_hour.unwrap_or(0.0),
            )?,
        };
        let mut i2c_outages = Vec::with_capacity(f.i2c_outage.len());
        for o in &f.i2c_outage {
            let at_us = self.time_us("i2c_outage.at_s", o.at_s)?;
            self.positive(group, "i2c_outage.for_s", o.for_s)?;
            let for_us = self.time_us("i2c_outage.for_s", o.for_s)?;
            i2c_outages.push(Outage { at_us, for_us });
        }
        i2c_outages.sort_by_key(|o| o.at_us);
        let times = |field, list: &[f64]| -> Result<Vec<u64>, ModelFileError> {
            let mut v = list
                .iter()
                .map(|&s| self.time_us(field, s))
                .collect::<Result<Vec<_>, _>>()?;
            v.sort_unstable();
            Ok(v)
        };
        let who_am_i = match f.who_am_i {
            Some(v) => Some(
                u8::try_from(v)
                    .map_err(|_| self.error(group, "who_am_i", format!("{v} is not a byte")))?,
            ),
            None => None,
        };
        Ok(FaultPlan {
            clock,
            i2c_outages,
            sensor_resets_us: times("sensor_reset", &f.sensor_reset)?,
            board_resets_us: times("board_reset", &f.board_reset)?,
            who_am_i,
        })
    }

    /// Keys that exist but do not belong in `group`.
    fn reject(
        &self,
        group: &'static str,
        present: &[(&'static str, bool)],
    ) -> Result<(), ModelFileError> {
        match present.iter().find(|(_, p)| *p) {
            Some((field, _)) => Err(self.error(group, field, format!("not a key of [{group}]"))),
            None => Ok(()),
        }
    }

    fn noise(&self, group: &'static str, g: &GroupSpec) -> Result<NoiseTerms, ModelFileError> {
        let opt = |field, v: Option<f64>| v.map_or(Ok(0.0), |v| self.non_negative(group, field, v));
        let gauss_markov = match &g.gauss_markov {
            Some(s) => Some(GaussMarkov {
                sigma: self.non_negative(group, "gauss_markov.sigma", s.sigma)?,
                tau_c: self.positive(group, "gauss_markov.tau_c", s.tau_c)?,
            }),
            None => None,
        };
        let sinusoid = match &g.sinusoid {
            Some(s) => Some(Sinusoid {
                amplitude: self.non_negative(group, "sinusoid.amplitude", s.amplitude)?,
                freq_hz: self.non_negative(group, "sinusoid.freq_hz", s.freq_hz)?,
            }),
            None => None,
        };
        Ok(NoiseTerms {
            n: opt("noise_density", g.noise_density)?,
            b: opt("bias_instability", g.bias_instability)?,
            k: opt("rate_random_walk", g.rate_random_walk)?,
            r: opt("rate_ramp", g.rate_ramp)?,
            q: opt("quantization", g.quantization)?,
            gauss_markov,
            sinusoid,
        })
    }

    fn sensor(&self, group: &'static str, g: &GroupSpec) -> Result<SensorModel, ModelFileError> {
        self.reject(
            group,
            &[
                ("initial", g.initial.is_some()),
                ("warmup", g.warmup.is_some()),
                ("ramp", g.ramp.is_some()),
                ("cycle", g.cycle.is_some()),
                ("reference", g.reference.is_some()),
                ("gravity_axis", group == "gyro" && g.gravity_axis.is_some()),
            ],
        )?;
        let triple = |field, v: Option<[f64; 3]>| -> Result<[f64; 3], ModelFileError> {
            let v = v.unwrap_or_default();
            for x in v {
                self.finite(group, field, x)?;
            }
            Ok(v)
        };
        let mut misalignment = [[0.0; 3]; 3];
        if let Some(m) = g.misalignment {
            for (i, row) in m.iter().enumerate() {
                misalignment[i] = triple("misalignment", Some(*row))?;
            }
        }
        let temperature = match &g.temperature {
            Some(c) => TempCoupling {
                bias_coeff: self.finite(group, "temperature.bias_coeff", c.bias_coeff)?,
                scale_coeff: self.finite(group, "temperature.scale_coeff", c.scale_coeff)?,
                rate_coeff: self.finite(group, "temperature.rate_coeff", c.rate_coeff)?,
            },
            None => TempCoupling::default(),
        };
        let lines = g
            .lines
            .iter()
            .flatten()
            .map(|l| {
                Ok(NarrowBand {
                    amplitude: self.non_negative(group, "lines.amplitude", l.amplitude)?,
                    freq_hz: self.positive(group, "lines.freq_hz", l.freq_hz)?,
                    width_hz: self.non_negative(group, "lines.width_hz", l.width_hz)?,
                    shape: match l.shape {
                        LineShapeSpec::DiffusingPhase => LineShape::DiffusingPhase,
                        LineShapeSpec::Resonance => LineShape::Resonance,
                    },
                })
            })
            .collect::<Result<Vec<_>, ModelFileError>>()?;
        Ok(SensorModel {
            noise: self.noise(group, g)?,
            lines,
            bias: triple("bias", g.bias)?,
            scale_factor: triple("scale_factor", g.scale_factor)?,
            misalignment,
            temperature,
        })
    }

    fn temperature(&self, g: &GroupSpec) -> Result<TemperatureModel, ModelFileError> {
        let group = "temperature";
        self.reject(
            group,
            &[
                ("temperature", g.temperature.is_some()),
                ("lines", g.lines.is_some()),
                ("bias", g.bias.is_some()),
                ("scale_factor", g.scale_factor.is_some()),
                ("misalignment", g.misalignment.is_some()),
                ("gravity_axis", g.gravity_axis.is_some()),
            ],
        )?;
        let warmup = match &g.warmup {
            Some(w) => Some(Warmup {
                rise: self.finite(group, "warmup.rise", w.rise)?,
                tau: self.positive(group, "warmup.tau", w.tau)?,
            }),
            None => None,
        };
        let cycle = match &g.cycle {
            Some(c) => Some(Cycle {
                amplitude: self.finite(group, "cycle.amplitude", c.amplitude)?,
                period: self.positive(group, "cycle.period", c.period)?,
            }),
            None => None,
        };
        Ok(TemperatureModel {
            profile: TemperatureProfile {
                initial: self.finite(group, "initial", g.initial.unwrap_or(25.0))?,
                warmup,
                ramp: self.finite(group, "ramp", g.ramp.unwrap_or(0.0))?,
                cycle,
            },
            reference: self.finite(group, "reference", g.reference.unwrap_or(25.0))?,
            noise: self.noise(group, g)?,
        })
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_example_model_parses() {
        super::parse(super::EXAMPLE_GY85, std::path::Path::new("gy85")).unwrap();
        let model = super::parse(super::EXAMPLE, std::path::Path::new("example")).unwrap();
        assert_eq!(model.gyro.noise.n, 1.5e-4);
    }
    use super::*;
    use crate::sim::device::SimMpu6050;

    fn parse_str(text: &str) -> Result<ImuModel, ModelFileError> {
        parse(text, Path::new("m.toml"))
    }

    #[test]
    fn the_example_file_parses() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/mpu6050.toml");
        let m = load(&path).unwrap();
        assert_eq!(m.gyro.noise.n, 1.5e-4);
        assert_eq!(m.accel.noise.k, 5e-5);
        assert_eq!(m.gravity, GravityAxis::default());
    }

    #[test]
    fn every_key() {
        let m = parse_str(
            r#"
            [gyro]
            noise_density = 1e-4
            bias_instability = 2e-5
            rate_random_walk = 1e-6
            rate_ramp = 1e-8
            quantization = 1e-6
            gauss_markov = { sigma = 1e-4, tau_c = 50 }
            sinusoid = { amplitude = 1e-3, freq_hz = 30 }
            lines = [{ amplitude = 2e-3, freq_hz = 31.5, width_hz = 0.4 }, { amplitude = 1e-3, freq_hz = 7, shape = "resonance" }]
            temperature = { bias_coeff = 1e-4, scale_coeff = 2e-4, rate_coeff = 0.03 }
            bias = [0.01, 0, -0.01]
            scale_factor = [0.01, 0, 0]
            misalignment = [[0, 0.001, 0], [0, 0, 0], [0, 0, 0]]
            [accel]
            gravity_axis = "-x"
            [temperature]
            initial = 20
            warmup = { rise = 8, tau = 300 }
            ramp = 0.001
            cycle = { amplitude = 2, period = 3600 }
            reference = 25
            noise_density = 0.01
            "#,
        )
        .unwrap();
        assert_eq!(m.gyro.noise.gauss_markov.unwrap().tau_c, 50.0);
        assert_eq!(m.gyro.noise.sinusoid.unwrap().freq_hz, 30.0);
        assert_eq!(m.gyro.temperature.scale_coeff, 2e-4);
        assert_eq!(m.gyro.temperature.rate_coeff, 0.03);
        assert_eq!(
            m.gyro.lines,
            [
                NarrowBand {
                    amplitude: 2e-3,
                    freq_hz: 31.5,
                    width_hz: 0.4,
                    shape: LineShape::DiffusingPhase,
                },
                NarrowBand {
                    amplitude: 1e-3,
                    freq_hz: 7.0,
                    width_hz: 0.0,
                    shape: LineShape::Resonance,
                },
            ]
        );
        assert!(m.accel.lines.is_empty());
        assert_eq!(m.gyro.misalignment[0][1], 0.001);
        assert_eq!(m.gravity, "-x".parse().unwrap());
        assert_eq!(m.temperature.profile.warmup.unwrap().tau, 300.0);
        assert_eq!(m.temperature.noise.n, 0.01);
    }

    #[test]
    fn the_faults_table() {
        let f = parse_file(
            r#"
            [gyro]
            noise_density = 1e-4
            [faults]
            clock_ppm = 3000.0
            clock_drift_ppm_per_hour = -2.5
            i2c_outage = [{ at_s = 120.0, for_s = 2.0 }, { at_s = 60.5, for_s = 0.25 }]
            sensor_reset = [300.0, 200.000001]
            board_reset = [420.0]
            who_am_i = 0x70
            "#,
            Path::new("m.toml"),
        )
        .unwrap();
        assert_eq!(f.model.gyro.noise.n, 1e-4);
        let plan = &f.faults;
        assert_eq!(
            plan.clock,
            SensorClock {
                ppm: 3000.0,
                drift_ppm_per_hour: -2.5
            }
        );
        assert_eq!(
            plan.i2c_outages,
            [
                Outage {
                    at_us: 60_500_000,
                    for_us: 250_000
                },
                Outage {
                    at_us: 120_000_000,
                    for_us: 2_000_000
                }
            ]
        );
        assert_eq!(plan.sensor_resets_us, [200_000_001, 300_000_000]);
        assert_eq!(plan.board_resets_us, [420_000_000]);
        assert_eq!(plan.who_am_i, Some(0x70));
        assert!(!plan.is_empty());
        // Every key optional; a file without the table injects nothing.
        assert!(
            parse_file("[faults]\n", Path::new("m.toml"))
                .unwrap()
                .faults
                .is_empty()
        );
        assert!(
            parse_file("", Path::new("m.toml"))
                .unwrap()
                .faults
                .is_empty()
        );
        // `parse` checks the table and returns the model alone.
        assert!(parse_str("[faults]\nclock_ppm = 3000.0").is_ok());
        assert!(parse_str("[faults]\nclock_ppm = -1e7").is_err());
    }

    #[test]
    fn a_plan_reaches_the_sensor() {
        let plan = FaultPlan {
            clock: SensorClock {
                ppm: -10_000.0,
                drift_ppm_per_hour: 0.0,
            },
            i2c_outages: vec![Outage {
                at_us: 5,
                for_us: 10,
            }],
            sensor_resets_us: vec![3, 1],
            board_resets_us: vec![7],
            who_am_i: Some(0x70),
        };
        let mut dev = SimMpu6050::new(ImuModel::default(), 1);
        dev.schedule_reset(2);
        plan.apply_to_sensor(&mut dev);
        let faults = dev.faults();
        assert_eq!(faults.clock, plan.clock);
        assert_eq!(faults.i2c_outages, plan.i2c_outages);
        assert_eq!(faults.resets_at_us, [1, 2, 3]);
        assert_eq!(faults.who_am_i, Some(0x70));
    }

    #[test]
    fn errors_name_file_and_field() {
        let cases = [
            ("[gyro]\nnoise_densty = 1e-4", "noise_densty"),
            ("[gyro]\nnoise_density = -1", "[gyro] noise_density"),
            (
                "[accel]\ngauss_markov = { sigma = 1, tau_c = 0 }",
                "gauss_markov.tau_c",
            ),
            ("[gyro]\ngravity_axis = \"z\"", "[gyro] gravity_axis"),
            ("[accel]\ngravity_axis = \"w\"", "[accel] gravity_axis"),
            ("[temperature]\nbias = [0, 0, 0]", "[temperature] bias"),
            ("[gyro]\nramp = 1", "[gyro] ramp"),
            ("[magnetometer]\nnoise_density = 1", "magnetometer"),
            ("[gyro]\nsinusoid = { amplitude = 1 }", "freq_hz"),
            (
                "[gyro]\nlines = [{ amplitude = 1, freq_hz = 0 }]",
                "[gyro] lines.freq_hz",
            ),
            (
                "[accel]\nlines = [{ amplitude = -1, freq_hz = 3 }]",
                "[accel] lines.amplitude",
            ),
            (
                "[gyro]\nlines = [{ amplitude = 1, freq_hz = 3, shape = \"sine\" }]",
                "sine",
            ),
            ("[temperature]\nlines = []", "[temperature] lines"),
            ("[faults]\nclock_pm = 1", "clock_pm"),
            ("[faults]\nclock_ppm = -1e6", "[faults] clock_ppm"),
            ("[faults]\nclock_ppm = nan", "[faults] clock_ppm"),
            (
                "[faults]\nclock_drift_ppm_per_hour = inf",
                "[faults] clock_drift_ppm_per_hour",
            ),
            (
                "[faults]\ni2c_outage = [{ at_s = -1, for_s = 2 }]",
                "[faults] i2c_outage.at_s",
            ),
            (
                "[faults]\ni2c_outage = [{ at_s = 1, for_s = 0 }]",
                "[faults] i2c_outage.for_s",
            ),
            ("[faults]\ni2c_outage = [{ at_s = 1 }]", "for_s"),
            ("[faults]\nsensor_reset = [1, -2]", "[faults] sensor_reset"),
            ("[faults]\nboard_reset = [inf]", "[faults] board_reset"),
            ("[faults]\nwho_am_i = 256", "[faults] who_am_i"),
            ("[faults]\nwho_am_i = -1", "[faults] who_am_i"),
        ];
        for (text, needle) in cases {
            let e = parse_str(text).unwrap_err().to_string();
            assert!(e.starts_with("m.toml"), "{e}");
            assert!(e.contains(needle), "{needle}: {e}");
        }
        let e = load_file(Path::new("/nonexistent/model.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/model.toml"), "{e}");
    }
}

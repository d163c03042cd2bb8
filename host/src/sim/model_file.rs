//! The simulator's model file (TOML): one table per group, `[gyro]`, `[accel]`,
//! `[temperature]`, every key optional, SI units (u = rad/s for the gyro, m/s^2 for the
//! accelerometer, degC for the temperature; DESIGN.md, Units). Example: `examples/mpu6050.toml`.
//!
//! Noise keys (any group; in `[temperature]` they are the TEMP_OUT reading's noise):
//! `noise_density` N (u/sqrt(Hz), the Allan coefficient: two-sided density, = the Allan
//! deviation at 1 s), `bias_instability` B (u), `rate_random_walk` K (u sqrt(Hz)),
//! `rate_ramp` R (u/s), `quantization` Q (u s), `gauss_markov = { sigma, tau_c }` (u, s),
//! `sinusoid = { amplitude, freq_hz }` (u, Hz).
//!
//! `[gyro]` and `[accel]` also take `temperature = { bias_coeff, scale_coeff }` (u/degC,
//! 1/degC), `bias = [x, y, z]` (u), `scale_factor = [x, y, z]` (relative error),
//! `misalignment = [[..3], [..3], [..3]]` (added to the identity); `[accel]` takes
//! `gravity_axis = "z"` (x, y, z, -x, -y, -z; default z).
//!
//! `[temperature]` also takes the profile: `initial` (degC, default 25), `warmup = { rise,
//! tau }`, `ramp` (degC/s), `cycle = { amplitude, period }`, and `reference` (degC, default
//! 25: the temperature at which the coupling is zero).
//!
//! Unknown keys, keys in the wrong group, negative or non-finite values are errors naming the
//! file and the field.

use super::imu::{GravityAxis, ImuModel, SensorModel, TemperatureModel};
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
struct CouplingSpec {
    #[serde(default)]
    bias_coeff: f64,
    #[serde(default)]
    scale_coeff: f64,
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

/// Read and check a model file.
/// The documented example model (examples/mpu6050.toml), built in so that the demo and the
/// virtual board run anywhere.
pub const EXAMPLE: &str = include_str!("../../../examples/mpu6050.toml");

/// [`EXAMPLE`], parsed.
pub fn example() -> ImuModel {
    // The example is part of the build and tested (`the_example_model_parses`); a failure here
    // would be a broken build, so fall back to the default model rather than panic.
    parse(EXAMPLE, Path::new("examples/mpu6050.toml")).unwrap_or_default()
}

pub fn load(path: &Path) -> Result<ImuModel, ModelFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| ModelFileError::Read {
        file: path.to_owned(),
        source,
    })?;
    parse(&text, path)
}

/// Parse model-file text; `file` names it in errors.
pub fn parse(text: &str, file: &Path) -> Result<ImuModel, ModelFileError> {
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
            .map_err(|m| cx.error("accel", "gravity_axis", m))?,
        None => GravityAxis::default(),
    };
    let temperature = cx.temperature(&spec.temperature)?;
    Ok(ImuModel {
        gyro,
        accel,
        gravity,
        temperature,
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
            },
            None => TempCoupling::default(),
        };
        Ok(SensorModel {
            noise: self.noise(group, g)?,
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
        let model = super::parse(super::EXAMPLE, std::path::Path::new("example")).unwrap();
        assert_eq!(model.gyro.noise.n, 1.5e-4);
    }
    use super::*;

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
            temperature = { bias_coeff = 1e-4, scale_coeff = 2e-4 }
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
        assert_eq!(m.gyro.misalignment[0][1], 0.001);
        assert_eq!(m.gravity, "-x".parse().unwrap());
        assert_eq!(m.temperature.profile.warmup.unwrap().tau, 300.0);
        assert_eq!(m.temperature.noise.n, 0.01);
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
        ];
        for (text, needle) in cases {
            let e = parse_str(text).unwrap_err().to_string();
            assert!(e.starts_with("m.toml"), "{e}");
            assert!(e.contains(needle), "{needle}: {e}");
        }
        let e = load(Path::new("/nonexistent/model.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/model.toml"), "{e}");
    }
}

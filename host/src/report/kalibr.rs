//! Kalibr's IMU noise parameters (the `imu.yaml` of kalibr_calibrate_imu_camera), from the
//! fitted IEEE-952 terms. Kalibr's IMU noise model (github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model):
//! - `gyroscope_noise_density` = N of the gyro, rad/s/sqrt(Hz) (continuous-time white noise:
//!   the Allan deviation at tau = 1 s on the -1/2 line);
//! - `gyroscope_random_walk` = K of the gyro, rad/s^2/sqrt(Hz) (bias random walk);
//! - `accelerometer_noise_density` = N of the accelerometer, m/s^2/sqrt(Hz);
//! - `accelerometer_random_walk` = K of the accelerometer, m/s^3/sqrt(Hz).
//!
//! Kalibr takes one number per sensor: we give the largest over the sensor's axes. Where the
//! fit finds no random walk in the record (K = 0), the upper end of its interval is used and
//! the YAML says so, since Kalibr needs a non-zero value.

use crate::analysis::fit::Term;
use crate::analysis::pipeline::ChannelResult;
use crate::analysis::units::{KalibrNoise, SensorKind};
use crate::record::Record;
use serde::Serialize;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KalibrNumbers {
    #[serde(flatten)]
    pub noise: KalibrNoise,
    /// Which numbers are upper bounds (random walk not resolved in the record).
    pub upper_bounds: Vec<&'static str>,
    /// How each number was taken from the axes.
    pub rule: &'static str,
}

/// What the record lacks for Kalibr's numbers: channels of a sensor with a noise fit.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("Kalibr needs {sensor} channels with a noise fit; the record has {channels}")]
pub struct KalibrError {
    /// `gyroscope` or `accelerometer`.
    pub sensor: &'static str,
    /// The record's channels, comma-separated.
    pub channels: String,
}

/// The four numbers, or an error naming what the record lacks.
pub fn numbers(results: &[ChannelResult]) -> Result<KalibrNumbers, KalibrError> {
    let mut upper_bounds = Vec::new();
    let (gn, gk) = sensor(results, SensorKind::Gyro, "gyroscope", &mut upper_bounds)?;
    let (an, ak) = sensor(
        results,
        SensorKind::Accel,
        "accelerometer",
        &mut upper_bounds,
    )?;
    Ok(KalibrNumbers {
        noise: KalibrNoise::from_terms(gn, gk, an, ak),
        upper_bounds,
        rule: "largest over the sensor's axes",
    })
}

/// (N, K) of one sensor: the largest over its fitted axes.
fn sensor(
    results: &[ChannelResult],
    kind: SensorKind,
    label: &'static str,
    upper_bounds: &mut Vec<&'static str>,
) -> Result<(f64, f64), KalibrError> {
    let fits: Vec<_> = results
        .iter()
        .filter(|r| r.kind == kind)
        .filter_map(|r| r.fit.as_ref().ok())
        .collect();
    if fits.is_empty() {
        return Err(KalibrError {
            sensor: label,
            channels: results
                .iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    let n = fits.iter().map(|f| f.n.value).fold(0.0, f64::max);
    let k = fits.iter().map(|f| f.k.value).fold(0.0, f64::max);
    if k > 0.0 {
        return Ok((n, k));
    }
    upper_bounds.push(if kind == SensorKind::Gyro {
        "gyroscope_random_walk"
    } else {
        "accelerometer_random_walk"
    });
    let bound = fits.iter().map(|f| upper(&f.k)).fold(0.0, f64::max);
    Ok((n, bound))
}

fn upper(t: &Term) -> f64 {
    t.hi.max(t.value)
}

/// The YAML file Kalibr reads, with each number's definition as a comment.
pub fn yaml(record: &Record, results: &[ChannelResult]) -> Result<String, KalibrError> {
    let numbers = numbers(results)?;
    let (k, noise) = (&numbers, &numbers.noise);
    let bound = |name: &str| {
        if k.upper_bounds.contains(&name) {
            "  (upper bound: no random walk resolved in this record)"
        } else {
            ""
        }
    };
    Ok(format!(
        "# IMU noise parameters for Kalibr, from imunoise {version} (IEEE-952 fit to the overlapping\n\
         # Allan variance of {source}, {samples} samples at {rate} Hz); {rule}.\n\
         # Definitions: github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model\n\
         #Accelerometers\n\
         accelerometer_noise_density: {an}  # [m/s^2/sqrt(Hz)] continuous-time white noise (N)\n\
         accelerometer_random_walk: {ak}  # [m/s^3/sqrt(Hz)] bias random walk (K){akb}\n\
         #Gyroscopes\n\
         gyroscope_noise_density: {gn}  # [rad/s/sqrt(Hz)] continuous-time white noise (N)\n\
         gyroscope_random_walk: {gk}  # [rad/s^2/sqrt(Hz)] bias random walk (K){gkb}\n\
         rostopic: /imu0  # the IMU's ROS topic: edit to match your bag\n\
         update_rate: {rate}  # [Hz]\n",
        version = env!("CARGO_PKG_VERSION"),
        source = record.source,
        samples = super::samples(record, results),
        rate = record.rate_hz,
        rule = k.rule,
        an = yaml_float(noise.accelerometer_noise_density),
        ak = yaml_float(noise.accelerometer_random_walk),
        gn = yaml_float(noise.gyroscope_noise_density),
        gk = yaml_float(noise.gyroscope_random_walk),
        akb = bound("accelerometer_random_walk"),
        gkb = bound("gyroscope_random_walk"),
    ))
}

/// A float YAML 1.1 readers (PyYAML, which Kalibr uses) parse as a float: scientific notation
/// with a decimal point and a signed exponent, e.g. `1.2340e-04`.
fn yaml_float(x: f64) -> String {
    let text = format!("{x:.4e}");
    match text.split_once('e') {
        Some((mantissa, exp)) if !exp.starts_with('-') => format!("{mantissa}e+{exp:0>2}"),
        Some((mantissa, exp)) => format!("{mantissa}e-{:0>2}", &exp[1..]),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::yaml_float;

    #[test]
    fn floats_are_yaml_floats() {
        assert_eq!(yaml_float(1.234e-4), "1.2340e-04");
        assert_eq!(yaml_float(2.5), "2.5000e+00");
        assert_eq!(yaml_float(0.0), "0.0000e+00");
        assert_eq!(yaml_float(3.0e12), "3.0000e+12");
    }
}

//! Bias against the die temperature (TEMP_OUT), from a warm-up or cool-down record at rest:
//!
//! ```text
//!   f(T) = c0 + c1 (T - T_ref) + c2 (T - T_ref)^2        (c2 = 0 unless justified)
//! ```
//!
//! T_ref is the record's mean temperature (centring keeps the columns well conditioned).
//! The samples are first averaged over 1 s blocks: a block mean of the sensor's white noise is
//! independent of the next, which the F-test below assumes, and the fit becomes cheap.
//!
//! **The rule for quadratic.** Fit both; keep the quadratic if the extra-sum-of-squares F
//! statistic `F = (RSS_lin - RSS_quad) / (RSS_quad / (n - 3))` exceeds the 99th percentile
//! of F(1, n - 3) (p < 0.01; n the number of blocks). Bias instability and rate random walk
//! correlate neighbouring blocks, which makes the test accept curvature somewhat too easily;
//! the residual RMS printed with the fit shows how much is left either way.
//!
//! Only the bias's dependence is modelled (c1, c2): the constant c0 of a static record also
//! holds gravity on the accelerometer's vertical axis, so a correction uses the shape, moved
//! to the bias a calibration measured at its own temperature ([`TemperatureModel::shift`]).
//! On the vertical axis of the accelerometer the fitted slope also holds the scale factor's
//! temperature change times g.

use super::{Sensor, Vec3};
use crate::analysis::numerics::householder_solve;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// Significance of the F-test that admits the quadratic term.
pub const QUADRATIC_P: f64 = 0.01;

/// Block length for the fit, s.
pub const BLOCK_S: f64 = 1.0;

/// Smallest temperature span, degC, over which a slope is worth fitting.
pub const MIN_SPAN_C: f64 = 0.5;

/// One axis's fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AxisFit {
    pub c0: f64,
    /// u/degC.
    pub c1: f64,
    /// u/degC^2 (0 when linear).
    pub c2: f64,
    pub quadratic: bool,
    /// The F statistic of the quadratic term and its p-value.
    pub f_statistic: f64,
    pub p_value: f64,
    /// RMS of the block means about the chosen fit, u.
    pub residual_rms: f64,
}

/// A sensor's temperature model: what a correction applies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureModel {
    pub sensor: Sensor,
    /// T_ref, degC.
    pub reference_c: f64,
    /// Temperatures covered by the record, degC: the model is not trusted outside.
    pub min_c: f64,
    pub max_c: f64,
    pub blocks: usize,
    pub axes: [AxisFit; 3],
}

impl TemperatureModel {
    /// c1 d + c2 d^2 per axis at `temp_c` (d = T - T_ref): the bias's temperature part.
    pub fn bias_at(&self, temp_c: f64) -> Vec3 {
        let d = temp_c - self.reference_c;
        self.axes.map(|a| a.c1 * d + a.c2 * d * d)
    }

    /// The bias change from `from_c` (where a calibration measured the bias) to `to_c`.
    pub fn shift(&self, from_c: f64, to_c: f64) -> Vec3 {
        let (a, b) = (self.bias_at(to_c), self.bias_at(from_c));
        [0, 1, 2].map(|i| a[i] - b[i])
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TemperatureFitError {
    #[error(
        "the record is {seconds:.1} s long: a temperature fit needs at least 10 s (10 blocks of 1 s)"
    )]
    TooShort { seconds: f64 },
    #[error(
        "the temperature changes by only {span:.2} degC ({min:.2} to {max:.2} degC): a warm-up or cool-down record spanning at least 0.5 degC is needed"
    )]
    NoSpan { span: f64, min: f64, max: f64 },
}

/// Fit `sensor`'s three axes (`values`, u) against `temp` (degC), sampled at `rate_hz`.
pub fn fit(
    sensor: Sensor,
    temp: &[f64],
    values: [&[f64]; 3],
    rate_hz: f64,
) -> Result<TemperatureModel, TemperatureFitError> {
    let block = ((rate_hz * BLOCK_S).round() as usize).max(1);
    let t = block_means(temp, block);
    if t.len() < 10 {
        return Err(TemperatureFitError::TooShort {
            seconds: temp.len() as f64 / rate_hz,
        });
    }
    let (min, max) = t
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    if max - min < MIN_SPAN_C {
        return Err(TemperatureFitError::NoSpan {
            span: max - min,
            min,
            max,
        });
    }
    let reference_c = t.iter().sum::<f64>() / t.len() as f64;
    let d: Vec<f64> = t.iter().map(|x| x - reference_c).collect();
    let axes = values.map(|v| fit_axis(&d, &block_means(v, block)));
    Ok(TemperatureModel {
        sensor,
        reference_c,
        min_c: min,
        max_c: max,
        blocks: t.len(),
        axes,
    })
}

/// Linear and quadratic fits of `y` on the centred temperatures `d`, and the F-test between
/// them (module documentation).
fn fit_axis(d: &[f64], y: &[f64]) -> AxisFit {
    let n = d.len().min(y.len());
    let (lin, rss_lin) = poly_fit(&d[..n], &y[..n], 1);
    let (quad, rss_quad) = poly_fit(&d[..n], &y[..n], 2);
    let dof = (n - 3) as f64;
    let f_statistic = if rss_quad > 0.0 {
        (rss_lin - rss_quad).max(0.0) / (rss_quad / dof)
    } else {
        f64::INFINITY
    };
    let p_value = FisherSnedecor::new(1.0, dof)
        .map(|f| 1.0 - f.cdf(f_statistic))
        .unwrap_or(f64::NAN);
    let quadratic = p_value < QUADRATIC_P;
    let (c, rss) = if quadratic {
        (quad, rss_quad)
    } else {
        (vec![lin[0], lin[1], 0.0], rss_lin)
    };
    AxisFit {
        c0: c[0],
        c1: c[1],
        c2: c[2],
        quadratic,
        f_statistic,
        p_value,
        residual_rms: (rss / n as f64).sqrt(),
    }
}

/// Least-squares polynomial of `order` in d: coefficients (constant first) and the residual
/// sum of squares.
fn poly_fit(d: &[f64], y: &[f64], order: usize) -> (Vec<f64>, f64) {
    let mut rows: Vec<Vec<f64>> = d
        .iter()
        .map(|&x| (0..=order).map(|k| x.powi(k as i32)).collect())
        .collect();
    let mut rhs = y.to_vec();
    let c = householder_solve(&mut rows, &mut rhs);
    let rss = d
        .iter()
        .zip(y)
        .map(|(&x, &v)| {
            let model: f64 = c
                .iter()
                .enumerate()
                .map(|(k, ck)| ck * x.powi(k as i32))
                .sum();
            (v - model).powi(2)
        })
        .sum();
    (c, rss)
}

/// Means of consecutive blocks of `len` samples (a short last block is left out).
fn block_means(x: &[f64], len: usize) -> Vec<f64> {
    x.chunks_exact(len)
        .map(|c| c.iter().sum::<f64>() / len as f64)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// 30 min at 50 Hz of a warm-up (25 -> 31 degC, tau 600 s), each axis c0 + c1 d + c2 d^2
    /// plus white noise of 0.002 per sample.
    fn record(c: [(f64, f64, f64); 3], seed: u64) -> (Vec<f64>, [Vec<f64>; 3]) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.002).unwrap();
        let n = 50 * 1800;
        let temp: Vec<f64> = (0..n)
            .map(|i| 25.0 + 6.0 * (1.0 - (-(i as f64 / 50.0) / 600.0).exp()))
            .collect();
        let values = c.map(|(c0, c1, c2)| {
            temp.iter()
                .map(|&t| {
                    let d = t - 25.0;
                    c0 + c1 * d + c2 * d * d + noise.sample(&mut rng)
                })
                .collect()
        });
        (temp, values)
    }

    #[test]
    fn recovers_linear_and_admits_quadratic_only_when_there() {
        let truth = [(0.02, 1e-4, 0.0), (-0.01, -2e-4, 0.0), (0.005, 1e-4, 2e-5)];
        let (temp, v) = record(truth, 5);
        let m = fit(Sensor::Gyro, &temp, [&v[0], &v[1], &v[2]], 50.0).unwrap();
        assert_eq!(m.blocks, 1800);
        assert!((m.min_c - 25.0).abs() < 0.01 && (m.max_c - 30.7).abs() < 0.01);
        // Slope standard error: block noise 0.002 / sqrt(50) = 2.8e-4 over 1800 blocks whose
        // temperatures spread by sd ~1.6 degC: 2.8e-4 / (sqrt(1800) 1.6) = 4.2e-6; 4 sigma.
        for (axis, (_, c1, c2)) in m.axes.iter().zip(truth) {
            // The slope at T_ref of the true curve (T_ref is not 25 degC).
            let slope = c1 + 2.0 * c2 * (m.reference_c - 25.0);
            assert!((axis.c1 - slope).abs() < 1.7e-5, "{axis:?}");
            assert_eq!(axis.quadratic, c2 != 0.0, "{axis:?}");
            // The residual is the block noise, 2.8e-4.
            assert!((axis.residual_rms / 2.83e-4 - 1.0).abs() < 0.1, "{axis:?}");
        }
        // c2's standard error: the block noise over the part of d^2 the linear terms do not
        // explain, 2.83e-4 / sqrt(RSS of d^2 on [1, d]); 4 sigma.
        let d: Vec<f64> = block_means(&temp, 50)
            .iter()
            .map(|t| t - m.reference_c)
            .collect();
        let d2: Vec<f64> = d.iter().map(|x| x * x).collect();
        let se = 2.83e-4 / poly_fit(&d, &d2, 1).1.sqrt();
        assert!(
            (m.axes[2].c2 - 2e-5).abs() < 4.0 * se,
            "{:?} se {se}",
            m.axes[2]
        );
        // The model's shift between two temperatures is the true curve's.
        let s = m.shift(26.0, 30.0);
        assert!((s[0] - 4e-4).abs() < 6e-5, "{s:?}");
    }

    #[test]
    fn constant_temperature_or_short_record_is_refused() {
        let temp = vec![25.0; 5000];
        let v = vec![0.0; 5000];
        let err = fit(Sensor::Gyro, &temp, [&v, &v, &v], 100.0).unwrap_err();
        assert!(err.to_string().contains("warm-up"), "{err}");
        let err = fit(Sensor::Gyro, &temp[..500], [&v, &v, &v], 100.0).unwrap_err();
        assert!(matches!(err, TemperatureFitError::TooShort { .. }), "{err}");
    }
}

//! The deterministic fits: per-axis two-point (accelerometer up/down, gyro clockwise and
//! anticlockwise) and the least-squares fit of the whole `f_meas = K f_true + b` from known
//! inputs (six positions, a rate table).

use super::{Correction, Mat3, Sensor, Vec3, identity};
use crate::analysis::numerics::householder_solve;
use serde::Serialize;

/// One axis from two opposite inputs of known magnitude m (the reading with the axis along
/// +m and along -m), as in the settings study (docs/references.md):
///
/// ```text
///   bias = (f_up + f_down) / 2        scale factor = (f_up - f_down - 2 m) / (2 m)
/// ```
///
/// (from f_up = (1 + s) m + b and f_down = -(1 + s) m + b). For the accelerometer m is local
/// gravity; for a rate table the commanded rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TwoPoint {
    pub plus: f64,
    pub minus: f64,
    pub magnitude: f64,
    pub bias: f64,
    pub scale_factor: f64,
}

pub fn two_point(plus: f64, minus: f64, magnitude: f64) -> TwoPoint {
    TwoPoint {
        plus,
        minus,
        magnitude,
        bias: (plus + minus) / 2.0,
        scale_factor: (plus - minus - 2.0 * magnitude) / (2.0 * magnitude),
    }
}

/// One known input and the mean reading it gave.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Observation {
    /// A label for reports: "+x up", "z +100 deg/s".
    pub label: String,
    pub truth: Vec3,
    pub measured: Vec3,
}

/// The least-squares K and b, with what is left of each observation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinearFit {
    pub correction: Correction,
    /// measured - (K truth + b) per observation, in the sensor's unit.
    pub residuals: Vec<Vec3>,
    /// RMS of all residual components.
    pub residual_rms: f64,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FitError {
    #[error("{0} observation(s): the fit of K and b needs at least 4 (e.g. the six positions)")]
    TooFew(usize),
    #[error(
        "the known inputs do not span all three axes (every axis needs a + and a - position or rate)"
    )]
    Degenerate,
}

/// Solve `measured = K truth + b` for the 12 unknowns (each output axis i separately:
/// measured_i = sum_j K_ij truth_j + b_i, 4 unknowns, one equation per observation) by
/// Householder QR. With the six positions +-g on each axis this is the classic six-position
/// calibration; with more observations (a rate table with several rates) the same fit.
pub fn fit_linear(
    sensor: Sensor,
    observations: &[Observation],
    temperature_c: f64,
) -> Result<LinearFit, FitError> {
    if observations.len() < 4 {
        return Err(FitError::TooFew(observations.len()));
    }
    if !spans_three_axes(observations) {
        return Err(FitError::Degenerate);
    }
    let mut matrix = identity();
    let mut bias = [0.0; 3];
    for i in 0..3 {
        let mut rows: Vec<Vec<f64>> = observations
            .iter()
            .map(|o| vec![o.truth[0], o.truth[1], o.truth[2], 1.0])
            .collect();
        let mut y: Vec<f64> = observations.iter().map(|o| o.measured[i]).collect();
        let x = householder_solve(&mut rows, &mut y);
        matrix[i] = [x[0], x[1], x[2]];
        bias[i] = x[3];
    }
    let correction = Correction {
        sensor,
        bias,
        matrix: Some(matrix),
        temperature_c,
    };
    let residuals: Vec<Vec3> = observations
        .iter()
        .map(|o| {
            let model = apply_forward(&correction.k(), correction.bias, o.truth);
            [0, 1, 2].map(|i| o.measured[i] - model[i])
        })
        .collect();
    let n = (3 * residuals.len()) as f64;
    let residual_rms = (residuals.iter().flatten().map(|r| r * r).sum::<f64>() / n).sqrt();
    Ok(LinearFit {
        correction,
        residuals,
        residual_rms,
    })
}

/// K truth + b.
pub fn apply_forward(k: &Mat3, b: Vec3, truth: Vec3) -> Vec3 {
    [0, 1, 2].map(|i| (0..3).map(|j| k[i][j] * truth[j]).sum::<f64>() + b[i])
}

/// Whether the inputs, with a constant column, determine K and b: the centred inputs'
/// scatter matrix must be well conditioned (its determinant not negligible against the
/// product of its diagonal).
fn spans_three_axes(observations: &[Observation]) -> bool {
    let n = observations.len() as f64;
    let mean = [0, 1, 2].map(|j| observations.iter().map(|o| o.truth[j]).sum::<f64>() / n);
    let mut s = [[0.0; 3]; 3];
    for o in observations {
        for (i, row) in s.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += (o.truth[i] - mean[i]) * (o.truth[j] - mean[j]);
            }
        }
    }
    let det = s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1])
        - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
        + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]);
    let diag = s[0][0] * s[1][1] * s[2][2];
    diag > 0.0 && det > 1e-6 * diag
}

/// The six static positions: `axis` up (+g on it) or down.
pub fn six_positions() -> [(usize, bool); 6] {
    [
        (0, false),
        (0, true),
        (1, false),
        (1, true),
        (2, false),
        (2, true),
    ]
}

/// "+x", "-z".
pub fn axis_label(axis: usize, negative: bool) -> String {
    format!("{}{}", if negative { '-' } else { '+' }, super::AXES[axis])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth_k() -> Mat3 {
        [
            [1.01, 0.002, -0.001],
            [0.001, 0.995, 0.002],
            [-0.002, 0.001, 1.0],
        ]
    }

    #[test]
    fn two_point_inverts_the_paper_model() {
        // f = (1 + s) m + b with s = 0.004, b = 0.2, m = 9.8.
        let (s, b, m) = (0.004, 0.2, 9.8);
        let t = two_point((1.0 + s) * m + b, -(1.0 + s) * m + b, m);
        assert!((t.bias - b).abs() < 1e-12);
        assert!((t.scale_factor - s).abs() < 1e-12);
    }

    #[test]
    fn six_positions_recover_k_and_b_exactly_without_noise() {
        let (k, b, g) = (truth_k(), [0.2, -0.1, 0.3], 9.80665);
        let obs: Vec<Observation> = six_positions()
            .iter()
            .map(|&(axis, neg)| {
                let mut truth = [0.0; 3];
                truth[axis] = if neg { -g } else { g };
                Observation {
                    label: axis_label(axis, neg),
                    truth,
                    measured: apply_forward(&k, b, truth),
                }
            })
            .collect();
        let fit = fit_linear(Sensor::Accel, &obs, 25.0).unwrap();
        for i in 0..3 {
            assert!((fit.correction.bias[i] - b[i]).abs() < 1e-12);
            for (got, want) in fit.correction.k()[i].iter().zip(k[i]) {
                assert!((got - want).abs() < 1e-12);
            }
        }
        assert!(fit.residual_rms < 1e-12);
        assert!((fit.correction.scale_factors().unwrap()[0] - 0.01).abs() < 1e-12);
        assert_eq!(fit.correction.misalignment().unwrap()[1][1], 0.0);
        // The correction inverts the model.
        let back = fit
            .correction
            .correct(apply_forward(&k, b, [1.0, 2.0, 3.0]), [0.0; 3])
            .unwrap();
        assert!(
            back.iter()
                .zip([1.0, 2.0, 3.0])
                .all(|(a, b)| (a - b).abs() < 1e-12)
        );
    }

    #[test]
    fn too_few_or_one_axis_only_is_refused() {
        let obs = |truths: &[Vec3]| -> Vec<Observation> {
            truths
                .iter()
                .map(|&truth| Observation {
                    label: String::new(),
                    truth,
                    measured: truth,
                })
                .collect()
        };
        assert_eq!(
            fit_linear(Sensor::Gyro, &obs(&[[1.0, 0.0, 0.0]]), 25.0),
            Err(FitError::TooFew(1))
        );
        let z_only = obs(&[
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.0, 0.0, 2.0],
            [0.0, 0.0, -2.0],
        ]);
        assert_eq!(
            fit_linear(Sensor::Gyro, &z_only, 25.0),
            Err(FitError::Degenerate)
        );
    }
}

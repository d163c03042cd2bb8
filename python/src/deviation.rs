//! One Allan-family curve for the allantools-compatible functions
//! (python/imunoise/allantools.py), at the averaging factors the Python layer chose by
//! allantools' rules.

use crate::{Array, check_rate, samples, value_error};
use imunoise::analysis::{Estimator, allan, phase_from_rate};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// The factors kept, the deviations and the number of terms summed at each, for `estimator`
/// on `data` (phase, or rate when `phase` is false, sampled at `rate` Hz).
///
/// Rate data become N + 1 phase points (`analysis::phase_from_rate`, allantools'
/// `frequency2phase`). Totdev runs on the whole reflected extension (m up to N - 1), as
/// allantools' does. Factors without a term are left out.
#[pyfunction]
pub fn deviation<'py>(
    py: Python<'py>,
    estimator: &str,
    data: PyReadonlyArray1<'py, f64>,
    rate: f64,
    phase: bool,
    factors: Vec<usize>,
) -> PyResult<(Array<'py, usize>, Array<'py>, Array<'py, usize>)> {
    let est: Estimator = estimator.parse().map_err(value_error)?;
    check_rate(rate)?;
    let y = samples(&data, "data")?;
    let curve = py.detach(|| {
        if let Some(index) = y.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "data[{index}] is {}: the samples must be finite",
                y[index]
            ));
        }
        let tau0 = 1.0 / rate;
        let owned;
        let x = if phase {
            y
        } else {
            owned = phase_from_rate(y, tau0);
            &owned[..]
        };
        Ok(match est {
            Estimator::Totdev => allan::totdev_whole_extension(x, tau0, &factors),
            _ => allan::deviation(est, x, tau0, &factors),
        })
    });
    let curve = curve.map_err(value_error)?;
    Ok((
        PyArray1::from_vec(py, curve.m),
        PyArray1::from_vec(py, curve.dev),
        PyArray1::from_vec(py, curve.n),
    ))
}

//! Welch's one-sided PSD of one array (`analysis::psd::welch`, scipy.signal.welch's
//! definition).

use crate::analysis::segment_len;
use crate::{Array, check_rate, samples, value_error};
use imunoise::analysis::psd::{WelchOptions, Window, welch};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

/// Frequencies (Hz) and one-sided density (u²/Hz) of `data` sampled at `rate` Hz, with
/// `segment` samples per segment (0 chooses it from the length) and `window`.
#[pyfunction]
#[pyo3(signature = (data, rate, segment=0, window="hann"))]
pub fn psd<'py>(
    py: Python<'py>,
    data: PyReadonlyArray1<'py, f64>,
    rate: f64,
    segment: i64,
    window: &str,
) -> PyResult<(Array<'py>, Array<'py>)> {
    check_rate(rate)?;
    let window: Window = window.parse().map_err(value_error)?;
    let y = samples(&data, "data")?;
    // 0 asks for the length chosen from the record's.
    let segment_len = match segment {
        0 => 0,
        _ => segment_len(segment, y.len(), "segment")?,
    };
    let options = WelchOptions {
        segment_len,
        window,
        ..WelchOptions::default()
    };
    let spectrum = py
        .detach(|| welch(y, rate, &options))
        .map_err(value_error)?;
    Ok((
        PyArray1::from_vec(py, spectrum.freq),
        PyArray1::from_vec(py, spectrum.density),
    ))
}

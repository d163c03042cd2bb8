//! `imunoise._imunoise`: the extension module under the `imunoise` Python package. The
//! package's Python layer (python/imunoise/) takes the user's arrays and keywords, checks
//! them, and calls these functions with contiguous float64 arrays; each function borrows
//! the array's memory (no copy), releases the GIL for the computation, and turns the
//! library's errors into `ValueError`s that carry its message.

use pyo3::prelude::*;

mod analysis;
mod deviation;
mod input;
mod model;
mod spectrum;

/// The module's functions; their Python-facing documentation is in python/imunoise/.
#[pymodule]
fn _imunoise(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(deviation::deviation, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::analyze, m)?)?;
    m.add_function(wrap_pyfunction!(model::model, m)?)?;
    m.add_function(wrap_pyfunction!(spectrum::psd, m)?)?;
    m.add_function(wrap_pyfunction!(input::load, m)?)?;
    m.add_function(wrap_pyfunction!(input::load_session, m)?)?;
    m.add("VERSION", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

/// A numpy array handed to Python (float64 unless said).
type Array<'py, T = f64> = Bound<'py, numpy::PyArray1<T>>;

/// A `ValueError` with `message`.
fn value_error(message: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(message.to_string())
}

/// The samples of a one-dimensional float64 array, borrowed; `what` names it in the error
/// for an array that is not contiguous (the Python layer hands over contiguous ones).
fn samples<'a>(array: &'a numpy::PyReadonlyArray1<'_, f64>, what: &str) -> PyResult<&'a [f64]> {
    array
        .as_slice()
        .map_err(|e| value_error(format!("{what}: {e}")))
}

/// A sample rate that is a positive, finite number of hertz.
fn check_rate(rate: f64) -> PyResult<()> {
    if rate.is_finite() && rate > 0.0 {
        Ok(())
    } else {
        Err(value_error(format!(
            "rate {rate}: the sample rate must be a positive, finite number of Hz"
        )))
    }
}

/// An error and its sources, joined by ": " (the library's errors name the file, line or
/// field in their own message and the cause in their source); a source whose text the
/// message already holds is not repeated.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let part = s.to_string();
        if !text.contains(&part) {
            text.push_str(": ");
            text.push_str(&part);
        }
        source = s.source();
    }
    text
}

//! Records from files (`input::load`: captures, text tables, NumPy arrays, gzipped or not,
//! ROS bags) and from a session store (`store::load_session`).

use crate::error_chain;
use imunoise::input::{self, LoadOptions, Loaded};
use imunoise::store::{self, Store};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::path::PathBuf;

/// What the Python layer makes a `Record` of: the channels' names and samples, the rate in
/// Hz, where it came from, the sensor settings (JSON, a capture's), the reader's notes and
/// how the file was read (JSON).
type Loaded4Py<'py> = (
    Vec<String>,
    Vec<crate::Array<'py>>,
    f64,
    String,
    Option<String>,
    Vec<String>,
    String,
);

/// The record in the file at `path`.
#[pyfunction]
#[pyo3(signature = (
    path, *, rate=None, names=None, ignore_time=false, longest_run=false, topic=None
))]
pub fn load<'py>(
    py: Python<'py>,
    path: PathBuf,
    rate: Option<f64>,
    names: Option<Vec<String>>,
    ignore_time: bool,
    longest_run: bool,
    topic: Option<String>,
) -> PyResult<Loaded4Py<'py>> {
    let options = load_options(rate, names, ignore_time, longest_run, topic);
    let loaded = py
        .detach(|| input::load(&path, &options))
        .map_err(|e| os_or_value_error(&e))?;
    hand_over(py, loaded)
}

/// The record of the stored session `key` (its id or name) in the store at `store` (default:
/// `$IMUNOISE_STORE`, else the platform data directory).
#[pyfunction]
#[pyo3(signature = (
    key, *, store=None, rate=None, names=None, ignore_time=false, longest_run=false, topic=None
))]
#[allow(clippy::too_many_arguments)] // the keywords of `imunoise analyze SESSION`
pub fn load_session<'py>(
    py: Python<'py>,
    key: &str,
    store: Option<PathBuf>,
    rate: Option<f64>,
    names: Option<Vec<String>>,
    ignore_time: bool,
    longest_run: bool,
    topic: Option<String>,
) -> PyResult<Loaded4Py<'py>> {
    let options = load_options(rate, names, ignore_time, longest_run, topic);
    let loaded = py
        .detach(|| -> Result<Loaded, String> {
            let dir = store::locate(store.as_deref()).map_err(|e| error_chain(&e))?;
            let store = Store::open_existing(&dir).map_err(|e| error_chain(&e))?;
            let session = store.find(key).map_err(|e| error_chain(&e))?;
            store::load_session(&session, &options).map_err(|e| error_chain(&e))
        })
        .map_err(crate::value_error)?;
    hand_over(py, loaded)
}

fn load_options(
    rate: Option<f64>,
    names: Option<Vec<String>>,
    ignore_time: bool,
    longest_run: bool,
    topic: Option<String>,
) -> LoadOptions {
    LoadOptions {
        rate_hz: rate,
        ignore_time,
        names: names.unwrap_or_default(),
        longest_run,
        topic,
        ..LoadOptions::default()
    }
}

/// A missing or unreadable file is an `OSError`, anything wrong inside it a `ValueError`.
fn os_or_value_error(e: &input::InputError) -> PyErr {
    match e {
        input::InputError::Io { .. } => pyo3::exceptions::PyOSError::new_err(error_chain(e)),
        _ => crate::value_error(error_chain(e)),
    }
}

/// The loaded record's parts for the Python layer; the channels' samples move into numpy
/// arrays without a copy.
fn hand_over(py: Python<'_>, loaded: Loaded) -> PyResult<Loaded4Py<'_>> {
    let Loaded {
        record,
        notes,
        settings,
        report,
    } = loaded;
    let settings = settings
        .map(|s| serde_json::to_string(&s))
        .transpose()
        .map_err(crate::value_error)?;
    let report = serde_json::to_string(&report).map_err(crate::value_error)?;
    let (names, columns) = record
        .channels
        .into_iter()
        .map(|c| (c.name, PyArray1::from_vec(py, c.values)))
        .unzip();
    Ok((
        names,
        columns,
        record.rate_hz,
        record.source,
        settings,
        notes,
        report,
    ))
}

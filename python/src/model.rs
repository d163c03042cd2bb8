//! The model workflow on one channel (`model::run`): fit, simulate, compare, name the
//! missing effect, refit; returned as the document `imunoise model --json` writes.

use crate::analysis::{parse_bandwidth, record, sensor_settings};
use crate::{check_rate, value_error};
use imunoise::analysis::pipeline::LowPassChoice;
use imunoise::model::{Settings, report, run};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;

/// The model document (JSON text) for channel `column` (default: the first gyro channel, else
/// the first accelerometer channel, else the only other channel) of
/// the record `names`/`columns` at `rate` Hz, with `temp_column` as its temperature.
#[pyfunction]
#[pyo3(signature = (
    names, columns, rate, *, column=None, temp_column=None, seed=1, realisations=24,
    bandwidth=None, settings=None, source="arrays"
))]
#[allow(clippy::too_many_arguments)]
pub fn model(
    py: Python<'_>,
    names: Vec<String>,
    columns: Vec<PyReadonlyArray1<'_, f64>>,
    rate: f64,
    column: Option<&str>,
    temp_column: Option<&str>,
    seed: u64,
    realisations: usize,
    bandwidth: Option<String>,
    settings: Option<&str>,
    source: &str,
) -> PyResult<String> {
    check_rate(rate)?;
    if realisations < 2 {
        return Err(value_error(format!(
            "realisations {realisations}: at least 2 simulated realisations per model"
        )));
    }
    let settings = Settings {
        realisations,
        seed,
        low_pass: LowPassChoice::chosen(parse_bandwidth(bandwidth)?, sensor_settings(settings)?),
    };
    let record = record(names, &columns, rate, source)?;
    py.detach(|| {
        let outcome = run(&record, column, temp_column, &settings)
            .map_err(|e| format!("{}: {}", record.source, crate::error_chain(&e)))?;
        serde_json::to_string(&report::document(&outcome)).map_err(|e| e.to_string())
    })
    .map_err(value_error)
}

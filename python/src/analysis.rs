//! The whole analysis of a record (`analysis::pipeline::analyze_taking`), returned as the JSON
//! document `imunoise analyze --json` writes, with the filter numbers when a filter period
//! is given and Kalibr's YAML.

use crate::{check_rate, error_chain, samples, value_error};
use imunoise::analysis::pipeline::{self, Bandwidth, KnownFilters, Request};
use imunoise::analysis::{DataType, Estimator, filter};
use imunoise::record::{Channel, Record};
use imunoise::report;
use numpy::PyReadonlyArray1;
use protocol::mpu6050::SensorSettings;
use pyo3::prelude::*;

/// The analysis document (JSON text) of the channels `names` with samples `columns` at
/// `rate` Hz, and Kalibr's IMU YAML, or `None` and why there is none. The keywords are `imunoise
/// analyze`'s options; `settings` (JSON) are the sensor settings a capture states, `input`
/// (JSON) how a file was read, `source` where the record came from.
#[pyfunction]
#[pyo3(signature = (
    names, columns, rate, *, data_type="rate", estimators=None, taus="per-decade:10",
    confidence=0.683, fit_tau_min=None, bandwidth=None, psd_segment=None, psd_window="hann",
    filter_period=None, settings=None, input=None, source="arrays"
))]
#[allow(clippy::too_many_arguments)]
pub fn analyze(
    py: Python<'_>,
    names: Vec<String>,
    columns: Vec<PyReadonlyArray1<'_, f64>>,
    rate: f64,
    data_type: &str,
    estimators: Option<Vec<String>>,
    taus: &str,
    confidence: f64,
    fit_tau_min: Option<f64>,
    bandwidth: Option<String>,
    psd_segment: Option<i64>,
    psd_window: &str,
    filter_period: Option<f64>,
    settings: Option<&str>,
    input: Option<&str>,
    source: &str,
) -> PyResult<(String, Option<String>, Option<String>)> {
    check_rate(rate)?;
    let mut record = record(names, &columns, rate, source)?;
    let psd_segment = psd_segment
        .map(|segment| segment_len(segment, record.len(), "psd_segment"))
        .transpose()?;
    let request = Request {
        data_type: match data_type {
            "rate" | "freq" => DataType::Rate,
            "phase" => DataType::Phase,
            other => {
                return Err(value_error(format!(
                    "data_type '{other}': 'rate' (or allantools' 'freq') or 'phase'"
                )));
            }
        },
        estimators: estimators
            .unwrap_or_default()
            .iter()
            .map(|e| e.parse::<Estimator>())
            .collect::<Result<_, _>>()
            .map_err(value_error)?,
        taus: taus.parse().map_err(value_error)?,
        confidence,
        fit_tau_min,
        bandwidth: parse_bandwidth(bandwidth)?,
        psd_segment,
        psd_window: psd_window.parse().map_err(value_error)?,
    };
    let settings = sensor_settings(settings)?;
    let input: serde_json::Value = match input {
        Some(text) => serde_json::from_str(text).map_err(|e| value_error(format!("input: {e}")))?,
        None => {
            serde_json::to_value(imunoise::input::ReadReport::default()).map_err(value_error)?
        }
    };
    let options = request.options(settings);
    py.detach(|| -> Result<_, String> {
        // The record is this call's own copy of the arrays: the analysis works in it.
        let results = pipeline::analyze_taking(&mut record, &options, &|| {})
            .map_err(|e| format!("{}: {e}", record.source))?;
        let mut document = report::json::document(&record, &options, &results);
        document["input"] = input;
        if let Some(period) = filter_period {
            let filters = filter::for_channels(&results, period)
                .map_err(|e| format!("filter_period {period}: {e}"))?;
            document["filter"] = report::filter::document(&record, &filters);
        }
        let (kalibr, why) = match report::kalibr::yaml(&record, &results) {
            Ok(yaml) => (Some(yaml), None),
            Err(e) => (None, Some(error_chain(&e))),
        };
        let text = serde_json::to_string(&document).map_err(|e| e.to_string())?;
        Ok((text, kalibr, why))
    })
    .map_err(value_error)
}

/// A Welch segment length (keyword `what`): 2 to the record's `samples`.
pub fn segment_len(segment: i64, samples: usize, what: &str) -> PyResult<usize> {
    usize::try_from(segment)
        .ok()
        .filter(|s| (2..=samples).contains(s))
        .ok_or_else(|| {
            value_error(format!(
                "{what} {segment}: a segment length in samples, from 2 to the record's length ({samples})"
            ))
        })
}

/// The filters a loaded capture's settings give (`{"gyro": ..., "accel": ...}`, each an
/// MPU-6050 settings object or null), from their JSON; an MPU-6050's settings alone are
/// taken for both of its chains.
pub fn sensor_settings(settings: Option<&str>) -> PyResult<Option<KnownFilters>> {
    let Some(text) = settings else {
        return Ok(None);
    };
    serde_json::from_str::<KnownFilters>(text)
        .or_else(|_| serde_json::from_str::<SensorSettings>(text).map(KnownFilters::from))
        .map(Some)
        .map_err(|e| value_error(format!("settings: {e}")))
}

/// The `bandwidth` keyword: Hz or "off".
pub fn parse_bandwidth(bandwidth: Option<String>) -> PyResult<Option<Bandwidth>> {
    bandwidth
        .map(|b| b.parse())
        .transpose()
        .map_err(|e| value_error(format!("bandwidth {e}")))
}

/// A record of the named columns (each copied once into its channel), all of one length.
pub fn record(
    names: Vec<String>,
    columns: &[PyReadonlyArray1<'_, f64>],
    rate: f64,
    source: &str,
) -> PyResult<Record> {
    if names.len() != columns.len() {
        return Err(value_error(format!(
            "{} names for {} channels",
            names.len(),
            columns.len()
        )));
    }
    let mut channels: Vec<Channel> = Vec::with_capacity(names.len());
    for (name, column) in names.into_iter().zip(columns) {
        if channels.iter().any(|c| c.name == name) {
            return Err(value_error(format!("channel '{name}' is named twice")));
        }
        let values = samples(column, &name)?.to_vec();
        if let Some(first) = channels.first()
            && first.values.len() != values.len()
        {
            return Err(value_error(format!(
                "channel '{name}' has {} samples and '{}' {}: every channel must have the same length",
                values.len(),
                first.name,
                first.values.len()
            )));
        }
        channels.push(Channel::named(name, values));
    }
    Ok(Record {
        source: source.to_string(),
        rate_hz: rate,
        channels,
    })
}

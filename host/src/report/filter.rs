//! Filter-ready noise parameters ([`crate::analysis::filter`]) as a table, a JSON document
//! and the same document as YAML, written beside the Kalibr file.

use super::sig;
use crate::analysis::filter::{CONVENTIONS, FilterNoise, Value as Number};
use crate::record::Record;
use serde_json::{Value, json};
use std::fmt::Write;
use std::path::Path;

/// The document: source, period, conventions and one entry per channel.
pub fn document(record: &Record, filters: &[FilterNoise]) -> Value {
    json!({
        "tool": "imunoise",
        "version": env!("CARGO_PKG_VERSION"),
        "source": record.source,
        "rate_hz": record.rate_hz,
        "period_s": filters.first().map(|f| f.period_s),
        "conventions": CONVENTIONS,
        "channels": filters,
    })
}

/// A filter file that cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum FilterFileError {
    #[error(
        "{}: the file name must end in .json, .yaml or .yml (it picks the format)",
        .0.display()
    )]
    Format(std::path::PathBuf),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// The text of a filter file: JSON for `.json`, YAML for `.yaml`/`.yml`; any other
/// extension is an error naming the path.
pub fn file_text(path: &Path, document: &Value) -> Result<String, FilterFileError> {
    if check_format(path)? == "json" {
        return Ok(serde_json::to_string_pretty(document)? + "\n");
    }
    Ok(yaml(
        document,
        "Filter noise parameters from imunoise (imunoise analyze --filter).\n\
         Conventions: see the `conventions` key. u = the channel's unit.",
    ))
}

/// The format a `--filter` file name picks: `json` or `yaml` (also for `.yml`).
pub fn check_format(path: &Path) -> Result<&'static str, FilterFileError> {
    let extension = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    match extension.to_ascii_lowercase().as_str() {
        "json" => Ok("json"),
        "yaml" | "yml" => Ok("yaml"),
        _ => Err(FilterFileError::Format(path.to_owned())),
    }
}

/// The table `analyze --filter-period` prints: one block per channel, a line per quantity.
pub fn render(filters: &[FilterNoise]) -> String {
    let mut out = String::new();
    let Some(first) = filters.first() else {
        return out;
    };
    let _ = writeln!(
        out,
        "\nFilter noise for period dt = {} s (two-sided PSDs; random walks Q_d = q dt; \
         Gauss-Markov Q_d = sigma^2 (1 - phi^2))",
        first.period_s
    );
    for f in filters {
        let _ = writeln!(out, "{} ({}):", f.channel, f.unit);
        let line = |out: &mut String, what: &str, n: &Number| {
            let _ = writeln!(out, "  {what:<40} {:>10} {}", sig(n.value, 4), n.unit);
        };
        line(&mut out, "white: density N", &f.white.density);
        line(&mut out, "white: PSD q = N^2", &f.white.psd);
        line(
            &mut out,
            "white: sample std N/sqrt(dt)",
            &f.white.sample_std,
        );
        line(
            &mut out,
            "white: integrated Q_d = N^2 dt",
            &f.white.integrated_variance,
        );
        let bound = if f.random_walk.upper_bound {
            " (upper bound)"
        } else {
            ""
        };
        line(
            &mut out,
            &format!("random walk: PSD q = K^2{bound}"),
            &f.random_walk.psd,
        );
        line(
            &mut out,
            &format!("random walk: Q_d = K^2 dt{bound}"),
            &f.random_walk.variance_per_step,
        );
        match &f.gauss_markov {
            Ok(g) => {
                line(&mut out, "Gauss-Markov: sigma", &g.sigma);
                line(&mut out, "Gauss-Markov: tau_c", &g.tau_c);
                line(
                    &mut out,
                    "Gauss-Markov: PSD q = 2 sigma^2/tau_c",
                    &g.driving_psd,
                );
                let _ = writeln!(
                    out,
                    "  {:<40} {:>10} (dimensionless)",
                    "Gauss-Markov: phi = exp(-dt/tau_c)",
                    format!("{:.8}", g.phi)
                );
                line(
                    &mut out,
                    "Gauss-Markov: Q_d = sigma^2 (1 - phi^2)",
                    &g.variance_per_step,
                );
            }
            Err(reason) => {
                let _ = writeln!(out, "  Gauss-Markov bias: {reason}");
            }
        }
    }
    out
}

/// `value` as block YAML (YAML 1.1, as PyYAML reads it), under a comment header. Numbers
/// are written as YAML floats (`1.5e-8`), strings double-quoted with JSON escapes (a
/// subset of YAML's double-quoted style).
pub fn yaml(value: &Value, header: &str) -> String {
    let mut out = String::new();
    for line in header.lines() {
        let _ = writeln!(out, "# {line}");
    }
    write_yaml(&mut out, value, 0);
    out
}

fn write_yaml(out: &mut String, value: &Value, indent: usize) {
    let pad = " ".repeat(indent);
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                if is_block(v) {
                    let _ = writeln!(out, "{pad}{key}:");
                    write_yaml(out, v, indent + 2);
                } else {
                    let _ = writeln!(out, "{pad}{key}: {}", scalar(v));
                }
            }
        }
        Value::Array(items) => {
            for v in items {
                if is_block(v) {
                    // The item's first line goes after the dash; the rest keep its indent.
                    let mut item = String::new();
                    write_yaml(&mut item, v, indent + 2);
                    let _ = write!(out, "{pad}- {}", &item[indent + 2..]);
                } else {
                    let _ = writeln!(out, "{pad}- {}", scalar(v));
                }
            }
        }
        other => {
            let _ = writeln!(out, "{pad}{}", scalar(other));
        }
    }
}

/// A float with every digit of its shortest round-trip form, spelt as YAML 1.1 readers
/// (PyYAML) recognise a float: a decimal point and a signed exponent, e.g. `1.5e-8`, `2.0e+0`.
fn yaml_float(x: f64) -> String {
    let text = format!("{x:e}");
    let (mantissa, exp) = text.split_once('e').unwrap_or((&text, "0"));
    let mantissa = if mantissa.contains('.') {
        mantissa.to_string()
    } else {
        format!("{mantissa}.0")
    };
    let exp = if exp.starts_with('-') {
        exp.to_string()
    } else {
        format!("+{exp}")
    };
    format!("{mantissa}e{exp}")
}

fn is_block(v: &Value) -> bool {
    match v {
        Value::Object(m) => !m.is_empty(),
        Value::Array(a) => !a.is_empty(),
        _ => false,
    }
}

fn scalar(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) if n.is_f64() => yaml_float(n.as_f64().unwrap_or(0.0)),
        Value::Number(n) => n.to_string(),
        Value::String(s) => Value::String(s.clone()).to_string(),
        Value::Object(_) => "{}".into(),
        Value::Array(_) => "[]".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaml_of_nested_maps_lists_and_scalars() {
        let v = json!({
            "period_s": 0.01,
            "name": "a \"b\"",
            "channels": [{"channel": "gx", "white": {"psd": {"value": 1.5e-8, "unit": "x"}}}],
            "flag": true,
            "count": 3,
        });
        let text = yaml(&v, "head");
        let expected = "# head\n\
                        channels:\n\
                        \x20 - channel: \"gx\"\n\
                        \x20   white:\n\
                        \x20     psd:\n\
                        \x20       unit: \"x\"\n\
                        \x20       value: 1.5e-8\n\
                        count: 3\n\
                        flag: true\n\
                        name: \"a \\\"b\\\"\"\n\
                        period_s: 1.0e-2\n";
        assert_eq!(text, expected);
        assert_eq!(yaml_float(2.0), "2.0e+0");
        assert_eq!(yaml_float(-0.99980002), "-9.9980002e-1");
    }
}

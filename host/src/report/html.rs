//! A self-contained HTML report: the record, the conventions, the noise-term tables and the
//! figures (inline SVG) on one page with no external resources.

use super::plot::{self, PlotError};
use super::{
    NOISE_TERMS, conventions, figures, kalibr, sig, sig_interval, support_of, table, term_of,
};
use crate::analysis::pipeline::{ChannelResult, Options};
use crate::analysis::units::{self, SensorKind};
use crate::record::Record;
use std::fmt::Write;

/// The stylesheet every report page shares.
pub const STYLE: &str = "body{font-family:sans-serif;max-width:1400px;margin:2em auto;padding:0 1em;color:#222}\
    table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:.3em .6em;text-align:right}\
    th{background:#f3f3f3}td{white-space:nowrap}td:first-child,th:first-child{text-align:left}td:first-child{white-space:normal}.svg svg{max-width:100%;height:auto}\
    pre{background:#f7f7f7;padding:1em;overflow-x:auto}.warn{color:#a40}";

pub fn page(
    record: &Record,
    options: &Options,
    results: &[ChannelResult],
) -> Result<String, PlotError> {
    let mut h = open_page(&format!("imunoise — {}", record.source));
    let _ = writeln!(
        h,
        "<p>{} channel(s), {} samples at {} Hz ({} s). Intervals: {} % two-sided.</p>",
        results.len(),
        super::samples(record, results),
        sig(record.rate_hz, 6),
        sig(super::duration_s(record, results), 6),
        sig(options.confidence * 100.0, 3)
    );
    h.push_str("<h2>Noise terms (IEEE-952 fit to the overlapping Allan variance)</h2>\n");
    for r in results {
        terms_table(&mut h, r);
    }
    lines_table(&mut h, results);
    if let Ok(k) = kalibr::numbers(results) {
        let _ = writeln!(
            h,
            "<h2>Kalibr</h2><table><tr><th>parameter</th><th>value</th></tr>\
             <tr><td>gyroscope_noise_density (rad/s/sqrt(Hz))</td><td>{}</td></tr>\
             <tr><td>gyroscope_random_walk (rad/s^2/sqrt(Hz))</td><td>{}</td></tr>\
             <tr><td>accelerometer_noise_density (m/s^2/sqrt(Hz))</td><td>{}</td></tr>\
             <tr><td>accelerometer_random_walk (m/s^3/sqrt(Hz))</td><td>{}</td></tr></table>\
             <p>{}; upper bounds: {}</p>",
            sig(k.noise.gyroscope_noise_density, 4),
            sig(k.noise.gyroscope_random_walk, 4),
            sig(k.noise.accelerometer_noise_density, 4),
            sig(k.noise.accelerometer_random_walk, 4),
            k.rule,
            if k.upper_bounds.is_empty() {
                "none".to_string()
            } else {
                k.upper_bounds.join(", ")
            }
        );
    }
    h.push_str("<h2>Figures</h2>\n");
    for figure in figures::figures(results) {
        let _ = writeln!(h, "<div class=\"svg\">{}</div>", plot::svg_string(&figure)?);
    }
    let _ = writeln!(
        h,
        "<h2>Summary as printed</h2><pre>{}</pre>",
        escape(&table::render(record, options, results))
    );
    conventions_list(&mut h, options);
    close_page(&mut h);
    Ok(h)
}

/// The head of a report page (the shared [`STYLE`]) and its `title` as the heading; `title`
/// is plain text.
pub fn open_page(title: &str) -> String {
    let title = escape(title);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>\
         <style>{STYLE}</style></head><body>\n<h1>{title}</h1>\n"
    )
}

/// The conventions every output states ([`conventions`]) as a section.
pub fn conventions_list(h: &mut String, options: &Options) {
    h.push_str("<h2>Conventions</h2><ul>\n");
    if let Some(map) = conventions(options).as_object() {
        for (k, v) in map {
            let _ = writeln!(
                h,
                "<li><b>{k}</b>: {}</li>",
                escape(v.as_str().unwrap_or(""))
            );
        }
    }
    h.push_str("</ul>\n");
}

/// The version line and the end of a page begun with [`open_page`].
pub fn close_page(h: &mut String) {
    let _ = writeln!(
        h,
        "<p>imunoise {}</p></body></html>",
        env!("CARGO_PKG_VERSION")
    );
}

fn terms_table(h: &mut String, r: &ChannelResult) {
    let _ = writeln!(h, "<h3>{} ({})</h3>", escape(&r.name), r.unit);
    let fit = match &r.fit {
        Ok(fit) => fit,
        Err(e) => {
            let _ = writeln!(h, "<p>No fit: {}</p>", escape(&e.to_string()));
            return;
        }
    };
    h.push_str("<table><tr><th>term</th><th>value</th><th>interval</th><th>SI unit</th>");
    if r.kind != SensorKind::Other {
        h.push_str("<th>conventional</th><th>interval</th><th>unit</th>");
    }
    h.push_str("<th>detected</th></tr>\n");
    for term in NOISE_TERMS {
        let t = term_of(fit, term);
        let [value, lo, hi] = sig_interval(t.value, t.lo, t.hi, 3);
        let _ = write!(
            h,
            "<tr><td>{term:?}</td><td>{}</td><td>{} .. {}</td><td>{}</td>",
            value,
            lo,
            hi,
            units::si_unit(r.kind, term)
        );
        if r.kind != SensorKind::Other {
            let c = |v| units::conventional(r.kind, term, v);
            let [value, lo, hi] = sig_interval(c(t.value).value, c(t.lo).value, c(t.hi).value, 3);
            let _ = write!(
                h,
                "<td>{value}</td><td>{lo} .. {hi}</td><td>{}</td>",
                c(t.value).unit
            );
        }
        let s = support_of(fit, term);
        let _ = write!(
            h,
            "<td>{} (p = {})</td>",
            if s.detected { "yes" } else { "no" },
            sig(s.p_value, 2)
        );
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    let _ = writeln!(h, "<p>{}</p>", escape(&table::goodness_line(fit)));
    if let Some(warning) = table::poor_fit_warning(&r.name, fit) {
        let _ = writeln!(h, "<p><strong>Warning:</strong> {}</p>", escape(&warning));
    }
}

/// The spectral lines of every channel, removed before the fit, each value with its standard
/// error.
fn lines_table(h: &mut String, results: &[ChannelResult]) {
    if results.iter().all(|r| r.lines.is_empty()) {
        return;
    }
    h.push_str(
        "<h2>Spectral lines (removed from the record before the fit)</h2>\n\
         <table><tr><th>channel</th><th>frequency (Hz)</th><th>amplitude</th>\
         <th>width (Hz)</th><th>power</th><th>z</th><th>p (family-wise)</th></tr>\n",
    );
    let with_error = |value: f64, se: Option<f64>, digits: usize| match se {
        Some(se) => format!("{} &plusmn; {}", sig(value, digits), sig(se, 2)),
        None => sig(value, digits),
    };
    for r in results {
        for l in &r.lines {
            let e = &l.standard_errors;
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{} {}</td><td>{}</td><td>{} {}^2</td>\
                 <td>{}</td><td>{}</td></tr>",
                escape(&r.name),
                with_error(l.freq_hz, Some(e.freq_hz), 6),
                with_error(l.amplitude, Some(e.amplitude), 3),
                r.unit,
                with_error(l.width_hz, e.width_hz, 3),
                sig(l.power, 3),
                r.unit,
                sig(l.statistic, 3),
                table::p_text(l.p_value)
            );
        }
    }
    h.push_str(
        "</table>\n<p>&plusmn;: one standard error (a pure tone: the Cramer-Rao bounds at the \
         background there; its width, 0, is below the resolution). Amplitude: the peak of the \
         equivalent sinusoid, sqrt(2 power).</p>\n",
    );
}

/// Text made safe to put inside HTML elements and attribute values.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

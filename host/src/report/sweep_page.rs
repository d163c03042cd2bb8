//! The HTML page of a settings sweep (`imunoise sweep --report`, `imunoise demo`): one
//! session per MPU-6050 setting, its noise terms per axis, the Allan deviation of every axis
//! at every setting, the gyro's white noise against the folding prediction, and a published
//! table (Table 2 of the settings study, docs/references.md) beside the sweep in the same
//! unit, with the unit assumed and what no stationary input can produce
//! (docs/signal_chain.md). Self-contained, styled like `analyze`'s report ([`super::html`]).

use super::figures::{curve_lines, sensor_title};
use super::html::{close_page, conventions_list, escape, open_page};
use super::plot::{self, Figure, Panel, PlotError};
use super::table::{goodness_line, poor_fit_warning};
use super::{sig, sig_interval, term_of};
use crate::analysis::fit::Term;
use crate::analysis::pipeline::{ChannelResult, Options};
use crate::analysis::units::{self, NoiseTerm, SensorKind, rad_to_deg};
use protocol::mpu6050::Hz;
use std::fmt::Write;

/// The terms a sweep's table shows: white noise, bias instability, rate random walk.
const TERMS: [NoiseTerm; 3] = [NoiseTerm::N, NoiseTerm::B, NoiseTerm::K];

/// A published ratio of N to the reference setting's "reproduces" where it is within this
/// fraction of the predicted ratio. Ratios, not levels: the datasheet's density is a typical
/// value, and one chip may differ from it by more than any ratio's error.
pub const AGREES_WITHIN: f64 = 0.05;

/// One setting of a sweep: its session and its analysis.
#[derive(Debug, Clone, Copy)]
pub struct Setting<'a> {
    /// Output data rate, Hz.
    pub rate_hz: f64,
    /// The gyro DLPF's -3 dB bandwidth, Hz (what settings are named by).
    pub bandwidth_hz: f64,
    /// The bandwidth is above half the output rate: noise above Nyquist folds back.
    pub folds: bool,
    pub session_id: i64,
    pub session_name: &'a str,
    /// Samples the board numbered that never reached the store.
    pub samples_lost: u64,
    pub results: &'a [ChannelResult],
}

/// The gyro's white noise N at one setting, every value in deg/sqrt(s) (= deg/s/sqrt(Hz),
/// the Allan deviation at tau = 1 s on the -1/2 line: the two-sided density).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroNoise {
    pub rate_hz: f64,
    pub bandwidth_hz: f64,
    /// The folding prediction N / N0 (docs/signal_chain.md).
    pub folding: f64,
    /// The datasheet's density as N (one-sided / sqrt(2)) times [`GyroNoise::folding`].
    pub datasheet: f64,
    /// The published value at this setting, read in deg/sqrt(s), if there is one.
    pub published: Option<f64>,
    /// The sweep's N (the gyro axes' mean) with its interval.
    pub measured: Option<Term>,
}

/// Where the published values come from and what they are read against.
#[derive(Debug, Clone, Copy)]
pub struct Published<'a> {
    /// The table's name as the page prints it, e.g. "the settings study's Table 2".
    pub source: &'a str,
    /// The datasheet's one-sided gyro rate noise density, deg/s/sqrt(Hz).
    pub datasheet_density: f64,
}

/// Everything on a sweep's page.
#[derive(Debug, Clone, Copy)]
pub struct SweepPage<'a> {
    pub title: &'a str,
    /// The sensor the settings are of, in words ("the MPU-6050").
    pub sensor: &'a str,
    pub settings: &'a [Setting<'a>],
    /// One row per setting, in the order of `settings`.
    pub gyro: &'a [GyroNoise],
    pub published: Published<'a>,
    /// The options every setting was analysed with.
    pub options: &'a Options,
}

/// The page as one self-contained HTML document.
pub fn page(p: &SweepPage) -> Result<String, PlotError> {
    let mut h = open_page(p.title);
    intro(&mut h, p);
    let reference = reference(p.gyro);
    let published = reference.is_some() && p.gyro.iter().any(|g| g.published.is_some());
    let sections = [
        ("sessions", "sessions", true),
        ("terms", "noise terms", true),
        ("folding", "folding", reference.is_some()),
        ("published", "published values", published),
        ("figures", "figures", true),
    ];
    let contents: Vec<String> = sections
        .iter()
        .filter(|s| s.2)
        .map(|(id, name, _)| format!("<a href=\"#{id}\">{name}</a>"))
        .collect();
    let _ = writeln!(h, "<p>Contents: {}</p>", contents.join(" &middot; "));
    sessions_table(&mut h, p.settings);
    h.push_str(
        "<h2 id=\"terms\">Noise terms per setting and axis (IEEE-952 fit to the overlapping Allan variance)</h2>\n",
    );
    for group in sensor_groups(p.settings) {
        terms_table(&mut h, p.settings, &group);
    }
    if let Some(reference) = reference {
        folding_table(&mut h, p.gyro, reference);
        if published {
            published_section(&mut h, p, reference);
        }
    }
    h.push_str("<h2 id=\"figures\">Figures</h2>\n");
    for figure in figures(p.settings) {
        let _ = writeln!(h, "<div class=\"svg\">{}</div>", plot::svg_string(&figure)?);
    }
    conventions_list(&mut h, p.options);
    close_page(&mut h);
    Ok(h)
}

/// "200/42 Hz".
fn label(rate_hz: f64, bandwidth_hz: f64) -> String {
    format!("{}/{} Hz", Hz(rate_hz), Hz(bandwidth_hz))
}

/// A value and its interval's bounds with three significant digits, or as many more as
/// show the interval's width.
fn interval(t: Term) -> [String; 3] {
    sig_interval(t.value, t.lo, t.hi, 3)
}

fn intro(h: &mut String, p: &SweepPage) {
    let folding = p.settings.iter().any(|s| s.folds);
    let _ = writeln!(
        h,
        "<p>{} setting(s) of {}, one stored session each (output rate / gyro DLPF \
         bandwidth), each analysed on its own. Intervals: {} % two-sided.{}</p>",
        p.settings.len(),
        escape(p.sensor),
        sig(p.options.confidence * 100.0, 3),
        if folding {
            " Settings marked * have the bandwidth above half the output rate: the chip \
             decimates without an anti-alias filter, so noise above the Nyquist frequency \
             folds back."
        } else {
            ""
        }
    );
}

fn sessions_table(h: &mut String, settings: &[Setting]) {
    h.push_str(
        "<h2 id=\"sessions\">Sessions</h2>\n<table><tr><th>setting</th><th>rate (Hz)</th><th>bandwidth (Hz)</th>\
         <th>session</th><th>name</th><th>samples analysed</th><th>record (s)</th>\
         <th>samples lost</th></tr>\n",
    );
    for s in settings {
        let samples = s.results.first().map_or(0, |r| r.n);
        let _ = writeln!(
            h,
            "<tr><td>{}{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{samples}</td>\
             <td>{}</td><td>{}</td></tr>",
            label(s.rate_hz, s.bandwidth_hz),
            if s.folds { "*" } else { "" },
            Hz(s.rate_hz),
            Hz(s.bandwidth_hz),
            s.session_id,
            escape(s.session_name),
            sig(samples as f64 / s.rate_hz, 6),
            s.samples_lost
        );
    }
    h.push_str("</table>\n");
}

/// A sensor (as [`sensor_title`] names it) and its channels, in order of first appearance
/// over the settings.
struct SensorGroup {
    title: String,
    kind: SensorKind,
    unit: &'static str,
    channels: Vec<String>,
}

fn sensor_groups(settings: &[Setting]) -> Vec<SensorGroup> {
    let mut groups: Vec<SensorGroup> = Vec::new();
    for r in settings.iter().flat_map(|s| s.results) {
        let title = sensor_title(r);
        let index = match groups.iter().position(|g| g.title == title) {
            Some(i) => i,
            None => {
                groups.push(SensorGroup {
                    title,
                    kind: r.kind,
                    unit: r.unit,
                    channels: Vec::new(),
                });
                groups.len() - 1
            }
        };
        let channels = &mut groups[index].channels;
        if !channels.contains(&r.name) {
            channels.push(r.name.clone());
        }
    }
    groups
}

/// The results of `group`'s channels at one setting.
fn members<'a>(s: &Setting<'a>, group: &SensorGroup) -> Vec<&'a ChannelResult> {
    group
        .channels
        .iter()
        .filter_map(|c| s.results.iter().find(|r| &r.name == c))
        .collect()
}

fn terms_table(h: &mut String, settings: &[Setting], group: &SensorGroup) {
    let _ = writeln!(h, "<h3>{}</h3>", escape(&group.title));
    h.push_str(
        "<table><tr><th>rate (Hz)</th><th>bandwidth (Hz)</th><th>samples</th><th>lost</th>\
         <th>axis</th>",
    );
    for term in TERMS {
        let unit = units::conventional(group.kind, term, 0.0).unit;
        let _ = write!(h, "<th>{term:?} ({unit})</th><th>interval</th>");
    }
    h.push_str("<th>reduced chi-square</th></tr>\n");
    let mut warnings = Vec::new();
    for s in settings {
        let rows = members(s, group);
        for (i, r) in rows.iter().enumerate() {
            h.push_str("<tr>");
            if i == 0 {
                let _ = write!(
                    h,
                    "<td rowspan=\"{n}\">{}</td><td rowspan=\"{n}\">{}{}</td>\
                     <td rowspan=\"{n}\">{}</td><td rowspan=\"{n}\">{}</td>",
                    Hz(s.rate_hz),
                    Hz(s.bandwidth_hz),
                    if s.folds { "*" } else { "" },
                    r.n,
                    s.samples_lost,
                    n = rows.len()
                );
            }
            let _ = write!(h, "<td>{}</td>", escape(&r.name));
            match &r.fit {
                Ok(fit) => {
                    for term in TERMS {
                        let t = term_of(fit, term);
                        let c = |v| units::conventional(r.kind, term, v).value;
                        let [value, lo, hi] = interval(Term {
                            value: c(t.value),
                            lo: c(t.lo),
                            hi: c(t.hi),
                        });
                        let _ = write!(h, "<td>{value}</td><td>{lo} .. {hi}</td>");
                    }
                    let _ = write!(
                        h,
                        "<td title=\"{}\">{}</td>",
                        escape(&goodness_line(fit)),
                        sig(fit.goodness.reduced_chi2, 3)
                    );
                    let name = format!("{} at {}", r.name, label(s.rate_hz, s.bandwidth_hz));
                    warnings.extend(poor_fit_warning(&name, fit));
                }
                Err(e) => {
                    let _ = write!(
                        h,
                        "<td colspan=\"{}\">no fit: {}</td>",
                        2 * TERMS.len() + 1,
                        escape(&e.to_string())
                    );
                }
            }
            h.push_str("</tr>\n");
        }
    }
    h.push_str("</table>\n");
    if group.kind == SensorKind::Other {
        let _ = writeln!(h, "<p>u = {}.</p>", group.unit);
    }
    for w in warnings {
        let _ = writeln!(
            h,
            "<p class=\"warn\"><strong>Warning:</strong> {}</p>",
            escape(&w)
        );
    }
}

/// The setting the ratios are taken to: the one with the least folding (where the gyro's N
/// is nearest its unfolded N0), when it has a measured or a published N.
fn reference(gyro: &[GyroNoise]) -> Option<&GyroNoise> {
    gyro.iter()
        .filter(|g| g.measured.is_some() || g.published.is_some())
        .min_by(|a, b| a.folding.total_cmp(&b.folding))
}

/// `a / b` with an interval from the two relative half-widths in quadrature (independent
/// records), and that relative half-width.
fn ratio(a: Term, b: Term) -> Option<(f64, f64)> {
    let half = |t: Term| (t.hi - t.lo) / 2.0 / t.value;
    // An interval of no width (a hand-written row) has no scale to measure a ratio in.
    (a.value > 0.0 && b.value > 0.0 && a.hi > a.lo && b.hi > b.lo).then(|| {
        (
            a.value / b.value,
            (half(a).powi(2) + half(b).powi(2)).sqrt(),
        )
    })
}

fn folding_table(h: &mut String, gyro: &[GyroNoise], reference: &GyroNoise) {
    let name = label(reference.rate_hz, reference.bandwidth_hz);
    let _ = writeln!(
        h,
        "<h2 id=\"folding\">Folding: the gyro's white noise, predicted and measured</h2>\n<p>Decimating \
         without an anti-alias filter adds the filtered noise at every alias of DC: for white \
         input N0 the output's N<sup>2</sup> = N0<sup>2</sup> &Sigma;<sub>j</sub> \
         |H(j f<sub>s</sub>)|<sup>2</sup> (H the DLPF at the internal rate, f<sub>s</sub> the \
         output rate; docs/signal_chain.md). The measured N is the mean of the gyro axes; \
         ratios to {name} (the least folding) cancel the sensor's own N0. A ratio's interval \
         combines the two relative half-widths in quadrature (independent records); z is the \
         measured ratio's distance from the predicted one in those half-widths.</p>"
    );
    let _ = writeln!(
        h,
        "<table><tr><th>setting</th><th>predicted N / N0</th><th>predicted ratio to {name}</th>\
         <th>measured N (deg/sqrt(s))</th><th>interval</th><th>measured ratio to {name}</th>\
         <th>interval</th><th>z</th></tr>"
    );
    for g in gyro {
        let predicted = g.folding / reference.folding;
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.3}</td><td>{:.3}</td>",
            label(g.rate_hz, g.bandwidth_hz),
            g.folding,
            predicted
        );
        match g.measured {
            Some(m) => {
                let [value, lo, hi] = interval(m);
                let _ = write!(h, "<td>{value}</td><td>{lo} .. {hi}</td>");
            }
            None => h.push_str("<td>-</td><td>-</td>"),
        }
        if std::ptr::eq(g, reference) {
            h.push_str("<td>1 (reference)</td><td>-</td><td>-</td></tr>\n");
            continue;
        }
        match g
            .measured
            .zip(reference.measured)
            .and_then(|(a, b)| ratio(a, b))
        {
            Some((r, rel)) => {
                let _ = writeln!(
                    h,
                    "<td>{:.3}</td><td>{:.3} .. {:.3}</td><td>{:+.1}</td></tr>",
                    r,
                    r * (1.0 - rel),
                    r * (1.0 + rel),
                    (r - predicted) / (r * rel)
                );
            }
            None => h.push_str("<td>-</td><td>-</td><td>-</td></tr>\n"),
        }
    }
    h.push_str("</table>\n");
}

fn published_section(h: &mut String, p: &SweepPage, reference: &GyroNoise) {
    let source = escape(p.published.source);
    let name = label(reference.rate_hz, reference.bandwidth_hz);
    let n_datasheet = p.published.datasheet_density / 2f64.sqrt();
    let _ = writeln!(
        h,
        "<h2 id=\"published\">{} beside this sweep</h2>\n<p>Every value in deg/sqrt(s) = \
         deg/s/sqrt(Hz) (the Allan deviation at tau = 1 s; 1 deg/sqrt(s) = 60 deg/sqrt(h), the \
         unit of the noise table above). Datasheet &times; folding: the datasheet's typical \
         one-sided density {} deg/s/sqrt(Hz) as N = {} deg/sqrt(s), times the folding \
         prediction. A level depends on the chip (and this sweep's on its sensor, real or \
         simulated); a ratio to {name} does not, so reproduction is judged on the ratios: a \
         published ratio reproduces where it is within {} % of the predicted one.</p>",
        capitalise(&source),
        p.published.datasheet_density,
        sig(n_datasheet, 3),
        AGREES_WITHIN * 100.0,
    );
    unit_assumption(h, &source, reference, n_datasheet);
    let _ = writeln!(
        h,
        "<table><tr><th>setting</th><th>published</th><th>datasheet &times; folding</th>\
         <th>published / (datasheet &times; folding)</th><th>this sweep</th><th>interval</th>\
         <th>published ratio to {name}</th><th>predicted ratio</th>\
         <th>this sweep's ratio</th><th>published ratio reproduces</th></tr>"
    );
    // Published values as published, with their own digits.
    let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| v.to_string());
    let mut reproduced = Vec::new();
    for g in p.gyro {
        let (value, bounds) = g.measured.map_or(("-".into(), "-".into()), |m| {
            let [value, lo, hi] = interval(m);
            (value, format!("{lo} .. {hi}"))
        });
        let predicted = g.folding / reference.folding;
        let published_ratio = g.published.zip(reference.published).map(|(a, b)| a / b);
        let measured_ratio = g
            .measured
            .zip(reference.measured)
            .and_then(|(a, b)| ratio(a, b))
            .map(|(r, _)| format!("{r:.2}"));
        let verdict = match published_ratio {
            _ if std::ptr::eq(g, reference) => "reference".to_string(),
            Some(r) => {
                let off = r / predicted - 1.0;
                let agrees = off.abs() <= AGREES_WITHIN;
                if agrees {
                    reproduced.push(format!(
                        "{} (published ratio {r:.2}, predicted {predicted:.2})",
                        label(g.rate_hz, g.bandwidth_hz)
                    ));
                }
                format!(
                    "{} ({:+.0} %)",
                    if agrees { "yes" } else { "no" },
                    off * 100.0
                )
            }
            None => "-".to_string(),
        };
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{value}</td><td>{bounds}</td>\
             <td>{}</td><td>{predicted:.2}</td><td>{}</td><td>{verdict}</td></tr>",
            label(g.rate_hz, g.bandwidth_hz),
            opt(g.published),
            sig(g.datasheet, 3),
            g.published.map_or_else(
                || "-".into(),
                |v| format!("{:+.0} %", (v / g.datasheet - 1.0) * 100.0)
            ),
            published_ratio.map_or_else(|| "-".into(), |r| format!("{r:.2}")),
            measured_ratio.as_deref().unwrap_or("-"),
        );
    }
    h.push_str("</table>\n");
    let _ = writeln!(
        h,
        "<p><b>What reproduces:</b> {}.</p>",
        if reproduced.is_empty() {
            "no published ratio".to_string()
        } else {
            reproduced.join("; ")
        }
    );
    subset_checks(h, p);
}

/// Why deg/sqrt(s): the published value where nothing folds, read in each candidate unit,
/// against the datasheet's N.
fn unit_assumption(h: &mut String, source: &str, reference: &GyroNoise, n_datasheet: f64) {
    let Some(v) = reference.published else {
        let _ = writeln!(
            h,
            "<p><b>Unit assumed: deg/sqrt(s).</b> No unit is stated in {source} \
             (docs/signal_chain.md gives the reasons for this reading).</p>"
        );
        return;
    };
    let name = label(reference.rate_hz, reference.bandwidth_hz);
    let _ = writeln!(
        h,
        "<p><b>Unit assumed: deg/sqrt(s)</b> (the two-sided density N): no unit is stated in \
         {source}. At {name}, where the folding prediction is {:.3}, its value {} read in \
         each candidate unit, against the datasheet's N there ({}):</p>",
        reference.folding,
        v,
        sig(reference.datasheet, 3)
    );
    h.push_str(
        "<table><tr><th>read as</th><th>in deg/sqrt(s)</th><th>against the datasheet</th></tr>\n",
    );
    let readings = [
        ("deg/sqrt(s) = deg/s/sqrt(Hz) (assumed)", v),
        ("deg/sqrt(h)", v / 60.0),
        ("rad/sqrt(s) = rad/s/sqrt(Hz)", rad_to_deg(v)),
        (
            "deg/s, the standard deviation of the samples",
            v / reference.rate_hz.sqrt(),
        ),
        ("deg/sqrt(s) as a one-sided density", v / 2f64.sqrt()),
    ];
    for (unit, n) in readings {
        let _ = writeln!(
            h,
            "<tr><td>{unit}</td><td>{}</td><td>{}</td></tr>",
            sig(n, 3),
            times(n / reference.datasheet)
        );
    }
    let _ = writeln!(
        h,
        "</table>\n<p>Only the assumed unit and the one-sided reading put the chip near its \
         datasheet (N = {} deg/sqrt(s) unfolded); the one-sided reading would scale every \
         published value by the same 1/sqrt(2) and change no ratio below.</p>",
        sig(n_datasheet, 3)
    );
}

/// A ratio as "0.95" near 1, "1/63" or "55" far from it.
fn times(r: f64) -> String {
    if r < 0.2 {
        format!("1/{:.0}", 1.0 / r)
    } else if r > 5.0 {
        format!("{r:.0}")
    } else {
        format!("{r:.2}")
    }
}

fn capitalise(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map_or_else(String::new, |f| f.to_uppercase().chain(c).collect())
}

/// Pairs of settings with one filter whose rates divide: the aliases of DC at the higher
/// rate are a subset of those at the lower one, so the lower rate's N is at least the
/// higher's for any stationary input. A published pair that breaks this is said so.
fn subset_checks(h: &mut String, p: &SweepPage) {
    let mut broken = false;
    for lo in p.gyro {
        for hi in p.gyro {
            let m = hi.rate_hz / lo.rate_hz;
            if lo.bandwidth_hz != hi.bandwidth_hz || m <= 1.0 || (m - m.round()).abs() > 1e-9 {
                continue;
            }
            let (Some(a), Some(b)) = (lo.published, hi.published) else {
                continue;
            };
            let (low, high) = (
                label(lo.rate_hz, lo.bandwidth_hz),
                label(hi.rate_hz, hi.bandwidth_hz),
            );
            let _ = write!(
                h,
                "<p><b>{low} against {high}:</b> one filter, and the aliases of DC at {} Hz \
                 (its multiples) are a subset of those at {} Hz, so N({low}) &ge; N({high}) \
                 for any stationary input, white or not (docs/signal_chain.md). Predicted \
                 ratio {:.2}",
                Hz(hi.rate_hz),
                Hz(lo.rate_hz),
                lo.folding / hi.folding
            );
            if let Some((r, rel)) = lo.measured.zip(hi.measured).and_then(|(a, b)| ratio(a, b)) {
                let _ = write!(h, "; this sweep's {r:.3} (&plusmn;{:.1} %)", rel * 100.0);
            }
            let _ = write!(h, "; published {:.2}.", a / b);
            if a < b {
                broken = true;
                let _ = write!(
                    h,
                    " <span class=\"warn\">The published {low} is {:.0} % below {high}: no \
                     stationary input through the same filter can produce that, so this sweep \
                     cannot reproduce it.</span>",
                    (1.0 - a / b) * 100.0
                );
                if let Some((_, rel)) = lo.measured.zip(hi.measured).and_then(|(a, b)| ratio(a, b))
                {
                    let _ = write!(
                        h,
                        " Nor is it estimation scatter: at this sweep's record length the \
                         ratio's half-width is {:.1} %, the shortfall below 1 is {:.0} times \
                         that (a half-width that shrinks as one over the square root of the \
                         record length).",
                        rel * 100.0,
                        (1.0 - a / b) / rel
                    );
                }
            }
            h.push_str("</p>\n");
        }
    }
    if broken {
        h.push_str(
            "<p>What could explain it (none can be decided from the published table alone; \
             docs/signal_chain.md):</p><ul>\
             <li>different records: settings logged one after another differ in warm-up and \
             chip temperature, and a warm-up drift raises the Allan deviation near 1 s in \
             whichever record has it;</li>\
             <li>a different read-out: the Allan deviation at tau = 1 s, or a -1/2 line over \
             another tau range, includes bias instability and drift, which differ between \
             records;</li>\
             <li>a conversion that differs per setting: a per-sample standard deviation turned \
             into a density with the wrong rate scales N by sqrt(rate assumed / rate \
             true);</li>\
             <li>a setting other than named: a lower DLPF at the lower rate, or a divider that \
             averages, gives N = N0 at both rates, which is still not below the higher rate's, \
             so one of the first three must be involved.</li></ul>\n",
        );
    }
}

/// One figure per sensor, one panel per axis: the overlapping Allan deviation the fit used,
/// shaded with its confidence interval, and the fitted model dashed, at every setting.
pub fn figures(settings: &[Setting]) -> Vec<Figure> {
    sensor_groups(settings)
        .into_iter()
        .map(|group| Figure {
            title: format!("{}: every setting", group.title),
            panels: group
                .channels
                .iter()
                .map(|channel| Panel {
                    title: format!("{channel} (shaded: confidence interval; dashed: fit)"),
                    x_label: "tau (s)".into(),
                    y_label: format!("overlapping Allan deviation ({})", group.unit),
                    lines: settings
                        .iter()
                        .enumerate()
                        .filter_map(|(i, s)| {
                            let r = s.results.iter().find(|r| &r.name == channel)?;
                            Some(curve_lines(
                                &r.fit_curve,
                                r.fit.as_ref().ok(),
                                label(s.rate_hz, s.bandwidth_hz),
                                i,
                            ))
                        })
                        .flatten()
                        .collect(),
                })
                .collect(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::pipeline;
    use crate::record::{Channel, Record};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;
    use std::path::{Path, PathBuf};
    use std::process::{Command, Stdio};

    /// 30 s of white noise at `rate_hz` on two gyro axes, one accelerometer axis and the
    /// temperature (one channel of each kind of group), analysed.
    fn results(rate_hz: f64, seed: u64) -> Vec<ChannelResult> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = (30.0 * rate_hz) as usize;
        let mut white = |mean: f64, sigma: f64| -> Vec<f64> {
            (0..n)
                .map(|_| mean + sigma * rng.sample::<f64, _>(StandardNormal))
                .collect()
        };
        let record = Record {
            source: "fixture".into(),
            rate_hz,
            channels: vec![
                Channel::named("gx", white(0.0, 1e-3)),
                Channel::named("gy", white(0.0, 1e-3)),
                Channel::named("ax", white(0.0, 1e-2)),
                Channel::named("temp", white(25.0, 1e-2)),
            ],
        };
        pipeline::analyze(&record, &Options::default(), &|| {}).unwrap()
    }

    /// The settings study's four settings: their folding predictions, the datasheet's N
    /// (0.005 / sqrt(2) deg/s/sqrt(Hz)) times them, the study's Table 2 and a 2-minute
    /// simulated sweep's N, deg/sqrt(s).
    fn gyro_rows(published: bool) -> Vec<GyroNoise> {
        let rows = [
            (200.0, 256.0, 1.768, 0.00955, (0.0152, 0.0151, 0.0153)),
            (200.0, 42.0, 1.006, 0.00337, (0.00862, 0.00849, 0.00876)),
            (50.0, 256.0, 3.535, 0.01197, (0.0306, 0.0304, 0.0308)),
            (50.0, 42.0, 1.418, 0.00283, (0.0122, 0.0121, 0.0123)),
        ];
        rows.iter()
            .map(
                |&(rate_hz, bandwidth_hz, folding, paper, (value, lo, hi))| GyroNoise {
                    rate_hz,
                    bandwidth_hz,
                    folding,
                    datasheet: 0.005 / 2f64.sqrt() * folding,
                    published: published.then_some(paper),
                    measured: Some(Term { value, lo, hi }),
                },
            )
            .collect()
    }

    /// The page of four settings: 200 Hz and 50 Hz records (each shared by two settings),
    /// one setting with a failed fit on gy, one with lost samples and a name to escape.
    fn with_page<T>(published: bool, check: impl FnOnce(&str) -> T) -> T {
        let (r200, r50) = (results(200.0, 7), results(50.0, 8));
        let mut r50_failed = r50.clone();
        r50_failed[1].fit = Err(crate::analysis::fit::FitError::TooFewPoints(1));
        let setting = |rate_hz, bandwidth_hz, session_id, results| Setting {
            rate_hz,
            bandwidth_hz,
            folds: bandwidth_hz > rate_hz / 2.0,
            session_id,
            session_name: "sweep",
            samples_lost: 0,
            results,
        };
        let settings = [
            Setting {
                session_name: "sweep<1>",
                ..setting(200.0, 256.0, 1, &r200[..])
            },
            setting(200.0, 42.0, 2, &r200[..]),
            Setting {
                samples_lost: 64,
                ..setting(50.0, 256.0, 3, &r50[..])
            },
            setting(50.0, 42.0, 4, &r50_failed[..]),
        ];
        let gyro = gyro_rows(published);
        let html = page(&SweepPage {
            sensor: "the MPU-6050",
            title: "imunoise sweep",
            settings: &settings,
            gyro: &gyro,
            published: Published {
                source: "the settings study's Table 2",
                datasheet_density: 0.005,
            },
            options: &Options::default(),
        })
        .unwrap();
        check(&html)
    }

    /// Elements opened and closed out of order, or left open, outside the inline SVG
    /// (plotters' output).
    fn nesting_errors(html: &str) -> Vec<String> {
        const VOID: [&str; 5] = ["meta", "br", "img", "hr", "link"];
        let mut errors = Vec::new();
        let mut open: Vec<String> = Vec::new();
        let mut rest = html;
        while let Some(start) = rest.find('<') {
            rest = &rest[start + 1..];
            let end = rest.find('>').unwrap_or(rest.len());
            let tag = &rest[..end];
            rest = &rest[end.min(rest.len())..];
            if tag.starts_with('!') {
                continue;
            }
            let name: String = tag
                .trim_start_matches('/')
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric())
                .collect();
            if name == "svg" {
                match rest.find("</svg>") {
                    Some(close) => rest = &rest[close + "</svg>".len()..],
                    None => errors.push("an <svg> not closed".into()),
                }
            } else if tag.starts_with('/') {
                if open.pop().as_deref() != Some(name.as_str()) {
                    errors.push(format!("</{name}> closes something else"));
                }
            } else if !VOID.contains(&name.as_str()) && !tag.ends_with('/') {
                open.push(name);
            }
        }
        errors.extend(open.into_iter().map(|n| format!("<{n}> not closed")));
        errors
    }

    #[test]
    fn the_page_has_every_table_figure_and_published_value() {
        with_page(true, |html| {
            assert_eq!(nesting_errors(html), Vec::<String>::new());
            // Sessions, the three sensors' terms, folding, the unit readings, Table 2.
            assert_eq!(html.matches("<table>").count(), 7);
            for heading in ["Gyroscope", "Accelerometer", "temp (degC)"] {
                assert!(html.contains(&format!("<h3>{heading}</h3>")), "{heading}");
            }
            // One row per setting and axis, the setting's cells spanning its axes.
            for axis in ["gx", "gy", "ax", "temp"] {
                assert_eq!(
                    html.matches(&format!("<td>{axis}</td>")).count(),
                    4,
                    "{axis}"
                );
            }
            assert_eq!(html.matches("<td rowspan=\"2\">").count(), 4 * 4);
            assert!(html.contains("<th>N (deg/sqrt(h))</th>") && html.contains("<th>B (ug)</th>"));
            assert!(html.contains(">6000</td><td rowspan=\"2\">0</td>"));
            assert!(html.contains(">1500</td><td rowspan=\"2\">64</td>"));
            assert_eq!(
                html.matches("no fit: 1 points: the noise fit needs at least 2")
                    .count(),
                1
            );
            assert!(html.contains("sweep&lt;1&gt;") && !html.contains("sweep<1>"));
            // Every axis's figure: one per sensor, one panel per axis, every setting on it.
            assert_eq!(html.matches("<svg").count(), 3);
            for axis in ["gx", "gy", "ax", "temp"] {
                assert!(
                    html.contains(&format!("{axis} (shaded: confidence")),
                    "{axis}"
                );
            }
            for setting in ["200/256 Hz", "200/42 Hz", "50/256 Hz", "50/42 Hz"] {
                let legend = format!(">\n{setting}\n</text>");
                assert_eq!(html.matches(&legend).count(), 4, "{setting}");
            }
            // Folding: predictions, their ratios to 200/42 Hz, the sweep's ratios.
            for text in [
                "1.768",
                "3.535",
                "<td>3.514</td>",
                "<td>3.550</td>",
                "1 (reference)",
            ] {
                assert!(html.contains(text), "{text}");
            }
            // The study's values as published, the unit assumed and its alternatives, the
            // ratios judged against the prediction.
            for text in [
                "<td>0.00955</td>",
                "<td>0.00337</td>",
                "<td>0.01197</td>",
                "<td>0.00283</td>",
                "Unit assumed: deg/sqrt(s)",
                "<td>1/63</td>",
                "<td>-44 %</td>",
                "yes (+1 %)",
                "no (+61 %)",
                "no (-40 %)",
                "What reproduces:</b> 50/256 Hz (published ratio 3.55, predicted 3.51)",
            ] {
                assert!(html.contains(text), "{text}");
            }
            // 50/42 below 200/42 is no stationary input's; 50/256 above 200/256 is.
            assert!(
                html.contains(
                    "The published 50/42 Hz is 16 % below 200/42 Hz: no stationary input"
                )
            );
            assert!(!html.contains("The published 50/256 Hz is"));
            assert!(html.contains("What could explain it"));
        });
    }

    #[test]
    fn without_published_values_there_is_no_such_section() {
        with_page(false, |html| {
            assert_eq!(nesting_errors(html), Vec::<String>::new());
            assert_eq!(html.matches("<table>").count(), 5);
            assert!(html.contains("href=\"#folding\"") && !html.contains("#published"));
            assert!(!html.contains("Unit assumed") && !html.contains("no stationary input"));
        });
    }

    #[test]
    fn the_nesting_check_sees_misnested_elements() {
        assert_eq!(
            nesting_errors("<table><tr><td>x</tr></table><p>"),
            [
                "</tr> closes something else",
                "</table> closes something else",
                "<table> not closed",
                "<p> not closed"
            ]
            .map(String::from)
        );
    }

    fn on_path(names: &[&str]) -> Option<PathBuf> {
        let path = std::env::var_os("PATH")?;
        std::env::split_paths(&path)
            .flat_map(|dir| names.iter().map(move |n| dir.join(n)))
            .find(|p| p.is_file())
    }

    /// `html` loaded from a file in `dir` by headless Chromium: the DOM it parsed and the
    /// console messages it logged. Chromium's profile and home are in `dir`; its output goes
    /// to files there (a pipe would fill while the guard below waits).
    fn render(chromium: &Path, dir: &Path, name: &str, html: &str) -> (String, Vec<String>) {
        let file = dir.join(name);
        std::fs::write(&file, html).unwrap();
        let (dom, log) = (file.with_extension("dom"), file.with_extension("log"));
        let mut child = Command::new(chromium)
            .args(["--headless", "--no-sandbox", "--disable-gpu"])
            .args(["--enable-logging=stderr", "--v=0", "--dump-dom"])
            .arg(format!("--user-data-dir={}", dir.join("profile").display()))
            .arg(format!("file://{}", file.display()))
            .env("HOME", dir)
            .env("XDG_CONFIG_HOME", dir)
            .env("XDG_CACHE_HOME", dir)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&dom).unwrap())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("chromium starts");
        // A guard against a browser that never exits, not a timing assertion.
        let mut status = None;
        for _ in 0..1200 {
            status = child.try_wait().unwrap();
            if status.is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let log = std::fs::read_to_string(&log).unwrap();
        let Some(status) = status else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("chromium did not exit within a minute:\n{log}");
        };
        assert!(status.success(), "{status}: {log}");
        let console = log
            .lines()
            .filter(|l| l.contains(":CONSOLE"))
            .map(String::from)
            .collect();
        (std::fs::read_to_string(&dom).unwrap(), console)
    }

    /// The page in a real browser: Chromium parses it into the tables and figures of the
    /// source and logs nothing to the console. A control page that logs an error shows the
    /// check sees one. Skipped, saying so, where no chromium is on PATH.
    #[test]
    fn renders_in_headless_chromium_without_console_messages() {
        let Some(chromium) = on_path(&["chromium", "chromium-browser"]) else {
            println!("SKIPPED: no chromium on PATH (Debian: apt-get install chromium)");
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let (_, console) = render(
            &chromium,
            dir.path(),
            "control.html",
            "<!DOCTYPE html><html><body><script>console.error('control')</script></body></html>",
        );
        assert!(console.iter().any(|l| l.contains("control")), "{console:?}");
        with_page(true, |html| {
            let (dom, console) = render(&chromium, dir.path(), "sweep.html", html);
            assert_eq!(console, Vec::<String>::new());
            assert_eq!(dom.matches("<table>").count(), 7, "{dom}");
            assert_eq!(dom.matches("<tr>").count(), html.matches("<tr>").count());
            assert_eq!(dom.matches("<svg").count(), 3);
            assert!(dom.contains("Unit assumed: deg/sqrt(s)"));
        });
    }
}

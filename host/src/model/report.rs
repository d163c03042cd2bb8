//! The workflow's outcome as JSON, as the simulator's model file (TOML), as a table, and as
//! an HTML page with the measured curve against the simulated band at every step, each step
//! with its evidence: every candidate's statistic, the simulated spread and z.

use super::evidence::Evidence;
use super::{
    Comparison, FAMILY_ALPHA, MONTE_CARLO_EXCEEDANCES, Model, Outcome, REFINE, Step, UNSURE_ABOVE,
    UNSURE_BELOW,
};
use crate::analysis::low_pass::LowPassSource;
use crate::record::Quantity;
use crate::report::html::{STYLE, escape};
use crate::report::plot::{self, Figure, Line, Panel};
use crate::report::sig;
use crate::report::table::aligned as aligned_table;
use serde_json::{Value, json};
use std::fmt::Write;

/// The group of the model file the channel belongs to.
fn group(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::Acceleration => "accel",
        _ => "gyro",
    }
}

/// The model's keys as in the simulator's model file (absent terms left out).
pub fn model_keys(model: &Model) -> Value {
    let t = &model.terms;
    let mut m = serde_json::Map::new();
    let mut put = |k: &str, v: f64| {
        if v != 0.0 {
            m.insert(k.to_string(), json!(v));
        }
    };
    put("noise_density", t.n);
    put("bias_instability", t.b);
    put("rate_random_walk", t.k);
    put("rate_ramp", t.r);
    put("quantization", t.q);
    if let Some(g) = t.gauss_markov {
        m.insert(
            "gauss_markov".into(),
            json!({"sigma": g.sigma, "tau_c": g.tau_c}),
        );
    }
    if let Some(s) = t.sinusoid {
        m.insert(
            "sinusoid".into(),
            json!({"amplitude": s.amplitude, "freq_hz": s.freq_hz}),
        );
    }
    if let Some(c) = model.temp_coeff {
        m.insert(
            "temperature".into(),
            json!({"bias_coeff": c, "scale_coeff": 0.0}),
        );
    }
    if let Some(c) = model.temp_rate_coeff {
        m.insert("temperature_rate_coeff".into(), json!(c));
    }
    if !model.lines.is_empty() {
        m.insert("lines".into(), json!(model.lines));
    }
    if let Some(lp) = &model.low_pass {
        m.insert(
            "low_pass".into(),
            json!({"cutoff_hz": lp.cutoff_hz, "shape": lp.shape, "source": lp.source, "filter": lp.filter, "unshaped_share": lp.unshaped_share}),
        );
    }
    Value::Object(m)
}

/// The model as a model file (TOML) with one group, in the simulator's terms: the white
/// density and the lines' amplitudes are those at the sensor filter's input
/// ([`LowPass::input_density`](crate::analysis::low_pass::LowPass::input_density),
/// [`LowPass::line_power_gain`](crate::analysis::low_pass::LowPass::line_power_gain)),
/// because `imunoise simulate` puts everything through the DLPF its `--bandwidth` selects;
/// the filter itself is a comment, and so is the white noise a fitted filter has after it
/// ([`LowPass::unshaped_share`](crate::analysis::low_pass::LowPass::unshaped_share)), which
/// the input density leaves out. Every named line is in `lines` (the first is also the
/// JSON's `sinusoid`, left out here so that it is not simulated twice). A temperature
/// coupling is written as `temperature = { bias_coeff, rate_coeff }`; the simulator then needs
/// a `[temperature]` profile, which this workflow does not estimate (it used the record's
/// measured temperature).
pub fn model_toml(quantity: Quantity, model: &Model) -> String {
    use toml::{Table, Value as Toml};
    let t = &model.terms;
    let low_pass = model.low_pass.as_ref();
    let mut keys = Table::new();
    let put = |keys: &mut Table, k: &str, v: f64| {
        if v != 0.0 {
            keys.insert(k.into(), Toml::Float(v));
        }
    };
    let n_in = low_pass.map_or(t.n, |lp| lp.input_density(t.n));
    put(&mut keys, "noise_density", n_in);
    put(&mut keys, "bias_instability", t.b);
    put(&mut keys, "rate_random_walk", t.k);
    put(&mut keys, "rate_ramp", t.r);
    put(&mut keys, "quantization", t.q);
    if let Some(g) = t.gauss_markov {
        let mut gm = Table::new();
        put(&mut gm, "sigma", g.sigma);
        gm.insert("tau_c".into(), Toml::Float(g.tau_c));
        keys.insert("gauss_markov".into(), Toml::Table(gm));
    }
    let coupled = model.temp_coeff.is_some() || model.temp_rate_coeff.is_some();
    if coupled {
        let mut c = Table::new();
        put(&mut c, "bias_coeff", model.temp_coeff.unwrap_or(0.0));
        put(&mut c, "rate_coeff", model.temp_rate_coeff.unwrap_or(0.0));
        keys.insert("temperature".into(), Toml::Table(c));
    }
    let lines: Vec<Toml> = model
        .lines
        .iter()
        .map(|l| {
            let gain = low_pass.map_or(1.0, |lp| lp.line_power_gain(l.freq_hz));
            let mut line = Table::new();
            line.insert(
                "amplitude".into(),
                Toml::Float(l.amplitude / gain.max(f64::MIN_POSITIVE).sqrt()),
            );
            line.insert("freq_hz".into(), Toml::Float(l.freq_hz));
            line.insert("width_hz".into(), Toml::Float(l.width_hz));
            Toml::Table(line)
        })
        .collect();
    if !lines.is_empty() {
        keys.insert("lines".into(), Toml::Array(lines));
    }
    let mut out = String::new();
    if let Some(lp) = low_pass {
        let _ = writeln!(
            out,
            "# The sensor's low-pass filter: {}; -3 dB at {} Hz. It is not a key:\n\
             # `imunoise simulate` applies the DLPF its --bandwidth selects. noise_density and\n\
             # the lines' amplitudes are at the filter's input; at its output, with any white noise\n\
             # after it, N = {} (the model's).",
            lp.filter,
            sig(lp.cutoff_hz, 4),
            sig(t.n, 4)
        );
    }
    if low_pass.is_none() {
        out.push_str(
            "# No sensor filter in the model: the values are the record's. `imunoise simulate`\n\
             # puts them through the DLPF its --bandwidth selects, whose aliases raise N at a\n\
             # bandwidth near or above half the --rate.\n",
        );
    }
    if coupled {
        out.push_str(
            "# The temperature coupling needs a [temperature] profile (initial, warmup, ramp,\n\
             # cycle), which the workflow does not estimate: it used the record's temperature.\n",
        );
    }
    let mut doc = Table::new();
    doc.insert(group(quantity).into(), Toml::Table(keys));
    match toml::to_string(&doc) {
        Ok(text) => out.push_str(&text),
        Err(e) => {
            let _ = writeln!(out, "# the model could not be written as TOML: {e}");
        }
    }
    out
}

fn comparison_json(c: &Comparison) -> Value {
    json!({
        "gap": c.gap,
        "disagreeing": c.disagreeing,
        "z": c.z,
        "band": c.band,
    })
}

/// The JSON document.
pub fn document(o: &Outcome) -> Value {
    let steps: Vec<Value> = o
        .steps
        .iter()
        .map(|s| {
            json!({
                "effect": s.effect,
                "at_naming": s.at_naming,
                "standard_errors": s.standard_errors,
                "description": s.description,
                "view": s.view,
                "round": s.round,
                "gap_before": s.gap_before,
                "gap_after": s.gap_after,
                "evidence": s.evidence,
                "rivals": s.rivals,
                "disagreeing_after": s.comparison.disagreeing,
            })
        })
        .collect();
    let fin = o.final_model();
    json!({
        "channel": o.channel,
        "unit": o.unit,
        "rate_hz": o.rate_hz,
        "samples": o.n,
        "realisations": o.realisations,
        "temperature_channel": o.temperature,
        "temperature_note": o.temperature_note,
        "rule": format!("an effect is named when the p-value of its statistic against the simulated realisations of the current model (a scaled chi-square matched to their mean and variance; for a spectral line, at least the line detector's own family-wise p-value) is below {FAMILY_ALPHA} / (candidates in the round) and the measured statistic exceeds every simulated one; deterministic effects (lines, ramp, temperature) are judged before stochastic terms; a round that names a spectral line names with it every further line the line search finds on the record without it whose statistic passes against the same simulations (steps[].round); of stochastic terms passing together, and of a passing Gauss-Markov process and the slow line found beside it whatever its own p-value, the one whose model brings the simulations closest to the record (the least Allan gap; steps[].rivals) is named, and a step standing for a stochastic term is taken back unless it shrinks the gap; after the search, each effect named before a later effect of the other kind (deterministic or stochastic) is tested again against the final model without it and dropped when no candidate, itself included, passes there (rechecked[]); a candidate whose statistic exceeds every simulated one with a p-value from {UNSURE_BELOW:e} times below to {UNSURE_ABOVE} times above the threshold is judged again on {REFINE} times as many simulations (evidence[].simulations); a ramp or temperature candidate with such a p-value, above every draw or not, is decided by the Monte Carlo p-value (1 + draws at or beyond its statistic) / (draws + 1) of enough bootstrap draws that the threshold lies {MONTE_CARLO_EXCEEDANCES} draws deep in their tail"),
        "gap_definition": "gap = RMS over the measured oadev taus of z, z = (ln ADEV_measured - mean ln ADEV_simulated) / std ln ADEV_simulated; |z| > 2 marks a disagreeing tau",
        "measured": {"tau": o.measured.tau, "adev": o.measured.dev},
        "baseline": model_keys(&o.baseline),
        "baseline_fit": o.baseline_fit,
        "gap_initial": o.initial.gap,
        "initial": comparison_json(&o.initial),
        "initial_evidence": o.initial_evidence,
        "steps": steps,
        "rechecked": o.rechecked,
        "gap_final": o.final_comparison().gap,
        "final": comparison_json(o.final_comparison()),
        "final_evidence": o.final_evidence,
        "stop": o.stop.to_string(),
        "stop_detail": o.stop,
        "model": model_keys(fin),
        "model_toml": model_toml(o.quantity, fin),
    })
}

/// A p-value with 3 significant digits (`1` when nothing in the record exceeds the noise).
pub(super) fn p_text(p: f64) -> String {
    if p >= 1.0 { "1".to_string() } else { sig(p, 3) }
}

/// A z with 2 decimals; `-` where it is infinite: a p of 1 (the view found nothing above
/// the noise) or of 0 (beyond double precision), which JSON also writes as null.
pub(super) fn z_text(z: f64) -> String {
    if z.is_finite() {
        format!("{z:.2}")
    } else {
        "-".to_string()
    }
}

/// A summary of the simulated values, or `-` where the view drew none (its test could not
/// run on this record).
fn simulated(e: &Evidence, text: String) -> String {
    if e.simulations == 0 {
        "-".to_string()
    } else {
        text
    }
}

/// The evidence of one round as aligned rows: candidate, view, measured statistic, the
/// simulated mean +- sd and maximum, how many simulations they come from, p, z, and the
/// verdict.
fn evidence_rows(evidence: &[Evidence], named: Option<&Step>, u: &str) -> String {
    let rows: Vec<Vec<String>> = evidence
        .iter()
        .map(|e| {
            let verdict = match (named, e.passes) {
                // An effect named by the gap in place of a random term did not pass its own test.
                (Some(s), _) if Some(s.at_naming) == e.effect => "named",
                (_, true) => "passes",
                _ => "-",
            };
            vec![
                e.effect
                    .map_or_else(|| format!("{}: none found", e.candidate), |x| x.describe(u)),
                e.view.describe().to_string(),
                sig(e.statistic, 4),
                simulated(e, format!("{} +- {}", sig(e.sim_mean, 3), sig(e.sim_sd, 3))),
                simulated(e, sig(e.sim_max, 3)),
                e.simulations.to_string(),
                p_text(e.p_value),
                z_text(e.z),
                verdict.to_string(),
            ]
        })
        .collect();
    aligned_table(
        &[
            "  candidate",
            "view",
            "statistic",
            "simulated mean +- sd",
            "sim max",
            "sims",
            "p",
            "z",
            "verdict",
        ],
        &rows
            .into_iter()
            .map(|mut r| {
                r[0] = format!("  {}", r[0]);
                r
            })
            .collect::<Vec<_>>(),
    )
}

/// The model's terms in one line, 4 significant digits.
fn model_line(m: &Model, u: &str) -> String {
    let t = &m.terms;
    let mut parts = vec![
        format!("N = {} {u}/sqrt(Hz)", sig(t.n, 4)),
        format!("B = {} {u}", sig(t.b, 4)),
        format!("K = {} {u}*sqrt(Hz)", sig(t.k, 4)),
        format!("Q = {} {u}*s", sig(t.q, 4)),
    ];
    if let Some(g) = t.gauss_markov {
        parts.push(format!(
            "Gauss-Markov sigma = {} {u}, tau_c = {} s",
            sig(g.sigma, 4),
            sig(g.tau_c, 4)
        ));
    }
    if t.r != 0.0 {
        parts.push(format!("R = {} {u}/s", sig(t.r, 4)));
    }
    for l in &m.lines {
        parts.push(format!(
            "line {} Hz, {} {u}, {} Hz wide",
            sig(l.freq_hz, 5),
            sig(l.amplitude, 4),
            sig(l.width_hz, 3)
        ));
    }
    if let Some(c) = m.temp_coeff {
        parts.push(format!("temperature {} {u}/degC", sig(c, 4)));
    }
    if let Some(c) = m.temp_rate_coeff {
        parts.push(format!("d(temperature)/dt {} {u}/(degC/s)", sig(c, 4)));
    }
    if let Some(lp) = &m.low_pass {
        parts.push(format!(
            "low-pass -3 dB at {} Hz{} ({})",
            sig(lp.cutoff_hz, 4),
            lp.shape
                .map_or(String::new(), |s| format!(", {}", s.describe())),
            match lp.source {
                LowPassSource::Settings => "from the sensor's settings",
                LowPassSource::Fitted => "fitted to the record",
            }
        ));
    }
    parts.join(", ")
}

/// A human summary: the baseline, each step with the evidence that named it, the final model.
pub fn table(o: &Outcome) -> String {
    let u = o.unit;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "channel {} ({} samples at {} Hz, {} s){}; {} simulated realisations per model",
        o.channel,
        o.n,
        sig(o.rate_hz, 6),
        sig(o.n as f64 / o.rate_hz, 4),
        o.temperature
            .as_ref()
            .map_or(String::new(), |t| format!(", temperature channel {t}")),
        o.realisations
    );
    if let Some(note) = &o.temperature_note {
        let _ = writeln!(s, "{note}");
    }
    let _ = writeln!(s, "baseline: {}", model_line(&o.baseline, u));
    let _ = writeln!(
        s,
        "Allan gap of the baseline (RMS z of ln ADEV against the simulations): {}",
        sig(o.initial.gap, 3)
    );
    disagreeing(&mut s, &o.initial);
    let _ = writeln!(
        s,
        "rule: name a candidate whose p-value against the simulations is below {FAMILY_ALPHA} / (candidates) and whose statistic exceeds every simulated one (lines, ramp, temperature first, the lines passing in a round named together; of random terms passing together, and of a passing Gauss-Markov process and the slow line beside it, the one closest to the record by the Allan gap; an effect named before one of the other kind is dropped when, tested again without it, nothing passes); a verdict near that line is simulated again {REFINE} times as often (a ramp or temperature one decided by the Monte Carlo p-value of enough bootstrap draws)"
    );
    for (i, st) in o.steps.iter().enumerate() {
        let _ = writeln!(
            s,
            "\nstep {}: {} (by the {}); Allan gap {} -> {}",
            i + 1,
            st.description,
            st.view.describe(),
            sig(st.gap_before, 3),
            sig(st.gap_after, 3)
        );
        s.push_str(&evidence_rows(&st.evidence, Some(st), u));
    }
    if !o.rechecked.is_empty() {
        let _ = writeln!(
            s,
            "\neffects tested again against the final model without them:"
        );
        for r in &o.rechecked {
            let _ = writeln!(s, "  {}", r.describe(u));
        }
    }
    let _ = writeln!(s, "\nagainst the final model:");
    s.push_str(&evidence_rows(&o.final_evidence, None, u));
    disagreeing(&mut s, o.final_comparison());
    let _ = writeln!(s, "stop: {}", o.stop);
    let _ = writeln!(s, "final model: {}", model_line(o.final_model(), u));
    let _ = write!(
        s,
        "as a model file:\n{}",
        model_toml(o.quantity, o.final_model())
    );
    s
}

fn disagreeing(s: &mut String, c: &Comparison) {
    for r in &c.disagreeing {
        let _ = writeln!(
            s,
            "  measured {} the simulations at tau {} .. {} s",
            if r.sign > 0 { "above" } else { "below" },
            sig(r.tau_lo, 3),
            sig(r.tau_hi, 3)
        );
    }
}

fn panel(o: &Outcome, title: String, c: &Comparison) -> Panel {
    let band = &c.band;
    let edge = |k: f64| -> Vec<f64> {
        band.mean_log
            .iter()
            .zip(&band.std_log)
            .map(|(m, s)| (m + k * s).exp())
            .collect()
    };
    Panel {
        title: format!("{title} (Allan gap {})", sig(c.gap, 3)),
        x_label: "tau (s)".into(),
        y_label: format!("Allan deviation ({})", o.unit),
        lines: vec![
            Line {
                label: "simulated (mean, +-2 sigma of ln)".into(),
                x: band.tau.clone(),
                y: band.mean_log.iter().map(|m| m.exp()).collect(),
                band: Some((edge(-2.0), edge(2.0))),
                color: 0,
                dashed: true,
            },
            Line {
                label: "measured".into(),
                x: o.measured.tau.clone(),
                y: o.measured.dev.clone(),
                band: None,
                color: 1,
                dashed: false,
            },
        ],
    }
}

/// The evidence of one round as an HTML table.
fn evidence_html(page: &mut String, evidence: &[Evidence], named: Option<&Step>, u: &str) {
    page.push_str(
        "<table><tr><th>candidate</th><th>view</th><th>statistic</th><th>simulated mean</th>\
         <th>simulated sd</th><th>simulated max</th><th>simulations</th><th>p</th><th>z</th><th>verdict</th></tr>\n",
    );
    for e in evidence {
        let verdict = match (named, e.passes) {
            (Some(s), _) if Some(s.at_naming) == e.effect => "<b>named</b>",
            (_, true) => "passes",
            _ => "",
        };
        let _ = writeln!(
            page,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{verdict}</td></tr>",
            escape(
                &e.effect
                    .map_or_else(|| format!("{}: none found", e.candidate), |x| x.describe(u))
            ),
            e.view.describe(),
            sig(e.statistic, 4),
            simulated(e, sig(e.sim_mean, 3)),
            simulated(e, sig(e.sim_sd, 3)),
            simulated(e, sig(e.sim_max, 3)),
            e.simulations,
            p_text(e.p_value),
            z_text(e.z)
        );
    }
    page.push_str("</table>\n");
}

/// The panel as a figure whose own title says what the panel shows, so that the panel's
/// caption (the step and its Allan gap) is not printed twice.
fn figure(page: &mut String, p: Panel) -> Result<(), plot::PlotError> {
    let svg = plot::svg_string(&Figure {
        title: "measured against the model's simulations".into(),
        panels: vec![p],
    })?;
    let _ = write!(page, "<div class=\"svg\">{svg}</div>");
    Ok(())
}

/// A self-contained HTML page: the baseline, then each step with its evidence table and the
/// measured curve against the new model's simulated band.
pub fn html(o: &Outcome) -> Result<String, plot::PlotError> {
    let u = o.unit;
    let title = format!("imunoise model — {}", escape(&o.channel));
    let mut page = format!(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>\
         <style>{STYLE}</style></head><body><h1>{title}</h1>\n"
    );
    let _ = writeln!(
        page,
        "<p>{} samples at {} Hz ({} s); {} simulated realisations per model. A candidate is named when the p-value of its statistic against the simulations of the current model is below {FAMILY_ALPHA} / (candidates in the round) and the statistic exceeds every simulated one; lines, ramp and temperature are judged before stochastic terms, and an effect named before one of the other kind (deterministic or random) is dropped when, tested again against the final model without it, nothing passes. A verdict near that line is judged again on {REFINE} times as many simulations.</p>",
        o.n,
        sig(o.rate_hz, 6),
        sig(o.n as f64 / o.rate_hz, 4),
        o.realisations
    );
    let _ = writeln!(
        page,
        "<h2>Baseline</h2><p>{}</p>",
        escape(&model_line(&o.baseline, u))
    );
    figure(&mut page, panel(o, "baseline".into(), &o.initial))?;
    for (i, st) in o.steps.iter().enumerate() {
        let _ = writeln!(
            page,
            "<h2>Step {}: {}</h2><p>Named by the {}. Evidence against the model before this step:</p>",
            i + 1,
            escape(&st.description),
            st.view.describe()
        );
        evidence_html(&mut page, &st.evidence, Some(st), u);
        // Lines named in one round share the comparison after it: one figure, after the last.
        if o.steps
            .get(i + 1)
            .is_some_and(|next| next.round == st.round)
        {
            continue;
        }
        figure(
            &mut page,
            panel(
                o,
                format!("step {}: + {}", i + 1, st.effect.kind()),
                &st.comparison,
            ),
        )?;
    }
    if !o.rechecked.is_empty() {
        let _ = writeln!(
            page,
            "<h2>Effects tested again</h2><p>Each against the final model without it:</p><ul>"
        );
        for r in &o.rechecked {
            let _ = writeln!(page, "<li>{}</li>", escape(&r.describe(u)));
        }
        let _ = writeln!(page, "</ul>");
    }
    let _ = writeln!(
        page,
        "<h2>Final model</h2><p>{}</p><p>Stop: {}</p>",
        escape(&model_line(o.final_model(), u)),
        escape(&o.stop.to_string())
    );
    evidence_html(&mut page, &o.final_evidence, None, u);
    let _ = writeln!(
        page,
        "<pre>{}</pre></body></html>",
        escape(&model_toml(o.quantity, o.final_model()))
    );
    Ok(page)
}

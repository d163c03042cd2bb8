//! The workflow's outcome as JSON, as the simulator's model file (TOML), as a table, and as
//! an HTML page with the measured curve against the simulated band at every step.

use super::{Comparison, GAP_ACCEPT, MIN_SHRINK, Model, Outcome, PENALTY_PER_PARAMETER};
use crate::record::Quantity;
use crate::report::html::escape;
use crate::report::plot::{self, Figure, Line, Panel};
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
    Value::Object(m)
}

/// The model as a model file (TOML) with one group. A temperature coefficient is written as
/// `temperature = { bias_coeff }`; the simulator then needs a `[temperature]` profile, which
/// this workflow does not estimate (it used the record's measured temperature).
pub fn model_toml(quantity: Quantity, model: &Model) -> String {
    let mut out = format!("[{}]\n", group(quantity));
    if let Value::Object(m) = model_keys(model) {
        for (k, v) in m {
            let text = match v {
                Value::Object(inner) => {
                    let parts: Vec<String> =
                        inner.iter().map(|(k, v)| format!("{k} = {v}")).collect();
                    format!("{{ {} }}", parts.join(", "))
                }
                other => other.to_string(),
            };
            let _ = writeln!(out, "{k} = {text}");
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
                "description": s.description,
                "gap_before": s.gap_before,
                "gap_after": s.gap_after,
                "candidates": s.candidates,
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
        "gap_definition": "gap = RMS over the measured oadev taus of z, z = (ln ADEV_measured - mean ln ADEV_simulated) / std ln ADEV_simulated; |z| > 2 marks a disagreeing tau",
        "rules": {
            "gap_accept": GAP_ACCEPT,
            "penalty_per_parameter": PENALTY_PER_PARAMETER,
            "min_shrink": MIN_SHRINK,
        },
        "measured": {"tau": o.measured.tau, "adev": o.measured.dev},
        "baseline": model_keys(&o.baseline),
        "baseline_fit": o.baseline_fit,
        "gap_initial": o.initial.gap,
        "initial": comparison_json(&o.initial),
        "steps": steps,
        "gap_final": o.final_comparison().gap,
        "final": comparison_json(o.final_comparison()),
        "stop": o.stop,
        "model": model_keys(&fin),
        "model_toml": model_toml(o.quantity, &fin),
    })
}

/// A human summary.
pub fn table(o: &Outcome) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "channel {} ({} samples at {} Hz)",
        o.channel, o.n, o.rate_hz
    );
    let _ = writeln!(
        s,
        "baseline: {}",
        model_toml(o.quantity, &o.baseline).replace('\n', "; ")
    );
    let _ = writeln!(
        s,
        "gap (RMS z of ln ADEV vs the simulations): {:.2}",
        o.initial.gap
    );
    for r in &o.initial.disagreeing {
        let _ = writeln!(
            s,
            "  disagrees {} tau {:.3}..{:.3} s",
            if r.sign > 0 { "above" } else { "below" },
            r.tau_lo,
            r.tau_hi
        );
    }
    for (i, st) in o.steps.iter().enumerate() {
        let _ = writeln!(
            s,
            "step {}: add {}: gap {:.2} -> {:.2}",
            i + 1,
            st.description,
            st.gap_before,
            st.gap_after
        );
    }
    let _ = writeln!(s, "stop: {}", o.stop);
    let _ = write!(
        s,
        "final model:\n{}",
        model_toml(o.quantity, &o.final_model())
    );
    s
}

fn panel(o: &Outcome, title: String, c: &Comparison) -> Panel {
    let band = &c.band;
    let lo: Vec<f64> = band
        .mean_log
        .iter()
        .zip(&band.std_log)
        .map(|(m, s)| (m - 2.0 * s).exp())
        .collect();
    let hi: Vec<f64> = band
        .mean_log
        .iter()
        .zip(&band.std_log)
        .map(|(m, s)| (m + 2.0 * s).exp())
        .collect();
    Panel {
        title: format!("{title} (gap {:.2})", c.gap),
        x_label: "tau (s)".into(),
        y_label: format!("Allan deviation ({})", o.unit),
        lines: vec![
            Line {
                label: "simulated (mean, +-2 sigma of ln)".into(),
                x: band.tau.clone(),
                y: band.mean_log.iter().map(|m| m.exp()).collect(),
                band: Some((lo, hi)),
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

/// A self-contained HTML page: one figure per stage.
pub fn html(o: &Outcome) -> Result<String, plot::PlotError> {
    let mut stages = vec![panel(o, "baseline".into(), &o.initial)];
    for (i, s) in o.steps.iter().enumerate() {
        stages.push(panel(
            o,
            format!("step {}: + {}", i + 1, s.effect.kind()),
            &s.comparison,
        ));
    }
    let mut page = String::from(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>imunoise model</title></head><body>",
    );
    let _ = write!(
        page,
        "<h1>Noise model of {}</h1><pre>{}</pre>",
        escape(&o.channel),
        escape(&table(o))
    );
    for p in stages {
        let svg = plot::svg_string(&Figure {
            title: p.title.clone(),
            panels: vec![p],
        })?;
        let _ = write!(page, "<div>{svg}</div>");
    }
    page.push_str("</body></html>\n");
    Ok(page)
}

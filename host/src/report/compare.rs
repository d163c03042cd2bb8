//! `imunoise compare`'s table: per channel and term, each session's value with its interval,
//! and which sessions differ significantly.

use super::{sig, sig_interval};
use crate::analysis::compare::{Comparison, TermRow};
use std::fmt::Write;

pub fn render(c: &Comparison) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "sessions:");
    for (i, label) in c.sessions.iter().enumerate() {
        let _ = writeln!(out, "  [{}] {label}", i + 1);
    }
    let _ = writeln!(
        out,
        "\nIEEE-952 terms per session, value [{} % interval]; verdict at family-wise level \
         alpha = {} per channel and term\ntest: {}\n",
        sig(c.confidence * 100.0, 3),
        c.alpha,
        c.test
    );
    for row in &c.rows {
        render_row(&mut out, row);
    }
    let differing: Vec<String> = c
        .rows
        .iter()
        .filter(|r| r.pairs.iter().any(|p| p.significant))
        .map(|r| format!("{} {:?}", r.channel, r.term))
        .collect();
    let _ = writeln!(
        out,
        "\n{} of {} rows differ significantly{}",
        differing.len(),
        c.rows.len(),
        if differing.is_empty() {
            String::new()
        } else {
            format!(": {}", differing.join(", "))
        }
    );
    if !c.skipped_channels.is_empty() {
        let _ = writeln!(
            out,
            "not in every session (not compared): {}",
            c.skipped_channels.join(", ")
        );
    }
    out
}

fn render_row(out: &mut String, row: &TermRow) {
    let _ = write!(out, "{:<6} {:?} {:<16}", row.channel, row.term, row.unit);
    for (i, value) in row.values.iter().enumerate() {
        let text = match value {
            Some(t) => {
                let [value, lo, hi] = sig_interval(t.value, t.lo, t.hi, 3);
                format!("{value} [{lo} .. {hi}]")
            }
            None => "no fit".to_string(),
        };
        let _ = write!(out, "  [{}] {text:<30}", i + 1);
    }
    let _ = writeln!(out, "  {}", verdict(row));
}

/// "consistent", or the significantly different pairs with their adjusted p.
pub fn verdict(row: &TermRow) -> String {
    let differing: Vec<String> = row
        .pairs
        .iter()
        .filter(|p| p.significant)
        .map(|p| {
            // Far out in the tail the p value underflows to 0: say how small it is instead.
            let p_text = if p.p_holm < 1e-15 {
                "< 1e-15".to_string()
            } else {
                sig(p.p_holm, 2)
            };
            format!(
                "[{}] vs [{}] (z {:.1}, p_holm {p_text})",
                p.a + 1,
                p.b + 1,
                p.z
            )
        })
        .collect();
    if differing.is_empty() {
        "consistent".to_string()
    } else {
        format!("DIFFER: {}", differing.join(", "))
    }
}

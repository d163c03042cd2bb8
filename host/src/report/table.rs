//! The human-readable summary `analyze` prints: the record, then per channel the fitted
//! IEEE-952 terms with intervals in SI and conventional units, the classic slope read-outs
//! and the PSD read-outs side by side. Every column names its unit.

use super::{NOISE_TERMS, sig, sig_interval, support_of, term_of};
use crate::analysis::fit::psd::PsdReadout;
use crate::analysis::fit::{NoiseFit, POOR_FIT_P};
use crate::analysis::low_pass::LowPassSource;
use crate::analysis::pipeline::{ChannelResult, Options};
use crate::analysis::units::{self, SensorKind};
use crate::record::Record;
use std::fmt::Write;

pub fn render(record: &Record, options: &Options, results: &[ChannelResult]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} channel(s), {} samples at {} Hz ({} s), {} data",
        record.source,
        results.len(),
        super::samples(record, results),
        sig(record.rate_hz, 6),
        sig(super::duration_s(record, results), 6),
        match options.data_type {
            crate::analysis::DataType::Rate => "rate",
            crate::analysis::DataType::Phase => "phase",
        }
    );
    // Every channel of a streamed record shares one ladder and one length: one line.
    let mut notes: Vec<&str> = results
        .iter()
        .filter_map(|r| r.computation.as_deref())
        .collect();
    notes.dedup();
    for note in notes {
        let _ = writeln!(out, "{note}");
    }
    let _ = writeln!(
        out,
        "\nIEEE-952 noise terms: weighted least squares on the overlapping Allan variance, \
         value [{} % interval]",
        sig(options.confidence * 100.0, 3)
    );
    for r in results {
        fit_rows(&mut out, r);
    }
    let _ = writeln!(
        out,
        "\nRead-outs for comparison (SI): slopes of the Allan deviation (N at tau = 1 s on the \
         -1/2 line, B = min / 0.664, K at tau = 3 s on the +1/2 line)"
    );
    let _ = writeln!(
        out,
        "{:<8} {:>10} {:>10} {:>10} {:>8}",
        "channel", "N slope", "B floor", "K slope", "tau_B s"
    );
    for r in results {
        readout_row(&mut out, r);
    }
    let _ = writeln!(
        out,
        "\nPSD read-outs (SI): 2 N^2 + 2 B^2/(2 pi f) + 2 K^2/(2 pi f)^2 fitted to the \
         multi-resolution one-sided PSD of the record without its lines over the band shown, \
         value [{} % interval, widened by sqrt(chi2/dof) where above 1]; \
         \"< x\": not resolved, upper bound",
        sig(options.confidence * 100.0, 3)
    );
    let _ = writeln!(
        out,
        "{:<8} {:>20} {:>26} {:>26} {:>26} {:>8}",
        "channel", "band Hz", "N psd", "B psd", "K psd", "chi2/dof"
    );
    for r in results {
        psd_row(&mut out, r);
    }
    out
}

fn fit_rows(out: &mut String, r: &ChannelResult) {
    let fit = match &r.fit {
        Ok(fit) => fit,
        Err(e) => {
            let _ = writeln!(out, "{:<8} no fit: {e}", r.name);
            return;
        }
    };
    let _ = writeln!(out, "{} ({}):", r.name, r.unit);
    for term in NOISE_TERMS {
        let t = term_of(fit, term);
        let si = units::si(r.kind, term, t.value);
        let [value, lo, hi] = sig_interval(t.value, t.lo, t.hi, 3);
        let line = format!("  {term:?} = {value} [{lo} .. {hi}] {}", si.unit);
        let conventional = if r.kind == SensorKind::Other {
            String::new()
        } else {
            let c = |v| units::conventional(r.kind, term, v);
            let [value, lo, hi] = sig_interval(c(t.value).value, c(t.lo).value, c(t.hi).value, 3);
            format!("= {value} [{lo} .. {hi}] {}", c(t.value).unit)
        };
        let detected = if support_of(fit, term).detected {
            ""
        } else {
            "  not detected"
        };
        let _ = writeln!(out, "{line:<52} {conventional}{detected}");
    }
    let _ = writeln!(out, "  {}", fit_note(fit));
    let _ = writeln!(out, "  {}", goodness_line(fit));
    if let Some(warning) = poor_fit_warning(&r.name, fit) {
        let _ = writeln!(out, "  WARNING: {warning}");
    }
    if let Some(line) = low_pass_note(fit) {
        let _ = writeln!(out, "  {line}");
    }
    line_rows(out, r);
}

/// The low-pass filter the fit modelled, and where it came from.
fn low_pass_note(fit: &NoiseFit) -> Option<String> {
    let lp = fit.low_pass.as_ref()?;
    Some(match lp.source {
        LowPassSource::Settings => format!(
            "low-pass {} Hz from the settings: {}",
            sig(lp.cutoff_hz, 4),
            lp.filter
        ),
        LowPassSource::Fitted => {
            let [cutoff, lo, hi] = sig_interval(lp.cutoff_hz, lp.cutoff_lo_hz, lp.cutoff_hi_hz, 3);
            let shape = lp.shape.map_or("generic shape", |s| s.describe());
            let knee = if lp.shape_approximate {
                "; its shape fitted to the knee only"
            } else {
                ""
            };
            format!(
                "low-pass fitted to the spectrum: cutoff {cutoff} Hz [{lo} .. {hi}] ({shape}{knee})"
            )
        }
    })
}

/// The channel's spectral lines, removed from the record before the fit, each value with its
/// standard error (`+-`; none for a pure tone's width).
fn line_rows(out: &mut String, r: &ChannelResult) {
    if r.lines.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "  spectral lines (removed before the fit): {:>10} {:>8} {:>12} {:>8} {:>10} {:>8} {:>12} {:>8} {:>9}",
        "freq Hz",
        "+-",
        format!("amp {}", r.unit),
        "+-",
        "width Hz",
        "+-",
        format!("power {}^2", r.unit),
        "z",
        "p"
    );
    for l in &r.lines {
        let e = &l.standard_errors;
        let _ = writeln!(
            out,
            "  {:>40} {:>10} {:>8} {:>12} {:>8} {:>10} {:>8} {:>12} {:>8} {:>9}",
            "",
            sig(l.freq_hz, 6),
            sig(e.freq_hz, 2),
            sig(l.amplitude, 3),
            sig(e.amplitude, 2),
            sig(l.width_hz, 3),
            e.width_hz.map_or("-".to_string(), |w| sig(w, 2)),
            sig(l.power, 3),
            sig(l.statistic, 3),
            p_text(l.p_value)
        );
    }
}

/// A family-wise p-value as printed: two significant digits, and `<1e-300` where the detector's
/// tail underflowed.
pub(super) fn p_text(p: f64) -> String {
    if p <= 0.0 {
        "<1e-300".to_string()
    } else {
        format!("{p:.1e}")
    }
}

fn fit_note(fit: &NoiseFit) -> String {
    format!(
        "({} taus from {} s, ~{} independent; a term not detected is 0 with its upper bound)",
        fit.points,
        sig(fit.tau_min, 3),
        sig(fit.effective_points, 2)
    )
}

/// The fit's goodness in one line: reduced chi-square, effective dof, p-value and the factor
/// the intervals were widened by.
pub fn goodness_line(fit: &NoiseFit) -> String {
    let g = &fit.goodness;
    if !g.reduced_chi2.is_finite() {
        return "goodness of fit: no residual degrees of freedom".into();
    }
    format!(
        "goodness of fit: reduced chi-square {} on {} effective dof, p = {}; intervals widened x{} (Birge ratio)",
        sig(g.reduced_chi2, 3),
        sig(g.dof, 2),
        sig(g.p_value, 2),
        sig(g.birge_ratio, 3)
    )
}

/// The warning for a channel whose curve the five-term model does not describe, if it is
/// one.
pub fn poor_fit_warning(channel: &str, fit: &NoiseFit) -> Option<String> {
    fit.goodness.poor().then(|| {
        format!(
            "{channel}: the five-term model does not describe the Allan curve (p = {} < {}); \
             its terms are biased by what it lacks (a tone, a Gauss-Markov or temperature \
             effect, a filter) beyond their intervals, which were widened x{}",
            sig(fit.goodness.p_value, 2),
            POOR_FIT_P,
            sig(fit.goodness.birge_ratio, 3)
        )
    })
}

/// The poor-fit warnings of every channel (for stderr).
pub fn fit_warnings(results: &[ChannelResult]) -> Vec<String> {
    results
        .iter()
        .filter_map(|r| poor_fit_warning(&r.name, r.fit.as_ref().ok()?))
        .collect()
}

fn readout_row(out: &mut String, r: &ChannelResult) {
    let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| sig(v, 3));
    let ro = &r.readouts;
    let _ = writeln!(
        out,
        "{:<8} {:>10} {:>10} {:>10} {:>8}",
        r.name,
        opt(ro.n.as_ref().map(|l| l.value)),
        opt(ro.b.as_ref().map(|b| b.value)),
        opt(ro.k.as_ref().map(|l| l.value)),
        opt(ro.b.as_ref().map(|b| b.tau)),
    );
}

fn psd_row(out: &mut String, r: &ChannelResult) {
    let p = match &r.psd_terms {
        Ok(p) => p,
        Err(e) => {
            let _ = writeln!(out, "{:<8} no PSD read-outs: {e}", r.name);
            return;
        }
    };
    let cell = |x: &PsdReadout| {
        if x.resolved() {
            let [value, lo, hi] = sig_interval(x.value, x.lo, x.hi, 3);
            format!("{value} [{lo}..{hi}]")
        } else {
            format!("< {}", sig(x.hi, 2))
        }
    };
    let _ = writeln!(
        out,
        "{:<8} {:>20} {:>26} {:>26} {:>26} {:>8}",
        r.name,
        format!("{}..{}", sig(p.f_min, 2), sig(p.f_max, 3)),
        cell(&p.n),
        cell(&p.b),
        cell(&p.k),
        sig(p.reduced_chi2, 3)
    );
}

/// Rows under a header, each column padded to its widest cell, two spaces apart (the
/// catalog listings: sessions, calibrations).
pub fn aligned(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &mut dyn Iterator<Item = &str>| {
        let padded: Vec<String> = cells
            .zip(&widths)
            .map(|(c, &w)| format!("{c:<w$}"))
            .collect();
        format!("{}\n", padded.join("  ").trim_end())
    };
    let mut out = line(&mut header.iter().copied());
    for row in rows {
        out += &line(&mut row.iter().map(String::as_str));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::fit::{FitOptions, fit_allan_with};
    use crate::analysis::low_pass::{LowPass, LowPassSource, Shape};

    /// The note names the shape the spectrum chose, not a fixed one.
    #[test]
    fn the_low_pass_note_names_the_fitted_shape() {
        let mut lp = LowPass::generic(Shape::Butterworth4, 10.0, 50.0).unwrap();
        lp.source = LowPassSource::Fitted;
        let tau: Vec<f64> = (0..12).map(|i| 0.5 * 2f64.powi(i)).collect();
        let avar: Vec<f64> = tau.iter().map(|t| 1e-6 / t).collect();
        let edf = vec![100.0; tau.len()];
        let options = FitOptions {
            low_pass: Some(lp),
            ..FitOptions::default()
        };
        let fit = fit_allan_with(&tau, &avar, &edf, &options).unwrap();
        let note = low_pass_note(&fit).unwrap();
        assert!(
            note.ends_with("(fourth-order Butterworth low-pass)"),
            "{note}"
        );
    }
}

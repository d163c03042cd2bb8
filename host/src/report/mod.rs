//! Results for people and machines: the text table, the JSON document, figures (SVG/PNG),
//! Kalibr's IMU YAML, a self-contained HTML report, a sweep's tables and page, and samples
//! as CSV.

pub mod compare;
pub mod csv;
pub mod figures;
pub mod filter;
pub mod html;
pub mod json;
pub mod kalibr;
pub mod plot;
pub mod sweep_page;
pub mod sweep_table;
pub mod table;
pub mod yaml;

use crate::analysis::fit::{NoiseFit, Support, Term};
use crate::analysis::pipeline::{ChannelResult, Options};
use crate::analysis::units::NoiseTerm;
use crate::record::Record;
use serde_json::{Value, json};

/// The IEEE-952 terms in the order they are printed.
pub const NOISE_TERMS: [NoiseTerm; 5] = [
    NoiseTerm::N,
    NoiseTerm::B,
    NoiseTerm::K,
    NoiseTerm::Q,
    NoiseTerm::R,
];

pub fn term_of(fit: &NoiseFit, term: NoiseTerm) -> &Term {
    match term {
        NoiseTerm::Q => &fit.q,
        NoiseTerm::N => &fit.n,
        NoiseTerm::B => &fit.b,
        NoiseTerm::K => &fit.k,
        NoiseTerm::R => &fit.r,
    }
}

/// Whether the data support `term` (see [`crate::analysis::fit::fit_allan_with`]).
pub fn support_of(fit: &NoiseFit, term: NoiseTerm) -> &Support {
    let s = &fit.support;
    match term {
        NoiseTerm::Q => &s.q,
        NoiseTerm::N => &s.n,
        NoiseTerm::B => &s.b,
        NoiseTerm::K => &s.k,
        NoiseTerm::R => &s.r,
    }
}

/// Samples per channel: the results', which count them when the record was analysed without
/// being held in memory (its channels then hold no samples).
pub fn samples(record: &Record, results: &[ChannelResult]) -> usize {
    results.first().map_or(record.len(), |r| r.n)
}

/// The record's length, s ([`samples`] at its rate).
pub fn duration_s(record: &Record, results: &[ChannelResult]) -> f64 {
    samples(record, results) as f64 / record.rate_hz
}

/// The conventions every output states, so no number is read in the wrong units.
pub fn conventions(options: &Options) -> Value {
    json!({
        "units": "SI; u is the channel's unit (rad/s gyro, m/s^2 accel): N in u/sqrt(Hz), B in u, K in u*sqrt(Hz), Q in u*s, R in u/s",
        "model": "IEEE Std 952-1997 Annex C: AVAR(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2",
        "intervals": format!("two-sided {} confidence: chi-squared with the equivalent degrees of freedom (Greenhall's algorithm; SP 1065 for totdev), noise type from the fitted model's dominant term at the taus it was fitted to, identified per tau elsewhere", options.confidence),
        "psd": "one-sided Welch estimate (as scipy.signal.welch), u^2/Hz; white rate noise with Allan coefficient N has one-sided PSD 2 N^2, so N = sqrt(S/2)",
        "noise_density": "N is the two-sided density (the Allan deviation at tau = 1 s on the -1/2 line), which is Kalibr's noise density; a datasheet's one-sided density is sqrt(2) N",
        "lines": options.lines.map(|l| format!("spectral lines of the full-record periodogram against a running-median background, family-wise false-alarm probability {} per channel; removed from the record before the Allan curve the noise fit uses; amplitude = sqrt(2 power), width = the interquartile range of the line's power (a Lorentzian's full width at half maximum; 0 for a pure tone), statistic = the excess power in standard deviations of the background's, p_value = the family-wise false-alarm probability at which the search would just have reported the line (its most unlikely test's tail probability times the tests the budget is split among; 0 where it underflows); standard_errors = one standard deviation of freq_hz, amplitude and width_hz (a pure tone: the Cramer-Rao bounds at the background there, its width null; a wider line: the spread of its measurement over 100 periodograms drawn from the measured line and background)", l.false_alarm)),
    })
}

/// `x` with `digits` significant digits: plain from 0.001 up to `digits` integer digits,
/// scientific otherwise (so no digit is printed that is not significant).
pub fn sig(x: f64, digits: usize) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let exp = x.abs().log10().floor() as i32;
    if (-3..digits as i32).contains(&exp) {
        let decimals = (digits as i32 - 1 - exp).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{:.*e}", digits.saturating_sub(1), x)
    }
}

/// A value and its interval's bounds, `[value, lo, hi]`, each with `digits` significant
/// digits, or with as many more (up to 17, a double's precision) as it takes for a bound
/// that differs from the value to print differently: a narrow interval reads as narrow
/// (`0.9110 [0.9105..0.9118]`), never as none (`0.911 [0.91..0.91]`).
pub fn sig_interval(value: f64, lo: f64, hi: f64, digits: usize) -> [String; 3] {
    let mut digits = digits.max(1);
    loop {
        let text = [value, lo, hi].map(|x| sig(x, digits));
        let collapsed = (lo != value && text[1] == text[0]) || (hi != value && text[2] == text[0]);
        if !collapsed || digits >= 17 {
            return text;
        }
        digits += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::{sig, sig_interval};

    #[test]
    fn intervals_show_their_width() {
        let next = f64::from_bits(1.0f64.to_bits() + 1);
        // (value, lo, hi, digits asked for) and what is printed.
        type Case = ((f64, f64, f64, usize), [&'static str; 3]);
        let cases: [Case; 8] = [
            // Wide enough for the digits asked for: as asked.
            ((0.911, 0.85, 0.97, 3), ["0.911", "0.850", "0.970"]),
            // Bounds that round apart from the value: as asked; those that round onto it:
            // more digits, the same for all three.
            ((0.911, 0.9105, 0.9118, 3), ["0.911", "0.910", "0.912"]),
            ((0.911, 0.9106, 0.9114, 3), ["0.9110", "0.9106", "0.9114"]),
            (
                (0.911, 0.91099, 0.91102, 2),
                ["0.91100", "0.91099", "0.91102"],
            ),
            // Scientific notation widens the same way.
            (
                (1.2345e-6, 1.2341e-6, 1.2349e-6, 3),
                ["1.2345e-6", "1.2341e-6", "1.2349e-6"],
            ),
            // A bound that is the value (an interval closed on one side) needs no more.
            ((0.5, 0.5, 0.6, 2), ["0.50", "0.50", "0.60"]),
            ((0.0, 0.0, 1e-9, 3), ["0", "0", "1.00e-9"]),
            // A bound one double away: 17 digits, a double's whole precision, tell them apart.
            (
                (1.0, 1.0, next, 3),
                [
                    "1.0000000000000000",
                    "1.0000000000000000",
                    "1.0000000000000002",
                ],
            ),
        ];
        for ((value, lo, hi, digits), expected) in cases {
            assert_eq!(
                sig_interval(value, lo, hi, digits),
                expected,
                "{value} {lo} {hi}"
            );
        }
        // Not finite: as sig prints it.
        assert_eq!(sig_interval(f64::NAN, 0.0, 1.0, 3)[0], "NaN");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.0123456, 3), "0.0123");
        assert_eq!(sig(123.456, 3), "123");
        assert_eq!(sig(1.23456e-6, 3), "1.23e-6");
        assert_eq!(sig(98765.0, 3), "9.88e4");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(1234.0, 3), "1.23e3");
        assert_eq!(sig(-0.5, 2), "-0.50");
    }
}

//! Results for people and machines: the text table, the JSON document, figures (SVG/PNG),
//! Kalibr's IMU YAML and a self-contained HTML report.

pub mod compare;
pub mod figures;
pub mod filter;
pub mod html;
pub mod json;
pub mod kalibr;
pub mod plot;
pub mod progress;
pub mod table;
pub mod yaml;

use crate::analysis::fit::{NoiseFit, Support, Term};
use crate::analysis::pipeline::Options;
use crate::analysis::units::NoiseTerm;
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

/// The conventions every output states, so no number is read in the wrong units.
pub fn conventions(options: &Options) -> Value {
    json!({
        "units": "SI; u is the channel's unit (rad/s gyro, m/s^2 accel): N in u/sqrt(Hz), B in u, K in u*sqrt(Hz), Q in u*s, R in u/s",
        "model": "IEEE Std 952-1997 Annex C: AVAR(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2",
        "intervals": format!("two-sided {} confidence: chi-squared with the equivalent degrees of freedom (Greenhall's algorithm; SP 1065 for totdev), noise type from the fitted model's dominant term at the taus it was fitted to, identified per tau elsewhere", options.confidence),
        "psd": "one-sided Welch estimate (as scipy.signal.welch), u^2/Hz; white rate noise with Allan coefficient N has one-sided PSD 2 N^2, so N = sqrt(S/2)",
        "noise_density": "N is the two-sided density (the Allan deviation at tau = 1 s on the -1/2 line), which is Kalibr's noise density; a datasheet's one-sided density is sqrt(2) N",
        "lines": options.lines.map(|l| format!("spectral lines of the full-record periodogram against a running-median background, family-wise false-alarm probability {} per channel; removed from the record before the Allan curve the noise fit uses; amplitude = sqrt(2 power), width = the interquartile range of the line's power (a Lorentzian's full width at half maximum; 0 for a pure tone), statistic = the excess power in standard deviations of the background's", l.false_alarm)),
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

#[cfg(test)]
mod tests {
    use super::sig;

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

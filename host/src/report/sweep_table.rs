//! The text tables of a settings sweep (`imunoise sweep`, `imunoise demo`): N, B and K per
//! axis per setting with intervals, then the gyro's N beside a published table, the
//! datasheet and the folding prediction. The same content as the page
//! ([`super::sweep_page`]), for a terminal.

use super::sweep_page::{GyroNoise, Setting};
use super::{sig, sig_interval};
use crate::analysis::fit::Term;
use crate::analysis::units::{self, NoiseTerm};
use protocol::mpu6050::Hz;
use std::fmt::Write as _;

/// The unit assumed for the settings study's Table 2: deg/sqrt(s), i.e. deg/s/sqrt(Hz) as
/// the Allan deviation at tau = 1 s (the two-sided density N). Why: the datasheet's rate
/// noise density, 0.005 deg/s/sqrt(Hz) one-sided, is N = 0.00354 deg/sqrt(s); the study's
/// 200 Hz / 42 Hz value, where nothing folds, is 0.00337 (-5 %). Read as deg/sqrt(h) it
/// would be 63 times quieter than the datasheet, as rad/sqrt(s) 55 times noisier, and as the
/// standard deviation of 200 Hz samples (deg/s) 15 times quieter than the datasheet's 0.05
/// deg/s rms.
pub const PAPER_ARW_UNIT: &str = "deg/sqrt(s)";

/// N, B, K per axis per setting, conventional units, with intervals; then the study's
/// Table 2 beside the gyro N ([`paper_table`]).
pub fn table(settings: &[Setting], gyro: &[GyroNoise]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\nNoise terms per setting (IEEE-952 fit to the overlapping Allan variance, 68.3 % intervals)"
    );
    let _ = writeln!(
        out,
        "{:<16} {:<5} {:>30} {:>30} {:>30}",
        "setting", "axis", "N", "B", "K"
    );
    for row in settings {
        let label = format!(
            "{}/{} Hz{}",
            Hz(row.rate_hz),
            Hz(row.bandwidth_hz),
            if row.folds { "*" } else { "" }
        );
        for r in row.results {
            let Ok(fit) = &r.fit else { continue };
            if r.kind == units::SensorKind::Other {
                continue;
            }
            let cell = |term: NoiseTerm, t: &Term| {
                let c = |v| units::conventional(r.kind, term, v);
                let [value, lo, hi] =
                    sig_interval(c(t.value).value, c(t.lo).value, c(t.hi).value, 3);
                format!("{value} [{lo}..{hi}] {}", c(t.value).unit)
            };
            let _ = writeln!(
                out,
                "{:<16} {:<5} {:>30} {:>30} {:>30}",
                label,
                r.name,
                cell(NoiseTerm::N, &fit.n),
                cell(NoiseTerm::B, &fit.b),
                cell(NoiseTerm::K, &fit.k)
            );
        }
    }
    let _ = writeln!(
        out,
        "* bandwidth above half the output rate: noise above the Nyquist frequency folds back"
    );
    for row in settings {
        let _ = writeln!(
            out,
            "session {} '{}': {} samples lost",
            row.session_id, row.session_name, row.samples_lost
        );
    }
    out + &paper_table(gyro)
}

/// The gyro's N per setting beside the study's Table 2 (an MPU-6050's; a board with
/// another gyro has no published values), as text: absolute values, and ratios to the
/// 200 Hz / 42 Hz setting (where nothing folds) when it is in the sweep.
pub fn paper_table(rows: &[GyroNoise]) -> String {
    let published = rows.iter().any(|r| r.published.is_some());
    let mut out = match published {
        true => format!(
            "\nGyro ARW beside the settings study's Table 2, in {PAPER_ARW_UNIT} (= deg/s/sqrt(Hz), \
             the Allan deviation at 1 s; the study's unit is assumed: docs/signal_chain.md)\n"
        ),
        false => format!(
            "\nGyro ARW beside the datasheet and the folding prediction, in {PAPER_ARW_UNIT} (= \
             deg/s/sqrt(Hz), the Allan deviation at 1 s)\n"
        ),
    };
    let _ = writeln!(
        out,
        "{:<12} {:>8} {:>10} {:>8} {:>8} {:>28} | {:>8} {:>6} {:>6}",
        "setting",
        "folding",
        "datasheet",
        "study",
        "vs ds",
        "this sweep [68.3 %]",
        "folding",
        "study",
        "sweep"
    );
    let reference = rows
        .iter()
        .find(|r| r.rate_hz == 200.0 && r.bandwidth_hz == 42.0);
    let ratio = |v: Option<f64>, r: Option<f64>| match (v, r) {
        (Some(v), Some(r)) if r > 0.0 => format!("{:.2}", v / r),
        _ => "-".to_string(),
    };
    for r in rows {
        let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| sig(v, 3));
        let vs_datasheet = r.published.map_or_else(
            || "-".to_string(),
            |p| format!("{:+.0} %", (p / r.datasheet - 1.0) * 100.0),
        );
        let sweep = r.measured.map_or_else(
            || "-".to_string(),
            |t| {
                let [value, lo, hi] = sig_interval(t.value, t.lo, t.hi, 4);
                format!("{value} [{lo}..{hi}]")
            },
        );
        let _ = writeln!(
            out,
            "{:<12} {:>8.3} {:>10} {:>8} {:>8} {:>28} | {:>8} {:>6} {:>6}",
            format!("{}/{} Hz", Hz(r.rate_hz), Hz(r.bandwidth_hz)),
            r.folding,
            sig(r.datasheet, 3),
            opt(r.published),
            vs_datasheet,
            sweep,
            ratio(Some(r.folding), reference.map(|x| x.folding)),
            ratio(r.published, reference.and_then(|x| x.published)),
            ratio(
                r.measured.map(|t| t.value),
                reference.and_then(|x| x.measured.map(|t| t.value))
            ),
        );
    }
    // Each row's datasheet value is N0 times its folding.
    let n0 = rows.first().map_or(0.0, |r| r.datasheet / r.folding);
    let _ = writeln!(
        out,
        "folding: predicted N / N0; datasheet: {} deg/s/sqrt(Hz) one-sided (N0 = {}) x \
         folding; vs ds: study / datasheet; after |: ratios to 200/42 Hz.",
        sig(n0 * 2f64.sqrt(), 3),
        sig(n0, 3)
    );
    if published {
        out.push_str(
            "The study agrees with datasheet x folding within 5 % at 200/42 and 50/256, not at \
             200/256 or 50/42; its 50/42 below 200/42 is impossible for any stationary input \
             through one filter (docs/signal_chain.md).\n",
        );
    }
    out
}

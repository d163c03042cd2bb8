//! Repeatability: do several sessions' fitted IEEE-952 terms differ by more than their
//! intervals allow? (The settings study's check across runs and days, docs/references.md.)
//!
//! **The test.** For one channel and one term, each pair of sessions (a, b) is compared by a
//! two-sided z-test, with each estimate's standard error recovered from its confidence
//! interval at confidence c (z_c the two-sided normal quantile of c):
//!
//! - both intervals above zero: on the log of the value, `se = ln(hi / lo) / (2 z_c)` and
//!   `z = (ln v_a - ln v_b) / sqrt(se_a^2 + se_b^2)`. The fit's intervals are chi-squared
//!   shaped (`fit/allan.rs`, `interval`), i.e. close to symmetric in the log, so the log is the
//!   scale on which they are most nearly normal;
//! - either interval reaching zero (a term the record does not resolve): on the squared
//!   value theta = v^2, which is what the fit estimates linearly and whose interval is
//!   `theta +- z_c sd` cut at 0, so `se = (hi^2 - v^2) / z_c` (the upper half-width, the
//!   half the cut at 0 leaves intact) and `z = (theta_a - theta_b) / sqrt(se_a^2 + se_b^2)`.
//!
//! `p = 2 (1 - Phi(|z|))`. With more than two sessions, the k(k-1)/2 pairs of one channel and
//! term are one family, and Holm–Bonferroni (Holm 1979) holds its family-wise error rate at
//! the level alpha: sort the p values, multiply the i-th smallest (from 1) by m - i + 1, take
//! the running maximum (capped at 1); a pair differs significantly when that adjusted p is at
//! most alpha. Each channel and term is its own family (a difference in gx's N is a separate
//! question from one in az's K).
//!
//! **Like with like.** Every session is fitted from the same shortest tau ([`align_fit_start`]):
//! where a sensor's low-pass filter shaped the short taus, the automatic fit start moves by a
//! tau step or two from record to record, and N moves with it by about 2 % — ten times its
//! standard error on an hour at 200 Hz, so unaligned fits of one sensor would be told apart.
//!
//! The standard errors are the fit's own (sandwich covariance with the modelled correlation
//! between taus): statistical only. A session with an effect the model lacks (a warm-up, a
//! Gauss-Markov bias) is biased beyond them and will be flagged, which is what a
//! repeatability check should do.

use crate::analysis::fit::{self, FitOptions, NoiseFit, Term};
use crate::analysis::pipeline::ChannelResult;
use crate::analysis::units::{NoiseTerm, si_unit};
use crate::report::{NOISE_TERMS, term_of};
use serde::Serialize;
use statrs::distribution::{ContinuousCDF, Normal};

/// One session's fitted channels, under a label the user recognises (id, name or file).
pub struct SessionFits<'a> {
    pub label: String,
    pub channels: &'a [ChannelResult],
}

/// Everything `imunoise compare` reports.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub sessions: Vec<String>,
    /// Family-wise significance level of the verdicts.
    pub alpha: f64,
    /// Confidence of the intervals the standard errors were recovered from.
    pub confidence: f64,
    pub test: &'static str,
    pub rows: Vec<TermRow>,
    /// Channels not in every session (not compared).
    pub skipped_channels: Vec<String>,
}

/// One channel's term across the sessions.
#[derive(Debug, Clone, Serialize)]
pub struct TermRow {
    pub channel: String,
    pub term: NoiseTerm,
    pub unit: &'static str,
    /// Per session, in the order of [`Comparison::sessions`]; `None` when the fit failed.
    pub values: Vec<Option<Term>>,
    pub pairs: Vec<PairTest>,
}

impl TermRow {
    /// Indices of the sessions in at least one significantly different pair.
    pub fn flagged(&self) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .pairs
            .iter()
            .filter(|p| p.significant)
            .flat_map(|p| [p.a, p.b])
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// The z-test of one pair of sessions.
#[derive(Debug, Clone, Serialize)]
pub struct PairTest {
    pub a: usize,
    pub b: usize,
    /// `log` or `squared`: the scale of the test (module documentation).
    pub scale: &'static str,
    pub z: f64,
    pub p: f64,
    /// Holm–Bonferroni adjusted p within the channel's term.
    pub p_holm: f64,
    pub significant: bool,
}

/// The one-line statement of the test, for tables and JSON.
pub const TEST: &str = "two-sided z-test per pair: on ln(value) with se = ln(hi/lo)/(2 z_c) when both intervals are above 0, else on value^2 with se = (hi^2 - value^2)/z_c; Holm-Bonferroni over the pairs of each channel and term";

/// Compare every channel present in all sessions, term by term: N, B and K always, Q and R
/// when some session's fit has them above zero.
pub fn compare(sessions: &[SessionFits], alpha: f64, confidence: f64) -> Comparison {
    let z_c = Normal::standard().inverse_cdf(0.5 + confidence / 2.0);
    let first = sessions.first().map_or(&[][..], |s| s.channels);
    let in_all = |name: &str| {
        sessions
            .iter()
            .all(|s| s.channels.iter().any(|c| c.name == name))
    };
    let mut rows = Vec::new();
    for channel in first.iter().filter(|c| in_all(&c.name)) {
        let fits: Vec<Option<&NoiseFit>> = sessions
            .iter()
            .map(|s| {
                s.channels
                    .iter()
                    .find(|c| c.name == channel.name)
                    .and_then(|c| c.fit.as_ref().ok())
            })
            .collect();
        for term in NOISE_TERMS {
            let values: Vec<Option<Term>> =
                fits.iter().map(|f| f.map(|f| *term_of(f, term))).collect();
            let always = matches!(term, NoiseTerm::N | NoiseTerm::B | NoiseTerm::K);
            if !always && !values.iter().flatten().any(|t| t.value > 0.0) {
                continue;
            }
            rows.push(TermRow {
                channel: channel.name.clone(),
                term,
                unit: si_unit(channel.kind, term),
                pairs: pair_tests(&values, z_c, alpha),
                values,
            });
        }
    }
    let mut skipped_channels: Vec<String> = sessions
        .iter()
        .flat_map(|s| s.channels.iter().map(|c| c.name.clone()))
        .filter(|name| !in_all(name))
        .collect();
    skipped_channels.sort();
    skipped_channels.dedup();
    Comparison {
        sessions: sessions.iter().map(|s| s.label.clone()).collect(),
        alpha,
        confidence,
        test: TEST,
        rows,
        skipped_channels,
    }
}

/// Refit every channel of every session from the latest fit start among them (the longest
/// `tau_min`), so all fits cover the same taus; returns that tau (s), or `None` when no
/// channel has a fit. The sessions must be rate data (phase points = samples + 1).
pub fn align_fit_start(sessions: &mut [Vec<ChannelResult>], confidence: f64) -> Option<f64> {
    let start = sessions
        .iter()
        .flatten()
        .filter_map(|c| c.fit.as_ref().ok())
        .map(|f| f.tau_min)
        .reduce(f64::max)?;
    let options = FitOptions {
        confidence,
        tau_min: Some(start),
        ..FitOptions::default()
    };
    for channel in sessions.iter_mut().flatten() {
        let behind = channel
            .fit
            .as_ref()
            .is_ok_and(|f| f.tau_min < start * (1.0 - 1e-9));
        if behind {
            let options = FitOptions {
                low_pass: channel.fit.as_ref().ok().and_then(|f| f.low_pass.clone()),
                ..options.clone()
            };
            channel.fit = fit::fit_deviation(&channel.fit_curve.deviation, channel.n + 1, &options);
        }
    }
    Some(start)
}

/// Every pair of sessions with a value, tested and Holm-adjusted as one family.
fn pair_tests(values: &[Option<Term>], z_c: f64, alpha: f64) -> Vec<PairTest> {
    let mut pairs = Vec::new();
    for a in 0..values.len() {
        for b in a + 1..values.len() {
            if let (Some(ta), Some(tb)) = (&values[a], &values[b]) {
                let (scale, z) = z_score(ta, tb, z_c);
                let p = 2.0 * Normal::standard().sf(z.abs());
                pairs.push(PairTest {
                    a,
                    b,
                    scale,
                    z,
                    p,
                    p_holm: p,
                    significant: false,
                });
            }
        }
    }
    let adjusted = holm(&pairs.iter().map(|p| p.p).collect::<Vec<_>>());
    for (pair, p_holm) in pairs.iter_mut().zip(adjusted) {
        pair.p_holm = p_holm;
        pair.significant = p_holm <= alpha;
    }
    pairs
}

/// The z statistic of `a` against `b` and the scale it was computed on (module docs).
pub fn z_score(a: &Term, b: &Term, z_c: f64) -> (&'static str, f64) {
    let resolved = |t: &Term| t.lo > 0.0 && t.hi > t.lo;
    if resolved(a) && resolved(b) {
        let se = |t: &Term| (t.hi / t.lo).ln() / (2.0 * z_c);
        let z = (a.value.ln() - b.value.ln()) / se(a).hypot(se(b));
        return ("log", z);
    }
    let se = |t: &Term| (t.hi * t.hi - t.value * t.value) / z_c;
    let denominator = se(a).hypot(se(b));
    let difference = a.value * a.value - b.value * b.value;
    let z = if denominator > 0.0 {
        difference / denominator
    } else {
        0.0
    };
    ("squared", z)
}

/// Holm–Bonferroni adjusted p values (Holm 1979), in the order given: the i-th smallest
/// (i from 0) times m - i, running maximum, capped at 1.
pub fn holm(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&i, &j| p[i].total_cmp(&p[j]));
    let mut adjusted = vec![0.0; m];
    let mut running = 0.0f64;
    for (rank, &i) in order.iter().enumerate() {
        running = running.max(((m - rank) as f64 * p[i]).min(1.0));
        adjusted[i] = running;
    }
    adjusted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holm_matches_a_hand_computed_example() {
        // p = (0.01, 0.04, 0.03), m = 3: sorted 0.01*3 = 0.03, 0.03*2 = 0.06, 0.04*1 = 0.04
        // -> running max 0.06; in the original order (0.03, 0.06, 0.06).
        let adjusted = holm(&[0.01, 0.04, 0.03]);
        let expected = [0.03, 0.06, 0.06];
        for (a, e) in adjusted.iter().zip(expected) {
            assert!((a - e).abs() < 1e-15, "{adjusted:?}");
        }
        assert_eq!(holm(&[0.6, 0.7]), vec![1.0, 1.0]);
    }

    #[test]
    fn log_scale_z_from_symmetric_log_intervals() {
        // Intervals exp(+-0.1) around 1 and around e^0.3 at z_c = 1: se = 0.1 each, so
        // z = -0.3 / (0.1 sqrt 2).
        let term = |ln_v: f64| Term {
            value: ln_v.exp(),
            lo: (ln_v - 0.1).exp(),
            hi: (ln_v + 0.1).exp(),
        };
        let (scale, z) = z_score(&term(0.0), &term(0.3), 1.0);
        assert_eq!(scale, "log");
        assert!((z + 0.3 / (0.1 * 2f64.sqrt())).abs() < 1e-12, "{z}");
    }

    #[test]
    fn squared_scale_when_a_term_is_not_resolved() {
        // theta_a = 4 with hi^2 = 5 (se 1 at z_c = 1); a pinned term with hi^2 = 1 (se 1):
        // z = (4 - 0) / sqrt(2).
        let a = Term {
            value: 2.0,
            lo: 3f64.sqrt(),
            hi: 5f64.sqrt(),
        };
        let b = Term {
            value: 0.0,
            lo: 0.0,
            hi: 1.0,
        };
        let (scale, z) = z_score(&a, &b, 1.0);
        assert_eq!(scale, "squared");
        assert!((z - 4.0 / 2f64.sqrt()).abs() < 1e-12, "{z}");
    }
}

//! The classic IEEE-952 graphical read-outs of an Allan deviation curve (Annex C, Figure
//! C.2): tangent lines of slope -1/2 and +1/2, and the flat minimum.

use super::FLICKER_AVAR_FACTOR;
use serde::Serialize;

/// A tangent line of fixed slope read off a log-log curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SlopeLine {
    /// The coefficient read at the reference tau (N at 1 s, K at 3 s).
    pub value: f64,
    /// The tau range of the points the line was fitted through, s.
    pub tau_min: f64,
    pub tau_max: f64,
    pub points: usize,
}

/// The flat minimum of the Allan deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BiasReadout {
    /// `min(adev) / sqrt(2 ln2 / pi)` (= min / 0.664), u.
    pub value: f64,
    /// The tau of the minimum, s.
    pub tau: f64,
}

/// The classic IEEE-952 graphical read-outs (Annex C, Figure C.2).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlopeReadouts {
    /// Angle/velocity random walk N: the -1/2-slope line at tau = 1 s.
    pub n: Option<SlopeLine>,
    /// Bias instability B from the minimum, when the minimum is interior to the curve.
    pub b: Option<BiasReadout>,
    /// Rate random walk K: the +1/2-slope line at tau = 3 s.
    pub k: Option<SlopeLine>,
}

/// Half-width of the band of local slopes counted as "the slope" of a region.
pub const SLOPE_TOLERANCE: f64 = 0.1;

/// The classic read-outs from an Allan **deviation** curve.
///
/// - Local slope at each point: least-squares slope of ln adev on ln tau over the point and
///   its two neighbours (two at the ends).
/// - N: the longest contiguous run (at least 2 points; ties: the shortest taus) whose local
///   slope is within [`SLOPE_TOLERANCE`] of -1/2; the line `adev = N / sqrt(tau)` through it
///   (`ln N = mean(ln adev + ln(tau) / 2)`) read at tau = 1 s.
/// - K: likewise for +1/2 (ties: the longest taus), `adev = K sqrt(tau / 3)`, read at 3 s.
/// - B: `min(adev) / sqrt(2 ln2 / pi)`, and its tau, if the minimum is not the first or last
///   point (otherwise the flat region is not in the curve).
///
/// Points with a non-finite or non-positive tau or adev are ignored (so are the extra
/// elements of the longer array); points are taken in increasing tau. The read-outs are
/// biased where terms overlap (the run includes points where neighbouring terms add a few
/// percent; the minimum lies above 0.664 B when N or K are not negligible there) — that is
/// the classic method; [`super::fit_allan`] has no such bias.
pub fn slope_readouts(tau: &[f64], adev: &[f64]) -> SlopeReadouts {
    let mut pts: Vec<(f64, f64)> = tau
        .iter()
        .zip(adev)
        .filter(|(t, a)| t.is_finite() && **t > 0.0 && a.is_finite() && **a > 0.0)
        .map(|(t, a)| (t.ln(), a.ln()))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let slopes = local_slopes(&pts);
    let n = slope_run(&slopes, -0.5, false).map(|run| tangent(&pts[run], -0.5, 1.0));
    let k = slope_run(&slopes, 0.5, true).map(|run| tangent(&pts[run], 0.5, 3.0));
    let b = pts
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.1.total_cmp(&b.1.1))
        .filter(|(i, _)| *i > 0 && *i + 1 < pts.len())
        .map(|(_, &(lt, la))| BiasReadout {
            value: la.exp() / FLICKER_AVAR_FACTOR.sqrt(),
            tau: lt.exp(),
        });
    SlopeReadouts { n, b, k }
}

/// Least-squares slope through each point and its neighbours (log-log points).
fn local_slopes(pts: &[(f64, f64)]) -> Vec<f64> {
    (0..pts.len())
        .map(|i| {
            let window = &pts[i.saturating_sub(1)..(i + 2).min(pts.len())];
            ls_slope(window)
        })
        .collect()
}

pub(crate) fn ls_slope(pts: &[(f64, f64)]) -> f64 {
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx > 0.0 { sxy / sxx } else { f64::NAN }
}

/// The longest contiguous run (>= 2 points) of slopes within the tolerance of `target`;
/// ties go to the last run if `prefer_last`, else the first.
fn slope_run(slopes: &[f64], target: f64, prefer_last: bool) -> Option<std::ops::Range<usize>> {
    longest_run(
        slopes,
        |s| (s - target).abs() <= SLOPE_TOLERANCE,
        prefer_last,
    )
}

pub(crate) fn longest_run(
    values: &[f64],
    keep: impl Fn(f64) -> bool,
    prefer_last: bool,
) -> Option<std::ops::Range<usize>> {
    let mut best: Option<std::ops::Range<usize>> = None;
    let mut start = None;
    for i in 0..=values.len() {
        let inside = i < values.len() && keep(values[i]);
        match (inside, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                let len = i - s;
                let better = best
                    .as_ref()
                    .is_none_or(|b| len > b.len() || (prefer_last && len == b.len()));
                if len >= 2 && better {
                    best = Some(s..i);
                }
                start = None;
            }
            _ => {}
        }
    }
    best
}

/// The line of fixed `slope` through log-log points, read at `tau_ref`:
/// `ln value = mean(ln adev - slope ln(tau / tau_ref))`.
fn tangent(pts: &[(f64, f64)], slope: f64, tau_ref: f64) -> SlopeLine {
    let lr = tau_ref.ln();
    let mean = pts
        .iter()
        .map(|(lt, la)| la - slope * (lt - lr))
        .sum::<f64>()
        / pts.len() as f64;
    SlopeLine {
        value: mean.exp(),
        tau_min: pts[0].0.exp(),
        tau_max: pts[pts.len() - 1].0.exp(),
        points: pts.len(),
    }
}

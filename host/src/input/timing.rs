//! Time columns stamped by a host (an Arduino's serial log, a ROS node's receive stamps): the
//! rate by least squares, the jitter, and the gaps where samples went missing.
//!
//! # Why jitter is accepted and gaps are refused
//!
//! The sensor samples on its own clock at a fixed rate; a host stamps each sample when it
//! *arrives*, after a delay that varies with the scheduler and the USB link (USB serial
//! delivers in bursts: several samples stamped at nearly the same time, then a long step).
//! The stamps therefore carry the host's timing noise, not the sampling instants. As long as
//! no sample is missing, sample `i` was taken at `t0 + i * T`, and the index is a better
//! clock than its stamp: the fitted period `T` is the only timing quantity the analysis needs,
//! and regression over `n` stamps whose offsets from the line have spread `s` determines it to
//! `s * sqrt(12 / n^3)` (a relative error under 1e-6 for 10 minutes of 100 Hz stamps
//! scattered over a whole period), far below anything an Allan or PSD estimate resolves. So jitter
//! and bursts of any size are accepted (with a warning that states them) as long as every
//! stamp's offset from the line returns to where it was.
//!
//! A missing sample is different: every later stamp then lies a whole period further along
//! the line than its index says, a permanent step in the offset. Taking the rows as contiguous
//! would splice two stretches of data together, so such gaps are refused. A step of at least
//! 1.5 periods is a candidate; it is a gap when the least offset over the stamps after it
//! exceeds the least offset over the stamps before it by half a period or more. Least offsets
//! over windows of `window` stamps (two seconds' worth) compare the undelayed baseline on
//! either side: a burst is only ever late, so its catch-up settles back onto the baseline
//! within the window, while a gap moves the baseline itself (a host that stalls for longer
//! and then delivers its backlog at once is taken for a gap). Judging the cumulative offset,
//! not single steps, is what tells a burst's long step from a lost sample.

use serde::Serialize;

/// Worst step deviation from the fitted period, as a fraction of the period, under which the
/// stamps count as uniform and no warning is given (printing times to a few digits alone
/// moves steps by less).
const UNIFORM_TOLERANCE: f64 = 0.01;

/// A step this many periods long is examined as a possible gap.
const GAP_CANDIDATE_PERIODS: f64 = 1.5;

/// A permanent step in the offset of at least this many periods is a gap.
const GAP_LEVEL_PERIODS: f64 = 0.5;

/// Refits with the gaps found so far before the gap list is final.
const REFITS: usize = 3;

/// Stamps compared on either side of a step while the period is refined.
const SHORT_WINDOW: usize = 8;

/// What a time column says about the sampling, for the user and the JSON document.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Timing {
    /// The time column's name in the file.
    pub column: String,
    /// The unit its values were read in, and how it was decided (`s, unstated`; `ns, by
    /// its name`).
    pub unit: String,
    pub stamps: usize,
    /// 1 / period, Hz.
    pub rate_hz: f64,
    /// Least-squares slope of time on sample index, s.
    pub period_s: f64,
    /// Median absolute deviation of the steps from the period, s.
    pub step_mad_s: f64,
    /// The step farthest from the period.
    pub worst_step: WorstStep,
    /// Largest distance of a stamp from the fitted line, in periods.
    pub max_offset_periods: f64,
    /// Every step within 1 % of the period: nothing to warn about.
    pub uniform: bool,
}

impl std::fmt::Display for Timing {
    /// One line: the rate, and for jittered stamps the jitter and why it is accepted.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "time column '{}' ({}): {} Hz by least squares over {} stamps",
            self.column, self.unit, self.rate_hz, self.stamps
        )?;
        if self.uniform {
            return write!(f, ", every step within 1 % of the period");
        }
        let ms = |s: f64| format!("{:.4} ms", s * 1e3);
        let w = &self.worst_step;
        write!(
            f,
            "; host-stamped jitter: steps deviate from the period ({}) by {} (median), the \
             worst is {} at line {} (t = {} s); the stamps stay within {:.3} periods of the \
             fitted line and no sample is missing, so the rows are taken as uniformly sampled",
            ms(self.period_s),
            ms(self.step_mad_s),
            ms(w.step_s),
            w.line,
            w.time_s,
            self.max_offset_periods
        )
    }
}

/// One step of a time column: the row it ends at (0-based), that row's line in the file and
/// its time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstStep {
    #[serde(skip)]
    pub row: usize,
    pub line: usize,
    pub time_s: f64,
    pub step_s: f64,
}

/// Samples missing before `row` (0-based), stamped `time_s`.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    pub row: usize,
    pub time_s: f64,
    pub missing: u64,
}

/// Why a time column gives no rate.
#[derive(Debug, Clone, PartialEq)]
pub enum TimingError {
    TooShort,
    /// Every stamp is the same.
    NotIncreasing,
    /// The stamp at `row` is earlier than the one before (a clock reset or wrap).
    Backwards {
        row: usize,
        step_s: f64,
    },
    /// Samples are missing; the fitted period for reference.
    Gaps {
        gaps: Vec<Gap>,
        period_s: f64,
    },
}

/// Gaps listed one by one in an explanation; the rest are counted.
const GAPS_LISTED: usize = 10;

impl TimingError {
    /// The rows the error is about: the row that steps back, or the first row after each gap.
    pub fn rows(&self) -> Vec<usize> {
        match self {
            TimingError::Backwards { row, .. } => vec![*row],
            TimingError::Gaps { gaps, .. } => gaps.iter().map(|g| g.row).collect(),
            TimingError::TooShort | TimingError::NotIncreasing => Vec::new(),
        }
    }

    /// The error in words, for the time column `name`, with the remedy; `place` names where a
    /// row is in the input (`line 12` of a table, `message 12` of a bag).
    pub fn explain(&self, name: &str, place: &dyn Fn(usize) -> String) -> String {
        match self {
            TimingError::TooShort => format!("time column '{name}' needs at least two rows"),
            TimingError::NotIncreasing => format!("time column '{name}' does not increase"),
            TimingError::Backwards { step_s, .. } => format!(
                "time column '{name}' steps back by {} s (a clock reset or wrap-around?): \
                 split the file here, or give --ignore-time --rate HZ",
                -step_s
            ),
            TimingError::Gaps { gaps, period_s } => {
                let mut listed: Vec<String> = gaps
                    .iter()
                    .take(GAPS_LISTED)
                    .map(|g| {
                        format!(
                            "{} (t = {} s): {} sample(s) missing",
                            place(g.row),
                            g.time_s,
                            g.missing
                        )
                    })
                    .collect();
                if gaps.len() > GAPS_LISTED {
                    listed.push(format!("and {} more", gaps.len() - GAPS_LISTED));
                }
                let missing: u64 = gaps.iter().map(|g| g.missing).sum();
                format!(
                    "time column '{name}': {missing} sample(s) missing in {} gap(s) that the fitted \
                     period ({:.4} ms) cannot absorb: {}; split the file at the gaps, or give \
                     --ignore-time --rate HZ to take the rows as contiguous",
                    gaps.len(),
                    period_s * 1e3,
                    listed.join("; ")
                )
            }
        }
    }
}

/// The longest run of rows between `gaps` (each starting at its `row`) of `rows` rows; the
/// first such run on a tie.
pub fn longest_run(gaps: &[Gap], rows: usize) -> std::ops::Range<usize> {
    let mut bounds: Vec<usize> = gaps.iter().map(|g| g.row).collect();
    bounds.push(rows);
    let mut best = 0..0;
    let mut start = 0;
    for end in bounds {
        if end - start > best.len() {
            best = start..end;
        }
        start = end;
    }
    best
}

/// Fit a time column (seconds) and judge it; `column` names it in the result. Line numbers are
/// left 0 for the caller to fill in.
pub fn analyse(column: &str, times: &[f64]) -> Result<Timing, TimingError> {
    let n = times.len();
    if n < 2 {
        return Err(TimingError::TooShort);
    }
    if let Some(row) = (1..n).find(|&i| times[i] < times[i - 1]) {
        return Err(TimingError::Backwards {
            row,
            step_s: times[row] - times[row - 1],
        });
    }
    if times[n - 1] == times[0] {
        return Err(TimingError::NotIncreasing);
    }
    let plain = fit(times, &[]);
    let mut period = plain.1;
    // Missing samples lengthen the fitted period, and the offsets then drift by that error
    // per stamp, which long windows would mistake for a level. Short windows see through a
    // drift of up to 1 / (2 SHORT_WINDOW) periods per stamp (a loss of 1 sample in 16), and the
    // gaps they find (a long burst among them, harmlessly) only refine the period.
    for _ in 0..REFITS {
        let found = find_gaps(times, period, SHORT_WINDOW);
        if found.is_empty() {
            break;
        }
        period = fit(times, &found).1;
    }
    let mut gaps = Vec::new();
    for _ in 0..REFITS {
        let found = find_gaps(times, period, window(period));
        if found == gaps {
            break;
        }
        period = fit(times, &found).1;
        gaps = found;
    }
    if !gaps.is_empty() {
        return Err(TimingError::Gaps {
            gaps,
            period_s: period,
        });
    }
    // No sample is missing: the row index is the sample index.
    let (intercept, period) = plain;
    // deviations[i - 1] is row i's step's distance from the period.
    let mut deviations: Vec<f64> = (1..n)
        .map(|i| (times[i] - times[i - 1] - period).abs())
        .collect();
    let (worst_row, worst_deviation) = deviations
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map_or((1, 0.0), |(i, d)| (i + 1, *d));
    let mid = deviations.len() / 2;
    let step_mad_s = *deviations.select_nth_unstable_by(mid, f64::total_cmp).1;
    let max_offset = (0..n)
        .map(|i| (times[i] - times[0] - intercept - period * i as f64).abs())
        .fold(0.0, f64::max);
    Ok(Timing {
        column: column.to_string(),
        unit: "s".into(),
        stamps: n,
        rate_hz: round_to_print(1.0 / period),
        period_s: period,
        step_mad_s,
        worst_step: WorstStep {
            row: worst_row,
            line: 0,
            time_s: times[worst_row],
            step_s: times[worst_row] - times[worst_row - 1],
        },
        max_offset_periods: max_offset / period,
        uniform: worst_deviation <= UNIFORM_TOLERANCE * period,
    })
}

/// A rate rounded to 9 significant digits: times printed to a few decimals give their exact
/// rate (0.005 s steps give 200 Hz, not 200.00000000000423 Hz).
fn round_to_print(hz: f64) -> f64 {
    format!("{hz:.8e}").parse().unwrap_or(hz)
}

/// Least-squares line `t - t0 = a + T * k` over the stamps, where `k` is the sample index
/// counting the samples `gaps` say are missing; returns (a, T). Sums are centred for
/// precision with epoch-sized stamps.
fn fit(times: &[f64], gaps: &[Gap]) -> (f64, f64) {
    let index = corrected_index(times.len(), gaps);
    let n = times.len() as f64;
    let t0 = times[0];
    let k_mean = index.iter().sum::<f64>() / n;
    let t_mean = times.iter().map(|t| t - t0).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, t) in index.iter().zip(times) {
        let dk = k - k_mean;
        sxy += dk * (t - t0 - t_mean);
        sxx += dk * dk;
    }
    let period = sxy / sxx;
    (t_mean - period * k_mean, period)
}

/// Sample indices with the missing samples counted: row `i` is sample `i + missing before it`.
fn corrected_index(n: usize, gaps: &[Gap]) -> Vec<f64> {
    let mut shift = 0u64;
    let mut next = gaps.iter().peekable();
    (0..n)
        .map(|i| {
            while let Some(g) = next.next_if(|g| g.row <= i) {
                shift += g.missing;
            }
            (i as u64 + shift) as f64
        })
        .collect()
}

/// Stamps compared on either side of a candidate step: two seconds' worth, and at least 64.
fn window(period: f64) -> usize {
    ((2.0 / period).ceil() as usize).max(64)
}

/// Candidate steps (of `w` stamps either side) whose baseline offset (the least offset over a window) rises by half a
/// period or more across them; the before-window stops at the previous gap so that gaps are
/// counted once.
fn find_gaps(times: &[f64], period: f64, w: usize) -> Vec<Gap> {
    let n = times.len();
    let offset: Vec<f64> = (0..n)
        .map(|i| (times[i] - times[0]) / period - i as f64)
        .collect();
    let before = sliding_min(&offset, w, false);
    let after = sliding_min(&offset, w, true);
    let mut gaps = Vec::new();
    let mut last_gap = 0;
    for j in 1..n {
        if times[j] - times[j - 1] < GAP_CANDIDATE_PERIODS * period {
            continue;
        }
        let base = if last_gap + w > j {
            offset[last_gap..j]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min)
        } else {
            before[j]
        };
        let rise = after[j] - base;
        if rise >= GAP_LEVEL_PERIODS {
            gaps.push(Gap {
                row: j,
                time_s: times[j],
                missing: (rise.round() as u64).max(1),
            });
            last_gap = j;
        }
    }
    gaps
}

/// Minimum of `x` over `[j - w, j)` (`ahead` false) or `[j, j + w)` (`ahead` true), clipped to
/// the ends, for every `j` (a monotonic deque: linear time).
fn sliding_min(x: &[f64], w: usize, ahead: bool) -> Vec<f64> {
    let n = x.len();
    let mut out = vec![f64::INFINITY; n];
    let mut deque = std::collections::VecDeque::<usize>::new();
    let order: Box<dyn Iterator<Item = usize>> = if ahead {
        Box::new((0..n).rev())
    } else {
        Box::new(0..n)
    };
    for j in order {
        if !ahead {
            // The window before j holds j - w .. j - 1: answer before admitting j.
            while deque.front().is_some_and(|&f| f + w < j) {
                deque.pop_front();
            }
            out[j] = deque.front().map_or(f64::INFINITY, |&f| x[f]);
        }
        while deque.back().is_some_and(|&b| x[b] >= x[j]) {
            deque.pop_back();
        }
        deque.push_back(j);
        if ahead {
            while deque.front().is_some_and(|&f| f >= j + w) {
                deque.pop_front();
            }
            out[j] = x[deque[0]];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `n` stamps of a `rate` Hz sensor with uniform jitter of +-`jitter` s.
    fn jittered(n: usize, rate: f64, jitter: f64, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|i| 1000.0 + i as f64 / rate + rng.random_range(-jitter..=jitter))
            .collect()
    }

    #[test]
    fn sliding_minima_match_the_direct_ones() {
        let x = [5.0, 3.0, 4.0, 1.0, 2.0, 6.0, 0.5];
        let w = 3;
        let before = sliding_min(&x, w, false);
        let after = sliding_min(&x, w, true);
        for j in 0..x.len() {
            let direct =
                |r: std::ops::Range<usize>| x[r].iter().copied().fold(f64::INFINITY, f64::min);
            assert_eq!(before[j], direct(j.saturating_sub(w)..j), "before {j}");
            assert_eq!(after[j], direct(j..(j + w).min(x.len())), "after {j}");
        }
    }

    /// +-100 us uniform jitter at 100 Hz (1 % of the period either way): accepted, and the
    /// rate to the regression's precision: sigma_T / T = 58 us * sqrt(12 / n^3) / 10 ms =
    /// 1.4e-9 for n = 60000; the bound adds the rounding to 9 digits (5e-9) with room.
    #[test]
    fn jitter_of_100_us_at_100_hz_is_accepted() {
        let t = jittered(60_000, 100.0, 100e-6, 1);
        let timing = analyse("t", &t).unwrap();
        assert!((timing.rate_hz / 100.0 - 1.0).abs() < 2e-8, "{timing:?}");
        assert!(!timing.uniform);
        // |u1 - u2| for two uniforms on +-100 us has median (1 - 1/sqrt(2)) * 200 us = 58.6 us.
        assert!((timing.step_mad_s - 58.6e-6).abs() < 3e-6, "{timing:?}");
        // |step - T| reaches 150 us with probability 1/16 per step: the worst is beyond it.
        let worst = (timing.worst_step.step_s - 0.01).abs();
        assert!(worst > 150e-6 && worst <= 200e-6 + 1e-9, "{timing:?}");
        assert!(timing.max_offset_periods <= 0.0101, "{timing:?}");
    }

    /// Bursts as USB serial delivers them: a sensor at 99.87 Hz stamped when each 16 ms
    /// transfer arrives (0, 1 or 2 samples per transfer: steps of 0 or twice the period), and
    /// a 150 ms stall after which 15 samples arrive at once. No sample is missing, so no gap,
    /// and the rate comes out of the regression, not the steps.
    #[test]
    fn bursts_that_track_the_line_are_jitter() {
        let rate = 99.87;
        let transfer = 0.016;
        let mut t: Vec<f64> = (0..30_000)
            .map(|i| ((i as f64 / rate) / transfer).ceil() * transfer)
            .collect();
        let stall = 12_000;
        let held = t[stall + 14];
        t[stall..stall + 15].iter_mut().for_each(|x| *x = held);
        let timing = analyse("t", &t).unwrap();
        assert!((timing.rate_hz / rate - 1.0).abs() < 1e-5, "{timing:?}");
        assert!(timing.max_offset_periods > 10.0, "{timing:?}");
        assert_eq!(timing.worst_step.row, stall);
    }

    /// Missing samples are gaps, counted and placed, even among bursts and jitter; a refit
    /// without the gaps keeps their counts exact.
    #[test]
    fn missing_samples_are_gaps_with_counts() {
        let full = jittered(20_000, 100.0, 100e-6, 2);
        let mut t: Vec<f64> = Vec::new();
        for (i, &x) in full.iter().enumerate() {
            let lost = (5_000..5_003).contains(&i) || (12_000..12_040).contains(&i) || i == 19_990;
            if !lost {
                t.push(x);
            }
        }
        let TimingError::Gaps { gaps, period_s } = analyse("t", &t).unwrap_err() else {
            panic!("gaps expected");
        };
        let found: Vec<(usize, u64)> = gaps.iter().map(|g| (g.row, g.missing)).collect();
        assert_eq!(found, [(5_000, 3), (11_997, 40), (19_947, 1)]);
        assert_eq!(gaps[1].time_s, full[12_040]);
        assert!((period_s - 0.01).abs() < 1e-8, "{period_s}");
    }

    /// One sample in 25 lost (4 %): the first fit's period is 4 % long, and only the short
    /// windows' refinement finds the gaps.
    #[test]
    fn scattered_losses_are_found_despite_the_biased_first_fit() {
        let full = jittered(10_000, 100.0, 100e-6, 3);
        let t: Vec<f64> = (0..full.len())
            .filter(|i| i % 25 != 7)
            .map(|i| full[i])
            .collect();
        let TimingError::Gaps { gaps, period_s } = analyse("t", &t).unwrap_err() else {
            panic!("gaps expected");
        };
        assert_eq!(gaps.len(), 400);
        assert!(gaps.iter().all(|g| g.missing == 1));
        assert_eq!((gaps[0].row, gaps[1].row), (7, 31));
        assert!((period_s - 0.01).abs() < 1e-8, "{period_s}");
    }

    #[test]
    fn uniform_stamps_give_an_exact_rate() {
        let t: Vec<f64> = (0..4000)
            .map(|i| format!("{:.3}", i as f64 * 0.005).parse().unwrap())
            .collect();
        let timing = analyse("time", &t).unwrap();
        assert_eq!(timing.rate_hz, 200.0);
        assert!(timing.uniform);
    }

    #[test]
    fn backwards_and_flat_columns_are_errors() {
        assert_eq!(
            analyse("t", &[0.0, 0.01, 0.005, 0.02]),
            Err(TimingError::Backwards {
                row: 2,
                step_s: 0.005 - 0.01
            })
        );
        assert_eq!(analyse("t", &[1.0, 1.0]), Err(TimingError::NotIncreasing));
        assert_eq!(analyse("t", &[1.0]), Err(TimingError::TooShort));
    }
}

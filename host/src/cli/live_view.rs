//! The live view of `capture` and `sweep`: the recorder's snapshots ([`Snapshot`]) shown as
//! they come.
//!
//! - On a terminal: one line per axis above the progress bar, redrawn in place: a sparkline
//!   of the Allan deviation over tau (log scale, eight levels), N, B and K so far with their
//!   relative half-widths, and, under a stop rule, the record length still needed.
//! - With `--json-progress`: one JSON object per snapshot on stdout (`"event": "live"`, the
//!   snapshot's fields), for a program to follow.
//! - Otherwise (a pipe, a log): a one-line summary at most every [`LINE_EVERY`].

use imunoise::analysis::fit::Term;
use imunoise::analysis::live::{ChannelSnapshot, Snapshot};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::io::Write;
use std::time::{Duration, Instant};

/// Least wall time between one-line summaries.
const LINE_EVERY: Duration = Duration::from_secs(30);

/// Where snapshots go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Terminal,
    Lines,
    Json,
}

impl Mode {
    /// JSON when asked for, the redrawn lines on a terminal, else summaries.
    pub fn choose(json: bool) -> Mode {
        if json {
            Mode::Json
        } else if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            Mode::Terminal
        } else {
            Mode::Lines
        }
    }
}

pub struct LiveView {
    mode: Mode,
    /// The terminal's lines (a header and one per axis), created with the first snapshot.
    lines: Vec<ProgressBar>,
    multi: MultiProgress,
    last_line: Option<Instant>,
}

impl LiveView {
    /// A view whose terminal lines go above `bar` (added to the same display).
    pub fn new(mode: Mode, bar: &ProgressBar) -> (LiveView, ProgressBar) {
        let multi = MultiProgress::new();
        let bar = multi.add(bar.clone());
        (
            LiveView {
                mode,
                lines: Vec::new(),
                multi,
                last_line: None,
            },
            bar,
        )
    }

    pub fn show(&mut self, snapshot: &Snapshot) {
        match self.mode {
            Mode::Json => {
                let mut value = serde_json::to_value(snapshot).unwrap_or_default();
                if let Some(object) = value.as_object_mut() {
                    object.insert("event".into(), "live".into());
                }
                // A closed pipe ends the view, not the capture.
                let _ = writeln!(std::io::stdout().lock(), "{value}");
            }
            Mode::Lines => {
                if self.last_line.is_some_and(|t| t.elapsed() < LINE_EVERY) {
                    return;
                }
                self.last_line = Some(Instant::now());
                eprintln!("{}", summary(snapshot));
            }
            Mode::Terminal => self.draw(snapshot),
        }
    }

    fn draw(&mut self, snapshot: &Snapshot) {
        if self.lines.is_empty() {
            let style = ProgressStyle::with_template("{msg}").ok();
            for i in 0..=snapshot.channels.len() {
                let line = self.multi.insert(i, ProgressBar::new(1));
                if let Some(s) = &style {
                    line.set_style(s.clone());
                }
                self.lines.push(line);
            }
        }
        self.lines[0].set_message(header(snapshot));
        for (line, c) in self.lines[1..].iter().zip(&snapshot.channels) {
            line.set_message(axis_line(c));
        }
    }

    /// Take the lines down (the capture's own summary follows).
    pub fn finish(&self) {
        for line in &self.lines {
            line.finish_and_clear();
        }
    }
}

/// `live: 12.5 min of data, 68 % intervals; the stop rule needs about 42.0 min in all ...`.
fn header(s: &Snapshot) -> String {
    format!(
        "live: {} of data, {:.0} % intervals{}   Allan deviation over tau, then N, B, K (+- half-width)",
        duration_text(s.elapsed_s),
        100.0 * s.confidence,
        rule_text(s)
    )
}

/// The stop rule's state, to follow a line (empty without a rule).
fn rule_text(s: &Snapshot) -> String {
    if !s.has_rule() {
        String::new()
    } else if s.rule_met() {
        "; the stop rule is met, confirming".to_string()
    } else {
        match s.needed_s() {
            Some(t) => format!("; the stop rule needs about {} in all", duration_text(t)),
            None => "; the stop rule: some target not reachable yet".to_string(),
        }
    }
}

/// `gx ▁▂▃▄▅ N 1.03e-4 +-0.8 % B 4.1e-6 +-35 % K -  [N:1% in 4.2 min]`.
fn axis_line(c: &ChannelSnapshot) -> String {
    let terms = [("N", c.n), ("B", c.b), ("K", c.k)]
        .into_iter()
        .map(|(name, t)| format!("{name} {}", term_text(t)))
        .collect::<Vec<_>>()
        .join("  ");
    let targets: Vec<String> = c
        .targets
        .iter()
        .map(|t| {
            let target = format!(
                "{}:{}%",
                t.status.target.term,
                100.0 * t.status.target.fraction
            );
            match (t.status.met, t.needed_s) {
                (true, _) => format!("{target} met"),
                (false, Some(n)) => format!("{target} at {}", duration_text(n)),
                (false, None) => format!("{target} not in sight"),
            }
        })
        .collect();
    let rule = if targets.is_empty() {
        String::new()
    } else {
        format!("  [{}]", targets.join(", "))
    };
    format!("{:<4} {:<24} {terms}{rule}", c.name, sparkline(&c.adev))
}

/// A value with its relative half-width, `-` when the fit has no such term.
fn term_text(t: Option<Term>) -> String {
    match t {
        Some(t) if t.value > 0.0 => {
            let half = (t.hi - t.lo) / (2.0 * t.value);
            format!("{:.3e} +-{:.1} %", t.value, 100.0 * half)
        }
        _ => "-".to_string(),
    }
}

/// The curve in eight levels of log ADEV, one character per tau (at most 24, evenly picked).
fn sparkline(adev: &[f64]) -> String {
    const LEVELS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
    let logs: Vec<f64> = adev
        .iter()
        .filter(|d| **d > 0.0 && d.is_finite())
        .map(|d| d.log10())
        .collect();
    if logs.is_empty() {
        return String::new();
    }
    let (lo, hi) = logs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let width = logs.len().min(24);
    (0..width)
        .map(|i| {
            let v = logs[i * (logs.len() - 1) / (width - 1).max(1)];
            let level = if hi > lo {
                ((v - lo) / (hi - lo) * 7.0).round() as usize
            } else {
                0
            };
            LEVELS[level.min(7)]
        })
        .collect()
}

/// `45 s`, `12.5 min`, `3.20 h`.
pub fn duration_text(seconds: f64) -> String {
    if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.2} h", seconds / 3600.0)
    }
}

/// One line for a log: the elapsed data, N on each axis, and the rule's state.
fn summary(s: &Snapshot) -> String {
    let axes: Vec<String> = s
        .channels
        .iter()
        .map(|c| format!("{} N {}", c.name, term_text(c.n)))
        .collect();
    format!(
        "live {}: {}{}",
        duration_text(s.elapsed_s),
        axes.join(", "),
        rule_text(s)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sparklines_follow_the_curve() {
        assert_eq!(sparkline(&[1.0, 0.1, 0.01, 0.1]), "█▅▁▅");
        assert_eq!(sparkline(&[]), "");
        assert_eq!(sparkline(&[2.0, 2.0]), "▁▁");
        assert_eq!(sparkline(&vec![1.0; 50]).chars().count(), 24);
    }

    #[test]
    fn durations_read_in_sensible_units() {
        assert_eq!(duration_text(45.0), "45 s");
        assert_eq!(duration_text(750.0), "12.5 min");
        assert_eq!(duration_text(11520.0), "3.20 h");
    }

    #[test]
    fn terms_show_their_half_width() {
        let t = Term {
            value: 2e-4,
            lo: 1.9e-4,
            hi: 2.1e-4,
        };
        assert_eq!(term_text(Some(t)), "2.000e-4 +-5.0 %");
        assert_eq!(term_text(None), "-");
    }
}

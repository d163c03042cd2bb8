//! Column names as loggers write them: quoted (`"Time (s)"`), with a unit in brackets
//! (`Gyroscope x (rad/s)`, `gx [deg/s]`) or a suffix (`time_ms`, `gx_dps`), and the time
//! and counter columns of ROS (`%time`, `field.header.stamp`, `field.header.seq`) and phone
//! logging apps (`seconds_elapsed`).

/// `field` without one pair of surrounding double or single quotes, trimmed.
pub(super) fn unquote(field: &str) -> &str {
    let f = field.trim();
    for q in ['"', '\''] {
        if let Some(inner) = f.strip_prefix(q).and_then(|r| r.strip_suffix(q)) {
            return inner.trim();
        }
    }
    f
}

/// A name ending in a bracketed unit, `Time (s)` or `gx [deg/s]`: the stem and the unit as
/// written, both trimmed; None without one (or with nothing before it).
pub(super) fn bracketed(name: &str) -> Option<(&str, &str)> {
    let name = name.trim();
    let close = name.chars().last()?;
    let open = match close {
        ')' => '(',
        ']' => '[',
        _ => return None,
    };
    let at = name.rfind(open)?;
    let stem = name[..at].trim();
    let unit = name[at + 1..name.len() - 1].trim();
    (!stem.is_empty() && !unit.is_empty()).then_some((stem, unit))
}

/// A unit as written in brackets, folded to one spelling: lower case, no spaces, `°` as
/// `deg`, `²` as `^2`, `sec` as `s` (`°/sec` is `deg/s`, `m/s²` is `m/s^2`).
pub(super) fn folded_unit(unit: &str) -> String {
    let mut u: String = unit
        .to_lowercase()
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    for (from, to) in [
        ("°", "deg"),
        ("²", "^2"),
        ("µ", "u"),
        ("μ", "u"),
        ("/sec", "/s"),
    ] {
        u = u.replace(from, to);
    }
    u
}

/// How a time column's values become seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum TimeUnit {
    /// Stated by the name (a suffix, a bracketed unit, or a ROS stamp's nanoseconds).
    Stated { to_s: f64, label: &'static str },
    /// Not stated: seconds, unless the values are too large to be seconds since anything
    /// ([`TimeUnit::resolve`]).
    Unstated,
}

/// Names of time columns without their unit (lower case, a leading `%` dropped).
const TIME_STEMS: [&str; 10] = [
    "time",
    "t",
    "timestamp",
    "stamp",
    "seconds_elapsed",
    "elapsed",
    "elapsed_time",
    "header.stamp",
    "field.header.stamp",
    "host_time",
];

/// Time units by suffix or bracketed spelling, with their factor to seconds.
const TIME_UNITS: [(&[&str], f64, &str); 4] = [
    (&["s", "sec", "secs", "second", "seconds"], 1.0, "s"),
    (&["ms", "msec", "millis", "milliseconds"], 1e-3, "ms"),
    (&["us", "usec", "micros", "microseconds"], 1e-6, "us"),
    (&["ns", "nsec", "nanos", "nanoseconds"], 1e-9, "ns"),
];

fn time_unit_named(unit: &str) -> Option<TimeUnit> {
    let u = folded_unit(unit);
    TIME_UNITS
        .iter()
        .find(|(spellings, _, _)| spellings.contains(&u.as_str()))
        .map(|&(_, to_s, label)| TimeUnit::Stated { to_s, label })
}

/// The time unit of a column named `name`, or None when it is not a time column.
pub(super) fn time_column(name: &str) -> Option<TimeUnit> {
    let raw = unquote(name);
    let percent = raw.starts_with('%');
    let lower = raw.to_lowercase();
    let lower = lower.strip_prefix('%').unwrap_or(&lower).trim();
    if let Some((stem, unit)) = bracketed(lower) {
        return TIME_STEMS
            .contains(&stem)
            .then(|| time_unit_named(unit))
            .flatten();
    }
    if TIME_STEMS.contains(&lower) {
        // ROS writes its stamps (`%time`, `header.stamp`) in nanoseconds.
        return Some(
            if percent || (lower.ends_with("stamp") && lower.contains('.')) {
                TimeUnit::Stated {
                    to_s: 1e-9,
                    label: "ns",
                }
            } else {
                TimeUnit::Unstated
            },
        );
    }
    let (stem, unit) = lower.rsplit_once('_')?;
    TIME_STEMS
        .contains(&stem)
        .then(|| time_unit_named(unit))
        .flatten()
}

impl TimeUnit {
    /// The factor to seconds and how it was decided, for values starting at `first`.
    /// Unstated, seconds; but stamps of 1e11 or more cannot be seconds since any epoch a
    /// logger uses (1e11 s is 3000 years), and Unix time now is about 1.7e9 s, 1.7e12 ms,
    /// 1.7e15 us and 1.7e18 ns: the size picks the unit.
    pub(super) fn resolve(self, first: f64) -> (f64, String) {
        match self {
            TimeUnit::Stated { to_s, label } => (to_s, format!("{label}, by its name")),
            TimeUnit::Unstated => {
                let size = first.abs();
                let (to_s, label) = if size >= 1e17 {
                    (1e-9, "ns")
                } else if size >= 1e14 {
                    (1e-6, "us")
                } else if size >= 1e11 {
                    (1e-3, "ms")
                } else {
                    return (1.0, "s, unstated".into());
                };
                (
                    to_s,
                    format!(
                        "{label}, unstated: the stamps (from {first:e}) are too large for seconds"
                    ),
                )
            }
        }
    }
}

/// Whether a column is a running count of samples or messages (ROS's `field.header.seq`),
/// which is neither a time base nor a signal.
pub(super) fn counter_column(name: &str) -> bool {
    let lower = unquote(name).to_lowercase();
    matches!(
        lower.as_str(),
        "seq" | "header.seq" | "field.header.seq" | "index" | "sample_index" | "counter"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_and_brackets() {
        assert_eq!(unquote(" \"Time (s)\" "), "Time (s)");
        assert_eq!(unquote("'gx'"), "gx");
        assert_eq!(unquote("\"gx"), "\"gx");
        assert_eq!(
            bracketed("Gyroscope x (rad/s)"),
            Some(("Gyroscope x", "rad/s"))
        );
        assert_eq!(bracketed("gx [deg/s]"), Some(("gx", "deg/s")));
        assert_eq!(bracketed("(s)"), None);
        assert_eq!(bracketed("gx"), None);
        assert_eq!(folded_unit(" °/sec "), "deg/s");
        assert_eq!(folded_unit("m/s²"), "m/s^2");
        assert_eq!(folded_unit("µs"), "us");
    }

    #[test]
    fn time_columns_and_their_units() {
        let stated = |to_s, label| Some(TimeUnit::Stated { to_s, label });
        assert_eq!(time_column("time"), Some(TimeUnit::Unstated));
        assert_eq!(time_column("Timestamp"), Some(TimeUnit::Unstated));
        assert_eq!(time_column("Time (s)"), stated(1.0, "s"));
        assert_eq!(time_column("\"time [ms]\""), stated(1e-3, "ms"));
        assert_eq!(time_column("t_us"), stated(1e-6, "us"));
        assert_eq!(time_column("timestamp_ns"), stated(1e-9, "ns"));
        assert_eq!(time_column("%time"), stated(1e-9, "ns"));
        assert_eq!(time_column("field.header.stamp"), stated(1e-9, "ns"));
        assert_eq!(time_column("seconds_elapsed"), Some(TimeUnit::Unstated));
        assert_eq!(time_column("gx"), None);
        assert_eq!(time_column("time (deg)"), None);
        assert_eq!(time_column("gyro_time_x"), None);
    }

    #[test]
    fn an_unstated_unit_follows_the_stamps_size() {
        assert_eq!(TimeUnit::Unstated.resolve(12.5).0, 1.0);
        assert_eq!(TimeUnit::Unstated.resolve(1.7e9).0, 1.0);
        assert_eq!(TimeUnit::Unstated.resolve(1.7e12).0, 1e-3);
        assert_eq!(TimeUnit::Unstated.resolve(1.7e15).0, 1e-6);
        let (to_s, how) = TimeUnit::Unstated.resolve(1.7e18);
        assert_eq!(to_s, 1e-9);
        assert!(how.starts_with("ns, unstated"), "{how}");
    }

    #[test]
    fn counters() {
        assert!(counter_column("field.header.seq"));
        assert!(counter_column("\"seq\""));
        assert!(!counter_column("gx"));
    }
}

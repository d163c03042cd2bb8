//! UTC timestamps without a date-time crate: the catalog needs only "now" as ISO 8601 text
//! (readable, sortable, unambiguous) and as seconds (for durations and liveness).

use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Seconds since the Unix epoch.
pub fn unix_seconds(t: SystemTime) -> f64 {
    t.duration_since(UNIX_EPOCH)
        .unwrap_or(Duration::ZERO)
        .as_secs_f64()
}

/// `2024-05-01T12:34:56.789Z`.
pub fn iso8601(t: SystemTime) -> String {
    let (date, (h, m, s), ms) = civil(t);
    format!("{}T{h:02}:{m:02}:{s:02}.{ms:03}Z", date_text(date, "-"))
}

/// `20240501-123456`, for default session names.
pub fn compact(t: SystemTime) -> String {
    let (date, (h, m, s), _) = civil(t);
    format!("{}-{h:02}{m:02}{s:02}", date_text(date, ""))
}

fn date_text((y, mo, d): (i64, u32, u32), sep: &str) -> String {
    format!("{y:04}{sep}{mo:02}{sep}{d:02}")
}

type Civil = ((i64, u32, u32), (u64, u64, u64), u32);

fn civil(t: SystemTime) -> Civil {
    let since = t.duration_since(UNIX_EPOCH).unwrap_or(Duration::ZERO);
    let secs = since.as_secs();
    let day_secs = secs % 86_400;
    let time = (day_secs / 3600, day_secs % 3600 / 60, day_secs % 60);
    (
        days_to_date((secs / 86_400) as i64),
        time,
        since.subsec_millis(),
    )
}

/// Days since 1970-01-01 to (year, month, day): H. Hinnant's `civil_from_days`.
fn days_to_date(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_instants() {
        let t = UNIX_EPOCH + Duration::from_millis(1_714_566_896_789);
        assert_eq!(iso8601(t), "2024-05-01T12:34:56.789Z");
        assert_eq!(compact(t), "20240501-123456");
        assert_eq!(iso8601(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        // A leap day.
        let leap = UNIX_EPOCH + Duration::from_secs(951_782_400);
        assert_eq!(iso8601(leap), "2000-02-29T00:00:00.000Z");
    }
}

//! Text tables: numeric columns separated by commas, semicolons, tabs or spaces (with a
//! decimal comma where the separator is not a comma); `#` comments, `//` comment lines and
//! blank lines anywhere; fields and names in quotes or not; before the data, optional
//! metadata lines (a rate among them: [`stated_rate`]) and an optional header line of
//! column names, a UTF-8 byte-order mark and a `sep=;` hint ignored. A time column
//! ([`names::time_column`]: `time`, `Time (s)`, `time_ms`, ROS's `%time` in nanoseconds...)
//! gives the rate by least squares; jitter is accepted and gaps of missing samples are
//! refused ([`super::timing`]). Other time columns and sample counters (`field.header.seq`)
//! are set aside, by name.
//!
//! The data lines are parsed in parallel chunks: a 300 MB 8-hour log is read in about a second.

use super::names::{self, unquote};
use super::timing::{self, Timing, TimingError};
use super::{InputError, RateSource, Table};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

/// A parsed chunk: its line count, and its columns or the chunk-relative line of the first
/// error with the message.
type Chunk = (usize, Result<Vec<Vec<f64>>, (usize, String)>);

/// Chunk size for parallel parsing; each chunk ends at a line end.
const CHUNK_BYTES: usize = 1 << 20;

/// How a table's time column is used.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct TimeOptions {
    /// Set the time column aside: the rows are uniform samples.
    pub ignore_time: bool,
    /// Where samples are missing, keep the longest run of rows between gaps (a note says
    /// which rows and what was left out) instead of refusing the file.
    pub longest_run: bool,
}

/// The table in `bytes`; a time column is fitted unless `time.ignore_time` sets it aside.
/// What the caller must show the user (the run kept) goes into `notes`.
pub(super) fn parse(
    path: &Path,
    bytes: &[u8],
    time: TimeOptions,
    notes: &mut Vec<String>,
) -> Result<Table, InputError> {
    // Spreadsheet exports start with a byte-order mark; lines are counted as before.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut preamble = read_preamble(path, bytes)?;
    preamble.missing_ok = time.longest_run;
    let width = preamble.names.len();
    let columns = parse_data(path, bytes, &preamble)?;
    let rows = columns.first().map_or(0, Vec::len);
    if rows == 0 {
        return Err(InputError::file(path, "no data lines"));
    }
    let mut channels: Vec<(String, Vec<f64>)> =
        preamble.names.iter().cloned().zip(columns).collect();
    debug_assert_eq!(channels.len(), width);
    let (mut timing, mut ignored_time) = (None, None);
    // The rows kept start at this data row (a run between gaps).
    let mut first_row = 0;
    if let Some(at) = channels
        .iter()
        .position(|(n, _)| names::time_column(n).is_some())
    {
        let (name, times) = channels.remove(at);
        if time.ignore_time {
            ignored_time = Some(name);
        } else {
            let (fitted, run) = time_column(path, bytes, &preamble, &name, times, time, notes)?;
            keep_rows(&mut channels, run.clone());
            first_row = run.start;
            timing = Some(fitted);
        }
    }
    if time.longest_run {
        let run = complete_rows(bytes, &preamble, &channels, first_row, notes);
        keep_rows(&mut channels, run);
    }
    // Further stamps and counters are neither the time base nor signals.
    let mut set_aside = Vec::new();
    channels.retain(|(n, _)| {
        let keep = names::time_column(n).is_none() && !names::counter_column(n);
        if !keep {
            set_aside.push(n.clone());
        }
        keep
    });
    if channels.is_empty() {
        return Err(InputError::file(path, "no data columns besides time"));
    }
    Ok(Table {
        channels,
        rate_hz: preamble.rate_hz.take(),
        timing,
        ignored_time,
        set_aside,
    })
}

/// A time column's fit, read in its unit, and the rows it keeps: all, or with
/// `time.longest_run` the longest run between gaps (a note says which).
fn time_column(
    path: &Path,
    bytes: &[u8],
    pre: &Preamble,
    name: &str,
    mut times: Vec<f64>,
    time: TimeOptions,
    notes: &mut Vec<String>,
) -> Result<(Timing, Range<usize>), InputError> {
    if let Some(row) = times.iter().position(|t| t.is_nan()) {
        let line = row_lines(bytes, pre, &[row])(row);
        return Err(InputError::line(
            path,
            line,
            format!("time column '{name}' has no value"),
        ));
    }
    let unit = names::time_column(name).unwrap_or(names::TimeUnit::Unstated);
    let (scale, how) = unit.resolve(times[0]);
    if scale != 1.0 {
        times.iter_mut().for_each(|t| *t *= scale);
    }
    let (mut fitted, run) = match timing::analyse(name, &times) {
        Err(TimingError::Gaps { gaps, .. }) if time.longest_run => {
            let run = timing::longest_run(&gaps, times.len());
            let kept = timing::analyse(name, &times[run.clone()]);
            let fitted = time_base(path, bytes, pre, name, kept, run.start)?;
            let lines = row_lines(bytes, pre, &[run.start, run.end - 1]);
            let missing: u64 = gaps.iter().map(|g| g.missing).sum();
            notes.push(format!(
                "time column '{name}': {missing} sample(s) missing in {} gap(s); analysed the \
                 longest gap-free run (--longest-run): lines {} to {}, {} of {} rows",
                gaps.len(),
                lines(run.start),
                lines(run.end - 1),
                run.len(),
                times.len()
            ));
            (fitted, run)
        }
        fitted => (
            time_base(path, bytes, pre, name, fitted, 0)?,
            0..times.len(),
        ),
    };
    fitted.unit = how;
    Ok((fitted, run))
}

/// Every channel's rows `run`.
fn keep_rows(channels: &mut [(String, Vec<f64>)], run: Range<usize>) {
    for (_, values) in channels {
        values.truncate(run.end);
        values.drain(..run.start);
    }
}

/// The longest run of rows with a value in every channel (a missing value is a lost sample),
/// the rows counted from data row `first_row`; a note when some rows lack one.
fn complete_rows(
    bytes: &[u8],
    pre: &Preamble,
    channels: &[(String, Vec<f64>)],
    first_row: usize,
    notes: &mut Vec<String>,
) -> Range<usize> {
    let rows = channels.first().map_or(0, |c| c.1.len());
    let incomplete: Vec<usize> = (0..rows)
        .filter(|&r| channels.iter().any(|(_, v)| v[r].is_nan()))
        .collect();
    if incomplete.is_empty() {
        return 0..rows;
    }
    let mut best = 0..0;
    let mut start = 0;
    for end in incomplete.iter().copied().chain([rows]) {
        if end - start > best.len() {
            best = start..end;
        }
        start = end + 1;
    }
    let wanted = [
        first_row + incomplete[0],
        first_row + best.start,
        first_row + best.end.max(1) - 1,
    ];
    let lines = row_lines(bytes, pre, &wanted);
    notes.push(format!(
        "{} row(s) with a missing value, the first at line {}; analysed the longest run of \
         complete rows (--longest-run): lines {} to {}, {} of {} rows",
        incomplete.len(),
        lines(wanted[0]),
        lines(wanted[1]),
        lines(wanted[2]),
        best.len(),
        rows
    ));
    best
}

/// The time column's fit (of the rows from `first_row` on) with its worst step's line, or
/// an error naming the lines at fault.
fn time_base(
    path: &Path,
    bytes: &[u8],
    pre: &Preamble,
    name: &str,
    fitted: Result<Timing, TimingError>,
    first_row: usize,
) -> Result<Timing, InputError> {
    match fitted {
        Ok(mut t) => {
            let row = first_row + t.worst_step.row;
            t.worst_step.row = row;
            t.worst_step.line = row_lines(bytes, pre, &[row])(row);
            Ok(t)
        }
        Err(e) => {
            let rows: Vec<usize> = e.rows().iter().map(|r| first_row + r).collect();
            let lines = row_lines(bytes, pre, &rows);
            let place = |row| format!("line {}", lines(first_row + row));
            let mut message = e.explain(name, &place);
            if matches!(e, TimingError::Gaps { .. }) {
                message.push_str(", or --longest-run to analyse the longest run between gaps");
            }
            Err(match e {
                TimingError::Backwards { row, .. } => {
                    InputError::line(path, lines(first_row + row), message)
                }
                _ => InputError::file(path, message),
            })
        }
    }
}

/// The file line of each data row (0-based) in `rows`, as a lookup: data lines are counted as
/// the parser counts them, skipping blank and comment lines.
fn row_lines(bytes: &[u8], pre: &Preamble, rows: &[usize]) -> impl Fn(usize) -> usize + use<> {
    let mut wanted: Vec<usize> = rows.to_vec();
    wanted.sort_unstable();
    wanted.dedup();
    let mut wanted = wanted.into_iter().peekable();
    let mut found = BTreeMap::new();
    let mut row = 0;
    for (i, (_, raw)) in lines(bytes, pre.data_start).enumerate() {
        let Some(&next) = wanted.peek() else { break };
        if clean(raw).is_empty() {
            continue;
        }
        if row == next {
            found.insert(row, pre.first_data_line + i);
            wanted.next();
        }
        row += 1;
    }
    let first = pre.first_data_line;
    move |row| found.get(&row).copied().unwrap_or(first)
}

/// Everything before the first data line.
struct Preamble {
    names: Vec<String>,
    delimiter: Delimiter,
    /// Numbers are written with a decimal comma (`0,25;1,5`).
    decimal_comma: bool,
    /// An empty field or `NaN` is a missing value (read as NaN) rather than an error.
    missing_ok: bool,
    rate_hz: Option<RateSource>,
    /// Byte offset and 1-based line number of the first data line.
    data_start: usize,
    first_data_line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Delimiter {
    Char(char),
    Whitespace,
}

impl Delimiter {
    /// A semicolon or a tab before a comma: where either separates, a comma is a decimal
    /// comma.
    fn detect(line: &str) -> Delimiter {
        [';', '\t', ',']
            .into_iter()
            .find(|c| line.contains(*c))
            .map_or(Delimiter::Whitespace, Delimiter::Char)
    }

    fn split(self, line: &str) -> Box<dyn Iterator<Item = &str> + '_> {
        match self {
            Delimiter::Char(c) => Box::new(line.split(c).map(unquote)),
            Delimiter::Whitespace => Box::new(line.split_whitespace().map(unquote)),
        }
    }
}

/// Lines with their 1-based numbers and byte offsets, `\r` and comments stripped.
fn lines(bytes: &[u8], start: usize) -> impl Iterator<Item = (usize, &[u8])> {
    let mut offset = start;
    std::iter::from_fn(move || {
        if offset >= bytes.len() {
            return None;
        }
        let end = bytes[offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| offset + p);
        let line = &bytes[offset..end];
        let at = offset;
        offset = end + 1;
        Some((at, line))
    })
}

/// A line without its comment: from `#` on, or the whole line when it starts with `//`.
fn clean(line: &[u8]) -> &[u8] {
    let line = line
        .iter()
        .position(|&b| b == b'#')
        .map_or(line, |p| &line[..p])
        .trim_ascii();
    if line.starts_with(b"//") { &[] } else { line }
}

/// A comment just before the data read as its header: as many fields as the data has, split
/// the same way, none of them a number.
fn commented_header(comment: &str, delimiter: Delimiter, width: usize) -> Option<Vec<String>> {
    let fields: Vec<&str> = delimiter.split(comment.trim()).collect();
    let names = fields.len() == width
        && fields
            .iter()
            .all(|f| !f.is_empty() && f.parse::<f64>().is_err());
    names.then(|| fields.iter().map(|f| f.to_string()).collect())
}

/// Keys that state a sample rate in a preamble line, lower case, spaces as `_`.
const RATE_KEYS: [&str; 13] = [
    "fs",
    "rate",
    "rate_hz",
    "sample_rate",
    "sampling_rate",
    "sample_rate_hz",
    "sampling_rate_hz",
    "update_rate",
    "output_rate",
    "data_rate",
    "output_data_rate",
    "sampling_frequency",
    "sample_frequency",
];

/// The sample rate a preamble line states, commented or not, with the key as written:
/// `Fs,100` (the MPU-6050 logger's), `sample rate = 200 Hz`, `# rate: 100`, Xsens MT
/// Manager's `// Update Rate: 100.0Hz`.
fn stated_rate(line: &str) -> Option<(&str, f64)> {
    let line = line.trim();
    let line = line
        .strip_prefix("//")
        .or_else(|| line.strip_prefix('#'))
        .unwrap_or(line)
        .trim();
    let at = line.find([',', ';', '\t', ':', '='])?;
    let key = line[..at].trim();
    let normal = unquote(key).to_ascii_lowercase().replace([' ', '-'], "_");
    if !RATE_KEYS.contains(&normal.as_str()) {
        return None;
    }
    let value = unquote(&line[at + 1..]);
    let digits = value
        .strip_suffix("Hz")
        .or_else(|| value.strip_suffix("hz"))
        .or_else(|| value.strip_suffix("HZ"))
        .unwrap_or(value)
        .trim();
    digits.parse().ok().map(|hz| (key, hz))
}

fn utf8<'a>(path: &Path, number: usize, line: &'a [u8]) -> Result<&'a str, InputError> {
    std::str::from_utf8(line).map_err(|_| InputError::line(path, number, "not UTF-8 text"))
}

fn read_preamble(path: &Path, bytes: &[u8]) -> Result<Preamble, InputError> {
    let mut names: Option<Vec<String>> = None;
    let mut rate_hz = None;
    // The last line before the data that was wholly a `#` comment: EuRoC and TUM-VI write
    // their header as one (`#timestamp [ns],w_RS_S_x [rad s^-1],...`).
    let mut commented: Option<&str> = None;
    for (number, (offset, raw)) in lines(bytes, 0).enumerate().map(|(i, l)| (i + 1, l)) {
        let before = commented;
        if let Some(text) = raw.trim_ascii().strip_prefix(b"#") {
            commented = std::str::from_utf8(text).ok();
        } else if !raw.trim_ascii().is_empty() {
            commented = None;
        }
        if names.is_none()
            && let Some((key, hz)) = stated_rate(utf8(path, number, raw)?)
        {
            if !(hz.is_finite() && hz > 0.0) {
                return Err(InputError::line(
                    path,
                    number,
                    format!("{key}: the rate must be a positive number of Hz"),
                ));
            }
            rate_hz = Some(RateSource {
                hz,
                from: format!("rate in the header ({key}, line {number})"),
            });
            continue;
        }
        let line = utf8(path, number, clean(raw))?;
        if line.is_empty() {
            continue;
        }
        let delimiter = Delimiter::detect(line);
        let fields: Vec<&str> = delimiter.split(line).collect();
        // A data line may lack a value (read as missing), but not every one.
        let numeric = |decimal_comma| {
            fields
                .iter()
                .all(|f| missing(f) || read_number(f, decimal_comma).is_some())
                && fields
                    .iter()
                    .any(|f| read_number(f, decimal_comma).is_some_and(f64::is_finite))
        };
        let decimal_comma = delimiter != Delimiter::Char(',') && !numeric(false) && numeric(true);
        if numeric(decimal_comma) {
            let width = fields.len();
            let names = match names {
                Some(n) if n.len() != width => {
                    return Err(InputError::line(
                        path,
                        number,
                        format!("{width} fields, but the header names {} columns", n.len()),
                    ));
                }
                Some(n) => n,
                None => match before.and_then(|c| commented_header(c, delimiter, width)) {
                    Some(n) => n,
                    None => (0..width).map(|i| format!("c{i}")).collect(),
                },
            };
            return Ok(Preamble {
                names,
                delimiter,
                decimal_comma,
                missing_ok: false,
                rate_hz,
                data_start: offset,
                first_data_line: number,
            });
        }
        if names.is_none()
            && let [_, value] = fields[..]
            && value.parse::<f64>().is_ok()
        {
            // Metadata `key,value`; a rate among them was read above.
            continue;
        }
        if names.is_none() && line.to_ascii_lowercase().starts_with("sep=") {
            // A spreadsheet's separator hint (`sep=;`): the separator is detected anyway.
            continue;
        }
        if names.is_some() {
            return Err(InputError::line(
                path,
                number,
                format!("expected numbers after the header, found '{line}'"),
            ));
        }
        names = Some(fields.iter().map(|f| f.to_string()).collect());
    }
    Err(InputError::file(path, "no data lines"))
}

/// Parse every data line into columns, in parallel chunks; the first bad line is reported.
fn parse_data(path: &Path, bytes: &[u8], pre: &Preamble) -> Result<Vec<Vec<f64>>, InputError> {
    let body = &bytes[pre.data_start..];
    let mut bounds = vec![0];
    while let Some(&last) = bounds.last() {
        if last >= body.len() {
            break;
        }
        let target = (last + CHUNK_BYTES).min(body.len());
        let end = body[target..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(body.len(), |p| target + p + 1);
        bounds.push(end);
    }
    let width = pre.names.len();
    let chunks: Vec<Chunk> = bounds
        .par_windows(2)
        .map(|w| parse_chunk(&body[w[0]..w[1]], pre, width))
        .collect();
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); width];
    let mut line = pre.first_data_line;
    for (count, result) in chunks {
        match result {
            Ok(part) => columns
                .iter_mut()
                .zip(part)
                .for_each(|(c, p)| c.extend_from_slice(&p)),
            Err((at, message)) => return Err(InputError::line(path, line + at, message)),
        }
        line += count;
    }
    Ok(columns)
}

/// Whether a field is a missing value: empty, or `NaN`, `NA`, `null`, `None` in any case.
fn missing(field: &str) -> bool {
    field.is_empty()
        || ["nan", "na", "null", "none"]
            .iter()
            .any(|m| field.eq_ignore_ascii_case(m))
}

/// A field's number, read with a decimal comma if `decimal_comma`; None if it is none.
fn read_number(field: &str, decimal_comma: bool) -> Option<f64> {
    if decimal_comma && field.contains(',') {
        field.replacen(',', ".", 1).parse().ok()
    } else {
        field.parse().ok()
    }
}

/// One chunk: its line count and its columns, or the chunk-relative line of the first error.
fn parse_chunk(chunk: &[u8], pre: &Preamble, width: usize) -> Chunk {
    let (delimiter, names) = (pre.delimiter, &pre.names);
    let mut columns: Vec<Vec<f64>> = vec![Vec::with_capacity(chunk.len() / (8 * width + 1)); width];
    let mut count = 0;
    for (i, (_, raw)) in lines(chunk, 0).enumerate() {
        count = i + 1;
        let Ok(line) = std::str::from_utf8(clean(raw)) else {
            return (count, Err((i, "not UTF-8 text".into())));
        };
        if line.is_empty() {
            continue;
        }
        let mut n = 0;
        for field in delimiter.split(line) {
            let Some(column) = columns.get_mut(n) else {
                n += 1;
                continue;
            };
            // A number first: the missing-value spellings are checked only where none parses.
            match read_number(field, pre.decimal_comma) {
                Some(v) if v.is_finite() => column.push(v),
                _ if missing(field) && pre.missing_ok => column.push(f64::NAN),
                _ if missing(field) => {
                    let message = format!(
                        "column '{}': a missing value ('{field}'); --longest-run analyses the \
                         longest run of complete rows",
                        names[n]
                    );
                    return (count, Err((i, message)));
                }
                Some(v) => {
                    return (count, Err((i, format!("column '{}' is {v}", names[n]))));
                }
                None => {
                    let message = format!("column '{}': '{field}' is not a number", names[n]);
                    return (count, Err((i, message)));
                }
            }
            n += 1;
        }
        if n != width {
            return (
                count,
                Err((i, format!("{n} fields where the table has {width}"))),
            );
        }
    }
    (count, Ok(columns))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<Table, InputError> {
        parse(
            Path::new("t.csv"),
            s.as_bytes(),
            TimeOptions::default(),
            &mut Vec::new(),
        )
    }

    /// The table with `--longest-run`, and its notes.
    fn parse_longest(bytes: &[u8]) -> Result<(Table, Vec<String>), InputError> {
        let mut notes = Vec::new();
        let longest = TimeOptions {
            longest_run: true,
            ..TimeOptions::default()
        };
        parse(Path::new("t.csv"), bytes, longest, &mut notes).map(|t| (t, notes))
    }

    #[test]
    fn header_metadata_and_comments() {
        let t = parse_str("Fs,100\nLogging Type,1\nax,ay,gz\n# c\n1,2,3\n\n4,5,6 # x\r\n").unwrap();
        assert_eq!(t.rate_hz.unwrap().hz, 100.0);
        let names: Vec<_> = t.channels.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(names, ["ax", "ay", "gz"]);
        assert_eq!(t.channels[2].1, [3.0, 6.0]);
    }

    #[test]
    fn rates_stated_before_the_header() {
        for (preamble, hz) in [
            ("Fs,100\n", 100.0),
            ("sample rate = 200 Hz\n", 200.0),
            ("# Sampling Rate: 50\n", 50.0),
            (
                "// Update Rate: 400.0Hz\n// Filter Profile: general\n",
                400.0,
            ),
            ("sep=;\nrate;25\n", 25.0),
        ] {
            let t = parse_str(&format!("{preamble}gx;gy\n1;2\n")).unwrap();
            assert_eq!(t.rate_hz.map(|r| r.hz), Some(hz), "{preamble}");
            assert_eq!(t.channels[1].1, [2.0], "{preamble}");
        }
        let err = parse_str("fs: 0 Hz\ngx\n1\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:1: fs: the rate must be a positive number of Hz");
        // A rate named after the header is data, and refused as such.
        assert!(parse_str("gx\nrate: 5\n").is_err());
    }

    #[test]
    fn a_commented_header_as_euroc_writes_it() {
        let text = "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],\
                    a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n\
                    1403636579758555392,-0.09,0.13,0.08,8.16,-0.37,-2.44\n\
                    1403636579763555584,-0.08,0.13,0.08,8.33,-0.40,-2.20\n\
                    1403636579768555520,-0.08,0.12,0.08,8.33,-0.40,-2.21\n";
        let t = parse_str(text).unwrap();
        let timing = t.timing.unwrap();
        assert_eq!(timing.unit, "ns, by its name");
        // Three stamps 5.000192 and 4.999936 ms apart.
        assert!((timing.rate_hz - 200.0).abs() < 1e-2, "{timing:?}");
        assert_eq!(t.channels.len(), 6);
        assert_eq!(t.channels[0].0, "w_RS_S_x [rad s^-1]");
        // A comment that is not a header stays a comment.
        let t = parse_str("# logged by me\n1,2\n").unwrap();
        assert_eq!(t.channels[0].0, "c0");
        let t = parse_str("# a, b, 3\n1,2,3\n").unwrap();
        assert_eq!(t.channels[0].0, "c0");
    }

    #[test]
    fn whitespace_and_headerless() {
        let t = parse_str("1.5 2\n3 4e-1\n").unwrap();
        assert_eq!(t.channels[0].0, "c0");
        assert_eq!(t.channels[1].1, [2.0, 0.4]);
        assert!(t.rate_hz.is_none());
    }

    #[test]
    fn time_column_gives_the_rate() {
        let t = parse_str("time,gx\n0.00,1\n0.01,2\n0.02,3\n").unwrap();
        assert_eq!(t.timing.unwrap().rate_hz, 100.0);
        assert_eq!(t.channels.len(), 1);
        let t = parse_str("time_ms;gx\n0;1\n5;2\n10;3\n").unwrap();
        assert_eq!(t.timing.unwrap().rate_hz, 200.0);
        assert!(t.rate_hz.is_none());
    }

    #[test]
    fn quoted_names_bracketed_units_and_a_byte_order_mark() {
        // A phone app's export: BOM, quoted names with units, CRLF.
        let text = "\u{feff}\"Time (s)\",\"Gyroscope x (rad/s)\",\"Gyroscope y (rad/s)\"\r\n\
                    0.000,1,2\r\n0.005,3,4\r\n0.010,5,6\r\n";
        let t = parse_str(text).unwrap();
        let timing = t.timing.unwrap();
        assert_eq!(
            (timing.column.as_str(), timing.rate_hz),
            ("Time (s)", 200.0)
        );
        assert_eq!(timing.unit, "s, by its name");
        let names: Vec<_> = t.channels.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(names, ["Gyroscope x (rad/s)", "Gyroscope y (rad/s)"]);
        assert_eq!(t.channels[1].1, [2.0, 4.0, 6.0]);
        // Quoted numbers too.
        let t = parse_str("\"gx\",\"gy\"\n\"1.5\",\"2\"\n").unwrap();
        assert_eq!(t.channels[0].1, [1.5]);
    }

    #[test]
    fn a_decimal_comma_beside_semicolons_or_tabs() {
        let t = parse_str("time;gx;gy\n0,00;1,5;-2\n0,01;2,25;3e-3\n").unwrap();
        assert_eq!(t.timing.unwrap().rate_hz, 100.0);
        assert_eq!(t.channels[0].1, [1.5, 2.25]);
        assert_eq!(t.channels[1].1, [-2.0, 3e-3]);
        let t = parse_str("gx\tgy\n0,5\t1\n").unwrap();
        assert_eq!(t.channels[0].1, [0.5]);
        // A comma that separates is never a decimal comma.
        let t = parse_str("gx,gy\n0,5\n").unwrap();
        assert_eq!((t.channels[0].1[0], t.channels[1].1[0]), (0.0, 5.0));
        let err = parse_str("gx;gy\n0,5;1\n1,5;1,2,3\n")
            .unwrap_err()
            .to_string();
        assert_eq!(err, "t.csv:3: column 'gy': '1,2,3' is not a number");
    }

    #[test]
    fn ros_stamps_in_nanoseconds_and_counters_set_aside() {
        // `rostopic echo -p` output: receive time and header stamp in ns, a sequence number.
        let mut text =
            String::from("%time,field.header.seq,field.header.stamp,field.angular_velocity.x\n");
        for i in 0..50u64 {
            let ns = 1_700_000_000_000_000_000 + i * 5_000_000;
            text.push_str(&format!("{ns},{i},{ns},{}\n", i % 3));
        }
        let t = parse_str(&text).unwrap();
        let timing = t.timing.unwrap();
        assert_eq!(timing.column, "%time");
        assert_eq!(timing.unit, "ns, by its name");
        // Stamps near 1.7e18 hold 256 ns in a double: 5e-5 of a period per stamp.
        assert!((timing.rate_hz - 200.0).abs() < 1e-4, "{timing:?}");
        let names: Vec<_> = t.channels.iter().map(|c| c.0.as_str()).collect();
        assert_eq!(names, ["field.angular_velocity.x"]);
        assert_eq!(t.set_aside, ["field.header.seq", "field.header.stamp"]);
    }

    #[test]
    fn unstated_epoch_stamps_are_read_by_their_size() {
        for (scale, unit) in [(1.0, "s"), (1e3, "ms"), (1e6, "us"), (1e9, "ns")] {
            let mut text = String::from("timestamp,gx\n");
            for i in 0..40 {
                let t = (1.7e9 + i as f64 * 0.01) * scale;
                text.push_str(&format!("{t:.0},{i}\n"));
            }
            if scale == 1.0 {
                // Seconds are printed to the period's precision.
                text = String::from("timestamp,gx\n");
                for i in 0..40 {
                    text.push_str(&format!("{:.2},{i}\n", 1.7e9 + i as f64 * 0.01));
                }
            }
            let timing = parse_str(&text).unwrap().timing.unwrap();
            assert!((timing.rate_hz - 100.0).abs() < 1e-3, "{unit}: {timing:?}");
            assert!(timing.unit.starts_with(unit), "{unit}: {}", timing.unit);
        }
    }

    #[test]
    fn errors_name_the_line_and_column() {
        let err = parse_str("gx,gy\n1,2\n3,x\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: column 'gy': 'x' is not a number");
        let err = parse_str("gx,gy\n1,2\n3\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: 1 fields where the table has 2");
        let err = parse_str("gx,gy\n1,2\n3,NaN\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "t.csv:3: column 'gy': a missing value ('NaN'); --longest-run analyses the longest \
             run of complete rows"
        );
        let err = parse_str("gx,gy\n1,2\n3,inf\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: column 'gy' is inf");
        let err = parse_str("gx\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv: no data lines");
        let err = parse_str("gx\ngy\n1\n").unwrap_err().to_string();
        assert!(err.starts_with("t.csv:2: expected numbers"), "{err}");
    }

    #[test]
    fn chunks_keep_line_numbers() {
        // More than one parallel chunk, with the error deep in a later one.
        let mut s = String::from("gx\n");
        let rows = CHUNK_BYTES / 4 * 3;
        for i in 0..rows {
            s.push_str(&format!("{}\n", i % 10));
        }
        let t = parse_str(&s).unwrap();
        assert_eq!(t.channels[0].1.len(), rows);
        assert_eq!(t.channels[0].1[rows - 1], ((rows - 1) % 10) as f64);
        s.push_str("oops\n");
        let err = parse_str(&s).unwrap_err().to_string();
        assert_eq!(
            err,
            format!("t.csv:{}: column 'gx': 'oops' is not a number", rows + 2)
        );
    }

    /// `n` rows `t,gx` at 100 Hz with a comment line after every 100th data row, so that file
    /// lines and data rows differ; `stamp` gives row i's time.
    fn timed(n: usize, stamp: impl Fn(usize) -> Option<f64>) -> String {
        let mut s = String::from("# logger v2\nt,gx\n");
        for i in 0..n {
            if let Some(t) = stamp(i) {
                s.push_str(&format!("{t:.6},{}\n", i % 7));
            }
            if i % 100 == 99 {
                s.push_str("# marker\n");
            }
        }
        s
    }

    /// The line of the row `timed` wrote for `i`, `dropped` rows before it left out: two
    /// header lines, the data rows and the markers before it.
    fn line_of_row(i: usize, dropped: usize) -> usize {
        3 + (i - dropped) + i / 100
    }

    #[test]
    fn jitter_is_accepted_and_its_worst_step_named_by_line() {
        // +-100 us of deterministic jitter (steps within 200 us of the period), and from row
        // 1234 on every stamp 500 us later: one step 300 us beyond any other.
        let jitter = |i: usize| ((i * 7919) % 201) as f64 * 1e-6 - 100e-6;
        let text = timed(3000, |i| {
            Some(i as f64 * 0.01 + jitter(i) + if i >= 1234 { 500e-6 } else { 0.0 })
        });
        let t = parse_str(&text).unwrap();
        let timing = t.timing.unwrap();
        // The 0.05-period step at 41 % of the record tilts the line by 6 h p (1 - p) / n =
        // 2.4e-5 of the period: 2.4 mHz.
        assert!((timing.rate_hz - 100.0).abs() < 5e-3, "{timing:?}");
        assert!(!timing.uniform);
        assert_eq!(timing.worst_step.row, 1234);
        assert_eq!(timing.worst_step.line, line_of_row(1234, 0));
        let shown = timing.to_string();
        assert!(
            shown.contains(&format!("at line {}", line_of_row(1234, 0))),
            "{shown}"
        );
    }

    #[test]
    fn missing_values_are_refused_or_cut_around() {
        let mut text = String::from("gx,gy\n");
        for r in 0..12 {
            let gy = match r {
                2 => String::new(),
                9 => "NaN".into(),
                _ => format!("{}", r * 10),
            };
            text.push_str(&format!("{r},{gy}\n"));
        }
        let err = parse_str(&text).unwrap_err().to_string();
        assert!(
            err.starts_with("t.csv:4: column 'gy': a missing value ('')"),
            "{err}"
        );
        let (t, notes) = parse_longest(text.as_bytes()).unwrap();
        assert_eq!(t.channels[0].1, [3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
        assert_eq!(t.channels[1].1, [30.0, 40.0, 50.0, 60.0, 70.0, 80.0]);
        assert_eq!(
            notes,
            [
                "2 row(s) with a missing value, the first at line 4; analysed the longest run of \
              complete rows (--longest-run): lines 5 to 10, 6 of 12 rows"
            ]
        );
        // A first data line with a missing value is still data.
        let t = parse_longest(b"gx,gy\n1,\n2,3\n4,5\n").unwrap().0;
        assert_eq!(t.channels[1].1, [3.0, 5.0]);
        let err = parse_str("t,gx\n0,1\n,2\n").unwrap_err().to_string();
        assert!(
            err.starts_with("t.csv:3: column 't': a missing value"),
            "{err}"
        );
        let err = parse_longest(b"t,gx\n0,1\n,2\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: time column 't' has no value");
    }

    #[test]
    fn gaps_are_refused_by_line_time_and_count() {
        // Rows 500..503 and 2100 never made it into the file.
        let text = timed(3000, |i| {
            let lost = (500..503).contains(&i) || i == 2100;
            (!lost).then_some(i as f64 * 0.01)
        });
        let err = parse_str(&text).unwrap_err().to_string();
        let expected = format!(
            "t.csv: time column 't': 4 sample(s) missing in 2 gap(s) that the fitted period (10.0000 ms) \
             cannot absorb: line {} (t = 5.03 s): 3 sample(s) missing; line {} (t = 21.01 s): \
             1 sample(s) missing;",
            line_of_row(503, 3),
            line_of_row(2101, 4)
        );
        assert!(err.starts_with(&expected), "{err}\n{expected}");
        assert!(
            err.ends_with(", or --longest-run to analyse the longest run between gaps"),
            "{err}"
        );
        // With --longest-run, the rows between the two gaps (stamps 5.03 s to 20.99 s).
        let (t, notes) = parse_longest(text.as_bytes()).unwrap();
        assert_eq!(t.channels[0].1.len(), 1597);
        assert_eq!(t.channels[0].1[0], (503 % 7) as f64);
        let timing = t.timing.unwrap();
        assert!((timing.rate_hz - 100.0).abs() < 1e-6, "{timing:?}");
        assert_eq!(
            notes,
            [format!(
                "time column 't': 4 sample(s) missing in 2 gap(s); analysed the longest gap-free \
                 run (--longest-run): lines {} to {}, 1597 of 2996 rows",
                line_of_row(503, 3),
                line_of_row(2099, 3)
            )]
        );
        // The time column set aside, the rows are taken as they are.
        let ignore = TimeOptions {
            ignore_time: true,
            ..TimeOptions::default()
        };
        let t = parse(Path::new("t.csv"), text.as_bytes(), ignore, &mut Vec::new()).unwrap();
        assert!(t.timing.is_none());
        assert_eq!(t.ignored_time.as_deref(), Some("t"));
        assert_eq!(t.channels[0].1.len(), 2996);
    }

    #[test]
    fn a_clock_going_back_is_refused_at_its_line() {
        let text = timed(500, |i| {
            Some(i as f64 * 0.01 - if i >= 321 { 5.0 } else { 0.0 })
        });
        let err = parse_str(&text).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!(
                "t.csv:{}: time column 't' steps back by 4.99",
                line_of_row(321, 0)
            )),
            "{err}"
        );
    }
}

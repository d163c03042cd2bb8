//! Text tables: numeric columns separated by commas, semicolons, tabs or spaces; `#` comments
//! and blank lines anywhere; before the data, optional `key,value` metadata lines (the
//! MPU-6050 logger's `Fs,100` gives the rate) and an optional header line of column names.
//! A `time` column (seconds; `time_ms`, `time_us` scaled) gives the rate and must be uniform.
//!
//! The data lines are parsed in parallel chunks: a 300 MB 8-hour log is read in about a second.

use super::{InputError, RateSource, Table};
use rayon::prelude::*;
use std::path::Path;

/// A parsed chunk: its line count, and its columns or the chunk-relative line of the first
/// error with the message.
type Chunk = (usize, Result<Vec<Vec<f64>>, (usize, String)>);

/// Chunk size for parallel parsing; each chunk ends at a line end.
const CHUNK_BYTES: usize = 1 << 20;

/// Relative tolerance on each time step against the record's mean step.
const TIME_STEP_TOLERANCE: f64 = 0.01;

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<Table, InputError> {
    let preamble = read_preamble(path, bytes)?;
    let width = preamble.names.len();
    let columns = parse_data(path, bytes, &preamble)?;
    let rows = columns.first().map_or(0, Vec::len);
    if rows == 0 {
        return Err(InputError::file(path, "no data lines"));
    }
    let mut channels: Vec<(String, Vec<f64>)> = preamble.names.into_iter().zip(columns).collect();
    debug_assert_eq!(channels.len(), width);
    let mut rate_hz = preamble.rate_hz;
    if let Some(at) = channels.iter().position(|(n, _)| time_scale(n).is_some()) {
        let (name, times) = channels.remove(at);
        let scale = time_scale(&name).unwrap_or(1.0);
        let hz = uniform_rate(path, &times, scale, preamble.first_data_line, &name)?;
        if let Some(stated) = &rate_hz
            && ((stated.hz - hz) / hz).abs() > 1e-3
        {
            return Err(InputError::file(
                path,
                format!(
                    "the {} ({} Hz) disagrees with the time column '{name}' ({hz} Hz)",
                    stated.from, stated.hz
                ),
            ));
        }
        rate_hz = Some(RateSource {
            hz,
            from: format!("time column '{name}'"),
        });
    }
    if channels.is_empty() {
        return Err(InputError::file(path, "no data columns besides time"));
    }
    Ok(Table { channels, rate_hz })
}

/// A time column's factor to seconds, or None if the name is not a time column's.
fn time_scale(name: &str) -> Option<f64> {
    match name.trim().to_ascii_lowercase().as_str() {
        "time" | "t" | "timestamp" | "time_s" | "t_s" | "timestamp_s" => Some(1.0),
        "time_ms" | "t_ms" | "timestamp_ms" => Some(1e-3),
        "time_us" | "t_us" | "timestamp_us" => Some(1e-6),
        _ => None,
    }
}

/// Everything before the first data line.
struct Preamble {
    names: Vec<String>,
    delimiter: Delimiter,
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
    fn detect(line: &str) -> Delimiter {
        [',', ';', '\t']
            .into_iter()
            .find(|c| line.contains(*c))
            .map_or(Delimiter::Whitespace, Delimiter::Char)
    }

    fn split(self, line: &str) -> Box<dyn Iterator<Item = &str> + '_> {
        match self {
            Delimiter::Char(c) => Box::new(line.split(c).map(str::trim)),
            Delimiter::Whitespace => Box::new(line.split_whitespace()),
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

fn clean(line: &[u8]) -> &[u8] {
    let line = line
        .iter()
        .position(|&b| b == b'#')
        .map_or(line, |p| &line[..p]);
    line.trim_ascii()
}

fn utf8<'a>(path: &Path, number: usize, line: &'a [u8]) -> Result<&'a str, InputError> {
    std::str::from_utf8(line).map_err(|_| InputError::line(path, number, "not UTF-8 text"))
}

fn read_preamble(path: &Path, bytes: &[u8]) -> Result<Preamble, InputError> {
    let mut names: Option<Vec<String>> = None;
    let mut rate_hz = None;
    for (number, (offset, raw)) in lines(bytes, 0).enumerate().map(|(i, l)| (i + 1, l)) {
        let line = utf8(path, number, clean(raw))?;
        if line.is_empty() {
            continue;
        }
        let delimiter = Delimiter::detect(line);
        let fields: Vec<&str> = delimiter.split(line).collect();
        let numeric = fields.iter().all(|f| f.parse::<f64>().is_ok());
        if numeric {
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
                None => (0..width).map(|i| format!("c{i}")).collect(),
            };
            return Ok(Preamble {
                names,
                delimiter,
                rate_hz,
                data_start: offset,
                first_data_line: number,
            });
        }
        if names.is_none()
            && let [key, value] = fields[..]
            && let Ok(v) = value.parse::<f64>()
        {
            // Metadata `key,value`: the MPU-6050 logger writes `Fs,100` for its rate.
            if matches!(
                key.to_ascii_lowercase().as_str(),
                "fs" | "rate" | "rate_hz" | "sample_rate" | "sampling_rate"
            ) {
                if !(v.is_finite() && v > 0.0) {
                    return Err(InputError::line(
                        path,
                        number,
                        format!("{key},{value}: the rate must be a positive number of Hz"),
                    ));
                }
                rate_hz = Some(RateSource {
                    hz: v,
                    from: format!("rate in the header ({key}, line {number})"),
                });
            }
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
        .map(|w| parse_chunk(&body[w[0]..w[1]], width, pre.delimiter, &pre.names))
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

/// One chunk: its line count and its columns, or the chunk-relative line of the first error.
fn parse_chunk(chunk: &[u8], width: usize, delimiter: Delimiter, names: &[String]) -> Chunk {
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
            match field.parse::<f64>() {
                Ok(v) if v.is_finite() => column.push(v),
                Ok(v) => {
                    return (count, Err((i, format!("column '{}' is {v}", names[n]))));
                }
                Err(_) => {
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

/// The rate of a time column, which must step uniformly: every step within 1 % of the median
/// step (a dropped sample or a jump is an error naming its line).
fn uniform_rate(
    path: &Path,
    times: &[f64],
    scale: f64,
    first_line: usize,
    name: &str,
) -> Result<f64, InputError> {
    if times.len() < 2 {
        return Err(InputError::file(
            path,
            format!("time column '{name}' needs at least two rows"),
        ));
    }
    // The median step is the nominal one: a single gap cannot shift it.
    let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    let mid = steps.len() / 2;
    let step = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
    drop(steps);
    if step.is_nan() || step <= 0.0 {
        return Err(InputError::file(
            path,
            format!("time column '{name}' does not increase"),
        ));
    }
    if let Some(i) = times
        .windows(2)
        .position(|w| ((w[1] - w[0]) - step).abs() > TIME_STEP_TOLERANCE * step)
    {
        // Data lines may be interleaved with comments; name the row and its time.
        return Err(InputError::file(
            path,
            format!(
                "time column '{name}' is not uniform: data row {} (first data line is {first_line}) \
                 at t = {} steps by {} where the nominal (median) step is {}; resample the data or split the file",
                i + 2,
                times[i + 1],
                times[i + 1] - times[i],
                step
            ),
        ));
    }
    // The rate from the whole span (the mean step) is exact to the last digit the times
    // were printed with; rounding to 9 significant digits removes the binary residue
    // (0.005 s steps give 200 Hz, not 200.00000000000423 Hz).
    let mean_step = (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64;
    let hz = 1.0 / (mean_step * scale);
    Ok(format!("{hz:.8e}").parse().unwrap_or(hz))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<Table, InputError> {
        parse(Path::new("t.csv"), s.as_bytes())
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
    fn whitespace_and_headerless() {
        let t = parse_str("1.5 2\n3 4e-1\n").unwrap();
        assert_eq!(t.channels[0].0, "c0");
        assert_eq!(t.channels[1].1, [2.0, 0.4]);
        assert!(t.rate_hz.is_none());
    }

    #[test]
    fn time_column_gives_the_rate() {
        let t = parse_str("time,gx\n0.00,1\n0.01,2\n0.02,3\n").unwrap();
        assert!((t.rate_hz.unwrap().hz - 100.0).abs() < 1e-9);
        assert_eq!(t.channels.len(), 1);
        let t = parse_str("time_ms;gx\n0;1\n5;2\n10;3\n").unwrap();
        assert!((t.rate_hz.unwrap().hz - 200.0).abs() < 1e-9);
    }

    #[test]
    fn errors_name_the_line_and_column() {
        let err = parse_str("gx,gy\n1,2\n3,x\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: column 'gy': 'x' is not a number");
        let err = parse_str("gx,gy\n1,2\n3\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: 1 fields where the table has 2");
        let err = parse_str("gx,gy\n1,2\n3,NaN\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv:3: column 'gy' is NaN");
        let err = parse_str("gx\n").unwrap_err().to_string();
        assert_eq!(err, "t.csv: no data lines");
        let err = parse_str("time,gx\n0,1\n1,1\n3,1\n4,1\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("not uniform: data row 3"), "{err}");
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
}

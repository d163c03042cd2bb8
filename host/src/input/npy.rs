//! NumPy `.npy` arrays (format versions 1.0 to 3.0, numpy.lib.format): 1-D (one channel) or
//! 2-D with one column per channel, C or Fortran order, float64/32 or any integer type of
//! either byte order. Channels are named `c0`, `c1`, ... unless `--names` says otherwise.

use super::{InputError, Table};
use std::io::Read;
use std::path::Path;

/// The bytes every `.npy` file starts with.
pub(super) const MAGIC: &[u8] = b"\x93NUMPY";

/// Why a `.npy` file cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NpyError {
    #[error("not a NumPy .npy file (bad magic)")]
    BadMagic,
    #[error("unsupported .npy format version {0}")]
    Version(u8),
    #[error("header truncated")]
    HeaderTruncated,
    #[error("header is not text")]
    HeaderNotText,
    #[error("header has no '{0}'")]
    MissingKey(&'static str),
    #[error("bad shape {0}")]
    BadShape(String),
    #[error("dtype '{0}' is not supported: use float64/32 or an integer type")]
    Dtype(String),
    #[error("shape {0:?}: only 1-D or 2-D (samples x channels) arrays")]
    Dimensions(Vec<usize>),
    #[error("shape too large")]
    TooLarge,
    #[error("data truncated: shape {shape:?} of {dtype} needs {need} bytes, the file has {have}")]
    Truncated {
        shape: Vec<usize>,
        dtype: String,
        need: usize,
        have: usize,
    },
    #[error("the array is empty")]
    Empty,
    #[error("element [{row}, {col}] is {value}: the data must be finite")]
    NotFinite { row: usize, col: usize, value: f64 },
}

pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<Table, InputError> {
    parse_reader(path, bytes, bytes.len() as u64)
}

/// [`parse`] from a reader holding `len` bytes (a file read as it is): each value goes
/// straight into its channel, so reading costs no buffer beside the channels.
pub(super) fn parse_reader(path: &Path, reader: impl Read, len: u64) -> Result<Table, InputError> {
    read(reader, len).map_err(|e| e.at(path))
}

/// A reader's failure or a format error.
enum ReadError {
    Io(std::io::Error),
    Npy(NpyError),
}

impl ReadError {
    /// The error as the file at `path`'s.
    fn at(self, path: &Path) -> InputError {
        match self {
            ReadError::Io(source) => InputError::Io {
                path: path.to_owned(),
                source,
            },
            ReadError::Npy(source) => InputError::Npy {
                path: path.to_owned(),
                source,
            },
        }
    }
}

impl From<NpyError> for ReadError {
    fn from(e: NpyError) -> Self {
        ReadError::Npy(e)
    }
}

impl From<std::io::Error> for ReadError {
    fn from(e: std::io::Error) -> Self {
        ReadError::Io(e)
    }
}

/// Values read per chunk.
const CHUNK: usize = 1 << 13;

/// What the header says about the data, checked against the file's length.
struct Layout {
    dtype: Dtype,
    fortran: bool,
    shape: Vec<usize>,
    rows: usize,
    cols: usize,
    /// Bytes before the data.
    header_end: usize,
}

impl Layout {
    fn read(reader: &mut impl Read, len: u64) -> Result<Layout, ReadError> {
        let (header, header_end) = read_header(reader)?;
        let key = |name: &'static str| dict_value(&header, name).ok_or(NpyError::MissingKey(name));
        let dtype = Dtype::parse(key("descr")?.trim_matches(['\'', '"']))?;
        let fortran = key("fortran_order")? == "True";
        let shape = parse_shape(key("shape")?)?;
        let (rows, cols) = match shape[..] {
            [n] => (n, 1),
            [n, c] => (n, c),
            _ => return Err(NpyError::Dimensions(shape).into()),
        };
        let layout = Layout {
            dtype,
            fortran,
            shape,
            rows,
            cols,
            header_end,
        };
        let count = rows.checked_mul(cols).ok_or(NpyError::TooLarge)?;
        let have = len.saturating_sub(header_end as u64);
        if have < layout.need() as u64 {
            return Err(layout.truncated(have).into());
        }
        if count == 0 {
            return Err(NpyError::Empty.into());
        }
        Ok(layout)
    }

    /// Bytes of data the shape needs.
    fn need(&self) -> usize {
        (self.rows * self.cols).saturating_mul(self.dtype.size)
    }

    fn truncated(&self, have: u64) -> NpyError {
        NpyError::Truncated {
            shape: self.shape.clone(),
            dtype: self.dtype.name.clone(),
            need: self.need(),
            have: usize::try_from(have).unwrap_or(usize::MAX),
        }
    }

    /// Value `b` of element [row, col], finite or the error naming it.
    fn value(&self, b: &[u8], row: usize, col: usize) -> Result<f64, NpyError> {
        let value = self.dtype.read(b);
        if value.is_finite() {
            Ok(value)
        } else {
            Err(NpyError::NotFinite { row, col, value })
        }
    }

    /// Fill `bytes` from the reader; a short file is `Truncated` with `at` bytes read.
    fn read_exact(
        &self,
        reader: &mut impl Read,
        bytes: &mut [u8],
        at: usize,
    ) -> Result<(), ReadError> {
        reader.read_exact(bytes).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => self.truncated(at as u64).into(),
            _ => e.into(),
        })
    }
}

fn read(mut reader: impl Read, len: u64) -> Result<Table, ReadError> {
    let layout = Layout::read(&mut reader, len)?;
    let Layout {
        ref dtype,
        fortran,
        rows,
        cols,
        ..
    } = layout;
    let count = rows * cols;
    let mut columns: Vec<Vec<f64>> = (0..cols).map(|_| Vec::with_capacity(rows)).collect();
    let mut bytes = vec![0u8; CHUNK * dtype.size];
    let mut values = Vec::with_capacity(CHUNK);
    let mut at = 0;
    // Where the next element goes: the file's order runs along a row (C order) or down a
    // column (Fortran order).
    let (mut row, mut col) = (0, 0);
    while at < count {
        let take = CHUNK.min(count - at);
        let chunk = &mut bytes[..take * dtype.size];
        layout.read_exact(&mut reader, chunk, at * dtype.size)?;
        values.clear();
        dtype.decode(chunk, &mut values);
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            let (row, col) = if fortran {
                ((row + i) % rows, col + (row + i) / rows)
            } else {
                (row + (col + i) / cols, (col + i) % cols)
            };
            let value = values[i];
            return Err(NpyError::NotFinite { row, col, value }.into());
        }
        if cols == 1 {
            columns[0].extend_from_slice(&values);
            row += take;
        } else {
            for &v in &values {
                columns[col].push(v);
                if fortran {
                    row += 1;
                    if row == rows {
                        (row, col) = (0, col + 1);
                    }
                } else {
                    col += 1;
                    if col == cols {
                        (row, col) = (row + 1, 0);
                    }
                }
            }
        }
        at += take;
    }
    let channels = columns
        .into_iter()
        .enumerate()
        .map(|(c, column)| (format!("c{c}"), column))
        .collect();
    Ok(Table {
        channels,
        rate_hz: None,
        timing: None,
        ignored_time: None,
        set_aside: Vec::new(),
    })
}

/// An `.npy` array read a block of rows at a time, for records larger than memory: the
/// same checks and errors as reading it whole (`parse_reader`), in memory that does not
/// grow with the array. C order is read straight through; Fortran order reads each column's
/// next rows after a seek.
pub struct NpyChunks<R> {
    path: std::path::PathBuf,
    reader: R,
    layout: Layout,
    /// Rows read so far.
    row: usize,
    bytes: Vec<u8>,
}

impl NpyChunks<std::io::BufReader<std::fs::File>> {
    /// Open the `.npy` file at `path` (uncompressed) and read its header.
    pub fn open(path: &Path) -> Result<Self, InputError> {
        let io = |source| InputError::Io {
            path: path.to_owned(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        NpyChunks::new(path, std::io::BufReader::new(file), len)
    }
}

impl<R: Read + std::io::Seek> NpyChunks<R> {
    /// The array in `reader`, `len` bytes long; `path` names it in errors.
    pub fn new(path: &Path, mut reader: R, len: u64) -> Result<Self, InputError> {
        let layout = Layout::read(&mut reader, len).map_err(|e| e.at(path))?;
        Ok(NpyChunks {
            path: path.to_owned(),
            reader,
            layout,
            row: 0,
            bytes: Vec::new(),
        })
    }

    /// Rows (samples per channel).
    pub fn rows(&self) -> usize {
        self.layout.rows
    }

    /// Columns (channels).
    pub fn cols(&self) -> usize {
        self.layout.cols
    }

    /// Replace `columns` (one per channel) with the next rows, at most `max_rows` (at least
    /// one); the count read, 0 at the end.
    pub fn next_rows(
        &mut self,
        max_rows: usize,
        columns: &mut [Vec<f64>],
    ) -> Result<usize, InputError> {
        self.fill(max_rows.max(1), columns)
            .map_err(|e| e.at(&self.path))
    }

    fn fill(&mut self, max_rows: usize, columns: &mut [Vec<f64>]) -> Result<usize, ReadError> {
        let Layout {
            ref dtype,
            fortran,
            rows,
            cols,
            header_end,
            ..
        } = self.layout;
        let take = max_rows.min(rows - self.row);
        columns.iter_mut().for_each(Vec::clear);
        if take == 0 {
            return Ok(0);
        }
        let size = dtype.size;
        if fortran {
            self.bytes.resize(take * size, 0);
            for (col, column) in columns.iter_mut().enumerate().take(cols) {
                let at = (col * rows + self.row) * size;
                self.reader
                    .seek(std::io::SeekFrom::Start((header_end + at) as u64))?;
                self.layout
                    .read_exact(&mut self.reader, &mut self.bytes, at)?;
                for (row, b) in (self.row..).zip(self.bytes.chunks_exact(size)) {
                    column.push(self.layout.value(b, row, col)?);
                }
            }
        } else {
            self.bytes.resize(take * cols * size, 0);
            let at = self.row * cols * size;
            self.layout
                .read_exact(&mut self.reader, &mut self.bytes, at)?;
            for (i, b) in self.bytes.chunks_exact(size).enumerate() {
                let (row, col) = (self.row + i / cols, i % cols);
                columns[col].push(self.layout.value(b, row, col)?);
            }
        }
        self.row += take;
        Ok(take)
    }
}

/// Write a 1-D float64 array as `.npy` (format 1.0): the bench hands data to numpy this way.
pub fn write_f64(path: &Path, values: &[f64]) -> std::io::Result<()> {
    use std::io::Write;
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({},), }}",
        values.len()
    );
    // The data must start on a 64-byte boundary; the header ends with a newline.
    while !(MAGIC.len() + 4 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    out.write_all(MAGIC)?;
    out.write_all(&[1, 0])?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    for v in values {
        out.write_all(&v.to_le_bytes())?;
    }
    out.flush()
}

/// The header dictionary text and the number of bytes before the data.
fn read_header(reader: &mut impl Read) -> Result<(String, usize), ReadError> {
    let mut start = [0u8; 12];
    let got = read_up_to(reader, &mut start[..10])?;
    if got < 10 || !start.starts_with(MAGIC) {
        return Err(NpyError::BadMagic.into());
    }
    let (len, begin): (usize, usize) = match start[6] {
        1 => (u16::from_le_bytes([start[8], start[9]]) as usize, 10),
        v @ (2 | 3) => {
            if read_up_to(reader, &mut start[10..12])? < 2 {
                return Err(NpyError::Version(v).into());
            }
            (
                u32::from_le_bytes([start[8], start[9], start[10], start[11]]) as usize,
                12,
            )
        }
        v => return Err(NpyError::Version(v).into()),
    };
    let mut header = Vec::new();
    let got = reader.by_ref().take(len as u64).read_to_end(&mut header)?;
    if got < len {
        return Err(NpyError::HeaderTruncated.into());
    }
    let header = String::from_utf8(header).map_err(|_| NpyError::HeaderNotText)?;
    Ok((header, begin + len))
}

/// Fill as much of `buf` as the reader holds; the count filled.
fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(k) => filled += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// The text of `key`'s value in the header's Python dict literal.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = header[at + key.len() + 2..]
        .trim_start()
        .strip_prefix(':')?;
    let rest = rest.trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else {
        rest.find([',', '}']).unwrap_or(rest.len())
    };
    Some(rest[..end].trim())
}

fn parse_shape(text: &str) -> Result<Vec<usize>, NpyError> {
    text.trim_matches(['(', ')'])
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| NpyError::BadShape(text.to_string())))
        .collect()
}

/// The element types we read, all converted to f64 (exact for every integer up to 2^53).
struct Dtype {
    name: String,
    size: usize,
    big_endian: bool,
    kind: char,
}

impl Dtype {
    fn parse(descr: &str) -> Result<Dtype, NpyError> {
        let unsupported = || NpyError::Dtype(descr.to_string());
        let mut chars = descr.chars();
        let order = chars.next().ok_or_else(unsupported)?;
        let kind = chars.next().ok_or_else(unsupported)?;
        let size: usize = chars.as_str().parse().map_err(|_| unsupported())?;
        let ok = match kind {
            'f' => matches!(size, 4 | 8),
            'i' | 'u' => matches!(size, 1 | 2 | 4 | 8),
            _ => false,
        };
        if !ok || !matches!(order, '<' | '>' | '|' | '=') {
            return Err(unsupported());
        }
        Ok(Dtype {
            name: descr.to_string(),
            size,
            big_endian: order == '>',
            kind,
        })
    }

    /// Every element of `bytes` (whole elements of this type), appended to `out`; the
    /// common little-endian float64 without a per-element dispatch.
    fn decode(&self, bytes: &[u8], out: &mut Vec<f64>) {
        if self.kind == 'f' && self.size == 8 && !self.big_endian {
            out.extend(bytes.chunks_exact(8).map(|b| {
                let mut buf = [0u8; 8];
                buf.copy_from_slice(b);
                f64::from_le_bytes(buf)
            }));
        } else {
            out.extend(bytes.chunks_exact(self.size).map(|b| self.read(b)));
        }
    }

    fn read(&self, b: &[u8]) -> f64 {
        let mut buf = [0u8; 8];
        buf[..self.size].copy_from_slice(b);
        if self.big_endian {
            buf[..self.size].reverse();
        }
        match (self.kind, self.size) {
            ('f', 8) => f64::from_le_bytes(buf),
            ('f', _) => f64::from(f32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]])),
            ('u', _) => u64::from_le_bytes(buf) as f64,
            // Sign-extend a narrower integer from its top bit.
            (_, n) => {
                let shift = 64 - 8 * n as u32;
                ((i64::from_le_bytes(buf) << shift) >> shift) as f64
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy(descr: &str, fortran: bool, shape: &str, data: &[u8]) -> Vec<u8> {
        let mut header = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
            if fortran { "True" } else { "False" }
        );
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(data);
        out
    }

    fn parse_bytes(b: &[u8]) -> Result<Table, InputError> {
        parse(Path::new("a.npy"), b)
    }

    #[test]
    fn two_d_c_and_fortran_order() {
        let data: Vec<u8> = [1.0f64, 2.0, 3.0, 4.0, 5.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let c = parse_bytes(&npy("<f8", false, "(3, 2)", &data)).unwrap();
        assert_eq!(c.channels[0].1, [1.0, 3.0, 5.0]);
        assert_eq!(c.channels[1].0, "c1");
        let f = parse_bytes(&npy("<f8", true, "(3, 2)", &data)).unwrap();
        assert_eq!(f.channels[0].1, [1.0, 2.0, 3.0]);
        assert_eq!(f.channels[1].1, [4.0, 5.0, 6.0]);
    }

    /// A value that is not finite is named by its row and column, across the reader's chunks
    /// and in both orders.
    #[test]
    fn a_value_not_finite_is_named_where_it_is() {
        let (rows, cols) = (5000, 3);
        for (fortran, at) in [
            (false, (1, 1)),
            (false, (4000, 2)),
            (true, (2, 0)),
            (true, (4321, 2)),
        ] {
            let mut values = vec![1.0f64; rows * cols];
            let index = if fortran {
                at.1 * rows + at.0
            } else {
                at.0 * cols + at.1
            };
            values[index] = f64::NAN;
            let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
            let shape = format!("({rows}, {cols})");
            let error = parse_bytes(&npy("<f8", fortran, &shape, &data)).unwrap_err();
            let text = error.to_string();
            assert!(
                text.contains(&format!("element [{}, {}] is NaN", at.0, at.1)),
                "fortran {fortran}: {text}"
            );
        }
    }

    #[test]
    fn written_arrays_read_back() {
        let scratch = tempfile::tempdir().unwrap();
        let path = scratch.path().join("a.npy");
        write_f64(&path, &[1.5, -2.0, 1e-300]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!((bytes.len() - 3 * 8) % 64, 0);
        let t = parse_bytes(&bytes).unwrap();
        assert_eq!(t.channels[0].1, [1.5, -2.0, 1e-300]);
    }

    #[test]
    fn integer_and_float_types() {
        let i16s: Vec<u8> = [-2i16, 300].iter().flat_map(|v| v.to_le_bytes()).collect();
        let t = parse_bytes(&npy("<i2", false, "(2,)", &i16s)).unwrap();
        assert_eq!(t.channels[0].1, [-2.0, 300.0]);
        let be: Vec<u8> = [-7i32, 9].iter().flat_map(|v| v.to_be_bytes()).collect();
        let t = parse_bytes(&npy(">i4", false, "(2,)", &be)).unwrap();
        assert_eq!(t.channels[0].1, [-7.0, 9.0]);
        let f32s: Vec<u8> = [0.5f32, -1.25]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let t = parse_bytes(&npy("<f4", false, "(2,)", &f32s)).unwrap();
        assert_eq!(t.channels[0].1, [0.5, -1.25]);
        let t = parse_bytes(&npy("|u1", false, "(2,)", &[255, 1])).unwrap();
        assert_eq!(t.channels[0].1, [255.0, 1.0]);
    }

    #[test]
    fn bad_files_say_why() {
        let nan: Vec<u8> = [1.0f64, f64::NAN]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let e = parse_bytes(&npy("<f8", false, "(1, 2)", &nan)).unwrap_err();
        assert!(e.to_string().contains("element [0, 1] is NaN"), "{e}");
        let e = parse_bytes(&npy("<c16", false, "(1,)", &[0; 16])).unwrap_err();
        assert!(
            e.to_string().contains("dtype '<c16' is not supported"),
            "{e}"
        );
        let e = parse_bytes(&npy("<f8", false, "(4,)", &[0; 8])).unwrap_err();
        assert!(e.to_string().contains("truncated"), "{e}");
        let e = parse_bytes(b"hello").unwrap_err();
        assert!(e.to_string().contains("bad magic"), "{e}");
        let e = parse_bytes(&npy("<f8", false, "(1, 1, 1)", &[0; 8])).unwrap_err();
        assert!(e.to_string().contains("only 1-D or 2-D"), "{e}");
    }

    /// Read `bytes` in blocks of `block` rows: the channels, or the first error.
    fn chunked(bytes: &[u8], block: usize) -> Result<Vec<Vec<f64>>, InputError> {
        let cursor = std::io::Cursor::new(bytes);
        let mut chunks = NpyChunks::new(Path::new("a.npy"), cursor, bytes.len() as u64)?;
        let mut out = vec![Vec::new(); chunks.cols()];
        let mut block_columns = vec![Vec::new(); chunks.cols()];
        while chunks.next_rows(block, &mut block_columns)? > 0 {
            for (o, b) in out.iter_mut().zip(&block_columns) {
                o.extend_from_slice(b);
            }
        }
        assert_eq!(out[0].len(), chunks.rows());
        Ok(out)
    }

    /// Blocks of any size give the channels (and the errors) reading the whole array gives,
    /// for 1-D and 2-D arrays in C and Fortran order.
    #[test]
    fn chunks_read_what_the_whole_read_reads() {
        let values: Vec<f64> = (0..105).map(|i| (i as f64 * 0.37).sin()).collect();
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let ints: Vec<u8> = (0..105i16).flat_map(|v| (v - 50).to_be_bytes()).collect();
        let files = [
            npy("<f8", false, "(105,)", &data),
            npy("<f8", false, "(35, 3)", &data),
            npy("<f8", true, "(35, 3)", &data),
            npy("<f8", false, "(21, 5)", &data),
            npy(">i2", false, "(15, 7)", &ints),
        ];
        for file in &files {
            let whole: Vec<Vec<f64>> = parse_bytes(file)
                .unwrap()
                .channels
                .into_iter()
                .map(|(_, v)| v)
                .collect();
            for block in [1, 2, 7, 1000] {
                assert_eq!(chunked(file, block).unwrap(), whole, "block {block}");
            }
        }
        // A NaN at [4, 1], and a file cut short: the same messages as the whole read's.
        let mut bad = values.clone();
        bad[4 * 3 + 1] = f64::NAN;
        let bad: Vec<u8> = bad.iter().flat_map(|v| v.to_le_bytes()).collect();
        let short = &data[..data.len() - 8];
        for file in [
            npy("<f8", false, "(35, 3)", &bad),
            npy("<f8", false, "(35, 3)", short),
        ] {
            let whole = parse_bytes(&file).err().map(|e| e.to_string());
            assert!(whole.is_some());
            assert_eq!(chunked(&file, 3).err().map(|e| e.to_string()), whole);
        }
        assert_eq!(
            chunked(&npy("<f8", false, "(35, 3)", &bad), 3)
                .unwrap_err()
                .to_string(),
            "a.npy: element [4, 1] is NaN: the data must be finite"
        );
    }
}

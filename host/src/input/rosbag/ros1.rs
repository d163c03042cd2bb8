//! ROS 1 bags, format 2.0 (wiki.ros.org/Bags/Format/2.0): after the line `#ROSBAG V2.0`, a
//! sequence of records, each a header (little-endian u32 length, then fields `len name=value`)
//! and data (u32 length, bytes). The header's `op` field gives the kind: 0x02 message data,
//! 0x03 bag header, 0x04 index data, 0x05 chunk, 0x06 chunk info, 0x07 connection.
//!
//! The file is read front to back, record by record, never through its index: a bag whose
//! recording was cut short has no index (`index_pos` 0) but whole chunks, and those still
//! read. A chunk's data is more records (connections and messages), stored uncompressed,
//! bz2 or lz4 (the LZ4 frame format, which roslz4 writes).

use super::{Encoding, Sink};
use crate::input::InputError;
use std::io::{BufReader, Read};
use std::path::Path;

const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

const OP_MESSAGE: u8 = 0x02;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// One record: its header fields and its data.
struct Record {
    fields: Vec<(String, Vec<u8>)>,
    data: Vec<u8>,
}

impl Record {
    fn field(&self, name: &str) -> Result<&[u8], String> {
        self.fields
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
            .ok_or_else(|| format!("header has no '{name}' field"))
    }

    fn op(&self) -> Result<u8, String> {
        match self.field("op")? {
            [op] => Ok(*op),
            other => Err(format!("'op' field of {} bytes, not 1", other.len())),
        }
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        let v = self.field(name)?;
        <[u8; 4]>::try_from(v)
            .map(u32::from_le_bytes)
            .map_err(|_| format!("'{name}' field of {} bytes, not 4", v.len()))
    }

    fn text(&self, name: &str) -> Result<String, String> {
        Ok(String::from_utf8_lossy(self.field(name)?).into_owned())
    }

    /// A `time` field (u32 seconds, u32 nanoseconds) in ns.
    fn time_ns(&self, name: &str) -> Result<i64, String> {
        let v = self.field(name)?;
        let b = <[u8; 8]>::try_from(v)
            .map_err(|_| format!("'{name}' field of {} bytes, not 8", v.len()))?;
        let [s0, s1, s2, s3, n0, n1, n2, n3] = b;
        let secs = u32::from_le_bytes([s0, s1, s2, s3]);
        let nsecs = u32::from_le_bytes([n0, n1, n2, n3]);
        Ok(i64::from(secs) * 1_000_000_000 + i64::from(nsecs))
    }
}

/// The next record in `source`, `None` at a clean end; `left` is how many
/// bytes remain, so a corrupt length is caught before it is allocated.
fn next_record(source: &mut impl Read, left: &mut u64) -> Result<Option<Record>, String> {
    if *left == 0 {
        return Ok(None);
    }
    let header = block(source, left, "record header")?;
    let data = block(source, left, "record data")?;
    let fields = parse_fields(&header)?;
    Ok(Some(Record { fields, data }))
}

/// Header fields: each a u32 length, then `name=value`.
fn parse_fields(header: &[u8]) -> Result<Vec<(String, Vec<u8>)>, String> {
    let mut fields = Vec::new();
    let mut rest = header;
    while !rest.is_empty() {
        let (len, tail) = rest
            .split_first_chunk::<4>()
            .ok_or("header field length cut short")?;
        let len = u32::from_le_bytes(*len) as usize;
        let field = tail
            .get(..len)
            .ok_or_else(|| format!("header field of {len} bytes overruns its header"))?;
        let eq = field
            .iter()
            .position(|&b| b == b'=')
            .ok_or("header field without '='")?;
        fields.push((
            String::from_utf8_lossy(&field[..eq]).into_owned(),
            field[eq + 1..].to_vec(),
        ));
        rest = &tail[len..];
    }
    Ok(fields)
}

/// A u32 length and that many bytes.
fn block(source: &mut impl Read, left: &mut u64, what: &str) -> Result<Vec<u8>, String> {
    let mut len = [0u8; 4];
    if *left < 4 {
        return Err(format!("{what}: the file ends inside its length"));
    }
    source
        .read_exact(&mut len)
        .map_err(|e| format!("{what}: {e}"))?;
    *left -= 4;
    let len = u64::from(u32::from_le_bytes(len));
    if len > *left {
        return Err(format!(
            "{what} of {len} bytes, but only {} remain (a truncated bag?)",
            *left
        ));
    }
    let mut bytes = vec![0; len as usize];
    source
        .read_exact(&mut bytes)
        .map_err(|e| format!("{what}: {e}"))?;
    *left -= len;
    Ok(bytes)
}

/// Every connection and message of the bag at `path` into `sink`.
pub(super) fn read(path: &Path, sink: &mut Sink) -> Result<(), InputError> {
    let io = |source| InputError::Io {
        path: path.to_owned(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut left = file.metadata().map_err(io)?.len();
    let mut source = BufReader::with_capacity(1 << 20, file);
    let mut magic = [0u8; MAGIC.len()];
    if left < MAGIC.len() as u64 || source.read_exact(&mut magic).is_err() || magic != MAGIC {
        return Err(InputError::file(
            path,
            "not a ROS 1 bag: it does not start with '#ROSBAG V2.0'",
        ));
    }
    left -= MAGIC.len() as u64;
    let size = left;
    loop {
        let offset = MAGIC.len() as u64 + size - left;
        let at =
            |e: String| InputError::file(path, format!("ROS 1 bag, record at byte {offset}: {e}"));
        let Some(record) = next_record(&mut source, &mut left).map_err(at)? else {
            return Ok(());
        };
        match record.op().map_err(at)? {
            OP_CHUNK => chunk(&record, sink).map_err(at)?,
            OP_CONNECTION => connection(&record, sink).map_err(at)?,
            OP_MESSAGE => message(&record, sink).map_err(at)?,
            _ => {}
        }
    }
}

/// A chunk's connections and messages.
fn chunk(record: &Record, sink: &mut Sink) -> Result<(), String> {
    let size = record.u32("size")? as usize;
    let compression = record.text("compression")?;
    let data = match compression.as_str() {
        "none" => record.data.clone(),
        "bz2" => inflate(bzip2::read::BzDecoder::new(&record.data[..]), size, "bz2")?,
        "lz4" => {
            let decoder = lz4::Decoder::new(&record.data[..]).map_err(|e| format!("lz4: {e}"))?;
            inflate(decoder, size, "lz4")?
        }
        other => {
            return Err(format!(
                "chunk compression '{other}' is not read (none, bz2 and lz4 are)"
            ));
        }
    };
    if data.len() != size {
        return Err(format!(
            "chunk of {} bytes, but its header says {size}",
            data.len()
        ));
    }
    let mut inner = data.as_slice();
    let mut left = data.len() as u64;
    while let Some(r) = next_record(&mut inner, &mut left).map_err(|e| format!("in chunk: {e}"))? {
        match r.op()? {
            OP_CONNECTION => connection(&r, sink)?,
            OP_MESSAGE => message(&r, sink)?,
            _ => {}
        }
    }
    Ok(())
}

/// A decompressed chunk, at most `size` bytes (and one more, to tell a wrong size).
fn inflate(decoder: impl Read, size: usize, name: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(size);
    decoder
        .take(size as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("{name} chunk: {e}"))?;
    Ok(out)
}

/// A connection record: the header's `conn` and `topic`, the data's `type` (a connection
/// header, fields as in a record header).
fn connection(record: &Record, sink: &mut Sink) -> Result<(), String> {
    let id = record.u32("conn")?;
    let topic = record.text("topic")?;
    let fields = Record {
        fields: parse_fields(&record.data)?,
        data: Vec::new(),
    };
    let type_name = fields.text("type")?;
    sink.topic(u64::from(id), &topic, &type_name, Encoding::Ros1);
    Ok(())
}

fn message(record: &Record, sink: &mut Sink) -> Result<(), String> {
    let id = u64::from(record.u32("conn")?);
    let time = record.time_ns("time")?;
    sink.message(id, time, &record.data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corrupt_lengths_are_errors_not_allocations() {
        let mut bytes: &[u8] = &[0xff, 0xff, 0xff, 0x7f, 1, 2];
        let mut left = bytes.len() as u64;
        let err = next_record(&mut bytes, &mut left).err().unwrap();
        assert!(err.contains("only 2 remain"), "{err}");
        let mut bytes: &[u8] = &[4, 0, 0, 0, 9, 0, 0, 0, 0, 0, 0, 0];
        let mut left = bytes.len() as u64;
        let err = next_record(&mut bytes, &mut left).err().unwrap();
        assert!(err.contains("overruns"), "{err}");
    }
}

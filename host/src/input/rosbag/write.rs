//! Bags of Imu messages written in each container this module reads: the tests' inputs and
//! the bench's 8-hour bag, made without ROS. [`BagWriter`] is the one interface:
//! topics first, then messages in the order they were received.

use super::imu::encode::{self, Imu};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::Path;

/// One Imu message to write.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Header stamp, ns since the epoch (0: unset).
    pub stamp_ns: i64,
    /// When the recorder received it, ns since the epoch.
    pub received_ns: i64,
    /// rad/s
    pub gyro: [f64; 3],
    /// m/s^2
    pub accel: [f64; 3],
}

impl ImuSample {
    fn imu(&self, seq: u32) -> Imu<'static> {
        Imu {
            seq,
            stamp_ns: self.stamp_ns,
            frame_id: "imu_link",
            gyro: self.gyro,
            accel: self.accel,
        }
    }
}

/// A bag being written.
pub trait BagWriter {
    /// A topic of Imu messages; its key for [`BagWriter::write`].
    fn topic(&mut self, name: &str) -> io::Result<u32>;
    fn write(&mut self, topic: u32, sample: &ImuSample) -> io::Result<()>;
    /// Completes the file (index, summary, metadata).
    fn finish(self: Box<Self>) -> io::Result<()>;
}

/// The containers, and a ROS 1 bag's chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Container {
    /// ROS 1 bag 2.0 with chunks stored as `none`, `bz2` or `lz4`.
    Ros1(Ros1Compression),
    /// MCAP, ROS 2 profile, zstd chunks (what `ros2 bag record` writes).
    Mcap,
    /// A rosbag2 directory: `metadata.yaml` and one `.db3`.
    Db3,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ros1Compression {
    None,
    Bz2,
    Lz4,
}

/// A writer for `container` at `path` (for [`Container::Db3`], a directory to create).
pub fn create(container: Container, path: &Path) -> io::Result<Box<dyn BagWriter>> {
    Ok(match container {
        Container::Ros1(c) => Box::new(Ros1Writer::create(path, c)?),
        Container::Mcap => Box::new(McapWriter::create(path)?),
        Container::Db3 => Box::new(Db3Writer::create(path)?),
    })
}

/// `topics` written to a new bag at `path`, all messages in order of receive time.
pub fn write(container: Container, path: &Path, topics: &[(&str, &[ImuSample])]) -> io::Result<()> {
    let mut writer = create(container, path)?;
    let mut all = Vec::new();
    for (name, samples) in topics {
        let key = writer.topic(name)?;
        all.extend(samples.iter().map(|s| (key, s)));
    }
    all.sort_by_key(|(_, s)| s.received_ns);
    for (key, sample) in all {
        writer.write(key, sample)?;
    }
    writer.finish()
}

/// The message definition's md5 sum that ROS 1 gives `sensor_msgs/Imu`.
const IMU_MD5: &str = "6a62c6daae103f4ff57a132d6f95cec2";

/// An abridged definition: the fields this module reads, for tools that show it.
const IMU_DEFINITION: &str = "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n\
float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n\
float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
float64[9] linear_acceleration_covariance\n";

/// Uncompressed bytes a ROS 1 chunk collects before it is written (rosbag's default).
const CHUNK_BYTES: usize = 768 * 1024;

/// The bag header record is padded to this many bytes, so that it can be rewritten in place.
const BAG_HEADER_BYTES: usize = 4096;

/// A written chunk, for its chunk info record in the index.
struct ChunkInfo {
    position: u64,
    start: i64,
    end: i64,
    /// (connection, messages) in the chunk.
    counts: Vec<(u32, u32)>,
}

struct Ros1Writer {
    file: BufWriter<File>,
    compression: Ros1Compression,
    topics: Vec<String>,
    chunk: Vec<u8>,
    /// Connections already written into the current chunk.
    in_chunk: Vec<bool>,
    /// Per connection, the current chunk's (time, offset) index entries.
    index: Vec<Vec<(i64, u32)>>,
    chunk_range: Option<(i64, i64)>,
    chunks: Vec<ChunkInfo>,
    seq: u32,
}

fn field(out: &mut Vec<u8>, name: &str, value: &[u8]) {
    out.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
    out.extend(name.as_bytes());
    out.push(b'=');
    out.extend(value);
}

fn record(out: &mut Vec<u8>, header: &[u8], data: &[u8]) {
    out.extend((header.len() as u32).to_le_bytes());
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
}

fn time(ns: i64) -> [u8; 8] {
    let secs = ns.div_euclid(1_000_000_000) as u32;
    let nsecs = ns.rem_euclid(1_000_000_000) as u32;
    let mut t = [0u8; 8];
    t[..4].copy_from_slice(&secs.to_le_bytes());
    t[4..].copy_from_slice(&nsecs.to_le_bytes());
    t
}

impl Ros1Writer {
    fn create(path: &Path, compression: Ros1Compression) -> io::Result<Ros1Writer> {
        let mut file = BufWriter::new(File::create_new(path)?);
        file.write_all(b"#ROSBAG V2.0\n")?;
        file.write_all(&Self::bag_header(0, 0, 0))?;
        Ok(Ros1Writer {
            file,
            compression,
            topics: Vec::new(),
            chunk: Vec::new(),
            in_chunk: Vec::new(),
            index: Vec::new(),
            chunk_range: None,
            chunks: Vec::new(),
            seq: 0,
        })
    }

    fn bag_header(index_pos: u64, conns: u32, chunks: u32) -> Vec<u8> {
        let mut header = Vec::new();
        field(&mut header, "op", &[0x03]);
        field(&mut header, "index_pos", &index_pos.to_le_bytes());
        field(&mut header, "conn_count", &conns.to_le_bytes());
        field(&mut header, "chunk_count", &chunks.to_le_bytes());
        let padding = vec![b' '; BAG_HEADER_BYTES - 8 - header.len()];
        let mut out = Vec::new();
        record(&mut out, &header, &padding);
        out
    }

    fn connection(&self, conn: u32) -> Vec<u8> {
        let topic = self.topics[conn as usize].as_bytes();
        let mut header = Vec::new();
        field(&mut header, "op", &[0x07]);
        field(&mut header, "conn", &conn.to_le_bytes());
        field(&mut header, "topic", topic);
        let mut data = Vec::new();
        field(&mut data, "topic", topic);
        field(&mut data, "type", b"sensor_msgs/Imu");
        field(&mut data, "md5sum", IMU_MD5.as_bytes());
        field(&mut data, "message_definition", IMU_DEFINITION.as_bytes());
        let mut out = Vec::new();
        record(&mut out, &header, &data);
        out
    }

    fn flush_chunk(&mut self) -> io::Result<()> {
        let Some((start, end)) = self.chunk_range.take() else {
            return Ok(());
        };
        let data = std::mem::take(&mut self.chunk);
        let (name, stored): (&[u8], Vec<u8>) = match self.compression {
            Ros1Compression::None => (b"none", data.clone()),
            Ros1Compression::Bz2 => {
                let mut z = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::best());
                z.write_all(&data)?;
                (b"bz2", z.finish()?)
            }
            Ros1Compression::Lz4 => {
                let mut z = lz4::EncoderBuilder::new().build(Vec::new())?;
                z.write_all(&data)?;
                let (bytes, result) = z.finish();
                result?;
                (b"lz4", bytes)
            }
        };
        let position = self.file.stream_position()?;
        let mut header = Vec::new();
        field(&mut header, "op", &[0x05]);
        field(&mut header, "compression", name);
        field(&mut header, "size", &(data.len() as u32).to_le_bytes());
        let mut out = Vec::new();
        record(&mut out, &header, &stored);
        let mut counts = Vec::new();
        for (conn, entries) in self.index.iter_mut().enumerate() {
            if entries.is_empty() {
                continue;
            }
            let mut header = Vec::new();
            field(&mut header, "op", &[0x04]);
            field(&mut header, "ver", &1u32.to_le_bytes());
            field(&mut header, "conn", &(conn as u32).to_le_bytes());
            field(&mut header, "count", &(entries.len() as u32).to_le_bytes());
            let mut data = Vec::new();
            for (t, offset) in entries.drain(..) {
                data.extend(time(t));
                data.extend(offset.to_le_bytes());
            }
            record(&mut out, &header, &data);
            counts.push((conn as u32, (data.len() / 12) as u32));
        }
        self.file.write_all(&out)?;
        self.chunks.push(ChunkInfo {
            position,
            start,
            end,
            counts,
        });
        self.in_chunk.iter_mut().for_each(|c| *c = false);
        Ok(())
    }
}

impl BagWriter for Ros1Writer {
    fn topic(&mut self, name: &str) -> io::Result<u32> {
        self.topics.push(name.to_owned());
        self.in_chunk.push(false);
        self.index.push(Vec::new());
        Ok(self.topics.len() as u32 - 1)
    }

    fn write(&mut self, conn: u32, sample: &ImuSample) -> io::Result<()> {
        let c = conn as usize;
        if c >= self.topics.len() {
            return Err(io::Error::other(format!("no topic {conn}")));
        }
        if !self.in_chunk[c] {
            let connection = self.connection(conn);
            self.chunk.extend(connection);
            self.in_chunk[c] = true;
        }
        let t = sample.received_ns;
        self.index[c].push((t, self.chunk.len() as u32));
        let mut header = Vec::new();
        field(&mut header, "op", &[0x02]);
        field(&mut header, "conn", &conn.to_le_bytes());
        field(&mut header, "time", &time(t));
        record(
            &mut self.chunk,
            &header,
            &encode::ros1(&sample.imu(self.seq)),
        );
        self.seq = self.seq.wrapping_add(1);
        self.chunk_range = Some(
            self.chunk_range
                .map_or((t, t), |(a, b)| (a.min(t), b.max(t))),
        );
        if self.chunk.len() >= CHUNK_BYTES {
            self.flush_chunk()?;
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> io::Result<()> {
        self.flush_chunk()?;
        let index_pos = self.file.stream_position()?;
        let mut out = Vec::new();
        for conn in 0..self.topics.len() as u32 {
            out.extend(self.connection(conn));
        }
        for ChunkInfo {
            position,
            start,
            end,
            counts,
        } in &self.chunks
        {
            let mut header = Vec::new();
            field(&mut header, "op", &[0x06]);
            field(&mut header, "ver", &1u32.to_le_bytes());
            field(&mut header, "chunk_pos", &position.to_le_bytes());
            field(&mut header, "start_time", &time(*start));
            field(&mut header, "end_time", &time(*end));
            field(&mut header, "count", &(counts.len() as u32).to_le_bytes());
            let data: Vec<u8> = counts
                .iter()
                .flat_map(|(c, n)| c.to_le_bytes().into_iter().chain(n.to_le_bytes()))
                .collect();
            record(&mut out, &header, &data);
        }
        self.file.write_all(&out)?;
        self.file.seek(SeekFrom::Start(13))?;
        let header = Self::bag_header(
            index_pos,
            self.topics.len() as u32,
            self.chunks.len() as u32,
        );
        self.file.write_all(&header)?;
        self.file.flush()
    }
}

struct McapWriter {
    writer: mcap::Writer<BufWriter<File>>,
    sequence: u32,
}

fn mcap_error(e: mcap::McapError) -> io::Error {
    io::Error::other(e.to_string())
}

impl McapWriter {
    fn create(path: &Path) -> io::Result<McapWriter> {
        let file = BufWriter::new(File::create_new(path)?);
        let writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("ros2")
            .create(file)
            .map_err(mcap_error)?;
        Ok(McapWriter {
            writer,
            sequence: 0,
        })
    }
}

impl BagWriter for McapWriter {
    fn topic(&mut self, name: &str) -> io::Result<u32> {
        let schema = self
            .writer
            .add_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_DEFINITION.as_bytes())
            .map_err(mcap_error)?;
        let channel = self
            .writer
            .add_channel(schema, name, "cdr", &BTreeMap::new())
            .map_err(mcap_error)?;
        Ok(u32::from(channel))
    }

    fn write(&mut self, topic: u32, sample: &ImuSample) -> io::Result<()> {
        let channel_id = u16::try_from(topic).map_err(io::Error::other)?;
        let time = u64::try_from(sample.received_ns).map_err(io::Error::other)?;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: time,
            publish_time: time,
        };
        let data = encode::cdr(&sample.imu(0), true);
        self.sequence = self.sequence.wrapping_add(1);
        self.writer
            .write_to_known_channel(&header, &data)
            .map_err(mcap_error)
    }

    fn finish(mut self: Box<Self>) -> io::Result<()> {
        self.writer.finish().map_err(mcap_error)?;
        Ok(())
    }
}

struct Db3Writer {
    dir: std::path::PathBuf,
    conn: rusqlite::Connection,
    topics: Vec<(String, u64)>,
    range: Option<(i64, i64)>,
}

fn sql_error(e: rusqlite::Error) -> io::Error {
    io::Error::other(e.to_string())
}

/// The db3 file's name inside its directory.
const DB3_NAME: &str = "imu_0.db3";

impl Db3Writer {
    fn create(dir: &Path) -> io::Result<Db3Writer> {
        std::fs::create_dir(dir)?;
        let conn = rusqlite::Connection::open(dir.join(DB3_NAME)).map_err(sql_error)?;
        // The schema of rosbag2's sqlite3 storage plugin (sqlite_storage.cpp).
        conn.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);
             CREATE INDEX timestamp_idx ON messages (timestamp ASC);
             BEGIN;",
        )
        .map_err(sql_error)?;
        Ok(Db3Writer {
            dir: dir.to_owned(),
            conn,
            topics: Vec::new(),
            range: None,
        })
    }
}

impl BagWriter for Db3Writer {
    fn topic(&mut self, name: &str) -> io::Result<u32> {
        let id = self.topics.len() as u32 + 1;
        self.conn
            .execute(
                "INSERT INTO topics VALUES (?1, ?2, 'sensor_msgs/msg/Imu', 'cdr', '')",
                rusqlite::params![id, name],
            )
            .map_err(sql_error)?;
        self.topics.push((name.to_owned(), 0));
        Ok(id)
    }

    fn write(&mut self, topic: u32, sample: &ImuSample) -> io::Result<()> {
        let t = sample.received_ns;
        self.conn
            .prepare_cached("INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)")
            .and_then(|mut s| {
                s.execute(rusqlite::params![
                    topic,
                    t,
                    encode::cdr(&sample.imu(0), true)
                ])
            })
            .map_err(sql_error)?;
        if let Some(entry) = (topic as usize)
            .checked_sub(1)
            .and_then(|i| self.topics.get_mut(i))
        {
            entry.1 += 1;
        }
        self.range = Some(self.range.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
        Ok(())
    }

    fn finish(self: Box<Self>) -> io::Result<()> {
        self.conn.execute_batch("COMMIT;").map_err(sql_error)?;
        let (start, end) = self.range.unwrap_or((0, 0));
        let total: u64 = self.topics.iter().map(|t| t.1).sum();
        let mut yaml = format!(
            "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  \
             duration:\n    nanoseconds: {}\n  starting_time:\n    nanoseconds_since_epoch: {start}\n  \
             message_count: {total}\n  topics_with_message_count:\n",
            end - start
        );
        for (name, count) in &self.topics {
            yaml.push_str(&format!(
                "    - topic_metadata:\n        name: {name}\n        type: sensor_msgs/msg/Imu\n        \
                 serialization_format: cdr\n        offered_qos_profiles: \"\"\n      message_count: {count}\n"
            ));
        }
        yaml.push_str(&format!(
            "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - {DB3_NAME}\n"
        ));
        std::fs::write(self.dir.join("metadata.yaml"), yaml)
    }
}

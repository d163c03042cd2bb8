//! ROS bags: the `sensor_msgs/Imu` messages of one topic as a record. Three containers are
//! read, each recognised by its magic bytes:
//!
//! - ROS 1 bags, format 2.0 (`ros1.rs`: uncompressed, bz2 and lz4 chunks);
//! - MCAP files (`mcap.rs`, the rosbag2 default since Iron: zstd, lz4 or
//!   uncompressed chunks; ROS 2 CDR or ROS 1 messages);
//! - rosbag2 SQLite3 files, `.db3` (`db3.rs`).
//!
//! A rosbag2 directory (its `metadata.yaml` beside the storage file) is read through its one
//! storage file ([`storage_file`]). The angular velocity becomes `gx gy gz` (rad/s) and the
//! linear acceleration `ax ay az` (m/s^2), SI as ROS states them (REP 103). The header stamps
//! give the time base, or the bag's receive times when a publisher left them unset, and go
//! through the same judgement as a text table's time column ([`super::timing`]): rate by
//! least squares, jitter reported, missing messages refused by message number.

mod cdr;
mod db3;
mod imu;
mod mcap;
mod ros1;

use super::timing::{self, TimingError};
use super::{InputError, Table};
use imu::ImuMessage;
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The containers, by the bytes they start with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Format {
    Ros1,
    Mcap,
    Db3,
}

impl Format {
    /// The container `magic` (a file's first bytes) announces, if a bag.
    pub(super) fn of(magic: &[u8]) -> Option<Format> {
        // ROS 1: wiki.ros.org/Bags/Format/2.0; MCAP: mcap.dev/spec, "Magic"; SQLite: the
        // database file format, 1.3 "The Database Header".
        [
            (&b"#ROSBAG V2.0\n"[..], Format::Ros1),
            (&b"\x89MCAP0\r\n"[..], Format::Mcap),
            (&b"SQLite format 3\0"[..], Format::Db3),
        ]
        .into_iter()
        .find(|(m, _)| magic.starts_with(m))
        .map(|(_, f)| f)
    }

    fn describe(self) -> &'static str {
        match self {
            Format::Ros1 => "ROS 1 bag",
            Format::Mcap => "MCAP",
            Format::Db3 => "rosbag2 SQLite3",
        }
    }
}

/// The longest magic [`Format::of`] compares.
pub(super) const MAGIC_LEN: usize = 16;

/// The storage file of a rosbag2 directory (its one `.mcap` or `.db3`); any other path as it
/// is.
pub fn storage_file(path: &Path) -> Result<PathBuf, InputError> {
    if !path.is_dir() {
        return Ok(path.to_owned());
    }
    let entries = std::fs::read_dir(path).map_err(|source| InputError::Io {
        path: path.to_owned(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("db3"))
        })
        .collect();
    files.sort();
    match files.len() {
        1 => Ok(files.remove(0)),
        0 => Err(InputError::file(
            path,
            "a directory, but no rosbag2 storage file (.mcap or .db3) in it",
        )),
        n => Err(InputError::file(
            path,
            format!(
                "a rosbag2 directory split into {n} storage files ({}): give one of them, or \
                 merge them first (ros2 bag convert)",
                files
                    .iter()
                    .filter_map(|f| f.file_name())
                    .map(|f| f.to_string_lossy())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// How a topic's messages are serialised.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Encoding {
    Ros1,
    Cdr,
    /// Another encoding, by its name in the bag.
    Other(String),
}

/// One topic of a bag, as the readers report it.
#[derive(Debug)]
struct Topic {
    name: String,
    type_name: String,
    encoding: Encoding,
    messages: u64,
    /// Whether its messages are decoded (an Imu topic that may be the one read).
    decoded: bool,
    samples: Vec<ImuMessage>,
    /// Receive (log) times, ns, one per sample.
    received_ns: Vec<i64>,
}

impl Topic {
    fn is_imu(&self) -> bool {
        imu::TYPE_NAMES.contains(&self.type_name.as_str())
    }
}

/// Where the readers put what they find: topics by the container's own key (a ROS 1
/// connection, an MCAP channel, a db3 topic id), and the decoded messages of the topics that
/// may be read.
struct Sink {
    wanted: Option<String>,
    topics: Vec<Topic>,
    by_key: HashMap<u64, usize>,
}

impl Sink {
    fn new(wanted: Option<&str>) -> Sink {
        Sink {
            wanted: wanted.map(str::to_owned),
            topics: Vec::new(),
            by_key: HashMap::new(),
        }
    }

    /// A topic under `key`; a key seen before (a repeated connection record) changes nothing.
    fn topic(&mut self, key: u64, name: &str, type_name: &str, encoding: Encoding) {
        if self.by_key.contains_key(&key) {
            return;
        }
        // Several ROS 1 connections (publishers) may share one topic.
        let at = match self.topics.iter().position(|t| t.name == name) {
            Some(at) => at,
            None => {
                let mut topic = Topic {
                    name: name.to_owned(),
                    type_name: type_name.to_owned(),
                    encoding,
                    messages: 0,
                    decoded: false,
                    samples: Vec::new(),
                    received_ns: Vec::new(),
                };
                topic.decoded = topic.is_imu()
                    && self.wanted.as_deref().is_none_or(|w| w == topic.name)
                    && !matches!(topic.encoding, Encoding::Other(_));
                self.topics.push(topic);
                self.topics.len() - 1
            }
        };
        self.by_key.insert(key, at);
    }

    /// Whether messages under `key` are decoded (false for unknown keys).
    fn decodes(&self, key: u64) -> bool {
        self.by_key
            .get(&key)
            .is_some_and(|&at| self.topics[at].decoded)
    }

    /// `count` messages under `key` that are not decoded.
    fn count(&mut self, key: u64, count: u64) {
        if let Some(&at) = self.by_key.get(&key) {
            self.topics[at].messages += count;
        }
    }

    /// One message under `key`, received at `received_ns`.
    fn message(&mut self, key: u64, received_ns: i64, data: &[u8]) -> Result<(), String> {
        let Some(&at) = self.by_key.get(&key) else {
            return Err(format!(
                "a message on connection {key}, which no record declares"
            ));
        };
        let topic = &mut self.topics[at];
        topic.messages += 1;
        if !topic.decoded {
            return Ok(());
        }
        let decoded = match &topic.encoding {
            Encoding::Ros1 => imu::decode_ros1(data),
            Encoding::Cdr => imu::decode_cdr(data),
            Encoding::Other(name) => Err(format!("message encoding '{name}' is not read")),
        };
        let message =
            decoded.map_err(|e| format!("{} message {}: {e}", topic.name, topic.messages))?;
        topic.samples.push(message);
        topic.received_ns.push(received_ns);
        Ok(())
    }

    /// The topic to read: the one asked for, or the bag's only Imu topic.
    fn chosen(self, path: &Path) -> Result<Topic, InputError> {
        let listing = |topics: &[&Topic]| {
            topics
                .iter()
                .map(|t| format!("{} ({}, {} messages)", t.name, t.type_name, t.messages))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let all: Vec<&Topic> = self.topics.iter().collect();
        let imus: Vec<&Topic> = self.topics.iter().filter(|t| t.is_imu()).collect();
        let at = match &self.wanted {
            Some(want) => {
                let Some(at) = self.topics.iter().position(|t| &t.name == want) else {
                    return Err(InputError::file(
                        path,
                        format!(
                            "no topic '{want}'; the bag has {}",
                            none_if_empty(listing(&all))
                        ),
                    ));
                };
                if !self.topics[at].is_imu() {
                    return Err(InputError::file(
                        path,
                        format!(
                            "topic '{want}' is {}, not sensor_msgs/Imu; the IMU topics: {}",
                            self.topics[at].type_name,
                            none_if_empty(listing(&imus))
                        ),
                    ));
                }
                at
            }
            None => match self.topics.iter().position(|t| t.is_imu()) {
                Some(at) if imus.len() == 1 => at,
                None => {
                    return Err(InputError::file(
                        path,
                        format!(
                            "no sensor_msgs/Imu topic; the bag has {}",
                            none_if_empty(listing(&all))
                        ),
                    ));
                }
                Some(_) => {
                    return Err(InputError::file(
                        path,
                        format!(
                            "{} IMU topics: {}; choose one with --topic",
                            imus.len(),
                            listing(&imus)
                        ),
                    ));
                }
            },
        };
        let topic = self
            .topics
            .into_iter()
            .nth(at)
            .ok_or_else(|| InputError::file(path, "the chosen topic vanished while reading"))?;
        if let Encoding::Other(name) = &topic.encoding {
            return Err(InputError::file(
                path,
                format!(
                    "topic '{}' has message encoding '{name}': only CDR and ROS 1 are read",
                    topic.name
                ),
            ));
        }
        if topic.samples.is_empty() {
            return Err(InputError::file(
                path,
                format!("topic '{}' has no messages", topic.name),
            ));
        }
        Ok(topic)
    }
}

fn none_if_empty(s: String) -> String {
    if s.is_empty() { "none".into() } else { s }
}

/// Where a record read from a bag came from, for the output and the JSON document.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BagRead {
    /// `ROS 1 bag`, `MCAP` or `rosbag2 SQLite3`.
    pub format: &'static str,
    pub topic: String,
    /// The message type's name as the bag gives it.
    pub message_type: String,
    pub messages: u64,
    /// What gave the times: `header.stamp`, or `receive time` when stamps were unset.
    pub time_base: &'static str,
    /// Messages whose header stamp is unset (zero); any makes the receive times the time base.
    pub unset_stamps: usize,
}

impl std::fmt::Display for BagRead {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: topic {} ({}), {} messages, times from {}",
            self.format, self.topic, self.message_type, self.messages, self.time_base
        )?;
        if self.unset_stamps > 0 {
            write!(
                f,
                " (the header stamp is unset in {} of them)",
                self.unset_stamps
            )?;
        }
        Ok(())
    }
}

/// The Imu record on `topic` (or the bag's only Imu topic) of the bag at `path`, in the
/// container `format`; with `ignore_time` the stamps are set aside for a rate given by the
/// caller.
pub(super) fn table(
    path: &Path,
    format: Format,
    topic: Option<&str>,
    ignore_time: bool,
) -> Result<(Table, BagRead), InputError> {
    let mut sink = Sink::new(topic);
    match format {
        Format::Ros1 => ros1::read(path, &mut sink)?,
        Format::Mcap => mcap::read(path, &mut sink)?,
        Format::Db3 => db3::read(path, &mut sink)?,
    }
    let topic = sink.chosen(path)?;
    let unset_stamps = topic.samples.iter().filter(|s| s.stamp_ns == 0).count();
    let stamped = unset_stamps == 0;
    let time_base = if stamped {
        "header.stamp"
    } else {
        "receive time"
    };
    let column = format!("{} {time_base}", topic.name);
    let (mut timing, mut ignored_time) = (None, None);
    if ignore_time {
        ignored_time = Some(column);
    } else {
        let first = if stamped {
            topic.samples[0].stamp_ns
        } else {
            topic.received_ns[0]
        };
        // Seconds from the first message, so that f64 keeps nanoseconds.
        let times: Vec<f64> = topic
            .samples
            .iter()
            .zip(&topic.received_ns)
            .map(|(s, &r)| (if stamped { s.stamp_ns } else { r } - first) as f64 * 1e-9)
            .collect();
        timing = Some(time_base_of(path, &column, &times)?);
    }
    let read = BagRead {
        format: format.describe(),
        topic: topic.name.clone(),
        message_type: topic.type_name.clone(),
        messages: topic.messages,
        time_base,
        unset_stamps,
    };
    let channels = channels(path, &topic)?;
    Ok((
        Table {
            channels,
            rate_hz: None,
            timing,
            ignored_time,
            set_aside: Vec::new(),
        },
        read,
    ))
}

/// The fitted time base, or the timing error told by message number.
fn time_base_of(path: &Path, column: &str, times: &[f64]) -> Result<timing::Timing, InputError> {
    let message = |row: usize| format!("message {}", row + 1);
    match timing::analyse(column, times) {
        Ok(mut t) => {
            t.worst_step.line = t.worst_step.row + 1;
            Ok(t)
        }
        Err(e @ TimingError::Backwards { row, .. }) => Err(InputError::file(
            path,
            format!("{}: {}", message(row), e.explain(column, &message)),
        )),
        Err(e) => Err(InputError::file(path, e.explain(column, &message))),
    }
}

/// `gx gy gz ax ay az`, less a vector every message marks as not provided.
fn channels(path: &Path, topic: &Topic) -> Result<Vec<(String, Vec<f64>)>, InputError> {
    let mut channels = Vec::new();
    let gyro = !topic.samples.iter().all(|s| s.gyro_absent);
    let accel = !topic.samples.iter().all(|s| s.accel_absent);
    for (present, prefix, pick) in [
        (
            gyro,
            'g',
            (|s: &ImuMessage| s.gyro) as fn(&ImuMessage) -> [f64; 3],
        ),
        (accel, 'a', |s: &ImuMessage| s.accel),
    ] {
        if !present {
            continue;
        }
        for (axis, name) in ['x', 'y', 'z'].into_iter().enumerate() {
            let values = topic.samples.iter().map(|s| pick(s)[axis]).collect();
            channels.push((format!("{prefix}{name}"), values));
        }
    }
    if channels.is_empty() {
        return Err(InputError::file(
            path,
            format!(
                "topic '{}': every message marks both angular_velocity and \
                 linear_acceleration as not provided (covariance -1)",
                topic.name
            ),
        ));
    }
    Ok(channels)
}

pub mod write;

#[cfg(test)]
mod tests;

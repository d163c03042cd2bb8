//! MCAP files (mcap.dev/spec), read front to back by foxglove's `mcap` crate in bounded
//! memory, chunks decompressed (zstd, lz4) as they come. A channel's `message_encoding` says
//! how its messages are serialised: `cdr` (ROS 2) or `ros1`; its schema's name is the message
//! type.

use super::{Encoding, Sink};
use crate::input::InputError;
use std::io::BufReader;
use std::path::Path;

/// Every channel and message of the MCAP file at `path` into `sink`.
pub(super) fn read(path: &Path, sink: &mut Sink) -> Result<(), InputError> {
    let file = std::fs::File::open(path).map_err(|source| InputError::Io {
        path: path.to_owned(),
        source,
    })?;
    let reader = ::mcap::io::MessageReader::new(BufReader::with_capacity(1 << 20, file));
    for (n, message) in reader.enumerate() {
        let message = message
            .map_err(|e| InputError::file(path, format!("MCAP, after {n} messages: {e}")))?;
        let channel = &message.channel;
        let key = u64::from(channel.id);
        let type_name = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        let encoding = match channel.message_encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => Encoding::Other(other.to_owned()),
        };
        sink.topic(key, &channel.topic, type_name, encoding);
        // log_time: when the recorder received the message, ns.
        let received = i64::try_from(message.log_time).unwrap_or(i64::MAX);
        sink.message(key, received, &message.data)
            .map_err(|e| InputError::file(path, format!("MCAP: {e}")))?;
    }
    Ok(())
}

//! rosbag2's SQLite3 storage (`.db3`, the default before Iron): table `topics (id, name,
//! type, serialization_format, offered_qos_profiles)` and table `messages (id, topic_id,
//! timestamp, data)`, timestamps in ns when the recorder received the message
//! (rosbag2_storage_default_plugins, sqlite_storage.cpp). The file is opened read-only and
//! immutable, so reading it never writes beside it (no journal, no lock file).

use super::{Encoding, Sink};
use crate::input::InputError;
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

/// Every topic of the db3 at `path` into `sink`, and the messages of the topics it decodes.
pub(super) fn read(path: &Path, sink: &mut Sink) -> Result<(), InputError> {
    let sql = |e: rusqlite::Error| InputError::file(path, format!("rosbag2 SQLite3: {e}"));
    let conn = Connection::open_with_flags(
        uri(path),
        OpenFlags::SQLITE_OPEN_READ_ONLY
            | OpenFlags::SQLITE_OPEN_URI
            | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(sql)?;
    let mut topics = conn
        .prepare("SELECT id, name, type, serialization_format FROM topics")
        .map_err(sql)?;
    let rows = topics
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, String>(2)?,
                r.get::<_, String>(3)?,
            ))
        })
        .map_err(sql)?;
    for row in rows {
        let (id, name, type_name, format) = row.map_err(sql)?;
        let encoding = match format.as_str() {
            "cdr" => Encoding::Cdr,
            other => Encoding::Other(other.to_owned()),
        };
        sink.topic(key(id), &name, &type_name, encoding);
    }
    let mut counts = conn
        .prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id")
        .map_err(sql)?;
    let rows = counts
        .query_map([], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, u64>(1)?)))
        .map_err(sql)?;
    let mut decoded = Vec::new();
    for row in rows {
        let (id, count) = row.map_err(sql)?;
        if sink.decodes(key(id)) {
            decoded.push(id);
        } else {
            sink.count(key(id), count);
        }
    }
    // In insertion order, which is the order the recorder received them.
    let mut messages = conn
        .prepare("SELECT timestamp, data FROM messages WHERE topic_id = ?1 ORDER BY id")
        .map_err(sql)?;
    for id in decoded {
        let mut rows = messages.query([id]).map_err(sql)?;
        while let Some(row) = rows.next().map_err(sql)? {
            let time: i64 = row.get(0).map_err(sql)?;
            let data = row.get_ref(1).map_err(sql)?.as_blob().map_err(|e| {
                InputError::file(path, format!("rosbag2 SQLite3: message data: {e}"))
            })?;
            sink.message(key(id), time, data)
                .map_err(|e| InputError::file(path, format!("rosbag2 SQLite3: {e}")))?;
        }
    }
    Ok(())
}

/// A topic id as the sink's key (ids are SQLite integers: any i64, kept distinct).
fn key(id: i64) -> u64 {
    id as u64
}

/// `path` as an SQLite URI that opens it immutable (sqlite.org/uri.html): `%`, `?` and `#`
/// percent-encoded.
fn uri(path: &Path) -> String {
    let mut out = String::from("file:");
    for c in path.to_string_lossy().chars() {
        match c {
            '%' => out.push_str("%25"),
            '?' => out.push_str("%3f"),
            '#' => out.push_str("%23"),
            c => out.push(c),
        }
    }
    out.push_str("?immutable=1");
    out
}

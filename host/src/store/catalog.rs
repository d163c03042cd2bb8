//! Catalog statements shared by the store and the session writer (each has its own
//! connection: a capture runs in one process while others list and show sessions).

use super::session::{Board, Counts, Kind, Session};
use super::{CAPTURE_EXT, SESSIONS, StoreError, clock, schema};
use crate::capture::StreamDecoder;
use rusqlite::{Connection, params};
use std::path::Path;
use std::time::Duration;

/// A recorder that has not updated its session for this long is taken for gone, even when
/// its process id cannot be checked (another host, or no /proc).
pub const HEARTBEAT_TIMEOUT_S: f64 = 10.0;

/// Open the catalog: WAL (readers never block the recorder, and a crash cannot corrupt it),
/// a busy timeout for concurrent writers, foreign keys (analyses go with their session).
pub fn connect(path: &Path) -> Result<Connection, StoreError> {
    let sql = |source| StoreError::Sql {
        path: path.to_owned(),
        source,
    };
    let mut conn = Connection::open(path).map_err(sql)?;
    conn.busy_timeout(Duration::from_secs(5)).map_err(sql)?;
    conn.pragma_update_and_check(None, "journal_mode", "WAL", |_| Ok(()))
        .map_err(sql)?;
    conn.pragma_update(None, "synchronous", "NORMAL")
        .map_err(sql)?;
    conn.pragma_update(None, "foreign_keys", "ON")
        .map_err(sql)?;
    schema::migrate(&mut conn).map_err(|source| StoreError::Schema {
        path: path.to_owned(),
        source,
    })?;
    Ok(conn)
}

/// Open an existing catalog for reading only (a store on read-only media, or one whose
/// files this user may not write): no schema change, no recovery, no journal setup.
pub fn connect_read_only(path: &Path) -> Result<Connection, StoreError> {
    use rusqlite::OpenFlags;
    let sql = |source| StoreError::Sql {
        path: path.to_owned(),
        source,
    };
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = Connection::open_with_flags(path, flags).map_err(sql)?;
    conn.busy_timeout(Duration::from_secs(5)).map_err(sql)?;
    let version: u32 = conn
        .pragma_query_value(None, "user_version", |r| r.get(0))
        .map_err(sql)?;
    if version != schema::VERSION {
        return Err(StoreError::Schema {
            path: path.to_owned(),
            source: schema::MigrateError::ReadOnly {
                found: version,
                known: schema::VERSION,
            },
        });
    }
    Ok(conn)
}

/// `sessions/<id>.<ext>`, relative to the store directory.
pub fn file_name(id: i64, ext: &str) -> String {
    format!("{SESSIONS}/{id}.{ext}")
}

pub fn name_taken(conn: &Connection, name: &str) -> rusqlite::Result<bool> {
    conn.query_row(
        "SELECT EXISTS (SELECT 1 FROM sessions WHERE name = ?1)",
        [name],
        |r| r.get(0),
    )
}

/// `base`, or `base-2`, `base-3`, ... if taken.
pub fn unique_name(conn: &Connection, base: &str) -> rusqlite::Result<String> {
    let mut name = base.to_string();
    let mut n = 2;
    while name_taken(conn, &name)? {
        name = format!("{base}-{n}");
        n += 1;
    }
    Ok(name)
}

/// Is the recorder of a `recording` session still at work? Its heartbeat must be fresh and,
/// where processes can be checked (Linux /proc), its process must exist.
pub fn recorder_alive(pid: Option<u32>, heartbeat: Option<f64>, now: f64) -> bool {
    let fresh = heartbeat.is_some_and(|h| now - h < HEARTBEAT_TIMEOUT_S);
    let proc = Path::new("/proc");
    let exists = match pid {
        Some(pid) if proc.join("self").exists() => proc.join(pid.to_string()).exists(),
        _ => true,
    };
    fresh && exists
}

pub fn set_board(conn: &Connection, id: i64, board: &Board) -> rusqlite::Result<usize> {
    conn.execute(
        "UPDATE sessions SET board_id = ?2, firmware_version = ?3, protocol_version = ?4, \
         rate_hz = ?5, gyro_bandwidth_hz = ?6, accel_bandwidth_hz = ?7, dlpf_cfg = ?8, \
         smplrt_div = ?9, gyro_range_dps = ?10, accel_range_g = ?11 WHERE id = ?1",
        params![
            id,
            board.board_id,
            board.firmware_version,
            board.protocol_version,
            board.rate_hz,
            board.gyro_bandwidth_hz,
            board.accel_bandwidth_hz,
            board.dlpf_cfg,
            board.smplrt_div,
            board.gyro_range_dps,
            board.accel_range_g,
        ],
    )
}

pub fn set_counts(conn: &Connection, id: i64, c: &Counts, now: f64) -> rusqlite::Result<usize> {
    let status = c
        .board_status
        .as_ref()
        .and_then(|s| serde_json::to_string(s).ok());
    conn.execute(
        "UPDATE sessions SET bytes = ?2, samples_received = ?3, samples_lost = ?4, gaps = ?5, \
         restarts = ?6, out_of_order_batches = ?7, frames_ok = ?8, frames_rejected = ?9, \
         bytes_discarded = ?10, board_status = ?11, heartbeat_unix = ?12 WHERE id = ?1",
        params![
            id,
            c.bytes,
            c.samples_received,
            c.samples_lost,
            c.gaps,
            c.restarts,
            c.out_of_order_batches,
            c.frames_ok,
            c.frames_rejected,
            c.bytes_discarded,
            status,
            now,
        ],
    )
}

/// Close a session: its final state, why, and when.
pub fn set_end(
    conn: &Connection,
    id: i64,
    state: &str,
    reason: Option<&str>,
    ended: std::time::SystemTime,
) -> rusqlite::Result<usize> {
    conn.execute(
        "UPDATE sessions SET state = ?2, end_reason = ?3, ended_at = ?4, ended_unix = ?5, \
         recorder_pid = NULL WHERE id = ?1",
        params![
            id,
            state,
            reason,
            clock::iso8601(ended),
            clock::unix_seconds(ended)
        ],
    )
}

/// An interrupted recording: counts from the raw file (the truth), the end at the file's
/// last write, state `incomplete`, reason `interrupted`.
pub fn recover(conn: &Connection, session: &Session) -> rusqlite::Result<()> {
    let meta = std::fs::metadata(&session.file).ok();
    let ended = meta
        .as_ref()
        .and_then(|m| m.modified().ok())
        .unwrap_or_else(std::time::SystemTime::now);
    if session.kind == Kind::Capture
        && session.file.extension().is_some_and(|e| e == CAPTURE_EXT)
        && let Ok(bytes) = std::fs::read(&session.file)
    {
        let mut decoder = StreamDecoder::new(false);
        decoder.feed(&bytes);
        let mut counts = Counts::of(&decoder, bytes.len() as u64);
        if let Some(info) = decoder.info_seen() {
            set_board(conn, session.id, &Board::of(info))?;
        }
        // The recorder died mid-frame: the frame's bytes are on disk but not a sample.
        counts.bytes_discarded += decoder.pending() as u64;
        set_counts(conn, session.id, &counts, clock::unix_seconds(ended))?;
    }
    set_end(conn, session.id, "incomplete", Some("interrupted"), ended)?;
    Ok(())
}

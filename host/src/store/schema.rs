//! The catalog's schema and its migrations, versioned by `PRAGMA user_version`.
//!
//! Each migration runs in one transaction with the version bump, so a crash leaves either
//! the old or the new schema, and running `migrate` again does nothing (idempotent).

use rusqlite::Connection;

/// Migration `i` brings the schema from version `i` to `i + 1`.
const MIGRATIONS: &[&str] = &[
    // Version 1.
    r#"
CREATE TABLE IF NOT EXISTS sessions (
    id                  INTEGER PRIMARY KEY AUTOINCREMENT, -- never reused: files are named by it
    name                TEXT NOT NULL UNIQUE,
    kind                TEXT NOT NULL CHECK (kind IN ('capture', 'imported')),
    file                TEXT NOT NULL,          -- relative to the store directory
    started_at          TEXT NOT NULL,          -- UTC ISO 8601
    started_unix        REAL NOT NULL,
    ended_at            TEXT,
    ended_unix          REAL,
    state               TEXT NOT NULL CHECK (state IN ('recording', 'complete', 'incomplete')),
    end_reason          TEXT,                   -- why incomplete: interrupted, link error, ...
    recorder_pid        INTEGER,                -- the process writing a 'recording' session
    heartbeat_unix      REAL,                   -- its last catalog update
    board_id            TEXT,                   -- hex: a u64 does not fit SQLite's i64
    firmware_version    TEXT,
    protocol_version    INTEGER,
    rate_hz             REAL,
    gyro_bandwidth_hz   REAL,
    accel_bandwidth_hz  REAL,
    dlpf_cfg            INTEGER,
    smplrt_div          INTEGER,
    gyro_range_dps      INTEGER,
    accel_range_g       INTEGER,
    bytes               INTEGER NOT NULL DEFAULT 0,
    samples_received    INTEGER NOT NULL DEFAULT 0,
    samples_lost        INTEGER NOT NULL DEFAULT 0,
    gaps                INTEGER NOT NULL DEFAULT 0,
    restarts            INTEGER NOT NULL DEFAULT 0,
    out_of_order_batches INTEGER NOT NULL DEFAULT 0,
    frames_ok           INTEGER NOT NULL DEFAULT 0,
    frames_rejected     INTEGER NOT NULL DEFAULT 0,
    bytes_discarded     INTEGER NOT NULL DEFAULT 0,
    board_status        TEXT,                   -- JSON of the board's last Status
    notes               TEXT,
    import_source       TEXT,                   -- imported: the original path
    import_options      TEXT                    -- imported: JSON of how to read it again
);
CREATE TABLE IF NOT EXISTS analyses (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    session_id  INTEGER NOT NULL REFERENCES sessions(id) ON DELETE CASCADE,
    created_at  TEXT NOT NULL,
    options     TEXT NOT NULL,                  -- JSON: the command line and the options
    document    TEXT NOT NULL                   -- the analysis JSON document
);
CREATE INDEX IF NOT EXISTS analyses_session ON analyses(session_id);
"#,
    // Version 2: deterministic calibrations, per board (store/calibrations.rs).
    r#"
CREATE TABLE IF NOT EXISTS calibrations (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    board_id    TEXT NOT NULL,                  -- hex, as sessions.board_id
    created_at  TEXT NOT NULL,                  -- UTC ISO 8601
    kind        TEXT NOT NULL CHECK (kind IN ('accel', 'gyro', 'temperature')),
    settings    TEXT NOT NULL,                  -- JSON: rate, DLPF, ranges in force
    sources     TEXT NOT NULL,                  -- JSON: the sessions or files it was made from
    document    TEXT NOT NULL                   -- JSON: the calibration (calibration::Calibration)
);
CREATE INDEX IF NOT EXISTS calibrations_board ON calibrations(board_id);
"#,
];

/// The schema version this build writes.
pub const VERSION: u32 = MIGRATIONS.len() as u32;

/// Bring the catalog to [`VERSION`]; refuses a catalog from a newer imunoise.
pub fn migrate(conn: &mut Connection) -> Result<(), MigrateError> {
    let current: u32 = conn.pragma_query_value(None, "user_version", |r| r.get(0))?;
    if current > VERSION {
        return Err(MigrateError::Newer {
            found: current,
            known: VERSION,
        });
    }
    for (from, sql) in MIGRATIONS.iter().enumerate().skip(current as usize) {
        let tx = conn.transaction()?;
        tx.execute_batch(sql)?;
        tx.pragma_update(None, "user_version", from as u32 + 1)?;
        tx.commit()?;
    }
    Ok(())
}

#[derive(Debug, thiserror::Error)]
pub enum MigrateError {
    #[error(
        "the catalog has schema version {found}, newer than this imunoise knows ({known}): update imunoise"
    )]
    Newer { found: u32, known: u32 },
    #[error(
        "the catalog has schema version {found} and cannot be brought to {known}: it is read-only; open it once where it is writable"
    )]
    ReadOnly { found: u32, known: u32 },
    #[error(transparent)]
    Sql(#[from] rusqlite::Error),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn migrations_are_idempotent_and_refuse_newer() {
        let mut conn = Connection::open_in_memory().unwrap();
        migrate(&mut conn).unwrap();
        migrate(&mut conn).unwrap();
        let v: u32 = conn
            .pragma_query_value(None, "user_version", |r| r.get(0))
            .unwrap();
        assert_eq!(v, VERSION);
        conn.pragma_update(None, "user_version", VERSION + 1)
            .unwrap();
        let err = migrate(&mut conn).unwrap_err();
        assert!(err.to_string().contains("update imunoise"), "{err}");
    }
}

//! Sessions: each one a file under `sessions/` (a capture's raw bytes, appended as they
//! arrive, or an imported file copied verbatim) plus a row in a SQLite catalog
//! (`catalog.sqlite`) with its metadata, counts and the analyses computed from it.
//!
//! The raw file is the truth; the catalog describes it. So a capture killed mid-way loses at
//! most what was not yet flushed (under a second), and its counts are recomputed from the
//! file the next time the store is opened ([`Store::open`] recovers interrupted recordings).
//!
//! ```text
//! <store>/catalog.sqlite        the catalog (WAL mode; schema in schema.rs)
//! <store>/sessions/<id>.imucap  a capture's raw bytes
//! <store>/sessions/<id>.<ext>   an imported file (csv, txt, npy, ...)
//! <store>/.reserve-<id>         room to close session <id> on a full disk, while it records
//! ```

mod calibrations;
mod catalog;
pub mod clock;
mod integrity;
mod load;
pub mod location;
mod lookup;
mod schema;
mod session;
mod writer;

pub use calibrations::{CalibrationSettings, StoredCalibration};
pub use integrity::{CountsSeen, Problem, Repair};
pub use load::{LoadError, load_session, provenance};
pub use location::{ENV, locate};
pub use schema::VERSION as SCHEMA_VERSION;
pub use session::{Analysis, Board, Counts, ImportSpec, Kind, Session, State};
pub use writer::{End, RESERVE_BYTES, RawSink, STOPPED, SYNC_INTERVAL, SessionWriter};

use rusqlite::{Connection, OptionalExtension, params};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// The catalog's file name in the store directory.
pub const CATALOG: &str = "catalog.sqlite";
/// The folder of session files in the store directory.
pub const SESSIONS: &str = "sessions";
/// The extension of capture files.
pub const CAPTURE_EXT: &str = "imucap";

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("no default store directory on this platform: give --store DIR or set {ENV}")]
    NoDefaultDir,
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("catalog {path}: {source}")]
    Sql {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error("catalog {path}: {source}")]
    Schema {
        path: PathBuf,
        source: schema::MigrateError,
    },
    #[error("no session '{key}' in {store}{}", lookup::suggest(.close))]
    NotFound {
        key: String,
        store: PathBuf,
        close: Vec<String>,
    },
    #[error("'{key}' matches several sessions: {}; give the id or the full name", .matches.join(", "))]
    Ambiguous { key: String, matches: Vec<String> },
    #[error("session name '{name}': {reason}")]
    BadName { name: String, reason: &'static str },
    #[error("a session named '{0}' exists already")]
    NameTaken(String),
    #[error(
        "no store at {0} (check --store or ${ENV}; `capture`, `import`, `sweep` and `demo` create one)"
    )]
    Missing(PathBuf),
}

impl StoreError {
    pub(crate) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
        move |source| StoreError::Io {
            path: path.to_owned(),
            source,
        }
    }
}

/// Whether opening failed because the store cannot be written.
fn read_only(error: &StoreError) -> bool {
    use rusqlite::ErrorCode::{CannotOpen, ReadOnly};
    match error {
        StoreError::Io { source, .. } => matches!(
            source.kind(),
            std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem
        ),
        StoreError::Sql {
            source: rusqlite::Error::SqliteFailure(e, _),
            ..
        }
        | StoreError::Schema {
            source: schema::MigrateError::Sql(rusqlite::Error::SqliteFailure(e, _)),
            ..
        } => matches!(e.code, ReadOnly | CannotOpen),
        _ => false,
    }
}

/// Copy `source` to a `target` that must not exist yet; the bytes copied.
fn copy_new(source: &Path, target: &Path) -> Result<u64, StoreError> {
    let mut from = std::fs::File::open(source).map_err(StoreError::io(source))?;
    let mut to = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(target)
        .map_err(StoreError::io(target))?;
    std::io::copy(&mut from, &mut to).map_err(|e| {
        let _ = std::fs::remove_file(target);
        StoreError::Io {
            path: target.to_owned(),
            source: e,
        }
    })
}

/// The session id a file in `sessions/` is named by (`12.imucap` -> 12).
fn file_id(name: &str) -> Option<i64> {
    let stem = name.split('.').next()?;
    stem.parse().ok().filter(|&id: &i64| id > 0)
}

/// An open store: its directory and a connection to its catalog.
pub struct Store {
    dir: PathBuf,
    conn: Connection,
}

impl Store {
    /// Open an existing store to read it: as [`Store::open`] where the store can be
    /// written, read-only where it cannot (read-only media, another user's files). A missing
    /// store is an error, never created: a mistyped `--store` must not look like an empty
    /// store.
    pub fn open_existing(dir: &Path) -> Result<Store, StoreError> {
        let catalog_path = dir.join(CATALOG);
        // A store is its catalog or its session files (a store whose catalog was lost is
        // still one: `store repair` rebuilds the catalog).
        if !catalog_path.is_file() && !dir.join(SESSIONS).is_dir() {
            return Err(StoreError::Missing(dir.to_owned()));
        }
        match Store::open(dir) {
            Err(e) if read_only(&e) => Ok(Store {
                dir: dir.to_owned(),
                conn: catalog::connect_read_only(&catalog_path)?,
            }),
            other => other,
        }
    }

    /// Open (creating if needed) the store in `dir`, bring its catalog's schema up to date
    /// and recover recordings whose recorder is gone.
    pub fn open(dir: &Path) -> Result<Store, StoreError> {
        let sessions = dir.join(SESSIONS);
        std::fs::create_dir_all(&sessions).map_err(StoreError::io(&sessions))?;
        let conn = catalog::connect(&dir.join(CATALOG))?;
        let store = Store {
            dir: dir.to_owned(),
            conn,
        };
        store.recover_interrupted()?;
        Ok(store)
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Whether the store was opened read-only ([`Store::open_existing`]).
    pub fn is_read_only(&self) -> bool {
        self.conn.is_readonly(rusqlite::MAIN_DB).unwrap_or(true)
    }

    pub fn catalog_path(&self) -> PathBuf {
        self.dir.join(CATALOG)
    }

    pub(crate) fn sql(&self) -> impl FnOnce(rusqlite::Error) -> StoreError + '_ {
        move |source| StoreError::Sql {
            path: self.catalog_path(),
            source,
        }
    }

    /// Every session, oldest first.
    pub fn list(&self) -> Result<Vec<Session>, StoreError> {
        let sql = format!("SELECT {} FROM sessions ORDER BY id", Session::COLUMNS);
        let mut stmt = self.conn.prepare(&sql).map_err(self.sql())?;
        let rows = stmt
            .query_map([], |row| Session::from_row(row, &self.dir))
            .map_err(self.sql())?;
        rows.collect::<Result<_, _>>().map_err(self.sql())
    }

    pub fn get(&self, id: i64) -> Result<Option<Session>, StoreError> {
        let sql = format!("SELECT {} FROM sessions WHERE id = ?1", Session::COLUMNS);
        self.conn
            .query_row(&sql, [id], |row| Session::from_row(row, &self.dir))
            .optional()
            .map_err(self.sql())
    }

    /// The session a user means by `key`: its id, its name, or a unique prefix of its name.
    /// Absence and ambiguity are errors listing the close matches.
    pub fn find(&self, key: &str) -> Result<Session, StoreError> {
        let sessions = self.list()?;
        lookup::find(&sessions, key).map_err(|e| match e {
            lookup::Miss::None(close) => StoreError::NotFound {
                key: key.to_string(),
                store: self.dir.clone(),
                close,
            },
            lookup::Miss::Several(matches) => StoreError::Ambiguous {
                key: key.to_string(),
                matches,
            },
        })
    }

    /// Start a capture session: a catalog row in state `recording` and its empty raw file,
    /// returned as the writer a capture loop feeds.
    pub fn begin_capture(
        &self,
        name: Option<&str>,
        notes: Option<&str>,
    ) -> Result<SessionWriter, StoreError> {
        let now = SystemTime::now();
        let (id, name) = self.insert(Kind::Capture, name, notes, now, None)?;
        let file = self.dir.join(catalog::file_name(id, CAPTURE_EXT));
        SessionWriter::create(self.catalog_path(), id, name.is_none(), file, now)
    }

    /// Import a third-party file: copied into the store verbatim, read again with `spec`
    /// whenever the session is analysed or exported (no conversion, so nothing is lost).
    pub fn import(
        &self,
        source: &Path,
        spec: &ImportSpec,
        name: Option<&str>,
        notes: Option<&str>,
        samples: u64,
        rate_hz: f64,
    ) -> Result<Session, StoreError> {
        let now = SystemTime::now();
        let (id, _) = self.insert(Kind::Imported, name, notes, now, Some((source, spec)))?;
        let ext = source
            .extension()
            .and_then(|e| e.to_str())
            .filter(|e| !e.is_empty() && e.chars().all(|c| c.is_ascii_alphanumeric()))
            .unwrap_or("dat");
        let relative = catalog::file_name(id, ext);
        let target = self.dir.join(&relative);
        // The copy removes what it half-wrote itself; a failure to create the file (it
        // exists: some other session's) must not remove it.
        let recorded = copy_new(source, &target).map(|bytes| {
            let updated = self
                .conn
                .execute(
                    "UPDATE sessions SET file = ?2, bytes = ?3, samples_received = ?4, \
                     rate_hz = ?5, state = 'complete', ended_at = started_at, \
                     ended_unix = started_unix WHERE id = ?1",
                    params![id, relative, bytes, samples, rate_hz],
                )
                .map_err(self.sql());
            if updated.is_err() {
                let _ = std::fs::remove_file(&target);
            }
            updated
        });
        if let Err(e) = recorded.and_then(|updated| updated) {
            // Best effort: leave no half-imported session row behind.
            let _ = self
                .conn
                .execute("DELETE FROM sessions WHERE id = ?1", [id]);
            return Err(e);
        }
        Ok(self.get(id)?.expect("the session just imported"))
    }

    fn insert(
        &self,
        kind: Kind,
        name: Option<&str>,
        notes: Option<&str>,
        now: SystemTime,
        import: Option<(&Path, &ImportSpec)>,
    ) -> Result<(i64, Option<String>), StoreError> {
        if let Some(name) = name {
            lookup::check_name(name)?;
        }
        // A default name until the board says its rate and bandwidth (SessionWriter renames).
        let stamp = clock::compact(now);
        let chosen = match name {
            Some(n) => {
                if self.name_taken(n)? {
                    return Err(StoreError::NameTaken(n.to_string()));
                }
                n.to_string()
            }
            None => catalog::unique_name(&self.conn, &stamp).map_err(self.sql())?,
        };
        let spec = import.map(|(_, s)| serde_json::to_string(s).unwrap_or_default());
        let id = self.next_id()?;
        self.conn
            .execute(
                "INSERT INTO sessions (name, kind, file, started_at, started_unix, state, \
                 recorder_pid, heartbeat_unix, notes, import_source, import_options, id) \
                 VALUES (?1, ?2, '', ?3, ?4, 'recording', ?5, ?4, ?6, ?7, ?8, ?9)",
                params![
                    chosen,
                    if kind == Kind::Imported {
                        "imported"
                    } else {
                        "capture"
                    },
                    clock::iso8601(now),
                    clock::unix_seconds(now),
                    std::process::id(),
                    notes,
                    import.map(|(p, _)| p.display().to_string()),
                    spec,
                    id,
                ],
            )
            .map_err(self.sql())?;
        let relative = catalog::file_name(id, CAPTURE_EXT);
        self.conn
            .execute(
                "UPDATE sessions SET file = ?2 WHERE id = ?1",
                params![id, relative],
            )
            .map_err(self.sql())?;
        Ok((id, name.map(str::to_string)))
    }

    /// The id of the next session: above every id the catalog ever gave (AUTOINCREMENT's
    /// counter) and above every session file in `sessions/`, so that an id is never reused,
    /// even after the catalog was lost and its files remain.
    fn next_id(&self) -> Result<i64, StoreError> {
        let given: i64 = self
            .conn
            .query_row(
                "SELECT MAX(COALESCE((SELECT seq FROM sqlite_sequence WHERE name = 'sessions'), 0), \
                 COALESCE((SELECT MAX(id) FROM sessions), 0))",
                [],
                |r| r.get(0),
            )
            .map_err(self.sql())?;
        Ok(given.max(self.highest_file_id()?) + 1)
    }

    /// The highest id among the files in `sessions/` (named `<id>.<ext>`), 0 if none.
    fn highest_file_id(&self) -> Result<i64, StoreError> {
        let dir = self.dir.join(SESSIONS);
        let entries = std::fs::read_dir(&dir).map_err(StoreError::io(&dir))?;
        Ok(entries
            .filter_map(|e| e.ok())
            .filter_map(|e| file_id(&e.file_name().to_string_lossy()))
            .max()
            .unwrap_or(0))
    }

    fn name_taken(&self, name: &str) -> Result<bool, StoreError> {
        catalog::name_taken(&self.conn, name).map_err(self.sql())
    }

    /// Remove a session: its catalog row (with its analyses) and its file.
    pub fn remove(&self, session: &Session) -> Result<(), StoreError> {
        self.conn
            .execute("DELETE FROM sessions WHERE id = ?1", [session.id])
            .map_err(self.sql())?;
        match std::fs::remove_file(&session.file) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(StoreError::Io {
                path: session.file.clone(),
                source: e,
            }),
            _ => Ok(()),
        }
    }

    /// Keep an analysis computed from a session: its JSON document and how it was made.
    pub fn add_analysis(
        &self,
        session: i64,
        options: &serde_json::Value,
        document: &serde_json::Value,
    ) -> Result<i64, StoreError> {
        self.conn
            .execute(
                "INSERT INTO analyses (session_id, created_at, options, document) \
                 VALUES (?1, ?2, ?3, ?4)",
                params![
                    session,
                    clock::iso8601(SystemTime::now()),
                    options.to_string(),
                    document.to_string()
                ],
            )
            .map_err(self.sql())?;
        Ok(self.conn.last_insert_rowid())
    }

    pub fn analyses(&self, session: i64) -> Result<Vec<Analysis>, StoreError> {
        let mut stmt = self
            .conn
            .prepare(
                "SELECT id, created_at, options, document FROM analyses \
                 WHERE session_id = ?1 ORDER BY id",
            )
            .map_err(self.sql())?;
        let rows = stmt
            .query_map([session], |row| {
                let text = |i| -> rusqlite::Result<serde_json::Value> {
                    let t: String = row.get(i)?;
                    Ok(serde_json::from_str(&t).unwrap_or(serde_json::Value::String(t)))
                };
                Ok(Analysis {
                    id: row.get(0)?,
                    created_at: row.get(1)?,
                    options: text(2)?,
                    document: text(3)?,
                })
            })
            .map_err(self.sql())?;
        rows.collect::<Result<_, _>>().map_err(self.sql())
    }

    /// Sessions left in state `recording` by a recorder that is gone (killed, crashed, power
    /// lost) become `incomplete (interrupted)`, their counts recomputed from the raw file.
    fn recover_interrupted(&self) -> Result<(), StoreError> {
        let mut stmt = self
            .conn
            .prepare(
                "SELECT id, recorder_pid, heartbeat_unix FROM sessions WHERE state = 'recording'",
            )
            .map_err(self.sql())?;
        let recording: Vec<(i64, Option<u32>, Option<f64>)> = stmt
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
            .map_err(self.sql())?
            .collect::<Result<_, _>>()
            .map_err(self.sql())?;
        let now = clock::unix_seconds(SystemTime::now());
        for (id, pid, heartbeat) in recording {
            if catalog::recorder_alive(pid, heartbeat, now) {
                continue;
            }
            if let Some(session) = self.get(id)? {
                catalog::recover(&self.conn, &session).map_err(self.sql())?;
            }
            // The space its recorder held for closing it (see `writer`).
            let _ = std::fs::remove_file(writer::reserve_path(&self.dir, id));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A store that cannot be written is read through a read-only catalog: listed and shown,
    /// never written; a missing store is an error, not an empty new one.
    #[test]
    fn read_only_and_missing_stores() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("typo");
        assert!(matches!(
            Store::open_existing(&missing),
            Err(StoreError::Missing(_))
        ));
        assert!(!missing.exists(), "a reading command creates nothing");
        let store = Store::open(dir.path()).unwrap();
        let writer = store.begin_capture(Some("kept"), None).unwrap();
        writer.finish(End::Complete, &Counts::default()).unwrap();
        drop(store);
        // As the fallback opens it when writing fails (root ignores file modes, so the
        // failure itself cannot be staged here).
        let store = Store {
            dir: dir.path().to_owned(),
            conn: catalog::connect_read_only(&dir.path().join(CATALOG)).unwrap(),
        };
        assert!(store.is_read_only());
        assert_eq!(store.list().unwrap()[0].name, "kept");
        let doc = serde_json::json!({});
        assert!(store.add_analysis(1, &doc, &doc).is_err());
        // The errors that mean "cannot write" and nothing else.
        let sql = |code| StoreError::Sql {
            path: PathBuf::new(),
            source: rusqlite::Error::SqliteFailure(rusqlite::ffi::Error::new(code), None),
        };
        assert!(read_only(&sql(rusqlite::ffi::SQLITE_READONLY)));
        assert!(!read_only(&sql(rusqlite::ffi::SQLITE_CORRUPT)));
        let io = |kind| StoreError::Io {
            path: PathBuf::new(),
            source: std::io::Error::from(kind),
        };
        assert!(read_only(&io(std::io::ErrorKind::PermissionDenied)));
        assert!(!read_only(&io(std::io::ErrorKind::NotFound)));
    }
}

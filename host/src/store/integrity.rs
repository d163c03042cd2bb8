//! Checking a store's catalog against its files, and rebuilding what the catalog lost.
//!
//! The raw files are the truth and the catalog describes them, so the two can disagree only
//! one way that loses data: a file the catalog no longer knows (a catalog deleted, emptied
//! or restored from an old backup). [`Store::check`] lists every disagreement; [`Store::
//! repair`] gives orphaned files their catalog rows back (under their own ids, with counts
//! recomputed from the bytes) and brings stale counts up to date. Nothing is ever deleted or
//! rewritten: a row whose file is missing stays, reported.

use super::session::{Board, Counts, Kind, State};
use super::{CAPTURE_EXT, SESSIONS, Store, StoreError, catalog, clock, file_id};
use crate::capture::StreamDecoder;
use rusqlite::params;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// One disagreement between the catalog and the files.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "problem", rename_all = "snake_case")]
pub enum Problem {
    /// A file in `sessions/` that no catalog row names.
    Orphan { file: PathBuf, id: Option<i64> },
    /// A catalog row whose file is gone.
    MissingFile {
        id: i64,
        name: String,
        file: PathBuf,
    },
    /// A finished capture whose catalog counts differ from what its file holds.
    Counts {
        id: i64,
        name: String,
        catalog: CountsSeen,
        file: CountsSeen,
    },
}

/// The counts a check compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct CountsSeen {
    pub bytes: u64,
    pub samples_received: u64,
    pub samples_lost: u64,
}

impl CountsSeen {
    fn of(c: &Counts) -> CountsSeen {
        CountsSeen {
            bytes: c.bytes,
            samples_received: c.samples_received,
            samples_lost: c.samples_lost,
        }
    }
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Problem::Orphan { file, id: Some(id) } => write!(
                f,
                "orphan: {} (session {id}) has no catalog row; `imunoise store repair` restores it",
                file.display()
            ),
            Problem::Orphan { file, id: None } => write!(
                f,
                "stray file: {} is not named as a session file; left alone",
                file.display()
            ),
            Problem::MissingFile { id, name, file } => write!(
                f,
                "missing: session {id} '{name}' names {}, which does not exist",
                file.display()
            ),
            Problem::Counts {
                id,
                name,
                catalog,
                file,
            } => write!(
                f,
                "counts: session {id} '{name}': the catalog says {} bytes, {} samples received, {} lost; the file holds {}, {}, {}",
                catalog.bytes,
                catalog.samples_received,
                catalog.samples_lost,
                file.bytes,
                file.samples_received,
                file.samples_lost
            ),
        }
    }
}

/// What a repair did.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "action", rename_all = "snake_case")]
pub enum Repair {
    /// An orphaned file got its catalog row back.
    Restored {
        id: i64,
        name: String,
        file: PathBuf,
    },
    /// A capture's counts were recomputed from its file.
    Recounted { id: i64, name: String },
}

impl std::fmt::Display for Repair {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Repair::Restored { id, name, file } => {
                write!(f, "restored session {id} '{name}' from {}", file.display())
            }
            Repair::Recounted { id, name } => {
                write!(f, "recounted session {id} '{name}' from its file")
            }
        }
    }
}

/// A capture file's counts and board, as its bytes say.
fn decode(path: &Path) -> Result<(Counts, Option<Board>), StoreError> {
    let bytes = std::fs::read(path).map_err(StoreError::io(path))?;
    let mut decoder = StreamDecoder::new(false);
    decoder.feed(&bytes);
    decoder.settle();
    let mut counts = Counts::of(&decoder, bytes.len() as u64);
    // A recorder that died mid-frame left the frame's bytes on disk, not a sample.
    counts.bytes_discarded += decoder.pending() as u64;
    Ok((counts, decoder.info_seen().map(Board::of)))
}

impl Store {
    /// Every disagreement between the catalog and the files in `sessions/`.
    pub fn check(&self) -> Result<Vec<Problem>, StoreError> {
        let sessions = self.list()?;
        let mut problems = Vec::new();
        for path in self.session_files()? {
            if !sessions.iter().any(|s| s.file == path) {
                let id = path.file_name().and_then(|n| file_id(&n.to_string_lossy()));
                problems.push(Problem::Orphan { file: path, id });
            }
        }
        for s in &sessions {
            if !s.file.exists() {
                problems.push(Problem::MissingFile {
                    id: s.id,
                    name: s.name.clone(),
                    file: s.file.clone(),
                });
                continue;
            }
            if s.kind != Kind::Capture || s.state == State::Recording {
                continue;
            }
            let (counts, _) = decode(&s.file)?;
            let (catalog, file) = (CountsSeen::of(&s.counts), CountsSeen::of(&counts));
            if catalog != file {
                problems.push(Problem::Counts {
                    id: s.id,
                    name: s.name.clone(),
                    catalog,
                    file,
                });
            }
        }
        Ok(problems)
    }

    /// Restore orphaned session files' catalog rows and recount stale captures; delete
    /// nothing. Returns what was done.
    pub fn repair(&self) -> Result<Vec<Repair>, StoreError> {
        let mut done = Vec::new();
        for problem in self.check()? {
            match problem {
                Problem::Orphan { file, id: Some(id) } => {
                    let name = self.restore(id, &file)?;
                    done.push(Repair::Restored { id, name, file });
                }
                Problem::Counts { id, name, .. } => {
                    if let Some(s) = self.get(id)? {
                        let (counts, _) = decode(&s.file)?;
                        catalog::set_counts(&self.conn, id, &counts, now()).map_err(self.sql())?;
                        done.push(Repair::Recounted { id, name });
                    }
                }
                Problem::Orphan { id: None, .. } | Problem::MissingFile { .. } => {}
            }
        }
        Ok(done)
    }

    /// A catalog row for the orphaned `file` of session `id`: a capture's counts and board
    /// from its bytes, an imported file as imported with its options unknown (read with
    /// the defaults, `--rate` and `--names` on use). Its name is `recovered-<id>`.
    fn restore(&self, id: i64, file: &Path) -> Result<String, StoreError> {
        let name =
            catalog::unique_name(&self.conn, &format!("recovered-{id}")).map_err(self.sql())?;
        let modified = std::fs::metadata(file)
            .and_then(|m| m.modified())
            .unwrap_or_else(|_| SystemTime::now());
        let capture = file.extension().is_some_and(|e| e == CAPTURE_EXT);
        let relative = format!(
            "{SESSIONS}/{}",
            file.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        );
        self.conn
            .execute(
                "INSERT INTO sessions (id, name, kind, file, started_at, started_unix, state, \
                 notes) VALUES (?1, ?2, ?3, ?4, ?5, ?6, 'recording', ?7)",
                params![
                    id,
                    name,
                    if capture { "capture" } else { "imported" },
                    relative,
                    clock::iso8601(modified),
                    clock::unix_seconds(modified),
                    "restored by `imunoise store repair` from a file the catalog had lost; \
                     its start time is the file's last write",
                ],
            )
            .map_err(self.sql())?;
        if capture {
            let (counts, board) = decode(file)?;
            if let Some(board) = board {
                catalog::set_board(&self.conn, id, &board).map_err(self.sql())?;
            }
            catalog::set_counts(&self.conn, id, &counts, clock::unix_seconds(modified))
                .map_err(self.sql())?;
        } else {
            let bytes = std::fs::metadata(file).map_or(0, |m| m.len());
            self.conn
                .execute(
                    "UPDATE sessions SET bytes = ?2 WHERE id = ?1",
                    params![id, bytes],
                )
                .map_err(self.sql())?;
        }
        catalog::set_end(
            &self.conn,
            id,
            "incomplete",
            Some("restored by store repair; how it ended is unknown"),
            modified,
        )
        .map_err(self.sql())?;
        Ok(name)
    }

    /// The files in `sessions/`, sorted.
    fn session_files(&self) -> Result<Vec<PathBuf>, StoreError> {
        let dir = self.dir.join(SESSIONS);
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map_err(StoreError::io(&dir))?
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        Ok(files)
    }
}

fn now() -> f64 {
    clock::unix_seconds(SystemTime::now())
}

//! The writer a capture loop feeds: appends the raw bytes to the session's file as they
//! arrive, flushes and fsyncs at least every [`SYNC_INTERVAL`], and keeps the catalog's
//! counts and heartbeat current, so a recorder killed at any moment leaves a listed,
//! readable session that lacks at most the last interval of data.
//!
//! A disk that fills up fails the catalog as well as the raw file: closing the session needs
//! a few pages of the catalog's write-ahead log. So each recording holds a small reserve
//! file ([`RESERVE_BYTES`], `<store>/.reserve-<id>`), released just before the session is
//! closed: the end and its real reason reach the catalog even on a full disk.

use super::session::{Board, Counts};
use super::{StoreError, catalog, clock};
use protocol::DeviceInfo;
use rusqlite::Connection;
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime};

/// The longest time received bytes stay in memory before they are on disk (flushed and
/// fsync'd): half the promised second, so a slow loop iteration cannot stretch it past one.
pub const SYNC_INTERVAL: std::time::Duration = std::time::Duration::from_millis(500);

/// Room kept free for closing a session on a full disk, bytes: the catalog's closing
/// transaction writes a few 4 KiB pages (with their 24-byte frame headers) to its
/// write-ahead log; this is several times that.
pub const RESERVE_BYTES: usize = 128 * 1024;

/// How a session ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum End {
    /// The source ended or the duration was reached.
    Complete,
    /// The user stopped it (Ctrl-C): what it holds is whole, but shorter than asked for.
    Stopped,
    /// Complete, ended for the reason given (a stop rule met, or the duration reached
    /// before it was).
    CompleteBecause(String),
    /// Something cut it short (a link error, a disk error); the reason is kept and shown.
    Incomplete(String),
}

/// Sink of the raw bytes; a trait so tests can make the disk fail mid-capture.
pub trait RawSink: Write + Send {
    fn sync(&mut self) -> std::io::Result<()>;
}

impl RawSink for File {
    fn sync(&mut self) -> std::io::Result<()> {
        self.sync_data()
    }
}

pub struct SessionWriter {
    id: i64,
    path: PathBuf,
    catalog: PathBuf,
    out: BufWriter<Box<dyn RawSink>>,
    conn: Connection,
    /// The session got a default name, to be completed with the rate and bandwidth.
    default_name: bool,
    started: SystemTime,
    bytes: u64,
    last_sync: Instant,
    /// Counts as last given, written at the next sync.
    counts: Counts,
    board: bool,
    /// The space reserve, removed when the session is closed.
    reserve: PathBuf,
}

/// The space reserve of session `id` in the store `dir`.
pub(super) fn reserve_path(dir: &Path, id: i64) -> PathBuf {
    dir.join(format!(".reserve-{id}"))
}

/// Why a session ended, for a failed write to its file: the system's reason (the session's
/// own file goes without saying).
fn write_failed(error: &StoreError) -> String {
    match error {
        StoreError::Io { source, .. } => format!("write failed: {source}"),
        other => format!("write failed: {other}"),
    }
}

/// Hold [`RESERVE_BYTES`] at `path`. The bytes vary (a pseudo-random sequence), so neither a
/// sparse file nor a compressing file system can hold them for free.
fn reserve(path: &Path) -> std::io::Result<()> {
    let mut state: u64 = 0x2545_F491_4F6C_DD1D;
    let bytes: Vec<u8> = (0..RESERVE_BYTES)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect();
    let mut file = OpenOptions::new()
        .create(true)
        .truncate(true)
        .write(true)
        .open(path)?;
    file.write_all(&bytes)?;
    file.sync_data()
}

impl SessionWriter {
    pub(super) fn create(
        catalog_path: PathBuf,
        id: i64,
        default_name: bool,
        path: PathBuf,
        started: SystemTime,
    ) -> Result<SessionWriter, StoreError> {
        // A new session never writes into a file that exists (an orphan of a lost catalog,
        // say): created here or not at all.
        let file = OpenOptions::new()
            .create_new(true)
            .append(true)
            .open(&path)
            .map_err(StoreError::io(&path))?;
        let dir = catalog_path.parent().unwrap_or(Path::new("."));
        let reserve_file = reserve_path(dir, id);
        reserve(&reserve_file).map_err(StoreError::io(&reserve_file))?;
        let conn = catalog::connect(&catalog_path)?;
        Ok(SessionWriter {
            id,
            path,
            catalog: catalog_path,
            out: BufWriter::with_capacity(1 << 16, Box::new(file)),
            conn,
            default_name,
            started,
            bytes: 0,
            last_sync: Instant::now(),
            counts: Counts::default(),
            board: false,
            reserve: reserve_file,
        })
    }

    /// Replace the file sink (tests: a disk that fails after N bytes).
    #[doc(hidden)]
    pub fn with_sink(mut self, sink: Box<dyn RawSink>) -> SessionWriter {
        self.out = BufWriter::with_capacity(1 << 16, sink);
        self
    }

    pub fn id(&self) -> i64 {
        self.id
    }

    /// The session's raw file.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }

    /// Bytes accepted so far.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Append received bytes (buffered; on disk by the next [`SessionWriter::tick`]).
    pub fn write(&mut self, bytes: &[u8]) -> Result<(), StoreError> {
        self.out
            .write_all(bytes)
            .map_err(StoreError::io(&self.path))?;
        self.bytes += bytes.len() as u64;
        Ok(())
    }

    /// The board's Info: its metadata into the catalog (once it succeeds: a catalog that
    /// failed is tried again at the next call), and a default name becomes
    /// `YYYYmmdd-HHMMSS-<rate>hz-<bw>hz`.
    pub fn set_board(&mut self, info: &DeviceInfo) -> Result<(), StoreError> {
        if self.board {
            return Ok(());
        }
        let board = Board::of(info);
        let sql = self.sql_error();
        catalog::set_board(&self.conn, self.id, &board).map_err(sql)?;
        if self.default_name {
            let base = format!(
                "{}-{}hz-{}hz",
                clock::compact(self.started),
                protocol::mpu6050::Hz(board.rate_hz),
                board
                    .gyro_bandwidth_hz
                    .map_or("reserved".to_string(), |b| protocol::mpu6050::Hz(b)
                        .to_string())
            );
            let name = catalog::unique_name(&self.conn, &base).map_err(self.sql_error())?;
            self.conn
                .execute(
                    "UPDATE sessions SET name = ?2 WHERE id = ?1",
                    rusqlite::params![self.id, name],
                )
                .map_err(self.sql_error())?;
        }
        self.board = true;
        Ok(())
    }

    /// Call often (at least every few hundred ms, with or without new data): flushes and
    /// fsyncs the file and writes `counts` to the catalog once [`SYNC_INTERVAL`] has passed.
    ///
    /// A disk error is returned (the capture cannot go on); a catalog error is returned too,
    /// but the caller may go on recording, as the counts can always be recomputed from the
    /// file.
    pub fn tick(&mut self, counts: &Counts) -> Result<(), StoreError> {
        self.counts = counts.clone();
        if self.last_sync.elapsed() < SYNC_INTERVAL {
            return Ok(());
        }
        self.last_sync = Instant::now();
        self.sync()?;
        self.write_counts()
    }

    /// Everything written so far onto the file (not fsynced), for a reader of the file
    /// while the recording goes on.
    pub fn flush(&mut self) -> Result<(), StoreError> {
        self.out.flush().map_err(StoreError::io(&self.path))
    }

    fn sync(&mut self) -> Result<(), StoreError> {
        self.out.flush().map_err(StoreError::io(&self.path))?;
        self.out
            .get_mut()
            .sync()
            .map_err(StoreError::io(&self.path))
    }

    fn write_counts(&mut self) -> Result<(), StoreError> {
        catalog::set_counts(&self.conn, self.id, &self.final_counts(), now())
            .map_err(self.sql_error())?;
        Ok(())
    }

    /// The counts as last given, with the bytes accepted (or, after a failure, on disk).
    fn final_counts(&self) -> Counts {
        Counts {
            bytes: self.bytes,
            ..self.counts.clone()
        }
    }

    /// Close the session: everything onto disk, final counts, end time and state. If the
    /// disk fails here, the session is still closed as incomplete with that reason, and the
    /// disk error is returned. The space reserve is released first, so that a full disk
    /// still takes the closing.
    pub fn finish(mut self, end: End, counts: &Counts) -> Result<i64, StoreError> {
        self.counts = counts.clone();
        let synced = self.sync();
        let end = match (&synced, end) {
            (Err(e), _) => End::Incomplete(write_failed(e)),
            (Ok(()), end) => end,
        };
        let (state, reason) = match &end {
            End::Complete => ("complete", None),
            End::Stopped => ("complete", Some(STOPPED)),
            End::CompleteBecause(reason) => ("complete", Some(reason.as_str())),
            End::Incomplete(reason) => ("incomplete", Some(reason.as_str())),
        };
        if synced.is_err() {
            // Count only what reached the file.
            self.bytes = std::fs::metadata(&self.path).map_or(0, |m| m.len());
        }
        let _ = std::fs::remove_file(&self.reserve);
        let closed = self
            .conn
            .unchecked_transaction()
            .and_then(|tx| {
                catalog::set_counts(&tx, self.id, &self.final_counts(), now())?;
                catalog::set_end(&tx, self.id, state, reason, SystemTime::now())?;
                tx.commit()
            })
            .map_err(self.sql_error());
        closed.and(synced).map(|()| self.id)
    }

    /// Mark the session incomplete after a failure, keeping whatever reached the disk.
    pub fn abandon(self, reason: &str) -> Result<i64, StoreError> {
        let counts = self.counts.clone();
        self.finish(End::Incomplete(reason.to_string()), &counts)
    }

    /// Close the session after its file could not be written: incomplete, with the
    /// system's reason, keeping whatever reached the disk.
    pub fn write_failed(self, error: &StoreError, counts: &Counts) -> Result<i64, StoreError> {
        self.finish(End::Incomplete(write_failed(error)), counts)
    }

    fn sql_error(&self) -> impl FnOnce(rusqlite::Error) -> StoreError + use<> {
        let path = self.catalog.clone();
        move |source| StoreError::Sql { path, source }
    }
}

/// The end reason of a session the user stopped ([`End::Stopped`]).
pub const STOPPED: &str = "interrupted by the user";

fn now() -> f64 {
    clock::unix_seconds(SystemTime::now())
}

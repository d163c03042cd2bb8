//! The capture loop: bytes from a [`Link`] go, exactly as received, into a session
//! ([`SessionWriter`]) and through the same [`StreamDecoder`] a replay uses, which counts
//! samples and losses live. It ends when the source ends, the duration is reached, the user
//! stops it (Ctrl-C: `complete`), or the link fails (`incomplete`, with the reason).

use crate::capture::{BoardReport, Capture, RecoveryReport, StreamDecoder};
use crate::link::Link;
use crate::store::{Counts, End, SessionWriter, Store, StoreError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long one read may wait: short, so the writer's one-second sync and a stop request are
/// served promptly even on a silent link.
const READ_TIMEOUT: Duration = Duration::from_millis(100);

#[derive(Debug, Clone, Default)]
pub struct RecordOptions {
    pub name: Option<String>,
    pub notes: Option<String>,
    /// Stop after this much sample time (samples numbered by the board / rate).
    pub duration_s: Option<f64>,
    /// Keep the decoded samples in memory and return them (tests, analysing right after);
    /// a long capture needs only the counts, its samples are in its file.
    pub keep_samples: bool,
}

/// Why a capture ended.
#[derive(Debug)]
pub enum Ending {
    /// The source had nothing more (a replayed file).
    SourceEnded,
    DurationReached,
    /// The stop flag was raised (Ctrl-C).
    Stopped,
    /// The link failed (a disconnect): the session is `incomplete`.
    LinkFailed(std::io::Error),
}

/// What the loop reports after each read, for a progress display.
#[derive(Debug, Clone)]
pub struct Progress {
    pub elapsed: Duration,
    pub counts: Counts,
    /// Samples numbered by the board so far (received + lost), and how many are wanted.
    pub samples_expected: u64,
    pub samples_wanted: Option<u64>,
    pub rate_hz: Option<f64>,
    /// Refusals and faults the board sent since the previous progress report.
    pub new_board_errors: Vec<BoardReport>,
    /// Faults the board recovered from since the previous progress report.
    pub new_recoveries: Vec<RecoveryReport>,
}

pub struct Outcome {
    pub session_id: i64,
    pub ending: Ending,
    pub counts: Counts,
    /// The decoded capture, with its samples if [`RecordOptions::keep_samples`].
    pub capture: Option<Capture>,
}

#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The store failed; the session was closed as incomplete with what reached the disk.
    #[error(
        "session {session}: {source}; the session is kept as incomplete with what was written before"
    )]
    Store { session: i64, source: StoreError },
    #[error(transparent)]
    Begin(StoreError),
}

/// Record from `link` into a new session of `store` until the source ends, the duration is
/// reached, `stop` is raised or the link fails.
pub fn record(
    link: &mut dyn Link,
    store: &Store,
    options: &RecordOptions,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Outcome, RecordError> {
    let writer = store
        .begin_capture(options.name.as_deref(), options.notes.as_deref())
        .map_err(RecordError::Begin)?;
    record_into(link, writer, options, stop, progress)
}

/// [`record`] into a session already begun (`options.name` and `notes` are then unused).
pub fn record_into(
    link: &mut dyn Link,
    writer: SessionWriter,
    options: &RecordOptions,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Outcome, RecordError> {
    let mut decoder = StreamDecoder::new(options.keep_samples);
    let id = writer.id();
    run(link, writer, &mut decoder, options, stop, progress).map(|(ending, counts)| Outcome {
        session_id: id,
        ending,
        counts,
        capture: decoder.finish().ok(),
    })
}

fn run(
    link: &mut dyn Link,
    mut writer: SessionWriter,
    decoder: &mut StreamDecoder,
    options: &RecordOptions,
    stop: &AtomicBool,
    progress: &mut dyn FnMut(&Progress),
) -> Result<(Ending, Counts), RecordError> {
    let started = Instant::now();
    let mut buf = vec![0u8; 1 << 16];
    let mut catalog_warned = false;
    let mut board_errors_shown = 0;
    let mut recoveries_shown = 0;
    let ending = loop {
        if stop.load(Ordering::Relaxed) {
            break Ending::Stopped;
        }
        if link.at_end() {
            break Ending::SourceEnded;
        }
        let n = match link.read(&mut buf, READ_TIMEOUT) {
            Ok(n) => n,
            Err(e) => break Ending::LinkFailed(e),
        };
        let chunk = &buf[..n];
        if let Err(source) = writer.write(chunk) {
            return Err(fail(writer, decoder, source));
        }
        if decoder.feed(chunk) > 0
            && let Some(info) = decoder.info_seen().copied()
            && let Err(e) = writer.set_board(&info)
        {
            warn_catalog(&mut catalog_warned, &e);
        }
        let counts = Counts::of(decoder, writer.bytes());
        match writer.tick(&counts) {
            Err(source @ StoreError::Io { .. }) => return Err(fail(writer, decoder, source)),
            Err(e) => warn_catalog(&mut catalog_warned, &e),
            Ok(()) => {}
        }
        let rate_hz = decoder.info_seen().map(|i| i.settings.output_rate_hz());
        let wanted = options
            .duration_s
            .zip(rate_hz)
            .map(|(d, r)| (d * r).round() as u64);
        let expected = decoder.accounting().expected();
        let new_board_errors = decoder.board_errors()[board_errors_shown..].to_vec();
        board_errors_shown += new_board_errors.len();
        let new_recoveries = decoder.recoveries()[recoveries_shown..].to_vec();
        recoveries_shown += new_recoveries.len();
        progress(&Progress {
            elapsed: started.elapsed(),
            counts,
            samples_expected: expected,
            samples_wanted: wanted,
            rate_hz,
            new_board_errors,
            new_recoveries,
        });
        if wanted.is_some_and(|w| expected >= w) {
            break Ending::DurationReached;
        }
    };
    let counts = Counts::of(decoder, writer.bytes());
    let end = match &ending {
        Ending::LinkFailed(e) => End::Incomplete(format!("link error on {}: {e}", link.describe())),
        _ => End::Complete,
    };
    let session = writer.id();
    writer
        .finish(end, &counts)
        .map_err(|source| RecordError::Store { session, source })?;
    Ok((ending, counts))
}

/// A disk error: close the session as incomplete (keeping what reached the disk) and say so.
fn fail(writer: SessionWriter, decoder: &StreamDecoder, source: StoreError) -> RecordError {
    let session = writer.id();
    let counts = Counts::of(decoder, writer.bytes());
    let _ = writer.finish(End::Incomplete(format!("disk error: {source}")), &counts);
    RecordError::Store { session, source }
}

/// The catalog is only a description of the raw file: a failure to update it must not stop
/// the recording (the counts are recomputed from the file when needed). Say so once.
fn warn_catalog(warned: &mut bool, error: &StoreError) {
    if !*warned {
        eprintln!("warning: {error}; recording goes on (the catalog is updated at the end)");
        *warned = true;
    }
}

//! What the session commands share: opening the store (`--store`, `$IMUNOISE_STORE`, the
//! platform data directory) and reading an input that is a file or a stored session.

use anyhow::{Context, Result};
use imunoise::analysis::pipeline::Options;
use imunoise::input::{self, LoadOptions, Loaded};
use imunoise::store::{self, Session, Store};
use std::path::Path;

/// Open the store the user chose for a command that writes to it (capture, import, rm ...),
/// creating it on first use and saying so.
pub fn open_store(flag: Option<&Path>) -> Result<Store> {
    let dir = store::locate(flag)?;
    let new = !dir.join(store::CATALOG).exists();
    let store = Store::open(&dir).with_context(|| format!("store {}", dir.display()))?;
    if new {
        eprintln!("note: created a new store at {}", dir.display());
    }
    Ok(store)
}

/// Open the store the user chose for a command that only reads it (sessions, show, export
/// ...): it must exist, and a read-only store is opened read-only.
pub fn read_store(flag: Option<&Path>) -> Result<Store> {
    let dir = store::locate(flag)?;
    Ok(Store::open_existing(&dir)?)
}

/// A catalog listing: as JSON, or as a table, or a line saying the store has no `what`.
pub fn print_listing<T: serde::Serialize>(
    items: &[T],
    json: bool,
    store: &Store,
    what: &str,
    table: impl Fn(&[T]) -> String,
) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(items)?);
    } else if items.is_empty() {
        println!("no {what} in {}", store.dir().display());
    } else {
        print!("{}", table(items));
    }
    Ok(())
}

/// A record read from a file or from a stored session, and the session if it was one.
pub struct Input {
    pub loaded: Loaded,
    pub session: Option<(Store, Session)>,
}

/// What a reader says about the input (losses, the run chosen), on stderr.
pub fn print_notes(notes: &[String]) {
    for note in notes {
        eprintln!("note: {note}");
    }
}

/// What the user must know before trusting a record read (jitter, an overridden rate), on
/// stderr.
pub fn print_warnings(warnings: &[String]) {
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
}

/// How a stored analysis was made: this process's command line (its arguments, without the
/// program name) and the analysis options, both JSON.
pub fn provenance(options: &Options) -> serde_json::Value {
    store::provenance(&std::env::args().skip(1).collect::<Vec<_>>(), options)
}

/// Keep an analysis of a stored session (its options and JSON document) in its catalog row.
pub fn keep_analysis(
    session: Option<&(Store, Session)>,
    options: &Options,
    document: &serde_json::Value,
) -> Result<()> {
    {
        let Some((store, session)) = session else {
            return Ok(());
        };
        let options = provenance(options);
        if store.is_read_only() {
            eprintln!(
                "note: the analysis is not stored with session {}: the store {} is read-only",
                session.id,
                store.dir().display()
            );
            return Ok(());
        }
        let id = store.add_analysis(session.id, &options, document)?;
        eprintln!(
            "stored analysis {id} with session {} '{}'",
            session.id, session.name
        );
        Ok(())
    }
}

/// `input` names an existing file (read as such) or else a stored session (its id or name).
pub fn load(input: &Path, options: &LoadOptions, store: Option<&Path>) -> Result<Input> {
    if input.exists() {
        return Ok(Input {
            loaded: read(input, options)?,
            session: None,
        });
    }
    let key = input.to_string_lossy();
    let store = read_store(store).with_context(|| format!("{key}: no such file"))?;
    let session = store
        .find(&key)
        .with_context(|| format!("{key}: no such file"))?;
    let loaded = load_session(&session, options)?;
    Ok(Input {
        loaded,
        session: Some((store, session)),
    })
}

/// A session's record ([`store::load_session`]), with a spinner while it is read and its
/// warnings on stderr.
pub fn load_session(session: &Session, options: &LoadOptions) -> Result<Loaded> {
    reading(&session.file, || store::load_session(session, options))
}

/// Read a file as a record, with a spinner while it is read and its warnings on stderr.
fn read(path: &Path, options: &LoadOptions) -> Result<Loaded> {
    reading(path, || input::load(path, options))
}

/// `load` (which reads `path`) under a spinner; then the record's warnings.
fn reading<E: std::error::Error + Send + Sync + 'static>(
    path: &Path,
    load: impl FnOnce() -> Result<Loaded, E>,
) -> Result<Loaded> {
    let reading = crate::cli::progress::spinner(format!("reading {}", path.display()));
    let loaded = load();
    reading.finish_and_clear();
    let loaded = loaded?;
    print_warnings(&loaded.report.warnings);
    Ok(loaded)
}

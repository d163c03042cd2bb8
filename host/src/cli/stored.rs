//! What the session commands share: opening the store (`--store`, `$IMUNOISE_STORE`, the
//! platform data directory) and reading an input that is a file or a stored session.

use crate::analysis::pipeline::Options;
use crate::cli::analyze::Analysed;
use crate::input::{self, LoadOptions, Loaded};
use crate::report;
use crate::store::{self, Kind, Session, Store};
use anyhow::{Context, Result};
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
    serde_json::json!({
        "command": std::env::args().skip(1).collect::<Vec<_>>(),
        "options": options,
    })
}

/// Keep an analysis of a stored session in its catalog row.
pub fn keep_analysis(session: Option<&(Store, Session)>, analysed: &Analysed) -> Result<()> {
    {
        let Some((store, session)) = session else {
            return Ok(());
        };
        let options = provenance(&analysed.options);
        if store.is_read_only() {
            eprintln!(
                "note: the analysis is not stored with session {}: the store {} is read-only",
                session.id,
                store.dir().display()
            );
            return Ok(());
        }
        let id = store.add_analysis(session.id, &options, &analysed.document)?;
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

/// A session's record: a capture decoded from its raw bytes, an imported file read again
/// with the options it was imported with (the user's own options take precedence).
pub fn load_session(session: &Session, options: &LoadOptions) -> Result<Loaded> {
    let mut options = options.clone();
    if session.kind == Kind::Imported
        && let Some(spec) = &session.import_options
    {
        options.rate_hz = options.rate_hz.or(spec.rate_hz);
        options.ignore_time |= spec.ignore_time;
        if options.names.is_empty() {
            options.names = spec.names.clone();
        }
        options.scales.splice(0..0, spec.scales.iter().cloned());
    }
    let mut loaded = read(&session.file, &options)
        .with_context(|| format!("session {} '{}'", session.id, session.name))?;
    loaded.record.source = format!("session {} '{}'", session.id, session.name);
    Ok(loaded)
}

fn read(path: &Path, options: &LoadOptions) -> Result<Loaded> {
    let reading = report::progress::spinner(format!("reading {}", path.display()));
    let loaded = input::load(path, options);
    reading.finish_and_clear();
    let loaded = loaded?;
    print_warnings(&loaded.report.warnings);
    Ok(loaded)
}

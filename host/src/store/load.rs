//! A stored session read back as a record: a capture decoded from its raw bytes, an
//! imported file read again with the options it was imported with.

use super::{Kind, Session};
use crate::input::{self, InputError, LoadOptions, Loaded};

/// A session whose file could not be read as a record.
#[derive(Debug, thiserror::Error)]
#[error("session {id} '{name}'")]
pub struct LoadError {
    pub id: i64,
    pub name: String,
    pub source: InputError,
}

/// A session's record, named after the session. An imported file is read with the options
/// it was imported with; the caller's `options` take precedence.
pub fn load_session(session: &Session, options: &LoadOptions) -> Result<Loaded, LoadError> {
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
        options.topic = options.topic.or_else(|| spec.topic.clone());
    }
    let source = format!("session {} '{}'", session.id, session.name);
    let mut loaded = input::load(&session.file, &options).map_err(|source| LoadError {
        id: session.id,
        name: session.name.clone(),
        source,
    })?;
    loaded.record.source = source;
    Ok(loaded)
}

/// How a stored analysis was made, as the catalog keeps it: the command that asked for it
/// (its arguments, without the program name) and the analysis options.
pub fn provenance(command: &[String], options: &impl serde::Serialize) -> serde_json::Value {
    serde_json::json!({
        "command": command,
        "options": options,
    })
}

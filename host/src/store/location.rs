//! Where the store lives: `--store DIR`, else `$IMUNOISE_STORE`, else the platform's data
//! directory (XDG on Linux: `~/.local/share/imunoise`), so a user's sessions persist across
//! working directories without configuration, and tests can point at a temporary one.

use super::StoreError;
use std::path::{Path, PathBuf};

/// The environment variable that overrides the default store directory.
pub const ENV: &str = "IMUNOISE_STORE";

pub fn locate(flag: Option<&Path>) -> Result<PathBuf, StoreError> {
    if let Some(dir) = flag {
        return Ok(dir.to_owned());
    }
    if let Some(dir) = std::env::var_os(ENV).filter(|v| !v.is_empty()) {
        return Ok(PathBuf::from(dir));
    }
    directories::ProjectDirs::from("", "", "imunoise")
        .map(|d| d.data_dir().to_owned())
        .ok_or(StoreError::NoDefaultDir)
}

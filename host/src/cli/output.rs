//! Output files a command is asked to write: never one of its own inputs, never a file of
//! the store (its catalog and its `sessions/`, which the store writes itself, exclusively). `export 3 --out
//! <session 3's raw file>` would otherwise truncate the session before reading it.

use anyhow::{Result, bail};
use std::path::{Path, PathBuf};

/// Where `path` would be, resolved (the file itself may not exist yet); `None` if its folder
/// does not exist either (writing will fail with its own error).
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = path.canonicalize() {
        return Some(p);
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(parent.canonicalize().ok()?.join(path.file_name()?))
}

/// Refuse to write `path` (named `what` in the error, e.g. "--out") when it is one of
/// `inputs` or lies inside the store `store`.
pub fn check(path: &Path, what: &str, store: Option<&Path>, inputs: &[&Path]) -> Result<()> {
    let Some(target) = resolved(path) else {
        return Ok(());
    };
    for input in inputs {
        if resolved(input).is_some_and(|i| i == target) {
            bail!(
                "{what} {}: that is this command's own input; writing it would destroy what it reads",
                path.display()
            );
        }
    }
    if let Some(store) = store.and_then(|s| s.canonicalize().ok())
        && store_file(&store, &target)
    {
        bail!(
            "{what} {}: that is inside the store {}, whose files only the store writes; choose a path outside it",
            path.display(),
            store.display()
        );
    }
    Ok(())
}

/// Refuse `path` (named `what`, e.g. "--report") when its folder does not exist: said before
/// the work whose results it would hold, not after.
pub fn check_folder(path: &Path, what: &str) -> Result<()> {
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !folder.is_dir() {
        bail!(
            "{what} {}: the folder {} does not exist",
            path.display(),
            folder.display()
        );
    }
    Ok(())
}

/// Whether `target` is one of the store's own files: its catalog (with SQLite's journal
/// files) or anything under `sessions/`. Other files in the store's folder are the user's.
fn store_file(store: &Path, target: &Path) -> bool {
    let catalog = imunoise::store::CATALOG;
    target.starts_with(store.join(imunoise::store::SESSIONS))
        || ["", "-wal", "-shm", "-journal"]
            .iter()
            .any(|suffix| target == store.join(format!("{catalog}{suffix}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_inputs_and_store_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("store");
        std::fs::create_dir_all(store.join("sessions")).unwrap();
        let raw = store.join("sessions/1.imucap");
        std::fs::write(&raw, b"\0data").unwrap();
        let input = dir.path().join("in.csv");
        std::fs::write(&input, "x\n1\n").unwrap();
        let err = check(&input, "--out", None, &[&input]).unwrap_err();
        assert!(err.to_string().contains("own input"), "{err}");
        // Through another spelling of the same path.
        let dotted = dir.path().join(".").join("in.csv");
        assert!(check(&dotted, "--out", None, &[&input]).is_err());
        let err = check(&raw, "--out", Some(&store), &[]).unwrap_err();
        assert!(err.to_string().contains("inside the store"), "{err}");
        let new_in_store = store.join("sessions/new.csv");
        assert!(check(&new_in_store, "--out", Some(&store), &[]).is_err());
        assert!(
            check(
                &store.join("catalog.sqlite-wal"),
                "--out",
                Some(&store),
                &[]
            )
            .is_err()
        );
        // The store's folder itself may hold the user's own files.
        assert!(check(&store.join("rest.csv"), "--out", Some(&store), &[]).is_ok());
        // Elsewhere is fine, existing or not; a missing folder is left to the write.
        assert!(
            check(
                &dir.path().join("out.csv"),
                "--out",
                Some(&store),
                &[&input]
            )
            .is_ok()
        );
        assert!(check(Path::new("/nonexistent/x.csv"), "--out", Some(&store), &[]).is_ok());
        assert_eq!(std::fs::read(&raw).unwrap(), b"\0data");
    }
}

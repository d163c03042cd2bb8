//! What the binary's tests share: one way to run `imunoise`, one way to give a test a store
//! and scratch files, both temporary, so that no test reads or writes the user's store.
//!
//! Every command is started by [`imunoise`], which points `$IMUNOISE_STORE`, `$XDG_DATA_HOME`
//! and `$HOME` at [`NO_STORE`]: a test that forgets `--store` fails ("no store at ...")
//! instead of reaching the user's sessions. A test that needs a store makes a [`TempStore`].
// Each test binary uses its own part of this module.
#![allow(dead_code)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use tempfile::TempDir;

/// Where every store lookup without `--store` lands: a path under `/dev/null`, where no
/// directory can exist or be created.
pub const NO_STORE: &str = "/dev/null/imunoise-test-store";

/// The `imunoise` binary, its store and data directory pointed at [`NO_STORE`], stdin closed.
pub fn imunoise() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_imunoise"));
    command
        .env("IMUNOISE_STORE", NO_STORE)
        .env("XDG_DATA_HOME", NO_STORE)
        .env("HOME", NO_STORE)
        .stdin(Stdio::null());
    command
}

/// `imunoise ARGS...`, run to the end.
pub fn run(args: &[&str]) -> Output {
    imunoise()
        .args(args)
        .output()
        .expect("the imunoise binary runs")
}

/// `imunoise ARGS...`, which must succeed; its stdout.
pub fn ok(args: &[&str]) -> String {
    let out = run(args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    stdout(&out)
}

pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `imunoise --store STORE ARGS...`, run to the end.
pub fn run_in(store: &Path, args: &[&str]) -> Output {
    imunoise()
        .arg("--store")
        .arg(store)
        .args(args)
        .output()
        .expect("the imunoise binary runs")
}

/// `imunoise --store STORE capture --port sim` at full speed, which must succeed; its output.
pub fn sim_capture(
    store: &Path,
    rate: &str,
    bandwidth: &str,
    duration: &str,
    name: &str,
) -> Output {
    let args = [
        "capture",
        "--port",
        "sim",
        "--rate",
        rate,
        "--bandwidth",
        bandwidth,
        "--duration",
        duration,
        "--speed",
        "max",
        "--name",
        name,
    ];
    let out = run_in(store, &args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    out
}

/// Stdout as JSON, from a command that must have succeeded.
pub fn json(out: &Output) -> Value {
    assert!(out.status.success(), "{}", stderr(out));
    serde_json::from_slice(&out.stdout).expect("stdout is JSON")
}

/// A temporary directory, removed when the value is dropped (at the end of the test).
pub fn scratch() -> TempDir {
    tempfile::Builder::new()
        .prefix("imunoise-test-")
        .tempdir()
        .expect("a temporary directory")
}

/// A store of the test's own: `store/` inside a [`scratch`] directory, not yet created (the
/// first writing command creates it), removed with the directory. Other files of the test
/// go beside it ([`TempStore::file`]).
pub struct TempStore {
    dir: TempDir,
}

impl TempStore {
    pub fn new() -> Self {
        TempStore { dir: scratch() }
    }

    /// The store directory, as `--store` takes it.
    pub fn path(&self) -> PathBuf {
        self.dir.path().join("store")
    }

    /// The store directory as a string, for argument lists.
    pub fn arg(&self) -> String {
        self.path().to_str().expect("a UTF-8 temp path").to_owned()
    }

    /// A path beside the store, in the same temporary directory.
    pub fn file(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `imunoise --store <this store> ARGS...`, run to the end.
    pub fn run(&self, args: &[&str]) -> Output {
        run_in(&self.path(), args)
    }

    /// As [`TempStore::run`], which must succeed.
    pub fn ok(&self, args: &[&str]) -> Output {
        let out = self.run(args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        out
    }
}

/// The documented example model, the one built into the binary.
pub fn example_model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/mpu6050.toml")
}

/// The real MPU-6050 record (`tests/data/mpu6050_static_100hz`).
pub fn mpu_record() -> String {
    concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/data/mpu6050_static_100hz/example_data_tinit_calc.csv"
    )
    .to_string()
}

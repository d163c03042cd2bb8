//! Sessions through the `imunoise` binary, each test with its own store (`--store`): a
//! capture killed with SIGKILL stays listed and readable; Ctrl-C ends one as complete;
//! import, export, show, replay, rm; errors name the thing at fault.

mod common;

use common::{example_model, run_in, scratch, sim_capture};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

fn ok(o: Output) -> String {
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn err(o: Output) -> String {
    assert!(!o.status.success(), "expected a failure");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A simulated 200 Hz / 42 Hz capture of `seconds`.
fn capture_file(dir: &Path, seconds: u32) -> PathBuf {
    let model = example_model();
    let out = dir.join(format!("sim{seconds}.imucap"));
    let o = common::imunoise()
        .args(["simulate", "--model"])
        .arg(&model)
        .args(["--rate", "200", "--bandwidth", "42", "--format", "capture"])
        .arg("--duration")
        .arg(format!("{seconds}s"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    ok(o);
    out
}

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// `imunoise capture --from-file SOURCE ARGS` running in the background.
fn spawn_capture(store: &Path, source: &Path, args: &[&str]) -> std::process::Child {
    common::imunoise()
        .arg("--store")
        .arg(store)
        .arg("capture")
        .args(args)
        .arg("--from-file")
        .arg(source)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn signal(pid: u32, sig: &str) {
    let s = Command::new("kill")
        .args([sig, &pid.to_string()])
        .status()
        .unwrap();
    assert!(s.success());
}

#[test]
fn a_capture_killed_with_sigkill_is_listed_and_readable() {
    let tmp = scratch();
    let store = tmp.path().join("store");
    let source = capture_file(tmp.path(), 60);
    let mut child = spawn_capture(&store, &source, &["--speed", "1", "--name", "killed"]);
    std::thread::sleep(Duration::from_secs(2));
    signal(child.id(), "-KILL");
    child.wait().unwrap();

    let list = json(&ok(run_in(&store, &["sessions", "--json"])));
    let s = &list[0];
    assert_eq!(s["name"], "killed");
    assert_eq!(s["state"], "incomplete");
    assert_eq!(s["end_reason"], "interrupted");
    let received = s["counts"]["samples_received"].as_u64().unwrap();
    // ~2 s at 200 Hz were sent; at most the last second (and the start-up) may be missing.
    assert!((150..=420).contains(&received), "{received} samples");
    let table = ok(run_in(&store, &["sessions"]));
    assert!(table.contains("incomplete (interrupted)"), "{table}");

    let shown = ok(run_in(&store, &["show", "killed"]));
    assert!(shown.contains("may not have reached the disk"), "{shown}");
    let file = PathBuf::from(s["file"].as_str().unwrap());
    let bytes = std::fs::read(&file).unwrap();
    let c = imunoise::capture::Capture::decode(&bytes).unwrap();
    assert_eq!(c.first().accounting.received(), received);
    assert_eq!(c.first().accounting.lost(), 0);
    // The head of the original stream, byte for byte.
    assert_eq!(bytes, std::fs::read(&source).unwrap()[..bytes.len()]);
}

#[test]
fn ctrl_c_ends_a_capture_as_complete() {
    let tmp = scratch();
    let store = tmp.path().join("store");
    let source = capture_file(tmp.path(), 60);
    let child = spawn_capture(&store, &source, &["--speed", "2"]);
    std::thread::sleep(Duration::from_millis(1500));
    signal(child.id(), "-INT");
    let out = ok(child.wait_with_output().unwrap());
    assert!(out.contains("complete"), "{out}");
    let list = json(&ok(run_in(&store, &["sessions", "--json"])));
    assert_eq!(list[0]["state"], "complete");
    assert_eq!(list[0]["end_reason"], "interrupted by the user");
    assert!(list[0]["ended_at"].is_string());
    assert!(list[0]["name"].as_str().unwrap().ends_with("-200hz-42hz"));
}

#[test]
fn sessions_show_export_replay_analyze_rm() {
    let tmp = scratch();
    let store = tmp.path().join("store");
    let source = capture_file(tmp.path(), 20);
    let src = source.to_str().unwrap();
    ok(run_in(
        &store,
        &[
            "capture",
            "--speed",
            "max",
            "--name",
            "bench-a",
            "--from-file",
            src,
        ],
    ));
    ok(run_in(
        &store,
        &[
            "capture",
            "--speed",
            "max",
            "--name",
            "bench-b",
            "--duration",
            "5s",
            "--from-file",
            src,
        ],
    ));
    let list = json(&ok(run_in(&store, &["sessions", "--json"])));
    assert_eq!(list[0]["counts"]["samples_received"], 4000);
    assert_eq!(list[0]["board"]["dlpf_cfg"], 3);
    assert_eq!(list[0]["board"]["smplrt_div"], 4);
    assert!(list[1]["counts"]["samples_received"].as_u64().unwrap() >= 1000);

    // Ambiguity and absence list the close names.
    let e = err(run_in(&store, &["show", "bench"]));
    assert!(e.contains("bench-a (1), bench-b (2)"), "{e}");
    let e = err(run_in(&store, &["show", "bench-c"]));
    assert!(e.contains("did you mean") && e.contains("bench-a"), "{e}");

    // Export: SI, time from the index; identical to the capture's record.
    let csv = ok(run_in(&store, &["export", "bench-a"]));
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("time,gx,gy,gz,ax,ay,az,temp"));
    assert!(lines.next().unwrap().starts_with("0,"));
    assert!(lines.next().unwrap().starts_with("0.005,"));
    assert_eq!(csv.lines().count(), 4001);

    // Replay and analyze by name store their analyses.
    ok(run_in(
        &store,
        &["replay", "bench-a", "--column", "gx", "--taus", "octave"],
    ));
    ok(run_in(
        &store,
        &["analyze", "1", "--column", "gz", "--taus", "octave"],
    ));
    let shown = json(&ok(run_in(&store, &["show", "1", "--json"])));
    let analyses = shown["analyses"].as_array().unwrap();
    assert_eq!(analyses.len(), 2);
    assert_eq!(analyses[0]["document"]["samples"], 4000);
    assert!(analyses[1]["options"]["command"].to_string().contains("gz"));

    // Import the exported CSV: a copy plus metadata, analysed the same way.
    let exported = tmp.path().join("a.csv");
    std::fs::write(&exported, &csv).unwrap();
    let out = ok(run_in(
        &store,
        &[
            "import",
            exported.to_str().unwrap(),
            "--name",
            "from-csv",
            "--note",
            "exported",
        ],
    ));
    assert!(out.contains("4000 samples at 200 Hz"), "{out}");
    let shown = json(&ok(run_in(&store, &["show", "from-csv", "--json"])));
    assert_eq!(shown["session"]["kind"], "imported");
    assert_eq!(shown["session"]["notes"], "exported");
    let again = ok(run_in(&store, &["export", "from-csv"]));
    assert_eq!(again.lines().count(), 4001);

    // rm needs --yes without a terminal.
    let e = err(run_in(&store, &["rm", "bench-b"]));
    assert!(e.contains("--yes"), "{e}");
    ok(run_in(&store, &["rm", "bench-b", "--yes"]));
    let list = json(&ok(run_in(&store, &["sessions", "--json"])));
    assert_eq!(list.as_array().unwrap().len(), 2);
    assert!(!store.join("sessions/2.imucap").exists());
}

#[test]
fn export_marks_gaps_without_bridging_them() {
    use imunoise::capture::CaptureWriter;
    use protocol::{DeviceInfo, DeviceMessage, FirmwareVersion, RawSample, SampleBatch};
    let tmp = scratch();
    let store = tmp.path().join("store");
    let mut w = CaptureWriter::new(Vec::new());
    w.message(&DeviceMessage::Info(DeviceInfo {
        protocol_version: protocol::PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 1,
        who_am_i: 0x68,
        settings: protocol::SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap(),
        streaming: true,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    }))
    .unwrap();
    for first in [0u64, 4, 10] {
        w.message(&DeviceMessage::Samples(SampleBatch {
            first_index: first,
            first_timestamp_us: first * 5000,
            samples: (0..2).map(|_| RawSample::default()).collect(),
        }))
        .unwrap();
    }
    let file = tmp.path().join("gaps.imucap");
    std::fs::write(&file, w.into_inner()).unwrap();
    ok(run_in(&store, &["import", file.to_str().unwrap()]));
    let csv = ok(run_in(&store, &["export", "1"]));
    let times: Vec<&str> = csv.lines().map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(
        times,
        [
            "time",
            "0",
            "0.005",
            "# gap: 2 samples lost at index 2",
            "0.02",
            "0.025",
            "# gap: 4 samples lost at index 6",
            "0.05",
            "0.055"
        ]
    );
}

#[test]
fn an_unwritable_store_is_a_clear_error() {
    let tmp = scratch();
    let blocker = tmp.path().join("not-a-dir");
    std::fs::write(&blocker, "x").unwrap();
    let store = blocker.join("store");
    let e = err(run_in(&store, &["sessions"]));
    assert!(e.contains(store.to_str().unwrap()), "{e}");
    let e = err(run_in(&tmp.path().join("s"), &["show", "nothing"]));
    assert!(e.contains("no store at"), "{e}");
    // rm writes: it opens (and creates) the store, then finds no such session.
    let e = err(run_in(&tmp.path().join("s"), &["rm", "nothing", "--yes"]));
    assert!(e.contains("no session 'nothing'"), "{e}");
}

/// A lost catalog never mixes data: the next capture gets a new id and a new file, and the
/// orphaned session's raw file stays byte for byte as it was.
#[test]
fn a_lost_catalog_never_reuses_an_id_or_a_file() {
    let dir = scratch();
    let store = dir.path().join("store");
    let capture = |name: &str| {
        sim_capture(&store, "200", "42", "5s", name);
    };
    capture("first");
    let first = store.join("sessions/1.imucap");
    let before = std::fs::read(&first).unwrap();
    let exported = ok(run_in(&store, &["export", "first"]));
    let shown = json(&ok(run_in(&store, &["show", "first", "--json"])));
    // The duration is the record's (5 s of samples), not the capture's wall time (a
    // fraction of a second at --speed max).
    let record_s = shown["session"]["duration_s"].as_f64().unwrap();
    assert!((5.0..5.2).contains(&record_s), "{record_s}");
    assert!(shown["session"]["wall_s"].as_f64().unwrap() < 5.0);
    for f in ["catalog.sqlite", "catalog.sqlite-wal", "catalog.sqlite-shm"] {
        let _ = std::fs::remove_file(store.join(f));
    }
    assert!(ok(run_in(&store, &["sessions"])).contains("no sessions"));
    capture("second");
    assert_eq!(
        std::fs::read(&first).unwrap(),
        before,
        "the orphan is untouched"
    );
    let listed = json(&ok(run_in(&store, &["show", "second", "--json"])));
    assert_eq!(listed["session"]["id"], 2, "{listed}");
    assert!(store.join("sessions/2.imucap").exists());
    // The catalog against the files: session 1's file is an orphan; repair gives it its
    // row back, from its bytes, and the two agree again.
    let problems = err(run_in(&store, &["store", "check"]));
    assert!(problems.contains("1 problem(s)"), "{problems}");
    let listed = json(&String::from_utf8_lossy(
        &run_in(&store, &["store", "check", "--json"]).stdout,
    ));
    assert_eq!(listed[0]["problem"], "orphan");
    assert_eq!(listed[0]["id"], 1);
    assert!(ok(run_in(&store, &["store", "repair"])).contains("restored session 1 'recovered-1'"));
    assert!(ok(run_in(&store, &["store", "check"])).contains("agree"));
    assert_eq!(
        std::fs::read(&first).unwrap(),
        before,
        "repair rewrites nothing"
    );
    assert_eq!(ok(run_in(&store, &["export", "1"])), exported);
    let restored = json(&ok(run_in(&store, &["show", "1", "--json"])));
    for key in ["samples_received", "samples_lost", "bytes"] {
        assert_eq!(
            restored["session"]["counts"][key], shown["session"]["counts"][key],
            "{key}"
        );
    }
    assert_eq!(restored["session"]["board"], shown["session"]["board"]);
    assert!(ok(run_in(&store, &["sessions"])).contains("second"));
    // Stale counts (a catalog restored from an old backup, say) are found and recounted.
    let catalog = rusqlite::Connection::open(store.join("catalog.sqlite")).unwrap();
    catalog
        .execute("UPDATE sessions SET samples_received = 5 WHERE id = 2", [])
        .unwrap();
    drop(catalog);
    let checked = run_in(&store, &["store", "check"]);
    assert!(!checked.status.success());
    let problems = String::from_utf8_lossy(&checked.stdout);
    assert!(
        problems.contains("counts: session 2 'second'"),
        "{problems}"
    );
    assert!(ok(run_in(&store, &["store", "repair"])).contains("recounted session 2"));
    assert!(ok(run_in(&store, &["store", "check"])).contains("agree"));
    // Removing the newest session does not free its id either.
    ok(run_in(&store, &["rm", "second", "--yes"]));
    capture("third");
    let listed = json(&ok(run_in(&store, &["show", "third", "--json"])));
    assert_eq!(listed["session"]["id"], 3, "{listed}");
}

/// A mistyped `--store` is an error for a reading command (nothing is created); a writing
/// command creates the store and says so.
#[test]
fn only_writing_commands_create_a_store() {
    let dir = scratch();
    let typo = dir.path().join("stroe");
    for args in [&["sessions"][..], &["show", "1"], &["export", "1"]] {
        let text = err(run_in(&typo, args));
        assert!(text.contains("no store at"), "{args:?}: {text}");
    }
    assert!(!typo.exists());
    let o = run_in(
        &typo,
        &[
            "capture",
            "--port",
            "sim",
            "--rate",
            "50",
            "--bandwidth",
            "20",
            "--duration",
            "2s",
            "--speed",
            "max",
        ],
    );
    let said = String::from_utf8_lossy(&o.stderr).into_owned();
    ok(o);
    assert!(said.contains("created a new store at"), "{said}");
    assert!(ok(run_in(&typo, &["sessions"])).contains("complete"));
}

/// A capture that fills the disk ends with that reason, in the catalog on the same full disk
/// (not "interrupted", which blames a killed recorder). The disk is a 512 KiB tmpfs in a
/// private mount namespace (`unshare`), gone with it; where user namespaces are not allowed
/// the test says so and passes (`recorder.rs` covers the reason with an injected disk).
#[test]
fn a_full_disk_ends_a_capture_with_that_reason() {
    let namespace = Command::new("unshare").args(["-rm", "true"]).status();
    if !namespace.is_ok_and(|s| s.success()) {
        eprintln!("skipped: no private mount namespace (unshare -rm) on this machine");
        return;
    }
    let dir = scratch();
    let script = r#"mount -t tmpfs -o size=512k tmpfs "$1" || exit 90
        "$2" --store "$1/s" capture --port sim --rate 1000 --bandwidth 188 --speed max --duration 1h
        echo "capture exit $?" >&2
        "$2" --store "$1/s" sessions --json"#;
    let o = Command::new("unshare")
        .args(["-rm", "sh", "-c", script, "sh"])
        .arg(dir.path())
        .arg(env!("CARGO_BIN_EXE_imunoise"))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_ne!(o.status.code(), Some(90), "{said}");
    assert!(said.contains("capture exit 1"), "{said}");
    assert!(said.contains("No space left on device"), "{said}");
    let list = json(&ok(o));
    assert_eq!(list[0]["state"], "incomplete");
    assert_eq!(
        list[0]["end_reason"],
        "write failed: No space left on device (os error 28)"
    );
    assert!(list[0]["counts"]["samples_received"].as_u64().unwrap() > 1000);
}

/// Ctrl-C in a sweep ends the session being captured cleanly ("interrupted by the user"),
/// starts no other, and says which sessions it made.
#[test]
fn ctrl_c_stops_a_sweep_with_its_sessions_closed() {
    let tmp = scratch();
    let store = tmp.path().join("store");
    let child = common::imunoise()
        .arg("--store")
        .arg(&store)
        .args(["sweep", "--port", "sim", "--settings", "200:42,50:42"])
        .args(["--duration", "10m", "--speed", "1"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Until the first session is recording (the handler is in place before it begins).
    let recording = (0..200).any(|_| {
        std::thread::sleep(Duration::from_millis(100));
        let o = run_in(&store, &["sessions", "--json"]);
        o.status.success() && json(&String::from_utf8_lossy(&o.stdout))[0]["state"] == "recording"
    });
    assert!(recording, "the sweep never started its first session");
    signal(child.id(), "-INT");
    let out = child.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains(
            "sweep stopped by the user at setting 1/2; sessions made: 1 'sweep-200hz-42hz' (cut short, not analysed)"
        ),
        "{said}"
    );
    let list = json(&ok(run_in(&store, &["sessions", "--json"])));
    assert_eq!(list.as_array().unwrap().len(), 1, "{list}");
    assert_eq!(list[0]["state"], "complete");
    assert_eq!(list[0]["end_reason"], "interrupted by the user");
    assert!(list[0]["counts"]["samples_received"].as_u64().unwrap() > 0);
}

/// Every stored analysis keeps the command line that made it and its options as JSON (a
/// sweep's too); analyses stored with the options as text (older stores) still show.
#[test]
fn stored_analyses_keep_their_command_and_options_as_json() {
    let tmp = scratch();
    let store = tmp.path().join("store");
    let sweep = [
        "sweep",
        "--port",
        "sim",
        "--settings",
        "200:42",
        "--duration",
        "30s",
        "--speed",
        "max",
    ];
    ok(run_in(&store, &sweep));
    ok(run_in(&store, &["analyze", "1", "--psd-window", "hamming"]));
    let shown = json(&ok(run_in(&store, &["show", "1", "--json"])));
    let made = |i: usize| shown["analyses"][i]["options"].clone();
    let mut command = vec![serde_json::json!("--store"), serde_json::json!(store)];
    command.extend(sweep.iter().map(|a| serde_json::json!(a)));
    assert_eq!(made(0)["command"], serde_json::Value::Array(command));
    assert_eq!(
        made(0)["options"]["taus"],
        serde_json::json!({"per_decade": 10})
    );
    assert_eq!(made(0)["options"]["psd_window"], "hann");
    assert_eq!(made(1)["options"]["psd_window"], "hamming");
    assert_eq!(made(1)["command"][2], "analyze");
    let text = ok(run_in(&store, &["show", "1"]));
    assert!(
        text.contains("sweep --port sim --settings 200:42"),
        "{text}"
    );

    // An analysis as older versions stored it: the command's name, the options as text.
    let catalog = rusqlite::Connection::open(store.join("catalog.sqlite")).unwrap();
    catalog
        .execute(
            "INSERT INTO analyses (session_id, created_at, options, document) VALUES \
             (1, '2025-01-01T00:00:00Z', ?1, '{}')",
            [r#"{"command":"sweep","options":"Options { data_type: Rate, confidence: 0.683 }"}"#],
        )
        .unwrap();
    drop(catalog);
    let shown = json(&ok(run_in(&store, &["show", "1", "--json"])));
    assert_eq!(
        shown["analyses"][2]["options"]["options"],
        "Options { data_type: Rate, confidence: 0.683 }"
    );
    let text = ok(run_in(&store, &["show", "1"]));
    assert!(
        text.contains("2025-01-01T00:00:00Z: imunoise sweep\n"),
        "{text}"
    );
}

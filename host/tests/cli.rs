//! The `imunoise` binary as a user runs it: output, JSON, errors and exit codes.

mod common;

use common::{json, run, scratch, sim_capture, stderr, stdout};
use std::path::Path;

#[test]
fn settings_resolves_the_papers_settings_to_registers() {
    let out = run(&["settings", "--rate", "200", "--bandwidth", "42", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["output_rate_hz"], 200.0);
    assert_eq!(v["dlpf_cfg"], 3);
    assert_eq!(v["smplrt_div"], 4);
    assert_eq!(v["registers"]["CONFIG"], 3);
    assert_eq!(v["gyro_bandwidth_hz"], 42.0);
    assert_eq!(v["bandwidth_exceeds_half_rate"], false);

    let out = run(&[
        "settings",
        "--rate",
        "50",
        "--bandwidth",
        "256",
        "--gyro-range",
        "2000",
        "--accel-range",
        "16",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(
        (v["dlpf_cfg"].as_u64(), v["smplrt_div"].as_u64()),
        (Some(0), Some(159))
    );
    assert_eq!(v["registers"]["GYRO_CONFIG"], 0x18);
    assert_eq!(v["registers"]["ACCEL_CONFIG"], 0x18);
    assert_eq!(v["gyro_lsb_per_dps"], 16.4);
    assert_eq!(v["bandwidth_exceeds_half_rate"], true);
}

#[test]
fn settings_table_lists_every_dlpf_row() {
    let out = run(&["settings", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let rows = v["dlpf"].as_array().unwrap();
    assert_eq!(rows.len(), 7);
    assert_eq!(rows[0]["gyro_internal_rate_hz"], 8000.0);
    assert_eq!(rows[6]["gyro_bandwidth_hz"], 5.0);
    let text = stdout(&run(&["settings"]));
    assert!(text.contains("reserved"), "{text}");
}

#[test]
fn unreachable_settings_fail_with_the_nearest_choices() {
    let out = run(&["settings", "--rate", "150", "--bandwidth", "42"]);
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("--rate 150 --bandwidth 42"), "{err}");
    assert!(
        err.contains("166.667 Hz (SMPLRT_DIV 5) or 142.857 Hz (SMPLRT_DIV 6)"),
        "{err}"
    );

    let out = run(&["settings", "--rate", "100", "--bandwidth", "40"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("nearest: 42 Hz (DLPF_CFG 3)"),
        "{}",
        stderr(&out)
    );

    let out = run(&[
        "settings",
        "--rate",
        "100",
        "--bandwidth",
        "42",
        "--gyro-range",
        "300",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("--gyro-range 300"),
        "{}",
        stderr(&out)
    );

    // A rate without a bandwidth is refused, naming the bandwidths there are.
    let out = run(&["settings", "--rate", "100"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("needs --bandwidth with --sensor mpu6050: one of 256 188 98 42"),
        "{}",
        stderr(&out)
    );
}

/// The GY-85's two sensors resolve to their datasheet registers, by their datasheet names.
#[test]
fn settings_resolve_the_gy85_sensors() {
    let out = run(&[
        "settings",
        "--sensor",
        "itg3200",
        "--rate",
        "50",
        "--bandwidth",
        "20",
        "--json",
    ]);
    let v = json(&out);
    assert_eq!(v["registers"]["SMPLRT_DIV"], 19);
    assert_eq!(v["registers"]["DLPF_FS"], 0x1C);
    assert_eq!(v["output_rate_hz"], 50.0);
    let v = json(&run(&[
        "settings", "--sensor", "adxl345", "--rate", "50", "--json",
    ]));
    assert_eq!(v["registers"]["BW_RATE"], 0x09);
    assert_eq!(v["registers"]["DATA_FORMAT"], 0x08);
    assert_eq!(v["bandwidth_hz"], 25.0);
    // The nearest choices when there is no exact one.
    let out = run(&["settings", "--sensor", "adxl345", "--rate", "60"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("nearest: 50 Hz (BW_RATE 0x09)"),
        "{}",
        stderr(&out)
    );
    let out = run(&[
        "settings",
        "--sensor",
        "itg3200",
        "--rate",
        "300",
        "--bandwidth",
        "42",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("333.333 Hz (SMPLRT_DIV 2)"),
        "{}",
        stderr(&out)
    );
    // The tables.
    let v = json(&run(&["settings", "--sensor", "adxl345", "--json"]));
    assert_eq!(v["rates"].as_array().map(Vec::len), Some(16));
    let v = json(&run(&["settings", "--sensor", "itg3200", "--json"]));
    assert_eq!(v["dlpf"].as_array().map(Vec::len), Some(7));
}

#[test]
fn demo_accounts_for_every_sample() {
    let dir = scratch();
    let store = dir.path().join("store");
    let store = store.to_str().unwrap();
    let out = run(&["--store", store, "demo", "--duration", "2m"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    // 10 s at 200 Hz = 2000 samples in 63 batches; one flipped and one truncated frame lose
    // two full batches of 32; the noise burst is rejected on its own.
    assert!(text.contains("2000 samples"), "{text}");
    assert!(text.contains("frames decoded: 61; rejected: 3"), "{text}");
    assert!(
        text.contains("2000 numbered by the board, 1936 received, 64 lost in 2 gaps"),
        "{text}"
    );
    // Its sessions' analyses keep the command that made them and their options, as JSON.
    let shown = run(&["--store", store, "show", "demo-200hz-42hz", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&shown)).unwrap();
    let made = &v["analyses"][0]["options"];
    assert_eq!(
        made["command"],
        serde_json::json!(["--store", store, "demo", "--duration", "2m"])
    );
    assert_eq!(made["options"]["confidence"], 0.683);
}

/// A reader that goes away (`imunoise export 1 | head -1`) ends the command quietly: exit 0,
/// nothing on stderr, where println! would panic on the closed pipe.
#[test]
fn a_closed_pipe_ends_the_command_quietly() {
    let dir = scratch();
    let store = dir.path().join("store");
    let store = store.to_str().unwrap();
    sim_capture(Path::new(store), "1000", "188", "20s", "pipe");
    for args in [
        vec!["--store", store, "export", "pipe"],
        vec!["--store", store, "show", "pipe", "--json"],
        vec!["--store", store, "sessions"],
    ] {
        let mut child = common::imunoise()
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The reader closes its end before (or while) the command writes.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {:?} {}",
            out.status,
            stderr(&out)
        );
        assert_eq!(stderr(&out), "", "{args:?}");
    }
}

/// No command writes onto its own input or into the store: `export ID --out <the session's
/// raw file>` is refused and the session stays byte for byte as it was.
#[test]
fn outputs_never_overwrite_inputs_or_store_files() {
    let dir = scratch();
    let store = dir.path().join("store");
    let s = store.to_str().unwrap();
    sim_capture(&store, "200", "42", "5s", "keep");
    let raw = store.join("sessions/1.imucap");
    let before = std::fs::read(&raw).unwrap();
    let out = run(&[
        "--store",
        s,
        "export",
        "keep",
        "--out",
        raw.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("own input"), "{}", stderr(&out));
    let catalog = store.join("catalog.sqlite");
    let out = run(&[
        "--store",
        s,
        "analyze",
        "keep",
        "--report",
        catalog.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("inside the store"),
        "{}",
        stderr(&out)
    );
    // A file analysed onto itself.
    let csv = dir.path().join("x.csv");
    let out = run(&[
        "--store",
        s,
        "export",
        "keep",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let exported = std::fs::read(&csv).unwrap();
    let out = run(&[
        "analyze",
        csv.to_str().unwrap(),
        "--json",
        csv.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("own input"), "{}", stderr(&out));
    assert_eq!(std::fs::read(&csv).unwrap(), exported);
    assert_eq!(std::fs::read(&raw).unwrap(), before);
}

/// Values that start with '-' are values: `--rate -100` is a rate, refused as one (exit 1,
/// not a usage error), and `--position -x=FILE` names the position -x.
#[test]
fn hyphen_values_are_values() {
    let dir = scratch();
    let store = dir.path().join("store");
    let store = store.to_str().unwrap();
    let model = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/mpu6050.toml");
    let out_csv = dir.path().join("x.csv");
    let rate = ["--rate", "-100", "--bandwidth", "42"];
    let runs: [Vec<&str>; 3] = [
        ["settings"].iter().chain(&rate).copied().collect(),
        ["--store", store, "capture", "--port", "sim"]
            .iter()
            .chain(&rate)
            .copied()
            .collect(),
        ["simulate", "--model", model, "--duration", "1s", "--out"]
            .iter()
            .copied()
            .chain([out_csv.to_str().unwrap()])
            .chain(rate)
            .collect(),
    ];
    for args in runs {
        let out = run(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("the output rate must be a positive number of Hz, not -100"),
            "{args:?}: {}",
            stderr(&out)
        );
    }
    assert!(!Path::new(store).exists() && !out_csv.exists());
    let positions: Vec<String> = ["+x", "-x", "+y", "-y", "+z", "-z"]
        .iter()
        .map(|p| format!("{p}=/nowhere/{p}.csv"))
        .collect();
    let mut args = vec!["--store", store, "calibrate", "accel"];
    for p in &positions {
        args.extend(["--position", p]);
    }
    let out = run(&args);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("/nowhere/+x.csv: no such file"),
        "{}",
        stderr(&out)
    );
}

/// The sensor can be set to 2 kHz (`settings` resolves it), the board's firmware does not
/// stream it: `capture` says so, naming the firmware's limit, before it opens anything.
#[test]
fn capture_names_the_firmwares_rate_limit() {
    let dir = scratch();
    let store = dir.path().join("store");
    let store = store.to_str().unwrap();
    let fast = ["--rate", "2000", "--bandwidth", "256"];
    let out = run(&["settings", fast[0], fast[1], fast[2], fast[3]]);
    assert!(
        stdout(&out).contains("2000 Hz output (SMPLRT_DIV 3)"),
        "{}",
        stdout(&out)
    );
    let mut args = vec!["--store", store, "capture", "--port", "sim"];
    args.extend(fast);
    let out = run(&args);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains(&format!(
            "--rate 2000: 2000 Hz is above the board firmware's output-rate limit of {} Hz",
            firmware::acquire::MAX_RATE_HZ
        )),
        "{}",
        stderr(&out)
    );
    assert!(!Path::new(store).exists());
    let out = run(&[
        "--store",
        store,
        "sweep",
        "--port",
        "sim",
        "--settings",
        "2000:256",
    ]);
    assert!(
        stderr(&out).contains("--settings 2000:256: 2000 Hz is above"),
        "{}",
        stderr(&out)
    );
}

/// `info --json` gives what a JSON reader takes as it is: the 64-bit board id as a hex string
/// (as a number it would lose its last digits above 2^53), the settings as numbers with
/// their units in the key names.
#[test]
fn info_json_has_a_hex_board_id_and_numeric_ranges() {
    let out = run(&["info", "--port", "sim", "--seed", "5", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let info = &v["info"];
    // The virtual board's id is "SIM" in ASCII, then its seed.
    assert_eq!(info["board_id"], "0x53494d0000000005");
    assert_eq!(info["firmware_version"], "0.1.0");
    assert_eq!(info["rate_hz"], 100.0);
    assert_eq!(info["gyro_bandwidth_hz"], 42.0);
    assert_eq!(info["gyro_range_dps"], 250.0);
    assert_eq!(info["accel_range_g"], 2.0);
    assert_eq!(info["chip"], "MPU-6050");
    assert_eq!(v["status"]["samples_lost"], 0);
}

/// The help, the README and the guide say what the program does, not when it did what (none
/// of the timeline phrases listed below); simulate names every format it writes; every sweep
/// of the virtual board in the docs runs at `--speed max` (else it takes hours).
#[test]
fn help_and_docs_say_what_is() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut docs = vec![root.join("README.md")];
    let mut guide: Vec<_> = std::fs::read_dir(root.join("docs/guide"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "md"))
        .collect();
    guide.sort();
    assert!(guide.len() >= 8, "{guide:?}");
    docs.extend(guide);
    let mut texts: Vec<(String, String)> = docs
        .iter()
        .map(|path| {
            let text = std::fs::read_to_string(path).unwrap();
            (path.display().to_string(), text)
        })
        .collect();
    let doc_count = texts.len();
    for command in ["", "demo", "simulate", "capture", "sweep"] {
        let args: Vec<&str> = [command, "--help"]
            .into_iter()
            .filter(|a| !a.is_empty())
            .collect();
        let out = run(&args);
        assert!(out.status.success());
        texts.push((format!("imunoise {command} --help"), stdout(&out)));
    }
    for (name, text) in &texts {
        for stale in ["now:", "comes next", "next issue", "works today"] {
            assert!(!text.contains(stale), "{name} says '{stale}'");
        }
    }
    let top = &texts[doc_count].1;
    let simulate = top
        .lines()
        .find(|l| l.trim_start().starts_with("simulate"))
        .unwrap();
    assert!(
        simulate.contains("CSV, or the bytes a board would send"),
        "{simulate}"
    );
    for (name, text) in &texts[..doc_count] {
        for line in text.lines().filter(|l| l.contains("imunoise sweep --port")) {
            assert!(line.contains("--speed max"), "{name}: {line}");
        }
    }
}

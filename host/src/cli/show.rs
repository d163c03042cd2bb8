//! `imunoise show ID`: everything the store knows about a session: metadata, counts, the
//! losses with their gap list (from the raw file), the stored analyses.

use crate::cli::sessions::{duration, rate_bandwidth};
use crate::cli::stored::read_store;
use anyhow::Result;
use imunoise::capture::{BoardReport, Capture, RecoveryReport, Segment, SensorCapture};
use imunoise::store::{Analysis, Kind, Session, State};
use serde_json::json;
use std::fmt::Write;
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct ShowArgs {
    /// The session's id or name
    pub session: String,
    /// Print as JSON (with the stored analysis documents in full)
    #[arg(long)]
    pub json: bool,
}

/// Gaps listed in the human output; JSON lists all.
const GAPS_SHOWN: usize = 20;

pub fn run(args: &ShowArgs, store: Option<&Path>) -> Result<()> {
    let store = read_store(store)?;
    let session = store.find(&args.session)?;
    let analyses = store.analyses(session.id)?;
    let losses = Losses::of(&session);
    if args.json {
        let doc = json!({
            "session": session,
            "losses": losses,
            "interruption": interruption(&session),
            "analyses": analyses,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print!("{}", text(&session, &losses, &analyses));
    }
    Ok(())
}

/// Losses as decoded from the raw file (the truth, also for a session still recording).
/// The index lists are sensor 0's (the whole board's on a one-sensor board); a board with
/// several sensors lists the others' in `other_sensors`.
#[derive(serde::Serialize, Default)]
struct Losses {
    /// Half-open ranges of lost sample indices.
    gaps: Vec<(u64, u64)>,
    /// Indices at which the board restarted.
    restarts: Vec<u64>,
    /// Bytes of an unfinished last frame.
    trailing_bytes: usize,
    /// Commands the board refused and faults it reported.
    board_errors: Vec<BoardReport>,
    /// Faults the board recovered from by itself, where samples resumed.
    recoveries: Vec<RecoveryReport>,
    /// Board restarts the capture bridged, with the silence measured on the host clock.
    segments: Vec<Segment>,
    /// Device frames missing by the board's frame numbers (damaged or lost whole).
    frames_missing: u64,
    /// The gaps of every sensor past the first (their indices are their own).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    other_sensors: Vec<SensorGaps>,
    error: Option<String>,
}

/// One sensor's gaps.
#[derive(serde::Serialize)]
struct SensorGaps {
    sensor: usize,
    kind: String,
    gaps: Vec<(u64, u64)>,
}

fn gap_list(sensor: &SensorCapture) -> Vec<(u64, u64)> {
    sensor.gaps().iter().map(|g| (g.start, g.end)).collect()
}

impl Losses {
    fn of(session: &Session) -> Losses {
        if session.kind != Kind::Capture {
            return Losses::default();
        }
        let decoded = std::fs::read(&session.file)
            .map_err(|e| format!("{}: {e}", session.file.display()))
            .and_then(|b| Capture::decode(&b).map_err(|e| e.to_string()));
        match decoded {
            Ok(c) => Losses {
                gaps: gap_list(c.first()),
                restarts: c.first().restarts.clone(),
                trailing_bytes: c.trailing_bytes,
                board_errors: c.board_errors.clone(),
                recoveries: c.recoveries().copied().collect(),
                segments: c.first().segments.clone(),
                frames_missing: c.frames_missing,
                other_sensors: c
                    .sensors
                    .iter()
                    .enumerate()
                    .skip(1)
                    .map(|(k, s)| SensorGaps {
                        sensor: k,
                        kind: s.sensor.kind.to_string(),
                        gaps: gap_list(s),
                    })
                    .collect(),
                error: None,
            },
            Err(e) => Losses {
                error: Some(e),
                ..Losses::default()
            },
        }
    }
}

/// What an interrupted recording may have lost, in words.
fn interruption(s: &Session) -> Option<String> {
    (s.state == State::Incomplete && s.end_reason.as_deref() == Some("interrupted")).then(|| {
        format!(
            "the recorder stopped without closing the session (killed, crashed or power lost) at about {}; bytes received in the last {} s before that may not have reached the disk",
            s.ended_at.as_deref().unwrap_or("an unknown time"),
            imunoise::store::SYNC_INTERVAL.as_secs_f64() * 2.0
        )
    })
}

fn text(s: &Session, losses: &Losses, analyses: &[Analysis]) -> String {
    let mut o = String::new();
    let mut kv = |k: &str, v: String| {
        let _ = writeln!(o, "{k:<22} {v}");
    };
    kv("id", s.id.to_string());
    kv("name", s.name.clone());
    kv("kind", format!("{:?}", s.kind).to_lowercase());
    kv("state", s.state_text());
    kv("file", s.file.display().to_string());
    kv("start (UTC)", s.started_at.clone());
    kv("end (UTC)", s.ended_at.clone().unwrap_or("-".into()));
    kv(
        "duration",
        s.duration_s.map_or("-".into(), |d| {
            format!("{} (samples received and lost / rate)", duration(d))
        }),
    );
    kv(
        "wall time",
        s.wall_s
            .map_or("-".into(), |w| format!("{} (start to end)", duration(w))),
    );
    kv("rate/bandwidth", rate_bandwidth(s));
    if let Some(b) = &s.board {
        kv("board id", b.board_id.clone());
        kv("firmware", b.firmware_version.clone());
        kv("protocol version", b.protocol_version.to_string());
        kv("DLPF_CFG", b.dlpf_cfg.to_string());
        kv("SMPLRT_DIV", b.smplrt_div.to_string());
        kv("gyro range", format!("{} deg/s", b.gyro_range_dps));
        kv("accel range", format!("{} g", b.accel_range_g));
    }
    if let Some(src) = &s.import_source {
        kv("imported from", src.clone());
    }
    let c = &s.counts;
    kv("bytes", c.bytes.to_string());
    kv("samples received", c.samples_received.to_string());
    kv(
        "samples lost",
        format!("{} in {} gap(s)", c.samples_lost, c.gaps),
    );
    if s.kind == Kind::Capture {
        kv("board restarts", c.restarts.to_string());
        kv("out-of-order batches", c.out_of_order_batches.to_string());
        kv(
            "frames",
            format!(
                "{} ok, {} rejected ({} bytes discarded)",
                c.frames_ok, c.frames_rejected, c.bytes_discarded
            ),
        );
    }
    if let Some(b) = &c.board_status {
        kv(
            "board counters",
            format!(
                "{} (last report; since the board's power-up)",
                board_counters(b)
            ),
        );
    }
    if let Some(n) = &s.notes {
        kv("notes", n.clone());
    }
    if let Some(i) = interruption(s) {
        kv("interrupted", i);
    }
    if let Some(e) = &losses.error {
        kv("decoding the file", e.clone());
    }
    if losses.frames_missing > 0 {
        kv(
            "frames missing",
            format!(
                "{} by the board's frame numbers (damaged on the line or lost whole; a lost Status, Fault or Recovered among them)",
                losses.frames_missing
            ),
        );
    }
    if losses.trailing_bytes > 0 {
        kv(
            "unfinished last frame",
            format!("{} bytes", losses.trailing_bytes),
        );
    }
    for e in &losses.board_errors {
        kv("board error", e.to_string());
    }
    for r in &losses.recoveries {
        kv("recovery", r.to_string());
    }
    for g in &losses.segments {
        kv(
            "board restart",
            format!(
                "silent {:.2} s on the host clock; {} samples counted lost; streaming resumed at index {}",
                g.silent_s, g.samples_lost, g.first_index
            ),
        );
    }
    for (start, end) in losses.gaps.iter().take(GAPS_SHOWN) {
        kv(
            "gap",
            format!("{} samples lost at index {start}", end - start),
        );
    }
    if losses.gaps.len() > GAPS_SHOWN {
        kv(
            "gap",
            format!(
                "... and {} more (--json lists all)",
                losses.gaps.len() - GAPS_SHOWN
            ),
        );
    }
    for other in &losses.other_sensors {
        for (start, end) in other.gaps.iter().take(GAPS_SHOWN) {
            kv(
                "gap",
                format!(
                    "sensor {} ({}): {} samples lost at index {start}",
                    other.sensor,
                    other.kind,
                    end - start
                ),
            );
        }
        if other.gaps.len() > GAPS_SHOWN {
            kv(
                "gap",
                format!(
                    "sensor {}: ... and {} more (--json lists all)",
                    other.sensor,
                    other.gaps.len() - GAPS_SHOWN
                ),
            );
        }
    }
    for r in &losses.restarts {
        kv("restart", format!("the board restarted at index {r}"));
    }
    for a in analyses {
        kv(
            "analysis",
            format!(
                "{} at {}: imunoise {}",
                a.id,
                a.created_at,
                command(&a.options["command"])
            ),
        );
    }
    o
}

/// A stored analysis's command line as text: its arguments (a list), or the bare command
/// name older stores kept.
fn command(stored: &serde_json::Value) -> String {
    match stored {
        serde_json::Value::Array(args) => args
            .iter()
            .filter_map(|x| x.as_str())
            .collect::<Vec<_>>()
            .join(" "),
        serde_json::Value::String(name) => name.clone(),
        _ => String::new(),
    }
}

/// A board's cumulative counters (its Status) in one line.
pub fn board_counters(b: &protocol::Status) -> String {
    format!(
        "{} acquired, {} lost ({} FIFO overflows; loss count {}), {} dropped in {} batches, {} I2C errors, {} recoveries, {} host frames rejected, {} replies dropped{}",
        b.samples_acquired,
        b.samples_lost,
        b.fifo_overflows,
        if b.loss_certain { "exact" } else { "estimated" },
        b.samples_dropped,
        b.batches_dropped,
        b.i2c_errors,
        b.recoveries,
        b.frames_rejected,
        b.replies_dropped,
        if b.sample_period_ns > 0 {
            format!(
                ", sensor sample period {:.3} us (measured)",
                f64::from(b.sample_period_ns) / 1e3
            )
        } else {
            String::new()
        }
    )
}

//! The capture loop: bytes from a [`Link`] go, exactly as received, into a session
//! ([`SessionWriter`]) and through the same [`StreamDecoder`] a replay uses, which counts
//! samples and losses live. It ends when the source ends, the duration is reached, the user
//! stops it (Ctrl-C: `complete`), or the link fails (`incomplete`, with the reason).

pub mod live;

use crate::analysis::live::Snapshot;
use crate::capture::{BoardReport, Capture, RecoveryReport, StreamDecoder};
use crate::link::Link;
use crate::link::keepalive::{Action, Keepalive};
use crate::link::plan::Plan;
use crate::store::{Counts, End, SessionWriter, Store, StoreError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long one read may wait: short, so the writer's one-second sync and a stop request are
/// served promptly even on a silent link.
const READ_TIMEOUT: Duration = Duration::from_millis(100);
/// A watched capture also ends when the host's clock passes the duration by this fraction
/// (the sensor's clock may be that much slow) plus [`OVERTIME_GRACE_S`], and no sample has
/// been accounted for during the last [`OVERTIME_GRACE_S`]: a board that is merely slower
/// than the host's clock (an emulated one on a loaded machine) still streams, and runs on.
const OVERTIME: f64 = 0.05;
const OVERTIME_GRACE_S: f64 = 60.0;

#[derive(Debug, Clone, Default)]
pub struct RecordOptions {
    pub name: Option<String>,
    pub notes: Option<String>,
    /// Stop after this much sample time (samples numbered by the board / rate).
    pub duration_s: Option<f64>,
    /// Keep the decoded samples in memory and return them (tests, analysing right after);
    /// a long capture needs only the counts, its samples are in its file.
    pub keep_samples: bool,
    /// The settings a live board was started with: the loop then watches it and, if it
    /// restarts, sets them again and starts it ([`crate::link::keepalive`]). `None` for a
    /// replayed file.
    pub watch: Option<Plan>,
    /// The live view (snapshots in the progress reports) and the stop rule.
    pub live: Option<live::LiveOptions>,
}

/// Why a capture ended.
#[derive(Debug)]
pub enum Ending {
    /// The source had nothing more (a replayed file).
    SourceEnded,
    DurationReached,
    /// The stop rule was met on every gyro axis.
    RuleMet(live::RuleMet),
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
    /// The first failure to update the catalog, once: the recording goes on, since the
    /// catalog only describes the raw file and is brought up to date at the end.
    pub catalog_warning: Option<String>,
    /// The live view's snapshot, when one is due ([`RecordOptions::live`]).
    pub live: Option<Snapshot>,
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
    /// The store failed and the catalog could not even record the end: the session will be
    /// shown as interrupted, with what reached its file.
    #[error(
        "session {session}: {source}; closing it in the catalog failed too ({closing}): it will be listed as interrupted, with what was written before"
    )]
    Unclosed {
        session: i64,
        source: StoreError,
        closing: Box<StoreError>,
    },
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
    let mut catalog_warning = None;
    let started_us = link.clock_us();
    let mut keepalive = options
        .watch
        .clone()
        .map(|plan| Keepalive::new(plan, started_us));
    let mut board_errors_shown = 0;
    let mut recoveries_shown = 0;
    let mut watcher = options.live.clone().map(live::Watcher::new);
    if watcher.is_some() {
        decoder.tap();
    }
    // The last snapshot's precision, for the end reason when the duration comes first.
    let mut last_snapshot: Option<Snapshot> = None;
    // The host's clock when the samples accounted for last grew.
    let (mut accounted, mut accounted_at_us) = (0u64, started_us);
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
        decoder.feed(chunk);
        // Until the catalog has taken the board's metadata (it may have failed once).
        if let Some(info) = decoder.info_seen().copied()
            && let Err(e) = writer.set_board(&info)
        {
            warn_catalog(&mut catalog_warned, &mut catalog_warning, &e);
        }
        if let Some(k) = keepalive.as_mut() {
            match k.after_read(n, link.clock_us(), decoder, link) {
                Ok(Action::Nothing) => {}
                Ok(Action::Note(note)) => {
                    if let Err(source) = record_note(&mut writer, decoder, &note) {
                        return Err(fail(writer, decoder, source));
                    }
                }
                Err(e) => break Ending::LinkFailed(e),
            }
        }
        let counts = Counts::of(decoder, writer.bytes());
        match writer.tick(&counts) {
            Err(source @ StoreError::Io { .. }) => return Err(fail(writer, decoder, source)),
            Err(e) => warn_catalog(&mut catalog_warned, &mut catalog_warning, &e),
            Ok(()) => {}
        }
        let rate_hz = decoder.rate_hz();
        let wanted = options
            .duration_s
            .zip(rate_hz)
            .map(|(d, r)| (d * r).round() as u64);
        let expected = decoder.accounting().expected();
        if expected > accounted {
            (accounted, accounted_at_us) = (expected, link.clock_us());
        }
        let new_board_errors = decoder.board_errors()[board_errors_shown..].to_vec();
        board_errors_shown += new_board_errors.len();
        let new_recoveries = decoder.recoveries()[recoveries_shown..].to_vec();
        recoveries_shown += new_recoveries.len();
        let snapshot = watcher.as_mut().and_then(|w| w.after_feed(decoder));
        let met = match (watcher.as_mut(), &snapshot) {
            (Some(w), Some(s)) if w.wants_confirmation(s) => {
                if let Err(source) = writer.flush() {
                    return Err(fail(writer, decoder, source));
                }
                w.confirm(s, writer.path())
            }
            _ => None,
        };
        let mut report = Progress {
            elapsed: started.elapsed(),
            counts,
            samples_expected: expected,
            samples_wanted: wanted,
            rate_hz,
            new_board_errors,
            new_recoveries,
            catalog_warning: catalog_warning.take(),
            live: snapshot,
        };
        progress(&report);
        if report.live.is_some() {
            last_snapshot = report.live.take();
        }
        if let Some(met) = met {
            break Ending::RuleMet(met);
        }
        if options.duration_s.is_some_and(|d| decoder.covers(d)) {
            break Ending::DurationReached;
        }
        // A board that brings nothing (its sensor gone for good) must not hold the capture
        // past its time: on the host's clock, the duration plus the sensor clock's tolerance
        // and a minute, with a minute of nothing, ends it too (the silence is counted lost).
        let now_us = link.clock_us();
        let grace_us = OVERTIME_GRACE_S * 1e6;
        if keepalive.is_some()
            && now_us.saturating_sub(accounted_at_us) as f64 >= grace_us
            && options.duration_s.is_some_and(|d| {
                let limit_us = d * (1.0 + OVERTIME) * 1e6 + grace_us;
                now_us.saturating_sub(started_us) as f64 >= limit_us
            })
        {
            break Ending::DurationReached;
        }
    };
    if let Some(note) = keepalive
        .as_ref()
        .and_then(|k| k.closing_note(link.clock_us(), decoder))
        && let Err(source) = record_note(&mut writer, decoder, &note)
    {
        return Err(fail(writer, decoder, source));
    }
    decoder.settle();
    let counts = Counts::of(decoder, writer.bytes());
    let end = match &ending {
        Ending::LinkFailed(e) => End::Incomplete(format!("link error on {}: {e}", link.describe())),
        Ending::Stopped => End::Stopped,
        Ending::RuleMet(met) => End::CompleteBecause(met.describe()),
        Ending::DurationReached => match options.live.as_ref().and_then(|l| l.rule.as_ref()) {
            Some(rule) => End::CompleteBecause(live::unmet(rule, last_snapshot.as_ref())),
            None => End::Complete,
        },
        Ending::SourceEnded => End::Complete,
    };
    let session = writer.id();
    writer
        .finish(end, &counts)
        .map_err(|source| RecordError::Store { session, source })?;
    Ok((ending, counts))
}

/// A host note into the session and through the decoder, like the board's frames.
fn record_note(
    writer: &mut SessionWriter,
    decoder: &mut StreamDecoder,
    note: &[u8],
) -> Result<(), StoreError> {
    writer.write(note)?;
    decoder.feed(note);
    Ok(())
}

/// A disk error: close the session as incomplete (keeping what reached the disk) and say so.
fn fail(writer: SessionWriter, decoder: &StreamDecoder, source: StoreError) -> RecordError {
    let session = writer.id();
    let counts = Counts::of(decoder, writer.bytes());
    match writer.write_failed(&source, &counts) {
        Err(closing @ StoreError::Sql { .. }) => RecordError::Unclosed {
            session,
            source,
            closing: Box::new(closing),
        },
        _ => RecordError::Store { session, source },
    }
}

/// The catalog is only a description of the raw file: a failure to update it must not stop
/// the recording (the counts are recomputed from the file when needed). Say so once, in the
/// next progress report.
fn warn_catalog(warned: &mut bool, pending: &mut Option<String>, error: &StoreError) {
    if !*warned {
        *pending = Some(format!(
            "{error}; recording goes on (the catalog is updated at the end)"
        ));
        *warned = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::board::Board;
    use crate::link::virtual_board::{Speed, VirtualBoard};
    use crate::sim::device::{Outage, SensorClock};
    use crate::sim::model_file::{self, FaultPlan};
    use protocol::SensorSettings;

    /// A watched capture of `duration_s` into `store`.
    fn watched(
        board: &mut VirtualBoard,
        store: &Store,
        settings: SensorSettings,
        duration_s: f64,
    ) -> Outcome {
        let options = RecordOptions {
            duration_s: Some(duration_s),
            keep_samples: true,
            watch: Some(Plan::mpu6050(settings)),
            ..RecordOptions::default()
        };
        let stop = AtomicBool::new(false);
        record(board, store, &options, &stop, &mut |_| {}).unwrap()
    }

    /// A catalog that refuses updates while a capture runs: the recording goes on to its
    /// end, and the failure reaches the caller once, in a progress report; the library
    /// itself prints nothing.
    #[test]
    fn a_catalog_failure_is_reported_once_and_the_recording_goes_on() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let blocker = rusqlite::Connection::open(dir.path().join("catalog.sqlite")).unwrap();
        blocker
            .execute_batch(
                "CREATE TRIGGER block BEFORE UPDATE OF board_id ON sessions \
                 BEGIN SELECT RAISE(ABORT, 'blocked by the test'); END;",
            )
            .unwrap();
        let mut board = started(3);
        let options = RecordOptions {
            duration_s: Some(30.0),
            ..RecordOptions::default()
        };
        let mut warnings = Vec::new();
        let outcome = record(
            &mut board,
            &store,
            &options,
            &AtomicBool::new(false),
            &mut |p| {
                if let Some(w) = &p.catalog_warning {
                    warnings.push(w.clone());
                    // The catalog recovers, so the session can be closed at the end.
                    blocker.execute_batch("DROP TRIGGER block;").unwrap();
                }
            },
        )
        .unwrap();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("blocked by the test")
                && warnings[0].contains("recording goes on"),
            "{}",
            warnings[0]
        );
        assert!(matches!(outcome.ending, Ending::DurationReached));
        assert_eq!(outcome.counts.samples_received, 6000);
        // The board's metadata, refused once, was written when the catalog came back.
        let session = store.get(outcome.session_id).unwrap().unwrap();
        assert_eq!(session.board.map(|b| b.rate_hz), Some(200.0));
    }

    /// The unattended night in ten minutes: a sensor clock 3000 ppm fast, a 2 s I2C outage at
    /// 120 s, a sensor reset at 300 s, a board reboot at 420 s, a clone chip. The capture
    /// must run to its end, and every sample the sensor made must be received or counted
    /// lost.
    #[test]
    fn a_capture_rides_through_outage_sensor_reset_and_board_reboot() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let s = |x: f64| (x * 1e6) as u64;
        let plan = FaultPlan {
            clock: SensorClock {
                ppm: 3000.0,
                drift_ppm_per_hour: 0.0,
            },
            i2c_outages: vec![Outage {
                at_us: s(120.0),
                for_us: s(2.0),
            }],
            sensor_resets_us: vec![s(300.0)],
            board_resets_us: vec![s(420.0)],
            who_am_i: Some(0x70),
        };
        let mut board = VirtualBoard::with_faults(model_file::example(), 3, 1, Speed::Max, &plan);
        let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        {
            let mut b = Board::new(&mut board);
            assert_eq!(b.handshake().unwrap().who_am_i, 0x70);
            b.configure(settings).unwrap();
            b.begin_stream().unwrap();
        }
        let made_at_start = board.sensor().lock().samples_made();
        let outcome = watched(&mut board, &store, settings, 600.0);
        assert!(matches!(outcome.ending, Ending::DurationReached));
        assert_eq!(board.reboots(), 1);
        let capture = outcome.capture.unwrap();
        let rate = settings.output_rate_hz();
        // Every loss is a gap at its own fault, none longer than the budget: the
        // outage plus a second, two seconds per reset.
        let gaps = capture.first().gaps().to_vec();
        assert_eq!(gaps.len(), 3, "{gaps:?}");
        let at = |t: f64| t * rate * 1.003;
        for (gap, (t, budget_s)) in gaps.iter().zip([(120.0, 3.0), (300.0, 2.0), (420.0, 2.0)]) {
            assert!(
                (gap.start as f64 - at(t)).abs() < rate,
                "gap {gap:?} is not at {t} s"
            );
            assert!(
                ((gap.end - gap.start) as f64) <= rate * budget_s,
                "gap {gap:?} costs more than {budget_s} s"
            );
        }
        assert_eq!(capture.first().recoveries.len(), 2);
        assert_eq!(capture.first().segments.len(), 1);
        assert!(capture.first().restarts.is_empty());
        // Received + lost against what the sensor made up to the last sample received (the
        // FIFO's unread tail aside): equal within the reboot's estimate, a few samples.
        let made = board.sensor().lock().samples_made() - made_at_start;
        let accounted = capture.first().accounting.expected();
        let unread = made.saturating_sub(accounted);
        assert!(unread < 64, "made {made}, accounted for {accounted}");
        assert!(accounted as f64 >= 600.0 * rate);
        // The clone's temperature is read on its own scale: the example model warms from
        // 25 degC by up to 6 degC (on the MPU-6050's scale it would read 15 degC high).
        let record = capture.run_record(capture.first(), &capture.first().runs[0], "faults");
        let temp = &record.channel("temp").unwrap().values;
        let mean = temp.iter().sum::<f64>() / temp.len() as f64;
        assert!((25.0..31.5).contains(&mean), "{mean} degC");
        let session = store.get(outcome.session_id).unwrap().unwrap();
        assert_eq!(
            session.counts.samples_lost,
            capture.first().accounting.lost()
        );
    }

    /// A sensor that never comes back: the board gives up after ten minutes, the watcher
    /// keeps trying, and the capture still ends at its time with the dead tail counted lost.
    #[test]
    fn a_sensor_gone_for_good_ends_the_capture_at_its_time_with_the_loss_counted() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let plan = FaultPlan {
            i2c_outages: vec![Outage {
                at_us: 60_000_000,
                for_us: u64::MAX / 2,
            }],
            ..FaultPlan::default()
        };
        let mut board = VirtualBoard::with_faults(model_file::example(), 4, 1, Speed::Max, &plan);
        let settings = SensorSettings::for_rate_and_bandwidth(50.0, 42.0).unwrap();
        {
            let mut b = Board::new(&mut board);
            b.handshake().unwrap();
            b.configure(settings).unwrap();
            b.begin_stream().unwrap();
        }
        let start_us = board.time_us();
        let outcome = watched(&mut board, &store, settings, 720.0);
        assert!(matches!(outcome.ending, Ending::DurationReached));
        let span_s = (board.time_us() - start_us) as f64 * 1e-6;
        assert!((816.0..830.0).contains(&span_s), "ended after {span_s} s");
        let capture = outcome.capture.unwrap();
        let rate = settings.output_rate_hz();
        let (received, lost) = (
            capture.first().accounting.received(),
            capture.first().accounting.lost(),
        );
        assert!(((received as f64) - 60.0 * rate).abs() < rate, "{received}");
        // Received + lost is the whole time on the host's clock, within a second.
        let accounted = (received + lost) as f64;
        assert!(
            (accounted - span_s * rate).abs() < rate,
            "{accounted} for {span_s} s"
        );
        assert!(
            capture
                .board_errors
                .iter()
                .any(|e| matches!(e.error, protocol::ErrorCode::GaveUp { .. }))
        );
        let session = store.get(outcome.session_id).unwrap().unwrap();
        assert_eq!(session.counts.samples_lost, lost);
    }

    /// The host's clock beside a board ten times slower than real time (an emulated board
    /// on a loaded machine): the board keeps streaming, so the capture runs to its samples
    /// however long the host waits.
    struct SlowBoard<'a>(&'a mut VirtualBoard);

    impl Link for SlowBoard<'_> {
        fn read(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
            Ok(self.0.read(buf, timeout))
        }
        fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
            Link::write_all(self.0, bytes)
        }
        fn describe(&self) -> String {
            "a slow board".into()
        }
        fn clock_us(&self) -> u64 {
            self.0.time_us() * 10
        }
    }

    #[test]
    fn a_board_slower_than_the_hosts_clock_is_captured_to_its_duration() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let mut board = started(5);
        let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        let options = RecordOptions {
            duration_s: Some(10.0),
            keep_samples: true,
            watch: Some(Plan::mpu6050(settings)),
            ..RecordOptions::default()
        };
        let outcome = record(
            &mut SlowBoard(&mut board),
            &store,
            &options,
            &AtomicBool::new(false),
            &mut |_| {},
        )
        .unwrap();
        assert!(matches!(outcome.ending, Ending::DurationReached));
        let capture = outcome.capture.unwrap();
        let accounting = &capture.first().accounting;
        assert_eq!(accounting.lost(), 0);
        assert!(accounting.received() >= 2000, "{}", accounting.received());
    }

    /// A virtual board (seed `seed`, full speed) streaming at 200 Hz / 42 Hz.
    fn started(seed: u64) -> VirtualBoard {
        let mut board = VirtualBoard::new(model_file::example(), seed, 1, Speed::Max).unwrap();
        let settings = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        let mut b = Board::new(&mut board);
        b.handshake().unwrap();
        b.configure(settings).unwrap();
        b.begin_stream().unwrap();
        board
    }

    /// The virtual board of [`started`] captured under `rule` with a cap of `cap_s`, into
    /// `store`; the snapshots seen.
    fn until(store: &Store, rule: &str, axes: &str, cap_s: f64) -> (Outcome, Vec<Snapshot>) {
        let mut board = started(11);
        let options = RecordOptions {
            duration_s: Some(cap_s),
            live: Some(live::LiveOptions {
                rule: Some(rule.parse().unwrap()),
                rule_axes: axes.parse().unwrap(),
                confidence: 0.683,
                longest_s: cap_s,
            }),
            ..RecordOptions::default()
        };
        let mut snapshots = Vec::new();
        let outcome = record(
            &mut board,
            store,
            &options,
            &AtomicBool::new(false),
            &mut |p| snapshots.extend(p.live.clone()),
        )
        .unwrap();
        (outcome, snapshots)
    }

    /// The stop rule ends the capture well before its cap (at about 80 s of 3600), near the
    /// length the first snapshot (10 s of data, so N's precision itself is known to only
    /// about 15 %) expected; the session says why, and `analyze`'s pipeline on the
    /// stored file (decoded afresh) shows N on every gyro axis within the 1 % asked for.
    #[test]
    fn the_stop_rule_ends_a_capture_with_the_precision_asked_for() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let (outcome, snapshots) = until(&store, "N:1%", "gyro", 3600.0);
        let Ending::RuleMet(met) = &outcome.ending else {
            panic!("{:?}", outcome.ending)
        };
        assert_eq!(met.axes.len(), 3);
        let seconds = outcome.counts.samples_received as f64 / 200.0;
        assert!(seconds < 600.0, "{seconds} s");
        // The first snapshot's expectation for N, against the length the rule needed.
        let first = &snapshots[0];
        let expected = first.needed_s().unwrap();
        assert!(
            seconds <= expected * 2.0 && seconds >= expected / 2.0,
            "stopped at {seconds} s, expected about {expected} s at {} s",
            first.elapsed_s
        );
        let session = store.get(outcome.session_id).unwrap().unwrap();
        let reason = session.end_reason.unwrap();
        assert!(reason.starts_with("stop rule N:1% met (gx N "), "{reason}");
        assert_eq!(session.state.as_str(), "complete");
        let capture = Capture::decode(&std::fs::read(&session.file).unwrap()).unwrap();
        assert_n_within(&capture, &["gx", "gy", "gz"], 0.01);
    }

    /// `analyze`'s pipeline on the stored `capture` gives N on each of `axes` within
    /// `fraction` (interval half-width over value).
    fn assert_n_within(capture: &Capture, axes: &[&str], fraction: f64) {
        let record = capture.to_record("until", false).unwrap();
        let options = crate::analysis::pipeline::Options {
            low_pass: crate::analysis::pipeline::LowPassChoice::Sensor(
                capture.info.settings.into(),
            ),
            ..Default::default()
        };
        let results = crate::analysis::pipeline::analyze(&record, &options, &|| {}).unwrap();
        for r in results.iter().filter(|r| axes.contains(&r.name.as_str())) {
            let n = r.fit.as_ref().unwrap().n;
            let half = (n.hi - n.lo) / (2.0 * n.value);
            assert!(half <= fraction, "{}: N {n:?}, {half}", r.name);
        }
    }

    /// A rule on chosen axes (one gyro and one accel axis) is judged on those axes only:
    /// the session's reason names them, and `analyze` shows the precision there.
    #[test]
    fn the_stop_rule_applies_to_the_axes_chosen() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let (outcome, _) = until(&store, "N:2%", "gz,az", 3600.0);
        let Ending::RuleMet(met) = &outcome.ending else {
            panic!("{:?}", outcome.ending)
        };
        let names: Vec<&str> = met.axes.iter().map(|(a, _)| a.as_str()).collect();
        assert_eq!(names, ["gz", "az"]);
        let session = store.get(outcome.session_id).unwrap().unwrap();
        let reason = session.end_reason.unwrap();
        assert!(reason.starts_with("stop rule N:2% met (gz N "), "{reason}");
        assert!(
            reason.contains("; az N ") && !reason.contains("gx"),
            "{reason}"
        );
        let capture = Capture::decode(&std::fs::read(&session.file).unwrap()).unwrap();
        assert_n_within(&capture, &["gz", "az"], 0.02);
    }

    /// A rule the cap comes first for: the session is complete, and its reason says which
    /// precision was reached instead.
    #[test]
    fn a_cap_before_the_rule_says_what_was_reached() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let (outcome, snapshots) = until(&store, "N:0.01%", "gyro", 60.0);
        assert!(matches!(outcome.ending, Ending::DurationReached));
        assert!(!snapshots.is_empty());
        let session = store.get(outcome.session_id).unwrap().unwrap();
        let reason = session.end_reason.unwrap();
        assert!(
            reason.starts_with("duration reached before stop rule N:0.01% was met (gx N "),
            "{reason}"
        );
        assert!(reason.contains("; gz N "), "{reason}");
    }
}

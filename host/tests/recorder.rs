//! The capture loop against damaged transports: bit flips, dropped and duplicated bytes, a
//! board restart, a disconnect, a failing disk. Every intact batch must be kept, every
//! sample accounted for, nothing may panic, and a live capture must decode exactly as its
//! replay.

mod common;

use imunoise::capture::{Capture, CaptureWriter};
use imunoise::link::Link;
use imunoise::recorder::{self, Ending, RecordOptions};
use imunoise::store::{State, Store};
use protocol::{
    DeviceInfo, DeviceMessage, FirmwareVersion, PROTOCOL_VERSION, RawSample, SampleBatch,
    SensorSettings,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::HashSet;
use std::io;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Serves bytes in random chunks, then ends (or fails, like a pulled cable).
struct ChunkLink {
    bytes: Vec<u8>,
    pos: usize,
    rng: ChaCha8Rng,
    fail_at_end: bool,
}

impl Link for ChunkLink {
    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
        if self.pos >= self.bytes.len() && self.fail_at_end {
            return Err(io::Error::new(
                io::ErrorKind::BrokenPipe,
                "device unplugged",
            ));
        }
        let n = self
            .rng
            .random_range(1..=600usize)
            .min(buf.len())
            .min(self.bytes.len() - self.pos);
        buf[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
    fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn at_end(&self) -> bool {
        self.pos >= self.bytes.len() && !self.fail_at_end
    }
    fn describe(&self) -> String {
        "test link".into()
    }
}

fn link(bytes: Vec<u8>, fail_at_end: bool) -> ChunkLink {
    ChunkLink {
        bytes,
        pos: 0,
        rng: ChaCha8Rng::seed_from_u64(7),
        fail_at_end,
    }
}

fn info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 42,
        who_am_i: 0x68,
        settings: SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap(),
        streaming: true,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    }
}

/// A frame and, for a batch, the tags of its samples (gyro x: unique over the stream).
struct Frame {
    bytes: Vec<u8>,
    tags: Vec<i16>,
}

/// Info, `batches` batches of 32 from `start_tag`, timestamps from `t0_us`.
fn segment(batches: u64, start_tag: i16, t0_us: u64, rng: &mut ChaCha8Rng) -> Vec<Frame> {
    let mut frames = vec![frame(&DeviceMessage::Info(info()), vec![])];
    for b in 0..batches {
        let tags: Vec<i16> = (0..32).map(|i| start_tag + (b * 32 + i) as i16).collect();
        let samples = tags
            .iter()
            .map(|&t| RawSample {
                gyro: [t, rng.random(), rng.random()],
                accel: [rng.random(), rng.random(), 16384],
                temp: rng.random_range(-500..500),
            })
            .collect();
        let message = DeviceMessage::Samples(SampleBatch {
            first_index: b * 32,
            first_timestamp_us: t0_us + b * 32 * 5000,
            samples,
        });
        frames.push(frame(&message, tags));
    }
    frames
}

fn frame(m: &DeviceMessage, tags: Vec<i16>) -> Frame {
    let mut w = CaptureWriter::new(Vec::new());
    w.message(m).unwrap();
    Frame {
        bytes: w.into_inner(),
        tags,
    }
}

fn record(bytes: Vec<u8>, fail_at_end: bool) -> (tempfile::TempDir, Store, recorder::Outcome) {
    let dir = common::scratch();
    let store = Store::open(dir.path()).unwrap();
    let options = RecordOptions {
        keep_samples: true,
        ..RecordOptions::default()
    };
    let outcome = recorder::record(
        &mut link(bytes, fail_at_end),
        &store,
        &options,
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .unwrap();
    (dir, store, outcome)
}

#[test]
fn live_capture_decodes_exactly_as_its_replay() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let bytes: Vec<u8> = segment(300, 0, 0, &mut rng)
        .into_iter()
        .flat_map(|f| f.bytes)
        .collect();
    let (_dir, store, outcome) = record(bytes.clone(), false);
    assert!(matches!(outcome.ending, Ending::SourceEnded));
    let live = outcome.capture.unwrap().to_record("x", false).unwrap();
    let session = store.get(outcome.session_id).unwrap().unwrap();
    assert_eq!(session.state, State::Complete);
    let file = std::fs::read(&session.file).unwrap();
    assert_eq!(
        file, bytes,
        "the session file holds the bytes exactly as received"
    );
    let replayed = Capture::decode(&file)
        .unwrap()
        .to_record("x", false)
        .unwrap();
    assert_eq!(live, replayed);
    assert_eq!(live.len(), 300 * 32);
    assert_eq!(session.counts.samples_received, 300 * 32);
}

#[test]
fn damaged_transport_keeps_every_intact_batch_and_counts_every_loss() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    // Two segments: the board resets after 200 batches (new Info, indices from 0, clock anew).
    let mut frames = segment(200, 0, 3_000_000, &mut rng);
    frames.extend(segment(200, 6400, 1_000_000, &mut rng));
    let mut stream = Vec::new();
    let mut intact: HashSet<i16> = HashSet::new();
    let mut all = 0usize;
    for f in &frames {
        let mut touched = false;
        for &b in &f.bytes {
            match rng.random_range(0..100_000) {
                0..10 => {
                    stream.push(b ^ (1 << rng.random_range(0..8))); // bit flip, 1e-4
                    touched = true;
                }
                10..15 => touched = true, // dropped byte
                15..20 => {
                    stream.extend([b, b]); // duplicated byte
                    touched = true;
                }
                _ => stream.push(b),
            }
        }
        all += f.tags.len();
        if !touched {
            intact.extend(&f.tags);
        }
    }
    assert!(intact.len() < all, "the test must damage some batches");
    let (_dir, store, outcome) = record(stream, false);
    let c = outcome.capture.unwrap();
    let kept: HashSet<i16> = c
        .first()
        .runs
        .iter()
        .flat_map(|r| r.samples.iter().map(|s| s.gyro[0]))
        .collect();
    let missing: Vec<_> = intact.difference(&kept).collect();
    assert!(missing.is_empty(), "intact samples lost: {missing:?}");
    let a = &c.first().accounting;
    assert_eq!(a.received() + a.lost(), a.expected());
    assert_eq!(c.first().restarts.len(), 1, "the board reset is recorded");
    assert!(c.decoder.rejected() > 0);
    let session = store.get(outcome.session_id).unwrap().unwrap();
    assert_eq!(session.counts.restarts, 1);
    assert_eq!(session.counts.samples_lost, a.lost());
    assert_eq!(session.counts.frames_rejected, c.decoder.rejected());
}

#[test]
fn a_disconnect_ends_the_session_as_incomplete() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let bytes: Vec<u8> = segment(50, 0, 0, &mut rng)
        .into_iter()
        .flat_map(|f| f.bytes)
        .collect();
    let (_dir, store, outcome) = record(bytes.clone(), true);
    assert!(matches!(outcome.ending, Ending::LinkFailed(_)));
    let session = store.get(outcome.session_id).unwrap().unwrap();
    assert_eq!(session.state, State::Incomplete);
    assert!(
        session.state_text().contains("device unplugged"),
        "{}",
        session.state_text()
    );
    assert!(session.ended_at.is_some());
    assert_eq!(std::fs::read(&session.file).unwrap(), bytes);
    assert_eq!(session.counts.samples_received, 50 * 32);
}

/// A disk that takes `budget` bytes, then fails (ENOSPC).
struct FullDisk {
    file: std::fs::File,
    budget: usize,
}

impl io::Write for FullDisk {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.budget == 0 {
            return Err(io::Error::from_raw_os_error(28));
        }
        let n = buf.len().min(self.budget);
        self.budget -= n;
        self.file.write(&buf[..n])
    }
    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

impl imunoise::store::RawSink for FullDisk {
    fn sync(&mut self) -> io::Result<()> {
        self.file.sync_data()
    }
}

#[test]
fn a_failing_disk_is_an_error_naming_the_file_and_keeps_what_was_written() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let bytes: Vec<u8> = segment(2000, 0, 0, &mut rng)
        .into_iter()
        .flat_map(|f| f.bytes)
        .collect();
    let dir = common::scratch();
    let store = Store::open(dir.path()).unwrap();
    let writer = store.begin_capture(Some("full"), None).unwrap();
    // Room to close the session when the disk is full, held while it records.
    let reserve = dir.path().join(".reserve-1");
    assert_eq!(
        std::fs::metadata(&reserve).unwrap().len(),
        imunoise::store::RESERVE_BYTES as u64
    );
    let file = std::fs::OpenOptions::new()
        .append(true)
        .open(writer.path())
        .unwrap();
    let writer = writer.with_sink(Box::new(FullDisk {
        file,
        budget: 100_000,
    }));
    let err = recorder::record_into(
        &mut link(bytes.clone(), false),
        writer,
        &RecordOptions::default(),
        &AtomicBool::new(false),
        &mut |_| {},
    )
    .err()
    .expect("the disk fills up");
    let text = err.to_string();
    assert!(
        text.contains("1.imucap") && text.contains("space"),
        "{text}"
    );
    let session = store.find("full").unwrap();
    assert_eq!(session.state, State::Incomplete);
    assert_eq!(
        session.end_reason.as_deref(),
        Some("write failed: No space left on device (os error 28)")
    );
    assert!(!reserve.exists(), "released for the closing");
    let kept = std::fs::read(&session.file).unwrap();
    assert_eq!(kept.len(), 100_000);
    assert_eq!(
        kept,
        bytes[..100_000],
        "everything written before the failure is kept"
    );
    let c = Capture::decode(&kept).unwrap();
    assert!(c.first().accounting.received() > 0);
}

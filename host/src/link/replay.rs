//! A [`Link`] serving the bytes of an existing capture file, as fast as asked (`max`) or
//! paced by the board's own sample timestamps at a speed factor (1 = real time), so a
//! capture loop can be exercised, and killed mid-way, without a board.

use super::transport::Link;
use protocol::DeviceMessage;
use protocol::frame::FrameDecoder;
use std::io;
use std::path::Path;
use std::time::{Duration, Instant};

pub use super::transport::Speed;

pub struct ReplayLink {
    bytes: Vec<u8>,
    pos: usize,
    /// For paced replay: (end offset of a frame, board time of its samples in µs relative
    /// to the first batch), in file order; bytes up to an offset are due at its time.
    schedule: Vec<(usize, u64)>,
    speed: Speed,
    started: Option<Instant>,
    source: String,
}

impl ReplayLink {
    pub fn open(path: &Path, speed: Speed) -> io::Result<ReplayLink> {
        let bytes = std::fs::read(path)?;
        Ok(ReplayLink::new(
            bytes,
            speed,
            format!("file {}", path.display()),
        ))
    }

    pub fn new(bytes: Vec<u8>, speed: Speed, source: String) -> ReplayLink {
        let schedule = match speed {
            Speed::Max => Vec::new(),
            Speed::Factor(_) => schedule(&bytes),
        };
        ReplayLink {
            bytes,
            pos: 0,
            schedule,
            speed,
            started: None,
            source,
        }
    }

    /// The end offset of the bytes due now, and when the next ones are due.
    fn due(&self, now: Instant) -> (usize, Option<Instant>) {
        let Speed::Factor(factor) = self.speed else {
            return (self.bytes.len(), None);
        };
        let started = self.started.unwrap_or(now);
        let board_us = (now - started).as_secs_f64() * 1e6 * factor;
        let k = self
            .schedule
            .partition_point(|&(_, t)| t as f64 <= board_us);
        let due = if k == self.schedule.len() {
            self.bytes.len()
        } else if k == 0 {
            0
        } else {
            self.schedule[k - 1].0
        };
        let next = self
            .schedule
            .get(k)
            .map(|&(_, t)| started + Duration::from_secs_f64(t as f64 / 1e6 / factor));
        (due, next)
    }
}

/// Frame ends with the timestamp of their samples; frames without samples (Info, Status,
/// damaged ones) go with the batch before them.
fn schedule(bytes: &[u8]) -> Vec<(usize, u64)> {
    let mut decoder = FrameDecoder::new();
    let mut out = Vec::new();
    let (mut first, mut last) = (None, 0u64);
    for (i, &b) in bytes.iter().enumerate() {
        let Some(frame) = decoder.push(b) else {
            continue;
        };
        if let Ok(body) = frame
            && let Ok(DeviceMessage::Samples(batch)) = postcard::from_bytes(body)
        {
            let t0 = *first.get_or_insert(batch.first_timestamp_us);
            last = batch.first_timestamp_us.saturating_sub(t0).max(last);
        }
        out.push((i + 1, last));
    }
    out
}

impl Link for ReplayLink {
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let now = Instant::now();
        self.started.get_or_insert(now);
        let deadline = now + timeout;
        loop {
            let now = Instant::now();
            let (due, next) = self.due(now);
            if due > self.pos {
                let n = (due - self.pos).min(buf.len());
                buf[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
                self.pos += n;
                return Ok(n);
            }
            let Some(next) = next.filter(|&t| t < deadline) else {
                std::thread::sleep(deadline.saturating_duration_since(now));
                return Ok(0);
            };
            std::thread::sleep(next.saturating_duration_since(now));
        }
    }

    /// A replay ignores commands: the file already holds what the board answered.
    fn write_all(&mut self, _bytes: &[u8]) -> io::Result<()> {
        Ok(())
    }

    fn at_end(&self) -> bool {
        self.pos >= self.bytes.len()
    }

    fn describe(&self) -> String {
        self.source.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn max_speed_serves_everything_in_order() {
        let data: Vec<u8> = (0..=255u8).cycle().take(10_000).collect();
        let mut link = ReplayLink::new(data.clone(), Speed::Max, "test".into());
        let mut got = Vec::new();
        let mut buf = [0u8; 777];
        while !link.at_end() {
            let n = link.read(&mut buf, Duration::from_millis(10)).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, data);
        assert_eq!("max".parse::<Speed>(), Ok(Speed::Max));
        assert_eq!("2.5".parse::<Speed>(), Ok(Speed::Factor(2.5)));
        assert!("0".parse::<Speed>().is_err());
    }
}

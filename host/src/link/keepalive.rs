//! Watching a streaming board so that a capture never waits forever.
//!
//! A board that restarts (watchdog, brown-out, a cable wiggle that resets it) comes back
//! silent: it streams again only when told. A capture left overnight must notice and carry
//! on. After [`SILENCE`] without a byte on the host's clock ([`Link::clock_us`]) the watcher
//! asks for the board's Status, and again after each further [`SILENCE`] without an
//! answer. A board that answers "streaming" is only quiet (it is bringing its sensor back,
//! and says so with Fault and Recovered messages); one that answers "not streaming" has
//! restarted: the watcher notes how long it was silent ([`HostNote::BoardRestarted`], written
//! among the frames so the loss is counted from the file alone), sets the session's
//! settings again and starts it. The replies go into the session like every other frame.
//!
//! Its commands use sequence numbers from [`FIRST_SEQ`] so they never match a reply the
//! capture's own commands wait for.

use super::Link;
use super::plan::Plan;
use crate::capture::{HostNote, StreamDecoder};
use protocol::frame::{self, MAX_WIRE_LEN};
use protocol::{Command, Request};
use std::time::Duration;

/// Silence after which the board is asked whether it still streams: longer than any gap a
/// streaming board leaves (a batch at least every 20 ms at every supported rate, a sample
/// every 256 ms at the lowest), shorter than the loss a restart may cost (2 s).
pub const SILENCE: Duration = Duration::from_millis(1000);
/// Longest wait between restarts that bring no samples (a board whose sensor is gone): the
/// wait doubles from [`SILENCE`] after each.
pub const MAX_SILENCE: Duration = Duration::from_secs(64);
/// First sequence number of the watcher's commands.
pub const FIRST_SEQ: u16 = 0xC000;

/// What the watcher does next.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Action {
    Nothing,
    /// Bytes to write into the session (a host note) before the commands.
    Note(Vec<u8>),
}

/// The watcher of one capture (module docs).
pub struct Keepalive {
    plan: Plan,
    last_heard_us: u64,
    /// When the Status was asked for, and how many had been seen before.
    asked: Option<(u64, u64)>,
    seq: u16,
    restarts: u32,
    /// Restarts since samples last flowed, and the sample count at the latest.
    fruitless: u32,
    expected_at_restart: u64,
}

impl Keepalive {
    /// A watcher for a board streaming as `plan` set it, heard from at `now_us`.
    pub fn new(plan: Plan, now_us: u64) -> Self {
        Keepalive {
            plan,
            last_heard_us: now_us,
            asked: None,
            seq: FIRST_SEQ,
            restarts: 0,
            fruitless: 0,
            expected_at_restart: 0,
        }
    }

    /// Restarts the watcher carried out.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// After a read of `received` bytes at `now_us` (decoded into `decoder`): send what is
    /// due on `link`, and return a note to record first if the board was restarted.
    pub fn after_read(
        &mut self,
        received: usize,
        now_us: u64,
        decoder: &StreamDecoder,
        link: &mut dyn Link,
    ) -> std::io::Result<Action> {
        let expected = decoder.accounting().expected();
        if expected > self.expected_at_restart {
            self.fruitless = 0;
        }
        if let Some((_, seen)) = self.asked
            && decoder.statuses_seen() > seen
        {
            self.asked = None;
            let streaming = decoder.status().is_some_and(|s| s.streaming);
            if !streaming {
                let silent_us = now_us.saturating_sub(self.last_heard_us);
                self.restarts += 1;
                self.fruitless += 1;
                self.expected_at_restart = expected;
                self.last_heard_us = now_us;
                let commands: Vec<Command> = self.plan.commands().collect();
                for command in commands
                    .into_iter()
                    .chain([Command::GetInfo, Command::Start])
                {
                    self.send(link, command)?;
                }
                return Ok(Action::Note(HostNote::BoardRestarted { silent_us }.frame()));
            }
        }
        if received > 0 {
            self.last_heard_us = now_us;
            return Ok(Action::Nothing);
        }
        let wait = SILENCE
            .saturating_mul(1 << self.fruitless.saturating_sub(1).min(6))
            .min(MAX_SILENCE);
        let silence = u64::try_from(wait.as_micros()).unwrap_or(u64::MAX);
        let since = self.asked.map_or(self.last_heard_us, |(at, _)| at);
        if now_us.saturating_sub(since) >= silence {
            self.asked = Some((now_us, decoder.statuses_seen()));
            self.send(link, Command::GetStatus)?;
        }
        Ok(Action::Nothing)
    }

    /// At the end of the capture: if the latest restart brought no samples, the silence
    /// since then, as a note (the board was gone until the end).
    pub fn closing_note(&self, now_us: u64, decoder: &StreamDecoder) -> Option<Vec<u8>> {
        let nothing_since = decoder.accounting().expected() <= self.expected_at_restart;
        (self.restarts > 0 && self.fruitless > 0 && nothing_since).then(|| {
            let silent_us = now_us.saturating_sub(self.last_heard_us);
            HostNote::BoardRestarted { silent_us }.frame()
        })
    }

    fn send(&mut self, link: &mut dyn Link, command: Command) -> std::io::Result<()> {
        self.seq = self.seq.wrapping_add(1).max(FIRST_SEQ);
        let mut buf = [0u8; MAX_WIRE_LEN];
        let request = Request {
            seq: self.seq,
            command,
        };
        // A request is a few bytes: it always fits a frame.
        let n = frame::encode(&request, &mut buf).unwrap_or(0);
        link.write_all(&buf[..n])
    }
}

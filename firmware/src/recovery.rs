//! Riding through sensor faults: a board left alone overnight must bring a sensor back by
//! itself, not end the run at the first glitch.
//!
//! When a run ends with an error (drains failing for [`crate::acquire::FAILING_FOR_US`], a
//! sensor that reset itself, an impossible FIFO count), the board reports it
//! ([`protocol::DeviceMessage::Fault`]) and keeps "streaming" from the host's point of view
//! while it tries, again and again, to: clear the bus ([`crate::driver::BusClear`]), probe
//! WHO_AM_I, write and verify the settings, and restart the FIFO. The first attempt is at
//! once; each failure doubles the wait, from [`FIRST_BACKOFF_US`] up to [`MAX_BACKOFF_US`],
//! so a short outage costs at most about its own length plus a second, and a sensor that
//! stays away costs one probe a second. After [`protocol::GAVE_UP_AFTER_S`] of failures the
//! board stops streaming and says [`protocol::ErrorCode::GaveUp`].
//!
//! The resumed run numbers its samples from where the old run's grid says the sensor would
//! be ([`crate::acquire::Timeline`]), so the time lost is a gap in the indices that the host
//! counts, and [`protocol::DeviceMessage::Recovered`] says where samples resumed.

use crate::acquire::Timeline;
use protocol::ErrorCode;

/// Wait before the second attempt.
pub const FIRST_BACKOFF_US: u64 = 50_000;
/// Longest wait between attempts.
pub const MAX_BACKOFF_US: u64 = 1_000_000;
/// A resumed run that fails again with the same error sooner than this continues the same
/// episode: the same backoff and the same give-up clock, and no second Fault message. A
/// sensor that comes back only to fail at once (a stuck FIFO count) must not be restarted in
/// a tight loop; another error, or one after a run this long, is a new fault.
pub const STABLE_RUN_US: u64 = 2_000_000;

/// A run being brought back.
#[derive(Debug, Clone)]
pub struct Recovery {
    /// The ended run's place on the grid.
    pub timeline: Timeline,
    /// Attempts made so far.
    pub attempts: u16,
    /// The latest reason (the fault, then each failed attempt's error).
    pub last_error: ErrorCode,
    since_us: u64,
    next_at_us: u64,
}

impl Recovery {
    /// Recovery of the run that ended at `now_us` with `error`; the first attempt is due at
    /// once.
    pub fn new(timeline: Timeline, error: ErrorCode, now_us: u64) -> Self {
        Recovery {
            timeline,
            attempts: 0,
            last_error: error,
            since_us: now_us,
            next_at_us: now_us,
        }
    }

    /// The episode of `self` going on: the run it resumed failed at `now_us` with `error`
    /// before it was stable, so the next attempt waits for the backoff.
    pub fn relapse(mut self, timeline: Timeline, error: ErrorCode, now_us: u64) -> Self {
        self.timeline = timeline;
        self.last_error = error;
        self.next_at_us = now_us.saturating_add(backoff_us(self.attempts));
        self
    }

    pub fn due(&self, now_us: u64) -> bool {
        now_us >= self.next_at_us
    }

    /// An attempt failed at `now_us` with `error`: schedule the next, or `false` if the
    /// board should give up.
    pub fn failed(&mut self, error: ErrorCode, now_us: u64) -> bool {
        self.last_error = error;
        if now_us.saturating_sub(self.since_us) >= u64::from(protocol::GAVE_UP_AFTER_S) * 1_000_000
        {
            return false;
        }
        self.next_at_us = now_us.saturating_add(backoff_us(self.attempts));
        true
    }
}

/// Wait after the `attempts`-th failed attempt: 50 ms, 100 ms, 200 ms ... capped at 1 s.
pub fn backoff_us(attempts: u16) -> u64 {
    let doublings = u32::from(attempts.saturating_sub(1)).min(16);
    (FIRST_BACKOFF_US << doublings).min(MAX_BACKOFF_US)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_to_a_second() {
        let waits: [u64; 7] = core::array::from_fn(|i| backoff_us(i as u16 + 1));
        assert_eq!(
            waits,
            [
                50_000, 100_000, 200_000, 400_000, 800_000, 1_000_000, 1_000_000
            ]
        );
        assert_eq!(backoff_us(u16::MAX), MAX_BACKOFF_US);
    }
}

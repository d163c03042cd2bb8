//! The board's log over RTT (defmt): a timestamp on every line, and a warning whenever a
//! counter that means trouble moves, so a probe attached the morning after shows what the
//! night was like.

use protocol::Status;

// Microseconds since boot, read from the timer's raw low and high words (the latched pair is
// the firmware clock's; reading the raw ones here never disturbs it).
defmt::timestamp!("{=u64:us}", {
    // SAFETY: TIMERAWH/TIMERAWL are read-only registers; reading them has no side effects.
    let timer = unsafe { &*rp2040_hal::pac::TIMER::ptr() };
    loop {
        let hi = timer.timerawh().read().bits();
        let lo = timer.timerawl().read().bits();
        if timer.timerawh().read().bits() == hi {
            break (u64::from(hi) << 32) | u64::from(lo);
        }
    }
});

/// The trouble counters as last logged.
#[derive(Default)]
pub struct Changes {
    last: Status,
}

impl Changes {
    /// Log what moved since the last call.
    pub fn report(&mut self, now: &Status) {
        let was = &self.last;
        if now.fifo_overflows != was.fifo_overflows {
            defmt::warn!(
                "FIFO overflow: {=u32} in all, {=u64} samples lost",
                now.fifo_overflows,
                now.samples_lost
            );
        }
        if now.batches_dropped != was.batches_dropped {
            defmt::warn!(
                "USB back-pressure: {=u32} batches ({=u64} samples) dropped in all",
                now.batches_dropped,
                now.samples_dropped
            );
        }
        if now.recoveries != was.recoveries {
            defmt::warn!(
                "sensor recovered ({=u32} recoveries), {=u64} samples lost in all",
                now.recoveries,
                now.samples_lost
            );
        }
        if now.replies_dropped != was.replies_dropped {
            defmt::error!("reply queue full: {=u32} replies dropped", now.replies_dropped);
        }
        if now.streaming != was.streaming {
            defmt::info!("streaming: {=bool}", now.streaming);
        }
        self.last = *now;
    }
}

//! The part of a sensor's stream that does not depend on its chip ([`RunState`]): the run
//! or the recovery under way, the last recovery's episode, the health-check schedule and the
//! counters, with the bookkeeping of a fault, a resumed run, a failed attempt and a loss.
//! Kept out of the generic [`crate::stream::SensorStream`] so that the board's image holds
//! it once, not once per kind of chip.

use crate::acquire::{Acquisition, Timeline};
use crate::recovery::{Recovery, STABLE_RUN_US};
use crate::reply::Reply;
use crate::stream::{HEALTH_INTERVAL_US, Outlet};
use protocol::{ErrorCode, Status};

/// One sensor's run and counters (module documentation).
pub struct RunState {
    /// The sensor's number in the board's list.
    pub number: u8,
    pub run: Option<Acquisition>,
    /// A run that ended with a fault and is being brought back.
    pub recovery: Option<Recovery>,
    /// The last recovery and when its run resumed, until the run has been stable for
    /// [`STABLE_RUN_US`].
    resumed: Option<(Recovery, u64)>,
    /// When the streaming sensor's configuration is next read back.
    next_health_us: u64,
    /// This sensor's share of the board's counters (samples, losses, overflows, drops,
    /// recoveries, certainty, the last run's period).
    pub counters: Status,
}

impl RunState {
    pub fn new(number: u8) -> Self {
        RunState {
            number,
            run: None,
            recovery: None,
            resumed: None,
            next_health_us: 0,
            counters: Status {
                loss_certain: true,
                ..Status::default()
            },
        }
    }

    /// Streaming as the host sees it: a run, or a run being recovered.
    pub fn streaming(&self) -> bool {
        self.run.is_some() || self.recovery.is_some()
    }

    /// The counters, with the period of the run under way (or of the last one).
    pub fn counters(&self, i2c_errors: u32) -> Status {
        Status {
            i2c_errors,
            sample_period_ns: match (&self.run, &self.recovery) {
                (Some(run), _) => run.grid().period_ns(),
                (None, Some(r)) => r.timeline.period_ns(),
                (None, None) => self.counters.sample_period_ns,
            },
            ..self.counters
        }
    }

    /// A run numbered from 0 started at `now_us`.
    pub fn started(&mut self, run: Acquisition, now_us: u64) {
        self.resumed = None;
        self.run = Some(run);
        self.next_health_us = now_us.saturating_add(HEALTH_INTERVAL_US);
    }

    /// Whether the configuration read-back is due at `now_us` (and schedule the next).
    pub fn health_due(&mut self, now_us: u64) -> bool {
        if self.run.is_some() && now_us >= self.next_health_us {
            self.next_health_us = now_us.saturating_add(HEALTH_INTERVAL_US);
            return true;
        }
        false
    }

    /// The recovery, if an attempt is due at `now_us`.
    pub fn take_due_recovery(&mut self, now_us: u64) -> Option<Recovery> {
        if self.recovery.as_ref().is_some_and(|r| r.due(now_us)) {
            return self.recovery.take();
        }
        None
    }

    /// The run ended with `error` at `now_us`: report it (unless it relapses into the last
    /// episode) and start bringing the sensor back. `false` if there was no run.
    pub fn fault(&mut self, error: ErrorCode, now_us: u64, outlet: &mut dyn Outlet) -> bool {
        let Some(run) = self.run.take() else {
            return false;
        };
        self.counters.sample_period_ns = run.grid().period_ns();
        let relapse = self.resumed.take().filter(|(episode, at)| {
            now_us.saturating_sub(*at) < STABLE_RUN_US && episode.last_error == error
        });
        self.recovery = Some(match relapse {
            Some((episode, _)) => episode.relapse(run.timeline(), error, now_us),
            None => {
                outlet.reply(Reply::Fault {
                    sensor: self.number,
                    error,
                });
                Recovery::new(run.timeline(), error, now_us)
            }
        });
        true
    }

    /// An attempt of `recovery` started `run` at `now_us`: count the gap, report it.
    pub fn resumed(
        &mut self,
        recovery: Recovery,
        run: Acquisition,
        now_us: u64,
        outlet: &mut dyn Outlet,
    ) {
        self.count_loss(&recovery.timeline, now_us, Some(run.next_index()));
        self.counters.loss_certain &= run.resume_certain();
        outlet.reply(Reply::Recovered {
            sensor: self.number,
            attempts: recovery.attempts,
            resumed_at_index: run.next_index(),
        });
        self.counters.recoveries = self.counters.recoveries.saturating_add(1);
        self.next_health_us = now_us.saturating_add(HEALTH_INTERVAL_US);
        self.run = Some(run);
        self.resumed = Some((recovery, now_us));
    }

    /// An attempt of `recovery` failed with `error` at `now_us`: wait for the next, or,
    /// after [`protocol::GAVE_UP_AFTER_S`], count the loss, say so and return `false` (the
    /// stream is over).
    pub fn attempt_failed(
        &mut self,
        mut recovery: Recovery,
        error: ErrorCode,
        now_us: u64,
        outlet: &mut dyn Outlet,
    ) -> bool {
        if recovery.failed(error, now_us) {
            self.recovery = Some(recovery);
            return true;
        }
        self.count_loss(&recovery.timeline, now_us, None);
        outlet.reply(Reply::Fault {
            sensor: self.number,
            error: ErrorCode::GaveUp {
                attempts: recovery.attempts,
                last: error.into(),
                ended_at: recovery.timeline.index_at(now_us).0,
            },
        });
        false
    }

    /// End a recovery under way at `now_us`, counting what it lost; `false` if there was
    /// none.
    pub fn end_recovery(&mut self, now_us: u64) -> bool {
        match self.recovery.take() {
            Some(recovery) => {
                self.count_loss(&recovery.timeline, now_us, None);
                true
            }
            None => false,
        }
    }

    /// End the run under way, keeping its period; `false` if there was none.
    pub fn end_run(&mut self) -> bool {
        self.resumed = None;
        match self.run.take() {
            Some(run) => {
                self.counters.sample_period_ns = run.grid().period_ns();
                true
            }
            None => false,
        }
    }

    /// Batches the link refused in a drain.
    pub fn dropped(&mut self, batches: u32, samples: u64) {
        let c = &mut self.counters;
        c.batches_dropped = c.batches_dropped.saturating_add(batches);
        c.samples_dropped = c.samples_dropped.saturating_add(samples);
    }

    /// Count as lost every sample between the ended run's last delivered one and `now_us`
    /// (or `resumed_at`, the index a resumed run starts at).
    fn count_loss(&mut self, timeline: &Timeline, now_us: u64, resumed_at: Option<u64>) {
        let (at_now, certain) = timeline.index_at(now_us);
        let until = resumed_at.unwrap_or(at_now);
        let lost = until.saturating_sub(timeline.next_index());
        self.counters.samples_lost = self.counters.samples_lost.saturating_add(lost);
        self.counters.loss_certain &= certain || lost == 0;
    }
}

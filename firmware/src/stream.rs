//! One sensor's life on the board, for any chip ([`SensorStream`] over [`SensorChip`]):
//! set-up, start, the drains, the health check, a fault and its recovery, stop, and the
//! counters of all that. A board with several sensors runs one stream per sensor; each numbers
//! its own samples from 0 at Start, and a fault of one does not touch the others.
//!
//! A fault while streaming (the sensor stops answering, resets itself, or reports an
//! impossible FIFO count) sends a Fault and the stream sets the sensor up again by itself
//! ([`crate::recovery`]); while it tries, it still counts as streaming. Every
//! [`HEALTH_INTERVAL_US`] a streaming sensor's configuration is read back, so a sensor that
//! reset to its power-on defaults is found even if its buffer count looks sane.

use crate::acquire::{Acquisition, Resume, Timeline};
use crate::chip::SensorChip;
use crate::recovery::{Recovery, STABLE_RUN_US};
use crate::reply::Reply;
use crate::timing::Clock;
use embedded_hal::delay::DelayNs;
use protocol::{ErrorCode, SampleBatch, SensorInfo, Status};

/// How often a streaming board reads each sensor's configuration back.
pub const HEALTH_INTERVAL_US: u64 = 1_000_000;

/// Where a stream's samples and messages go: the board's link and reply queue.
pub trait Outlet {
    /// Offer sensor `sensor`'s batch to the link; `false` if the link refused it (counted
    /// by the stream as dropped).
    fn samples(&mut self, sensor: u8, batch: SampleBatch) -> bool;
    /// Queue a reply for the host.
    fn reply(&mut self, reply: Reply);
}

/// One sensor and its run (module documentation).
pub struct SensorStream<S: SensorChip> {
    dev: S,
    /// The sensor's number in the board's list.
    number: u8,
    address: u8,
    /// What the identity register answered last (0: never answered).
    id: u8,
    settings: S::Settings,
    /// The sensor holds `settings`, awake, buffer selected.
    ready: bool,
    run: Option<Acquisition>,
    /// A run that ended with a fault and is being brought back.
    recovery: Option<Recovery>,
    /// The last recovery and when its run resumed, until the run has been stable for
    /// [`STABLE_RUN_US`].
    resumed: Option<(Recovery, u64)>,
    /// When the streaming sensor's configuration is next read back.
    next_health_us: u64,
    /// This sensor's share of the board's counters (samples, losses, overflows, drops,
    /// recoveries, certainty, the last run's period).
    counters: Status,
}

impl<S: SensorChip> SensorStream<S> {
    /// Sensor `number`, found at `address` answering `id`, with its default settings.
    pub fn new(dev: S, number: u8, address: u8, id: u8) -> Self {
        SensorStream {
            dev,
            number,
            address,
            id,
            settings: S::Settings::default(),
            ready: false,
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

    pub fn info(&self) -> SensorInfo {
        SensorInfo {
            kind: S::KIND,
            address: self.address,
            id: self.id,
            config: S::config(self.settings),
        }
    }

    pub fn number(&self) -> u8 {
        self.number
    }

    pub fn settings(&self) -> S::Settings {
        self.settings
    }

    pub fn device_mut(&mut self) -> &mut S {
        &mut self.dev
    }

    /// Streaming as the host sees it: a run, or a run being recovered.
    pub fn streaming(&self) -> bool {
        self.run.is_some() || self.recovery.is_some()
    }

    /// This sensor's counters; the board sums them ([`crate::control`]).
    pub fn counters(&self) -> Status {
        Status {
            i2c_errors: self.dev.i2c_errors(),
            sample_period_ns: match (&self.run, &self.recovery) {
                (Some(run), _) => run.grid().period_ns(),
                (None, Some(r)) => r.timeline.period_ns(),
                (None, None) => self.counters.sample_period_ns,
            },
            ..self.counters
        }
    }

    /// Power-up: reset, then the default settings.
    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), ErrorCode> {
        self.probe()?;
        self.dev.reset(delay)?;
        self.set_up(self.settings)
    }

    /// Set the sensor up with `settings` (the board refuses while streaming).
    pub fn configure(&mut self, settings: S::Settings) -> Result<(), ErrorCode> {
        S::period_us(&settings)?;
        self.probe()?;
        self.set_up(settings)
    }

    /// Start a run numbered from 0.
    pub fn start(&mut self, clock: &mut impl Clock) -> Result<(), ErrorCode> {
        self.resumed = None;
        if !self.ready {
            self.probe()?;
            self.set_up(self.settings)?;
        }
        self.dev.check_awake()?;
        let period = S::period_us(&self.settings)?;
        let run = Acquisition::start(&mut self.dev, clock, period, None)?;
        self.run = Some(run);
        self.next_health_us = clock.now_us().saturating_add(HEALTH_INTERVAL_US);
        Ok(())
    }

    /// Drain if due, check health if due, attempt a recovery if due.
    pub fn poll(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) {
        let now = clock.now_us();
        if self.run.as_ref().is_some_and(|run| run.due(now))
            && let Err(error) = self.drain(clock, outlet)
        {
            self.fault(error, clock, outlet);
        }
        if self.run.is_some() && now >= self.next_health_us {
            self.next_health_us = now.saturating_add(HEALTH_INTERVAL_US);
            // A read that fails is the drains' business (they end the run if it persists).
            if self.dev.check_streaming(&self.settings) == Err(ErrorCode::SensorReset) {
                self.fault(ErrorCode::SensorReset, clock, outlet);
            }
        }
        if self.recovery.as_ref().is_some_and(|r| r.due(now)) {
            self.attempt_recovery(clock, outlet);
        }
    }

    /// A last drain (everything made until now reaches the host), then the buffer off. A
    /// stream not streaming has nothing to stop.
    pub fn stop(
        &mut self,
        clock: &mut impl Clock,
        outlet: &mut dyn Outlet,
    ) -> Result<(), ErrorCode> {
        if let Some(recovery) = self.recovery.take() {
            self.count_loss(&recovery.timeline, clock.now_us(), None);
            // Best effort: the sensor is the problem.
            let _ = self.dev.stop();
            return Ok(());
        }
        if self.run.is_none() {
            return Ok(());
        }
        if let Err(error) = self.drain(clock, outlet) {
            outlet.reply(Reply::Fault {
                sensor: self.number,
                error,
            });
        }
        if let Some(run) = self.run.take() {
            self.counters.sample_period_ns = run.grid().period_ns();
        }
        self.dev.stop()
    }

    /// The host left: stop as a Stop would, without a last drain.
    pub fn host_left(&mut self, clock: &mut impl Clock) {
        if let Some(recovery) = self.recovery.take() {
            self.count_loss(&recovery.timeline, clock.now_us(), None);
        }
        if self.run.take().is_some() {
            // Best effort: a failure shows at the next Start.
            let _ = self.dev.stop();
        }
        self.resumed = None;
    }

    /// One drain; batches the link refuses are dropped and counted.
    fn drain(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) -> Result<(), ErrorCode> {
        let Some(run) = self.run.as_mut() else {
            return Ok(());
        };
        let (mut batches_dropped, mut samples_dropped) = (0u32, 0u64);
        let number = self.number;
        let mut deliver = |batch: SampleBatch| {
            let len = batch.samples.len() as u64;
            if !outlet.samples(number, batch) {
                batches_dropped += 1;
                samples_dropped += len;
            }
        };
        let result = run.drain(&mut self.dev, clock, &mut self.counters, &mut deliver);
        let c = &mut self.counters;
        c.batches_dropped = c.batches_dropped.saturating_add(batches_dropped);
        c.samples_dropped = c.samples_dropped.saturating_add(samples_dropped);
        result.map(|_| ())
    }

    /// The run ended with `error`: report it and start bringing the sensor back.
    fn fault(&mut self, error: ErrorCode, clock: &mut impl Clock, outlet: &mut dyn Outlet) {
        let now = clock.now_us();
        let Some(run) = self.run.take() else {
            return;
        };
        self.counters.sample_period_ns = run.grid().period_ns();
        self.ready = false;
        let relapse = self.resumed.take().filter(|(episode, at)| {
            now.saturating_sub(*at) < STABLE_RUN_US && episode.last_error == error
        });
        self.recovery = Some(match relapse {
            Some((episode, _)) => episode.relapse(run.timeline(), error, now),
            None => {
                outlet.reply(Reply::Fault {
                    sensor: self.number,
                    error,
                });
                Recovery::new(run.timeline(), error, now)
            }
        });
    }

    /// One recovery attempt: clear the bus, probe, set up, restart the buffer's numbering
    /// from where the old run's grid says the sensor is. A failure waits for the next
    /// attempt or, after [`protocol::GAVE_UP_AFTER_S`], stops this sensor's stream.
    fn attempt_recovery(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) {
        let Some(mut recovery) = self.recovery.take() else {
            return;
        };
        recovery.attempts = recovery.attempts.saturating_add(1);
        self.dev.clear_bus();
        let settings = self.settings;
        let started = self
            .probe()
            .and_then(|()| self.set_up(settings))
            .and_then(|()| self.dev.check_awake())
            .and_then(|()| {
                let resume = Resume {
                    timeline: recovery.timeline.clone(),
                };
                let period = S::period_us(&settings)?;
                Acquisition::start(&mut self.dev, clock, period, Some(resume))
            });
        let now = clock.now_us();
        match started {
            Ok(run) => {
                self.count_loss(&recovery.timeline, now, Some(run.next_index()));
                self.counters.loss_certain &= run.resume_certain();
                outlet.reply(Reply::Recovered {
                    sensor: self.number,
                    attempts: recovery.attempts,
                    resumed_at_index: run.next_index(),
                });
                self.counters.recoveries = self.counters.recoveries.saturating_add(1);
                self.next_health_us = now.saturating_add(HEALTH_INTERVAL_US);
                self.run = Some(run);
                self.resumed = Some((recovery, now));
            }
            Err(error) => {
                if recovery.failed(error, now) {
                    self.recovery = Some(recovery);
                    return;
                }
                self.count_loss(&recovery.timeline, now, None);
                let _ = self.dev.stop();
                outlet.reply(Reply::Fault {
                    sensor: self.number,
                    error: ErrorCode::GaveUp {
                        attempts: recovery.attempts,
                        last: error.into(),
                        ended_at: recovery.timeline.index_at(now).0,
                    },
                });
            }
        }
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

    /// Read the identity register; an answer that names another chip is kept for Info.
    fn probe(&mut self) -> Result<(), ErrorCode> {
        self.id = 0;
        match self.dev.probe() {
            Ok(id) => {
                self.id = id;
                Ok(())
            }
            Err(e) => {
                if let ErrorCode::WrongSensor { who_am_i } = e {
                    self.id = who_am_i;
                }
                self.ready = false;
                Err(e)
            }
        }
    }

    /// Awake, `settings` written, buffer selected but off until Start.
    fn set_up(&mut self, settings: S::Settings) -> Result<(), ErrorCode> {
        self.ready = false;
        self.dev.set_up(&settings)?;
        self.settings = settings;
        self.ready = true;
        Ok(())
    }
}

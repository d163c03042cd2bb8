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

use crate::acquire::{Acquisition, Resume};
use crate::chip::SensorChip;
use crate::reply::Reply;
use crate::run_state::RunState;
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
    address: u8,
    /// What the identity register answered last (0: never answered).
    id: u8,
    settings: S::Settings,
    /// The sensor holds `settings`, awake, buffer selected.
    ready: bool,
    state: RunState,
}

impl<S: SensorChip> SensorStream<S> {
    /// Sensor `number`, found at `address` answering `id`, with its default settings.
    pub fn new(dev: S, number: u8, address: u8, id: u8) -> Self {
        SensorStream {
            dev,
            address,
            id,
            settings: S::Settings::default(),
            ready: false,
            state: RunState::new(number),
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
        self.state.number
    }

    /// Streaming as the host sees it: a run, or a run being recovered.
    pub fn streaming(&self) -> bool {
        self.state.streaming()
    }

    /// This sensor's counters; the board sums them ([`crate::control`]).
    pub fn counters(&self) -> Status {
        self.state.counters(self.dev.i2c_errors())
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
        if !self.ready {
            self.probe()?;
            self.set_up(self.settings)?;
        }
        self.dev.check_awake()?;
        let period = S::period_us(&self.settings)?;
        let run = Acquisition::start(&mut self.dev, clock, period, None)?;
        self.state.started(run, clock.now_us());
        Ok(())
    }

    /// Drain if due, check health if due, attempt a recovery if due.
    pub fn poll(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) {
        let now = clock.now_us();
        if self.state.run.as_ref().is_some_and(|run| run.due(now))
            && let Err(error) = self.drain(clock, outlet)
        {
            self.fault(error, clock.now_us(), outlet);
        }
        // A read that fails is the drains' business (they end the run if it persists).
        if self.state.health_due(now)
            && self.dev.check_streaming(&self.settings) == Err(ErrorCode::SensorReset)
        {
            self.fault(ErrorCode::SensorReset, clock.now_us(), outlet);
        }
        if let Some(recovery) = self.state.take_due_recovery(now) {
            self.attempt_recovery(recovery, clock, outlet);
        }
    }

    /// A last drain (everything made until now reaches the host), then the buffer off. A
    /// stream not streaming has nothing to stop.
    pub fn stop(
        &mut self,
        clock: &mut impl Clock,
        outlet: &mut dyn Outlet,
    ) -> Result<(), ErrorCode> {
        if self.state.end_recovery(clock.now_us()) {
            // Best effort: the sensor is the problem.
            let _ = self.dev.stop();
            return Ok(());
        }
        if self.state.run.is_none() {
            return Ok(());
        }
        if let Err(error) = self.drain(clock, outlet) {
            outlet.reply(Reply::Fault {
                sensor: self.state.number,
                error,
            });
        }
        self.state.end_run();
        self.dev.stop()
    }

    /// The host left: stop as a Stop would, without a last drain.
    pub fn host_left(&mut self, clock: &mut impl Clock) {
        self.state.end_recovery(clock.now_us());
        if self.state.end_run() {
            // Best effort: a failure shows at the next Start.
            let _ = self.dev.stop();
        }
    }

    /// One drain; batches the link refuses are dropped and counted.
    fn drain(&mut self, clock: &mut impl Clock, outlet: &mut dyn Outlet) -> Result<(), ErrorCode> {
        let state = &mut self.state;
        let Some(run) = state.run.as_mut() else {
            return Ok(());
        };
        let (mut batches_dropped, mut samples_dropped) = (0u32, 0u64);
        let number = state.number;
        let mut deliver = |batch: SampleBatch| {
            let len = batch.samples.len() as u64;
            if !outlet.samples(number, batch) {
                batches_dropped += 1;
                samples_dropped += len;
            }
        };
        let result = run.drain(&mut self.dev, clock, &mut state.counters, &mut deliver);
        state.dropped(batches_dropped, samples_dropped);
        result.map(|_| ())
    }

    /// The run ended with `error`: report it and start bringing the sensor back.
    fn fault(&mut self, error: ErrorCode, now_us: u64, outlet: &mut dyn Outlet) {
        if self.state.fault(error, now_us, outlet) {
            self.ready = false;
        }
    }

    /// One recovery attempt: clear the bus, probe, set up, restart the buffer's numbering
    /// from where the old run's grid says the sensor is. A failure waits for the next
    /// attempt or, after [`protocol::GAVE_UP_AFTER_S`], stops this sensor's stream.
    fn attempt_recovery(
        &mut self,
        mut recovery: crate::recovery::Recovery,
        clock: &mut impl Clock,
        outlet: &mut dyn Outlet,
    ) {
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
            Ok(run) => self.state.resumed(recovery, run, now, outlet),
            Err(error) => {
                if !self.state.attempt_failed(recovery, error, now, outlet) {
                    let _ = self.dev.stop();
                }
            }
        }
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

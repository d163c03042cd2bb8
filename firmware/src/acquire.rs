//! FIFO drain -> sample batches, with exact accounting of every sample the sensor made.
//!
//! **Indices.** Sample `i` of a run is the `(i+1)`-th sample the sensor produced after the
//! FIFO reset at [`Acquisition::start`]. Indices follow production, not delivery, so a sample
//! that never reaches the host leaves a gap and the host counts it from the gap alone.
//!
//! **Draining.** Every [`Acquisition::drain_interval_us`] (at most 20 ms, at most 24 sample
//! periods) one drain reads FIFO_COUNT, pops every whole sample in one burst, then reads
//! INT_STATUS. The FIFO holds 1024 / 14 = 73 samples: 73 ms at 1 kHz, so a 20 ms cadence
//! leaves 53 ms for a late poll.
//!
//! **I2C ceiling.** At 400 kHz one byte with its ACK takes 9 clocks = 22.5 us, so a 14-byte
//! sample costs 315 us of bus time: 3175 samples/s is the hard ceiling with infinitely large
//! bursts. A drain adds three small transactions (count: 4 bytes + 2 starts, data: 3 bytes of
//! addressing, status: 4 bytes; about 12 bytes = 0.3 ms). At 1 kHz a 20-sample drain is
//! 20 * 0.315 + 0.3 = 6.6 ms of bus per 20 ms: 33 % load. Rates above 1 kHz (DLPF off, 8 kHz
//! internal) exceed what 400 kHz can carry (8 kHz needs 2.5x the bus) and are refused by
//! [`check_supported`].
//!
//! **Whole samples.** A drain pops `floor(FIFO_COUNT / 14)` samples, as InvenSense's and
//! ArduPilot's drivers do: a count that is not a multiple of 14 is a sample being written
//! while the count was read, and its bytes wait for the next drain.
//!
//! **Overflow and the loss count.** Only FIFO_OFLOW in INT_STATUS after the burst, or a full
//! FIFO (a count at the chip's capacity: its head may then be mid-sample), means the bytes
//! are not trustworthy: the burst is discarded, the FIFO reset and the run resynchronised.
//! After the reset the next drain reads `n` whole samples and asks the [`SampleGrid`] how
//! many samples the sensor had produced in total by then (`N`); those `n` samples are
//! indices `N - n .. N` and everything between the last index delivered and `N - n` is lost,
//! counted in [`Status::samples_lost`]. This is exact because (1) the FIFO count after a
//! reset counts exactly the samples made since, (2) every drain before the stall bounded the
//! grid's phase to an interval far shorter than a period, and (3) the period is the nominal
//! integer period or, if the sensor's oscillator is off, one re-measured over the whole run;
//! the residual error over a stall of `G` seconds is `G / run length` periods, far below half
//! a period for any stall the run survives. [`SampleGrid::produced`] also says whether the
//! bounds make the answer certain ([`Status::loss_certain`]).
//!
//! **Faults.** I2C errors are retried by the driver and counted; a drain that fails is
//! tried again at the next poll, and after [`FAILING_FOR_US`] of failures the run ends with
//! the error ([`ErrorCode::SensorNotResponding`] or [`ErrorCode::I2cFailure`]) for
//! [`crate::recovery`] to set the sensor up again. A count that contradicts the clock (more
//! samples than the sensor can have made, or far fewer) is checked against PWR_MGMT_1: a
//! sensor that reset itself reads asleep ([`ErrorCode::SensorReset`]); otherwise the count
//! itself is at fault ([`ErrorCode::FifoCountImplausible`]).
//!
//! **Resumed runs.** A run started after a fault ([`Resume`]) numbers its samples from the
//! index the old run's grid gives for the restart time, so the time lost shows as a gap the
//! host counts, and it starts from the period the old run measured.

use crate::sensor::{MAX_DRAIN_BYTES, Sensor};
use crate::timing::{Clock, MAX_RATE_ERROR_PERCENT, SampleGrid};
use protocol::mpu6050::{FIFO_SIZE, SensorSettings};
use protocol::{ErrorCode, MAX_SAMPLES_PER_BATCH, RawSample, SampleBatch, Status};

/// Most whole samples the MPU-6050's FIFO can hold.
pub const FIFO_SAMPLES: usize = FIFO_SIZE / RawSample::FIFO_BYTES;
/// Highest output rate this firmware streams (see the module docs for the I2C ceiling).
pub const MAX_RATE_HZ: f64 = 1000.0;
/// Longest gap between drains.
pub const DRAIN_INTERVAL_MAX_US: u64 = 20_000;
/// Drain after at most this many sample periods.
pub const DRAIN_INTERVAL_SAMPLES: u64 = 24;
/// How long drains may keep failing before the run ends and recovery takes over.
pub const FAILING_FOR_US: u64 = 500_000;
/// Slack, in samples, when checking a count against the clock.
const COUNT_SLACK: u64 = 2;

/// Whether this firmware streams `settings` exactly: a specified DLPF row and an output rate
/// the 400 kHz bus carries.
pub fn check_supported(settings: &SensorSettings) -> Result<(), ErrorCode> {
    if !settings.is_specified() || settings.output_rate_hz() > MAX_RATE_HZ {
        return Err(ErrorCode::InvalidSettings);
    }
    Ok(())
}

/// The nominal sample period in microseconds: 125 or 1000 us times (1 + SMPLRT_DIV), exact.
pub fn period_us(settings: &SensorSettings) -> u32 {
    settings.period_us()
}

/// Where a run resumed after a fault starts: on the old run's sample grid, at the moment
/// the FIFO takes samples again.
#[derive(Debug, Clone)]
pub struct Resume {
    pub timeline: Timeline,
}

/// What is left of a run that ended: where its samples stood on the sensor's grid, to count
/// the loss up to any later moment and resume the numbering from there.
#[derive(Debug, Clone)]
pub struct Timeline {
    grid: SampleGrid,
    base: u64,
    next_index: u64,
}

impl Timeline {
    /// Index of the next sample that reached a batch.
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    /// The index the sensor's next sample after `now_us` has, had the run gone on: (index,
    /// whether the grid makes it certain). Never below [`Timeline::next_index`].
    pub fn index_at(&self, now_us: u64) -> (u64, bool) {
        let (produced, certain) = self.grid.produced(now_us, now_us);
        let index = self.base.saturating_add(produced);
        (index.max(self.next_index), certain)
    }

    /// The sensor's sample period the run measured, nanoseconds.
    pub fn period_ns(&self) -> u32 {
        self.grid.period_ns()
    }

    /// The index of the first sample made after a moment between `before_us` and
    /// `after_us`, and whether the grid makes it certain (no sample of the grid falls
    /// between the two).
    pub fn index_between(&self, before_us: u64, after_us: u64) -> (u64, bool) {
        let (produced, certain) = self.grid.produced(before_us, after_us);
        (
            self.base.saturating_add(produced).max(self.next_index),
            certain,
        )
    }
}

/// One run: from [`Acquisition::start`] to stop or fault.
#[derive(Debug, Clone)]
pub struct Acquisition {
    grid: SampleGrid,
    /// Index of the grid's sample 1 minus one: 0 for a fresh run, the resume index after a
    /// fault.
    base: u64,
    /// Whether the resume index is certain (always, for a fresh run).
    resume_certain: bool,
    /// Whole samples the sensor's buffer holds.
    capacity: usize,
    period_us: u32,
    /// Index of the next sample read from the FIFO.
    next_index: u64,
    /// Samples produced since the start, as of the latest drain.
    produced: u64,
    /// When the FIFO's content was last known (a drain that emptied it, or a reset).
    known_at_us: u64,
    last_drain_us: u64,
    /// When the sensor's buffer was last read successfully (for a sensor that overwrites
    /// silently: a gap shorter than a period cannot hide a replaced sample).
    last_seen_us: u64,
    /// The FIFO was reset after a loss: the next drain takes its indices from the grid.
    resync: bool,
    /// A FIFO reset is owed (the last attempt failed).
    reset_owed: bool,
    failing_since_us: Option<u64>,
    buf: [u8; MAX_DRAIN_BYTES],
}

/// What a drain did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DrainReport {
    pub samples: u64,
    pub lost: u64,
    pub overflowed: bool,
}

impl Acquisition {
    /// Restart the sensor's buffer and count from index 0, or from where `resume` says;
    /// `period_us` is the sensor's nominal sample period.
    pub fn start<S: Sensor>(
        dev: &mut S,
        clock: &mut impl Clock,
        period_us: u32,
        resume: Option<Resume>,
    ) -> Result<Self, ErrorCode> {
        let (before, after) = dev.restart_timed(|| clock.now_us())?;
        Ok(Self::restarted(
            before,
            after,
            dev.capacity_samples(),
            period_us,
            resume,
        ))
    }

    /// The run whose buffer (of `capacity` samples) restarted between `before` and `after`;
    /// apart from [`Acquisition::start`] so that the image holds it once for every sensor.
    fn restarted(
        before: u64,
        after: u64,
        capacity: usize,
        period_us: u32,
        resume: Option<Resume>,
    ) -> Self {
        let (grid, base, resume_certain) = match resume {
            Some(r) => {
                let (first, certain) = r.timeline.index_between(before, after);
                let measured = r.timeline.grid.period_scaled();
                let grid = SampleGrid::with_period(before, after, period_us, measured);
                (grid, first, certain)
            }
            None => (SampleGrid::new(before, after, period_us), 0, true),
        };
        Acquisition {
            grid,
            base,
            resume_certain,
            capacity,
            period_us,
            next_index: base,
            produced: base,
            known_at_us: before,
            last_drain_us: after,
            last_seen_us: before,
            resync: false,
            reset_owed: false,
            failing_since_us: None,
            buf: [0; MAX_DRAIN_BYTES],
        }
    }

    /// Time between drains: 24 sample periods, at most 20 ms, and at most half of what the
    /// sensor's buffer holds (half a period for a sensor without a FIFO, so that every
    /// sample is seen).
    pub fn drain_interval_us(&self) -> u64 {
        let half_buffers = (2 * DRAIN_INTERVAL_SAMPLES).min(self.capacity.max(1) as u64);
        (u64::from(self.period_us) * half_buffers / 2).min(DRAIN_INTERVAL_MAX_US)
    }

    pub fn due(&self, now_us: u64) -> bool {
        now_us.saturating_sub(self.last_drain_us) >= self.drain_interval_us()
    }

    /// Index the next delivered sample will have (= samples accounted for so far).
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    pub fn grid(&self) -> &SampleGrid {
        &self.grid
    }

    /// Whether the run's first index is certain: a resumed run's is unless a sample of the
    /// old grid fell within the bus time of the write that restarted the FIFO.
    pub fn resume_certain(&self) -> bool {
        self.resume_certain
    }

    /// The run's place on the sensor's grid, kept when the run ends.
    pub fn timeline(&self) -> Timeline {
        Timeline {
            grid: self.grid.clone(),
            base: self.base,
            next_index: self.next_index,
        }
    }

    /// Read what the sensor's buffer holds, hand it to `emit` as batches of consecutive
    /// samples and update `status`. `Err` is a fault that ends the run.
    pub fn drain<S: Sensor>(
        &mut self,
        dev: &mut S,
        clock: &mut impl Clock,
        status: &mut Status,
        emit: &mut impl FnMut(SampleBatch),
    ) -> Result<DrainReport, ErrorCode> {
        let before = clock.now_us();
        self.last_drain_us = before;
        let mut report = DrainReport::default();
        if self.reset_owed {
            self.reset_fifo(dev, before)?;
            return Ok(report);
        }
        let waiting = match dev.waiting() {
            Ok(w) => w,
            Err(e) => return self.failed(before, e).map(|()| report),
        };
        let after = clock.now_us();
        let seen_before = core::mem::replace(&mut self.last_seen_us, before);
        let n = u64::from(waiting.samples);
        self.check_count(dev, waiting, after)?;
        if waiting.full {
            report.overflowed = true;
            status.fifo_overflows = status.fifo_overflows.saturating_add(1);
            self.reset_fifo(dev, before)?;
            return Ok(report);
        }
        if n == 0 {
            // Nothing to pop, and no bus can read zero bytes (rp2040-hal aborts such a
            // transfer with an error), so a drain between two samples ends here.
            self.failing_since_us = None;
            return Ok(report);
        }
        // A count check passed, so the samples fit; a count that would not is the count's
        // fault, not a reason to index past the buffer.
        let Some(bytes) = self.buf.get_mut(..n as usize * S::SAMPLE_BYTES) else {
            return Err(ErrorCode::FifoCountImplausible {
                count: waiting.count,
            });
        };
        if let Err(e) = dev.read_samples(bytes) {
            // Some bytes may have been popped: the FIFO is no longer aligned.
            self.reset_fifo(dev, before)?;
            return self.failed(before, e).map(|()| report);
        }
        match dev.overran() {
            Ok(false) => {}
            Ok(true) => {
                // Overflowed while we read: the burst may be shifted. Discard it.
                report.overflowed = true;
                status.fifo_overflows = status.fifo_overflows.saturating_add(1);
                self.reset_fifo(dev, before)?;
                return Ok(report);
            }
            Err(e) => {
                self.reset_fifo(dev, before)?;
                return self.failed(before, e).map(|()| report);
            }
        }
        self.failing_since_us = None;
        let first_index = if self.resync {
            self.resync = false;
            let (total, certain) = self.grid.produced(before, after);
            status.loss_certain &= certain;
            let first = (self.base + total).saturating_sub(n).max(self.next_index);
            report.lost = first - self.next_index;
            status.samples_lost = status.samples_lost.saturating_add(report.lost);
            first
        } else if S::OVERWRITES_SILENTLY && self.could_replace(seen_before, before) {
            self.replaced_before(before, after, n, status, &mut report)
        } else {
            self.next_index
        };
        self.produced = first_index + n;
        if self
            .grid
            .observe(before, after, self.produced - self.base)
            .is_err()
        {
            return Err(self.diagnose(dev, waiting.count));
        }
        self.known_at_us = before;
        self.emit_batches::<S>(first_index, n, emit);
        self.next_index = first_index + n;
        status.samples_acquired = status.samples_acquired.saturating_add(n);
        report.samples = n;
        Ok(report)
    }

    /// Whether two samples can have been made since the buffer was last read at `seen_us`
    /// (the sensor's oscillator as fast as it may be): only then can one have been replaced
    /// unread, and only then is the grid asked. Polls every half period never ask it.
    fn could_replace(&self, seen_us: u64, now_us: u64) -> bool {
        let gap = now_us.saturating_sub(seen_us);
        let shortest_period = u64::from(self.period_us) * (100 - MAX_RATE_ERROR_PERCENT as u64);
        gap * 100 >= shortest_period
    }

    /// For a sensor that replaces unread samples silently, the index of the one it holds
    /// (`n` is 0 or 1): the newest the grid says was made by the read, and the samples
    /// between the last one delivered and it are counted lost. Only a loss the grid makes
    /// certain counts; otherwise the sample is the next one.
    fn replaced_before(
        &mut self,
        before: u64,
        after: u64,
        n: u64,
        status: &mut Status,
        report: &mut DrainReport,
    ) -> u64 {
        let delivered = self.next_index - self.base;
        let (made, certain) = self.grid.produced(before, after);
        // An uncertain grid may count one sample that was not yet made.
        let margin = u64::from(!certain);
        if n == 0 || made <= delivered + n + margin {
            return self.next_index;
        }
        status.loss_certain &= certain;
        let first = (self.base + made).saturating_sub(n).max(self.next_index);
        report.lost = first - self.next_index;
        status.samples_lost = status.samples_lost.saturating_add(report.lost);
        first
    }

    /// A count the clock rules out: more samples than the sensor can have made since the
    /// buffer was last known, or (outside a resync, and as far as the buffer can hold) far
    /// fewer.
    fn check_count<S: Sensor>(
        &mut self,
        dev: &mut S,
        waiting: crate::sensor::Waiting,
        after: u64,
    ) -> Result<(), ErrorCode> {
        let n = u64::from(waiting.samples);
        let elapsed = after.saturating_sub(self.known_at_us);
        let period = u64::from(self.period_us);
        let pct = MAX_RATE_ERROR_PERCENT as u64;
        let most = elapsed * (100 + pct) / (100 * period) + COUNT_SLACK;
        let fewest = (elapsed * (100 - pct) / (100 * period))
            .saturating_sub(COUNT_SLACK)
            .min(self.capacity as u64);
        let full = waiting.full;
        if waiting.impossible || (n > most && !full) || (n < fewest && !full) {
            return Err(self.diagnose(dev, waiting.count));
        }
        Ok(())
    }

    /// Why the count disagrees with the clock: a sensor that reset itself, or a bad count.
    fn diagnose<S: Sensor>(&mut self, dev: &mut S, count: u16) -> ErrorCode {
        match dev.check_awake() {
            Err(ErrorCode::VerifyFailed { .. }) => ErrorCode::SensorReset,
            Err(e) => e,
            Ok(()) => ErrorCode::FifoCountImplausible { count },
        }
    }

    /// Reset the FIFO after a loss; the next drain resynchronises from the grid.
    fn reset_fifo<S: Sensor>(&mut self, dev: &mut S, now_us: u64) -> Result<(), ErrorCode> {
        match dev.restart_timed(|| now_us) {
            Ok(_) => {
                self.reset_owed = false;
                self.resync = true;
                self.known_at_us = now_us;
                Ok(())
            }
            Err(e) => {
                self.reset_owed = true;
                self.failed(now_us, e)
            }
        }
    }

    /// A failed transaction: try again at the next drain, end the run after
    /// [`FAILING_FOR_US`].
    fn failed(&mut self, now_us: u64, error: ErrorCode) -> Result<(), ErrorCode> {
        let since = *self.failing_since_us.get_or_insert(now_us);
        if now_us.saturating_sub(since) >= FAILING_FOR_US {
            return Err(error);
        }
        Ok(())
    }

    fn emit_batches<S: Sensor>(
        &self,
        first_index: u64,
        n: u64,
        emit: &mut impl FnMut(SampleBatch),
    ) {
        let chunks = self.buf[..n as usize * S::SAMPLE_BYTES]
            .chunks(MAX_SAMPLES_PER_BATCH * S::SAMPLE_BYTES);
        let mut index = first_index;
        for chunk in chunks {
            let mut batch = SampleBatch {
                first_index: index,
                first_timestamp_us: self.grid.time_of(index - self.base),
                samples: heapless::Vec::new(),
            };
            for bytes in chunk.chunks_exact(S::SAMPLE_BYTES) {
                // Cannot fail: a chunk holds at most MAX_SAMPLES_PER_BATCH samples.
                let _ = batch.samples.push(S::decode(bytes));
            }
            index += batch.samples.len() as u64;
            emit(batch);
        }
    }
}

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
//! **Overflow and the loss count.** A FIFO_COUNT that is not a multiple of 14 (after an
//! overflow it reads 1024 = 73 * 14 + 2, the head mid-sample) or FIFO_OFLOW in INT_STATUS
//! after the burst means the bytes are not trustworthy: the burst is discarded, the FIFO reset
//! and the run resynchronised. After the reset the next drain reads `n` whole samples and
//! asks the [`SampleGrid`] how many samples the sensor had produced in total by then
//! (`N`); those `n` samples are indices `N - n .. N` and everything between the last index
//! delivered and `N - n` is lost, counted in [`Status::samples_lost`]. This is exact because
//! (1) the FIFO count after a reset counts exactly the samples made since, (2) every drain
//! before the stall bounded the grid's phase to an interval far shorter than a period, and
//! (3) the period is the nominal integer period or, if the sensor's oscillator is off, one
//! re-measured over the whole run; the residual error over a stall of `G` seconds is
//! `G / run length` periods, far below half a period for any stall the run survives.
//! [`SampleGrid::produced`] also says whether the bounds make the answer certain.
//!
//! **Faults.** I2C errors are retried by the driver and counted; a drain that fails is
//! tried again at the next poll, and after [`GIVE_UP_US`] of failures the sensor is reported
//! ([`ErrorCode::SensorNotResponding`] or [`ErrorCode::I2cFailure`]) rather than waited on.
//! A count that contradicts the clock (more samples than the sensor can have made, or far
//! fewer) is checked against PWR_MGMT_1: a sensor that reset itself reads asleep
//! ([`ErrorCode::VerifyFailed`] on register 0x6B); otherwise the count itself is at fault
//! ([`ErrorCode::FifoCountImplausible`]).

use crate::driver::{INT_FIFO_OFLOW, Mpu6050};
use crate::timing::{Clock, MAX_RATE_ERROR_PERCENT, SampleGrid};
use embedded_hal::i2c::I2c;
use protocol::mpu6050::{FIFO_SIZE, SensorSettings};
use protocol::{ErrorCode, MAX_SAMPLES_PER_BATCH, RawSample, SampleBatch, Status};

const SAMPLE_BYTES: usize = RawSample::FIFO_BYTES;
/// Most whole samples the FIFO can hold.
pub const FIFO_SAMPLES: usize = FIFO_SIZE / SAMPLE_BYTES;
/// Highest output rate this firmware streams (see the module docs for the I2C ceiling).
pub const MAX_RATE_HZ: f64 = 1000.0;
/// Longest gap between drains.
pub const DRAIN_INTERVAL_MAX_US: u64 = 20_000;
/// Drain after at most this many sample periods.
pub const DRAIN_INTERVAL_SAMPLES: u64 = 24;
/// How long drains may keep failing before the sensor is reported.
pub const GIVE_UP_US: u64 = 500_000;
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
    let internal_period = if settings.dlpf.gyro_internal_rate_hz() > 1000.0 {
        125
    } else {
        1000
    };
    internal_period * (1 + u32::from(settings.smplrt_div))
}

/// One run: from [`Acquisition::start`] to stop or fault.
#[derive(Debug, Clone)]
pub struct Acquisition {
    grid: SampleGrid,
    period_us: u32,
    /// Index of the next sample read from the FIFO.
    next_index: u64,
    /// Samples produced since the start, as of the latest drain.
    produced: u64,
    /// When the FIFO's content was last known (a drain that emptied it, or a reset).
    known_at_us: u64,
    last_drain_us: u64,
    /// The FIFO was reset after a loss: the next drain takes its indices from the grid.
    resync: bool,
    /// A FIFO reset is owed (the last attempt failed).
    reset_owed: bool,
    failing_since_us: Option<u64>,
    buf: [u8; FIFO_SAMPLES * SAMPLE_BYTES],
}

/// What a drain did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DrainReport {
    pub samples: u64,
    pub lost: u64,
    pub overflowed: bool,
}

impl Acquisition {
    /// Reset the FIFO and start counting from index 0.
    pub fn start<I2C: I2c>(
        dev: &mut Mpu6050<I2C>,
        clock: &mut impl Clock,
        settings: &SensorSettings,
    ) -> Result<Self, ErrorCode> {
        check_supported(settings)?;
        let period_us = period_us(settings);
        let before = clock.now_us();
        dev.reset_fifo()?;
        let after = clock.now_us();
        Ok(Acquisition {
            grid: SampleGrid::new(before, after, period_us),
            period_us,
            next_index: 0,
            produced: 0,
            known_at_us: before,
            last_drain_us: after,
            resync: false,
            reset_owed: false,
            failing_since_us: None,
            buf: [0; FIFO_SAMPLES * SAMPLE_BYTES],
        })
    }

    /// Time between drains: 24 sample periods, at most 20 ms.
    pub fn drain_interval_us(&self) -> u64 {
        (u64::from(self.period_us) * DRAIN_INTERVAL_SAMPLES).min(DRAIN_INTERVAL_MAX_US)
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

    /// Read what the FIFO holds, hand it to `emit` as batches of consecutive samples and
    /// update `status`. `Err` is a fault that ends the run.
    pub fn drain<I2C: I2c>(
        &mut self,
        dev: &mut Mpu6050<I2C>,
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
        let count = match dev.fifo_count() {
            Ok(c) => c,
            Err(e) => return self.failed(before, e).map(|()| report),
        };
        let after = clock.now_us();
        let n = u64::from(count) / SAMPLE_BYTES as u64;
        self.check_count(dev, count, n, after)?;
        if usize::from(count) % SAMPLE_BYTES != 0 {
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
        let bytes = &mut self.buf[..usize::from(count)];
        if let Err(e) = dev.read_fifo(bytes) {
            // Some bytes may have been popped: the FIFO is no longer aligned.
            self.reset_fifo(dev, before)?;
            return self.failed(before, e).map(|()| report);
        }
        match dev.int_status() {
            Ok(s) if s & INT_FIFO_OFLOW == 0 => {}
            Ok(_) => {
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
            let (total, _certain) = self.grid.produced(before, after);
            let first = total.saturating_sub(n).max(self.next_index);
            report.lost = first - self.next_index;
            status.samples_lost = status.samples_lost.saturating_add(report.lost);
            first
        } else {
            self.next_index
        };
        self.produced = first_index + n;
        if self.grid.observe(before, after, self.produced).is_err() {
            return Err(self.diagnose(dev, count));
        }
        self.known_at_us = before;
        self.emit_batches(first_index, n, emit);
        self.next_index = first_index + n;
        status.samples_acquired = status.samples_acquired.saturating_add(n);
        report.samples = n;
        Ok(report)
    }

    /// A count the clock rules out: more samples than the sensor can have made since the
    /// FIFO was last known, or (outside a resync) far fewer.
    fn check_count<I2C: I2c>(
        &mut self,
        dev: &mut Mpu6050<I2C>,
        count: u16,
        n: u64,
        after: u64,
    ) -> Result<(), ErrorCode> {
        let elapsed = after.saturating_sub(self.known_at_us);
        let period = u64::from(self.period_us);
        let pct = MAX_RATE_ERROR_PERCENT as u64;
        let most = elapsed * (100 + pct) / (100 * period) + COUNT_SLACK;
        let fewest = (elapsed * (100 - pct) / (100 * period)).saturating_sub(COUNT_SLACK);
        let full = usize::from(count) >= FIFO_SIZE;
        if usize::from(count) > FIFO_SIZE || (n > most && !full) || (n < fewest && !full) {
            return Err(self.diagnose(dev, count));
        }
        Ok(())
    }

    /// Why the count disagrees with the clock: a sensor that reset itself, or a bad count.
    fn diagnose<I2C: I2c>(&mut self, dev: &mut Mpu6050<I2C>, count: u16) -> ErrorCode {
        match dev.check_awake() {
            Err(e) => e,
            Ok(()) => ErrorCode::FifoCountImplausible { count },
        }
    }

    /// Reset the FIFO after a loss; the next drain resynchronises from the grid.
    fn reset_fifo<I2C: I2c>(
        &mut self,
        dev: &mut Mpu6050<I2C>,
        now_us: u64,
    ) -> Result<(), ErrorCode> {
        match dev.reset_fifo() {
            Ok(()) => {
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

    /// A failed transaction: try again at the next drain, give up after [`GIVE_UP_US`].
    fn failed(&mut self, now_us: u64, error: ErrorCode) -> Result<(), ErrorCode> {
        let since = *self.failing_since_us.get_or_insert(now_us);
        if now_us.saturating_sub(since) >= GIVE_UP_US {
            return Err(error);
        }
        Ok(())
    }

    fn emit_batches(&self, first_index: u64, n: u64, emit: &mut impl FnMut(SampleBatch)) {
        let chunks =
            self.buf[..n as usize * SAMPLE_BYTES].chunks(MAX_SAMPLES_PER_BATCH * SAMPLE_BYTES);
        let mut index = first_index;
        for chunk in chunks {
            let mut batch = SampleBatch {
                first_index: index,
                first_timestamp_us: self.grid.time_of(index),
                samples: heapless::Vec::new(),
            };
            for bytes in chunk.chunks_exact(SAMPLE_BYTES) {
                let mut sample = [0u8; SAMPLE_BYTES];
                sample.copy_from_slice(bytes);
                // Cannot fail: a chunk holds at most MAX_SAMPLES_PER_BATCH samples.
                let _ = batch.samples.push(RawSample::from_fifo_bytes(&sample));
            }
            index += batch.samples.len() as u64;
            emit(batch);
        }
    }
}

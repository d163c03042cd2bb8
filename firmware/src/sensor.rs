//! What the acquisition needs from a sensor ([`Sensor`]): a buffer of whole samples that the
//! board empties, restarts and checks. The MPU-6050 (a 1024-byte FIFO), the ADXL345 (a
//! 32-sample FIFO) and the ITG-3200 (no FIFO: one sample in its data registers until the
//! next replaces it) are all read through it, so [`crate::acquire::Acquisition`]'s exact
//! accounting of every sample made is written once.

use protocol::mpu6050::FIFO_SIZE;
use protocol::{ErrorCode, RawSample};

/// Largest burst a drain reads: the MPU-6050's whole samples in its 1024-byte FIFO.
pub const MAX_DRAIN_BYTES: usize = FIFO_SIZE / RawSample::FIFO_BYTES * RawSample::FIFO_BYTES;

/// What a sensor's buffer held when asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Waiting {
    /// Whole samples that can be read.
    pub samples: u16,
    /// The count the sensor reported, in its own unit (bytes for the MPU-6050's FIFO), for
    /// the error that names an implausible one.
    pub count: u16,
    /// The buffer is full: samples may have been dropped, and (for a byte FIFO) its head may
    /// be mid-sample.
    pub full: bool,
    /// The count is more than the buffer can hold: the count itself is wrong.
    pub impossible: bool,
}

/// A sensor whose samples a board drains (module documentation). Errors are the values the
/// host receives.
pub trait Sensor {
    /// Bytes of one sample as [`Sensor::read_samples`] returns it.
    const SAMPLE_BYTES: usize;
    /// True for a sensor that replaces an unread sample without saying so (no FIFO, no
    /// overrun flag): the acquisition then counts what was replaced from the sample grid.
    const OVERWRITES_SILENTLY: bool = false;

    /// Failed I2C attempts so far.
    fn i2c_errors(&self) -> u32;

    /// Whole samples the buffer holds before it drops any.
    fn capacity_samples(&self) -> usize;

    /// Empty the buffer and start keeping samples again; `now()` is read just before and
    /// just after the write that restarts it, so the two times bracket where the new
    /// numbering starts.
    fn restart_timed(&mut self, now: impl FnMut() -> u64) -> Result<(u64, u64), ErrorCode>;

    /// What the buffer holds.
    fn waiting(&mut self) -> Result<Waiting, ErrorCode>;

    /// Pop `buf.len() / SAMPLE_BYTES` samples. Not retried: a failed read may already have
    /// popped some.
    fn read_samples(&mut self, buf: &mut [u8]) -> Result<(), ErrorCode>;

    /// Whether the buffer dropped samples while they were read (the read may then be
    /// shifted and is discarded).
    fn overran(&mut self) -> Result<bool, ErrorCode>;

    /// Whether the sensor still runs as it was set up: [`ErrorCode::VerifyFailed`] if it
    /// reads as after a power-on reset.
    fn check_awake(&mut self) -> Result<(), ErrorCode>;

    /// One sample's bytes as the protocol's sample (the channels the sensor lacks are 0).
    fn decode(bytes: &[u8]) -> RawSample;
}

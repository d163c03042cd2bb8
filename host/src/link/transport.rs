//! The byte stream from a board, whatever carries it: a USB serial port, the in-process
//! virtual board, or a capture file replayed. The capture loop (crate::recorder) is written
//! against this trait only, so a new source is a new `Link` and nothing else.

use std::io;
use std::time::Duration;

pub trait Link {
    /// Read the bytes that have arrived, waiting at most `timeout` for the first one.
    /// `Ok(0)` means nothing arrived in time (not the end); an error means the link is gone
    /// (a disconnect), which ends a capture as incomplete.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Send bytes to the board (commands).
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// A source with a natural end (a replayed file) says it has nothing more to give; a
    /// port never ends on its own (it disconnects, an error).
    fn at_end(&self) -> bool {
        false
    }

    /// What this link reads from, for messages ("file X.imucap", "/dev/ttyACM0").
    fn describe(&self) -> String;

    /// The host's clock beside this link, microseconds from an arbitrary origin: how long
    /// the board has been silent, how long a restart took. Wall time for a real port; the
    /// emulated time for a simulated board, whose clock is the one its samples keep.
    fn clock_us(&self) -> u64 {
        wall_clock_us()
    }
}

/// Microseconds of wall time since the first call in this process (monotonic).
pub fn wall_clock_us() -> u64 {
    static ORIGIN: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    let origin = ORIGIN.get_or_init(std::time::Instant::now);
    u64::try_from(origin.elapsed().as_micros()).unwrap_or(u64::MAX)
}

/// How fast a simulated or replayed source runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// As fast as the reader takes the bytes.
    Max,
    /// Board time runs this many times faster than wall time (1.0 = real time).
    Factor(f64),
}

/// A text that is neither `max` nor a positive factor.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("speed '{0}': 'max' or a positive factor (1 = real time, 60 = a minute per second)")]
pub struct BadSpeed(pub String);

impl std::str::FromStr for Speed {
    type Err = BadSpeed;
    fn from_str(s: &str) -> Result<Speed, BadSpeed> {
        if s.eq_ignore_ascii_case("max") {
            return Ok(Speed::Max);
        }
        match s.parse::<f64>() {
            Ok(f) if f.is_finite() && f > 0.0 => Ok(Speed::Factor(f)),
            _ => Err(BadSpeed(s.to_string())),
        }
    }
}

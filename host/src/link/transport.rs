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
}

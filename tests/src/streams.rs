//! Frame message streams the way the board writes them, remembering where each frame is.

use protocol::frame::{self, MAX_WIRE_LEN};
use serde::Serialize;

/// Bytes of several frames back to back, with each frame's byte range.
pub struct FramedStream {
    pub bytes: Vec<u8>,
    pub frames: Vec<std::ops::Range<usize>>,
}

pub fn frame_all<T: Serialize>(messages: &[T]) -> FramedStream {
    let mut bytes = Vec::new();
    let mut frames = Vec::new();
    let mut buf = [0u8; MAX_WIRE_LEN];
    for m in messages {
        let n = frame::encode(m, &mut buf).expect("every protocol message fits a frame");
        frames.push(bytes.len()..bytes.len() + n);
        bytes.extend_from_slice(&buf[..n]);
    }
    FramedStream { bytes, frames }
}

//! Framing: how a message becomes bytes on the serial link, and back.
//!
//! ```text
//!  0x00 | COBS( postcard(message) ++ CRC-32(postcard(message)) as 4 little-endian bytes ) | 0x00
//! ```
//!
//! - postcard gives a compact, schema-less body (the schema is `lib.rs`).
//! - CRC-32 (ISO-HDLC, the zlib/Ethernet polynomial; check value 0xCBF43926) catches
//!   corruption: every single-bit error and every burst up to 32 bits, and random damage
//!   with probability 1 - 2^-32.
//! - COBS removes every 0x00 from the frame so that 0x00 delimits frames unambiguously.
//! - A delimiter is sent *before* and after each frame: garbage on the line (a board reset
//!   mid-frame, a host attaching mid-stream) is then closed off by the leading delimiter of
//!   the next frame and costs no good frame. Empty frames between delimiters are ignored.
//!
//! [`FrameDecoder`] takes bytes in any chunking, holds one fixed buffer of [`MAX_FRAME_LEN`]
//! bytes, never panics and never allocates; every rejected frame is counted by cause.

use crate::cobs;
use serde::{Serialize, de::DeserializeOwned};

/// Longest COBS-encoded frame between delimiters, in bytes.
pub const MAX_FRAME_LEN: usize = 1024;
/// Bytes of CRC at the end of a body.
pub const CRC_LEN: usize = 4;
/// Longest postcard body that fits in a frame with its CRC.
pub const MAX_BODY_LEN: usize = 1000;
/// Most bytes one encoded frame takes on the wire, delimiters included.
pub const MAX_WIRE_LEN: usize = MAX_FRAME_LEN + 2;
/// The frame delimiter.
pub const DELIMITER: u8 = 0x00;

const _: () = assert!(cobs::max_encoded_len(MAX_BODY_LEN + CRC_LEN) <= MAX_FRAME_LEN);

/// CRC-32/ISO-HDLC: poly 0x04C11DB7, reflected, init and xorout 0xFFFFFFFF.
pub const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The message's postcard body is longer than [`MAX_BODY_LEN`] (or does not serialize).
    BodyTooLong,
    /// The output buffer is shorter than the frame (give it [`MAX_WIRE_LEN`] bytes).
    BufferTooSmall,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EncodeError::BodyTooLong => write!(f, "message body longer than {MAX_BODY_LEN} bytes"),
            EncodeError::BufferTooSmall => write!(f, "output buffer shorter than the frame"),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Encode `message` as one frame (with both delimiters) into `out`; returns the frame's
/// length in bytes.
pub fn encode<T: Serialize>(message: &T, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut body = [0u8; MAX_BODY_LEN + CRC_LEN];
    let body_len = postcard::to_slice(message, &mut body[..MAX_BODY_LEN])
        .map_err(|_| EncodeError::BodyTooLong)?
        .len();
    let crc = CRC.checksum(&body[..body_len]);
    body[body_len..body_len + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    let with_crc = &body[..body_len + CRC_LEN];

    let needed = cobs::max_encoded_len(with_crc.len()) + 2;
    if out.len() < needed {
        return Err(EncodeError::BufferTooSmall);
    }
    out[0] = DELIMITER;
    let n =
        cobs::encode(with_crc, &mut out[1..needed - 1]).map_err(|_| EncodeError::BufferTooSmall)?;
    out[1 + n] = DELIMITER;
    Ok(n + 2)
}

/// Why a frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// Not valid COBS (a code byte pointing past the frame's end).
    Cobs,
    /// Shorter than a CRC: cannot be a frame.
    TooShort,
    /// The CRC does not match the body.
    Crc,
    /// More than [`MAX_FRAME_LEN`] bytes without a delimiter; `len` bytes were discarded.
    Overlong { len: usize },
    /// The CRC matched but the body is not a message of the expected type (e.g. a peer
    /// speaking another protocol version).
    Malformed,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Cobs => f.write_str("invalid COBS encoding"),
            FrameError::TooShort => f.write_str("frame shorter than its CRC"),
            FrameError::Crc => f.write_str("CRC-32 mismatch"),
            FrameError::Overlong { len } => {
                write!(
                    f,
                    "no delimiter within {MAX_FRAME_LEN} bytes ({len} bytes discarded)"
                )
            }
            FrameError::Malformed => f.write_str("CRC valid but the body is not a known message"),
        }
    }
}

impl core::error::Error for FrameError {}

/// What a [`FrameDecoder`] has seen so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DecoderStats {
    /// Frames whose CRC matched.
    pub frames_ok: u64,
    pub cobs_errors: u64,
    pub too_short: u64,
    pub crc_errors: u64,
    pub overlong: u64,
    /// Counted only by [`FrameDecoder::feed`], which also decodes the body.
    pub malformed: u64,
    /// Bytes that belonged to rejected frames, delimiters not counted (as received; for a
    /// malformed frame, its decoded length).
    pub bytes_discarded: u64,
}

impl DecoderStats {
    /// Frames rejected for any reason.
    pub fn rejected(&self) -> u64 {
        self.cobs_errors + self.too_short + self.crc_errors + self.overlong + self.malformed
    }
}

/// A frame read by [`FrameDecoder::feed_or`]: the expected message, or the other reading.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decoded<T, U> {
    Current(T),
    Other(U),
}

/// Streaming frame decoder with one fixed buffer.
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Bytes seen since the buffer filled up; nonzero means "skip to the next delimiter".
    overflow: usize,
    stats: DecoderStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    pub const fn new() -> Self {
        FrameDecoder {
            buf: [0; MAX_FRAME_LEN],
            len: 0,
            overflow: 0,
            stats: DecoderStats {
                frames_ok: 0,
                cobs_errors: 0,
                too_short: 0,
                crc_errors: 0,
                overlong: 0,
                malformed: 0,
                bytes_discarded: 0,
            },
        }
    }

    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Bytes held of a frame not yet delimited (for diagnostics and tests).
    pub fn pending(&self) -> usize {
        self.len + self.overflow
    }

    /// Take one byte. At a delimiter that closes a non-empty frame, returns the frame's
    /// verified body (CRC stripped) or why it was rejected.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        if byte != DELIMITER {
            if self.len < MAX_FRAME_LEN {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflow += 1;
            }
            return None;
        }
        if self.len == 0 {
            return None; // leading delimiter or idle line
        }
        let raw_len = self.len;
        let overflow = self.overflow;
        self.len = 0;
        self.overflow = 0;
        let result = if overflow > 0 {
            Err(FrameError::Overlong {
                len: raw_len + overflow,
            })
        } else {
            verify(&mut self.buf[..raw_len])
        };
        match result {
            Ok(body_len) => {
                self.stats.frames_ok += 1;
                Some(Ok(&self.buf[..body_len]))
            }
            Err(error) => {
                self.count_rejected(error, (raw_len + overflow) as u64);
                Some(Err(error))
            }
        }
    }

    /// Take a chunk of bytes and decode each complete frame as a `T`, calling `on_message`
    /// with the message or the reason the frame was rejected.
    pub fn feed<T: DeserializeOwned>(
        &mut self,
        bytes: &[u8],
        mut on_message: impl FnMut(Result<T, FrameError>),
    ) {
        self.feed_salvaging(bytes, |outcome: Result<T, (FrameError, &[u8])>| {
            on_message(outcome.map_err(|(error, _)| error))
        });
    }

    /// [`FrameDecoder::feed`], but a frame whose CRC matched and whose body is not a `T`
    /// ([`FrameError::Malformed`]) comes with its body, so the receiver can salvage what the
    /// body still says (the firmware reads a request's `seq` to refuse it by name). Other
    /// rejections come with an empty body: their bytes are not trustworthy.
    pub fn feed_salvaging<T: DeserializeOwned>(
        &mut self,
        bytes: &[u8],
        mut on_message: impl FnMut(Result<T, (FrameError, &[u8])>),
    ) {
        self.feed_or::<T, T>(
            bytes,
            |_| None,
            |outcome| {
                on_message(outcome.map(|d| match d {
                    Decoded::Current(m) | Decoded::Other(m) => m,
                }))
            },
        );
    }

    /// [`FrameDecoder::feed_salvaging`], with a second reading for bodies that are not a
    /// `T`: `other(body)` (a message of an older protocol version that still has a meaning,
    /// or a note the receiver itself put among the frames) makes the frame a good one.
    pub fn feed_or<T: DeserializeOwned, U>(
        &mut self,
        bytes: &[u8],
        other: impl Fn(&[u8]) -> Option<U>,
        on_message: impl FnMut(Result<Decoded<T, U>, (FrameError, &[u8])>),
    ) {
        let decode = |body: &[u8]| match postcard::from_bytes::<T>(body) {
            Ok(message) => Some(Decoded::Current(message)),
            Err(_) => other(body).map(Decoded::Other),
        };
        self.feed_with(bytes, decode, on_message);
    }

    /// The frames in `bytes`, each body read by `decode`; a body it cannot read is
    /// [`FrameError::Malformed`] (counted, and passed on with the body).
    pub fn feed_with<T>(
        &mut self,
        bytes: &[u8],
        decode: impl Fn(&[u8]) -> Option<T>,
        mut on_message: impl FnMut(Result<T, (FrameError, &[u8])>),
    ) {
        for &byte in bytes {
            let Some(frame) = self.push(byte) else {
                continue;
            };
            match frame {
                Err(error) => on_message(Err((error, &[]))),
                Ok(body) => match decode(body) {
                    Some(message) => on_message(Ok(message)),
                    None => {
                        let len = body.len() + CRC_LEN;
                        // push() counted it as a good frame; it is not one after all.
                        self.stats.frames_ok -= 1;
                        self.count_rejected(FrameError::Malformed, len as u64);
                        on_message(Err((FrameError::Malformed, &self.buf[..len - CRC_LEN])));
                    }
                },
            }
        }
    }

    fn count_rejected(&mut self, error: FrameError, bytes: u64) {
        let counter = match error {
            FrameError::Cobs => &mut self.stats.cobs_errors,
            FrameError::TooShort => &mut self.stats.too_short,
            FrameError::Crc => &mut self.stats.crc_errors,
            FrameError::Overlong { .. } => &mut self.stats.overlong,
            FrameError::Malformed => &mut self.stats.malformed,
        };
        *counter += 1;
        self.stats.bytes_discarded += bytes;
    }
}

/// COBS-decode a frame in place and check its CRC; returns the body length.
fn verify(frame: &mut [u8]) -> Result<usize, FrameError> {
    let len = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    if len < CRC_LEN {
        return Err(FrameError::TooShort);
    }
    let body_len = len - CRC_LEN;
    let mut sent = [0u8; CRC_LEN];
    sent.copy_from_slice(&frame[body_len..len]);
    if CRC.checksum(&frame[..body_len]) != u32::from_le_bytes(sent) {
        return Err(FrameError::Crc);
    }
    Ok(body_len)
}

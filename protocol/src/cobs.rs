//! Consistent Overhead Byte Stuffing (Cheshire & Baker, "Consistent Overhead Byte
//! Stuffing", IEEE/ACM Trans. Networking 7(2), 1999).
//!
//! COBS rewrites a packet so that it contains no 0x00 byte, at a cost of at most one byte
//! per 254 plus one; 0x00 can then delimit frames, and a receiver that joins mid-stream or
//! sees garbage resynchronises at the next 0x00. Each block starts with a code byte `c`:
//! `c - 1` data bytes follow, and then (unless `c` is 0xFF or the packet ends) a zero.
//!
//! Ours rather than a crate's because the decoder works in place on the frame buffer, which
//! keeps the streaming decoder at one fixed buffer.

/// Most bytes `encode` writes for `n` input bytes.
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CobsError {
    /// The output buffer is too small (encode).
    BufferTooSmall,
    /// A 0x00 inside the encoded data, or a code byte pointing past the end (decode).
    Invalid,
}

/// COBS-encode `input` into `output`; returns the number of bytes written (never a 0x00).
pub fn encode(input: &[u8], output: &mut [u8]) -> Result<usize, CobsError> {
    if output.len() < max_encoded_len(input.len()) {
        return Err(CobsError::BufferTooSmall);
    }
    let mut code_at = 0;
    let mut out = 1;
    let mut code: u8 = 1;
    for &byte in input {
        if byte == 0 {
            output[code_at] = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            output[out] = byte;
            out += 1;
            code += 1;
            if code == 0xFF {
                output[code_at] = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    output[code_at] = code;
    Ok(out)
}

/// Decode COBS data in place; returns the decoded length (the data is at `buf[..len]`).
///
/// The decoded form is never longer than the encoded one and the write position never
/// passes the read position, so one buffer serves both.
pub fn decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let len = buf.len();
    let mut read = 0;
    let mut write = 0;
    while read < len {
        let code = buf[read] as usize;
        if code == 0 {
            return Err(CobsError::Invalid);
        }
        read += 1;
        let run = code - 1;
        if read + run > len {
            return Err(CobsError::Invalid);
        }
        if buf[read..read + run].contains(&0) {
            return Err(CobsError::Invalid);
        }
        buf.copy_within(read..read + run, write);
        write += run;
        read += run;
        if code != 0xFF && read < len {
            buf[write] = 0;
            write += 1;
        }
    }
    Ok(write)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(data: &[u8]) -> ([u8; 1024], usize) {
        let mut enc = [0u8; 1024];
        let n = encode(data, &mut enc).unwrap();
        assert!(n <= max_encoded_len(data.len()));
        assert!(!enc[..n].contains(&0), "encoded data must hold no zero");
        let mut decoded = enc;
        let m = decode_in_place(&mut decoded[..n]).unwrap();
        assert_eq!(&decoded[..m], data);
        (enc, n)
    }

    /// The examples of the COBS paper (and of its Wikipedia summary).
    #[test]
    fn known_encodings() {
        let cases: &[(&[u8], &[u8])] = &[
            (&[], &[0x01]),
            (&[0x00], &[0x01, 0x01]),
            (&[0x00, 0x00], &[0x01, 0x01, 0x01]),
            (&[0x11, 0x22, 0x00, 0x33], &[0x03, 0x11, 0x22, 0x02, 0x33]),
            (&[0x11, 0x22, 0x33, 0x44], &[0x05, 0x11, 0x22, 0x33, 0x44]),
            (&[0x11, 0x00, 0x00, 0x00], &[0x02, 0x11, 0x01, 0x01, 0x01]),
        ];
        for (raw, encoded) in cases {
            let (enc, n) = roundtrip(raw);
            assert_eq!(&enc[..n], *encoded, "encoding of {raw:02x?}");
        }
    }

    #[test]
    fn long_runs_split_every_254_bytes() {
        let data: [u8; 600] = core::array::from_fn(|i| (i % 255) as u8 + 1);
        let (enc, n) = roundtrip(&data);
        assert_eq!(enc[0], 0xFF);
        assert_eq!(enc[255], 0xFF);
        assert_eq!(n, max_encoded_len(600));
        let mut with_zeros = data;
        with_zeros[253] = 0;
        with_zeros[254] = 0;
        roundtrip(&with_zeros);
    }

    #[test]
    fn invalid_input_is_rejected() {
        assert_eq!(decode_in_place(&mut [0x03, 0x11]), Err(CobsError::Invalid));
        assert_eq!(decode_in_place(&mut [0x02, 0x00]), Err(CobsError::Invalid));
        assert_eq!(decode_in_place(&mut [0x00]), Err(CobsError::Invalid));
        let mut small = [0u8; 2];
        assert_eq!(encode(&[1, 2], &mut small), Err(CobsError::BufferTooSmall));
    }
}

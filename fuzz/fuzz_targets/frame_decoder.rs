//! Fuzz the streaming frame decoder: any bytes, in any chunking, must never panic, and the
//! decoder's accounting must stay consistent.
//!
//! The first input byte picks the chunk size, so the fuzzer also explores chunk boundaries.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::DeviceMessage;
use protocol::frame::FrameDecoder;

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, bytes)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk).max(1);
    let mut decoder = FrameDecoder::new();
    let (mut ok, mut rejected) = (0u64, 0u64);
    for piece in bytes.chunks(chunk) {
        decoder.feed::<DeviceMessage>(piece, |m| match m {
            Ok(_) => ok += 1,
            Err(_) => rejected += 1,
        });
    }
    let stats = decoder.stats();
    assert_eq!(stats.frames_ok, ok);
    assert_eq!(stats.rejected(), rejected);
    // Every byte is either a delimiter, pending, in a delivered frame or discarded: the
    // discarded count can never exceed the input.
    assert!(stats.bytes_discarded <= bytes.len() as u64);
});

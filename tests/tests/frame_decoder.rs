//! The streaming decoder against everything a serial line can do to frames: any chunking,
//! garbage between frames, single-bit flips, truncation, over-long runs. Every intact frame
//! must come out unchanged, every damaged one must be rejected and counted, and nothing may
//! panic or grow.

use imunoise_tests::streams::frame_all;
use proptest::prelude::*;
use protocol::frame::{self, CRC, FrameDecoder, FrameError, MAX_BODY_LEN, MAX_FRAME_LEN};
use protocol::mpu6050::SensorSettings;
use protocol::{DeviceMessage, RawSample, SampleBatch, Status, cobs};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A short stream of varied messages: info, a full batch, status, small replies.
fn sample_messages() -> Vec<DeviceMessage> {
    let samples: Vec<RawSample> = (0..32i16)
        .map(|i| RawSample {
            accel: [i, -i, 16384 - i],
            temp: -3740 + i,
            gyro: [i * 3, i16::MIN + i, i16::MAX - i],
        })
        .collect();
    vec![
        DeviceMessage::Ack { seq: 1 },
        DeviceMessage::Samples(SampleBatch {
            first_index: 0,
            first_timestamp_us: 1_000_000,
            samples: heapless::Vec::from_slice(&samples).unwrap(),
        }),
        DeviceMessage::Status(Status {
            streaming: true,
            uptime_us: 123_456_789,
            samples_acquired: 32,
            ..Status::default()
        }),
        DeviceMessage::Samples(SampleBatch {
            first_index: 32,
            first_timestamp_us: 1_160_000,
            samples: heapless::Vec::from_slice(&samples[..5]).unwrap(),
        }),
        DeviceMessage::Pong { seq: 0 },
    ]
}

struct Outcome {
    messages: Vec<DeviceMessage>,
    errors: Vec<FrameError>,
    decoder: FrameDecoder,
}

fn decode_chunks<'a>(chunks: impl IntoIterator<Item = &'a [u8]>) -> Outcome {
    let mut decoder = FrameDecoder::new();
    let mut messages = Vec::new();
    let mut errors = Vec::new();
    for chunk in chunks {
        decoder.feed::<DeviceMessage>(chunk, |m| match m {
            Ok(m) => messages.push(m),
            Err(e) => errors.push(e),
        });
    }
    let stats = decoder.stats();
    assert_eq!(
        stats.rejected(),
        errors.len() as u64,
        "every rejection is counted"
    );
    assert_eq!(stats.frames_ok, messages.len() as u64);
    Outcome {
        messages,
        errors,
        decoder,
    }
}

fn decode(bytes: &[u8]) -> Outcome {
    decode_chunks([bytes])
}

#[test]
fn split_at_every_byte_boundary() {
    let messages = sample_messages();
    let stream = frame_all(&messages);
    for split in 0..=stream.bytes.len() {
        let (a, b) = stream.bytes.split_at(split);
        let out = decode_chunks([a, b]);
        assert_eq!(out.messages, messages, "split at byte {split}");
        assert!(out.errors.is_empty(), "split at byte {split}");
    }
    // And one byte at a time.
    let out = decode_chunks(stream.bytes.chunks(1));
    assert_eq!(out.messages, messages);
}

proptest! {
    #[test]
    fn any_chunking_gives_the_same_frames(cuts in prop::collection::vec(any::<prop::sample::Index>(), 0..40)) {
        let messages = sample_messages();
        let stream = frame_all(&messages);
        let mut points: Vec<usize> = cuts.iter().map(|i| i.index(stream.bytes.len() + 1)).collect();
        points.sort_unstable();
        let mut chunks = Vec::new();
        let mut start = 0;
        for p in points.into_iter().chain([stream.bytes.len()]) {
            chunks.push(&stream.bytes[start..p]);
            start = p;
        }
        let out = decode_chunks(chunks);
        prop_assert_eq!(out.messages, messages);
        prop_assert!(out.errors.is_empty());
    }
}

/// Non-empty runs between zero bytes: each is one frame attempt for the decoder.
fn segments(garbage: &[u8]) -> usize {
    garbage.split(|&b| b == 0).filter(|s| !s.is_empty()).count()
}

#[test]
fn random_garbage_between_frames() {
    let messages = sample_messages();
    let stream = frame_all(&messages);
    let mut rng = ChaCha8Rng::seed_from_u64(0x1A0_5EED);
    for trial in 0..200 {
        let mut bytes = Vec::new();
        let mut expected_rejections = 0;
        for range in &stream.frames {
            let len = rng.random_range(0..300);
            // Half the runs have no zero byte, so that whole runs must be closed off by the
            // next frame's leading delimiter.
            let zero_free = rng.random_bool(0.5);
            let garbage: Vec<u8> = (0..len)
                .map(|_| {
                    if zero_free {
                        rng.random_range(1..=255)
                    } else {
                        rng.random()
                    }
                })
                .collect();
            expected_rejections += segments(&garbage);
            bytes.extend_from_slice(&garbage);
            bytes.extend_from_slice(&stream.bytes[range.clone()]);
        }
        let out = decode(&bytes);
        assert_eq!(out.messages, messages, "trial {trial}");
        assert_eq!(out.errors.len(), expected_rejections, "trial {trial}");
    }
}

#[test]
fn every_single_bit_flip_is_rejected_and_costs_no_other_frame() {
    let messages = sample_messages();
    let stream = frame_all(&messages);
    let victim = 1; // the full sample batch: the longest frame
    let range = stream.frames[victim].clone();
    let mut others = messages.clone();
    others.remove(victim);
    for byte in range.clone() {
        for bit in 0..8 {
            let mut bytes = stream.bytes.clone();
            bytes[byte] ^= 1 << bit;
            let out = decode(&bytes);
            assert_eq!(out.messages, others, "bit {bit} of byte {byte}");
            // A flipped delimiter or a new zero inside may split or merge runs, but at least
            // one rejection is always counted.
            assert!(
                !out.errors.is_empty(),
                "bit {bit} of byte {byte} went unnoticed"
            );
        }
    }
}

#[test]
fn truncated_frames_are_rejected_and_the_next_frame_survives() {
    let messages = sample_messages();
    let stream = frame_all(&messages);
    let victim = 1;
    let range = stream.frames[victim].clone();
    let mut others = messages.clone();
    others.remove(victim);
    // Keep the leading delimiter plus `kept` bytes of the frame's content, drop the rest.
    let content = range.len() - 2;
    for kept in 1..content {
        let mut bytes = stream.bytes[..range.start + 1 + kept].to_vec();
        bytes.extend_from_slice(&stream.bytes[range.end..]);
        let out = decode(&bytes);
        assert_eq!(out.messages, others, "kept {kept} bytes");
        assert_eq!(out.errors.len(), 1, "kept {kept} bytes");
    }
    // Losing only the trailing delimiter costs nothing: the next frame's leading one closes it.
    let mut bytes = stream.bytes[..range.end - 1].to_vec();
    bytes.extend_from_slice(&stream.bytes[range.end..]);
    let out = decode(&bytes);
    assert_eq!((out.messages, out.errors), (messages.clone(), vec![]));
    // A stream that ends mid-frame leaves it pending, not delivered.
    let out = decode(&stream.bytes[..range.start + 10]);
    assert_eq!(out.messages, messages[..victim]);
    assert_eq!(out.decoder.pending(), 9);
}

/// The COBS bytes of a frame holding `body` (any bytes) and its CRC, without delimiters.
fn raw_frame(body: &[u8]) -> Vec<u8> {
    let mut with_crc = body.to_vec();
    with_crc.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    let mut encoded = vec![0u8; cobs::max_encoded_len(with_crc.len())];
    let n = cobs::encode(&with_crc, &mut encoded).unwrap();
    encoded.truncate(n);
    encoded
}

#[test]
fn over_long_runs_are_dropped_without_growing() {
    let messages = sample_messages();
    let stream = frame_all(&messages);
    let mut bytes = vec![0xA5u8; 5 * MAX_FRAME_LEN + 17];
    bytes.extend_from_slice(&stream.bytes);
    let mut decoder = FrameDecoder::new();
    let mut out = Vec::new();
    for chunk in bytes.chunks(100) {
        decoder.feed::<DeviceMessage>(chunk, |m| out.push(m));
    }
    assert_eq!(
        out[0],
        Err(FrameError::Overlong {
            len: 5 * MAX_FRAME_LEN + 17
        })
    );
    let good: Vec<_> = out[1..].iter().cloned().map(Result::unwrap).collect();
    assert_eq!(good, messages);
    assert_eq!(decoder.stats().overlong, 1);
    assert_eq!(
        decoder.stats().bytes_discarded,
        5 * MAX_FRAME_LEN as u64 + 17
    );
    // The decoder is one fixed buffer plus counters, whatever it is fed.
    assert!(std::mem::size_of::<FrameDecoder>() < MAX_FRAME_LEN + 128);
}

#[test]
fn frames_at_the_length_limit() {
    // The longest body the encoder produces decodes.
    let body: Vec<u8> = (0..MAX_BODY_LEN).map(|i| (i % 251) as u8 + 1).collect();
    let encoded = raw_frame(&body);
    assert!(encoded.len() <= MAX_FRAME_LEN);
    let mut decoder = FrameDecoder::new();
    let mut delivered = None;
    for &b in encoded.iter().chain(&[0u8]) {
        if let Some(r) = decoder.push(b) {
            delivered = Some(r.map(<[u8]>::to_vec));
        }
    }
    assert_eq!(delivered, Some(Ok(body)));

    // Exactly MAX_FRAME_LEN bytes is accepted; one more is over-long.
    let fill = |len: usize| -> Vec<u8> {
        // Blocks of 0xFF code + 254 data bytes, then a final short block.
        let mut v = Vec::new();
        while v.len() + 255 <= len {
            v.push(0xFF);
            v.extend(std::iter::repeat_n(0x11, 254));
        }
        let rest = len - v.len();
        if rest > 0 {
            v.push(rest as u8);
            v.extend(std::iter::repeat_n(0x22, rest - 1));
        }
        v
    };
    for (len, overlong) in [(MAX_FRAME_LEN, false), (MAX_FRAME_LEN + 1, true)] {
        let mut decoder = FrameDecoder::new();
        let mut result = None;
        for &b in fill(len).iter().chain(&[0u8]) {
            if let Some(r) = decoder.push(b) {
                result = Some(r.map(<[u8]>::len));
            }
        }
        // Random content cannot match its CRC; the point is which check rejects it.
        assert_eq!(
            matches!(result, Some(Err(FrameError::Overlong { .. }))),
            overlong,
            "len {len}"
        );
        assert!(result.unwrap().is_err());
    }
}

#[test]
fn valid_crc_with_an_unknown_body_is_malformed() {
    // Variant 200 does not exist in DeviceMessage.
    let mut bytes = vec![0u8];
    bytes.extend_from_slice(&raw_frame(&[200, 1, 1]));
    bytes.push(0);
    bytes.extend_from_slice(&frame_all(&[DeviceMessage::Pong { seq: 9 }]).bytes);
    let out = decode(&bytes);
    assert_eq!(out.errors, vec![FrameError::Malformed]);
    assert_eq!(out.messages, vec![DeviceMessage::Pong { seq: 9 }]);
    assert_eq!(out.decoder.stats().malformed, 1);
    // Bodies shorter than a CRC and invalid COBS are told apart.
    let out = decode(&[0, 0x02, 0x33, 0, 0x05, 0x01, 0]);
    assert_eq!(out.errors, vec![FrameError::TooShort, FrameError::Cobs]);
}

#[test]
fn encoder_refuses_small_buffers() {
    let mut small = [0u8; 8];
    let message = DeviceMessage::Info(protocol::DeviceInfo {
        protocol_version: 1,
        firmware_version: protocol::FirmwareVersion {
            major: 1,
            minor: 0,
            patch: 0,
        },
        board_id: 1,
        who_am_i: 0x68,
        settings: SensorSettings::default(),
        streaming: false,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    });
    assert_eq!(
        frame::encode(&message, &mut small),
        Err(frame::EncodeError::BufferTooSmall)
    );
}

/// A sanity check of the CRC itself against the catalogue's check value (the CRC of the
/// ASCII string "123456789"; Greg Cook's CRC RevEng catalogue, CRC-32/ISO-HDLC).
#[test]
fn crc_matches_the_catalogue_check_value() {
    assert_eq!(CRC.checksum(b"123456789"), 0xCBF4_3926);
}

//! Every protocol message survives postcard and the full framing unchanged, for arbitrary
//! field values; the largest possible message still fits in one frame.

use imunoise_tests::strategies;
use imunoise_tests::streams::frame_all;
use proptest::prelude::*;
use protocol::frame::{FrameDecoder, MAX_BODY_LEN, MAX_FRAME_LEN};
use protocol::mpu6050::{AccelRange, DlpfCfg, GyroRange, SensorSettings};
use protocol::{
    DeviceInfo, DeviceMessage, FirmwareVersion, MAX_SAMPLES_PER_BATCH, RawSample, Request,
    SampleBatch, Status,
};
use serde::{Serialize, de::DeserializeOwned};
use std::fmt::Debug;

fn through_frames<T: Serialize + DeserializeOwned + PartialEq + Debug + Clone>(messages: &[T]) {
    let stream = frame_all(messages);
    let mut decoder = FrameDecoder::new();
    let mut out = Vec::new();
    decoder.feed::<T>(&stream.bytes, |m| {
        out.push(m.expect("an intact frame decodes"))
    });
    assert_eq!(out, messages);
    assert_eq!(decoder.stats().rejected(), 0);
    assert_eq!(decoder.stats().frames_ok, messages.len() as u64);
}

proptest! {
    #[test]
    fn requests_round_trip(requests in prop::collection::vec(strategies::request(), 1..8)) {
        for r in &requests {
            let body = postcard::to_allocvec(r).unwrap();
            prop_assert_eq!(&postcard::from_bytes::<Request>(&body).unwrap(), r);
        }
        through_frames(&requests);
    }

    #[test]
    fn device_messages_round_trip(messages in prop::collection::vec(strategies::device_message(), 1..8)) {
        for m in &messages {
            let body = postcard::to_allocvec(m).unwrap();
            prop_assert!(body.len() <= MAX_BODY_LEN);
            prop_assert_eq!(&postcard::from_bytes::<DeviceMessage>(&body).unwrap(), m);
        }
        through_frames(&messages);
    }
}

/// The longest sensor entry: an MPU-6050's settings are the widest config.
fn widest_sensor() -> protocol::SensorInfo {
    protocol::SensorInfo {
        kind: protocol::SensorKind::Mpu6050,
        address: u8::MAX,
        id: u8::MAX,
        config: protocol::SensorConfig::Mpu6050(SensorSettings {
            dlpf: DlpfCfg::Cfg7,
            smplrt_div: 255,
            gyro_range: GyroRange::Dps2000,
            accel_range: AccelRange::G16,
        }),
    }
}

/// The widest values postcard can meet: varints at their longest, a full batch.
#[test]
fn the_largest_messages_fit_one_frame() {
    let widest_sample = RawSample {
        accel: [i16::MIN; 3],
        temp: i16::MIN,
        gyro: [i16::MIN; 3],
    };
    let batch = SampleBatch {
        first_index: u64::MAX,
        first_timestamp_us: u64::MAX,
        samples: heapless::Vec::from_slice(&[widest_sample; MAX_SAMPLES_PER_BATCH]).unwrap(),
    };
    let info = DeviceInfo {
        protocol_version: u16::MAX,
        firmware_version: FirmwareVersion {
            major: u16::MAX,
            minor: u16::MAX,
            patch: u16::MAX,
        },
        board_id: u64::MAX,
        who_am_i: u8::MAX,
        settings: SensorSettings {
            dlpf: DlpfCfg::Cfg7,
            smplrt_div: 255,
            gyro_range: GyroRange::Dps2000,
            accel_range: AccelRange::G16,
        },
        streaming: true,
        max_samples_per_batch: u16::MAX,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::of(&[widest_sensor(); protocol::MAX_SENSORS]).unwrap(),
    };
    let status = Status {
        streaming: true,
        uptime_us: u64::MAX,
        samples_acquired: u64::MAX,
        fifo_overflows: u32::MAX,
        samples_lost: u64::MAX,
        i2c_errors: u32::MAX,
        batches_dropped: u32::MAX,
        samples_dropped: u64::MAX,
        frames_rejected: u32::MAX,
        replies_dropped: u32::MAX,
        recoveries: u32::MAX,
        loss_certain: true,
        sample_period_ns: u32::MAX,
    };
    let messages = [
        DeviceMessage::SensorSamples {
            sensor: u8::MAX,
            batch: batch.clone(),
        },
        DeviceMessage::Samples(batch),
        DeviceMessage::Info(info),
        DeviceMessage::Status(status),
    ];
    let stream = frame_all(&messages);
    for range in &stream.frames {
        // Both delimiters aside, the frame is within the decoder's limit.
        assert!(
            range.len() - 2 <= MAX_FRAME_LEN,
            "frame of {} bytes",
            range.len()
        );
    }
    // With the frame number the board appends (a varint, 5 bytes at most), too.
    for message in &messages {
        let mut buf = [0u8; protocol::frame::MAX_WIRE_LEN];
        let n = protocol::frame::encode(&(message, u32::MAX), &mut buf).unwrap();
        assert!(n - 2 <= MAX_FRAME_LEN, "numbered frame of {n} bytes");
    }
    // The full batch of worst-case samples: 7 zigzag varints of 3 bytes each per sample.
    assert!(
        stream.frames[1].len() > 32 * 21,
        "the worst case really was exercised"
    );
    through_frames(&messages);
}

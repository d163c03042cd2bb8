//! The capture decoder against hand-made frame streams.

use super::*;
use protocol::{FirmwareVersion, PROTOCOL_VERSION};

fn info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 7,
        who_am_i: 0x68,
        settings: SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap(),
        streaming: true,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    }
}

fn batch(first: u64, n: usize) -> DeviceMessage {
    let samples = (0..n)
        .map(|i| RawSample {
            gyro: [(first + i as u64) as i16, 0, 0],
            ..RawSample::default()
        })
        .collect();
    DeviceMessage::Samples(SampleBatch {
        first_index: first,
        first_timestamp_us: first * 5000,
        samples,
    })
}

fn capture(messages: &[DeviceMessage]) -> Vec<u8> {
    let mut w = CaptureWriter::new(Vec::new());
    for m in messages {
        w.message(m).unwrap();
    }
    w.into_inner()
}

#[test]
fn round_trip_without_gaps() {
    let bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 10)]);
    assert!(looks_like_capture(&bytes));
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.first().runs.len(), 1);
    let r = c.to_record("cap", false).unwrap();
    assert_eq!(r.rate_hz, 200.0);
    assert_eq!(r.len(), 42);
    assert_eq!(r.names(), ["gx", "gy", "gz", "ax", "ay", "az", "temp"]);
    let lsb = SensorSettings::default().gyro_range.rad_s_per_lsb();
    assert_eq!(r.channels[0].values[41], 41.0 * lsb);
}

#[test]
fn gaps_are_counted_and_never_bridged() {
    let status = Status {
        samples_acquired: 70,
        samples_lost: 10,
        ..Status::default()
    };
    let bytes = capture(&[
        DeviceMessage::Info(info()),
        batch(0, 32),
        batch(40, 32),
        DeviceMessage::Status(status),
    ]);
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.first().gaps(), std::slice::from_ref(&(32..40)));
    assert_eq!(c.first().accounting.lost(), 8);
    assert_eq!(c.status, Some(status));
    let err = c.to_record("cap", false).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("8 samples lost in 1 gap(s) (first at index 32)")
    );
    let r = c.to_record("cap", true).unwrap();
    assert_eq!(r.len(), 32);
    assert_eq!(
        r.channels[0].values[0],
        40.0 * SensorSettings::default().gyro_range.rad_s_per_lsb()
    );
}

#[test]
fn damaged_frames_are_counted() {
    let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)]);
    let second = bytes.len() - 10;
    bytes[second] ^= 0x40;
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.decoder.rejected(), 1);
    assert_eq!(c.first().runs[0].samples.len(), 32);
    assert_eq!(
        Capture::decode(&capture(&[batch(0, 3)])).unwrap_err(),
        CaptureError::NoInfo
    );
}

#[test]
fn a_board_restart_ends_the_run_and_is_recorded() {
    let mut restarted = batch(0, 32);
    if let DeviceMessage::Samples(b) = &mut restarted {
        b.first_timestamp_us = 1234; // another boot, another time
    }
    // With its Info (a reset announces itself) and without (the Info lost on the line).
    for with_info in [true, false] {
        let mut messages = vec![DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)];
        if with_info {
            messages.push(DeviceMessage::Info(info()));
        }
        messages.extend([restarted.clone(), batch(32, 32)]);
        let c = Capture::decode(&capture(&messages)).unwrap();
        assert_eq!(c.first().restarts, [64], "with_info {with_info}");
        assert_eq!(c.first().runs.len(), 2);
        assert_eq!(
            (
                c.first().runs[1].first_index,
                c.first().runs[1].samples.len()
            ),
            (64, 64)
        );
        assert_eq!(
            (c.first().accounting.received(), c.first().accounting.lost()),
            (128, 0)
        );
        let err = c.to_record("cap", false).unwrap_err();
        assert!(err.to_string().contains("restarted 1 time"), "{err}");
        assert_eq!(c.to_record("cap", true).unwrap().len(), 64);
    }
    // A repeated batch (same time) is not a restart.
    let c = Capture::decode(&capture(&[
        DeviceMessage::Info(info()),
        batch(0, 32),
        batch(32, 32),
        batch(0, 32),
    ]))
    .unwrap();
    assert!(c.first().restarts.is_empty());
    assert_eq!(c.first().accounting.out_of_order_batches(), 1);
}

#[test]
fn a_restart_the_host_measured_is_a_counted_gap() {
    let mut restarted = batch(0, 32);
    if let DeviceMessage::Samples(b) = &mut restarted {
        b.first_timestamp_us = 1234;
    }
    let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32), batch(32, 32)]);
    // 1.5 s of silence at the info's output rate.
    let rate = info().settings.output_rate_hz();
    bytes.extend(
        HostNote::BoardRestarted {
            silent_us: 1_500_000,
        }
        .frame(),
    );
    bytes.extend(capture(&[
        DeviceMessage::Info(info()),
        restarted,
        batch(32, 32),
    ]));
    let c = Capture::decode(&bytes).unwrap();
    let lost = (1.5 * rate).round() as u64;
    assert!(c.first().restarts.is_empty());
    assert_eq!(
        c.first().segments,
        [Segment {
            first_index: 64 + lost,
            silent_s: 1.5,
            samples_lost: lost
        }]
    );
    assert_eq!(c.first().gaps(), std::slice::from_ref(&(64..64 + lost)));
    assert_eq!(
        (c.first().accounting.received(), c.first().accounting.lost()),
        (128, lost)
    );
    // The note is a good frame, not a damaged one; an older decoder would skip it.
    assert_eq!(c.decoder.rejected(), 0);
    let mut buf = [0u8; 16];
    let pong = postcard::to_slice(&DeviceMessage::Pong { seq: 1 }, &mut buf).unwrap();
    assert_eq!(HostNote::decode(pong), None);
}

#[test]
fn a_version_2_status_in_a_stored_capture_still_decodes() {
    // Variant 4 (Status) and the nine fields version 2 sent.
    let v2 = (
        4u8,
        true,
        1_000_000u64,
        64u64,
        0u32,
        3u64,
        0u32,
        0u32,
        0u64,
        0u32,
    );
    let mut bytes = capture(&[DeviceMessage::Info(info()), batch(0, 32)]);
    let mut buf = vec![0u8; MAX_WIRE_LEN];
    let n = frame::encode(&v2, &mut buf).unwrap();
    bytes.extend_from_slice(&buf[..n]);
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.status.map(|s| s.samples_lost), Some(3));
    assert_eq!(c.decoder.rejected(), 0);
}

#[test]
fn chunked_decoding_equals_whole() {
    let bytes = capture(&[
        DeviceMessage::Info(info()),
        batch(0, 32),
        batch(40, 32),
        batch(72, 5),
    ]);
    let whole = Capture::decode(&bytes).unwrap();
    for chunk in [1, 3, 64, 1000] {
        let mut d = StreamDecoder::new(true);
        bytes.chunks(chunk).for_each(|c| {
            d.feed(c);
        });
        let c = d.finish().unwrap();
        assert_eq!(c.first().runs, whole.first().runs);
        assert_eq!(c.first().accounting, whole.first().accounting);
    }
}

/// A GY-85 board's Info: the ITG-3200 (sensor 0) at 50 Hz with its 20 Hz filter, the
/// ADXL345 (sensor 1) at `accel_code`'s rate.
fn gy85_info(accel_code: u8) -> DeviceInfo {
    use protocol::adxl345::{Adxl345Range, Adxl345Settings};
    use protocol::itg3200::Itg3200Settings;
    use protocol::mpu6050::DlpfCfg;
    let sensors = protocol::SensorList::of(&[
        SensorInfo {
            kind: SensorKind::Itg3200,
            address: 0x68,
            id: 0x69,
            config: SensorConfig::Itg3200(Itg3200Settings {
                dlpf: DlpfCfg::Cfg4,
                smplrt_div: 19,
            }),
        },
        SensorInfo {
            kind: SensorKind::Adxl345,
            address: 0x53,
            id: 0xE5,
            config: SensorConfig::Adxl345(Adxl345Settings {
                rate_code: accel_code,
                low_power: false,
                range: Adxl345Range::G16,
            }),
        },
    ])
    .unwrap();
    DeviceInfo {
        who_am_i: 0x69,
        settings: SensorSettings::default(),
        sensors,
        ..info()
    }
}

/// Sensor `sensor`'s batch of `n` samples from index `first`, the first made at
/// `start_us + first * period_us`; the gyro's x (or the accel's x) counts the index.
fn sensor_batch(sensor: u8, first: u64, n: usize, start_us: u64, period_us: u64) -> DeviceMessage {
    let samples = (0..n)
        .map(|i| {
            let k = (first + i as u64) as i16;
            match sensor {
                0 => RawSample {
                    gyro: [k, 2, 3],
                    temp: -13200,
                    ..RawSample::default()
                },
                _ => RawSample {
                    accel: [k, 0, 256],
                    ..RawSample::default()
                },
            }
        })
        .collect();
    DeviceMessage::samples_of(
        sensor,
        SampleBatch {
            first_index: first,
            first_timestamp_us: start_us + first * period_us,
            samples,
        },
    )
}

#[test]
fn a_gy85_capture_is_one_record_of_both_sensors_lined_up_in_time() {
    // The ADXL345's samples fall half a period after the ITG-3200's.
    let bytes = capture(&[
        DeviceMessage::Info(gy85_info(0x09)),
        sensor_batch(0, 0, 32, 1_000, 20_000),
        sensor_batch(1, 0, 32, 11_000, 20_000),
        sensor_batch(0, 32, 32, 1_000, 20_000),
        sensor_batch(1, 32, 32, 11_000, 20_000),
    ]);
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.sensors.len(), 2);
    assert_eq!(c.sensors[1].sensor.kind, SensorKind::Adxl345);
    assert_eq!(c.totals().received, 128);
    let (r, used) = c.to_record_with("gy85", false).unwrap();
    assert_eq!(r.names(), ["gx", "gy", "gz", "ax", "ay", "az", "temp"]);
    assert_eq!(r.rate_hz, 50.0);
    // The window both cover starts at the ADXL345's first sample and ends at the
    // ITG-3200's last: one sample of each is left out, and counted.
    assert_eq!(r.len(), 63);
    assert_eq!(
        used.iter().map(|u| (u.used, u.trimmed)).collect::<Vec<_>>(),
        [(63, 1), (63, 1)]
    );
    // Row 0: the ITG-3200's sample 1 (at 21 ms) beside the ADXL345's sample 0 (at 11 ms).
    let itg = protocol::itg3200::rad_s_per_lsb();
    assert_eq!(r.channels[0].values[0], 1.0 * itg);
    assert_eq!(r.channels[3].values[0], 0.0);
    assert_eq!(
        r.channels[5].values[0],
        256.0 * protocol::adxl345::m_s2_per_lsb()
    );
    // The ITG-3200's temperature formula: -13200 counts is 35 degC.
    assert_eq!(r.channels[6].values[0], 35.0);
}

#[test]
fn each_sensor_counts_its_own_losses_faults_and_recoveries() {
    let bytes = capture(&[
        DeviceMessage::Info(gy85_info(0x09)),
        sensor_batch(0, 0, 32, 0, 20_000),
        sensor_batch(1, 0, 32, 0, 20_000),
        DeviceMessage::fault_of(1, ErrorCode::I2cFailure),
        DeviceMessage::recovered_of(1, 2, 40),
        sensor_batch(0, 32, 32, 0, 20_000),
        sensor_batch(1, 40, 24, 0, 20_000),
    ]);
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(c.first().accounting.lost(), 0);
    assert_eq!(c.sensors[1].gaps(), std::slice::from_ref(&(32..40)));
    assert_eq!((c.totals().received, c.totals().lost), (120, 8));
    assert_eq!(c.board_errors.len(), 1);
    assert_eq!(c.board_errors[0].sensor, Some(1));
    assert_eq!(c.board_errors[0].at_index, 32);
    assert!(
        c.board_errors[0]
            .to_string()
            .starts_with("fault of sensor 1: I2C errors persisted"),
        "{}",
        c.board_errors[0]
    );
    let recoveries: Vec<_> = c.recoveries().collect();
    assert_eq!(recoveries.len(), 1);
    assert_eq!(
        (recoveries[0].sensor, recoveries[0].resumed_at_index),
        (1, 40)
    );
    let err = c.to_record("gy85", false).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("sensor 1 (ADXL345): 8 samples lost in 1 gap(s)"),
        "{err}"
    );
    // The longest runs: the ITG-3200's 64 and the ADXL345's 32 before the gap, cut to the
    // time they share (indices 0..32 of both).
    let (r, used) = c.to_record_with("gy85", true).unwrap();
    assert_eq!(r.len(), 32);
    assert_eq!((used[0].used, used[0].trimmed), (32, 32));
    assert_eq!((used[1].used, used[1].trimmed), (32, 0));
    assert_eq!(
        r.channels[0].values[31],
        31.0 * protocol::itg3200::rad_s_per_lsb()
    );
    assert_eq!(
        r.channels[3].values[31],
        31.0 * protocol::adxl345::m_s2_per_lsb()
    );
}

#[test]
fn sensors_at_different_rates_are_kept_apart() {
    let bytes = capture(&[
        DeviceMessage::Info(gy85_info(0x08)),
        sensor_batch(0, 0, 32, 0, 20_000),
        sensor_batch(1, 0, 16, 0, 40_000),
    ]);
    let c = Capture::decode(&bytes).unwrap();
    assert_eq!(
        (
            c.first().accounting.received(),
            c.sensors[1].accounting.received()
        ),
        (32, 16)
    );
    let err = c.to_record("gy85", false).unwrap_err();
    assert_eq!(
        err,
        CaptureError::RatesDiffer {
            rates: "ITG-3200 50 Hz, ADXL345 25 Hz".into()
        }
    );
    // Each sensor alone is a record at its own rate.
    let accel = c.run_record(&c.sensors[1], &c.sensors[1].runs[0], "accel");
    assert_eq!((accel.rate_hz, accel.len()), (25.0, 16));
    assert_eq!(accel.names(), ["ax", "ay", "az"]);
}

#[test]
fn a_board_restart_restarts_every_sensor_stream() {
    let bytes = capture(&[
        DeviceMessage::Info(gy85_info(0x09)),
        sensor_batch(0, 0, 32, 0, 20_000),
        sensor_batch(1, 0, 32, 0, 20_000),
        DeviceMessage::Info(gy85_info(0x09)),
        sensor_batch(0, 0, 32, 0, 20_000),
        sensor_batch(1, 0, 32, 0, 20_000),
    ]);
    let c = Capture::decode(&bytes).unwrap();
    for sensor in &c.sensors {
        assert_eq!(sensor.restarts, [32]);
        assert_eq!(sensor.runs.len(), 2);
        assert_eq!(sensor.accounting.received(), 64);
    }
    assert_eq!(c.restarts(), 1);
}

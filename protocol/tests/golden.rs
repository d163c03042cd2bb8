//! Golden wire vectors: every message of the protocol, framed, as fixed bytes. A field or
//! variant reordered, a type widened, the CRC or the COBS step changed — anything that
//! changes the bytes on the wire — fails here, and must come with a new PROTOCOL_VERSION.
//! (`GOLDEN_PRINT=1 cargo test -p imunoise-protocol --test golden -- --nocapture` prints the
//! bytes the code makes now, for a deliberate protocol change.)

use protocol::adxl345::{Adxl345Range, Adxl345Settings};
use protocol::frame::{MAX_WIRE_LEN, encode};
use protocol::itg3200::Itg3200Settings;
use protocol::mpu6050::{AccelRange, DlpfCfg, GyroRange, SensorSettings};
use protocol::{
    Command, DeviceInfo, DeviceMessage, ErrorCode, FaultKind, FirmwareVersion, RawSample, Request,
    ResetReason, SampleBatch, SensorConfig, SensorInfo, SensorKind, SensorList, Status,
};

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn framed(message: &impl serde::Serialize) -> String {
    let mut buf = [0u8; MAX_WIRE_LEN];
    let n = encode(message, &mut buf).unwrap();
    hex(&buf[..n])
}

fn check(name: &str, got: String, want: &str) {
    if std::env::var_os("GOLDEN_PRINT").is_some() {
        println!("(\"{name}\", \"{got}\"),");
        return;
    }
    assert_eq!(got, want, "{name}: the bytes on the wire changed");
}

fn settings() -> SensorSettings {
    SensorSettings {
        dlpf: DlpfCfg::Cfg3,
        smplrt_div: 4,
        gyro_range: GyroRange::Dps500,
        accel_range: AccelRange::G4,
    }
}

fn requests() -> Vec<(&'static str, Request)> {
    let r = |seq, command| Request { seq, command };
    vec![
        ("GetInfo", r(1, Command::GetInfo)),
        ("Configure", r(2, Command::Configure(settings()))),
        ("Start", r(3, Command::Start)),
        ("Stop", r(4, Command::Stop)),
        ("Ping", r(300, Command::Ping)),
        ("GetStatus", r(65535, Command::GetStatus)),
        (
            "ConfigureSensor",
            r(
                5,
                Command::ConfigureSensor {
                    sensor: 1,
                    config: SensorConfig::Adxl345(adxl345()),
                },
            ),
        ),
    ]
}

fn adxl345() -> Adxl345Settings {
    Adxl345Settings {
        rate_code: 0x09,
        low_power: false,
        range: Adxl345Range::G16,
    }
}

/// A GY-85 board's sensors.
fn gy85() -> SensorList {
    SensorList::of(&[
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
            config: SensorConfig::Adxl345(adxl345()),
        },
    ])
    .unwrap()
}

fn messages() -> Vec<(&'static str, DeviceMessage)> {
    let sample = |k: i16| RawSample {
        accel: [k, -k, 16384],
        temp: -3504 + k,
        gyro: [131 * k, i16::MIN, i16::MAX],
    };
    vec![
        (
            "Info",
            DeviceMessage::Info(DeviceInfo {
                protocol_version: 4,
                firmware_version: FirmwareVersion {
                    major: 0,
                    minor: 1,
                    patch: 2,
                },
                board_id: 0xE660_4130_2B1C_3A25,
                who_am_i: 0x70,
                settings: settings(),
                streaming: true,
                max_samples_per_batch: 32,
                reset_reason: ResetReason::Watchdog,
                sensors: gy85(),
            }),
        ),
        ("Ack", DeviceMessage::Ack { seq: 7 }),
        (
            "Nack",
            DeviceMessage::Nack {
                seq: 8,
                error: ErrorCode::VerifyFailed {
                    register: 0x6B,
                    wrote: 0x01,
                    read: 0x40,
                },
            },
        ),
        (
            "Samples",
            DeviceMessage::Samples(SampleBatch {
                first_index: 1_000_000,
                first_timestamp_us: 123_456_789,
                samples: heapless::Vec::from_slice(&[sample(1), sample(2)]).unwrap(),
            }),
        ),
        (
            "Status",
            DeviceMessage::Status(Status {
                streaming: true,
                uptime_us: 3_600_000_000,
                samples_acquired: 720_000,
                fifo_overflows: 1,
                samples_lost: 416,
                i2c_errors: 12,
                batches_dropped: 2,
                samples_dropped: 64,
                frames_rejected: 3,
                replies_dropped: 0,
                recoveries: 1,
                loss_certain: true,
                sample_period_ns: 4_987_654,
            }),
        ),
        ("Pong", DeviceMessage::Pong { seq: 9 }),
        (
            "Fault",
            DeviceMessage::Fault(ErrorCode::GaveUp {
                attempts: 605,
                last: FaultKind::SensorNotResponding,
                ended_at: 1_000_000_000,
            }),
        ),
        (
            "Recovered",
            DeviceMessage::Recovered {
                attempts: 6,
                resumed_at_index: 24_483,
            },
        ),
        (
            "SensorSamples",
            DeviceMessage::SensorSamples {
                sensor: 1,
                batch: SampleBatch {
                    first_index: 7,
                    first_timestamp_us: 20_000,
                    samples: heapless::Vec::from_slice(&[RawSample {
                        accel: [-3, 5, 256],
                        temp: 0,
                        gyro: [0; 3],
                    }])
                    .unwrap(),
                },
            },
        ),
        (
            "SensorFault",
            DeviceMessage::SensorFault {
                sensor: 1,
                error: ErrorCode::SensorReset,
            },
        ),
        (
            "SensorRecovered",
            DeviceMessage::SensorRecovered {
                sensor: 1,
                attempts: 1,
                resumed_at_index: 900,
            },
        ),
    ]
}

/// Every error code, each in a Nack (their variant indices are part of the wire too).
fn error_codes() -> Vec<(&'static str, ErrorCode)> {
    vec![
        ("Busy", ErrorCode::Busy),
        ("NotStreaming", ErrorCode::NotStreaming),
        ("InvalidSettings", ErrorCode::InvalidSettings),
        ("SensorNotResponding", ErrorCode::SensorNotResponding),
        ("WrongSensor", ErrorCode::WrongSensor { who_am_i: 0x71 }),
        ("I2cFailure", ErrorCode::I2cFailure),
        (
            "FifoCountImplausible",
            ErrorCode::FifoCountImplausible { count: 0x1C0 },
        ),
        ("UnknownCommand", ErrorCode::UnknownCommand),
        ("SensorReset", ErrorCode::SensorReset),
        (
            "GaveUp",
            ErrorCode::GaveUp {
                attempts: 3,
                last: FaultKind::I2cFailure,
                ended_at: 12,
            },
        ),
        ("NoSuchSensor", ErrorCode::NoSuchSensor { sensor: 2 }),
    ]
}

const REQUESTS: &[(&str, &str)] = &[
    ("GetInfo", "00020105be23c25800"),
    ("Configure", "000b020103040101fd2fcaba00"),
    ("Start", "000703021020fa8400"),
    ("Stop", "000704034186bcbc00"),
    ("Ping", "0008ac02048ddb781a00"),
    ("GetStatus", "0009ffff03054c4a9e1a00"),
    ("ConfigureSensor", "000605060102090603ca98bc1800"),
];
const MESSAGES: &[(&str, &str)] = &[
    (
        "Info",
        "00010204220102a5f4f0d882a690b0e601700304010101200301016869010413010253e502090903f0a204d9f92d9300",
    ),
    ("Ack", "000a0107f0a204b68f0d4800"),
    ("Nack", "000e0208056b0140f0a2048ceffda300"),
    (
        "Samples",
        "002f03c0843d959aef3a020201808002dd368602ffff03feff030403808002db368c04ffff03feff03f0a204f10cfa3100",
    ),
    (
        "Status",
        "0012040180c8ceb40d80f92b01a0030c0240030e010186b6b002f0a2040c3ca35000",
    ),
    ("Pong", "000a0509f0a204455e525d00"),
    ("Fault", "0005060add040d8094ebdc03f0a204581c91cc00"),
    ("Recovered", "000d0706a3bf01f0a20408110c9700"),
    (
        "SensorSamples",
        "000c080107a09c0101050a800401010108f0a2048710a2ef00",
    ),
    ("SensorFault", "000b090109f0a204f3ff3df800"),
    ("SensorRecovered", "000d0a01018407f0a204f95ce06e00"),
];
const ERROR_CODES: &[(&str, &str)] = &[
    ("Busy", "0003020108f0a204ba40f2ef00"),
    ("NotStreaming", "000b020101f0a204df274e5700"),
    ("InvalidSettings", "000b020102f0a2043188fb4500"),
    ("SensorNotResponding", "000b020103f0a20454ef47fd00"),
    ("WrongSensor", "000c02010471f0a204691534c900"),
    ("I2cFailure", "000b020106f0a204661f99ca00"),
    ("FifoCountImplausible", "000d020107c003f0a2048fcd4d4900"),
    ("UnknownCommand", "000b020108f0a2045568462a00"),
    ("SensorReset", "000b020109f0a204300ffa9200"),
    ("GaveUp", "000e02010a03030cf0a2049cbd5f0500"),
    ("NoSuchSensor", "000c02010b02f0a204ca8dee3200"),
];

fn run<T: serde::Serialize>(cases: Vec<(&'static str, T)>, golden: &[(&str, &str)]) {
    let print = std::env::var_os("GOLDEN_PRINT").is_some();
    assert!(
        print || cases.len() == golden.len(),
        "a case without golden bytes"
    );
    for (k, (name, message)) in cases.iter().enumerate() {
        let want = golden.get(k).map_or("", |g| {
            assert_eq!(g.0, *name);
            g.1
        });
        check(name, framed(message), want);
    }
}

#[test]
fn every_request_is_on_the_wire_as_it_always_was() {
    run(requests(), REQUESTS);
}

/// A device frame as the board sends it: the message, then its frame number.
fn numbered(message: DeviceMessage) -> (DeviceMessage, u32) {
    (message, 70_000)
}

#[test]
fn every_device_message_is_on_the_wire_as_it_always_was() {
    run(
        messages()
            .into_iter()
            .map(|(name, m)| (name, numbered(m)))
            .collect(),
        MESSAGES,
    );
}

#[test]
fn every_error_code_is_on_the_wire_as_it_always_was() {
    let nacks = error_codes()
        .into_iter()
        .map(|(name, error)| (name, numbered(DeviceMessage::Nack { seq: 1, error })))
        .collect();
    run(nacks, ERROR_CODES);
}

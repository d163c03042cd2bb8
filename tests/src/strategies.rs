//! proptest strategies for every protocol type, covering each field's whole range.

use proptest::prelude::*;
use protocol::adxl345::{Adxl345Range, Adxl345Settings};
use protocol::itg3200::Itg3200Settings;
use protocol::mpu6050::{AccelRange, DlpfCfg, GyroRange, SensorSettings};
use protocol::{
    Command, DeviceInfo, DeviceMessage, ErrorCode, FaultKind, FirmwareVersion,
    MAX_SAMPLES_PER_BATCH, RawSample, Request, SampleBatch, SensorConfig, SensorInfo, SensorList,
    Status,
};

pub fn settings() -> impl Strategy<Value = SensorSettings> {
    (
        prop::sample::select(DlpfCfg::ALL.to_vec()),
        any::<u8>(),
        prop::sample::select(GyroRange::ALL.to_vec()),
        prop::sample::select(AccelRange::ALL.to_vec()),
    )
        .prop_map(
            |(dlpf, smplrt_div, gyro_range, accel_range)| SensorSettings {
                dlpf,
                smplrt_div,
                gyro_range,
                accel_range,
            },
        )
}

pub fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::GetInfo),
        settings().prop_map(Command::Configure),
        Just(Command::Start),
        Just(Command::Stop),
        Just(Command::Ping),
        Just(Command::GetStatus),
        (any::<u8>(), sensor_info()).prop_map(|(sensor, info)| Command::ConfigureSensor {
            sensor,
            config: info.config
        }),
    ]
}

pub fn request() -> impl Strategy<Value = Request> {
    (any::<u16>(), command()).prop_map(|(seq, command)| Request { seq, command })
}

pub fn raw_sample() -> impl Strategy<Value = RawSample> {
    (any::<[i16; 3]>(), any::<i16>(), any::<[i16; 3]>()).prop_map(|(accel, temp, gyro)| RawSample {
        accel,
        temp,
        gyro,
    })
}

pub fn sample_batch() -> impl Strategy<Value = SampleBatch> {
    (
        any::<u64>(),
        any::<u64>(),
        prop::collection::vec(raw_sample(), 0..=MAX_SAMPLES_PER_BATCH),
    )
        .prop_map(|(first_index, first_timestamp_us, samples)| SampleBatch {
            first_index,
            first_timestamp_us,
            samples: heapless::Vec::from_slice(&samples).expect("at most MAX_SAMPLES_PER_BATCH"),
        })
}

pub fn device_info() -> impl Strategy<Value = DeviceInfo> {
    (
        any::<u16>(),
        any::<(u16, u16, u16)>(),
        any::<u64>(),
        any::<u8>(),
        settings(),
        any::<bool>(),
        any::<u16>(),
        sensor_list(),
    )
        .prop_map(
            |(
                protocol_version,
                (major, minor, patch),
                board_id,
                who_am_i,
                settings,
                streaming,
                max,
                sensors,
            )| DeviceInfo {
                protocol_version,
                firmware_version: FirmwareVersion {
                    major,
                    minor,
                    patch,
                },
                board_id,
                who_am_i,
                settings,
                streaming,
                max_samples_per_batch: max,
                reset_reason: protocol::ResetReason::Unknown,
                sensors,
            },
        )
}

/// Any sensor a board can list, with any settings of its kind.
pub fn sensor_info() -> impl Strategy<Value = SensorInfo> {
    let config = prop_oneof![
        settings().prop_map(SensorConfig::Mpu6050),
        (prop::sample::select(DlpfCfg::ALL.to_vec()), any::<u8>()).prop_map(
            |(dlpf, smplrt_div)| { SensorConfig::Itg3200(Itg3200Settings { dlpf, smplrt_div }) }
        ),
        (
            0u8..16,
            any::<bool>(),
            prop::sample::select(Adxl345Range::ALL.to_vec())
        )
            .prop_map(|(rate_code, low_power, range)| {
                SensorConfig::Adxl345(Adxl345Settings {
                    rate_code,
                    low_power,
                    range,
                })
            }),
    ];
    (any::<u8>(), any::<u8>(), config).prop_map(|(address, id, config)| SensorInfo {
        kind: config.kind(),
        address,
        id,
        config,
    })
}

/// Up to [`protocol::MAX_SENSORS`] sensors.
pub fn sensor_list() -> impl Strategy<Value = SensorList> {
    prop::collection::vec(sensor_info(), 0..=protocol::MAX_SENSORS)
        .prop_map(|sensors| SensorList::of(&sensors).expect("at most MAX_SENSORS"))
}

pub fn status() -> impl Strategy<Value = Status> {
    (
        any::<bool>(),
        any::<(u64, u64, u64)>(),
        any::<(u32, u32, u32, u32)>(),
        any::<u64>(),
        any::<(u32, u32, bool, u32)>(),
    )
        .prop_map(
            |(
                streaming,
                (uptime_us, samples_acquired, samples_lost),
                (fifo_overflows, i2c_errors, batches_dropped, frames_rejected),
                samples_dropped,
                (replies_dropped, recoveries, loss_certain, sample_period_ns),
            )| Status {
                streaming,
                uptime_us,
                samples_acquired,
                fifo_overflows,
                samples_lost,
                i2c_errors,
                batches_dropped,
                samples_dropped,
                frames_rejected,
                replies_dropped,
                recoveries,
                loss_certain,
                sample_period_ns,
            },
        )
}

pub fn error_code() -> impl Strategy<Value = ErrorCode> {
    prop_oneof![
        Just(ErrorCode::Busy),
        Just(ErrorCode::NotStreaming),
        Just(ErrorCode::InvalidSettings),
        Just(ErrorCode::SensorNotResponding),
        any::<u8>().prop_map(|who_am_i| ErrorCode::WrongSensor { who_am_i }),
        any::<(u8, u8, u8)>().prop_map(|(register, wrote, read)| ErrorCode::VerifyFailed {
            register,
            wrote,
            read
        }),
        Just(ErrorCode::I2cFailure),
        any::<u16>().prop_map(|count| ErrorCode::FifoCountImplausible { count }),
        Just(ErrorCode::UnknownCommand),
        Just(ErrorCode::SensorReset),
        any::<u8>().prop_map(|sensor| ErrorCode::NoSuchSensor { sensor }),
        (any::<u16>(), 0..7u8, any::<u64>()).prop_map(|(attempts, k, ended_at)| {
            ErrorCode::GaveUp {
                ended_at,
                attempts,
                last: [
                    FaultKind::SensorNotResponding,
                    FaultKind::WrongSensor,
                    FaultKind::VerifyFailed,
                    FaultKind::I2cFailure,
                    FaultKind::FifoCountImplausible,
                    FaultKind::SensorReset,
                    FaultKind::Other,
                ][usize::from(k)],
            }
        }),
    ]
}

pub fn device_message() -> impl Strategy<Value = DeviceMessage> {
    prop_oneof![
        device_info().prop_map(DeviceMessage::Info),
        any::<u16>().prop_map(|seq| DeviceMessage::Ack { seq }),
        (any::<u16>(), error_code()).prop_map(|(seq, error)| DeviceMessage::Nack { seq, error }),
        sample_batch().prop_map(DeviceMessage::Samples),
        status().prop_map(DeviceMessage::Status),
        any::<u16>().prop_map(|seq| DeviceMessage::Pong { seq }),
        error_code().prop_map(DeviceMessage::Fault),
        any::<(u16, u64)>().prop_map(|(attempts, resumed_at_index)| DeviceMessage::Recovered {
            attempts,
            resumed_at_index
        }),
        (1..=u8::MAX, sample_batch())
            .prop_map(|(sensor, batch)| DeviceMessage::SensorSamples { sensor, batch }),
        (1..=u8::MAX, error_code())
            .prop_map(|(sensor, error)| DeviceMessage::SensorFault { sensor, error }),
        (1..=u8::MAX, any::<(u16, u64)>()).prop_map(|(sensor, (attempts, resumed_at_index))| {
            DeviceMessage::SensorRecovered {
                sensor,
                attempts,
                resumed_at_index,
            }
        }),
    ]
}

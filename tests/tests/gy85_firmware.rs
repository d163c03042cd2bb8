//! The portable firmware on a GY-85 board (an ITG-3200 and an ADXL345 on one simulated I2C
//! bus): what the probe finds where, the sensor list and per-sensor settings, both sensors
//! streamed without a loss at equal and at different rates, a fault of one sensor that the
//! other does not see (recovered, or given up on), a Start that starts both or neither, and
//! a sensor whose clock runs fast.

use firmware::{BoardConfig, Firmware};
use imunoise::link::accounting::SampleAccounting;
use imunoise::link::shared_bus::SharedBus;
use imunoise::sim::device::{
    BusChip, JournalEntry, Outage, SensorClock, SimAdxl345, SimBus, SimChip, SimItg3200, SimMpu6050,
};
use imunoise_tests::models::gy85_model as model;
use protocol::adxl345::{Adxl345Range, Adxl345Settings};
use protocol::frame::{FrameDecoder, MAX_WIRE_LEN, encode};
use protocol::itg3200::Itg3200Settings;
use protocol::mpu6050::DlpfCfg;
use protocol::{
    Command, DeviceFrame, DeviceInfo, DeviceMessage, ErrorCode, RawSample, Request, SampleBatch,
    SensorConfig, SensorKind, SensorSettings, Status,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct NoDelay;
impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _: u32) {}
}

fn itg(address: u8) -> BusChip {
    BusChip::Itg3200(SimItg3200::new(model(), 7).with_address(address))
}

fn adxl(address: u8) -> BusChip {
    BusChip::Adxl345(SimAdxl345::new(model(), 8).with_address(address))
}

/// The GY-85 at its usual addresses.
fn gy85() -> Vec<BusChip> {
    vec![itg(0x68), adxl(0x53)]
}

/// 50 Hz on both: the ITG-3200 at 1 kHz / (1 + 19) with the 20 Hz filter, the ADXL345 at
/// rate code 0x09 (3200 Hz / 2^6).
fn at_50_hz() -> (Itg3200Settings, Adxl345Settings) {
    (
        Itg3200Settings {
            dlpf: DlpfCfg::Cfg4,
            smplrt_div: 19,
        },
        Adxl345Settings {
            rate_code: 0x09,
            low_power: false,
            range: Adxl345Range::G2,
        },
    )
}

/// A GY-85 board with `gyro` and `accel` set.
fn configured(gyro: Itg3200Settings, accel: Adxl345Settings) -> Board {
    let mut b = Board::new(gy85());
    b.ack(Command::ConfigureSensor {
        sensor: 0,
        config: SensorConfig::Itg3200(gyro),
    });
    b.ack(Command::ConfigureSensor {
        sensor: 1,
        config: SensorConfig::Adxl345(accel),
    });
    b
}

/// A GY-85 board streaming both sensors at 50 Hz, and when it started.
fn streaming_at_50_hz() -> (Board, u64) {
    let (gyro, accel) = at_50_hz();
    let mut b = configured(gyro, accel);
    b.ack(Command::Start);
    let t0 = b.now();
    (b, t0)
}

/// A board: firmware on the shared bus, and what the host decoded, per sensor.
struct Board {
    bus: SharedBus,
    fw: Firmware<SharedBus, SharedBus>,
    boot: Result<(), ErrorCode>,
    decoder: FrameDecoder,
    seq: u16,
    replies: Vec<DeviceMessage>,
    batches: [Vec<SampleBatch>; 2],
    jitter: ChaCha8Rng,
}

impl Board {
    fn new(chips: Vec<BusChip>) -> Self {
        let bus = SharedBus::new(SimBus::new(chips));
        let mut fw = Firmware::new(
            bus.clone(),
            bus.clone(),
            BoardConfig {
                board_id: 0x6785,
                reset_reason: protocol::ResetReason::Unknown,
            },
        );
        let boot = fw.init(&mut NoDelay);
        Board {
            bus,
            fw,
            boot,
            decoder: FrameDecoder::new(),
            seq: 0,
            replies: Vec::new(),
            batches: [Vec::new(), Vec::new()],
            jitter: ChaCha8Rng::seed_from_u64(85),
        }
    }

    fn receive(&mut self, bytes: &[u8]) -> Vec<DeviceMessage> {
        let mut msgs = Vec::new();
        self.decoder.feed_with(bytes, DeviceFrame::decode, |m| {
            msgs.push(m.expect("board frames decode").message)
        });
        let mut replies = Vec::new();
        for m in msgs {
            match m.sensor_samples() {
                Some((sensor, batch)) => self.batches[usize::from(sensor)].push(batch.clone()),
                None => replies.push(m),
            }
        }
        self.replies.extend(replies.iter().cloned());
        replies
    }

    /// Send a command; the replies it produced (not sample batches).
    fn command(&mut self, command: Command) -> Vec<DeviceMessage> {
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_WIRE_LEN];
        let n = encode(
            &Request {
                seq: self.seq,
                command,
            },
            &mut buf,
        )
        .unwrap();
        let mut wire = Vec::new();
        self.fw.handle_bytes(&buf[..n], &mut |f| {
            wire.extend_from_slice(f);
            true
        });
        self.receive(&wire)
    }

    fn ack(&mut self, command: Command) {
        let replies = self.command(command);
        assert!(
            matches!(replies.first(), Some(DeviceMessage::Ack { .. })),
            "{command:?}: {replies:?}"
        );
    }

    fn info(&mut self) -> DeviceInfo {
        match self.command(Command::GetInfo).as_slice() {
            [DeviceMessage::Info(i)] => *i,
            other => panic!("{other:?}"),
        }
    }

    fn status(&mut self) -> Status {
        match self.command(Command::GetStatus).as_slice() {
            [DeviceMessage::Status(s)] => *s,
            other => panic!("{other:?}"),
        }
    }

    fn now(&self) -> u64 {
        self.bus.lock().time_us()
    }

    /// Let `for_us` pass, polling every `step_us` on average (jittered by half of it either
    /// way, as a board's main loop is, so that the drains fall at every phase of the sample
    /// grids and pin them).
    fn run_for(&mut self, for_us: u64, step_us: u64) {
        let end = self.now() + for_us;
        let mut t = self.now();
        while t < end {
            let step = self.jitter.random_range(step_us / 2..=step_us * 3 / 2);
            t = (t + step).min(end);
            self.bus.lock().set_time_us(t);
            let mut wire = Vec::new();
            self.fw.poll(&mut |f| {
                wire.extend_from_slice(f);
                true
            });
            self.receive(&wire);
        }
    }

    /// Every sample of `sensor`, in index order, with its index.
    fn samples(&self, sensor: usize) -> Vec<(u64, RawSample)> {
        self.batches[sensor]
            .iter()
            .flat_map(|b| (b.first_index..).zip(b.samples.iter().copied()))
            .collect()
    }
}

/// Sensor `sensor`'s indices checked: from 0, each once and in order, gaps listed.
fn accounting(board: &Board, sensor: usize) -> SampleAccounting {
    let mut acc = SampleAccounting::new();
    for b in &board.batches[sensor] {
        acc.batch(b.first_index, b.samples.len()).unwrap();
    }
    acc
}

fn delivered(board: &Board, sensor: usize) -> u64 {
    board.batches[sensor]
        .iter()
        .map(|b| b.samples.len() as u64)
        .sum()
}

/// What a chip made after the journal was last taken: the samples its buffer kept (the
/// ITG-3200 has none: all of them).
fn made(entries: Vec<JournalEntry>, buffered: bool) -> Vec<RawSample> {
    entries
        .into_iter()
        .filter_map(|e| match e {
            JournalEntry::Sample { raw, in_fifo, .. } if in_fifo || !buffered => Some(raw),
            _ => None,
        })
        .collect()
}

#[test]
fn the_probe_finds_each_layout() {
    let kinds = |info: &DeviceInfo| -> Vec<(SensorKind, u8, u8)> {
        info.sensors
            .iter()
            .map(|s| (s.kind, s.address, s.id))
            .collect()
    };
    let mut b = Board::new(gy85());
    assert_eq!(b.boot, Ok(()));
    let info = b.info();
    assert_eq!(
        kinds(&info),
        [
            (SensorKind::Itg3200, 0x68, 0x68),
            (SensorKind::Adxl345, 0x53, 0xE5)
        ]
    );
    assert_eq!(info.who_am_i, 0x68);
    assert_eq!(
        info.sensors.get(0).map(|s| s.config),
        Some(SensorConfig::Itg3200(Itg3200Settings::default()))
    );
    assert_eq!(
        info.sensors.get(1).map(|s| s.config),
        Some(SensorConfig::Adxl345(Adxl345Settings::default()))
    );

    let mut b = Board::new(vec![adxl(0x1D), itg(0x69)]);
    assert_eq!(
        kinds(&b.info()),
        [
            (SensorKind::Itg3200, 0x69, 0x68),
            (SensorKind::Adxl345, 0x1D, 0xE5)
        ]
    );

    let mut b = Board::new(vec![BusChip::Mpu6050(SimMpu6050::new(model(), 1))]);
    assert_eq!(b.boot, Ok(()));
    assert_eq!(kinds(&b.info()), [(SensorKind::Mpu6050, 0x68, 0x68)]);

    let mut b = Board::new(vec![adxl(0x53)]);
    assert_eq!(kinds(&b.info()), [(SensorKind::Adxl345, 0x53, 0xE5)]);

    let mut b = Board::new(Vec::new());
    assert_eq!(b.boot, Err(ErrorCode::SensorNotResponding));
    let info = b.info();
    assert!(info.sensors.is_empty());
    assert_eq!(info.who_am_i, 0);
    assert!(matches!(
        b.command(Command::Start)[..],
        [DeviceMessage::Nack {
            error: ErrorCode::SensorNotResponding,
            ..
        }]
    ));
}

#[test]
fn each_sensor_takes_its_own_settings() {
    let (gyro, accel) = at_50_hz();
    let mut b = configured(gyro, accel);
    {
        let mut bus = b.bus.lock();
        assert_eq!(bus.itg3200_mut().unwrap().settings(), gyro);
        assert_eq!(bus.adxl345_mut().unwrap().settings(), accel);
    }
    let info = b.info();
    assert_eq!(
        info.sensors.iter().map(|s| s.config).collect::<Vec<_>>(),
        [SensorConfig::Itg3200(gyro), SensorConfig::Adxl345(accel)]
    );
    let refusals = [
        (
            Command::ConfigureSensor {
                sensor: 2,
                config: SensorConfig::Adxl345(accel),
            },
            ErrorCode::NoSuchSensor { sensor: 2 },
        ),
        (
            Command::ConfigureSensor {
                sensor: 1,
                config: SensorConfig::Itg3200(gyro),
            },
            ErrorCode::NoSuchSensor { sensor: 1 },
        ),
        // 3200 Hz: above what this firmware streams from an ADXL345.
        (
            Command::ConfigureSensor {
                sensor: 1,
                config: SensorConfig::Adxl345(Adxl345Settings {
                    rate_code: 0x0F,
                    ..accel
                }),
            },
            ErrorCode::InvalidSettings,
        ),
        // Sensor 0 is no MPU-6050.
        (
            Command::Configure(SensorSettings::default()),
            ErrorCode::InvalidSettings,
        ),
    ];
    for (command, error) in refusals {
        let replies = b.command(command);
        assert!(
            matches!(replies[..], [DeviceMessage::Nack { error: e, .. }] if e == error),
            "{command:?}: {replies:?}"
        );
    }
    // A refusal leaves the settings as they were.
    assert_eq!(b.info().sensors, info.sensors);
}

/// Five simulated minutes at 50 Hz on both sensors, polled every 2 ms: every index of each
/// sensor arrives once, as many as its rate times the time streamed (within the one sample
/// the phase of its grid may add or take), and each is the sample the chip made.
#[test]
fn both_sensors_stream_every_sample_at_50_hz() {
    let (gyro, accel) = at_50_hz();
    let mut b = configured(gyro, accel);
    {
        let mut bus = b.bus.lock();
        bus.itg3200_mut().unwrap().keep_journal();
        bus.adxl345_mut().unwrap().keep_journal();
    }
    b.ack(Command::Start);
    {
        // What the chips made before Start is not the run's.
        let mut bus = b.bus.lock();
        bus.itg3200_mut().unwrap().take_journal();
        bus.adxl345_mut().unwrap().take_journal();
    }
    let t0 = b.now();
    b.run_for(300_000_000, 2_000);
    b.ack(Command::Stop);
    let elapsed_s = (b.now() - t0) as f64 / 1e6;
    let status = b.status();
    assert_eq!(status.samples_lost, 0);
    assert!(status.loss_certain);
    assert_eq!(status.sample_period_ns, 20_000_000);
    for sensor in 0..2 {
        let acc = accounting(&b, sensor);
        assert!(acc.gaps().is_empty(), "sensor {sensor}: {:?}", acc.gaps());
        let n = delivered(&b, sensor) as f64;
        assert!((n - elapsed_s * 50.0).abs() <= 1.0, "sensor {sensor}: {n}");
    }
    assert_eq!(status.samples_acquired, delivered(&b, 0) + delivered(&b, 1));
    let (gyro_truth, accel_truth) = {
        let mut bus = b.bus.lock();
        let g = bus.itg3200_mut().unwrap().take_journal();
        let a = bus.adxl345_mut().unwrap().take_journal();
        (made(g, false), made(a, true))
    };
    let gyro_got: Vec<RawSample> = b.samples(0).into_iter().map(|(_, s)| s).collect();
    let accel_got: Vec<RawSample> = b.samples(1).into_iter().map(|(_, s)| s).collect();
    assert_eq!(gyro_got, gyro_truth);
    assert_eq!(accel_got, accel_truth);
    assert!(gyro_got.iter().all(|s| s.accel == [0; 3]));
    assert!(accel_got.iter().all(|s| s.gyro == [0; 3] && s.temp == 0));
}

/// ITG-3200 at 100 Hz, ADXL345 at 25 Hz, one simulated minute: each its own count.
#[test]
fn sensors_at_different_rates_keep_their_own_numbering() {
    let accel = Adxl345Settings {
        rate_code: 0x08,
        ..Adxl345Settings::default()
    };
    let mut b = configured(Itg3200Settings::default(), accel);
    b.ack(Command::Start);
    let t0 = b.now();
    b.run_for(60_000_000, 2_000);
    b.ack(Command::Stop);
    let elapsed_s = (b.now() - t0) as f64 / 1e6;
    for (sensor, rate) in [(0, 100.0), (1, 25.0)] {
        assert!(accounting(&b, sensor).gaps().is_empty());
        let n = delivered(&b, sensor) as f64;
        assert!((n - elapsed_s * rate).abs() <= 1.0, "sensor {sensor}: {n}");
    }
    assert_eq!(b.status().samples_lost, 0);
}

/// The ADXL345 drops off the bus for 2 s, later resets itself: sensor 1 reports each fault
/// and its recovery, its indices jump over exactly what the board counted lost, and the
/// ITG-3200's stream goes on without a gap.
#[test]
fn a_fault_of_the_accelerometer_leaves_the_gyro_streaming() {
    let (mut b, t0) = streaming_at_50_hz();
    {
        let mut bus = b.bus.lock();
        let chip = bus.adxl345_mut().unwrap();
        chip.faults_mut().i2c_outages.push(Outage {
            at_us: t0 + 10_000_000,
            for_us: 2_000_000,
        });
        chip.schedule_reset(t0 + 30_000_000);
    }
    b.run_for(60_000_000, 2_000);
    b.ack(Command::Stop);
    let elapsed_s = (b.now() - t0) as f64 / 1e6;
    let events: Vec<String> = b
        .replies
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Fault(_) | DeviceMessage::Recovered { .. } => Some(format!("{m:?}")),
            DeviceMessage::SensorFault { sensor, error } => {
                Some(format!("fault {sensor} {error:?}"))
            }
            DeviceMessage::SensorRecovered { sensor, .. } => Some(format!("recovered {sensor}")),
            _ => None,
        })
        .collect();
    assert_eq!(
        events,
        [
            "fault 1 SensorNotResponding",
            "recovered 1",
            "fault 1 SensorReset",
            "recovered 1"
        ]
    );
    let gyro = accounting(&b, 0);
    assert!(gyro.gaps().is_empty(), "{:?}", gyro.gaps());
    let n0 = delivered(&b, 0) as f64;
    assert!((n0 - elapsed_s * 50.0).abs() <= 1.0, "{n0}");

    let accel = accounting(&b, 1);
    let gaps = accel.gaps();
    assert_eq!(gaps.len(), 2, "{gaps:?}");
    let lost: u64 = gaps.iter().map(|g| g.end - g.start).sum();
    let status = b.status();
    assert_eq!(status.samples_lost, lost);
    assert_eq!(status.recoveries, 2);
    assert!(status.loss_certain);
    // The outage's 2 s (100 samples) at least, plus the 0.5 s of failing drains before the
    // fault is declared and the backoff of the attempts (at most 1 s more).
    let outage = gaps[0].end - gaps[0].start;
    assert!((100..=175).contains(&outage), "{outage}");
    // Every sample the ADXL345 made while streamed is delivered or counted lost.
    let n1 = (delivered(&b, 1) + lost) as f64;
    assert!((n1 - elapsed_s * 50.0).abs() <= 1.0, "{n1}");
}

/// The ADXL345's oscillator runs 0.3 % fast and drifts 100 ppm an hour; the ITG-3200's is
/// exact. Each sensor's count follows its own clock and nothing is lost.
#[test]
fn a_fast_clock_on_one_chip_moves_only_its_count() {
    let (gyro, accel) = at_50_hz();
    let mut b = configured(gyro, accel);
    let (ppm, drift) = (3000.0, 100.0);
    // Set before any time passes: the chip's oscillator runs so from its start.
    b.bus.lock().adxl345_mut().unwrap().faults_mut().clock = SensorClock {
        ppm,
        drift_ppm_per_hour: drift,
    };
    b.ack(Command::Start);
    let t0 = b.now();
    b.run_for(300_000_000, 2_000);
    b.ack(Command::Stop);
    let (t0_s, t1_s) = (t0 as f64 / 1e6, b.now() as f64 / 1e6);
    let status = b.status();
    assert_eq!(status.samples_lost, 0);
    assert!(accounting(&b, 0).gaps().is_empty());
    assert!(accounting(&b, 1).gaps().is_empty());
    let n0 = delivered(&b, 0) as f64;
    assert!((n0 - (t1_s - t0_s) * 50.0).abs() <= 1.0, "{n0}");
    // The oscillator's phase: the integral of 1 + (ppm + drift * t_hours) * 1e-6.
    let phase = |t: f64| t + (ppm * t + drift * t * t / 7200.0) * 1e-6;
    let n1 = delivered(&b, 1) as f64;
    let expected = (phase(t1_s) - phase(t0_s)) * 50.0;
    assert!((n1 - expected).abs() <= 1.0, "{n1} against {expected}");
    assert!(n1 - n0 >= 44.0, "0.3 % of 15000 samples: {n0} and {n1}");
}

/// An ADXL345 that never comes back: after `GAVE_UP_AFTER_S` of attempts sensor 1 gives up,
/// and the ITG-3200 streams on until Stop, every sample delivered.
#[test]
fn a_sensor_given_up_on_leaves_the_other_streaming() {
    let (mut b, t0) = streaming_at_50_hz();
    b.bus
        .lock()
        .adxl345_mut()
        .unwrap()
        .faults_mut()
        .nack_address = u32::MAX;
    let give_up_s = u64::from(protocol::GAVE_UP_AFTER_S);
    b.run_for((give_up_s + 60) * 1_000_000, 2_000);
    assert!(b.fw.streaming(), "sensor 0 still streams");
    let gave_up: Vec<_> = b
        .replies
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::SensorFault {
                sensor,
                error: ErrorCode::GaveUp { .. },
            } => Some(*sensor),
            _ => None,
        })
        .collect();
    assert_eq!(gave_up, [1]);
    b.ack(Command::Stop);
    let elapsed_s = (b.now() - t0) as f64 / 1e6;
    assert!(accounting(&b, 0).gaps().is_empty());
    let n0 = delivered(&b, 0) as f64;
    assert!((n0 - elapsed_s * 50.0).abs() <= 1.0, "{n0}");
    // Sensor 1: what it made until the board gave up is delivered or counted lost.
    let status = b.status();
    let n1 = (delivered(&b, 1) + status.samples_lost) as f64;
    let until_s = give_up_s as f64 + 0.5;
    assert!(
        n1 >= until_s * 50.0 && n1 <= (until_s + 1.0) * 50.0,
        "{n1} samples of sensor 1 in about {until_s} s"
    );
}

/// Start starts every sensor or none: an ADXL345 that does not answer refuses the Start,
/// and the ITG-3200 is left stopped.
#[test]
fn start_is_all_or_nothing() {
    let (gyro, accel) = at_50_hz();
    let mut b = configured(gyro, accel);
    b.bus
        .lock()
        .adxl345_mut()
        .unwrap()
        .faults_mut()
        .nack_address = u32::MAX;
    let replies = b.command(Command::Start);
    assert!(
        matches!(
            replies[..],
            [DeviceMessage::Nack {
                error: ErrorCode::SensorNotResponding,
                ..
            }]
        ),
        "{replies:?}"
    );
    assert!(!b.fw.streaming());
    b.run_for(1_000_000, 2_000);
    assert!(b.batches.iter().all(Vec::is_empty));
    b.bus
        .lock()
        .adxl345_mut()
        .unwrap()
        .faults_mut()
        .nack_address = 0;
    b.ack(Command::Start);
    b.run_for(1_000_000, 2_000);
    b.ack(Command::Stop);
    assert!(delivered(&b, 0) >= 49 && delivered(&b, 1) >= 49);
}

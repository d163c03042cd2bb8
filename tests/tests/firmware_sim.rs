//! The portable firmware against the simulated MPU-6050 on a simulated I2C bus: the
//! "virtual board". Configuration, loss-free streaming, overflow accounting, faults, and the
//! frames as the host decodes them.

use embedded_hal::i2c::I2c;
use firmware::acquire::FIFO_SAMPLES;
use firmware::{BoardConfig, Firmware};
use imunoise::link::accounting::SampleAccounting;
use imunoise::link::shared_bus::SharedBus;
use imunoise::sim::device::{BusChip, SimBus, SimChip, SimMpu6050};
use imunoise::sim::imu::ImuModel;
use imunoise::sim::noise::NoiseTerms;
use protocol::frame::{FrameDecoder, MAX_WIRE_LEN, encode};
use protocol::mpu6050::{AccelRange, DEFAULT_ADDRESS, DlpfCfg, GyroRange, SensorSettings, reg};
use protocol::{
    Command, DeviceFrame, DeviceMessage, ErrorCode, RawSample, Request, SampleBatch, Status,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::ops::Range;

struct NoDelay;
impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _: u32) {}
}

fn model() -> ImuModel {
    let mut model = ImuModel::default();
    model.gyro.noise = NoiseTerms {
        n: 1e-3,
        ..Default::default()
    };
    model.accel.noise = NoiseTerms {
        n: 1e-2,
        ..Default::default()
    };
    model
}

/// A board: firmware + simulated sensor + the host's decoder.
struct Board {
    sim: SharedBus,
    fw: Firmware<SharedBus, SharedBus>,
    decoder: FrameDecoder,
    seq: u16,
    /// The link takes frames only while this is true (back-pressure when false).
    link_open: bool,
    replies: Vec<DeviceMessage>,
    batches: Vec<SampleBatch>,
    /// The number of every frame received, in order.
    frame_numbers: Vec<u32>,
}

impl Board {
    fn new(seed: u64) -> Self {
        let chip = BusChip::Mpu6050(SimMpu6050::new(model(), seed));
        let sim = SharedBus::new(SimBus::new(vec![chip]));
        let mut fw = Firmware::new(
            sim.clone(),
            sim.clone(),
            BoardConfig {
                board_id: 0xB0A4D,
                reset_reason: protocol::ResetReason::Unknown,
            },
        );
        fw.init(&mut NoDelay).unwrap();
        Board {
            sim,
            fw,
            decoder: FrameDecoder::new(),
            seq: 0,
            link_open: true,
            replies: Vec::new(),
            batches: Vec::new(),
            frame_numbers: Vec::new(),
        }
    }

    fn sim(&self) -> Mpu<'_> {
        Mpu(self.sim.lock())
    }

    fn receive(&mut self, bytes: &[u8]) {
        let mut msgs = Vec::new();
        self.decoder.feed_with(bytes, DeviceFrame::decode, |m| {
            msgs.push(m.expect("board frames decode"))
        });
        for DeviceFrame {
            message: m,
            counter,
        } in msgs
        {
            self.frame_numbers
                .push(counter.expect("every frame is numbered"));
            match m {
                DeviceMessage::Samples(b) => self.batches.push(b),
                other => self.replies.push(other),
            }
        }
    }

    /// Send a command; return the replies it produced (not sample batches).
    fn command(&mut self, command: Command) -> Vec<DeviceMessage> {
        self.seq = self.seq.wrapping_add(1);
        let request = Request {
            seq: self.seq,
            command,
        };
        self.send(&request)
    }

    /// Any message as a framed request; the replies it gets.
    fn send(&mut self, message: &impl serde::Serialize) -> Vec<DeviceMessage> {
        let mut buf = [0u8; MAX_WIRE_LEN];
        let n = encode(message, &mut buf).unwrap();
        let mut wire = Vec::new();
        let open = self.link_open;
        self.fw.handle_bytes(&buf[..n], &mut |f| {
            if open {
                wire.extend_from_slice(f);
            }
            open
        });
        self.receive(&wire);
        std::mem::take(&mut self.replies)
    }

    fn ack(&mut self, command: Command) {
        let replies = self.command(command);
        assert!(
            matches!(replies.first(), Some(DeviceMessage::Ack { seq }) if *seq == self.seq),
            "{command:?}: {replies:?}"
        );
    }

    /// Move time to `t_us` and poll once.
    fn poll_at(&mut self, t_us: u64) {
        self.sim.lock().set_time_us(t_us);
        let mut wire = Vec::new();
        let open = self.link_open;
        self.fw.poll(&mut |f| {
            if open {
                wire.extend_from_slice(f);
            }
            open
        });
        self.receive(&wire);
    }

    fn status(&mut self) -> Status {
        match self.command(Command::GetStatus).as_slice() {
            [DeviceMessage::Status(s)] => *s,
            other => panic!("{other:?}"),
        }
    }

    fn now(&self) -> u64 {
        self.sim.lock().time_us()
    }
}

/// The board's MPU-6050, locked on its bus.
struct Mpu<'a>(std::sync::MutexGuard<'a, SimBus>);

impl std::ops::Deref for Mpu<'_> {
    type Target = SimMpu6050;
    fn deref(&self) -> &SimMpu6050 {
        self.0.mpu6050().expect("the board has an MPU-6050")
    }
}

impl std::ops::DerefMut for Mpu<'_> {
    fn deref_mut(&mut self) -> &mut SimMpu6050 {
        self.0.mpu6050_mut().expect("the board has an MPU-6050")
    }
}

/// What the sensor produced, read straight from a clone of it taken at Start (same state,
/// same noise): drained every millisecond, so it never overflows.
struct Oracle {
    sim: SimMpu6050,
    samples: Vec<RawSample>,
}

impl Oracle {
    fn at_start(board: &Board) -> Self {
        Oracle {
            sim: SimMpu6050::clone(&board.sim()),
            samples: Vec::new(),
        }
    }

    fn run_to(&mut self, t_us: u64) {
        let mut t = self.sim.time_us();
        while t < t_us {
            t = (t + 1000).min(t_us);
            self.sim.set_time_us(t);
            let mut c = [0u8; 2];
            self.sim
                .write_read(DEFAULT_ADDRESS, &[reg::FIFO_COUNT_H], &mut c)
                .unwrap();
            let n = usize::from(u16::from_be_bytes(c)) / 14;
            if n == 0 {
                continue;
            }
            let mut bytes = vec![0u8; n * 14];
            self.sim
                .write_read(DEFAULT_ADDRESS, &[reg::FIFO_R_W], &mut bytes)
                .unwrap();
            for s in bytes.chunks_exact(14) {
                self.samples
                    .push(RawSample::from_fifo_bytes(s.try_into().unwrap()));
            }
        }
    }
}

fn settings(dlpf: DlpfCfg, smplrt_div: u8) -> SensorSettings {
    SensorSettings {
        dlpf,
        smplrt_div,
        gyro_range: GyroRange::Dps500,
        accel_range: AccelRange::G4,
    }
}

/// Check batches against the oracle: indices in order, every index `< upto` present except
/// `missing`, values equal.
fn check_against(batches: &[SampleBatch], oracle: &Oracle, missing: &[Range<u64>]) {
    let mut acc = SampleAccounting::new();
    for b in batches {
        acc.batch(b.first_index, b.samples.len()).unwrap();
        for (k, s) in b.samples.iter().enumerate() {
            let i = b.first_index as usize + k;
            assert_eq!(*s, oracle.samples[i], "sample {i}");
        }
    }
    assert_eq!(acc.gaps(), missing);
    assert_eq!(acc.out_of_order_batches(), 0);
}

#[test]
fn configuration_lands_in_the_registers_for_every_dlpf_and_divider() {
    let mut board = Board::new(1);
    for dlpf in DlpfCfg::ALL {
        for div in [0u8, 1, 7, 9, 19, 99, 255] {
            let s = settings(dlpf, div);
            let replies = board.command(Command::Configure(s));
            let supported = dlpf != DlpfCfg::Cfg7 && s.output_rate_hz() <= 1000.0;
            if !supported {
                assert!(
                    matches!(
                        replies[..],
                        [DeviceMessage::Nack {
                            error: ErrorCode::InvalidSettings,
                            ..
                        }]
                    ),
                    "{s}: {replies:?}"
                );
                continue;
            }
            assert!(matches!(replies[..], [DeviceMessage::Ack { .. }]), "{s}");
            let sim = board.sim();
            assert_eq!(sim.settings(), s, "{s}");
            assert_eq!(sim.peek(reg::CONFIG), dlpf.bits());
            assert_eq!(sim.peek(reg::SMPLRT_DIV), div);
            assert_eq!(sim.peek(reg::GYRO_CONFIG), 1 << 3);
            assert_eq!(sim.peek(reg::ACCEL_CONFIG), 1 << 3);
            assert_eq!(sim.peek(reg::PWR_MGMT_1), 0x01, "awake on the gyro PLL");
            assert_eq!(sim.peek(reg::FIFO_EN), 0xF8, "accel, temperature, gyro");
            drop(sim);
            // The output rate: samples in one second of streaming.
            if s.output_rate_hz() >= 50.0 {
                board.ack(Command::Start);
                let t0 = board.now();
                let mut t = t0;
                while t < t0 + 1_000_000 {
                    t += 5_000;
                    board.poll_at(t);
                }
                board.ack(Command::Stop);
                let n: usize = board.batches.drain(..).map(|b| b.samples.len()).sum();
                let expected = s.output_rate_hz();
                assert!(
                    (n as f64 - expected).abs() <= 1.0,
                    "{s}: {n} samples in 1 s"
                );
            }
        }
    }
    // Configure while streaming is refused.
    board.ack(Command::Start);
    let replies = board.command(Command::Configure(SensorSettings::default()));
    assert!(matches!(
        replies[..],
        [DeviceMessage::Nack {
            error: ErrorCode::Busy,
            ..
        }]
    ));
}

/// Drain on a jittery schedule for `seconds` at 1 kHz; every sample arrives once, in order,
/// equal to what the sensor produced.
fn loss_free(seconds: u64) {
    let mut board = Board::new(7);
    board.ack(Command::Configure(settings(DlpfCfg::Cfg1, 0))); // 1 kHz
    board.ack(Command::Start);
    let mut oracle = Oracle::at_start(&board);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let end = board.now() + seconds * 1_000_000;
    let mut t = board.now();
    let mut checked = 0;
    while t < end {
        // Polls between 0.1 and 45 ms apart: within the FIFO's 73 ms.
        t += rng.random_range(100..45_000);
        board.poll_at(t);
        if board.batches.len() > 10_000 {
            oracle.run_to(t);
            check_tail(&board.batches, &oracle, &mut checked);
            board.batches.clear();
        }
    }
    board.ack(Command::Stop);
    oracle.run_to(board.now());
    check_tail(&board.batches, &oracle, &mut checked);
    assert_eq!(
        checked as usize,
        oracle.samples.len(),
        "every sample arrived"
    );
    let status = board.status();
    assert_eq!(status.samples_lost, 0);
    assert_eq!(status.fifo_overflows, 0);
    assert_eq!(status.samples_acquired, checked);
}

/// Check batches continue exactly at `checked` and match the oracle.
fn check_tail(batches: &[SampleBatch], oracle: &Oracle, checked: &mut u64) {
    for b in batches {
        assert_eq!(b.first_index, *checked, "no gap, no repeat");
        for (k, s) in b.samples.iter().enumerate() {
            assert_eq!(*s, oracle.samples[(*checked) as usize + k]);
        }
        *checked += b.samples.len() as u64;
    }
}

/// 3.6 million samples; about 4 s.
#[test]
fn loss_free_for_an_hour_at_1khz() {
    loss_free(3600);
}

#[test]
fn overflow_loss_is_counted_exactly_and_streaming_resumes() {
    let mut board = Board::new(3);
    board.ack(Command::Configure(settings(DlpfCfg::Cfg1, 0)));
    board.ack(Command::Start);
    let mut oracle = Oracle::at_start(&board);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut t = board.now();
    let mut run = |board: &mut Board, t: &mut u64, until: u64| {
        while *t < until {
            *t += rng.random_range(1_000..25_000);
            board.poll_at(*t);
        }
    };
    let start = t;
    run(&mut board, &mut t, start + 2_000_000);
    let before_stall = board
        .batches
        .last()
        .map(|b| b.first_index + b.samples.len() as u64);
    // A stall of 0.5 s: seven FIFOs' worth.
    t += 500_000;
    board.poll_at(t);
    run(&mut board, &mut t, start + 4_000_000);
    board.ack(Command::Stop);
    oracle.run_to(board.now());
    let status = board.status();
    assert_eq!(status.fifo_overflows, 1);
    // Every index the firmware did not deliver is a lost sample, and the count says so.
    let delivered: u64 = board.batches.iter().map(|b| b.samples.len() as u64).sum();
    assert_eq!(delivered + status.samples_lost, oracle.samples.len() as u64);
    assert_eq!(delivered, status.samples_acquired);
    // One gap, right after the last sample before the stall; values still line up after it.
    let gap_start = before_stall.unwrap();
    let gap_end = gap_start + status.samples_lost;
    let gap: Range<u64> = gap_start..gap_end;
    check_against(&board.batches, &oracle, std::slice::from_ref(&gap));
    assert!(status.samples_lost >= 500 - FIFO_SAMPLES as u64);
}

#[test]
fn back_pressure_drops_and_counts_whole_batches() {
    let mut board = Board::new(4);
    board.ack(Command::Configure(settings(DlpfCfg::Cfg3, 0)));
    board.ack(Command::Start);
    let mut oracle = Oracle::at_start(&board);
    let mut t = board.now();
    for step in 0..300 {
        board.link_open = !(100..150).contains(&step);
        t += 10_000;
        board.poll_at(t);
    }
    board.link_open = true;
    board.ack(Command::Stop);
    oracle.run_to(board.now());
    let status = board.status();
    assert!(status.batches_dropped > 0);
    let delivered: u64 = board.batches.iter().map(|b| b.samples.len() as u64).sum();
    assert_eq!(
        delivered + status.samples_dropped,
        oracle.samples.len() as u64
    );
    let mut acc = SampleAccounting::new();
    for b in &board.batches {
        acc.batch(b.first_index, b.samples.len()).unwrap();
    }
    assert_eq!(
        acc.lost(),
        status.samples_dropped,
        "the host sees the same loss"
    );
    assert_eq!(status.samples_lost, 0);
    // Frames the link refused never got a number: the numbers the host saw run on without a
    // jump, so a jump would mean a frame lost after it left the board.
    let numbers = &board.frame_numbers;
    assert!(numbers.windows(2).all(|w| w[1] == w[0] + 1), "{numbers:?}");
}

#[test]
fn transient_i2c_errors_are_retried_counted_and_lose_nothing() {
    let mut board = Board::new(5);
    board.ack(Command::Configure(SensorSettings::default()));
    board.ack(Command::Start);
    let mut oracle = Oracle::at_start(&board);
    let mut t = board.now();
    for step in 0..200 {
        if step % 10 == 0 {
            board.sim().faults_mut().nack_address = 1;
        }
        if step % 25 == 0 {
            board.sim().faults_mut().bus_error = 2;
        }
        t += 20_000;
        board.poll_at(t);
    }
    board.ack(Command::Stop);
    oracle.run_to(board.now());
    let status = board.status();
    assert!(status.i2c_errors >= 20 + 16, "{status:?}");
    check_against(&board.batches, &oracle, &[]);
    let delivered: u64 = board.batches.iter().map(|b| b.samples.len() as u64).sum();
    assert_eq!(delivered, oracle.samples.len() as u64);
}

/// Stream at the default settings for a second, then let `fault` happen and poll for
/// another two seconds; return the replies after the fault.
fn fault_after(fault: impl FnOnce(&mut SimMpu6050, u64)) -> (Board, Vec<DeviceMessage>) {
    let mut board = Board::new(6);
    board.ack(Command::Start);
    let mut t = board.now();
    for _ in 0..50 {
        t += 20_000;
        board.poll_at(t);
    }
    let now = board.now();
    fault(&mut board.sim(), now);
    for _ in 0..100 {
        t += 20_000;
        board.poll_at(t);
    }
    let faults = board.replies.drain(..).collect();
    (board, faults)
}

/// Poll every 20 ms for `us` microseconds.
fn poll_for(board: &mut Board, us: u64) {
    let end = board.now() + us;
    let mut t = board.now();
    while t < end {
        t += 20_000;
        board.poll_at(t);
    }
}

fn delivered(board: &Board) -> u64 {
    board.batches.iter().map(|b| b.samples.len() as u64).sum()
}

fn next_index(board: &Board) -> u64 {
    board
        .batches
        .last()
        .map_or(0, |b| b.first_index + b.samples.len() as u64)
}

#[test]
fn an_i2c_outage_is_ridden_through_and_its_loss_counted_exactly() {
    let mut board = Board::new(6);
    board.ack(Command::Start);
    let mut oracle = Oracle::at_start(&board);
    poll_for(&mut board, 1_000_000);
    let before = next_index(&board);
    // Two seconds in which every transfer is refused at the address.
    board.sim().faults_mut().nack_address = u32::MAX;
    poll_for(&mut board, 2_000_000);
    assert_eq!(
        board.replies.drain(..).collect::<Vec<_>>(),
        [DeviceMessage::Fault(ErrorCode::SensorNotResponding)]
    );
    assert!(board.fw.streaming(), "still streaming while it recovers");
    board.sim().faults_mut().nack_address = 0;
    poll_for(&mut board, 2_000_000);
    let resumed = match board.replies.drain(..).collect::<Vec<_>>()[..] {
        [
            DeviceMessage::Recovered {
                attempts,
                resumed_at_index,
            },
        ] => {
            assert!(attempts > 1, "the first attempts met the outage");
            resumed_at_index
        }
        ref other => panic!("{other:?}"),
    };
    board.ack(Command::Stop);
    oracle.run_to(board.now());
    let status = board.status();
    assert_eq!(status.recoveries, 1);
    assert!(status.loss_certain);
    // The resumed samples sit at their true indices: the values line up with the oracle,
    // and the only gap is the outage, counted exactly.
    let outage = before..resumed;
    check_against(&board.batches, &oracle, std::slice::from_ref(&outage));
    assert_eq!(
        delivered(&board) + status.samples_lost,
        oracle.samples.len() as u64
    );
    // At most the outage plus a second is lost.
    let rate = SensorSettings::default().output_rate_hz();
    assert!(
        ((resumed - before) as f64) < rate * 3.0,
        "{before}..{resumed}"
    );
    assert_eq!(status.sample_period_ns, 1_000_000_000 / rate as u32);
}

#[test]
fn a_sensor_gone_for_good_is_given_up_on_after_ten_minutes() {
    let (mut board, replies) = fault_after(|sim, _| sim.faults_mut().nack_address = u32::MAX);
    assert_eq!(
        replies,
        [DeviceMessage::Fault(ErrorCode::SensorNotResponding)]
    );
    let mut t = board.now();
    let end = t + u64::from(protocol::GAVE_UP_AFTER_S) * 1_000_000;
    while t < end + 2_000_000 && board.fw.streaming() {
        t += 100_000;
        board.poll_at(t);
    }
    assert!(!board.fw.streaming());
    match board.replies.drain(..).collect::<Vec<_>>()[..] {
        [
            DeviceMessage::Fault(ErrorCode::GaveUp {
                attempts,
                last,
                ended_at,
            }),
        ] => {
            // The run is accounted for up to the moment it was given up on.
            assert_eq!(ended_at, next_index(&board) + board.status().samples_lost);
            // A second apart once the backoff is at its cap.
            assert!((590..=620).contains(&attempts), "{attempts}");
            assert_eq!(last, protocol::FaultKind::SensorNotResponding);
        }
        ref other => panic!("{other:?}"),
    }
    // Everything the sensor made in those ten minutes is counted lost.
    let lost = board.status().samples_lost;
    let rate = SensorSettings::default().output_rate_hz();
    assert!(
        (lost as f64 - rate * 601.0).abs() < rate * 2.0,
        "lost {lost} at {rate} Hz"
    );
    // Start is refused with the reason while it stays away, and works once it is back.
    let r = board.command(Command::Start);
    assert!(matches!(
        r[..],
        [DeviceMessage::Nack {
            error: ErrorCode::SensorNotResponding,
            ..
        }]
    ));
    board.sim().faults_mut().nack_address = 0;
    board.ack(Command::Start);
}

#[test]
fn a_sensor_reset_mid_run_is_found_and_set_up_again() {
    let (mut board, replies) = fault_after(|sim, now| sim.schedule_reset(now + 5_000));
    let resumed = match replies[..] {
        [
            DeviceMessage::Fault(ErrorCode::SensorReset),
            DeviceMessage::Recovered {
                attempts: 1,
                resumed_at_index,
            },
        ] => resumed_at_index,
        ref other => panic!("{other:?}"),
    };
    // The sensor holds the host's settings again and samples flow, numbered on from where
    // the board's clock says the sensor would be.
    assert_eq!(board.sim().settings(), SensorSettings::default());
    let mut acc = SampleAccounting::new();
    for b in &board.batches {
        acc.batch(b.first_index, b.samples.len()).unwrap();
    }
    assert_eq!(acc.gaps().len(), 1);
    assert_eq!(acc.gaps()[0].end, resumed);
    let status = board.status();
    assert_eq!(acc.lost(), status.samples_lost);
    // Three seconds of streaming with one fault: received + lost is three seconds of samples.
    let rate = SensorSettings::default().output_rate_hz();
    let accounted = (acc.received() + acc.lost()) as f64;
    assert!((accounted - 3.0 * rate).abs() <= 2.0, "{accounted}");
}

#[test]
fn a_config_read_back_finds_a_sensor_that_reset_and_kept_sampling() {
    let mut board = Board::new(9);
    board.ack(Command::Start);
    poll_for(&mut board, 500_000);
    // The sensor lost its accelerometer range but is awake and its FIFO runs at the same
    // rate (as after a glitch in one register): only the read-back can tell.
    let held = board.sim().peek(reg::ACCEL_CONFIG);
    board
        .sim()
        .write(DEFAULT_ADDRESS, &[reg::ACCEL_CONFIG, held ^ 0x08])
        .unwrap();
    poll_for(&mut board, 1_500_000);
    assert!(
        matches!(
            board.replies[..],
            [
                DeviceMessage::Fault(ErrorCode::SensorReset),
                DeviceMessage::Recovered { attempts: 1, .. }
            ]
        ),
        "{:?}",
        board.replies
    );
    assert_eq!(board.sim().settings(), SensorSettings::default());
}

#[test]
fn a_stuck_fifo_count_is_reported_once_and_retried_with_backoff() {
    for count in [0x1C0, 0] {
        let (board, replies) =
            fault_after(|sim, _| sim.faults_mut().stuck_fifo_count = Some(count));
        assert_eq!(
            replies[0],
            DeviceMessage::Fault(ErrorCode::FifoCountImplausible { count })
        );
        // Each restart fails at once: one episode, no second Fault, restarts spaced by the
        // backoff (50, 100, 200, 400, 800 ms ... in two seconds: at most six).
        let restarts = replies[1..]
            .iter()
            .filter(|m| matches!(m, DeviceMessage::Recovered { .. }))
            .count();
        assert_eq!(restarts, replies.len() - 1, "{replies:?}");
        assert!((3..=6).contains(&restarts), "{restarts}");
        assert!(board.fw.streaming());
    }
}

#[test]
fn wrong_sensor_is_named_and_clones_are_accepted() {
    let mut board = Board::new(8);
    board.sim().faults_mut().who_am_i = Some(0x71); // an MPU-9250
    let r = board.command(Command::Configure(SensorSettings::default()));
    assert!(matches!(
        r[..],
        [DeviceMessage::Nack {
            error: ErrorCode::WrongSensor { who_am_i: 0x71 },
            ..
        }]
    ));
    match board.command(Command::GetInfo).as_slice() {
        [DeviceMessage::Info(info)] => {
            assert_eq!(info.who_am_i, 0x71);
            assert_eq!(info.board_id, 0xB0A4D);
        }
        other => panic!("{other:?}"),
    }
    for clone in [0x70, 0x72, 0x98] {
        board.sim().faults_mut().who_am_i = Some(clone);
        board.ack(Command::Configure(SensorSettings::default()));
        match board.command(Command::GetInfo).as_slice() {
            [DeviceMessage::Info(info)] => assert_eq!(info.who_am_i, clone),
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn commands_are_answered_and_bad_frames_counted() {
    let mut board = Board::new(9);
    assert!(matches!(
        board.command(Command::Ping)[..],
        [DeviceMessage::Pong { .. }]
    ));
    let r = board.command(Command::Stop);
    assert!(matches!(
        r[..],
        [DeviceMessage::Nack {
            error: ErrorCode::NotStreaming,
            ..
        }]
    ));
    board.ack(Command::Start);
    let r = board.command(Command::Start);
    assert!(matches!(
        r[..],
        [DeviceMessage::Nack {
            error: ErrorCode::Busy,
            ..
        }]
    ));
    // Garbage and a corrupted frame: counted, ignored, and the next command still works.
    let mut out = |_: &[u8]| true;
    board
        .fw
        .handle_bytes(&[0, 1, 2, 3, 0, 0x55, 0x66, 0], &mut out);
    let replies = board.command(Command::Stop);
    assert!(
        matches!(replies[0], DeviceMessage::Ack { .. }),
        "{replies:?}"
    );
    match &replies[1] {
        DeviceMessage::Status(s) => {
            assert_eq!(s.frames_rejected, 2);
            assert!(!s.streaming);
        }
        other => panic!("{other:?}"),
    }
}

/// An intact frame that is no command (as from a host of another protocol version): refused
/// by its seq with UnknownCommand, counted as rejected, and streaming goes on.
#[test]
fn unknown_command_is_refused_by_seq_while_streaming() {
    let mut board = Board::new(10);
    board.ack(Command::Configure(SensorSettings::default()));
    board.ack(Command::Start);
    board.poll_at(100_000);
    // seq 4242, then a command variant this protocol does not have.
    let replies = board.send(&(4242u16, 99u32));
    assert_eq!(
        replies,
        vec![DeviceMessage::Nack {
            seq: 4242,
            error: ErrorCode::UnknownCommand
        }]
    );
    let before = board.batches.iter().map(|b| b.samples.len()).sum::<usize>();
    board.poll_at(200_000);
    let after = board.batches.iter().map(|b| b.samples.len()).sum::<usize>();
    assert_eq!(after - before, 10, "100 Hz for 100 ms after the refusal");
    match &board.command(Command::GetStatus)[..] {
        [DeviceMessage::Status(s)] => {
            assert_eq!(s.frames_rejected, 1);
            assert!(s.streaming);
        }
        other => panic!("{other:?}"),
    }
}

/// Indices stay exact when the sensor's clock is off or drifting: after an overflow stall
/// and after an outage the firmware recovers from, every delivered sample sits at its true
/// index (its values are the oracle's), and delivered + lost is what the sensor made.
#[test]
fn indices_are_exact_with_a_sensor_clock_off_and_drifting() {
    use imunoise::sim::device::SensorClock;
    for (seed, ppm, drift_ppm_per_hour) in [
        (21, 10_000.0, 0.0),
        (22, -10_000.0, 0.0),
        (23, 3_000.0, 30_000.0),
        (24, -5_000.0, -30_000.0),
    ] {
        let mut board = Board::new(seed);
        board.sim().faults_mut().clock = SensorClock {
            ppm,
            drift_ppm_per_hour,
        };
        board.ack(Command::Configure(settings(DlpfCfg::Cfg1, 0)));
        board.ack(Command::Start);
        let mut oracle = Oracle::at_start(&board);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let start = board.now();
        let mut t = start;
        let mut run = |board: &mut Board, t: &mut u64, until: u64| {
            while *t < until {
                *t += rng.random_range(1_000..25_000);
                board.poll_at(*t);
            }
        };
        run(&mut board, &mut t, start + 20_000_000);
        // A stall of 0.3 s: the FIFO overflows.
        t += 300_000;
        board.poll_at(t);
        run(&mut board, &mut t, start + 40_000_000);
        // An outage of 1 s: the run ends, and is brought back.
        board.sim().faults_mut().nack_address = u32::MAX;
        run(&mut board, &mut t, start + 41_000_000);
        board.sim().faults_mut().nack_address = 0;
        run(&mut board, &mut t, start + 60_000_000);
        let replies: Vec<_> = board.replies.drain(..).collect();
        assert!(
            matches!(
                replies[..],
                [
                    DeviceMessage::Fault(ErrorCode::SensorNotResponding),
                    DeviceMessage::Recovered { .. }
                ]
            ),
            "{ppm} ppm: {replies:?}"
        );
        board.ack(Command::Stop);
        oracle.run_to(board.now());
        let status = board.status();
        assert_eq!(status.fifo_overflows, 1, "{ppm} ppm");
        assert_eq!(status.recoveries, 1, "{ppm} ppm");
        assert!(status.loss_certain, "{ppm} ppm");
        let mut acc = SampleAccounting::new();
        for b in &board.batches {
            acc.batch(b.first_index, b.samples.len()).unwrap();
        }
        assert_eq!(acc.gaps().len(), 2, "{ppm} ppm: {:?}", acc.gaps());
        check_against(&board.batches, &oracle, acc.gaps());
        assert_eq!(
            delivered(&board) + status.samples_lost,
            oracle.samples.len() as u64,
            "{ppm} ppm"
        );
        // The measured period is the sensor's, to a part in 10^4.
        let true_ns = 1e6 / (1.0 + ppm * 1e-6);
        let measured = f64::from(status.sample_period_ns);
        assert!(
            (measured / true_ns - 1.0).abs() < 5e-3,
            "{ppm} ppm: {measured} ns against {true_ns}"
        );
    }
}

#[test]
fn a_host_that_goes_away_stops_the_stream_and_the_next_one_starts_cleanly() {
    let mut board = Board::new(12);
    board.ack(Command::Start);
    poll_for(&mut board, 200_000);
    let before = delivered(&board);
    assert!(before > 0);
    board.fw.host_left();
    assert!(!board.fw.streaming());
    poll_for(&mut board, 200_000);
    assert_eq!(delivered(&board), before, "nothing is sent to nobody");
    // The next host: info, configure, start, as a capture does.
    match board.command(Command::GetInfo).as_slice() {
        [DeviceMessage::Info(info)] => assert!(!info.streaming),
        other => panic!("{other:?}"),
    }
    board.ack(Command::Configure(SensorSettings::default()));
    board.ack(Command::Start);
    poll_for(&mut board, 200_000);
    assert!(delivered(&board) > before);
    let restarted = board.batches.iter().filter(|b| b.first_index == 0).count();
    assert_eq!(restarted, 2, "the new run numbers from 0");
}

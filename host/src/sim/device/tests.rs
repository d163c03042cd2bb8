use super::*;
use crate::sim::noise::NoiseTerms;
use embedded_hal::i2c::{ErrorKind, I2c, NoAcknowledgeSource, Operation};

const ADDR: u8 = DEFAULT_ADDRESS;

fn device() -> SimMpu6050 {
    let mut model = ImuModel::default();
    model.gyro.noise = NoiseTerms {
        n: 1e-3,
        ..Default::default()
    };
    model.accel.noise = NoiseTerms {
        n: 1e-2,
        ..Default::default()
    };
    SimMpu6050::new(model, 42)
}

fn read(dev: &mut SimMpu6050, r: u8, n: usize) -> Vec<u8> {
    let mut buf = vec![0; n];
    dev.write_read(ADDR, &[r], &mut buf).unwrap();
    buf
}

#[test]
fn a_zero_byte_read_is_a_bus_error() {
    let mut dev = device();
    assert_eq!(
        dev.write_read(ADDR, &[reg::FIFO_R_W], &mut []),
        Err(SimI2cError::Bus)
    );
    assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68, "the bus recovers");
}

fn read1(dev: &mut SimMpu6050, r: u8) -> u8 {
    read(dev, r, 1)[0]
}

fn write(dev: &mut SimMpu6050, r: u8, v: u8) {
    dev.write(ADDR, &[r, v]).unwrap();
}

fn fifo_count(dev: &mut SimMpu6050) -> u16 {
    let b = read(dev, reg::FIFO_COUNT_H, 2);
    u16::from_be_bytes([b[0], b[1]])
}

/// Awake at 100 Hz / 42 Hz, FIFO on with everything: 14 bytes per sample.
fn running() -> SimMpu6050 {
    let mut dev = device();
    write(&mut dev, reg::PWR_MGMT_1, 0x01);
    // Burst write SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG (auto-increment).
    dev.write(ADDR, &[reg::SMPLRT_DIV, 9, 3, 0, 0]).unwrap();
    write(&mut dev, reg::FIFO_EN, 0xF8);
    write(&mut dev, reg::USER_CTRL, USER_FIFO_EN);
    dev
}

#[test]
fn identity_and_power_up_asleep() {
    let mut dev = device();
    assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68);
    assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
    write(&mut dev, reg::FIFO_EN, 0xF8);
    write(&mut dev, reg::USER_CTRL, USER_FIFO_EN);
    write(&mut dev, reg::INT_ENABLE, DATA_RDY);
    dev.advance(Duration::from_secs(1));
    assert_eq!(fifo_count(&mut dev), 0, "asleep: no samples");
    assert_eq!(read1(&mut dev, reg::INT_STATUS), 0);
    assert_eq!(read(&mut dev, reg::ACCEL_XOUT_H, 14), vec![0; 14]);
}

#[test]
fn burst_writes_and_reads_auto_increment() {
    let mut dev = running();
    assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![9, 3, 0, 0]);
    assert_eq!(dev.settings().output_rate_hz(), 100.0);
    // A transaction of several operations: pointer, then a continued write, then a read
    // after a repeated start that sets a new pointer.
    let mut out = [0u8; 2];
    dev.transaction(
        ADDR,
        &mut [
            Operation::Write(&[reg::SMPLRT_DIV]),
            Operation::Write(&[4, 3]),
            Operation::Read(&mut out),
        ],
    )
    .unwrap();
    // The read continues at SMPLRT_DIV + 2 (the pointer after two written bytes).
    assert_eq!(out, [0, 0]);
    assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 2), vec![4, 3]);
}

#[test]
fn data_registers_and_data_ready() {
    let mut dev = running();
    write(&mut dev, reg::INT_ENABLE, DATA_RDY);
    dev.advance(Duration::from_micros(9_999));
    assert_eq!(
        read1(&mut dev, reg::INT_STATUS),
        0,
        "no sample before 10 ms"
    );
    dev.advance(Duration::from_micros(1));
    assert_eq!(read1(&mut dev, reg::INT_STATUS), DATA_RDY);
    assert_eq!(read1(&mut dev, reg::INT_STATUS), 0, "cleared on read");
    let d = read(&mut dev, reg::ACCEL_XOUT_H, 14);
    let word = |i: usize| i16::from_be_bytes([d[2 * i], d[2 * i + 1]]);
    assert!((word(2) - 16384).abs() < 50, "1 g on z: {}", word(2));
    assert!(word(0).abs() < 50 && word(4).abs() < 50);
    // 25 degC: (25 - 36.53) * 340 = -3920.
    assert_eq!(word(3), -3920);
}

#[test]
fn fifo_fills_in_order_and_pops() {
    let mut dev = running();
    dev.advance(Duration::from_millis(100));
    assert_eq!(fifo_count(&mut dev), 140, "10 samples of 14 bytes");
    let regs = read(&mut dev, reg::ACCEL_XOUT_H, 14);
    let all = read(&mut dev, reg::FIFO_R_W, 140);
    assert_eq!(
        &all[126..],
        &regs[..],
        "newest FIFO sample = data registers"
    );
    assert_eq!(fifo_count(&mut dev), 0);
    // Reading an empty FIFO repeats the last byte.
    assert_eq!(read1(&mut dev, reg::FIFO_R_W), all[139]);
    // Only gyro z: 2 bytes per sample.
    write(&mut dev, reg::FIFO_EN, ZG_FIFO_EN);
    dev.advance(Duration::from_millis(50));
    assert_eq!(fifo_count(&mut dev), 10);
    let z = read(&mut dev, reg::FIFO_R_W, 10);
    assert_eq!(&z[8..], &read(&mut dev, reg::GYRO_XOUT_H + 4, 2)[..]);
}

#[test]
fn fifo_overflow_drops_oldest_and_flags() {
    let mut dev = running();
    write(&mut dev, reg::INT_ENABLE, FIFO_OFLOW);
    dev.advance(Duration::from_millis(730)); // 73 samples = 1022 bytes: fits
    assert_eq!(fifo_count(&mut dev), 1022);
    assert_eq!(read1(&mut dev, reg::INT_STATUS), 0);
    dev.advance(Duration::from_secs(2));
    assert_eq!(fifo_count(&mut dev), 1024);
    assert_eq!(read1(&mut dev, reg::INT_STATUS), FIFO_OFLOW);
    let regs = read(&mut dev, reg::ACCEL_XOUT_H, 14);
    let all = read(&mut dev, reg::FIFO_R_W, 1024);
    // Kept the newest bytes; 1024 = 73 * 14 + 2, so the head is mid-sample.
    assert_eq!(&all[1010..], &regs[..]);
    // FIFO reset empties it and the bit clears itself.
    dev.advance(Duration::from_millis(100));
    write(&mut dev, reg::USER_CTRL, USER_FIFO_EN | FIFO_RESET);
    assert_eq!(fifo_count(&mut dev), 0);
    assert_eq!(read1(&mut dev, reg::USER_CTRL), USER_FIFO_EN);
}

#[test]
fn device_reset_restores_defaults() {
    let mut dev = running();
    dev.advance(Duration::from_millis(100));
    write(&mut dev, reg::PWR_MGMT_1, DEVICE_RESET);
    assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
    assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![0; 4]);
    assert_eq!(fifo_count(&mut dev), 0);
    dev.advance(Duration::from_millis(100));
    assert_eq!(fifo_count(&mut dev), 0, "asleep after reset");
    assert_eq!(dev.resets(), 1);
}

#[test]
fn faults() {
    let mut dev = running();
    let mut buf = [0u8; 1];
    assert_eq!(
        dev.write_read(0x69, &[reg::WHO_AM_I], &mut buf),
        Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))
    );
    dev.faults_mut().nack_address = 1;
    assert!(matches!(
        dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf),
        Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))
    ));
    assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68, "one transaction only");
    dev.faults_mut().nack_data = 1;
    let mut fifo = [0u8; 2];
    dev.read(ADDR, &mut fifo).unwrap(); // a plain read does not consume nack_data
    assert_eq!(
        dev.write(ADDR, &[reg::SMPLRT_DIV, 1]),
        Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Data))
    );
    assert_eq!(
        read1(&mut dev, reg::SMPLRT_DIV),
        9,
        "NACKed write had no effect"
    );
    dev.faults_mut().bus_error = 2;
    assert_eq!(
        dev.write(ADDR, &[reg::SMPLRT_DIV, 1]),
        Err(SimI2cError::Bus)
    );
    assert!(dev.read(ADDR, &mut buf).is_err());
    use embedded_hal::i2c::Error;
    assert_eq!(SimI2cError::Bus.kind(), ErrorKind::Bus);
    dev.faults_mut().who_am_i = Some(0x72);
    assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x72);
    dev.faults_mut().stuck_fifo_count = Some(0x0200);
    dev.advance(Duration::from_millis(100));
    assert_eq!(fifo_count(&mut dev), 0x0200);
    assert_eq!(dev.fifo_len(), 140);
    dev.faults_mut().stuck_fifo_count = None;
    // A reset in the middle of the run: samples stop at 150 ms.
    let now = dev.time_us();
    dev.schedule_reset(now + 50_000);
    dev.advance(Duration::from_millis(200));
    assert_eq!(dev.resets(), 1);
    assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
    assert_eq!(fifo_count(&mut dev), 0);
}

/// Awake at 1 kHz (DLPF on, divider 0), FIFO off, under `clock`, from `start_us`.
fn at_1khz(clock: SensorClock, start_us: u64) -> SimMpu6050 {
    let mut dev = device();
    dev.faults_mut().clock = clock;
    dev.set_time_us(start_us);
    dev.write(ADDR, &[reg::SMPLRT_DIV, 0, 1, 0, 0]).unwrap();
    write(&mut dev, reg::PWR_MGMT_1, 0x01);
    assert_eq!(dev.settings().output_rate_hz(), 1000.0);
    dev
}

fn sample_times(dev: &mut SimMpu6050) -> Vec<u64> {
    dev.take_journal()
        .iter()
        .filter_map(|e| match e {
            JournalEntry::Sample { time_us, .. } => Some(*time_us),
            JournalEntry::FifoReset { .. } => None,
        })
        .collect()
}

#[test]
fn a_clock_offset_changes_the_sample_count() {
    for (ppm, expected) in [
        (0.0, 60_000),
        (3000.0, 60_180),
        (10_000.0, 60_600),
        (-10_000.0, 59_400),
    ] {
        let clock = SensorClock {
            ppm,
            drift_ppm_per_hour: 0.0,
        };
        let mut dev = at_1khz(clock, 0);
        dev.advance(Duration::from_secs(60));
        let n = dev.samples_made();
        assert!(n.abs_diff(expected) <= 1, "{ppm} ppm: {n} samples");
    }
    // The ideal clock keeps sample k at exactly k ms.
    let mut dev = at_1khz(SensorClock::default(), 0);
    dev.keep_journal();
    dev.advance(Duration::from_millis(5));
    assert_eq!(sample_times(&mut dev), [1000, 2000, 3000, 4000, 5000]);
}

#[test]
fn a_drifting_clock_follows_the_integral_of_its_rate() {
    // From 1 h to 1 h + 60 s, rate 1 + (2000 - 5000 t_h) 1e-6: the sensor's elapsed time
    // is the integral, 60 s + 1e-6 (2000 * 60 - 5000 (3660^2 - 3600^2) / 7200) s.
    let clock = SensorClock {
        ppm: 2000.0,
        drift_ppm_per_hour: -5000.0,
    };
    let (t0, t1) = (3600.0_f64, 3660.0_f64);
    let integral =
        |a: f64, b: f64| (b - a) + 1e-6 * (2000.0 * (b - a) - 5000.0 * (b * b - a * a) / 7200.0);
    assert!((integral(t0, t1) - 59.8175).abs() < 1e-9);
    let mut dev = at_1khz(clock, 3_600_000_000);
    dev.keep_journal();
    dev.advance(Duration::from_secs(60));
    let times = sample_times(&mut dev);
    let expected = (integral(t0, t1) * 1000.0).floor() as u64;
    assert_eq!(expected, 59_817);
    assert!(dev.samples_made().abs_diff(expected) <= 1);
    assert_eq!(times.len() as u64, dev.samples_made());
    // Each sample k at the first whole us where the integral has reached k ms.
    for (k, &t) in times.iter().enumerate().step_by(997) {
        let due = (k + 1) as f64 * 1e-3;
        let t = t as f64 * 1e-6;
        assert!(integral(t0, t) <= due + 1e-9, "sample {k} early");
        assert!(integral(t0, t + 1e-6) > due - 1e-9, "sample {k} late");
    }
}

#[test]
fn the_clock_model_inverts_exactly_over_a_night() {
    for (ppm, drift) in [(10_000.0, 0.0), (-10_000.0, 500.0), (3000.0, -800.0)] {
        let clock = SensorClock {
            ppm,
            drift_ppm_per_hour: drift,
        };
        for hours in [0.001, 1.0, 8.0, 14.0] {
            let phase = hours * 3600e6;
            let t = clock.time_at_phase_us(phase);
            assert!(
                (clock.phase_us(t) - phase).abs() < 1e-3,
                "{ppm} {drift} {hours}"
            );
            // The rate is what the model says: 1 + (ppm + drift t_h) 1e-6 (a central
            // difference is exact for a quadratic; a wide one keeps rounding small).
            let h = 1e6;
            let rate = (clock.phase_us(t + h) - clock.phase_us(t - h)) / (2.0 * h);
            let expected = 1.0 + (ppm + drift * t / 3600e6) * 1e-6;
            assert!((rate - expected).abs() < 1e-8, "{rate} {expected}");
        }
    }
    // A falling rate that reaches zero: the phase never gets past its maximum.
    let stopping = SensorClock {
        ppm: 0.0,
        drift_ppm_per_hour: -1e6,
    };
    assert_eq!(stopping.time_at_phase_us(1e10), f64::INFINITY);
}

#[test]
fn a_clock_change_mid_run_keeps_the_phase() {
    let mut dev = at_1khz(SensorClock::default(), 0);
    dev.keep_journal();
    dev.set_time_us(10_000_500);
    assert_eq!(dev.samples_made(), 10_000);
    // Half a period to go; at 1 % fast it takes 500 / 1.01 = 495.05 us.
    dev.faults_mut().clock.ppm = 10_000.0;
    dev.take_journal();
    dev.set_time_us(10_002_000);
    let times = sample_times(&mut dev);
    assert_eq!(times[0], 10_000_995);
    // The next one a full fast period (990.1 us) later.
    assert_eq!(times[1], 10_001_985);
}

#[test]
fn an_i2c_outage_nacks_everything_while_sampling_goes_on() {
    let mut dev = running();
    write(&mut dev, reg::INT_ENABLE, FIFO_OFLOW);
    dev.faults_mut().i2c_outages = vec![Outage {
        at_us: 100_000,
        for_us: 3_000_000,
    }];
    let nack = Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address));
    let mut buf = [0u8; 1];
    dev.set_time_us(99_999);
    assert_eq!(read1(&mut dev, reg::WHO_AM_I), 0x68);
    dev.set_time_us(100_000);
    assert_eq!(dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf), nack);
    // Writes have no effect: neither settings nor a FIFO reset.
    assert_eq!(dev.write(ADDR, &[reg::SMPLRT_DIV, 1]), nack);
    assert_eq!(
        dev.write(ADDR, &[reg::USER_CTRL, USER_FIFO_EN | FIFO_RESET]),
        nack
    );
    assert_eq!(dev.read(ADDR, &mut buf), nack);
    let samples_before = dev.samples_made();
    dev.set_time_us(3_099_999);
    assert_eq!(dev.write_read(ADDR, &[reg::WHO_AM_I], &mut buf), nack);
    // The chip went on at 100 Hz and its FIFO overflowed.
    assert_eq!(dev.samples_made() - samples_before, 299);
    assert_eq!(dev.fifo_len(), 1024);
    dev.set_time_us(3_100_000);
    assert_eq!(
        read1(&mut dev, reg::WHO_AM_I),
        0x68,
        "back after the window"
    );
    assert_eq!(read1(&mut dev, reg::SMPLRT_DIV), 9);
    assert_eq!(read1(&mut dev, reg::INT_STATUS), FIFO_OFLOW);
    assert_eq!(fifo_count(&mut dev), 1024);
    assert_eq!(dev.faults().nack_address, 0);
    assert_eq!(dev.resets(), 0);
}

#[test]
fn resets_at_listed_times() {
    let mut dev = running();
    dev.keep_journal();
    // Given out of order, partly through the field and partly scheduled.
    dev.faults_mut().resets_at_us = vec![500_000, 150_000];
    dev.schedule_reset(300_000);
    assert_eq!(dev.faults().resets_at_us, [150_000, 300_000, 500_000]);
    dev.set_time_us(149_999);
    assert_eq!(dev.resets(), 0);
    assert_eq!(dev.samples_made(), 14);
    dev.set_time_us(150_000);
    assert_eq!(dev.resets(), 1);
    assert_eq!(dev.fifo_len(), 0);
    assert_eq!(read1(&mut dev, reg::PWR_MGMT_1), SLEEP);
    assert_eq!(read(&mut dev, reg::SMPLRT_DIV, 4), vec![0; 4]);
    let journal = dev.take_journal();
    assert_eq!(
        journal.last(),
        Some(&JournalEntry::FifoReset { time_us: 150_000 })
    );
    // Asleep until woken; woken again, it samples until the next reset.
    dev.set_time_us(200_000);
    assert_eq!(
        dev.samples_made(),
        14,
        "the reset came before the sample at 150 ms"
    );
    write(&mut dev, reg::PWR_MGMT_1, 0x01);
    dev.set_time_us(1_000_000);
    assert_eq!(dev.resets(), 3);
    assert!(dev.faults().resets_at_us.is_empty());
    // The reset settings (divider 0, DLPF off) sample at 8 kHz: 200 ms to 300 ms, the
    // sample due at the reset not made.
    assert_eq!(dev.settings().output_rate_hz(), 8000.0);
    assert_eq!(dev.samples_made(), 14 + 799);
}

#[test]
fn reproducible_and_clock_driven() {
    let run = || {
        let mut dev = running();
        dev.set_time_us(250_000);
        dev.set_time_us(100); // the past is ignored
        read(&mut dev, reg::FIFO_R_W, 350)
    };
    let a = run();
    assert_eq!(a, run());
    assert_ne!(&a[..14], &a[14..28], "noise varies sample to sample");
}

//! The GY-85's simulated chips against their data sheets, on one bus.

use super::*;
use crate::analysis::{Estimator, allan, ci, phase_from_rate};
use crate::sim::imu::{GravityAxis, ImuModel};
use crate::sim::noise::NoiseTerms;
use embedded_hal::i2c::{I2c, NoAcknowledgeSource};
use protocol::adxl345::{self, reg as areg};
use protocol::itg3200::{self, reg as greg};

const GYRO: u8 = itg3200::DEFAULT_ADDRESS;
const ACCEL: u8 = adxl345::DEFAULT_ADDRESS;

fn model(gyro_n: f64, accel_n: f64) -> ImuModel {
    let mut model = ImuModel::default();
    model.gyro.noise = NoiseTerms {
        n: gyro_n,
        ..Default::default()
    };
    model.accel.noise = NoiseTerms {
        n: accel_n,
        ..Default::default()
    };
    model.gravity = GravityAxis {
        axis: 2,
        negative: false,
    };
    model
}

fn gy85(model: ImuModel) -> SimBus {
    SimBus::new(vec![
        BusChip::Itg3200(SimItg3200::new(model.clone(), 1)),
        BusChip::Adxl345(SimAdxl345::new(model, 2)),
    ])
}

fn read(bus: &mut SimBus, address: u8, register: u8, n: usize) -> Vec<u8> {
    let mut buf = vec![0; n];
    bus.write_read(address, &[register], &mut buf).unwrap();
    buf
}

fn write(bus: &mut SimBus, address: u8, register: u8, value: u8) {
    bus.write(address, &[register, value]).unwrap();
}

/// The Allan-derived N at tau = 1 s and its 99 % interval, from rate samples.
fn n_at_one_second(y: &[f64], rate_hz: f64) -> (f64, f64, f64) {
    let tau0 = 1.0 / rate_hz;
    let x = phase_from_rate(y, tau0);
    let dev = allan::deviation(Estimator::Oadev, &x, tau0, &[rate_hz as usize]);
    let iv = ci::intervals(&dev, &x, 0.99);
    (dev.dev[0], iv.lo[0], iv.hi[0])
}

#[test]
fn both_chips_answer_at_their_addresses_and_nothing_else_does() {
    let mut bus = gy85(model(1e-3, 1e-2));
    assert_eq!(read(&mut bus, GYRO, greg::WHO_AM_I, 1), [0x68]);
    assert_eq!(read(&mut bus, ACCEL, areg::DEVID, 1), [0xE5]);
    assert_eq!(
        bus.write(0x1D, &[0]),
        Err(SimI2cError::NoAcknowledge(NoAcknowledgeSource::Address))
    );
}

#[test]
fn the_gyro_samples_at_its_setting_and_flags_each_sample() {
    let mut bus = gy85(model(1e-3, 1e-2));
    let s = itg3200::Itg3200Settings::for_rate_and_bandwidth(50.0, 20.0).unwrap();
    write(&mut bus, GYRO, greg::SMPLRT_DIV, s.smplrt_div);
    write(&mut bus, GYRO, greg::DLPF_FS, s.dlpf_fs());
    write(&mut bus, GYRO, greg::INT_CFG, greg::bits::RAW_RDY_EN);
    let chip = bus.itg3200_mut().unwrap();
    assert_eq!(chip.settings(), s);
    let before = chip.samples_made();
    bus.set_time_us(1_000_000);
    let made = bus.itg3200_mut().unwrap().samples_made() - before;
    assert_eq!(made, 50, "one second at 50 Hz");
    assert_eq!(read(&mut bus, GYRO, greg::INT_STATUS, 1), [1]);
    assert_eq!(
        read(&mut bus, GYRO, greg::INT_STATUS, 1),
        [0],
        "cleared by the read"
    );
    bus.set_time_us(1_020_000);
    assert_eq!(read(&mut bus, GYRO, greg::INT_STATUS, 1), [1]);
    // H_RESET: back to the power-on registers.
    write(&mut bus, GYRO, greg::PWR_MGM, greg::bits::H_RESET);
    assert_eq!(read(&mut bus, GYRO, greg::DLPF_FS, 1), [0]);
    assert_eq!(bus.itg3200_mut().unwrap().resets(), 1);
}

#[test]
fn the_gyro_noise_and_temperature_come_out_in_its_own_scale() {
    let n0 = 2e-3; // rad/s/sqrt(Hz), large against the 1.2e-3 rad/s LSB
    let mut m = model(n0, 1e-2);
    m.temperature.profile.initial = 30.0;
    let mut bus = gy85(m);
    let s = itg3200::Itg3200Settings::for_rate_and_bandwidth(50.0, 20.0).unwrap();
    write(&mut bus, GYRO, greg::SMPLRT_DIV, s.smplrt_div);
    write(&mut bus, GYRO, greg::DLPF_FS, s.dlpf_fs());
    let mut gz = Vec::new();
    let mut temps = Vec::new();
    let t0 = bus.time_us();
    for k in 1..=30_000u64 {
        bus.set_time_us(t0 + k * 20_000);
        let b = read(&mut bus, GYRO, greg::TEMP_OUT_H, 8);
        let word = |i: usize| i16::from_be_bytes([b[2 * i], b[2 * i + 1]]);
        temps.push(itg3200::temperature_celsius(word(0)));
        gz.push(f64::from(word(3)) * itg3200::rad_s_per_lsb());
    }
    // The MPU-6050's gyro path: the 20 Hz filter passes a little noise from above 25 Hz,
    // which the decimation folds back.
    let design = crate::sim::dlpf::DlpfDesign::for_setting(s.dlpf, crate::sim::dlpf::Sensor::Gyro);
    let expected = n0 * crate::sim::chain::white_noise_inflation(&design, 20);
    let (n, lo, hi) = n_at_one_second(&gz, 50.0);
    assert!(
        lo <= expected && expected <= hi,
        "N {n} [{lo}, {hi}] against {expected}"
    );
    let mean_t = temps.iter().sum::<f64>() / temps.len() as f64;
    assert!((mean_t - 30.0).abs() < 0.01, "{mean_t}");
}

#[test]
fn the_accelerometer_measures_only_when_told_and_keeps_32_in_stream_mode() {
    let mut bus = gy85(model(1e-3, 1e-3));
    bus.set_time_us(100_000);
    assert_eq!(bus.adxl345_mut().unwrap().samples_made(), 0, "standby");
    let s = adxl345::Adxl345Settings::for_rate(50.0, false).unwrap();
    write(&mut bus, ACCEL, areg::BW_RATE, s.bw_rate());
    write(&mut bus, ACCEL, areg::DATA_FORMAT, s.data_format());
    write(
        &mut bus,
        ACCEL,
        areg::FIFO_CTL,
        areg::bits::FIFO_MODE_STREAM,
    );
    write(&mut bus, ACCEL, areg::POWER_CTL, areg::bits::MEASURE);
    bus.set_time_us(100_000 + 400_000);
    assert_eq!(bus.adxl345_mut().unwrap().samples_made(), 20);
    assert_eq!(read(&mut bus, ACCEL, areg::FIFO_STATUS, 1), [20]);
    bus.set_time_us(100_000 + 1_000_000);
    assert_eq!(
        read(&mut bus, ACCEL, areg::FIFO_STATUS, 1),
        [32],
        "50 made, 32 kept"
    );
    let overrun = |bus: &mut SimBus| read(bus, ACCEL, areg::INT_SOURCE, 1)[0] & areg::bits::OVERRUN;
    assert_eq!(overrun(&mut bus), areg::bits::OVERRUN);
    assert_eq!(
        overrun(&mut bus),
        areg::bits::OVERRUN,
        "reading INT_SOURCE keeps it"
    );
    // One burst of six bytes is one sample: gravity on z, 1 g = 256 LSB at full resolution.
    let b = read(&mut bus, ACCEL, areg::DATAX0, 6);
    let z = i16::from_le_bytes([b[4], b[5]]);
    assert!((z - 256).abs() <= 2, "{z}");
    assert_eq!(read(&mut bus, ACCEL, areg::FIFO_STATUS, 1), [31]);
    assert_eq!(
        overrun(&mut bus),
        0,
        "cleared once a read leaves the FIFO below full"
    );
}

/// The data sheet's noise against rate: the same LSB rms at 100 Hz and below (so N grows as
/// 1 / sqrt(rate) below 100 Hz), a constant density above, 1.8 / 0.75 more in low power.
#[test]
fn the_accelerometer_noise_follows_the_data_sheet_against_rate() {
    let n100 = 290e-6 * protocol::mpu6050::STANDARD_GRAVITY; // m/s^2/sqrt(Hz), x and y
    for (rate, low_power, expected) in [
        (100.0, false, 1.0),
        (50.0, false, 2f64.sqrt()),
        (400.0, false, 1.0),
        (50.0, true, 1.8 / 0.75 * 2f64.sqrt()),
    ] {
        let mut bus = gy85(model(1e-3, n100));
        let s = adxl345::Adxl345Settings::for_rate(rate, low_power).unwrap();
        write(&mut bus, ACCEL, areg::BW_RATE, s.bw_rate());
        write(&mut bus, ACCEL, areg::DATA_FORMAT, s.data_format());
        write(&mut bus, ACCEL, areg::POWER_CTL, areg::bits::MEASURE);
        let period = (1e6 / rate) as u64;
        let t0 = bus.time_us();
        let mut x = Vec::new();
        for k in 1..=(600.0 * rate) as u64 {
            bus.set_time_us(t0 + k * period + 1);
            let b = read(&mut bus, ACCEL, areg::DATAX0, 2);
            x.push(f64::from(i16::from_le_bytes([b[0], b[1]])) * adxl345::m_s2_per_lsb());
        }
        let (n, lo, hi) = n_at_one_second(&x, rate);
        let truth = n100 * expected;
        // Quantization adds white noise of its own: (LSB / sqrt(12))^2 per sample.
        let q = adxl345::m_s2_per_lsb() / 12f64.sqrt() / rate.sqrt();
        let with_q = (truth * truth + q * q).sqrt();
        assert!(
            lo <= with_q && with_q <= hi,
            "{rate} Hz low power {low_power}: N {n:.3e} [{lo:.3e}, {hi:.3e}], expected {with_q:.3e}"
        );
    }
}

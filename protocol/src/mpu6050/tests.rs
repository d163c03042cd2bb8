//! The settings model against the register map and the product specification.

use super::settings::abs;
use super::*;
use core::f64::consts::PI;

/// The DLPF table as printed in \[RM\], register 26, restated independently of
/// `DLPF_TABLE`: DLPF_CFG, accel (bandwidth Hz, delay ms, Fs kHz), gyro (bandwidth Hz,
/// delay ms, Fs kHz).
/// (bandwidth Hz, delay ms, sample rate kHz) of one sensor in one row.
type Filter = (f64, f64, f64);
const DATASHEET: [(u8, Filter, Filter); 7] = [
    (0, (260.0, 0.0, 1.0), (256.0, 0.98, 8.0)),
    (1, (184.0, 2.0, 1.0), (188.0, 1.9, 1.0)),
    (2, (94.0, 3.0, 1.0), (98.0, 2.8, 1.0)),
    (3, (44.0, 4.9, 1.0), (42.0, 4.8, 1.0)),
    (4, (21.0, 8.5, 1.0), (20.0, 8.3, 1.0)),
    (5, (10.0, 13.8, 1.0), (10.0, 13.4, 1.0)),
    (6, (5.0, 19.0, 1.0), (5.0, 18.6, 1.0)),
];

#[test]
fn every_dlpf_row_matches_the_datasheet() {
    for (cfg, accel, gyro) in DATASHEET {
        let dlpf = DlpfCfg::from_bits(cfg).unwrap();
        assert_eq!(dlpf.bits(), cfg);
        let r = dlpf.row().unwrap();
        assert_eq!(r.cfg, dlpf);
        assert_eq!(
            (r.accel_bandwidth_hz, r.accel_delay_ms),
            (accel.0, accel.1),
            "cfg {cfg}"
        );
        assert_eq!(
            (r.gyro_bandwidth_hz, r.gyro_delay_ms),
            (gyro.0, gyro.1),
            "cfg {cfg}"
        );
        assert_eq!(r.gyro_internal_rate_hz, gyro.2 * 1000.0, "cfg {cfg}");
        assert_eq!(dlpf.gyro_internal_rate_hz(), gyro.2 * 1000.0, "cfg {cfg}");
        assert_eq!(accel.2 * 1000.0, ACCEL_INTERNAL_RATE_HZ);
    }
    assert!(DlpfCfg::Cfg7.row().is_none());
    assert_eq!(DlpfCfg::Cfg7.gyro_internal_rate_hz(), 8000.0);
    assert_eq!(DlpfCfg::from_bits(8), None);
}

#[test]
fn divider_edges_at_both_internal_rates() {
    let rate = |dlpf, smplrt_div| {
        SensorSettings {
            dlpf,
            smplrt_div,
            ..SensorSettings::default()
        }
        .output_rate_hz()
    };
    assert_eq!(rate(DlpfCfg::Cfg0, 0), 8000.0);
    assert_eq!(rate(DlpfCfg::Cfg0, 1), 4000.0);
    assert_eq!(rate(DlpfCfg::Cfg0, 255), 31.25);
    assert_eq!(rate(DlpfCfg::Cfg7, 7), 1000.0);
    assert_eq!(rate(DlpfCfg::Cfg1, 0), 1000.0);
    assert_eq!(rate(DlpfCfg::Cfg1, 255), 3.906_25);
    assert_eq!(rate(DlpfCfg::Cfg6, 9), 100.0);
    // Above 1 kHz output the 1 kHz accelerometer repeats samples.
    let fast = SensorSettings {
        dlpf: DlpfCfg::Cfg0,
        smplrt_div: 3,
        ..SensorSettings::default()
    };
    assert!(fast.accel_repeats_samples());
    let kilohertz = SensorSettings {
        dlpf: DlpfCfg::Cfg0,
        smplrt_div: 7,
        ..SensorSettings::default()
    };
    assert!(!kilohertz.accel_repeats_samples());
}

#[test]
fn the_papers_four_settings_resolve_exactly() {
    // (rate Hz, bandwidth Hz) -> (DLPF_CFG, SMPLRT_DIV): 8000/(1+39) = 200,
    // 1000/(1+4) = 200, 8000/(1+159) = 50, 1000/(1+19) = 50.
    let expected = [
        ((200.0, 256.0), (0, 39)),
        ((200.0, 42.0), (3, 4)),
        ((50.0, 256.0), (0, 159)),
        ((50.0, 42.0), (3, 19)),
    ];
    for ((rate, bw), (cfg, div)) in expected {
        let s = SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap();
        assert_eq!(
            (s.dlpf.bits(), s.smplrt_div),
            (cfg, div),
            "{rate} Hz / {bw} Hz"
        );
        assert_eq!(s.output_rate_hz(), rate);
        assert_eq!(s.dlpf.row().unwrap().gyro_bandwidth_hz, bw);
    }
}

#[test]
fn accel_bandwidths_name_the_same_rows() {
    for r in &DLPF_TABLE {
        let by_gyro = SensorSettings::for_rate_and_bandwidth(50.0, r.gyro_bandwidth_hz).unwrap();
        let by_accel = SensorSettings::for_rate_and_bandwidth(50.0, r.accel_bandwidth_hz).unwrap();
        assert_eq!(by_gyro, by_accel);
        assert_eq!(by_gyro.dlpf, r.cfg);
    }
}

#[test]
fn every_exact_rate_resolves_back_to_its_divider() {
    for r in &DLPF_TABLE {
        for div in 0..=255u8 {
            let rate = r.gyro_internal_rate_hz / (1.0 + f64::from(div));
            let s = SensorSettings::for_rate_and_bandwidth(rate, r.gyro_bandwidth_hz).unwrap();
            assert_eq!(s.smplrt_div, div);
        }
    }
}

#[test]
fn unreachable_rates_name_their_neighbours() {
    let err = SensorSettings::for_rate_and_bandwidth(150.0, 42.0).unwrap_err();
    // 1000/6 = 166.67 (div 5) above, 1000/7 = 142.86 (div 6) below.
    let [above, below] = err.nearest_rates();
    assert_eq!(above.unwrap().1, 5);
    assert_eq!(below.unwrap().1, 6);
    // Too fast: only the top rate is a neighbour; too slow: only the bottom one.
    let err = SensorSettings::for_rate_and_bandwidth(2000.0, 42.0).unwrap_err();
    assert_eq!(err.nearest_rates(), [None, Some((1000.0, 0))]);
    let err = SensorSettings::for_rate_and_bandwidth(1.0, 42.0).unwrap_err();
    assert_eq!(err.nearest_rates(), [Some((3.906_25, 255)), None]);
    // 8000 / 3.9 needs SMPLRT_DIV 2050: below the slowest 8 kHz rate, 31.25 Hz.
    let err = SensorSettings::for_rate_and_bandwidth(3.9, 256.0).unwrap_err();
    assert_eq!(err.nearest_rates(), [Some((31.25, 255)), None]);
}

#[test]
fn unknown_bandwidth_names_the_nearest_row() {
    let err = SensorSettings::for_rate_and_bandwidth(100.0, 40.0).unwrap_err();
    assert_eq!(err.nearest_bandwidth().unwrap().cfg, DlpfCfg::Cfg3);
    assert!(matches!(
        SensorSettings::for_rate_and_bandwidth(0.0, 42.0),
        Err(SettingsError::InvalidRate { .. })
    ));
    assert!(matches!(
        SensorSettings::for_rate_and_bandwidth(f64::NAN, 42.0),
        Err(SettingsError::InvalidRate { .. })
    ));
}

#[test]
fn ranges_and_sensitivities_match_the_datasheet() {
    let gyro: [(u8, f64, f64); 4] = [
        (0, 250.0, 131.0),
        (1, 500.0, 65.5),
        (2, 1000.0, 32.8),
        (3, 2000.0, 16.4),
    ];
    for (bits, fs, lsb) in gyro {
        let g = GyroRange::from_bits(bits).unwrap();
        assert_eq!((g.full_scale_dps(), g.lsb_per_dps()), (fs, lsb));
    }
    let accel: [(u8, f64, f64); 4] = [
        (0, 2.0, 16384.0),
        (1, 4.0, 8192.0),
        (2, 8.0, 4096.0),
        (3, 16.0, 2048.0),
    ];
    for (bits, fs, lsb) in accel {
        let a = AccelRange::from_bits(bits).unwrap();
        assert_eq!((a.full_scale_g(), a.lsb_per_g()), (fs, lsb));
    }
    // 131 counts = 1 deg/s; 16384 counts = 1 g.
    assert!(abs(131.0 * GyroRange::Dps250.rad_s_per_lsb() - PI / 180.0) < 1e-15);
    assert!(abs(16384.0 * AccelRange::G2.m_s2_per_lsb() - 9.806_65) < 1e-12);
}

#[test]
fn ranges_chosen_by_full_scale() {
    assert_eq!(GyroRange::from_full_scale_dps(1000), Ok(GyroRange::Dps1000));
    assert_eq!(AccelRange::from_full_scale_g(16), Ok(AccelRange::G16));
    assert_eq!(
        GyroRange::from_full_scale_dps(300),
        Err(RangeError::Gyro { dps: 300 })
    );
    assert_eq!(
        AccelRange::from_full_scale_g(3),
        Err(RangeError::Accel { g: 3 })
    );
}

#[test]
fn bandwidth_above_half_the_rate_aliases() {
    let at = |rate, bw| SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap();
    assert!(at(200.0, 256.0).aliases());
    assert!(at(50.0, 42.0).aliases());
    assert!(!at(200.0, 42.0).aliases());
    // Half of 166.667 Hz is 83.3 Hz: above 42 Hz, below 98 Hz.
    assert!(!at(1000.0 / 6.0, 42.0).aliases());
    assert!(at(1000.0 / 6.0, 98.0).aliases());
}

#[test]
fn frequencies_print_like_the_datasheet() {
    extern crate std;
    use std::format;
    assert_eq!(format!("{}", Hz(200.0)), "200");
    assert_eq!(format!("{}", Hz(1000.0 / 6.0)), "166.667");
    assert_eq!(format!("{}", Hz(3.906_25)), "3.906");
    assert_eq!(format!("{}", Hz(0.98)), "0.98");
    assert_eq!(format!("{}", Hz(31.25)), "31.25");
    let err = SensorSettings::for_rate_and_bandwidth(150.0, 42.0).unwrap_err();
    assert_eq!(
        format!("{err}"),
        "150 Hz is not reachable with DLPF_CFG 3: the output rate is 1000 Hz / (1 + SMPLRT_DIV), \
         SMPLRT_DIV 0..255; nearest: 166.667 Hz (SMPLRT_DIV 5) or 142.857 Hz (SMPLRT_DIV 6)"
    );
    // 4000 Hz is beyond the 1 kHz internal rate of 42 Hz, but 8000 / (1 + 1) at 256 Hz.
    let err = SensorSettings::for_rate_and_bandwidth(4000.0, 42.0).unwrap_err();
    assert!(
        format!("{err}").ends_with("bandwidths that give exactly 4000 Hz: 256 Hz"),
        "{err}"
    );
}

#[test]
fn temperature_conversion() {
    assert_eq!(temperature_celsius(0), 36.53);
    assert!(abs(temperature_celsius(-3740) - 25.53) < 1e-12); // -3740/340 = -11
    assert!(abs(temperature_celsius(340) - 37.53) < 1e-12);
    // The MPU-6500: 0 counts is 21 degC, 333.87 counts a degree.
    let mpu6500 = chip_or_mpu6050(0x70);
    assert!(abs(mpu6500.temperature_celsius(0) - 21.0) < 1e-12);
    assert!(abs(mpu6500.temperature_celsius(3339) - (3339.0 / 333.87 + 21.0)) < 1e-12);
    assert_eq!(
        chip_or_mpu6050(0x68).temperature_celsius(340),
        temperature_celsius(340)
    );
    assert_eq!(chip_or_mpu6050(0x01).name, "MPU-6050");
}

#[test]
fn registers_round_trip_and_field_positions() {
    let s = SensorSettings {
        dlpf: DlpfCfg::Cfg5,
        smplrt_div: 77,
        gyro_range: GyroRange::Dps1000,
        accel_range: AccelRange::G16,
    };
    let r = s.registers();
    assert_eq!(
        r,
        RegisterValues {
            smplrt_div: 77,
            config: 0x05,
            gyro_config: 0x10,
            accel_config: 0x18
        }
    );
    assert_eq!(SensorSettings::from_registers(r), s);
    // Bits outside the fields (EXT_SYNC_SET, self-test, ACCEL_HPF) do not change the meaning.
    let noisy = RegisterValues {
        config: 0x05 | 0x38,
        gyro_config: 0x10 | 0xE7,
        accel_config: 0x18 | 0xE7,
        ..r
    };
    assert_eq!(SensorSettings::from_registers(noisy), s);
}

//! The ITG-3200 settings model against its product specification.

extern crate std;
use super::*;
use crate::mpu6050::{DlpfCfg, SettingsError};
use std::string::ToString;

#[test]
fn the_gy85_study_setting_resolves_to_the_documented_registers() {
    // 50 Hz at the 20 Hz filter: 1 kHz / (1 + 19), DLPF_FS = FS_SEL 3 | DLPF_CFG 4.
    let s = Itg3200Settings::for_rate_and_bandwidth(50.0, 20.0).unwrap();
    assert_eq!(s.smplrt_div, 19);
    assert_eq!(s.dlpf_fs(), 0x1C);
    assert_eq!(s.output_rate_hz(), 50.0);
    assert!(!s.aliases());
}

#[test]
fn every_row_and_both_internal_rates() {
    let cases = [
        (8000.0, 256.0, 0, 0x18),
        (1000.0, 256.0, 7, 0x18),
        (1000.0, 188.0, 0, 0x19),
        (200.0, 98.0, 4, 0x1A),
        (100.0, 42.0, 9, 0x1B),
        (10.0, 10.0, 99, 0x1D),
        (3.90625, 5.0, 255, 0x1E),
    ];
    for (rate, bandwidth, div, dlpf_fs) in cases {
        let s = Itg3200Settings::for_rate_and_bandwidth(rate, bandwidth).unwrap();
        assert_eq!(
            (s.smplrt_div, s.dlpf_fs()),
            (div, dlpf_fs),
            "{rate} Hz {bandwidth} Hz"
        );
        assert_eq!(s.output_rate_hz(), rate);
        assert_eq!(f64::from(s.period_us()), 1e6 / rate);
        assert_eq!(s.bandwidth_hz(), Some(bandwidth));
        assert_eq!(Itg3200Settings::from_registers(div, dlpf_fs), s);
    }
    assert!(
        Itg3200Settings::for_rate_and_bandwidth(200.0, 256.0)
            .unwrap()
            .aliases()
    );
}

#[test]
fn accel_bandwidths_and_unreachable_rates_are_refused_with_the_alternatives() {
    let e = Itg3200Settings::for_rate_and_bandwidth(100.0, 44.0).unwrap_err();
    assert_eq!(
        e,
        SettingsError::UnknownBandwidth {
            requested_hz: 44.0,
            gyro_only: true
        }
    );
    let text = e.to_string();
    assert!(text.contains("nearest: 42 Hz (DLPF_CFG 3)"), "{text}");
    assert!(!text.contains("accel"), "{text}");
    let e = Itg3200Settings::for_rate_and_bandwidth(300.0, 42.0).unwrap_err();
    assert_eq!(
        e,
        SettingsError::RateNotReachable {
            requested_hz: 300.0,
            dlpf: DlpfCfg::Cfg3
        }
    );
    let text = e.to_string();
    assert!(
        text.contains("333.333 Hz (SMPLRT_DIV 2) or 250 Hz (SMPLRT_DIV 3)"),
        "{text}"
    );
    assert!(matches!(
        Itg3200Settings::for_rate_and_bandwidth(f64::NAN, 42.0),
        Err(SettingsError::InvalidRate { .. })
    ));
}

#[test]
fn identity_sensitivity_and_temperature() {
    // WHO_AM_I holds the address's bits 6:1; bits 7 and 0 are not part of it.
    assert!(is_itg3200(0x68) && is_itg3200(0x69) && is_itg3200(0xE8));
    assert!(!is_itg3200(0x70) && !is_itg3200(0x00) && !is_itg3200(0xE5));
    assert!((rad_s_per_lsb() - (1.0 / 14.375_f64).to_radians()).abs() < 1e-15);
    assert_eq!(temperature_celsius(-13200), 35.0);
    assert_eq!(temperature_celsius(-13200 + 280), 36.0);
}

//! The ADXL345 settings model against its data sheet.

extern crate std;
use super::settings::rate_of_code;
use super::*;
use std::string::ToString;

#[test]
fn rate_codes_match_table_7() {
    // Table 7 prints 3200 ... 0.10 Hz; the rates are 3200 / 2^k.
    let printed = [
        3200.0, 1600.0, 800.0, 400.0, 200.0, 100.0, 50.0, 25.0, 12.5, 6.25, 3.13, 1.56, 0.78, 0.39,
        0.20, 0.10,
    ];
    for (k, p) in printed.into_iter().enumerate() {
        let code = 15 - k as u8;
        assert_eq!(rate_of_code(code), 3200.0 / f64::from(1u32 << k));
        let s = Adxl345Settings::for_rate(p, false).unwrap();
        assert_eq!(s.rate_code, code, "{p} Hz");
        assert_eq!(s.bandwidth_hz(), s.output_rate_hz() / 2.0);
        if code < 15 {
            assert_eq!(f64::from(s.period_us()), 1e6 / s.output_rate_hz());
        }
        assert_eq!(
            Adxl345Settings::from_registers(s.bw_rate(), s.data_format()),
            s
        );
    }
}

#[test]
fn the_gy85_study_rate_resolves_to_the_documented_register() {
    let s = Adxl345Settings::for_rate(50.0, false).unwrap();
    assert_eq!(s.bw_rate(), 0x09);
    assert_eq!(s.data_format(), 0x08); // full resolution, +/-2 g
    assert_eq!(
        Adxl345Settings::for_rate(25.0, true).unwrap().bw_rate(),
        0x18
    );
}

#[test]
fn unavailable_rates_name_the_nearest() {
    let text = Adxl345Settings::for_rate(60.0, false)
        .unwrap_err()
        .to_string();
    assert!(text.contains("nearest: 50 Hz (BW_RATE 0x09)"), "{text}");
    let text = Adxl345Settings::for_rate(800.0, true)
        .unwrap_err()
        .to_string();
    assert!(text.contains("12.5 to 400 Hz"), "{text}");
    assert!(Adxl345Settings::for_rate(-1.0, false).is_err());
    // By ratio: 75 Hz is 1.33 from 100 and 1.5 from 50; 1000 Hz is 1.25 from 800.
    assert_eq!(Adxl345Settings::nearest_rate(75.0).output_rate_hz(), 100.0);
    assert_eq!(
        Adxl345Settings::nearest_rate(1000.0).output_rate_hz(),
        800.0
    );
    assert_eq!(Adxl345Settings::nearest_rate(50.0).bw_rate(), 0x09);
}

#[test]
fn noise_follows_the_data_sheet() {
    let at = |rate: f64, low_power: bool| Adxl345Settings::for_rate(rate, low_power).unwrap();
    for rate in [12.5, 50.0, 100.0] {
        assert_eq!(at(rate, false).noise_lsb_rms(false), 0.75);
        assert_eq!(at(rate, false).noise_lsb_rms(true), 1.1);
    }
    // "at 400 Hz ODR, the noise on the x- and y-axes is typically less than 1.5 LSB rms, and
    // the noise on the z-axis is typically less than 2.2 LSB rms".
    assert!((at(400.0, false).noise_lsb_rms(false) - 1.5).abs() < 1e-12);
    assert!((at(400.0, false).noise_lsb_rms(true) - 2.2).abs() < 1e-12);
    assert!((at(200.0, false).noise_lsb_rms(false) - 0.75 * 2f64.sqrt()).abs() < 1e-12);
    assert_eq!(at(50.0, true).noise_lsb_rms(false), 1.8);
    assert_eq!(at(50.0, true).noise_lsb_rms(true), 2.6);
}

#[test]
fn ranges_and_scale() {
    let full: std::vec::Vec<u32> = Adxl345Range::ALL.iter().map(|r| r.full_scale_g()).collect();
    assert_eq!(full, [2, 4, 8, 16]);
    assert!((m_s2_per_lsb() - 9.80665 / 256.0).abs() < 1e-15);
}

//! SI <-> conventional units for the IEEE-952 noise terms, and Kalibr's four noise numbers.
//!
//! Inside the library everything is SI (docs/ARCHITECTURE.md, "Units and conventions"): with u the sensor's unit (rad/s for a
//! gyroscope, m/s^2 for an accelerometer), Q in u*s, N in u/sqrt(Hz), B in u, K in
//! u*sqrt(Hz), R in u/s. Conventional units appear only in printed output, always labelled:
//!
//! | term | gyro | accel |
//! |---|---|---|
//! | Q | deg | m/s |
//! | N | deg/sqrt(h) | m/s/sqrt(h) |
//! | B | deg/h | ug (g = 9.80665 m/s^2) |
//! | K | deg/h/sqrt(h) | m/s/h/sqrt(h) |
//! | R | deg/h^2 | m/s/h^2 |
//!
//! Useful identities: 1/sqrt(Hz) = sqrt(s) = sqrt(h)/60, so u/sqrt(Hz) = 60 u/sqrt(h); 1 u/s
//! = 3600 u/h.

use serde::Serialize;
use std::f64::consts::PI;

/// Standard gravity, m/s^2 (CGPM 1901; ISO 80000-3).
pub const STANDARD_GRAVITY: f64 = 9.80665;
/// Degrees per radian.
const DEG_PER_RAD: f64 = 180.0 / PI;
/// sqrt(seconds per hour).
const SQRT_S_PER_H: f64 = 60.0;
const S_PER_H: f64 = 3600.0;

/// Which sensor a term belongs to, i.e. what u is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorKind {
    /// u = rad/s.
    Gyro,
    /// u = m/s^2.
    Accel,
    /// u = the record's own unit; conventional units are the SI ones.
    Other,
}

/// The IEEE-952 terms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum NoiseTerm {
    Q,
    N,
    B,
    K,
    R,
}

/// A value with its unit label.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Quantity {
    pub value: f64,
    pub unit: &'static str,
}

/// The SI unit label of `term` for `kind` (u written out for gyro and accel).
pub fn si_unit(kind: SensorKind, term: NoiseTerm) -> &'static str {
    use NoiseTerm::*;
    use SensorKind::*;
    match (kind, term) {
        (Gyro, Q) => "rad",
        (Gyro, N) => "rad/s/sqrt(Hz)",
        (Gyro, B) => "rad/s",
        (Gyro, K) => "rad/s*sqrt(Hz)",
        (Gyro, R) => "rad/s^2",
        (Accel, Q) => "m/s",
        (Accel, N) => "m/s^2/sqrt(Hz)",
        (Accel, B) => "m/s^2",
        (Accel, K) => "m/s^2*sqrt(Hz)",
        (Accel, R) => "m/s^3",
        (Other, Q) => "u*s",
        (Other, N) => "u/sqrt(Hz)",
        (Other, B) => "u",
        (Other, K) => "u*sqrt(Hz)",
        (Other, R) => "u/s",
    }
}

/// `term`'s SI value with its SI unit label.
pub fn si(kind: SensorKind, term: NoiseTerm, value: f64) -> Quantity {
    Quantity {
        value,
        unit: si_unit(kind, term),
    }
}

/// `term`'s SI value in the conventional unit of the table in the module documentation
/// (unchanged, SI-labelled, for [`SensorKind::Other`]).
pub fn conventional(kind: SensorKind, term: NoiseTerm, si_value: f64) -> Quantity {
    use NoiseTerm::*;
    use SensorKind::*;
    let (value, unit) = match (kind, term) {
        (Gyro, Q) => (rad_to_deg(si_value), "deg"),
        (Gyro, N) => (arw_to_deg_per_sqrt_h(si_value), "deg/sqrt(h)"),
        (Gyro, B) => (rad_s_to_deg_h(si_value), "deg/h"),
        (Gyro, K) => (rrw_to_deg_h_per_sqrt_h(si_value), "deg/h/sqrt(h)"),
        (Gyro, R) => (ramp_to_deg_per_h2(si_value), "deg/h^2"),
        (Accel, Q) => (si_value, "m/s"),
        (Accel, N) => (vrw_to_m_s_per_sqrt_h(si_value), "m/s/sqrt(h)"),
        (Accel, B) => (m_s2_to_micro_g(si_value), "ug"),
        (Accel, K) => (accel_rrw_to_m_s_h_per_sqrt_h(si_value), "m/s/h/sqrt(h)"),
        (Accel, R) => (accel_ramp_to_m_s_per_h2(si_value), "m/s/h^2"),
        (Other, t) => (si_value, si_unit(Other, t)),
    };
    Quantity { value, unit }
}

/// rad -> deg: `x * 180 / pi`.
pub fn rad_to_deg(x: f64) -> f64 {
    x * DEG_PER_RAD
}

/// Angle random walk, rad/s/sqrt(Hz) (= rad/sqrt(s)) -> deg/sqrt(h): `x * (180/pi) * 60`.
pub fn arw_to_deg_per_sqrt_h(x: f64) -> f64 {
    x * DEG_PER_RAD * SQRT_S_PER_H
}

/// deg/sqrt(h) -> rad/s/sqrt(Hz): `x * (pi/180) / 60`.
pub fn deg_per_sqrt_h_to_arw(x: f64) -> f64 {
    x / (DEG_PER_RAD * SQRT_S_PER_H)
}

/// rad/s -> deg/h: `x * (180/pi) * 3600`.
pub fn rad_s_to_deg_h(x: f64) -> f64 {
    x * DEG_PER_RAD * S_PER_H
}

/// deg/h -> rad/s: `x * (pi/180) / 3600`.
pub fn deg_h_to_rad_s(x: f64) -> f64 {
    x / (DEG_PER_RAD * S_PER_H)
}

/// Rate random walk, rad/s*sqrt(Hz) (= rad/s^1.5) -> deg/h/sqrt(h): `x * (180/pi) * 3600 * 60`.
pub fn rrw_to_deg_h_per_sqrt_h(x: f64) -> f64 {
    x * DEG_PER_RAD * S_PER_H * SQRT_S_PER_H
}

/// deg/h/sqrt(h) -> rad/s*sqrt(Hz): `x * (pi/180) / (3600 * 60)`.
pub fn deg_h_per_sqrt_h_to_rrw(x: f64) -> f64 {
    x / (DEG_PER_RAD * S_PER_H * SQRT_S_PER_H)
}

/// Rate ramp, rad/s^2 -> deg/h^2: `x * (180/pi) * 3600^2`.
pub fn ramp_to_deg_per_h2(x: f64) -> f64 {
    x * DEG_PER_RAD * S_PER_H * S_PER_H
}

/// Velocity random walk, m/s^2/sqrt(Hz) (= m/s^1.5) -> m/s/sqrt(h): `x * 60`.
pub fn vrw_to_m_s_per_sqrt_h(x: f64) -> f64 {
    x * SQRT_S_PER_H
}

/// m/s/sqrt(h) -> m/s^2/sqrt(Hz): `x / 60`.
pub fn m_s_per_sqrt_h_to_vrw(x: f64) -> f64 {
    x / SQRT_S_PER_H
}

/// m/s^2 -> micro-g: `x / 9.80665 * 1e6`.
pub fn m_s2_to_micro_g(x: f64) -> f64 {
    x / STANDARD_GRAVITY * 1e6
}

/// micro-g -> m/s^2: `x * 9.80665e-6`.
pub fn micro_g_to_m_s2(x: f64) -> f64 {
    x * STANDARD_GRAVITY * 1e-6
}

/// Accel rate random walk, m/s^2*sqrt(Hz) (= m/s^2.5) -> m/s/h/sqrt(h): `x * 3600 * 60`.
pub fn accel_rrw_to_m_s_h_per_sqrt_h(x: f64) -> f64 {
    x * S_PER_H * SQRT_S_PER_H
}

/// m/s/h/sqrt(h) -> m/s^2*sqrt(Hz): `x / (3600 * 60)`.
pub fn m_s_h_per_sqrt_h_to_accel_rrw(x: f64) -> f64 {
    x / (S_PER_H * SQRT_S_PER_H)
}

/// Accel ramp, m/s^3 -> m/s/h^2: `x * 3600^2`.
pub fn accel_ramp_to_m_s_per_h2(x: f64) -> f64 {
    x * S_PER_H * S_PER_H
}

/// The four noise parameters of Kalibr's IMU configuration YAML.
///
/// Definitions (Kalibr wiki, "IMU Noise Model",
/// <https://github.com/ethz-asl/kalibr/wiki/IMU-Noise-Model>): the measurement is
/// `w~(t) = w(t) + b(t) + n(t)` per axis, with `n` continuous-time white noise,
/// `E[n(t1) n(t2)] = sigma^2 delta(t1 - t2)` (the *noise density*), and the bias a Brownian
/// motion `db/dt = sigma_b w(t)`, `E[w(t1) w(t2)] = delta(t1 - t2)` (the *random walk*).
/// Kalibr discretises them as `sigma_d = sigma / sqrt(dt)` and `sigma_bd = sigma_b sqrt(dt)`.
/// In IEEE-952 terms: `sigma^2` is the two-sided PSD of the white rate noise, i.e. `N^2`, so
/// `sigma = N` (the Allan deviation of the white part at tau = 1 s); the bias PSD is
/// `sigma_b^2 / (2 pi f)^2`, i.e. IEEE-952's `K^2 / (2 pi f)^2`, so `sigma_b = K`. Note that a
/// datasheet's one-sided "noise density" is `sqrt(2) N`, not Kalibr's number.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KalibrNoise {
    /// Gyro N, rad/s/sqrt(Hz) (continuous time).
    pub gyroscope_noise_density: f64,
    /// Gyro K, rad/s^2/sqrt(Hz).
    pub gyroscope_random_walk: f64,
    /// Accel N, m/s^2/sqrt(Hz) (continuous time).
    pub accelerometer_noise_density: f64,
    /// Accel K, m/s^3/sqrt(Hz).
    pub accelerometer_random_walk: f64,
}

impl KalibrNoise {
    /// From the IEEE-952 N and K (SI) of the gyro and the accelerometer: Kalibr's numbers are
    /// these values unchanged (see the type's documentation).
    pub fn from_terms(gyro_n: f64, gyro_k: f64, accel_n: f64, accel_k: f64) -> Self {
        KalibrNoise {
            gyroscope_noise_density: gyro_n,
            gyroscope_random_walk: gyro_k,
            accelerometer_noise_density: accel_n,
            accelerometer_random_walk: accel_k,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
    }

    #[test]
    fn known_values() {
        // 1 deg/sqrt(h) = (pi/180)/60 rad/s/sqrt(Hz) = 2.908882e-4.
        assert!(close(deg_per_sqrt_h_to_arw(1.0), PI / 180.0 / 60.0));
        assert!((deg_per_sqrt_h_to_arw(1.0) - 2.908_882_086_657_216e-4).abs() < 1e-18);
        // 1 deg/h = 4.848137e-6 rad/s.
        assert!((deg_h_to_rad_s(1.0) - 4.848_136_811_095_36e-6).abs() < 1e-19);
        // 1 mg = 9.80665e-3 m/s^2 = 1000 ug.
        assert!(close(m_s2_to_micro_g(9.80665e-3), 1000.0));
        // 1 m/s/sqrt(h) = 1/60 m/s^2/sqrt(Hz).
        assert!(close(m_s_per_sqrt_h_to_vrw(1.0), 1.0 / 60.0));
        // 1 rad/s^1.5 = 57.2958 * 216000 deg/h/sqrt(h).
        assert!(close(rrw_to_deg_h_per_sqrt_h(1.0), 180.0 / PI * 216_000.0));
        assert!(close(ramp_to_deg_per_h2(1.0), 180.0 / PI * 3600.0 * 3600.0));
        assert!(close(accel_ramp_to_m_s_per_h2(2.0), 2.0 * 3600.0 * 3600.0));
    }

    #[test]
    fn round_trips() {
        for x in [1e-9, 3.7e-4, 1.0, 42.0] {
            assert!(close(deg_per_sqrt_h_to_arw(arw_to_deg_per_sqrt_h(x)), x));
            assert!(close(deg_h_to_rad_s(rad_s_to_deg_h(x)), x));
            assert!(close(
                deg_h_per_sqrt_h_to_rrw(rrw_to_deg_h_per_sqrt_h(x)),
                x
            ));
            assert!(close(m_s_per_sqrt_h_to_vrw(vrw_to_m_s_per_sqrt_h(x)), x));
            assert!(close(micro_g_to_m_s2(m_s2_to_micro_g(x)), x));
            assert!(close(
                m_s_h_per_sqrt_h_to_accel_rrw(accel_rrw_to_m_s_h_per_sqrt_h(x)),
                x
            ));
        }
    }

    #[test]
    fn labels() {
        let q = conventional(SensorKind::Gyro, NoiseTerm::N, deg_per_sqrt_h_to_arw(0.3));
        assert!(close(q.value, 0.3));
        assert_eq!(q.unit, "deg/sqrt(h)");
        let b = conventional(SensorKind::Accel, NoiseTerm::B, 9.80665e-5);
        assert!(close(b.value, 10.0));
        assert_eq!(b.unit, "ug");
        let o = conventional(SensorKind::Other, NoiseTerm::K, 2.0);
        assert_eq!((o.value, o.unit), (2.0, "u*sqrt(Hz)"));
        assert_eq!(
            si(SensorKind::Gyro, NoiseTerm::N, 1.0).unit,
            "rad/s/sqrt(Hz)"
        );
        assert_eq!(si_unit(SensorKind::Accel, NoiseTerm::K), "m/s^2*sqrt(Hz)");
    }

    #[test]
    fn kalibr_numbers_are_n_and_k() {
        let k = KalibrNoise::from_terms(1e-3, 2e-5, 3e-3, 4e-4);
        assert_eq!(k.gyroscope_noise_density, 1e-3);
        assert_eq!(k.gyroscope_random_walk, 2e-5);
        assert_eq!(k.accelerometer_noise_density, 3e-3);
        assert_eq!(k.accelerometer_random_walk, 4e-4);
        let json = serde_json::to_string(&k).unwrap();
        assert!(json.contains("\"gyroscope_noise_density\":0.001"));
    }
}

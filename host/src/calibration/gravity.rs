//! Local gravity, m/s^2: standard (9.80665) unless the user gives latitude and height.
//!
//! Normal gravity on the WGS84 ellipsoid by Somigliana's closed formula, then the
//! second-order free-air correction for the height above the ellipsoid — both as in NIMA
//! TR8350.2 (3rd ed., 2000), "Department of Defense World Geodetic System 1984", eq. 4-1 and
//! eq. 4-3:
//!
//! ```text
//!   gamma(phi)   = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)
//!   gamma(phi,h) = gamma(phi) [1 - 2/a (1 + f + m - 2 f sin^2 phi) h + 3 h^2 / a^2]
//! ```
//!
//! Neither includes local anomalies (up to ~1e-3 m/s^2 in mountains), which is why an
//! absolute measured value, when known, should be given directly.

/// Standard gravity (CGPM 1901), m/s^2.
pub const STANDARD: f64 = 9.80665;

/// WGS84 constants (TR8350.2 tables 3.1-3.4).
const GAMMA_E: f64 = 9.780_325_335_9; // normal gravity at the equator, m/s^2
const K: f64 = 0.001_931_852_652_41; // Somigliana's constant
const E2: f64 = 6.694_379_990_14e-3; // first eccentricity squared
const A: f64 = 6_378_137.0; // semi-major axis, m
const F: f64 = 1.0 / 298.257_223_563; // flattening
const M: f64 = 0.003_449_786_506_84; // omega^2 a^2 b / GM

/// Normal gravity at geodetic `latitude_deg` and `height_m` above the ellipsoid, m/s^2.
pub fn normal_gravity(latitude_deg: f64, height_m: f64) -> f64 {
    let s2 = latitude_deg.to_radians().sin().powi(2);
    let surface = GAMMA_E * (1.0 + K * s2) / (1.0 - E2 * s2).sqrt();
    let h = height_m;
    surface * (1.0 - 2.0 / A * (1.0 + F + M - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equator_pole_and_free_air_gradient() {
        // TR8350.2 table 3.4: gamma_e and gamma_p = 9.8321849378.
        assert!((normal_gravity(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-10);
        assert!((normal_gravity(90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        assert!((normal_gravity(-90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        // The textbook free-air gradient, 0.3086 mGal/m = 3.086e-6 s^-2 at mid latitudes.
        let gradient = (normal_gravity(45.0, 0.0) - normal_gravity(45.0, 100.0)) / 100.0;
        assert!((gradient - 3.086e-6).abs() < 0.005e-6, "{gradient}");
        // 45 deg: 9.806199 (the International Gravity Formula 1980 value, same ellipsoid).
        assert!((normal_gravity(45.0, 0.0) - 9.806_199).abs() < 2e-6);
    }
}

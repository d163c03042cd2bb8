//! Deterministic calibration: the errors the noise analysis should not see (bias, scale
//! factor, misalignment, temperature drift of the bias), estimated from guided static
//! positions, a rate table or a warm-up record, and removed from a record in memory.
//!
//! The model, per sensor (gyro in rad/s, accelerometer in m/s^2), is the issue's
//!
//! ```text
//!   f_meas = (I + S + M) f_true + b(T)         K = I + S + M
//! ```
//!
//! S diagonal (scale-factor errors), M off-diagonal (cross-axis misalignment: M_ij is the
//! part of true axis j read on axis i). The simulator writes the same product as
//! (I + M_sim) diag(1 + s): its K has K_jj = 1 + s_j and K_ij = M_sim,ij (1 + s_j), which is
//! what a fit here recovers exactly (first-order equal to M_sim,ij).
//!
//! The pieces: [`gravity`] (local g), [`fit`] (up/down, six-position and rate-table least
//! squares), [`static_bias`] (gyro bias and its Allan uncertainty), [`temperature`] (bias
//! against TEMP_OUT), [`still`] (is the sensor still, is it in the asked orientation),
//! [`rig`] (a board driven through a procedure: turned, watched until still, captured) and
//! [`apply`] (the correction of a record).

pub mod apply;
pub mod fit;
pub mod gravity;
pub mod rig;
pub mod static_bias;
pub mod still;
pub mod temperature;

use serde::{Deserialize, Serialize};

pub type Vec3 = [f64; 3];
pub type Mat3 = [[f64; 3]; 3];

pub const AXES: [&str; 3] = ["x", "y", "z"];

/// Which sensor group a calibration concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sensor {
    Gyro,
    Accel,
}

impl Sensor {
    /// The record's channel names of the three axes.
    pub fn channels(self) -> [&'static str; 3] {
        match self {
            Sensor::Gyro => ["gx", "gy", "gz"],
            Sensor::Accel => ["ax", "ay", "az"],
        }
    }

    /// The SI unit of its readings.
    pub fn unit(self) -> &'static str {
        match self {
            Sensor::Gyro => "rad/s",
            Sensor::Accel => "m/s^2",
        }
    }
}

/// `f_meas = K f_true + b` at the temperature the calibration was made at (module
/// documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Correction {
    pub sensor: Sensor,
    /// b, in the sensor's SI unit.
    pub bias: Vec3,
    /// K = I + S + M; None when this calibration measured the bias only (a static gyro
    /// bias): a correction then takes K from an older calibration, or I.
    pub matrix: Option<Mat3>,
    /// Mean TEMP_OUT while the calibration data were taken, degC (NaN: unknown); a
    /// temperature model moves the bias from here.
    pub temperature_c: f64,
}

impl Correction {
    /// Bias only (the matrix is the identity).
    pub fn bias_only(sensor: Sensor, bias: Vec3, temperature_c: f64) -> Correction {
        Correction {
            sensor,
            bias,
            matrix: None,
            temperature_c,
        }
    }

    /// K, I if not measured.
    pub fn k(&self) -> Mat3 {
        self.matrix.unwrap_or_else(identity)
    }

    /// S: the diagonal of K minus one (None: not measured).
    pub fn scale_factors(&self) -> Option<Vec3> {
        self.matrix.map(|k| [0, 1, 2].map(|i| k[i][i] - 1.0))
    }

    /// M: the off-diagonal of K, zero diagonal (None: not measured).
    pub fn misalignment(&self) -> Option<Mat3> {
        self.matrix.map(|mut m| {
            for (i, row) in m.iter_mut().enumerate() {
                row[i] = 0.0;
            }
            m
        })
    }

    /// f_true = K^-1 (f_meas - b - extra_bias); None if K is singular.
    pub fn correct(&self, measured: Vec3, extra_bias: Vec3) -> Option<Vec3> {
        let v = [0, 1, 2].map(|i| measured[i] - self.bias[i] - extra_bias[i]);
        crate::analysis::numerics::solve3(self.k(), v)
    }
}

pub fn identity() -> Mat3 {
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
}

/// What a calibration procedure produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Accel,
    Gyro,
    Temperature,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Accel => "accel",
            Kind::Gyro => "gyro",
            Kind::Temperature => "temperature",
        }
    }

    pub fn parse(s: &str) -> Option<Kind> {
        [Kind::Accel, Kind::Gyro, Kind::Temperature]
            .into_iter()
            .find(|k| k.name() == s)
    }
}

/// A calibration as stored: what is applied (`corrections`, `temperature`) and the
/// procedure's own evidence (`details`: residuals, up/down values, Allan curve, ...).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    pub kind: Kind,
    pub corrections: Vec<Correction>,
    pub temperature: Vec<temperature::TemperatureModel>,
    pub details: serde_json::Value,
}

//! The six-axis simulated MPU-6050 at rest: gyro xyz, accel xyz (gravity along a chosen
//! axis) and the die temperature, through the signal chain ([`super::chain`]) to the counts
//! the chip's registers hold.
//!
//! Per sensor group (gyro or accel), with true input u (0 rad/s; gravity for the accel), the
//! value entering the DLPF on axis i is
//!
//! ```text
//!   v_i = sum_j (I + M)_ij s_j(T) u_j + b_i + bias(T) + noise_i(t)
//!   s_j(T) = (1 + scale_factor_j) (1 + scale_coeff (T - T_ref)),  bias(T) = bias_coeff (T - T_ref)
//! ```
//!
//! M the cross-axis misalignment (off-diagonal, rad), b the constant bias, noise the axis's
//! [`NoiseTerms`] (independent per axis). The deterministic part is evaluated once per
//! output sample (temperature changes slowly) and held over the internal samples behind it.
//! TEMP_OUT is `round((T + noise - 36.53) * 340)` sampled at the output rate, without the DLPF
//! (another chip's scale with [`Imu::with_chip`]).
//!
//! Timing: output sample n is gyro internal sample n M (M = 1 + SMPLRT_DIV) and accel
//! internal sample floor(n M 1000 / f_i): above 1 kHz output the accelerometer repeats
//! samples, as the chip does. Time of sample n is n / f_s.
//!
//! Scripted procedures (calibration) replace the rest state by a [`TrueInput`]: the true
//! specific force and angular rate along the sensor's axes, taken as u in the formula above
//! (gravity along [`GravityAxis`] and zero rate otherwise).
//!
//! Seeding: every axis (and the temperature noise) draws from its own ChaCha8 stream of the
//! one seed, so a run is reproducible and the axes are independent.

use super::chain::{AxisChain, quantize};
use super::dlpf::{DlpfDesign, Sensor};
use super::line::NarrowBand;
use super::noise::{AxisNoise, NoiseTerms};
use super::temperature::{TempCoupling, TemperatureProfile};
use protocol::mpu6050::{
    ACCEL_INTERNAL_RATE_HZ, Chip, STANDARD_GRAVITY, SensorSettings, WHO_AM_I_VALUE, chip_or_mpu6050,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// One sensor group's error model.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SensorModel {
    /// The same noise terms on each axis (independent realisations).
    pub noise: NoiseTerms,
    /// Spectral lines in the rate (a vibration, a resonance), the same on each axis with
    /// independent phases, before the sensor's filter.
    pub lines: Vec<NarrowBand>,
    /// Constant bias per axis, u.
    pub bias: [f64; 3],
    /// Scale-factor error per axis (0.01 = +1 %).
    pub scale_factor: [f64; 3],
    /// Cross-axis misalignment, added to the identity (diagonal normally 0).
    pub misalignment: [[f64; 3]; 3],
    pub temperature: TempCoupling,
}

/// The die temperature: profile, reference for the coupling, and TEMP_OUT noise (degC).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemperatureModel {
    pub profile: TemperatureProfile,
    pub reference: f64,
    pub noise: NoiseTerms,
}

impl Default for TemperatureModel {
    fn default() -> Self {
        TemperatureModel {
            profile: TemperatureProfile::default(),
            reference: 25.0,
            noise: NoiseTerms::default(),
        }
    }
}

/// Which accelerometer axis gravity lies along, and its sign (+z: the board flat, face up).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GravityAxis {
    pub axis: usize,
    pub negative: bool,
}

impl Default for GravityAxis {
    fn default() -> Self {
        GravityAxis {
            axis: 2,
            negative: false,
        }
    }
}

/// A text that names no accelerometer axis.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not an axis: one of x, y, z, -x, -y, -z")]
pub struct NotAnAxis(pub String);

impl std::str::FromStr for GravityAxis {
    type Err = NotAnAxis;
    fn from_str(s: &str) -> Result<Self, NotAnAxis> {
        let (negative, name) = match s.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, s.strip_prefix('+').unwrap_or(s)),
        };
        let axis = ["x", "y", "z"]
            .iter()
            .position(|a| a.eq_ignore_ascii_case(name))
            .ok_or_else(|| NotAnAxis(s.to_string()))?;
        Ok(GravityAxis { axis, negative })
    }
}

/// The true inputs of a scripted procedure, along the sensor's own axes: the specific force
/// (m/s^2; at rest, +g on the axis pointing up) and the angular rate (rad/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrueInput {
    pub specific_force: [f64; 3],
    pub angular_rate: [f64; 3],
}

impl TrueInput {
    /// At rest with `axis` pointing up (`negative`: pointing down), gravity `g` m/s^2.
    pub fn at_rest(up: GravityAxis, g: f64) -> TrueInput {
        let mut specific_force = [0.0; 3];
        specific_force[up.axis] = if up.negative { -g } else { g };
        TrueInput {
            specific_force,
            angular_rate: [0.0; 3],
        }
    }
}

/// The whole simulated sensor's physics.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuModel {
    pub gyro: SensorModel,
    pub accel: SensorModel,
    pub gravity: GravityAxis,
    pub temperature: TemperatureModel,
}

/// One output sample as the chip's registers hold it (the protocol's type: the FIFO's
/// order and encoding are defined there).
pub use protocol::RawSample;

/// One output sample in SI units: rad/s, m/s^2, degC; time in s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SiSample {
    pub time: f64,
    pub gyro: [f64; 3],
    pub accel: [f64; 3],
    pub temp: f64,
}

impl SiSample {
    /// Counts to SI with the settings' sensitivities and the chip's temperature scale (what
    /// a reader of the registers does).
    pub fn from_raw(
        raw: &RawSample,
        settings: &SensorSettings,
        chip: &Chip,
        time: f64,
    ) -> SiSample {
        let g = settings.gyro_range.rad_s_per_lsb();
        let a = settings.accel_range.m_s2_per_lsb();
        SiSample {
            time,
            gyro: raw.gyro.map(|c| f64::from(c) * g),
            accel: raw.accel.map(|c| f64::from(c) * a),
            temp: chip.temperature_celsius(raw.temp),
        }
    }
}

/// A running six-axis sensor (module documentation).
#[derive(Debug, Clone)]
pub struct Imu {
    model: ImuModel,
    settings: SensorSettings,
    gyro: [AxisChain; 3],
    accel: [AxisChain; 3],
    temp_noise: AxisNoise,
    temp_rng: ChaCha8Rng,
    /// The scripted input, if any (else at rest, gravity along the model's axis).
    input: Option<TrueInput>,
    /// Next output sample index.
    n: u64,
    /// The chip whose TEMP_OUT scale the counts follow (the MPU-6050's unless told).
    chip: Chip,
    /// rad/s per gyro count: the range's unless told ([`Imu::with_gyro_scale`]).
    gyro_lsb: f64,
}

impl Imu {
    /// A sensor with `model` and `settings`, seeded by `seed`; `duration_s` (the expected run
    /// length) sets the flicker band.
    pub fn new(model: &ImuModel, settings: SensorSettings, seed: u64, duration_s: f64) -> Self {
        let stream = |s: u64| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(s);
            rng
        };
        let gyro_design = DlpfDesign::for_setting(settings.dlpf, Sensor::Gyro);
        let accel_design = DlpfDesign::for_setting(settings.dlpf, Sensor::Accel);
        let chains = |m: &SensorModel, d: &DlpfDesign, first: u64| {
            [0, 1, 2].map(|i| {
                AxisChain::new(m.noise, d, duration_s, stream(first + i)).with_lines(&m.lines)
            })
        };
        let mut temp_rng = stream(6);
        let temp_noise = AxisNoise::new(
            model.temperature.noise,
            settings.output_rate_hz(),
            duration_s,
            &mut temp_rng,
        );
        Imu {
            model: model.clone(),
            settings,
            gyro: chains(&model.gyro, &gyro_design, 0),
            accel: chains(&model.accel, &accel_design, 3),
            temp_noise,
            temp_rng,
            input: None,
            n: 0,
            chip: chip_or_mpu6050(WHO_AM_I_VALUE),
            gyro_lsb: settings.gyro_range.rad_s_per_lsb(),
        }
    }

    /// The same sensor with another gyro sensitivity, rad/s per count (a chip whose scale is
    /// not one of the MPU-6050's ranges: the ITG-3200's 14.375 LSB per deg/s).
    pub fn with_gyro_scale(mut self, rad_s_per_lsb: f64) -> Self {
        self.gyro_lsb = rad_s_per_lsb;
        self
    }

    /// The same sensor answering as `chip`: its TEMP_OUT follows that chip's scale.
    pub fn with_chip(mut self, chip: Chip) -> Self {
        self.chip = chip;
        self
    }

    /// Turn and rotate the sensor: from the next sample on, `input` is what it senses
    /// (`None`: back at rest in the model's orientation). The DLPF sees the step as it would
    /// a real turn.
    pub fn set_input(&mut self, input: Option<TrueInput>) {
        self.input = input;
    }

    pub fn settings(&self) -> &SensorSettings {
        &self.settings
    }

    pub fn output_rate_hz(&self) -> f64 {
        self.settings.output_rate_hz()
    }

    /// Time of the next sample, s.
    pub fn next_time(&self) -> f64 {
        self.n as f64 / self.output_rate_hz()
    }

    /// The next output sample, as counts.
    pub fn next_raw(&mut self) -> RawSample {
        let s = self.settings;
        let t = self.next_time();
        let temp = self.model.temperature.profile.at(t);
        let delta = temp - self.model.temperature.reference;
        let temp_rate = self.model.temperature.profile.rate_at(t);
        let decimation = 1 + u64::from(s.smplrt_div);
        let gyro_index = self.n * decimation;
        let internal = s.dlpf.gyro_internal_rate_hz() as u64;
        let accel_index = gyro_index * ACCEL_INTERNAL_RATE_HZ as u64 / internal;

        let input = self
            .input
            .unwrap_or_else(|| TrueInput::at_rest(self.model.gravity, STANDARD_GRAVITY));
        let gyro_signal = deterministic(&self.model.gyro, input.angular_rate, delta, temp_rate);
        let accel_signal = deterministic(&self.model.accel, input.specific_force, delta, temp_rate);
        let gyro_lsb = self.gyro_lsb;
        let accel_lsb = s.accel_range.m_s2_per_lsb();
        let gyro = [0, 1, 2].map(|i| {
            quantize(
                self.gyro[i].advance_to(gyro_index, gyro_signal[i]),
                gyro_lsb,
            )
        });
        let accel = [0, 1, 2].map(|i| {
            quantize(
                self.accel[i].advance_to(accel_index, accel_signal[i]),
                accel_lsb,
            )
        });
        let measured_temp = temp + self.temp_noise.next(&mut self.temp_rng);
        let temp = quantize(
            measured_temp - self.chip.temp_at_zero_c,
            1.0 / self.chip.temp_lsb_per_c,
        );
        self.n += 1;
        RawSample { accel, temp, gyro }
    }

    /// The next output sample in SI units (counts converted back: the values are quantized).
    pub fn next_si(&mut self) -> SiSample {
        let t = self.next_time();
        let raw = self.next_raw();
        SiSample {
            gyro: raw.gyro.map(|c| f64::from(c) * self.gyro_lsb),
            ..SiSample::from_raw(&raw, &self.settings, &self.chip, t)
        }
    }
}

/// The deterministic part of one group's three axes at temperature offset `delta`, changing
/// at `temp_rate` degC/s, for true input `u` (module documentation).
pub(crate) fn deterministic(m: &SensorModel, u: [f64; 3], delta: f64, temp_rate: f64) -> [f64; 3] {
    let (tbias, tscale) = m.temperature.at(delta, temp_rate);
    let scaled: [f64; 3] = [0, 1, 2].map(|j| (1.0 + m.scale_factor[j]) * tscale * u[j]);
    [0, 1, 2].map(|i| {
        let mixed: f64 = (0..3)
            .map(|j| (f64::from(u8::from(i == j)) + m.misalignment[i][j]) * scaled[j])
            .sum();
        mixed + m.bias[i] + tbias
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::temperature::Warmup;

    fn settings() -> SensorSettings {
        SensorSettings::for_rate_and_bandwidth(100.0, 42.0).unwrap()
    }

    #[test]
    fn at_rest_without_noise_reads_gravity_bias_and_temperature() {
        let mut model = ImuModel::default();
        model.gyro.bias = [0.01, -0.02, 0.0];
        model.accel.misalignment[0][2] = 0.01; // x picks up 1 % of z
        model.accel.scale_factor[2] = 0.001;
        model.temperature.profile.initial = 30.0;
        let s = settings();
        let mut imu = Imu::new(&model, s, 1, 10.0);
        let first = imu.next_si();
        assert_eq!(first.time, 0.0);
        let lsb = s.gyro_range.rad_s_per_lsb();
        assert!((first.gyro[0] - 0.01).abs() <= lsb / 2.0 + 1e-12);
        assert!((first.gyro[1] + 0.02).abs() <= lsb / 2.0 + 1e-12);
        let alsb = s.accel_range.m_s2_per_lsb();
        assert!((first.accel[2] - STANDARD_GRAVITY * 1.001).abs() <= alsb / 2.0 + 1e-12);
        assert!((first.accel[0] - 0.01 * STANDARD_GRAVITY * 1.001).abs() <= alsb / 2.0 + 1e-12);
        assert!((first.temp - 30.0).abs() <= 0.5 / 340.0 + 1e-12);
        assert_eq!(imu.next_si().time, 0.01);
        // Gravity on -y.
        model.gravity = "-y".parse().unwrap();
        let mut imu = Imu::new(&model, s, 1, 10.0);
        let raw = imu.next_raw();
        assert_eq!(raw.accel[1], -16384);
        assert!("w".parse::<GravityAxis>().is_err());
    }

    #[test]
    fn scripted_input_goes_through_scale_misalignment_and_bias() {
        let mut model = ImuModel::default();
        model.gyro.bias = [0.01, 0.0, 0.0];
        model.gyro.scale_factor = [0.0, 0.0, 0.02];
        model.gyro.misalignment[0][2] = 0.01;
        let mut imu = Imu::new(&model, settings(), 1, 10.0);
        imu.set_input(Some(TrueInput {
            specific_force: [0.0, -STANDARD_GRAVITY, 0.0],
            angular_rate: [0.0, 0.0, 1.0],
        }));
        let s = imu.next_si();
        let lsb = settings().gyro_range.rad_s_per_lsb();
        // x: bias + M_xz (1 + s_z) w_z; z: (1 + s_z) w_z.
        assert!((s.gyro[0] - (0.01 + 0.01 * 1.02)).abs() <= lsb / 2.0 + 1e-12);
        assert!((s.gyro[2] - 1.02).abs() <= lsb / 2.0 + 1e-12);
        assert_eq!(imu.next_raw().accel, [0, -16384, 0]);
    }

    #[test]
    fn full_scale_clips() {
        let mut model = ImuModel::default();
        model.gyro.bias = [10.0, -10.0, 0.0]; // 573 deg/s, beyond +/-250
        let mut imu = Imu::new(&model, settings(), 1, 1.0);
        let raw = imu.next_raw();
        assert_eq!((raw.gyro[0], raw.gyro[1]), (i16::MAX, i16::MIN));
    }

    #[test]
    fn temperature_couples_into_bias_and_is_reported() {
        let mut model = ImuModel::default();
        model.temperature.profile = TemperatureProfile {
            initial: 25.0,
            warmup: Some(Warmup {
                rise: 10.0,
                tau: 1.0,
            }),
            ..Default::default()
        };
        model.gyro.temperature.bias_coeff = 1e-3; // rad/s per degC
        let mut imu = Imu::new(&model, settings(), 3, 100.0);
        let samples: Vec<SiSample> = (0..2000).map(|_| imu.next_si()).collect();
        let last = samples.last().unwrap();
        assert!((last.temp - 35.0).abs() < 0.01, "{}", last.temp);
        assert!((last.gyro[0] - 0.01).abs() < 2e-4, "{}", last.gyro[0]);
        assert!(samples[0].gyro[0].abs() < 2e-4);
    }

    /// A coupling to the temperature's rate of change adds `rate_coeff dT/dt`: during a
    /// warm-up of 10 degC with tau 20 s, 0.5 degC/s at first and decaying with it. The DLPF
    /// (42 Hz) lags a signal this slow by about 5 ms, a change of under 0.1 LSB here.
    #[test]
    fn a_coupling_to_the_rate_of_change_follows_the_warm_up() {
        let mut model = ImuModel::default();
        let (rise, tau) = (10.0, 20.0);
        model.temperature.profile = TemperatureProfile {
            initial: 25.0,
            warmup: Some(Warmup { rise, tau }),
            ..Default::default()
        };
        model.gyro.temperature.rate_coeff = 0.2; // rad/s per degC/s
        let mut imu = Imu::new(&model, settings(), 3, 100.0);
        let lsb = settings().gyro_range.rad_s_per_lsb();
        for i in 0..6000 {
            let s = imu.next_si();
            let want = 0.2 * rise / tau * (-s.time / tau).exp();
            if i > 10 {
                assert!(
                    (s.gyro[0] - want).abs() <= lsb,
                    "t {}: {} against {want}",
                    s.time,
                    s.gyro[0]
                );
            }
        }
    }

    #[test]
    fn same_seed_same_data_and_axes_differ() {
        let mut model = ImuModel::default();
        model.gyro.noise.n = 1e-3;
        let mut a = Imu::new(&model, settings(), 7, 10.0);
        let mut b = Imu::new(&model, settings(), 7, 10.0);
        let ra: Vec<RawSample> = (0..100).map(|_| a.next_raw()).collect();
        let rb: Vec<RawSample> = (0..100).map(|_| b.next_raw()).collect();
        assert_eq!(ra, rb);
        assert_ne!(
            ra.iter().map(|r| r.gyro[0]).collect::<Vec<_>>(),
            ra.iter().map(|r| r.gyro[1]).collect::<Vec<_>>()
        );
    }
}

//! The MPU-6050's signal chain for one axis, as the chip does it:
//!
//! 1. the continuous-time noise sampled at the internal rate f_i (gyro 8 kHz with DLPF_CFG 0
//!    and 7, else 1 kHz; accelerometer 1 kHz): white noise of Allan coefficient N becomes
//!    per-sample sigma `N sqrt(f_i)` ([`super::noise::AxisNoise`] at f_i does exactly this),
//!    and spectral lines (a vibration, a resonance: [`super::line::LineNoise`]) are added
//!    there, so the DLPF shapes them as it shapes the noise;
//! 2. the DLPF of the chosen DLPF_CFG at f_i ([`super::dlpf`]);
//! 3. decimation to the output rate f_s = f_i / M (M = 1 + SMPLRT_DIV) by taking every M-th
//!    sample, **without** anti-alias filtering;
//! 4. full-scale clipping and rounding to LSB counts ([`quantize`]).
//!
//! Step 3 folds everything above f_s / 2 back into the band. For white input of two-sided
//! density N0^2 the output's two-sided density at f -> 0, which the Allan deviation reads as
//! N^2 at long tau, is
//!
//! ```text
//!   N^2 = N0^2 * sum_{j=0}^{M-1} |H(j f_s)|^2          (H periodic in f_i)
//! ```
//!
//! the sum of the filter's power gain over the M aliases of DC. When the bandwidth is well
//! below f_s / 2 only j = 0 counts and N = N0; otherwise N is inflated by
//! [`white_noise_inflation`]. For large M the sum tends to `2 ENBW / f_s` (ENBW the filter's
//! one-sided noise-equivalent bandwidth), the familiar "noise grows as sqrt(bandwidth / rate)".

use super::dlpf::{Dlpf, DlpfDesign};
use super::line::{LineNoise, NarrowBand};
use super::noise::{AxisNoise, NoiseTerms};
use rand_chacha::ChaCha8Rng;

/// sqrt(sum_{j<M} |H(j f_i / M)|^2): the factor by which decimation by `decimation` after
/// `design` multiplies the Allan coefficient N of white noise (module documentation).
pub fn white_noise_inflation(design: &DlpfDesign, decimation: usize) -> f64 {
    let m = decimation.max(1);
    let fs = design.rate_hz / m as f64;
    (0..m)
        .map(|j| design.response(j as f64 * fs).norm_sqr())
        .sum::<f64>()
        .sqrt()
}

/// `value / lsb` rounded to the nearest count, clipped to the i16 range (what the chip's
/// output registers hold at full scale). NaN gives 0.
pub fn quantize(value: f64, lsb: f64) -> i16 {
    let counts = (value / lsb).round();
    if counts.is_nan() {
        0
    } else {
        counts.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }
}

/// One axis's noise and DLPF at the internal rate, advanced on demand.
#[derive(Debug, Clone)]
pub struct AxisChain {
    noise: AxisNoise,
    lines: Vec<LineNoise>,
    rate_hz: f64,
    rng: ChaCha8Rng,
    dlpf: Dlpf,
    /// Internal samples consumed so far.
    consumed: u64,
    last: f64,
}

impl AxisChain {
    /// `terms` sampled at the design's rate, for a run of about `duration_s` (which sets the
    /// flicker band), drawing from `rng`.
    pub fn new(
        terms: NoiseTerms,
        design: &DlpfDesign,
        duration_s: f64,
        mut rng: ChaCha8Rng,
    ) -> Self {
        let noise = AxisNoise::new(terms, design.rate_hz, duration_s, &mut rng);
        AxisChain {
            noise,
            lines: Vec::new(),
            rate_hz: design.rate_hz,
            rng,
            dlpf: design.filter(),
            consumed: 0,
            last: 0.0,
        }
    }

    /// The same chain with `lines` added to its noise at the internal rate, each in its
    /// stationary state (a random phase) drawn from the chain's generator.
    pub fn with_lines(mut self, lines: &[NarrowBand]) -> Self {
        let rate_hz = self.rate_hz;
        self.lines = lines
            .iter()
            .map(|&line| LineNoise::new(line, rate_hz, &mut self.rng))
            .collect();
        self
    }

    /// The filtered value at internal sample `index` (0-based): every internal sample up to
    /// it is generated and filtered, `signal` being the deterministic part (held constant
    /// over this call). The first call primes the filter with `signal`, so a constant such
    /// as gravity shows no start-up transient. Asking for an index already passed returns
    /// the latest value.
    pub fn advance_to(&mut self, index: u64, signal: f64) -> f64 {
        if self.consumed == 0 {
            self.dlpf.prime(signal);
        }
        while self.consumed <= index {
            let mut x = signal + self.noise.next(&mut self.rng);
            for line in &mut self.lines {
                x += line.next(&mut self.rng);
            }
            self.last = self.dlpf.process(x);
            self.consumed += 1;
        }
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{Estimator, allan, ci, phase_from_rate};
    use crate::sim::dlpf::Sensor;
    use protocol::mpu6050::SensorSettings;
    use rand::SeedableRng;

    #[test]
    fn quantize_rounds_and_clips() {
        assert_eq!(quantize(1.4, 1.0), 1);
        assert_eq!(quantize(-1.6, 1.0), -2);
        assert_eq!(quantize(1e9, 1.0), i16::MAX);
        assert_eq!(quantize(-1e9, 1.0), i16::MIN);
        assert_eq!(quantize(f64::NAN, 1.0), 0);
    }

    /// White noise through the chain at the settings study's four settings: the Allan-derived
    /// N at tau = 1..4 s against N0 times the predicted inflation, inside the 99 % interval.
    /// (Gyro filters; unquantized so that the LSB does not add its own white noise.)
    #[test]
    fn folding_inflates_white_noise_as_predicted() {
        let n0 = 0.01;
        let seconds = 2000.0;
        let mut report = Vec::new();
        for (i, (rate, bw)) in [(200.0, 256.0), (200.0, 42.0), (50.0, 256.0), (50.0, 42.0)]
            .into_iter()
            .enumerate()
        {
            let s = SensorSettings::for_rate_and_bandwidth(rate, bw).unwrap();
            let design = DlpfDesign::for_setting(s.dlpf, Sensor::Gyro);
            let m = 1 + u64::from(s.smplrt_div);
            let predicted = white_noise_inflation(&design, m as usize);
            let terms = NoiseTerms {
                n: n0,
                ..Default::default()
            };
            let mut chain =
                AxisChain::new(terms, &design, seconds, ChaCha8Rng::seed_from_u64(i as u64));
            let count = (seconds * rate) as u64;
            let y: Vec<f64> = (0..count).map(|k| chain.advance_to(k * m, 0.0)).collect();
            let tau0 = 1.0 / rate;
            let x = phase_from_rate(&y, tau0);
            let factors: Vec<usize> = [1.0, 2.0, 4.0]
                .iter()
                .map(|t| (t * rate) as usize)
                .collect();
            let dev = allan::deviation(Estimator::Oadev, &x, tau0, &factors);
            let iv = ci::intervals(&dev, &x, 0.99);
            for k in 0..factors.len() {
                let root = dev.tau[k].sqrt();
                let (lo, hi) = (iv.lo[k] * root / n0, iv.hi[k] * root / n0);
                let measured = dev.dev[k] * root / n0;
                report.push(format!(
                    "{rate} Hz / {bw} Hz tau {}: measured {measured:.4} [{lo:.4}, {hi:.4}] predicted {predicted:.4}",
                    dev.tau[k]
                ));
                assert!(
                    lo <= predicted && predicted <= hi,
                    "{}",
                    report.last().unwrap()
                );
            }
            if (rate, bw) == (200.0, 42.0) {
                // Bandwidth below f_s / 2: N0 itself is inside every interval.
                assert!((predicted - 1.0).abs() < 0.01, "{predicted}");
                for k in 0..factors.len() {
                    let root = dev.tau[k].sqrt();
                    assert!(iv.lo[k] * root <= n0 && n0 <= iv.hi[k] * root);
                }
            }
        }
        println!("{}", report.join("\n"));
    }
}

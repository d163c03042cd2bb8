//! The MPU-6050's digital low-pass filter (DLPF), one design per row of the datasheet's
//! table ([`protocol::mpu6050::DLPF_TABLE`], RM-MPU-6000A register 26), which gives two
//! numbers per row and sensor: the -3 dB bandwidth f_c and the delay D. InvenSense does not
//! publish the filter itself, so we build the simplest filter that matches both numbers
//! exactly, with "delay" read as the group delay at DC (the lag of slow signals, equal to
//! the centroid `sum n h[n] / sum h[n]` of the impulse response):
//!
//! ```text
//!   H(z) = z^-k * G(z),   G = bilinear transform (with prewarping at f_c) of
//!   G(s) = (1 + a s) / (1 + T s)^2
//! ```
//!
//! - a critically damped two-pole low-pass (time constant T) with a lead zero a: its DC
//!   group delay is `2T - a` and `|G(j w)|^2 = (1 + w^2 a^2) / (1 + w^2 T^2)^2`;
//! - k whole samples of pure delay (the pipeline latency of the chip), used where the
//!   datasheet delay exceeds what the two-pole filter alone gives, `D_min = 2 sqrt(sqrt 2 - 1)
//!   / w_c` (a = 0): `k = ceil((D - D_min) / Ts)`, at least 0, so the remainder
//!   `D' = D - k Ts <= D_min` needs a lead `a = 2T - D' >= 0` (a minimum-phase zero);
//! - with `x = w_c T` and `d = w_c D'`, the -3 dB condition `|G|^2 = 1/2` at `w_c` is
//!   `1 + 2 d^2 - 8 d x + 6 x^2 - x^4 = 0`; we take its smallest positive root (the first
//!   crossing), found by scanning and bisection;
//! - the bilinear transform `s = (2/Ts)(1 - z^-1)/(1 + z^-1)` maps `w_c = (2/Ts) tan(pi f_c Ts)`
//!   to f_c exactly and preserves the DC group delay (the frequency warping has unit slope
//!   at DC), so the digital filter has the datasheet's bandwidth and delay exactly.
//!
//! A lead zero makes the response peak slightly above 1 before it falls (largest for the
//! zero-delay accelerometer row 0: +1.25 dB); [`DlpfDesign::peak_gain`] reports it. The
//! reserved DLPF_CFG 7 has no datasheet row: its 8 kHz gyro output is passed through
//! unfiltered (an assumption), the accelerometer uses row 0. The measured bandwidth and
//! delay of every row are checked in this module's tests and listed in `docs/signal_chain.md`.

use protocol::mpu6050::{ACCEL_INTERNAL_RATE_HZ, DlpfCfg};
use realfft::num_complex::Complex;
use std::f64::consts::PI;

/// Which sensor a filter belongs to (their rows differ slightly).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sensor {
    Gyro,
    Accel,
}

/// One DLPF: the design parameters and the digital coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct DlpfDesign {
    /// The rate the filter runs at (the sensor's internal rate), Hz.
    pub rate_hz: f64,
    /// The target -3 dB bandwidth, Hz (`None`: pass-through).
    pub bandwidth_hz: Option<f64>,
    /// The target DC group delay, s.
    pub delay_s: f64,
    /// Whole samples of pure delay, k.
    pub pure_delay: usize,
    /// Pole time constant T of the analog prototype, s.
    pub pole_s: f64,
    /// Lead-zero time constant a of the analog prototype, s.
    pub lead_s: f64,
    /// Biquad numerator b0, b1, b2 and denominator 1, a1, a2.
    pub b: [f64; 3],
    pub a: [f64; 3],
}

impl DlpfDesign {
    /// The filter of a DLPF_CFG for one sensor.
    pub fn for_setting(cfg: DlpfCfg, sensor: Sensor) -> Self {
        let row = cfg.row();
        match (sensor, row) {
            (Sensor::Gyro, Some(r)) => Self::design(
                r.gyro_bandwidth_hz,
                r.gyro_delay_ms * 1e-3,
                r.gyro_internal_rate_hz,
            ),
            (Sensor::Gyro, None) => Self::passthrough(cfg.gyro_internal_rate_hz()),
            (Sensor::Accel, r) => {
                let r = r.unwrap_or(&protocol::mpu6050::DLPF_TABLE[0]);
                Self::design(
                    r.accel_bandwidth_hz,
                    r.accel_delay_ms * 1e-3,
                    ACCEL_INTERNAL_RATE_HZ,
                )
            }
        }
    }

    /// No filtering at `rate_hz`.
    pub fn passthrough(rate_hz: f64) -> Self {
        DlpfDesign {
            rate_hz,
            bandwidth_hz: None,
            delay_s: 0.0,
            pure_delay: 0,
            pole_s: 0.0,
            lead_s: 0.0,
            b: [1.0, 0.0, 0.0],
            a: [1.0, 0.0, 0.0],
        }
    }

    /// The filter with -3 dB bandwidth `bandwidth_hz` (below `rate_hz / 2`) and DC group
    /// delay `delay_s` (>= 0) at `rate_hz` (module documentation).
    pub fn design(bandwidth_hz: f64, delay_s: f64, rate_hz: f64) -> Self {
        let ts = 1.0 / rate_hz;
        let wc = 2.0 / ts * (PI * bandwidth_hz * ts).tan();
        let d_min = 2.0 * (2f64.sqrt() - 1.0).sqrt() / wc;
        let pure_delay = ((delay_s - d_min) / ts - 1e-9).ceil().max(0.0) as usize;
        let remainder = delay_s - pure_delay as f64 * ts;
        let d = wc * remainder;
        let g = |x: f64| 1.0 + 2.0 * d * d - 8.0 * d * x + 6.0 * x * x - x.powi(4);
        let x = smallest_root(g, 0.0, 10.0);
        let pole_s = x / wc;
        let lead_s = 2.0 * pole_s - remainder;
        // Bilinear transform, K = 2 / Ts: numerator (1 + a s)(1 + z^-1)^2 / (1 + z^-1)^2 ...
        let k = 2.0 / ts;
        let (ak, tk) = (lead_s * k, pole_s * k);
        let b = [1.0 + ak, 2.0, 1.0 - ak];
        let a = [
            (1.0 + tk) * (1.0 + tk),
            2.0 * (1.0 + tk) * (1.0 - tk),
            (1.0 - tk) * (1.0 - tk),
        ];
        let a0 = a[0];
        DlpfDesign {
            rate_hz,
            bandwidth_hz: Some(bandwidth_hz),
            delay_s,
            pure_delay,
            pole_s,
            lead_s,
            b: b.map(|v| v / a0),
            a: a.map(|v| v / a0),
        }
    }

    /// The frequency response at `freq_hz`: `z^-k (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 +
    /// a2 z^-2)`, `z = exp(2 pi i f / rate)`.
    pub fn response(&self, freq_hz: f64) -> Complex<f64> {
        let w = 2.0 * PI * freq_hz / self.rate_hz;
        let z1 = Complex::from_polar(1.0, -w);
        let z2 = z1 * z1;
        let num = self.b[0] + z1 * self.b[1] + z2 * self.b[2];
        let den = self.a[0] + z1 * self.a[1] + z2 * self.a[2];
        num / den * Complex::from_polar(1.0, -w * self.pure_delay as f64)
    }

    /// The largest gain `|H|` over `[0, rate/2]` (1 without peaking).
    pub fn peak_gain(&self) -> f64 {
        (0..=2000)
            .map(|i| self.response(self.rate_hz / 2.0 * i as f64 / 2000.0).norm())
            .fold(0.0, f64::max)
    }

    /// A running filter of this design.
    pub fn filter(&self) -> Dlpf {
        Dlpf {
            b: self.b,
            a: self.a,
            s: [0.0; 2],
            delay: vec![0.0; self.pure_delay],
            head: 0,
        }
    }
}

/// Smallest root of `g` in `(lo, hi]` with `g(lo) > 0`: scan, then bisect. `hi` if none.
fn smallest_root(g: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    let steps = 10_000;
    let h = (hi - lo) / steps as f64;
    let mut a = lo;
    for i in 1..=steps {
        let b = lo + h * i as f64;
        if g(b) <= 0.0 {
            let (mut l, mut r) = (a, b);
            for _ in 0..100 {
                let m = 0.5 * (l + r);
                if g(m) > 0.0 { l = m } else { r = m }
            }
            return 0.5 * (l + r);
        }
        a = b;
    }
    hi
}

/// A running DLPF: the pure delay (a ring buffer) then the biquad (transposed direct form II).
#[derive(Debug, Clone)]
pub struct Dlpf {
    b: [f64; 3],
    a: [f64; 3],
    s: [f64; 2],
    delay: Vec<f64>,
    head: usize,
}

impl Dlpf {
    /// Put the filter in its steady state for a constant input `x` (no start-up transient).
    pub fn prime(&mut self, x: f64) {
        let [b0, b1, b2] = self.b;
        let [_, a1, a2] = self.a;
        let _ = b0;
        self.s[1] = (b2 - a2) * x;
        self.s[0] = (b1 - a1) * x + self.s[1];
        self.delay.fill(x);
    }

    /// Filter one sample.
    pub fn process(&mut self, x: f64) -> f64 {
        let x = if self.delay.is_empty() {
            x
        } else {
            let out = std::mem::replace(&mut self.delay[self.head], x);
            self.head = (self.head + 1) % self.delay.len();
            out
        };
        let y = self.b[0] * x + self.s[0];
        self.s[0] = self.b[1] * x - self.a[1] * y + self.s[1];
        self.s[1] = self.b[2] * x - self.a[2] * y;
        y
    }
}

/// Measurements of a running filter from its impulse response `h` (`len` samples): the -3 dB
/// bandwidth (first crossing of `|H|^2 = 1/2`, by bisection on the DTFT of `h`) and the DC
/// group delay (the centroid of `h`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    pub bandwidth_hz: f64,
    pub delay_s: f64,
    pub peak_gain: f64,
}

/// Measure a design by running its filter on an impulse (see [`Measured`]).
pub fn measure(design: &DlpfDesign, len: usize) -> Measured {
    let mut f = design.filter();
    let h: Vec<f64> = (0..len)
        .map(|i| f.process(if i == 0 { 1.0 } else { 0.0 }))
        .collect();
    let dtft = |freq: f64| -> f64 {
        let w = 2.0 * PI * freq / design.rate_hz;
        let (re, im) = h.iter().enumerate().fold((0.0, 0.0), |(re, im), (n, &v)| {
            let p = w * n as f64;
            (re + v * p.cos(), im - v * p.sin())
        });
        re * re + im * im
    };
    let nyquist = design.rate_hz / 2.0;
    let grid = 1000;
    let mut peak: f64 = 0.0;
    let mut crossing = None;
    for i in 0..=grid {
        let f = nyquist * i as f64 / grid as f64;
        let p = dtft(f);
        peak = peak.max(p);
        if crossing.is_none() && p < 0.5 {
            crossing = Some(f);
        }
    }
    let bandwidth_hz = match crossing {
        Some(hi) => {
            let (mut l, mut r) = (hi - nyquist / grid as f64, hi);
            for _ in 0..50 {
                let m = 0.5 * (l + r);
                if dtft(m) < 0.5 { r = m } else { l = m }
            }
            0.5 * (l + r)
        }
        None => nyquist,
    };
    let sum: f64 = h.iter().sum();
    let centroid: f64 = h.iter().enumerate().map(|(n, v)| n as f64 * v).sum::<f64>() / sum;
    Measured {
        bandwidth_hz,
        delay_s: centroid / design.rate_hz,
        peak_gain: peak.sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::mpu6050::DLPF_TABLE;

    /// Every row, both sensors: the running filter's measured -3 dB bandwidth and DC group
    /// delay match the datasheet (0.1 % and 1 us), unity DC gain, mild peaking at most.
    #[test]
    fn every_row_matches_the_datasheet_bandwidth_and_delay() {
        println!(
            "| cfg | sensor | rate Hz | datasheet BW / delay | measured BW / delay | k | T ms | a ms | peak dB |"
        );
        for r in &DLPF_TABLE {
            for sensor in [Sensor::Gyro, Sensor::Accel] {
                let d = DlpfDesign::for_setting(r.cfg, sensor);
                let m = measure(&d, 2_000);
                let bw = d.bandwidth_hz.unwrap();
                println!(
                    "| {} | {sensor:?} | {} | {bw} Hz / {} ms | {:.3} Hz / {:.3} ms | {} | {:.3} | {:.3} | {:+.2} |",
                    r.cfg.bits(),
                    d.rate_hz,
                    d.delay_s * 1e3,
                    m.bandwidth_hz,
                    m.delay_s * 1e3,
                    d.pure_delay,
                    d.pole_s * 1e3,
                    d.lead_s * 1e3,
                    20.0 * m.peak_gain.log10()
                );
                assert!(
                    (m.bandwidth_hz / bw - 1.0).abs() < 1e-3,
                    "{r:?} {sensor:?} {m:?}"
                );
                assert!(
                    (m.delay_s - d.delay_s).abs() < 1e-6,
                    "{r:?} {sensor:?} {m:?}"
                );
                assert!((d.response(0.0).norm() - 1.0).abs() < 1e-12);
                assert!(m.peak_gain < 1.16, "{r:?} {sensor:?} {m:?}");
                assert!(d.lead_s >= -1e-12 && d.pole_s > 0.0, "{d:?}");
            }
        }
        // The reserved setting passes the 8 kHz gyro through.
        let seven = DlpfDesign::for_setting(DlpfCfg::Cfg7, Sensor::Gyro);
        assert_eq!(seven.rate_hz, 8000.0);
        assert_eq!(seven.response(3000.0).norm(), 1.0);
    }

    #[test]
    fn primed_filter_holds_a_constant() {
        for r in &DLPF_TABLE {
            let mut f = DlpfDesign::for_setting(r.cfg, Sensor::Gyro).filter();
            f.prime(9.80665);
            for _ in 0..100 {
                let y = f.process(9.80665);
                assert!((y - 9.80665).abs() < 1e-9, "{:?} {y}", r.cfg);
            }
        }
    }
}

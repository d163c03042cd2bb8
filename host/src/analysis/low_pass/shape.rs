//! The shapes a low-pass of unknown make is fitted from: the filters sensors put between
//! their white noise and their samples, each fixed by its -3 dB cutoff.
//!
//! | shape | response | found in |
//! | --- | --- | --- |
//! | `one_pole` | `1 / (1 + s T)` | RC anti-alias filters, first-order digital low-passes |
//! | `two_pole` | `1 / (1 + s T)^2`, critically damped | the MPU-6050 DLPF's prototype without its lead zero |
//! | `butterworth2` | second-order Butterworth, Q = 1/sqrt(2) | analog anti-alias stages, configurable digital low-passes |
//! | `butterworth4` | fourth-order Butterworth (Q = 0.5412 and 1.3066) | sharp anti-alias filters |
//! | `moving_average` | mean over a window T: `sin(pi f T) / (pi f T)` | averaging or decimating sensors, a boxcar FIR |
//! | `bartlett` | two moving averages in series (triangular window): `sinc^2` | the ADIS1640x's Bartlett-window FIR |
//!
//! Every shape runs at an internal rate of [`super::OVERSAMPLE`] times the output rate and
//! is sampled from there without an anti-alias filter, so that it folds like a continuous
//! filter sampled at the output rate. The recursive ones are the analog prototypes through the
//! bilinear transform, prewarped so the digital cutoff is the analog one (Oppenheim &
//! Schafer, *Discrete-Time Signal Processing*, 3rd ed., 2010, sec. 7.2.2); the fourth-order
//! Butterworth is two second-order sections with `Q_k = 1 / (2 cos((2k - 1) pi / 8))`
//! (Williams & Taylor, *Electronic Filter Design Handbook*, 4th ed., 2006, table 11-1). A
//! moving average over T has its -3 dB point where `sinc^2(f T) = 1/2`, `f T = 0.4430`;
//! the Bartlett's where `sinc^4(f T) = 1/2`, `f T = 0.3188` (each average over T). A moving
//! average over a whole number of output samples, sampled at the output rate, is the
//! digital moving average at that rate: the folded `sinc^2` sums to the Dirichlet kernel.

use crate::sim::dlpf::DlpfDesign;
use realfft::num_complex::Complex;
use serde::Serialize;
use std::f64::consts::PI;

/// A shape of the generic low-pass family (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    OnePole,
    TwoPole,
    Butterworth2,
    Butterworth4,
    MovingAverage,
    Bartlett,
}

impl Shape {
    /// Every shape, in the order [`super::detect`] tries them: the first, the two-pole, is
    /// kept unless another fits the spectrum better by [`super::SHAPE_EVIDENCE`].
    pub const ALL: [Shape; 6] = [
        Shape::TwoPole,
        Shape::OnePole,
        Shape::Butterworth2,
        Shape::Butterworth4,
        Shape::MovingAverage,
        Shape::Bartlett,
    ];

    /// The shape in words.
    pub fn describe(self) -> &'static str {
        match self {
            Shape::OnePole => "one-pole low-pass 1/(1 + sT)",
            Shape::TwoPole => "two-pole low-pass 1/(1 + sT)^2",
            Shape::Butterworth2 => "second-order Butterworth low-pass",
            Shape::Butterworth4 => "fourth-order Butterworth low-pass",
            Shape::MovingAverage => "moving average (boxcar)",
            Shape::Bartlett => "Bartlett (triangular) moving average",
        }
    }

    /// The sections at `internal_hz` whose cascade has its -3 dB point at `cutoff_hz`.
    pub(super) fn sections(self, cutoff_hz: f64, internal_hz: f64) -> Vec<Section> {
        // Bilinear transform with prewarping: s = K (1 - z^-1) / (1 + z^-1), K = 2 f_i, and
        // the analog cutoff moved to 2 f_i tan(pi f_c / f_i); `u` is K over that cutoff.
        let u = 1.0 / (PI * cutoff_hz / internal_hz).tan();
        let second_order = |q: f64| {
            let a0 = 1.0 + u / q + u * u;
            Section::Biquad {
                b: [1.0 / a0, 2.0 / a0, 1.0 / a0],
                a: [2.0 * (1.0 - u * u) / a0, (1.0 - u / q + u * u) / a0],
            }
        };
        let boxcar = |power: i32| Section::Boxcar {
            len: sinc_half_power(power) * internal_hz / cutoff_hz,
        };
        match self {
            Shape::OnePole => vec![Section::Biquad {
                b: [1.0 / (1.0 + u), 1.0 / (1.0 + u), 0.0],
                a: [(1.0 - u) / (1.0 + u), 0.0],
            }],
            Shape::TwoPole => {
                let d = two_pole_design(cutoff_hz, internal_hz);
                vec![Section::Biquad {
                    b: d.b,
                    a: [d.a[1], d.a[2]],
                }]
            }
            Shape::Butterworth2 => vec![second_order(std::f64::consts::FRAC_1_SQRT_2)],
            Shape::Butterworth4 => [PI / 8.0, 3.0 * PI / 8.0]
                .iter()
                .map(|angle| second_order(1.0 / (2.0 * angle.cos())))
                .collect(),
            Shape::MovingAverage => vec![boxcar(2)],
            Shape::Bartlett => vec![boxcar(4), boxcar(4)],
        }
    }
}

/// The critically damped two-pole at `internal_hz`: the DLPF design ([`DlpfDesign::design`])
/// with the DC group delay of the two poles alone, `2 T = 2 sqrt(sqrt 2 - 1) / w_c`, which
/// leaves no lead zero.
fn two_pole_design(cutoff_hz: f64, internal_hz: f64) -> DlpfDesign {
    let ts = 1.0 / internal_hz;
    let wc = 2.0 / ts * (PI * cutoff_hz * ts).tan();
    let delay = 2.0 * (2f64.sqrt() - 1.0).sqrt() / wc;
    DlpfDesign::design(cutoff_hz, delay, internal_hz)
}

/// The x where `sinc(x)^power = 1/2`, `sinc(x) = sin(pi x) / (pi x)`, by bisection on
/// (0, 1/2) where sinc falls from 1 to 2 / pi.
fn sinc_half_power(power: i32) -> f64 {
    let sinc = |x: f64| (PI * x).sin() / (PI * x);
    let (mut lo, mut hi) = (1e-9, 0.5);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if sinc(mid).powi(power) > 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// A frequency at a cascade's rate as `w` radians per sample and `z^-1 = e^{-jw}`: the
/// trigonometry every section's response shares, computed once where a fit evaluates many
/// cascades at the same frequencies.
#[derive(Debug, Clone, Copy)]
pub(super) struct Phasor {
    w: f64,
    z1: Complex<f64>,
}

impl Phasor {
    pub(super) fn new(freq_hz: f64, rate_hz: f64) -> Phasor {
        let w = 2.0 * PI * freq_hz / rate_hz;
        Phasor {
            w,
            z1: Complex::from_polar(1.0, -w),
        }
    }
}

/// One stage of a cascade, at the cascade's rate.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Section {
    /// `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`.
    Biquad { b: [f64; 3], a: [f64; 2] },
    /// The mean over a window of `len` samples (at least 1): `floor(len)` taps of weight
    /// `1 / len` and one more weighing the fraction left, so the cutoff varies continuously.
    Boxcar { len: f64 },
}

impl Section {
    /// The response at `at`: the reference [`Section::power`] is tested against.
    #[cfg(test)]
    fn response(&self, at: &Phasor) -> Complex<f64> {
        let z1 = at.z1;
        match *self {
            Section::Biquad { b, a } => {
                let z2 = z1 * z1;
                (b[0] + z1 * b[1] + z2 * b[2]) / (1.0 + z1 * a[0] + z2 * a[1])
            }
            Section::Boxcar { len } => {
                let m = len.floor();
                let frac = len - m;
                let zm = Complex::from_polar(1.0, -at.w * m);
                let one = Complex::new(1.0, 0.0);
                // The geometric sum of the whole taps, m where z^-1 is 1.
                let whole = if (one - z1).norm() < 1e-9 {
                    Complex::new(m, 0.0)
                } else {
                    (one - zm) / (one - z1)
                };
                (whole + zm * frac) / len
            }
        }
    }

    /// `|H|^2` at `at`: [`Section::response`]'s numerator and denominator squared apart, with
    /// no complex division.
    fn power(&self, at: &Phasor) -> f64 {
        let z1 = at.z1;
        match *self {
            Section::Biquad { b, a } => {
                let z2 = z1 * z1;
                (b[0] + z1 * b[1] + z2 * b[2]).norm_sqr() / (1.0 + z1 * a[0] + z2 * a[1]).norm_sqr()
            }
            Section::Boxcar { len } => {
                let one = Complex::new(1.0, 0.0);
                let below = (one - z1).norm_sqr();
                if below < 1e-18 {
                    return 1.0;
                }
                // (whole + zm frac) (1 - z^-1), whole the geometric sum of the m whole taps.
                let m = len.floor();
                let zm = Complex::from_polar(1.0, -at.w * m);
                ((one - zm) + zm * (len - m) * (one - z1)).norm_sqr() / (below * len * len)
            }
        }
    }

    fn running(&self) -> RunningSection {
        match *self {
            Section::Biquad { b, a } => RunningSection::Biquad { b, a, s: [0.0; 2] },
            Section::Boxcar { len } => {
                let m = len.floor() as usize;
                RunningSection::Boxcar {
                    taps: m,
                    frac: len - m as f64,
                    len,
                    ring: vec![0.0; m + 1],
                    head: 0,
                    sum: 0.0,
                    since_exact: 0,
                }
            }
        }
    }
}

/// A cascade of sections at `rate_hz`.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cascade {
    pub(super) rate_hz: f64,
    pub(super) sections: Vec<Section>,
}

impl Cascade {
    /// The cascade's response at `freq_hz`: the reference [`Cascade::power_at`] is tested
    /// against.
    #[cfg(test)]
    pub(super) fn response(&self, freq_hz: f64) -> Complex<f64> {
        let at = Phasor::new(freq_hz, self.rate_hz);
        self.sections
            .iter()
            .fold(Complex::new(1.0, 0.0), |acc, s| acc * s.response(&at))
    }

    /// `|H|^2` at a phasor of its rate.
    pub(super) fn power_at(&self, at: &Phasor) -> f64 {
        self.sections.iter().map(|s| s.power(at)).product()
    }

    /// A running filter of the cascade, at rest.
    pub(super) fn running(&self) -> RunningCascade {
        RunningCascade(self.sections.iter().map(Section::running).collect())
    }
}

/// A running [`Cascade`].
pub(super) struct RunningCascade(Vec<RunningSection>);

impl RunningCascade {
    pub(super) fn process(&mut self, x: f64) -> f64 {
        self.0.iter_mut().fold(x, |v, s| s.process(v))
    }
}

/// Samples between exact re-summations of a running boxcar's window (the running sum's
/// rounding would otherwise drift over hours of samples).
const RESUM_EVERY: usize = 1 << 16;

enum RunningSection {
    /// Transposed direct form II.
    Biquad {
        b: [f64; 3],
        a: [f64; 2],
        s: [f64; 2],
    },
    /// The last `taps + 1` inputs, newest at `head`, and the sum of the newest `taps`.
    Boxcar {
        taps: usize,
        frac: f64,
        len: f64,
        ring: Vec<f64>,
        head: usize,
        sum: f64,
        since_exact: usize,
    },
}

impl RunningSection {
    fn process(&mut self, x: f64) -> f64 {
        match self {
            RunningSection::Biquad { b, a, s } => {
                let y = b[0] * x + s[0];
                s[0] = b[1] * x - a[0] * y + s[1];
                s[1] = b[2] * x - a[1] * y;
                y
            }
            RunningSection::Boxcar {
                taps,
                frac,
                len,
                ring,
                head,
                sum,
                since_exact,
            } => {
                let size = ring.len();
                *head = (*head + 1) % size;
                // The slot taken is the oldest input, `taps` samples before the newest:
                // it leaves the whole taps and becomes the fractional one.
                let leaving = ring[(*head + 1) % size];
                ring[*head] = x;
                *sum += x - leaving;
                *since_exact += 1;
                if *since_exact >= RESUM_EVERY {
                    *sum = (0..*taps).map(|i| ring[(*head + size - i) % size]).sum();
                    *since_exact = 0;
                }
                let oldest = ring[(*head + 1) % size];
                (*sum + *frac * oldest) / *len
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The internal rate of an output rate of 100 Hz.
    const INTERNAL_HZ: f64 = 1600.0;

    /// Every shape's cascade at [`INTERNAL_HZ`], for cutoffs from the lowest searched to the
    /// output Nyquist frequency.
    fn cascades() -> impl Iterator<Item = (Shape, f64, Cascade)> {
        Shape::ALL.into_iter().flat_map(|shape| {
            [1.6, 12.0, 50.0].map(|cutoff| {
                let c = Cascade {
                    rate_hz: INTERNAL_HZ,
                    sections: shape.sections(cutoff, INTERNAL_HZ),
                };
                (shape, cutoff, c)
            })
        })
    }

    /// Every shape has |H|^2 = 1/2 at its cutoff (folding aside: at the internal rate) and
    /// unit gain at DC, for cutoffs from the lowest searched to the output Nyquist frequency
    /// (an output rate of 100 Hz).
    #[test]
    fn every_shape_is_minus_3_db_at_its_cutoff() {
        for (shape, cutoff, c) in cascades() {
            let dc = c.response(0.0).norm_sqr();
            let at = c.response(cutoff).norm_sqr();
            assert!((dc - 1.0).abs() < 1e-9, "{shape:?} {cutoff}: DC {dc}");
            // The moving averages are the continuous prototype's cutoff, met by the
            // sampled window to its discretisation (below 1 % from 14 internal samples
            // on, a cutoff at the output Nyquist frequency).
            let tolerance = match shape {
                Shape::MovingAverage | Shape::Bartlett => 0.01,
                _ => 1e-9,
            };
            assert!(
                (at - 0.5).abs() < tolerance,
                "{shape:?} {cutoff}: |H|^2 = {at}"
            );
        }
    }

    /// The power the fits sum ([`Cascade::power_at`], no complex division) is the squared
    /// magnitude of the response, over the whole band of the internal rate, DC and the
    /// stopband's nulls included.
    #[test]
    fn the_power_is_the_responses_squared_magnitude() {
        for (shape, cutoff, c) in cascades() {
            for i in 0..=800 {
                let f = i as f64;
                let want = c.response(f).norm_sqr();
                let got = c.power_at(&Phasor::new(f, INTERNAL_HZ));
                assert!(
                    (got - want).abs() <= 1e-12 * want.max(1e-6),
                    "{shape:?} {cutoff} Hz at {f} Hz: {got} against {want}"
                );
            }
        }
    }

    /// The running filter's impulse response has the cascade's response: its DFT at a few
    /// frequencies matches, for every shape (the boxcar's fractional tap included).
    #[test]
    fn the_running_filter_has_the_cascades_response() {
        let internal = 800.0;
        for shape in Shape::ALL {
            let c = Cascade {
                rate_hz: internal,
                sections: shape.sections(23.7, internal),
            };
            let mut run = c.running();
            let h: Vec<f64> = (0..20_000)
                .map(|i| run.process(if i == 0 { 1.0 } else { 0.0 }))
                .collect();
            for f in [0.0, 5.0, 23.7, 61.0, 350.0] {
                let w = 2.0 * PI * f / internal;
                let dtft: Complex<f64> = h
                    .iter()
                    .enumerate()
                    .map(|(j, v)| Complex::from_polar(*v, -w * j as f64))
                    .sum();
                let want = c.response(f);
                assert!(
                    (dtft - want).norm() < 1e-9,
                    "{shape:?} at {f} Hz: {dtft} vs {want}"
                );
            }
        }
    }

    /// A boxcar's running sum stays exact over many re-summation periods.
    #[test]
    fn a_long_running_boxcar_keeps_its_mean() {
        let mut run = Cascade {
            rate_hz: 1.0,
            sections: vec![Section::Boxcar { len: 7.25 }],
        }
        .running();
        let mut last = 0.0;
        for i in 0..5 * RESUM_EVERY {
            last = run.process(1e6 + (i % 3) as f64);
        }
        // The window holds the last 8 inputs, cycling 0, 1, 2 on top of 1e6.
        let n = 5 * RESUM_EVERY;
        let input = |i: usize| 1e6 + (i % 3) as f64;
        let want = ((1..=7).map(|k| input(n - k)).sum::<f64>() + 0.25 * input(n - 8)) / 7.25;
        assert!((last - want).abs() < 1e-9, "{last} vs {want}");
    }
}

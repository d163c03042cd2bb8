//! The shapes a low-pass of unknown make is fitted from: the filters sensors put between
//! their white noise and their samples, each fixed by its -3 dB cutoff.
//!
//! | shape | response | found in |
//! | --- | --- | --- |
//! | `one_pole` | `1 / (1 + s T)`, sampled exactly: the exponential average `(1 - a) / (1 - a z^-1)` at the output rate, `a = exp(-2 pi f_c / f_s)` | RC filters; exponential moving averages at any rate (one decimated is again one) |
//! | `two_pole` | `1 / (1 + s T)^2`, critically damped | the MPU-6050 DLPF's prototype without its lead zero |
//! | `butterworth2` | second-order Butterworth, Q = 1/sqrt(2) | analog anti-alias stages, configurable digital low-passes |
//! | `butterworth4` | fourth-order Butterworth (Q = 0.5412 and 1.3066) | sharp anti-alias filters |
//! | `moving_average` | mean over a window T: `sin(pi f T) / (pi f T)` | averaging or decimating sensors, a boxcar FIR |
//! | `bartlett` | two moving averages in series (triangular window): `sinc^2` | the ADIS1640x's Bartlett-window FIR |
//! | `butterworth2_at_output_rate` | the second-order Butterworth through the bilinear transform at the output rate | a biquad low-pass run on the samples themselves (RBJ cookbook, `scipy.signal.butter(2, ...)`) |
//! | `butterworth4_at_output_rate` | the fourth-order Butterworth, likewise | two such biquads |
//!
//! **Sampled continuous filters.** The first six stand for continuous filters sampled at the
//! output rate without an anti-alias filter: every alias of their stopband folds onto the
//! output band. The one-pole does so exactly: a continuous one-pole's output sampled every
//! `1 / f_s` is the first-order autoregression of coefficient `a = exp(-2 pi f_c / f_s)` (its
//! autocovariance `exp(-|t| / T)` at `t = l / f_s`, `T = 1 / (2 pi f_c)`), whose spectrum is
//! the exponential average's. The others run at an internal rate of [`super::OVERSAMPLE`]
//! times the output rate and are sampled from there; their stopband beyond the internal
//! Nyquist frequency, which this leaves out, falls as `f^-4` or faster. The recursive ones
//! are the analog prototypes through the bilinear transform, prewarped so the digital
//! cutoff is the analog one (Oppenheim & Schafer, *Discrete-Time Signal Processing*, 3rd
//! ed., 2010, sec. 7.2.2); the fourth-order Butterworth is two second-order sections with
//! `Q_k = 1 / (2 cos((2k - 1) pi / 8))` (Williams & Taylor, *Electronic Filter Design
//! Handbook*, 4th ed., 2006, table 11-1). A moving average over T has its -3 dB point where
//! `sinc^2(f T) = 1/2`, `f T = 0.4430`; the Bartlett's where `sinc^4(f T) = 1/2`,
//! `f T = 0.3188` (each average over T). A moving average over a whole number of output
//! samples, sampled at the output rate, is the digital moving average at that rate: the
//! folded `sinc^2` sums to the Dirichlet kernel.
//!
//! **Filters run at the output rate.** The last two run on the output samples: their
//! response is periodic in the output rate with a double zero at its Nyquist frequency,
//! where a sampled continuous filter keeps its folded stopband. (A one-pole through the
//! bilinear transform at the output rate is left out: its zero at Nyquist, with the
//! quantization term the fits add, passes for the sampled one-pole.) Such filters, and the
//! sampled one-pole, are built into the same cascade at the internal rate with every delay
//! `z^-1` of the output rate written `z^-OVERSAMPLE` (`Section::AtOutputRate`): kept every
//! [`super::OVERSAMPLE`]-th sample, the cascade's output on white noise is then exactly the
//! output-rate filter on white noise, since only the inputs on the kept phase reach a kept
//! output.

use crate::sim::dlpf::DlpfDesign;
use realfft::num_complex::Complex;
use serde::Serialize;
use std::f64::consts::PI;

/// A shape of the generic low-pass family (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    OnePole,
    TwoPole,
    Butterworth2,
    Butterworth4,
    MovingAverage,
    Bartlett,
    Butterworth2AtOutputRate,
    Butterworth4AtOutputRate,
}

impl Shape {
    /// Every shape, in the order [`super::detect`] tries them: the first, the two-pole, is
    /// kept unless another fits the spectrum better by [`super::SHAPE_EVIDENCE`].
    pub const ALL: [Shape; 8] = [
        Shape::TwoPole,
        Shape::OnePole,
        Shape::Butterworth2,
        Shape::Butterworth4,
        Shape::MovingAverage,
        Shape::Bartlett,
        Shape::Butterworth2AtOutputRate,
        Shape::Butterworth4AtOutputRate,
    ];

    /// The highest cutoff of the shape, in multiples of the output rate: for the filters run
    /// at the output rate just below its Nyquist frequency, where the bilinear transform's
    /// prewarping diverges; for the others [`super::MAX_CUTOFF_PER_RATE`].
    pub fn max_cutoff_per_rate(self) -> f64 {
        match self {
            Shape::Butterworth2AtOutputRate | Shape::Butterworth4AtOutputRate => {
                MAX_CUTOFF_AT_OUTPUT_RATE
            }
            _ => super::MAX_CUTOFF_PER_RATE,
        }
    }

    /// The shape in words.
    pub fn describe(self) -> &'static str {
        match self {
            Shape::OnePole => "one-pole low-pass 1/(1 + sT) (an exponential average)",
            Shape::TwoPole => "two-pole low-pass 1/(1 + sT)^2",
            Shape::Butterworth2 => "second-order Butterworth low-pass",
            Shape::Butterworth4 => "fourth-order Butterworth low-pass",
            Shape::MovingAverage => "moving average (boxcar)",
            Shape::Bartlett => "Bartlett (triangular) moving average",
            Shape::Butterworth2AtOutputRate => {
                "second-order Butterworth low-pass run at the output rate"
            }
            Shape::Butterworth4AtOutputRate => {
                "fourth-order Butterworth low-pass run at the output rate"
            }
        }
    }

    /// The sections at `internal_hz` whose cascade has its -3 dB point at `cutoff_hz`.
    pub(super) fn sections(self, cutoff_hz: f64, internal_hz: f64) -> Vec<Section> {
        let output_hz = internal_hz / super::OVERSAMPLE as f64;
        let internal = |order| {
            bilinear_butterworth(order, cutoff_hz, internal_hz)
                .into_iter()
                .map(|(b, a)| Section::Biquad { b, a })
                .collect()
        };
        let at_output_rate = |order| {
            bilinear_butterworth(order, cutoff_hz, output_hz)
                .into_iter()
                .map(|(b, a)| Section::AtOutputRate { b, a })
                .collect()
        };
        let boxcar = |power: i32| Section::Boxcar {
            len: sinc_half_power(power) * internal_hz / cutoff_hz,
        };
        match self {
            Shape::OnePole => {
                let a = (-2.0 * PI * cutoff_hz / output_hz).exp();
                vec![Section::AtOutputRate {
                    b: [1.0 - a, 0.0, 0.0],
                    a: [-a, 0.0],
                }]
            }
            Shape::TwoPole => {
                let d = two_pole_design(cutoff_hz, internal_hz);
                vec![Section::Biquad {
                    b: d.b,
                    a: [d.a[1], d.a[2]],
                }]
            }
            Shape::Butterworth2 => internal(2),
            Shape::Butterworth4 => internal(4),
            Shape::MovingAverage => vec![boxcar(2)],
            Shape::Bartlett => vec![boxcar(4), boxcar(4)],
            Shape::Butterworth2AtOutputRate => at_output_rate(2),
            Shape::Butterworth4AtOutputRate => at_output_rate(4),
        }
    }
}

/// The highest cutoff of the filters run at the output rate, in multiples of that rate.
const MAX_CUTOFF_AT_OUTPUT_RATE: f64 = 0.49;

/// The Butterworth low-pass of `order` 2 or 4 at `rate_hz` with -3 dB at `cutoff_hz`, as
/// (numerator, denominator without its leading 1) pairs of its second-order sections:
/// the bilinear transform with prewarping, `s = K (1 - z^-1) / (1 + z^-1)`, `K = 2 f`, the
/// analog cutoff moved to `2 f tan(pi f_c / f)`; `u` is K over that cutoff.
fn bilinear_butterworth(order: usize, cutoff_hz: f64, rate_hz: f64) -> Vec<([f64; 3], [f64; 2])> {
    let u = 1.0 / (PI * cutoff_hz / rate_hz).tan();
    let second_order = |q: f64| {
        let a0 = 1.0 + u / q + u * u;
        (
            [1.0 / a0, 2.0 / a0, 1.0 / a0],
            [2.0 * (1.0 - u * u) / a0, (1.0 - u / q + u * u) / a0],
        )
    };
    match order {
        2 => vec![second_order(std::f64::consts::FRAC_1_SQRT_2)],
        _ => [PI / 8.0, 3.0 * PI / 8.0]
            .iter()
            .map(|angle| second_order(1.0 / (2.0 * angle.cos())))
            .collect(),
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

/// A frequency at a cascade's rate as `w` radians per sample, `z^-1 = e^{-jw}` and the delay
/// of one output sample `z^-OVERSAMPLE`: the trigonometry every section's response shares,
/// computed once where a fit evaluates many cascades at the same frequencies.
#[derive(Debug, Clone, Copy)]
pub(super) struct Phasor {
    w: f64,
    z1: Complex<f64>,
    z_output: Complex<f64>,
}

/// The phasors of `f + j f_s`, j = 0..OVERSAMPLE-1, at the internal rate `OVERSAMPLE f_s`:
/// the frequencies whose power folds onto `f` at the output rate `f_s`. Built only here, so
/// the k-th lies `k / OVERSAMPLE` of a turn from the first, which
/// [`Cascade::folded_power_at`] relies on.
#[derive(Debug, Clone)]
pub(super) struct Aliases([Phasor; super::OVERSAMPLE]);

impl Aliases {
    pub(super) fn new(freq_hz: f64, output_rate_hz: f64) -> Aliases {
        let internal = output_rate_hz * super::OVERSAMPLE as f64;
        Aliases(std::array::from_fn(|j| {
            Phasor::new(freq_hz + j as f64 * output_rate_hz, internal)
        }))
    }
}

impl Phasor {
    pub(super) fn new(freq_hz: f64, rate_hz: f64) -> Phasor {
        let w = 2.0 * PI * freq_hz / rate_hz;
        Phasor {
            w,
            z1: Complex::from_polar(1.0, -w),
            z_output: Complex::from_polar(1.0, -w * super::OVERSAMPLE as f64),
        }
    }
}

/// `(b0 + b1 z + b2 z^2) / (1 + a1 z + a2 z^2)`'s numerator and denominator at `z` (a delay).
fn biquad_parts(b: [f64; 3], a: [f64; 2], z: Complex<f64>) -> (Complex<f64>, Complex<f64>) {
    let z2 = z * z;
    (b[0] + z * b[1] + z2 * b[2], 1.0 + z * a[0] + z2 * a[1])
}

/// A [`Section::Boxcar`]'s `|H|^2` at the delay `z1` (`z^-1`), given `zm = z1^m` for its
/// `m = floor(len)` whole taps.
fn boxcar_power(len: f64, z1: Complex<f64>, zm: Complex<f64>) -> f64 {
    let one = Complex::new(1.0, 0.0);
    let below = (one - z1).norm_sqr();
    if below < 1e-18 {
        return 1.0;
    }
    // (whole + zm frac) (1 - z^-1), whole the geometric sum of the m whole taps.
    let m = len.floor();
    ((one - zm) + zm * (len - m) * (one - z1)).norm_sqr() / (below * len * len)
}

/// `e^{-j 2 pi k / OVERSAMPLE}`, k = 0..OVERSAMPLE-1: the turns between the aliases
/// [`Cascade::folded_power_at`] sums.
static ALIAS_TURNS: std::sync::LazyLock<[Complex<f64>; super::OVERSAMPLE]> =
    std::sync::LazyLock::new(|| {
        std::array::from_fn(|k| {
            Complex::from_polar(1.0, -2.0 * PI * k as f64 / super::OVERSAMPLE as f64)
        })
    });

/// Most sections a cascade of [`Shape::sections`] has: [`Cascade::folded_power_at`] keeps
/// their boxcars' first-alias delays on the stack.
const MAX_SECTIONS: usize = 4;

/// One stage of a cascade, at the cascade's rate.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Section {
    /// `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`.
    Biquad { b: [f64; 3], a: [f64; 2] },
    /// A biquad of the output rate: [`Section::Biquad`] with each `z^-1` a delay of
    /// [`super::OVERSAMPLE`] samples.
    AtOutputRate { b: [f64; 3], a: [f64; 2] },
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
                let (num, den) = biquad_parts(b, a, z1);
                num / den
            }
            Section::AtOutputRate { b, a } => {
                let (num, den) = biquad_parts(b, a, at.z_output);
                num / den
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
        let biquad = |b, a, z| {
            let (num, den) = biquad_parts(b, a, z);
            num.norm_sqr() / den.norm_sqr()
        };
        match *self {
            Section::Biquad { b, a } => biquad(b, a, z1),
            Section::AtOutputRate { b, a } => biquad(b, a, at.z_output),
            Section::Boxcar { len } => {
                boxcar_power(len, z1, Complex::from_polar(1.0, -at.w * len.floor()))
            }
        }
    }

    fn running(&self) -> RunningSection {
        match *self {
            Section::Biquad { b, a } => RunningSection::Biquad { b, a, s: [0.0; 2] },
            Section::AtOutputRate { b, a } => RunningSection::AtOutputRate {
                b,
                a,
                s: Box::new([[0.0; 2]; super::OVERSAMPLE]),
                phase: 0,
            },
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

    /// `sum_j |H|^2` over `aliases` at this cascade's rate `OVERSAMPLE f_s`: the power
    /// folded onto `f`. A cascade run wholly at the output rate has the same response at
    /// every alias (its delays turn by whole turns from one to the next), so it is evaluated
    /// once.
    ///
    /// The k-th alias lies `k / OVERSAMPLE` of a turn from the first ([`Aliases`]), so a
    /// boxcar's `z^-m` there is the first alias's turned by `k m` such steps: one sine and
    /// cosine per section rather than one per alias.
    pub(super) fn folded_power_at(&self, aliases: &Aliases) -> f64 {
        let aliases = &aliases.0;
        let first = &aliases[0];
        let all_at_output_rate = self
            .sections
            .iter()
            .all(|s| matches!(s, Section::AtOutputRate { .. }));
        if all_at_output_rate {
            return aliases.len() as f64 * self.power_at(first);
        }
        if self.sections.len() > MAX_SECTIONS {
            return aliases.iter().map(|p| self.power_at(p)).sum();
        }
        let mut first_zm = [Complex::new(1.0, 0.0); MAX_SECTIONS];
        for (zm, s) in first_zm.iter_mut().zip(&self.sections) {
            if let Section::Boxcar { len } = *s {
                *zm = Complex::from_polar(1.0, -first.w * len.floor());
            }
        }
        let turns = &*ALIAS_TURNS;
        aliases
            .iter()
            .enumerate()
            .map(|(k, at)| {
                self.sections
                    .iter()
                    .zip(&first_zm)
                    .map(|(s, zm)| match *s {
                        Section::Boxcar { len } => {
                            let m = len.floor() as usize;
                            let turn = turns[(k * m) % super::OVERSAMPLE];
                            boxcar_power(len, at.z1, zm * turn)
                        }
                        _ => s.power(at),
                    })
                    .product::<f64>()
            })
            .sum()
    }

    /// Whether a section runs at the output rate ([`Section::AtOutputRate`]).
    pub(super) fn at_output_rate(&self) -> bool {
        self.sections
            .iter()
            .any(|s| matches!(s, Section::AtOutputRate { .. }))
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
    /// A transposed direct form II per phase of the output rate: the internal samples
    /// `OVERSAMPLE` apart are one output-rate filter's, and the phases never mix.
    AtOutputRate {
        b: [f64; 3],
        a: [f64; 2],
        s: Box<[[f64; 2]; super::OVERSAMPLE]>,
        phase: usize,
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
            RunningSection::Biquad { b, a, s } => transposed_biquad(*b, *a, s, x),
            RunningSection::AtOutputRate { b, a, s, phase } => {
                let y = transposed_biquad(*b, *a, &mut s[*phase], x);
                *phase = (*phase + 1) % s.len();
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

/// One step of a transposed direct form II biquad with state `s`.
fn transposed_biquad(b: [f64; 3], a: [f64; 2], s: &mut [f64; 2], x: f64) -> f64 {
    let y = b[0] * x + s[0];
    s[0] = b[1] * x - a[0] * y + s[1];
    s[1] = b[2] * x - a[1] * y;
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The internal rate of an output rate of 100 Hz.
    const INTERNAL_HZ: f64 = 1600.0;

    /// Every shape's cascade at [`INTERNAL_HZ`], for cutoffs from the lowest searched to the
    /// output Nyquist frequency (to the highest of a shape run at the output rate).
    fn cascades() -> impl Iterator<Item = (Shape, f64, Cascade)> {
        Shape::ALL.into_iter().flat_map(|shape| {
            [1.6, 12.0, 50.0].map(|cutoff: f64| {
                let cutoff = cutoff.min(
                    shape.max_cutoff_per_rate() * INTERNAL_HZ / super::super::OVERSAMPLE as f64,
                );
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
    /// (an output rate of 100 Hz). The one-pole, sampled exactly, has unit gain at DC and
    /// its folded -3 dB point is tested in `the_one_pole_is_the_sampled_continuous_one_pole`.
    #[test]
    fn every_shape_is_minus_3_db_at_its_cutoff() {
        for (shape, cutoff, c) in cascades() {
            let dc = c.response(0.0).norm_sqr();
            if shape == Shape::OnePole {
                assert!((dc - 1.0).abs() < 1e-9, "{shape:?} {cutoff}: DC {dc}");
                continue;
            }
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

    /// The one-pole's folded power is the continuous one-pole's `1 / (1 + (f / f_c)^2)`
    /// summed over every alias `f + k f_s`, relative to DC: against the closed form of that
    /// sum, `sum_k 1 / (a^2 + (x + k)^2) = (pi / a) sinh(2 pi a) / (cosh(2 pi a) - cos(2 pi
    /// x))` with `a = f_c / f_s`, `x = f / f_s` (the partial fractions of the cotangent,
    /// Abramowitz & Stegun 4.3.91, summed in pairs), and against the sum itself truncated
    /// at |k| <= 20 000 (the tail left, `2 a^2 / 20 000`, below 1e-4 of it); for cutoffs
    /// from 1/64 of the rate to twice it.
    #[test]
    fn the_one_pole_is_the_sampled_continuous_one_pole() {
        let fs = 100.0;
        for cutoff in [1.6, 12.0, 31.0, 50.0, 150.0] {
            let c = Cascade {
                rate_hz: INTERNAL_HZ,
                sections: Shape::OnePole.sections(cutoff, INTERNAL_HZ),
            };
            let a = cutoff / fs;
            let closed = |x: f64| {
                PI / a * (2.0 * PI * a).sinh() / ((2.0 * PI * a).cosh() - (2.0 * PI * x).cos())
            };
            let truncated = |x: f64| -> f64 {
                (-20_000..=20_000)
                    .map(|k| 1.0 / (a * a + (x + k as f64).powi(2)))
                    .sum()
            };
            for i in 0..=20 {
                let f = fs / 2.0 * i as f64 / 20.0;
                let x = f / fs;
                let got = c.power_at(&Phasor::new(f, INTERNAL_HZ))
                    / c.power_at(&Phasor::new(0.0, INTERNAL_HZ));
                let want = closed(x) / closed(0.0);
                assert!(
                    (got / want - 1.0).abs() < 1e-9,
                    "{cutoff} Hz at {f} Hz: {got} against {want}"
                );
                let summed = truncated(x) / truncated(0.0);
                assert!(
                    (got / summed - 1.0).abs() < 1e-4,
                    "{cutoff} Hz at {f} Hz: {got} against the sum {summed}"
                );
            }
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

    /// The folded power a fit sums ([`Cascade::folded_power_at`], once for a cascade run at
    /// the output rate) is the sum of the responses' squared magnitudes over the aliases.
    #[test]
    fn the_folded_power_sums_the_aliases_responses() {
        let output = INTERNAL_HZ / super::super::OVERSAMPLE as f64;
        for (shape, cutoff, c) in cascades() {
            for i in 0..=50 {
                let f = output / 2.0 * i as f64 / 50.0;
                let aliases: Vec<f64> = (0..super::super::OVERSAMPLE)
                    .map(|j| f + j as f64 * output)
                    .collect();
                let want: f64 = aliases.iter().map(|&a| c.response(a).norm_sqr()).sum();
                let got = c.folded_power_at(&Aliases::new(f, output));
                assert!(
                    (got - want).abs() <= 1e-10 * want.max(1e-6),
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

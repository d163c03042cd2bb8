//! Families of hidden-effect records for testing the workflow: a baseline of white noise,
//! flicker (B) and rate random walk (K) with terms drawn from ranges, plus zero, one or two
//! effects with parameters drawn from ranges. Every draw comes from the record's seed, so a
//! family is many different records, not one case tuned to pass.
//!
//! Effect strengths are set relative to the baseline where the effect shows, by a factor f
//! drawn from [`RAISE`]: the Allan deviation at the effect's own tau is raised f times over
//! the baseline's (slow sinusoid, Gauss-Markov, ramp, temperature), or a line's excess
//! one-sided PSD is `rho` times the white level (tones).

use crate::analysis::low_pass::LowPass;
use crate::record::{Channel, Record};
use crate::sim::noise::sinusoid_avar;
use crate::sim::noise::{
    AxisNoise, GaussMarkov, NoiseTerms, Sinusoid, add_line, gauss_markov_avar,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// Range of the factor by which an effect raises the Allan deviation where it shows.
pub const RAISE: (f64, f64) = (2.0, 3.5);

/// Least separation of a slow sinusoid from the temperature cycle, in bins of `1 / record
/// length`, for the two to be told apart (see [`crate::model::clean`]).
pub const RESOLVED_BINS: f64 = 2.0;

/// What is hidden in a record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    None,
    /// No effect, but a temperature channel (warm-up and cycles) the rate does not follow.
    NoneWithTemperature,
    /// Gauss-Markov with tau_c 1-3 % of the record (minutes): the baseline's B can absorb it.
    GaussMarkov,
    /// A sinusoid with a period of 5-20 % of the record.
    SlowSinusoid,
    /// A line between 0.1 and 0.45 x the sample rate, 0 to 1 Hz wide.
    Tone,
    /// A ramp over the whole record.
    Ramp,
    /// A temperature coupling: a warm-up of a few degC plus slow cycles, channel given.
    Temperature,
    /// A tone and a ramp.
    ToneAndRamp,
    /// A slow sinusoid and a temperature coupling, the sinusoid at least [`RESOLVED_BINS`]
    /// bins of the record's periodogram from the temperature cycle: closer, a sinusoid is
    /// indistinguishable from a coupling to the temperature's rate of change.
    SlowSinusoidAndTemperature,
    /// The white noise through a low-pass filter of unknown cutoff (3-30 % of the rate,
    /// log-uniform).
    LowPass,
    /// A low-pass filter as [`Kind::LowPass`] and a line as [`Kind::Tone`] where the filter
    /// passes at least a tenth of the power, its strength relative to the filtered white
    /// level there: a sensor with its own filter and a mechanical resonance.
    LowPassAndTone,
    /// A ramp as [`Kind::Ramp`] and a temperature coupling as [`Kind::Temperature`]: the
    /// warm-up is nearly a ramp over its first minutes.
    RampAndTemperature,
    /// A Gauss-Markov process as [`Kind::GaussMarkov`] and a line as [`Kind::Tone`].
    GaussMarkovAndTone,
    /// A low-pass filter as [`Kind::LowPass`] and a ramp as [`Kind::Ramp`].
    LowPassAndRamp,
    /// A low-pass filter as [`Kind::LowPass`] and two to four narrow lines where it passes
    /// at least a tenth of the power, as in [`Kind::LowPassAndTone`], each 0.002-0.05 Hz
    /// wide (or a pure tone), 20-100x the filtered white PSD and apart from the others by
    /// forty widths: a sensor with its own filter and a comb of vibration lines (the
    /// ADIS16405's accelerometers carry lines 0.6-17 mHz wide, 0.1 Hz apart).
    LowPassAndLines,
    /// A temperature coupling as [`Kind::Temperature`] plus one to the temperature's rate of
    /// change (a thermal gradient across the sensor), each raising the Allan deviation on
    /// its own: the rate term peaks during the warm-up and is a quarter-cycle out of phase
    /// with the cycles.
    TemperatureAndItsRate,
}

impl Kind {
    /// The effect kinds the workflow should name, sorted.
    pub fn expected(self) -> Vec<&'static str> {
        let mut v = match self {
            Kind::None | Kind::NoneWithTemperature => vec![],
            Kind::GaussMarkov => vec!["gauss_markov"],
            Kind::SlowSinusoid | Kind::Tone => vec!["sinusoid"],
            Kind::Ramp => vec!["rate_ramp"],
            Kind::Temperature | Kind::TemperatureAndItsRate => vec!["temperature"],
            Kind::ToneAndRamp => vec!["rate_ramp", "sinusoid"],
            Kind::SlowSinusoidAndTemperature => vec!["sinusoid", "temperature"],
            Kind::LowPass => vec!["low_pass"],
            Kind::LowPassAndTone => vec!["low_pass", "sinusoid"],
            // One sinusoid per line drawn: `Hidden::expected`.
            Kind::LowPassAndLines => vec!["low_pass"],
            Kind::RampAndTemperature => vec!["rate_ramp", "temperature"],
            Kind::GaussMarkovAndTone => vec!["gauss_markov", "sinusoid"],
            Kind::LowPassAndRamp => vec!["low_pass", "rate_ramp"],
        };
        v.sort_unstable();
        v
    }
}

/// Record shape: rate (Hz) and length (s).
#[derive(Debug, Clone, Copy)]
pub struct Shape {
    pub rate_hz: f64,
    pub duration_s: f64,
}

/// The full study's records: 3 h at 50 Hz.
pub const STUDY_SHAPE: Shape = Shape {
    rate_hz: 50.0,
    duration_s: 3.0 * 3600.0,
};

/// The records of the tests that run in CI: 1 h at 20 Hz (shorter and slower than the
/// study's, so every effect is weaker against the noise).
pub const CI_SHAPE: Shape = Shape {
    rate_hz: 20.0,
    duration_s: 3600.0,
};

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (uniform(rng, lo.ln(), hi.ln())).exp()
}

/// A baseline drawn for a record of `t_rec` s: N log-uniform over 5e-5 to 5e-4
/// rad/s/sqrt(Hz); the flicker floor from 1 % to 4 % of N's Allan deviation at 1 s
/// (crossing N around 30-600 s); the random walk crossing N at a tenth to a third of the
/// record.
pub fn baseline(rng: &mut ChaCha8Rng, t_rec: f64) -> NoiseTerms {
    let n = log_uniform(rng, 5e-5, 5e-4);
    let b = n * log_uniform(rng, 0.03, 0.12);
    let tau_k = t_rec * uniform(rng, 0.1, 0.3);
    NoiseTerms {
        n,
        b,
        k: 3f64.sqrt() * n / tau_k,
        ..NoiseTerms::default()
    }
}

/// The baseline's AVAR at `tau` (IEEE 952 Table C.1).
fn baseline_avar(t: &NoiseTerms, tau: f64) -> f64 {
    t.n * t.n / tau + 2.0 * 2f64.ln() / PI * t.b * t.b + t.k * t.k * tau / 3.0
}

/// A generated record and what was hidden in it.
pub struct Hidden {
    pub record: Record,
    /// The baseline's terms (Gauss-Markov included for that kind; N is the white level
    /// before any low-pass filter).
    pub terms: NoiseTerms,
    /// The ramp's slope, rad/s/s, for the ramp kinds.
    pub slope: Option<f64>,
    /// The coupling to the temperature, rad/s/degC, for the temperature kinds.
    pub temp_coeff: Option<f64>,
    /// The coupling to the temperature's rate of change, rad/s per degC/s, for
    /// [`Kind::TemperatureAndItsRate`].
    pub temp_rate_coeff: Option<f64>,
    /// The slow sinusoid, for the slow-sinusoid kinds.
    pub sinusoid: Option<Sinusoid>,
    /// The lines `(freq_hz, width_hz, power u^2)`, for the tone kinds.
    pub tones: Vec<(f64, f64, f64)>,
    /// The low-pass filter's -3 dB cutoff, Hz, for the low-pass kinds.
    pub cutoff_hz: Option<f64>,
}

impl Hidden {
    /// What was hidden, for a study's report.
    pub fn describe(&self) -> String {
        let mut parts = vec![format!(
            "N {:.3e}, B {:.3e}, K {:.3e}",
            self.terms.n, self.terms.b, self.terms.k
        )];
        if let Some(g) = self.terms.gauss_markov {
            parts.push(format!(
                "Gauss-Markov tau_c {:.1} s, sigma {:.3e}",
                g.tau_c, g.sigma
            ));
        }
        if let Some(s) = self.sinusoid {
            parts.push(format!("sinusoid {:.5} Hz, {:.3e}", s.freq_hz, s.amplitude));
        }
        for &(f, w, p) in &self.tones {
            parts.push(format!(
                "line {f:.3} Hz, {w:.3} Hz wide, amplitude {:.3e}",
                (2.0 * p).sqrt()
            ));
        }
        if let Some(slope) = self.slope {
            parts.push(format!("ramp {slope:.3e}"));
        }
        if let Some(c) = self.cutoff_hz {
            parts.push(format!("low-pass {c:.2} Hz"));
        }
        parts.join("; ")
    }

    /// The effect kinds the workflow should name for the record of `kind`, sorted: one
    /// sinusoid per line drawn.
    pub fn expected(&self, kind: Kind) -> Vec<&'static str> {
        let mut v = kind.expected();
        if kind == Kind::LowPassAndLines {
            v.extend(self.tones.iter().map(|_| "sinusoid"));
            v.sort_unstable();
        }
        v
    }
}

/// A record of `kind` with everything drawn from `seed`; the channel is `gx` (rad/s), plus
/// `temp` (degC) for the temperature kinds.
pub fn record(kind: Kind, shape: Shape, seed: u64) -> Record {
    generate(kind, shape, seed).record
}

/// [`record`], with what was hidden in it.
pub fn generate(kind: Kind, shape: Shape, seed: u64) -> Hidden {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = (shape.rate_hz * shape.duration_s) as usize;
    let tau0 = 1.0 / shape.rate_hz;
    let t_rec = shape.duration_s;
    let mut terms = baseline(&mut rng, t_rec);
    let n_density = terms.n;
    let raise = |rng: &mut ChaCha8Rng| {
        let f = uniform(rng, RAISE.0, RAISE.1);
        f * f - 1.0
    };
    let mut extra: Vec<Box<dyn Fn(f64) -> f64>> = Vec::new();
    let mut temp_channel: Option<Vec<f64>> = None;
    let mut temp_coeff = None;
    let mut temp_rate_coeff = None;
    if matches!(kind, Kind::GaussMarkov | Kind::GaussMarkovAndTone) {
        let tau_c = t_rec * log_uniform(&mut rng, 0.01, 0.03);
        // The GM Allan variance peaks near tau = 1.89 tau_c.
        let peak_tau = 1.89 * tau_c;
        let unit = gauss_markov_avar(GaussMarkov { sigma: 1.0, tau_c }, peak_tau);
        let sigma = (raise(&mut rng) * baseline_avar(&terms, peak_tau) / unit).sqrt();
        terms.gauss_markov = Some(GaussMarkov { sigma, tau_c });
    }
    let mut slow: Option<Sinusoid> = None;
    if matches!(kind, Kind::SlowSinusoid | Kind::SlowSinusoidAndTemperature) {
        let period = t_rec * uniform(&mut rng, 0.05, 0.2);
        let freq_hz = 1.0 / period;
        // A sinusoid's Allan variance peaks at tau = 0.371 / f.
        let peak_tau = 0.371 * period;
        let unit = sinusoid_avar(
            Sinusoid {
                amplitude: 1.0,
                freq_hz,
            },
            peak_tau,
        );
        let amplitude = (raise(&mut rng) * baseline_avar(&terms, peak_tau) / unit).sqrt();
        slow = Some(Sinusoid { amplitude, freq_hz });
        let phase = uniform(&mut rng, 0.0, 2.0 * PI);
        extra.push(Box::new(move |t| {
            amplitude * (2.0 * PI * freq_hz * t + phase).sin()
        }));
    }
    let cutoff_hz = matches!(
        kind,
        Kind::LowPass | Kind::LowPassAndTone | Kind::LowPassAndLines | Kind::LowPassAndRamp
    )
    .then(|| shape.rate_hz * log_uniform(&mut rng, 0.03, 0.3));
    let low_pass =
        cutoff_hz.map(|c| LowPass::two_pole(c, shape.rate_hz).expect("a cutoff below Nyquist"));
    let passes = |f: f64| low_pass.as_ref().map_or(1.0, |lp| lp.power_gain(f));
    let count = match kind {
        Kind::Tone | Kind::ToneAndRamp | Kind::LowPassAndTone | Kind::GaussMarkovAndTone => 1,
        Kind::LowPassAndLines => rng.random_range(2..=4),
        _ => 0,
    };
    let mut tones: Vec<(f64, f64, f64)> = Vec::new();
    for _ in 0..count {
        // Where the filter passes a tenth of the power: a low cutoff moves the lines' band
        // below a tenth of the rate.
        let mut top = 0.45 * shape.rate_hz;
        while passes(top) < 0.1 {
            top *= 0.99;
        }
        let bottom = (0.1 * shape.rate_hz).min(0.5 * top);
        // A comb's lines apart by forty of their widths and twenty bins: a Lorentzian 50
        // times the background at its peak still stands 3 % above it 20 widths out, and the
        // detector's bands follow such wings until they reach the next line, which then
        // reads as one wide line (measured on widths of 0.04-0.17 Hz 1-2 Hz apart).
        let apart = |f: f64, w: f64| {
            tones
                .iter()
                .all(|&(g, v, _)| (f - g).abs() > 40.0 * (w + v) + 20.0 / t_rec)
        };
        let comb = kind == Kind::LowPassAndLines;
        let drawn = (0..1000).find_map(|_| {
            let freq_hz = uniform(&mut rng, bottom, top);
            let width_hz = if rng.random::<f64>() < 0.3 {
                0.0
            } else if comb {
                log_uniform(&mut rng, 0.002, 0.05)
            } else {
                uniform(&mut rng, 0.05, 1.0)
            };
            apart(freq_hz, width_hz).then_some((freq_hz, width_hz))
        });
        let Some((freq_hz, width_hz)) = drawn else {
            break;
        };
        // A comb's lines stand clear of the single line's detection limit (the tone kinds
        // measure that), so that the family measures naming several lines together.
        let rho = if comb {
            log_uniform(&mut rng, 20.0, 100.0)
        } else {
            log_uniform(&mut rng, 10.0, 50.0)
        };
        // Excess one-sided PSD rho x 2 N^2 (times the filter's gain) over the line's width (at least one bin); a
        // Lorentzian of FWHM w has peak 2 P / (pi w) for power P.
        let effective = width_hz.max(1.0 / t_rec);
        let power = rho * 2.0 * n_density * n_density * passes(freq_hz) * PI * effective / 2.0;
        tones.push((freq_hz, width_hz, power));
    }
    let mut ramp_slope = None;
    if matches!(
        kind,
        Kind::Ramp | Kind::ToneAndRamp | Kind::RampAndTemperature | Kind::LowPassAndRamp
    ) {
        // A ramp competes with the random walk's own trend (slope sd about K sqrt(1.2 / T)),
        // so it is drawn stronger: raising the deviation at T/4 3 to 5 times.
        let tau = t_rec / 4.0;
        let f = uniform(&mut rng, 3.0, 5.0);
        let slope = ((f * f - 1.0) * baseline_avar(&terms, tau) * 2.0 / (tau * tau)).sqrt()
            * if rng.random::<bool>() { 1.0 } else { -1.0 };
        ramp_slope = Some(slope);
        extra.push(Box::new(move |t| slope * t));
    }
    if matches!(
        kind,
        Kind::Temperature
            | Kind::SlowSinusoidAndTemperature
            | Kind::NoneWithTemperature
            | Kind::RampAndTemperature
            | Kind::TemperatureAndItsRate
    ) {
        let rise = uniform(&mut rng, 2.0, 6.0);
        let warm = uniform(&mut rng, 600.0, 2400.0);
        let swing = uniform(&mut rng, 0.5, 2.0);
        let mut cycle = t_rec * uniform(&mut rng, 0.15, 0.4);
        while slow.is_some_and(|s| (s.freq_hz - 1.0 / cycle).abs() * t_rec < RESOLVED_BINS) {
            cycle = t_rec * uniform(&mut rng, 0.15, 0.4);
        }
        let start = uniform(&mut rng, 20.0, 30.0);
        let temp = move |t: f64| {
            start + rise * (1.0 - (-t / warm).exp()) + swing * (2.0 * PI * t / cycle).sin()
        };
        let tau = t_rec / 8.0;
        // A coupling's Allan variance at tau is about coeff^2 times its regressor's.
        let avar_of = |f: &dyn Fn(f64) -> f64, tau: f64| {
            let m = (tau / tau0) as usize;
            let means: Vec<f64> = (0..n / m)
                .map(|j| (0..m).map(|i| f((j * m + i) as f64 * tau0)).sum::<f64>() / m as f64)
                .collect();
            means.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>()
                / (2.0 * (means.len() - 1).max(1) as f64)
        };
        let temp_avar = avar_of(&temp, tau);
        let coeff = (raise(&mut rng) * baseline_avar(&terms, tau) / temp_avar).sqrt()
            * if rng.random::<bool>() { 1.0 } else { -1.0 }
            * if kind == Kind::NoneWithTemperature {
                0.0
            } else {
                1.0
            };
        let mut noise = ChaCha8Rng::seed_from_u64(seed ^ 0x7e3);
        temp_channel = Some(
            (0..n)
                .map(|i| {
                    let v = temp(i as f64 * tau0) + 0.02 * noise.sample::<f64, _>(StandardNormal);
                    (v * 340.0).round() / 340.0
                })
                .collect(),
        );
        temp_coeff = Some(coeff);
        extra.push(Box::new(move |t| coeff * (temp(t) - start)));
        if kind == Kind::TemperatureAndItsRate {
            let rate = move |t: f64| {
                rise / warm * (-t / warm).exp()
                    + swing * 2.0 * PI / cycle * (2.0 * PI * t / cycle).cos()
            };
            // Raising the deviation where the warm-up's rate shows, at a tenth of the
            // warm-up's time constant.
            let at = warm / 10.0;
            let rate_coeff = (raise(&mut rng) * baseline_avar(&terms, at) / avar_of(&rate, at))
                .sqrt()
                * if rng.random::<bool>() { 1.0 } else { -1.0 };
            temp_rate_coeff = Some(rate_coeff);
            extra.push(Box::new(move |t| rate_coeff * rate(t)));
        }
    }
    let drawn = terms;
    if low_pass.is_some() {
        terms.n = 0.0;
    }
    let mut generator = AxisNoise::new(terms, shape.rate_hz, t_rec, &mut rng);
    let mut values = generator.take(n, &mut rng);
    if let Some(lp) = low_pass {
        let white = lp.white_through(drawn.n, n, &mut rng);
        values.iter_mut().zip(white).for_each(|(v, w)| *v += w);
    }
    for (i, v) in values.iter_mut().enumerate() {
        let t = i as f64 * tau0;
        *v += extra.iter().map(|f| f(t)).sum::<f64>();
    }
    for &(freq_hz, width_hz, power) in &tones {
        add_line(
            &mut values,
            shape.rate_hz,
            freq_hz,
            width_hz,
            (2.0 * power).sqrt(),
            &mut rng,
        );
    }
    let mut channels = vec![Channel::named("gx", values)];
    if let Some(t) = temp_channel {
        channels.push(Channel::named("temp", t));
    }
    Hidden {
        record: Record {
            source: format!("{kind:?} seed {seed}"),
            rate_hz: shape.rate_hz,
            channels,
        },
        terms: drawn,
        slope: ramp_slope,
        temp_coeff,
        temp_rate_coeff,
        sinusoid: slow,
        tones,
        cutoff_hz,
    }
}

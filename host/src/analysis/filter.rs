//! Filter-ready noise parameters: what a Kalman filter's process and measurement noise should
//! be, from a channel's fitted noise terms, in continuous time and for a filter period dt.
//!
//! u is the channel's unit (rad/s or m/s^2). Continuous-time densities are **two-sided** power
//! spectral densities (the IEEE-952 convention: white rate noise with Allan coefficient N has
//! PSD q = N^2, so that E[w(t) w(s)] = q delta(t - s)).
//!
//! | noise | continuous | discrete, period dt |
//! |---|---|---|
//! | white rate noise N | q_w = N^2, u^2/Hz = u^2 s | sample std N / sqrt(dt), u (the noise of one dt-average of the rate); integrated state (angle, velocity): Q_d = N^2 dt, (u s)^2 |
//! | rate random walk K (bias state b' = w) | q_b = K^2, u^2 Hz = u^2/s | Q_d = K^2 dt, u^2 |
//! | Gauss-Markov bias (b' = -b / tau_c + w) | sigma, tau_c; driving q = 2 sigma^2 / tau_c, u^2/s | phi = exp(-dt / tau_c), Q_d = sigma^2 (1 - phi^2), u^2 |
//!
//! The random-walk rows are the settings study's "Q = sigma^2 x period"
//! (docs/references.md): for a continuous white noise of PSD q driving a state, the state's
//! covariance grows by exactly q dt over dt
//! (the discrete-time equivalent `Q_d = integral_0^dt Phi(s) G q G^T Phi(s)^T ds` with
//! Phi = 1; Maybeck, *Stochastic Models, Estimation and Control*, vol. 1, ch. 4). The
//! Gauss-Markov row is the same integral with Phi(s) = e^(-s/tau_c):
//! Q_d = (q tau_c / 2)(1 - e^(-2 dt / tau_c)) = sigma^2 (1 - phi^2), the exact
//! discretisation, which is how the
//! simulator steps it (`sim/noise.rs`). A random walk the record does not resolve (K = 0)
//! is given as the upper end of its interval and marked, as in the Kalibr file.

use crate::analysis::fit::NoiseFit;
use crate::analysis::gauss_markov::{self, GaussMarkovError, GaussMarkovFit};
use crate::analysis::pipeline::ChannelResult;
use crate::analysis::units::{NoiseTerm, SensorKind, si_unit};
use serde::Serialize;

/// One number with its unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Value {
    pub value: f64,
    pub unit: String,
}

fn value(value: f64, unit: impl Into<String>) -> Value {
    Value {
        value,
        unit: unit.into(),
    }
}

/// A channel's filter parameters for period `period_s`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilterNoise {
    pub channel: String,
    /// u.
    pub unit: &'static str,
    pub period_s: f64,
    pub white: White,
    pub random_walk: RandomWalk,
    /// `Err`: why the data do not support a Gauss-Markov bias.
    #[serde(serialize_with = "serialize_gm")]
    pub gauss_markov: Result<GaussMarkovState, GaussMarkovError>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct White {
    /// N, u/sqrt(Hz).
    pub density: Value,
    /// q_w = N^2.
    pub psd: Value,
    /// N / sqrt(dt).
    pub sample_std: Value,
    /// N^2 dt.
    pub integrated_variance: Value,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RandomWalk {
    /// K, u*sqrt(Hz).
    pub density: Value,
    /// q_b = K^2.
    pub psd: Value,
    /// K^2 dt.
    pub variance_per_step: Value,
    /// K was not resolved: these are the upper end of its interval.
    pub upper_bound: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GaussMarkovState {
    pub sigma: Value,
    pub tau_c: Value,
    /// 2 sigma^2 / tau_c.
    pub driving_psd: Value,
    /// exp(-dt / tau_c), dimensionless.
    pub phi: f64,
    /// sigma^2 (1 - phi^2).
    pub variance_per_step: Value,
}

fn serialize_gm<S: serde::Serializer>(
    gm: &Result<GaussMarkovState, GaussMarkovError>,
    s: S,
) -> Result<S::Ok, S::Error> {
    /// The document's form of a Gauss-Markov bias the data do not support.
    #[derive(Serialize)]
    struct Unsupported {
        supported: bool,
        reason: String,
    }
    match gm {
        Ok(state) => state.serialize(s),
        Err(reason) => Unsupported {
            supported: false,
            reason: reason.to_string(),
        }
        .serialize(s),
    }
}

/// The filter parameters of every channel with a noise fit (the others are left out).
pub fn for_channels(
    results: &[ChannelResult],
    period_s: f64,
) -> Result<Vec<FilterNoise>, BadPeriod> {
    check_period(period_s)?;
    Ok(results
        .iter()
        .filter_map(|c| {
            let fit = c.fit.as_ref().ok()?;
            let gm = gauss_markov::fit_channel(c);
            Some(filter_noise(&c.name, c.kind, c.unit, fit, gm, period_s))
        })
        .collect())
}

/// A filter period that is not a positive, finite number of seconds.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("the filter period must be a positive number of seconds, not {0}")]
pub struct BadPeriod(pub f64);

/// A filter period must be a positive, finite number of seconds.
pub fn check_period(period_s: f64) -> Result<(), BadPeriod> {
    if !(period_s.is_finite() && period_s > 0.0) {
        return Err(BadPeriod(period_s));
    }
    Ok(())
}

/// The table of the module documentation for one channel.
pub fn filter_noise(
    channel: &str,
    kind: SensorKind,
    unit: &'static str,
    fit: &NoiseFit,
    gm: Result<GaussMarkovFit, GaussMarkovError>,
    dt: f64,
) -> FilterNoise {
    let u2 = squared(unit);
    let n = fit.n.value;
    let upper_bound = fit.k.value <= 0.0;
    let k = if upper_bound {
        fit.k.hi.max(0.0)
    } else {
        fit.k.value
    };
    let integrated = squared(si_unit(kind, NoiseTerm::Q));
    FilterNoise {
        channel: channel.to_string(),
        unit,
        period_s: dt,
        white: White {
            density: value(n, si_unit(kind, NoiseTerm::N)),
            psd: value(n * n, format!("{u2}/Hz")),
            sample_std: value(n / dt.sqrt(), unit),
            integrated_variance: value(n * n * dt, integrated),
        },
        random_walk: RandomWalk {
            density: value(k, si_unit(kind, NoiseTerm::K)),
            psd: value(k * k, format!("{u2}*Hz")),
            variance_per_step: value(k * k * dt, u2.clone()),
            upper_bound,
        },
        gauss_markov: gm.map(|g| {
            let phi = (-dt / g.tau_c).exp();
            let s2 = g.sigma * g.sigma;
            GaussMarkovState {
                sigma: value(g.sigma, unit),
                tau_c: value(g.tau_c, "s"),
                driving_psd: value(2.0 * s2 / g.tau_c, format!("{u2}/s")),
                phi,
                variance_per_step: value(s2 * (1.0 - phi * phi), u2),
            }
        }),
    }
}

/// `unit^2`, with parentheses when the unit is compound.
fn squared(unit: &str) -> String {
    if unit.contains(['/', '*', '^']) {
        format!("({unit})^2")
    } else {
        format!("{unit}^2")
    }
}

/// The conventions, stated in every output.
pub const CONVENTIONS: &str = "continuous-time densities are two-sided PSDs (white noise of PSD q: E[w(t)w(s)] = q delta(t-s)); white rate noise q = N^2, its per-sample std at period dt N/sqrt(dt), its integrated state (angle/velocity) grows by Q_d = N^2 dt per step; rate random walk q = K^2, Q_d = K^2 dt (the paper's Q = sigma^2 x period: a white PSD q integrated over dt); first-order Gauss-Markov b' = -b/tau_c + w: q = 2 sigma^2/tau_c, phi = exp(-dt/tau_c), Q_d = sigma^2 (1 - phi^2) (exact discretisation)";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::fit::{Goodness, Support, Term, TermSupport};

    fn term(value: f64, hi: f64) -> Term {
        Term { value, lo: 0.0, hi }
    }

    /// Hand-derived numbers for N = 2e-3 rad/s/sqrt(Hz), K = 0 (upper bound 3e-5), a
    /// Gauss-Markov of sigma 1e-3 rad/s, tau_c 50 s, at dt = 0.01 s:
    /// q_w = 4e-6, sample std = 2e-3 / 0.1 = 0.02, N^2 dt = 4e-8; K -> 3e-5: q_b = 9e-10,
    /// K^2 dt = 9e-12; GM: q = 2e-6 / 50 = 4e-8, phi = exp(-2e-4) = 0.99980002,
    /// Q_d = 1e-6 (1 - exp(-4e-4)) = 3.99920011e-10.
    #[test]
    fn hand_derived_values() {
        let fit = NoiseFit {
            q: term(0.0, 0.0),
            n: Term {
                value: 2e-3,
                lo: 1.9e-3,
                hi: 2.1e-3,
            },
            b: term(0.0, 0.0),
            k: term(0.0, 3e-5),
            r: term(0.0, 0.0),
            confidence: 0.683,
            points: 10,
            effective_points: 5.0,
            reduced_chi2: 1.0,
            iterations: 1,
            tau_min: 0.01,
            low_pass: None,
            goodness: Goodness::NOMINAL,
            support: TermSupport::same(Support {
                detected: true,
                p_value: 0.0,
            }),
        };
        let gm = GaussMarkovFit {
            sigma: 1e-3,
            tau_c: 50.0,
            q: 0.0,
            n: 2e-3,
            k: 0.0,
            peak_share: 0.9,
        };
        let f = filter_noise("gx", SensorKind::Gyro, "rad/s", &fit, Ok(gm), 0.01);
        let close = |a: f64, b: f64| (a / b - 1.0).abs() < 1e-7;
        assert!(close(f.white.psd.value, 4e-6));
        assert_eq!(f.white.psd.unit, "(rad/s)^2/Hz");
        assert!(close(f.white.sample_std.value, 0.02));
        assert!(close(f.white.integrated_variance.value, 4e-8));
        assert_eq!(f.white.integrated_variance.unit, "rad^2");
        assert!(f.random_walk.upper_bound);
        assert!(close(f.random_walk.psd.value, 9e-10));
        assert!(close(f.random_walk.variance_per_step.value, 9e-12));
        let g = f.gauss_markov.unwrap();
        assert!(close(g.driving_psd.value, 4e-8));
        assert!(close(g.phi, 0.999_800_019_998_666_7));
        assert!(close(g.variance_per_step.value, 3.999_200_106_656e-10));
    }
}

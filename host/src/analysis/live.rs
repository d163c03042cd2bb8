//! The noise of a record that is still growing: [`Streaming`] accumulators per channel, and on
//! demand a snapshot with each channel's Allan deviation and intervals, the five-term fit so
//! far, and the record length each term of a [`StopRule`] still needs.
//!
//! The ladder is the one `analyze` uses by default (10 factors per decade), up to the
//! longest record expected, with the factors above the exact range snapped to multiples of
//! a power of two ([`snap_factors`]; by at most 0.1 %). The fit is [`fit::fit_deviation`]
//! on the streamed curve: at the strided factors it takes the EDF of the fully overlapping
//! estimator, which is within 0.1 % of the decimated series' own at the default lag (see
//! [`super::streaming`]). A snapshot is an indication; the stop rule's decision is confirmed
//! by `analyze`'s own pipeline on the samples (see `capture --until`).

use super::fit::{self, FitError, FitOptions, NoiseFit};
use super::low_pass::LowPass;
use super::precision::{self, Horizon, Status, StopRule};
use super::streaming::{Config, Curve, Streaming, StreamingError, snap_factors};
use super::taus::{self, TauGrid};
use super::{Estimator, allan};
use serde::Serialize;

/// The ladder of [`Live`]: `analyze`'s default.
pub const GRID: TauGrid = TauGrid::PerDecade(10);

/// Running accumulators of several channels sampled together.
#[derive(Debug, Clone)]
pub struct Live {
    names: Vec<String>,
    tau0: f64,
    channels: Vec<Streaming>,
    /// Each channel's sensor low-pass filter, which its fit models (as `analyze` does).
    low_pass: Vec<Option<LowPass>>,
    /// The longest record expected, s: how far the stop rule's lengths are looked for.
    longest_s: f64,
}

/// One channel's state in a [`Snapshot`].
#[derive(Debug, Clone, Serialize)]
pub struct ChannelSnapshot {
    pub name: String,
    /// tau (s), Allan deviation (channel unit), and `confidence` bounds from the fit's noise
    /// types; empty bounds when the fit failed.
    pub tau: Vec<f64>,
    pub adev: Vec<f64>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    /// The five-term fit so far, or why there is none yet.
    #[serde(skip)]
    pub fit: Result<NoiseFit, FitError>,
    /// N, B and K so far (value, lo, hi), when the fit succeeded.
    pub n: Option<fit::Term>,
    pub b: Option<fit::Term>,
    pub k: Option<fit::Term>,
    /// Each target of the stop rule: the precision reached, and the record length (s) at
    /// which it is expected to be met (`None`: not within the longest record expected, or
    /// the term is not detected, or the model does not describe the curve).
    pub targets: Vec<TargetSnapshot>,
}

/// One target of the stop rule on one channel.
#[derive(Debug, Clone, Serialize)]
pub struct TargetSnapshot {
    #[serde(flatten)]
    pub status: Status,
    pub needed_s: Option<f64>,
}

/// Every channel at one moment.
#[derive(Debug, Clone, Serialize)]
pub struct Snapshot {
    /// Sample time so far, s.
    pub elapsed_s: f64,
    pub confidence: f64,
    pub channels: Vec<ChannelSnapshot>,
}

impl Snapshot {
    /// Whether every target is met on every channel with targets.
    pub fn rule_met(&self) -> bool {
        self.has_rule()
            && self
                .channels
                .iter()
                .flat_map(|c| &c.targets)
                .all(|t| t.status.met)
    }

    /// Whether some channel has stop-rule targets.
    pub fn has_rule(&self) -> bool {
        self.channels.iter().any(|c| !c.targets.is_empty())
    }

    /// The longest of the channels' expected lengths for the rule (s); `None` if some target
    /// has no expected length.
    pub fn needed_s(&self) -> Option<f64> {
        self.channels
            .iter()
            .flat_map(|c| &c.targets)
            .try_fold(0.0f64, |acc, t| t.needed_s.map(|n| acc.max(n)))
    }
}

impl Live {
    /// Accumulators for `names` sampled every `tau0` s, on [`GRID`] up to records of
    /// `longest_s` seconds.
    pub fn new(names: &[&str], tau0: f64, longest_s: f64) -> Result<Live, StreamingError> {
        let n_phase = (longest_s.max(tau0) / tau0).ceil() as usize + 1;
        let config = Config::default();
        let ladder = snap_factors(
            &taus::factors(GRID, allan::max_factor(Estimator::Oadev, n_phase)),
            config,
        );
        let channels = names
            .iter()
            .map(|_| Streaming::new(Estimator::Oadev, tau0, &ladder, config))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Live {
            names: names.iter().map(|s| s.to_string()).collect(),
            tau0,
            low_pass: vec![None; channels.len()],
            longest_s,
            channels,
        })
    }

    /// The sensor's low-pass filter on channel `index`, for its fit
    /// ([`FitOptions::low_pass`]).
    pub fn set_low_pass(&mut self, index: usize, low_pass: Option<LowPass>) {
        if let Some(slot) = self.low_pass.get_mut(index) {
            *slot = low_pass;
        }
    }

    /// One sample of every channel, in the order of the names (extra values are ignored).
    pub fn push(&mut self, values: &[f64]) {
        for (s, &v) in self.channels.iter_mut().zip(values) {
            s.push(v);
        }
    }

    /// Sample time so far, s.
    pub fn elapsed_s(&self) -> f64 {
        self.channels.first().map_or(0, |s| s.samples()) as f64 * self.tau0
    }

    /// Every channel's curve, fit and intervals at `options.confidence`, and, for the
    /// channels in `rule_channels`, the stop rule's targets.
    pub fn snapshot(
        &self,
        rule: Option<&StopRule>,
        rule_channels: &[&str],
        options: &FitOptions,
    ) -> Snapshot {
        let elapsed_s = self.elapsed_s();
        let channels = self
            .names
            .iter()
            .zip(&self.channels)
            .zip(&self.low_pass)
            .map(|((name, s), low_pass)| {
                let curve = s.curve();
                let options = FitOptions {
                    low_pass: low_pass.clone(),
                    ..options.clone()
                };
                let fit = fit::fit_deviation(&curve.deviation, curve.phase_points, &options);
                let wanted = rule.filter(|_| rule_channels.contains(&name.as_str()));
                self.channel(name, &curve, fit, wanted, elapsed_s, &options)
            })
            .collect();
        Snapshot {
            elapsed_s,
            confidence: options.confidence,
            channels,
        }
    }

    fn channel(
        &self,
        name: &str,
        curve: &Curve,
        fit: Result<NoiseFit, FitError>,
        rule: Option<&StopRule>,
        elapsed_s: f64,
        options: &FitOptions,
    ) -> ChannelSnapshot {
        let (lo, hi): (Vec<f64>, Vec<f64>) = match &fit {
            Ok(f) => {
                let intervals = curve.intervals(Some(f), options.confidence);
                (intervals.lo, intervals.hi)
            }
            Err(_) => (Vec::new(), Vec::new()),
        };
        let targets = match (&fit, rule) {
            (Ok(f), Some(rule)) => rule
                .status(f)
                .into_iter()
                .map(|status| TargetSnapshot {
                    status,
                    needed_s: precision::duration_for(
                        f,
                        status.target,
                        Horizon {
                            grid: GRID,
                            tau0: self.tau0,
                            now_s: elapsed_s,
                            limit_s: self.longest_s,
                        },
                        options,
                    ),
                })
                .collect(),
            (Err(_), Some(rule)) => rule
                .targets
                .iter()
                .map(|&target| TargetSnapshot {
                    status: Status {
                        target,
                        value: 0.0,
                        reached: f64::INFINITY,
                        met: false,
                    },
                    needed_s: None,
                })
                .collect(),
            (_, None) => Vec::new(),
        };
        let term = |t: fn(&NoiseFit) -> fit::Term| fit.as_ref().ok().map(t);
        ChannelSnapshot {
            name: name.to_string(),
            tau: curve.deviation.tau.clone(),
            adev: curve.deviation.dev.clone(),
            lo,
            hi,
            n: term(|f| f.n),
            b: term(|f| f.b),
            k: term(|f| f.k),
            fit,
            targets,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::pipeline::{self, Options};
    use crate::analysis::precision::test_noise;
    use crate::record::{Channel, Record};

    /// The live fit agrees with `analyze`'s pipeline on the same samples (lines and low-pass
    /// detection off, so both fit the same curve): N and K within a small fraction of their
    /// own half-widths.
    #[test]
    fn live_fit_matches_the_pipeline() {
        let rate_hz = 50.0;
        let y = test_noise(90_000, rate_hz, 5e-5, 7);
        let mut live = Live::new(&["gx"], 1.0 / rate_hz, 86400.0).unwrap();
        y.iter().for_each(|&v| live.push(&[v]));
        let rule: StopRule = "N:0.1%,K:10%".parse().unwrap();
        let snap = live.snapshot(Some(&rule), &["gx"], &FitOptions::default());
        let c = &snap.channels[0];
        let live_fit = c.fit.as_ref().unwrap();
        let record = Record {
            source: "test".into(),
            rate_hz,
            channels: vec![Channel::named("gx", y)],
        };
        let options = Options {
            lines: None,
            low_pass: pipeline::LowPassChoice::Off,
            ..Options::default()
        };
        let result = pipeline::analyze(&record, &options, &|| {}).unwrap();
        let batch = result[0].fit.as_ref().unwrap();
        for (a, b) in [(live_fit.n, batch.n), (live_fit.k, batch.k)] {
            let half = (b.hi - b.lo) / 2.0;
            assert!((a.value - b.value).abs() < 0.01 * half, "{a:?} vs {b:?}");
        }
        assert_eq!(c.targets.len(), 2);
        assert!((snap.elapsed_s - 1800.0).abs() < 1e-9);
        // N's precision, set by the short taus, goes as one over the square root of the
        // length (0.28 % reached here).
        let n = &c.targets[0];
        let scaled = 1800.0 * (n.status.reached / 0.001).powi(2);
        let needed = n.needed_s.unwrap();
        assert!((needed / scaled - 1.0).abs() < 0.2, "{needed} vs {scaled}");
        assert!(snap.needed_s().unwrap() >= needed);
        assert!(!snap.rule_met());
        assert_eq!(c.lo.len(), c.tau.len());
        assert!(c.lo.iter().zip(&c.adev).all(|(l, d)| l < d));
    }

    #[test]
    fn channels_without_a_rule_have_no_targets() {
        let mut live = Live::new(&["gx", "ax"], 0.01, 100.0).unwrap();
        for v in test_noise(5000, 100.0, 0.0, 1) {
            live.push(&[v, 2.0 * v]);
        }
        let rule: StopRule = "N:50%".parse().unwrap();
        let snap = live.snapshot(Some(&rule), &["gx"], &FitOptions::default());
        assert_eq!(snap.channels[0].targets.len(), 1);
        assert!(snap.channels[1].targets.is_empty());
        assert!(snap.rule_met(), "{:?}", snap.channels[0].targets);
        let ratio = snap.channels[1].n.unwrap().value / snap.channels[0].n.unwrap().value;
        assert!((ratio - 2.0).abs() < 1e-9);
    }
}

//! The analysis of a record that is not held in memory: fed block by block (of rows, one
//! slice per channel), it keeps per channel a [`Streaming`] accumulator per estimator and a
//! [`WelchStream`], so memory depends on the tau ladder and the Welch segment, not on the
//! record's length. The result has the shape [`pipeline::analyze`]'s has, and
//! [`ChannelResult::computation`] says what was computed and how.
//!
//! What it computes as the pipeline does: the overlapping Allan (and on request Hadamard)
//! deviation, exact at factors up to [`Config::exact_up_to`](super::streaming::Config::exact_up_to) and on a decimated
//! phase above ([`streaming`](super::streaming)'s module documentation), on the pipeline's taus moved by
//! [`snap_factors`] where decimated; the noise fit on that curve; the slope read-outs; the
//! Welch PSD. The intervals take each tau's noise type from the fitted model
//! ([`Curve::intervals`]), since there is no record to identify it on.
//!
//! What it does not compute, each needing the whole record at once: the spectral-line
//! search (the fit sees the record as it is), the roll-off detection (the fit models a
//! low-pass only when the options state one), the multi-resolution PSD fit, and every
//! estimator other than oadev and ohdev.

use super::fit::psd::PsdFitError;
use super::pipeline::{
    self, AnalysisError, ChannelResult, DeviationResult, LowPassChoice, Options,
};
use super::psd::{self, WelchOptions, WelchStream};
use super::streaming::{Config, Curve, Streaming, snap_factors};
use super::{DataType, Estimator, allan, taus};
use crate::record::Quantity;
use rayon::prelude::*;

/// Why a record cannot be analysed in bounded memory.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundedError {
    #[error(
        "--estimator {0}: a record analysed in bounded memory has oadev and ohdev only (a larger --memory-budget reads it whole)"
    )]
    Estimator(Estimator),
    #[error(
        "--data-type phase: a record analysed in bounded memory must be rate data (a larger --memory-budget reads it whole)"
    )]
    Phase,
    #[error("block of {got} samples for channel {channel}; the block has {expected}")]
    Ragged {
        channel: usize,
        got: usize,
        expected: usize,
    },
    #[error("a block of {got} channels; the record has {expected}")]
    Channels { got: usize, expected: usize },
    #[error("{got} samples fed; the record has {expected}")]
    Length { got: usize, expected: usize },
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
}

/// One channel's running state.
struct ChannelState {
    name: String,
    quantity: Quantity,
    curves: Vec<Streaming>,
    welch: Result<WelchStream, psd::PsdError>,
    first: Option<f64>,
    varies: bool,
}

/// A record's analysis in progress (see the module documentation).
pub struct Bounded {
    channels: Vec<ChannelState>,
    samples: usize,
    fed: usize,
    rate_hz: f64,
    options: Options,
    config: Config,
}

impl Bounded {
    /// The analysis of `samples` rows of `channels` (name, quantity) at `rate_hz`, as
    /// `options` ask; errors for what cannot be streamed and for what [`pipeline::analyze`]
    /// refuses before reading any sample.
    pub fn new(
        channels: &[(String, Quantity)],
        samples: usize,
        rate_hz: f64,
        options: &Options,
    ) -> Result<Bounded, BoundedError> {
        if channels.is_empty() {
            return Err(AnalysisError::NoChannels.into());
        }
        if options.data_type == DataType::Phase {
            return Err(BoundedError::Phase);
        }
        if let Some(&e) = options
            .estimators
            .iter()
            .find(|e| !matches!(e, Estimator::Oadev | Estimator::Ohdev))
        {
            return Err(BoundedError::Estimator(e));
        }
        pipeline::check_options(options, rate_hz)?;
        if samples < pipeline::MIN_SAMPLES {
            return Err(AnalysisError::TooShort {
                channel: channels[0].0.clone(),
                n: samples,
                needed: pipeline::MIN_SAMPLES,
            }
            .into());
        }
        let config = Config::default();
        let tau0 = 1.0 / rate_hz;
        let welch = WelchOptions {
            segment_len: options.psd_segment.unwrap_or(0),
            window: options.psd_window,
            ..WelchOptions::default()
        };
        // One window and one FFT plan serve every channel.
        let welch = WelchStream::new(samples, rate_hz, &welch);
        let states = channels
            .iter()
            .map(|(name, quantity)| {
                let curves = estimators(options)
                    .into_iter()
                    .map(|e| {
                        let factors =
                            taus::factors(options.taus, allan::max_factor(e, samples + 1));
                        Streaming::new(e, tau0, &snap_factors(&factors, config), config)
                    })
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| AnalysisError::Options(e.to_string()))?;
                Ok(ChannelState {
                    name: name.clone(),
                    quantity: *quantity,
                    curves,
                    welch: welch
                        .as_ref()
                        .map(WelchStream::empty_like)
                        .map_err(Clone::clone),
                    first: None,
                    varies: false,
                })
            })
            .collect::<Result<Vec<_>, BoundedError>>()?;
        Ok(Bounded {
            channels: states,
            samples,
            fed: 0,
            rate_hz,
            options: options.clone(),
            config,
        })
    }

    /// Take the next rows: one slice per channel, all of one length. A non-finite sample is
    /// [`AnalysisError::NotFinite`] with its index in the record.
    pub fn feed(&mut self, block: &[&[f64]]) -> Result<(), BoundedError> {
        if block.len() != self.channels.len() {
            return Err(BoundedError::Channels {
                got: block.len(),
                expected: self.channels.len(),
            });
        }
        let expected = block.first().map_or(0, |b| b.len());
        if let Some((channel, b)) = block.iter().enumerate().find(|(_, b)| b.len() != expected) {
            return Err(BoundedError::Ragged {
                channel,
                got: b.len(),
                expected,
            });
        }
        if self.fed + expected > self.samples {
            return Err(BoundedError::Length {
                got: self.fed + expected,
                expected: self.samples,
            });
        }
        let at = self.fed;
        self.channels
            .par_iter_mut()
            .zip(block)
            .try_for_each(|(state, ys)| state.feed(ys, at))?;
        self.fed += expected;
        Ok(())
    }

    /// Leave out the channels that never changed, once every row has been fed, as
    /// [`crate::record::Record::leave_out_constant`] does for a record in memory: one warning
    /// per channel left out, none left out when every channel is constant (then
    /// [`Bounded::finish`] says why the analysis cannot be made).
    pub fn leave_out_constant(&mut self) -> Vec<String> {
        if self.channels.iter().all(|c| !c.varies) {
            return Vec::new();
        }
        let samples = self.samples;
        let (gone, kept): (Vec<_>, Vec<_>) = std::mem::take(&mut self.channels)
            .into_iter()
            .partition(|c| !c.varies);
        self.channels = kept;
        gone.iter()
            .map(|c| {
                crate::record::left_out_as_constant(&c.name, c.first.unwrap_or(f64::NAN), samples)
            })
            .collect()
    }

    /// The results, once every row has been fed.
    pub fn finish(self) -> Result<Vec<ChannelResult>, BoundedError> {
        if self.fed != self.samples {
            return Err(BoundedError::Length {
                got: self.fed,
                expected: self.samples,
            });
        }
        if let Some(c) = self.channels.iter().find(|c| !c.varies) {
            return Err(AnalysisError::Constant {
                channel: c.name.clone(),
                value: c.first.unwrap_or(f64::NAN),
                n: self.samples,
            }
            .into());
        }
        let note = self.computation();
        let Bounded {
            channels,
            samples,
            rate_hz,
            options,
            ..
        } = self;
        Ok(channels
            .into_par_iter()
            .map(|c| c.result(samples, rate_hz, &options, &note))
            .collect())
    }

    /// What is computed and how, one line: which taus are exact and which decimated, and
    /// what is left out.
    pub fn computation(&self) -> String {
        let exact_up_to = self.config.exact_up_to;
        let ladders: Vec<String> = self
            .channels
            .first()
            .map(|c| {
                c.curves
                    .iter()
                    .map(|s| {
                        let m = s.factors();
                        let exact = m.iter().filter(|&&m| m <= exact_up_to).count();
                        format!(
                            "{} exact for m <= {exact_up_to} ({exact} taus), decimated above ({} taus)",
                            s.estimator(),
                            m.len() - exact
                        )
                    })
                    .collect()
            })
            .unwrap_or_default();
        let low_pass = match self.options.low_pass {
            LowPassChoice::Detect => "; no roll-off detection",
            _ => "",
        };
        format!(
            "streamed: {}; no line search{low_pass}; PSD by Welch only",
            ladders.join("; ")
        )
    }
}

/// The estimators computed: those asked for, and oadev for the fit.
fn estimators(options: &Options) -> Vec<Estimator> {
    let mut out = options.estimators.clone();
    if !out.contains(&Estimator::Oadev) {
        out.push(Estimator::Oadev);
    }
    out
}

impl ChannelState {
    fn feed(&mut self, ys: &[f64], at: usize) -> Result<(), AnalysisError> {
        if let Some(i) = ys.iter().position(|v| !v.is_finite()) {
            return Err(AnalysisError::NotFinite {
                channel: self.name.clone(),
                index: at + i,
                value: ys[i],
            });
        }
        let Some(&head) = ys.first() else {
            return Ok(());
        };
        let first = *self.first.get_or_insert(head);
        self.varies = self.varies || ys.iter().any(|&v| v != first);
        for s in &mut self.curves {
            s.extend(ys);
        }
        if let Ok(w) = &mut self.welch {
            w.extend(ys);
        }
        Ok(())
    }

    fn result(self, samples: usize, rate_hz: f64, options: &Options, note: &str) -> ChannelResult {
        let curves: Vec<Curve> = self.curves.iter().map(Streaming::curve).collect();
        let oadev = curves
            .iter()
            .find(|c| c.deviation.estimator == Estimator::Oadev)
            .cloned();
        let low_pass = match options.low_pass {
            LowPassChoice::Detect => None,
            _ => pipeline::channel_low_pass(self.quantity, &[], None, rate_hz, options),
        };
        let fit_curve = oadev.unwrap_or_else(|| curves[0].clone());
        let (fit, readouts) =
            pipeline::fit_noise(&fit_curve.deviation, samples + 1, low_pass, options);
        let model = fit.as_ref().ok();
        let with_intervals = |c: &Curve| DeviationResult {
            deviation: c.deviation.clone(),
            intervals: c.intervals(model, options.confidence),
        };
        let deviations = curves
            .iter()
            .filter(|c| options.estimators.contains(&c.deviation.estimator))
            .map(with_intervals)
            .collect();
        let psd = self.welch.and_then(|w| w.finish()).map(|spectrum| {
            let binned = psd::log_binned(&spectrum, options.psd_bins_per_decade);
            (spectrum, binned)
        });
        ChannelResult {
            kind: pipeline::sensor_kind(self.quantity),
            unit: self.quantity.si_unit(),
            name: self.name,
            quantity: self.quantity,
            rate_hz,
            n: samples,
            deviations,
            fit_curve: with_intervals(&fit_curve),
            lines: Vec::new(),
            fit,
            readouts,
            psd,
            psd_terms: Err(PsdFitError::NotComputed(
                "the multi-resolution PSD needs the whole record in memory",
            )),
            computation: Some(note.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::streaming::tests::series;
    use crate::record::{Channel, Record};

    fn streamed(
        record: &Record,
        options: &Options,
        block: usize,
    ) -> Result<Vec<ChannelResult>, BoundedError> {
        let names: Vec<(String, Quantity)> = record
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.quantity))
            .collect();
        let mut b = Bounded::new(&names, record.len(), record.rate_hz, options)?;
        for start in (0..record.len()).step_by(block) {
            let end = (start + block).min(record.len());
            let rows: Vec<&[f64]> = record
                .channels
                .iter()
                .map(|c| &c.values[start..end])
                .collect();
            b.feed(&rows)?;
        }
        b.finish()
    }

    /// Fed in blocks, the oadev at every exact tau is the pipeline's to rounding, the Welch
    /// PSD too, and the fitted N lies within the pipeline's interval; the note says what was
    /// computed.
    #[test]
    fn streamed_results_are_the_pipelines() {
        let record = Record {
            source: "test".into(),
            rate_hz: 100.0,
            channels: vec![
                Channel::named("gx", series(200_000, 1)),
                Channel::named("gy", series(200_000, 2)),
            ],
        };
        let options = Options {
            lines: None,
            low_pass: LowPassChoice::Off,
            estimators: vec![Estimator::Oadev, Estimator::Ohdev],
            ..Options::default()
        };
        let whole = pipeline::analyze(&record, &options, &|| {}).unwrap();
        let parts = streamed(&record, &options, 7_777).unwrap();
        for (w, s) in whole.iter().zip(&parts) {
            assert_eq!(w.name, s.name);
            for (wd, sd) in w.deviations.iter().zip(&s.deviations) {
                let (wi, wd, sd) = (&wd.intervals, &wd.deviation, &sd.deviation);
                assert_eq!(wd.estimator, sd.estimator);
                assert_eq!(wd.m.len(), sd.m.len());
                for k in 0..wd.m.len() {
                    let (a, b) = (wd.dev[k], sd.dev[k]);
                    if wd.m[k] <= 16384 {
                        assert_eq!((wd.m[k], wd.n[k]), (sd.m[k], sd.n[k]));
                        assert!((a / b - 1.0).abs() < 1e-9, "{} {a} vs {b}", wd.estimator);
                    } else {
                        // Snapped by at most 0.1 %, decimated: an estimate of the same
                        // variance, within the whole record's interval.
                        assert!((sd.m[k] as f64 / wd.m[k] as f64 - 1.0).abs() <= 1e-3);
                        assert!(wi.lo[k] <= b && b <= wi.hi[k], "m {}: {b} vs {a}", wd.m[k]);
                    }
                }
            }
            let (wp, sp) = (&w.psd.as_ref().unwrap().0, &s.psd.as_ref().unwrap().0);
            for (a, b) in wp.density.iter().zip(&sp.density) {
                assert!((a / b - 1.0).abs() < 1e-9);
            }
            let (wf, sf) = (w.fit.as_ref().unwrap(), s.fit.as_ref().unwrap());
            let (wn, sn) = (wf.n, sf.n);
            assert!(wn.lo <= sn.value && sn.value <= wn.hi, "{wn:?} vs {sn:?}");
            let note = s.computation.as_deref().unwrap();
            assert_eq!(
                note,
                "streamed: oadev exact for m <= 16384 (40 taus), decimated above (8 taus); \
                 ohdev exact for m <= 16384 (40 taus), decimated above (6 taus); \
                 no line search; PSD by Welch only"
            );
            assert!(matches!(s.psd_terms, Err(PsdFitError::NotComputed(_))));
        }
    }

    /// A channel that never changed is left out after the last row, with its warning, and
    /// the others come out as without it; when every channel is constant none is left out.
    #[test]
    fn a_constant_channel_is_left_out_after_the_last_row() {
        let names = [
            ("gx".to_string(), Quantity::AngularRate),
            ("temp".to_string(), Quantity::Temperature),
        ];
        let options = Options::default();
        let gx = series(1000, 5);
        let mut b = Bounded::new(&names, 1000, 100.0, &options).unwrap();
        b.feed(&[&gx, &[25.5; 1000]]).unwrap();
        assert_eq!(
            b.leave_out_constant(),
            [
                "channel 'temp' is constant (25.5 for all 1000 samples): left out, it has no noise to analyse"
            ]
        );
        let results = b.finish().unwrap();
        let mut alone = Bounded::new(&names[..1], 1000, 100.0, &options).unwrap();
        alone.feed(&[&gx]).unwrap();
        let want = alone.finish().unwrap();
        assert_eq!(results.len(), 1);
        assert_eq!(results[0].name, "gx");
        let n = |r: &ChannelResult| r.fit.as_ref().map(|f| f.n.value).ok();
        assert_eq!(n(&results[0]), n(&want[0]));
        let mut quiet = Bounded::new(&names[1..], 1000, 100.0, &options).unwrap();
        quiet.feed(&[&[25.5; 1000]]).unwrap();
        assert!(quiet.leave_out_constant().is_empty());
        assert!(quiet.finish().is_err());
    }

    /// A non-finite sample is the pipeline's error, at its index in the record; a constant
    /// channel too; estimators that need the whole record are refused by name.
    #[test]
    fn bad_records_are_the_pipelines_errors() {
        let mut values = series(1000, 3);
        values[700] = f64::NAN;
        let record = Record {
            source: "test".into(),
            rate_hz: 100.0,
            channels: vec![
                Channel::named("gx", series(1000, 4)),
                Channel::named("gy", values),
            ],
        };
        let options = Options::default();
        let whole = pipeline::analyze(&record, &options, &|| {}).unwrap_err();
        assert_eq!(
            streamed(&record, &options, 300).unwrap_err().to_string(),
            whole.to_string()
        );
        let record = Record {
            source: "test".into(),
            rate_hz: 100.0,
            channels: vec![Channel::named("gx", vec![0.5; 1000])],
        };
        let whole = pipeline::analyze(&record, &options, &|| {}).unwrap_err();
        assert_eq!(
            streamed(&record, &options, 300).unwrap_err().to_string(),
            whole.to_string()
        );
        let names = [("gx".to_string(), Quantity::AngularRate)];
        let mut b = Bounded::new(&names, 100, 100.0, &options).unwrap();
        assert_eq!(
            b.feed(&[]).unwrap_err(),
            BoundedError::Channels {
                got: 0,
                expected: 1
            }
        );
        b.feed(&[&[1.0; 60]]).unwrap();
        assert_eq!(
            b.feed(&[&[1.0; 60]]).unwrap_err(),
            BoundedError::Length {
                got: 120,
                expected: 100
            }
        );
        assert!(matches!(
            b.finish(),
            Err(BoundedError::Length { got: 60, .. })
        ));
        let options = Options {
            estimators: vec![Estimator::Oadev, Estimator::Totdev],
            ..Options::default()
        };
        assert_eq!(
            streamed(&record, &options, 300).unwrap_err().to_string(),
            "--estimator totdev: a record analysed in bounded memory has oadev and ohdev only (a larger --memory-budget reads it whole)"
        );
    }
}

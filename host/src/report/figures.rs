//! The figures of a analysis, like the studies' (docs/references.md): one row per sensor
//! (gyroscope, accelerometer, then any other channels), with an Allan-deviation panel per estimator
//! (confidence band, and the fitted IEEE-952 model dashed) and a PSD panel (one-sided,
//! log-binned, with the PSD read-outs' slope lines dashed).

use super::plot::{Figure, Line, Panel};
use crate::analysis::fit::NoiseFit;
use crate::analysis::fit::psd::PsdReadout;
use crate::analysis::pipeline::{ChannelResult, DeviationResult};
use crate::analysis::units::SensorKind;
use std::f64::consts::PI;

pub fn figures(results: &[ChannelResult]) -> Vec<Figure> {
    let mut groups: Vec<(String, Vec<&ChannelResult>)> = Vec::new();
    for r in results {
        let title = sensor_title(r);
        match groups.iter_mut().find(|(t, _)| *t == title) {
            Some((_, members)) => members.push(r),
            None => groups.push((title, vec![r])),
        }
    }
    groups
        .into_iter()
        .map(|(title, members)| figure(title, &members))
        .collect()
}

/// The sensor a channel's figure row belongs to: "Gyroscope", "Accelerometer", or the channel
/// itself with its unit.
pub fn sensor_title(r: &ChannelResult) -> String {
    match r.kind {
        SensorKind::Gyro => "Gyroscope".to_string(),
        SensorKind::Accel => "Accelerometer".to_string(),
        SensorKind::Other => format!("{} ({})", r.name, r.unit),
    }
}

fn figure(title: String, members: &[&ChannelResult]) -> Figure {
    let unit = members[0].unit;
    let mut panels: Vec<Panel> = members[0]
        .deviations
        .iter()
        .enumerate()
        .map(|(i, d)| Panel {
            title: format!(
                "{} (shaded: confidence interval; dashed: IEEE-952 fit)",
                d.deviation.estimator
            ),
            x_label: "tau (s)".into(),
            y_label: format!("deviation ({unit})"),
            lines: members
                .iter()
                .enumerate()
                .flat_map(|(c, r)| deviation_lines(r, i, c))
                .collect(),
        })
        .collect();
    panels.push(Panel {
        title: "one-sided PSD (dashed: PSD read-outs)".into(),
        x_label: "frequency (Hz)".into(),
        y_label: format!("PSD (({unit})^2/Hz)"),
        lines: members
            .iter()
            .enumerate()
            .flat_map(|(c, r)| psd_lines(r, c))
            .collect(),
    });
    Figure { title, panels }
}

fn deviation_lines(r: &ChannelResult, estimator: usize, color: usize) -> Vec<Line> {
    let Some(d) = r.deviations.get(estimator) else {
        return Vec::new();
    };
    curve_lines(d, r.fit.as_ref().ok(), r.name.clone(), color)
}

/// A deviation curve shaded with its confidence band, and the fitted IEEE-952 model dashed
/// over it in the same colour when there is a fit and the curve is of the Allan type.
pub fn curve_lines(
    d: &DeviationResult,
    fit: Option<&NoiseFit>,
    label: String,
    color: usize,
) -> Vec<Line> {
    let dev = &d.deviation;
    let mut lines = vec![Line {
        label,
        x: dev.tau.clone(),
        y: dev.dev.clone(),
        band: Some((d.intervals.lo.clone(), d.intervals.hi.clone())),
        color,
        dashed: false,
    }];
    // The five-term model is an Allan variance: draw it over the Allan-type curves only.
    let allan_type = matches!(
        dev.estimator,
        crate::analysis::Estimator::Oadev
            | crate::analysis::Estimator::Adev
            | crate::analysis::Estimator::Totdev
    );
    if let (Some(fit), true) = (fit, allan_type) {
        lines.push(Line {
            label: String::new(),
            x: dev.tau.clone(),
            y: dev.tau.iter().map(|&t| fit.avar(t).sqrt()).collect(),
            band: None,
            color,
            dashed: true,
        });
    }
    lines
}

fn psd_lines(r: &ChannelResult, color: usize) -> Vec<Line> {
    let Ok((_, binned)) = &r.psd else {
        return Vec::new();
    };
    let mut lines = vec![Line {
        label: r.name.clone(),
        x: binned.freq.clone(),
        y: binned.density.clone(),
        band: None,
        color,
        dashed: false,
    }];
    let Ok(terms) = &r.psd_terms else {
        return lines;
    };
    // One-sided levels of IEEE 952 Table C.1's two-sided PSDs: 2 N^2, 2 B^2/(2 pi f),
    // 2 K^2/(2 pi f)^2, drawn where each resolved term dominates the fitted PSD.
    type Level = fn(f64, f64) -> f64;
    let shapes: [(&PsdReadout, Level); 3] = [
        (&terms.n, |v, _| 2.0 * v * v),
        (&terms.b, |v, f| 2.0 * v * v / (2.0 * PI * f)),
        (&terms.k, |v, f| 2.0 * v * v / (2.0 * PI * f).powi(2)),
    ];
    for (x, level) in shapes {
        if x.resolved() && x.bins > 0 {
            let f = [x.f_min, x.f_max];
            lines.push(Line {
                label: String::new(),
                x: f.to_vec(),
                y: f.iter().map(|&f| level(x.value, f)).collect(),
                band: None,
                color,
                dashed: true,
            });
        }
    }
    lines
}

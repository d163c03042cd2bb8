//! `imunoise sweep`: the paper's experiment. One session per sensor setting (rate and DLPF
//! bandwidth), captured from the board (or the virtual board), analysed and stored; then the
//! table of N, B, K per axis per setting with intervals — the paper's Table 2 — and the
//! Allan curves of all settings on one figure.

use crate::analysis::pipeline::{self, ChannelResult, Options};
use crate::analysis::units::{self, NoiseTerm};
use crate::cli::capture::{PortSpec, VirtualBoardArgs, open_port, start_board, stop_board};
use crate::cli::settings::aliases;
use crate::cli::simulate::parse_duration;
use crate::cli::stored::open_store;
use crate::link::replay::Speed;
use crate::recorder::{self, Ending, RecordOptions};
use crate::report::html::escape;
use crate::report::plot::{self, Figure, Line, Panel};
use crate::report::{self, json, sig};
use crate::store::Store;
use anyhow::{Context, Result, anyhow, bail};
use protocol::SensorSettings;
use protocol::mpu6050::Hz;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// The board: a serial port or `sim` for the virtual board
    #[arg(long)]
    pub port: String,
    /// Settings as RATE:BANDWIDTH, comma-separated (the paper's four by default)
    #[arg(long, default_value = "200:256,200:42,50:256,50:42")]
    pub settings: String,
    /// Data per setting: 30m, 2h, ...
    #[arg(long, default_value = "30m")]
    pub duration: String,
    /// Speed of the virtual board: max, or a factor (1 = real time)
    #[arg(long, default_value = "1")]
    pub speed: Speed,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
    /// Session names are PREFIX-<rate>hz-<bandwidth>hz
    #[arg(long, default_value = "sweep")]
    pub prefix: String,
    /// Write the figure (Allan deviation of every setting) to PATH.svg or .png
    #[arg(long, value_name = "PATH")]
    pub plot: Option<PathBuf>,
    /// Write an HTML report (the table and the figures) to PATH
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// One setting's session and analysis.
pub struct SweepRow {
    pub settings: SensorSettings,
    pub session_id: i64,
    pub session_name: String,
    pub lost: u64,
    pub results: Vec<ChannelResult>,
}

/// "200:256,200:42" to settings, each checked against the settings model.
pub fn parse_settings(text: &str) -> Result<Vec<SensorSettings>> {
    text.split(',')
        .map(|pair| {
            let (rate, bw) = pair.split_once(':').ok_or_else(|| {
                anyhow!("--settings '{pair}': expected RATE:BANDWIDTH, e.g. 200:42")
            })?;
            let parse = |v: &str| {
                v.trim()
                    .parse::<f64>()
                    .map_err(|_| anyhow!("--settings '{pair}': '{v}' is not a number"))
            };
            let (rate, bw) = (parse(rate)?, parse(bw)?);
            SensorSettings::for_rate_and_bandwidth(rate, bw)
                .map_err(|e| anyhow!("--settings {rate}:{bw}: {e}"))
        })
        .collect()
}

pub fn run(args: &SweepArgs, store: Option<&Path>) -> Result<()> {
    let settings = parse_settings(&args.settings)?;
    let seconds = parse_duration(&args.duration).map_err(|e| anyhow!("--duration: {e}"))?;
    let store = open_store(store)?;
    let spec = PortSpec {
        port: &args.port,
        speed: args.speed,
        model: args.virtual_board.model.as_deref(),
        seed: args.virtual_board.seed,
    };
    let rows = sweep(&store, &spec, &settings, seconds, &args.prefix)?;
    print!("{}", table(&rows));
    if let Some(path) = &args.plot {
        plot::write(path, &figures(&rows))?;
        println!("wrote figure: {}", path.display());
    }
    if let Some(path) = &args.report {
        std::fs::write(path, html(&rows)?)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote HTML report: {}", path.display());
    }
    Ok(())
}

/// Capture, store and analyse each setting in turn on one board.
pub fn sweep(
    store: &Store,
    spec: &PortSpec,
    settings: &[SensorSettings],
    seconds: f64,
    prefix: &str,
) -> Result<Vec<SweepRow>> {
    let mut link = open_port(spec)?;
    let stop = AtomicBool::new(false);
    let mut rows = Vec::new();
    for (i, s) in settings.iter().enumerate() {
        let name = format!(
            "{prefix}-{}hz-{}hz",
            Hz(s.output_rate_hz()),
            Hz(bandwidth(s))
        );
        eprintln!(
            "setting {}/{}: {s} for {} s ({})",
            i + 1,
            settings.len(),
            seconds,
            link.describe()
        );
        start_board(link.as_mut(), *s)?;
        let options = RecordOptions {
            name: Some(unique_name(store, &name)?),
            notes: Some(format!("imunoise sweep {}", settings.len())),
            duration_s: Some(seconds),
            keep_samples: true,
        };
        let bar = report::progress::bar((seconds * s.output_rate_hz()) as u64, "capturing");
        let outcome = recorder::record(link.as_mut(), store, &options, &stop, &mut |p| {
            bar.set_position(p.samples_expected)
        });
        bar.finish_and_clear();
        stop_board(link.as_mut());
        let outcome = outcome?;
        if let Ending::LinkFailed(e) = &outcome.ending {
            bail!(
                "{}: {e}; session {} kept as incomplete",
                link.describe(),
                outcome.session_id
            );
        }
        let session = store
            .get(outcome.session_id)?
            .ok_or_else(|| anyhow!("session {} vanished", outcome.session_id))?;
        let capture = outcome
            .capture
            .ok_or_else(|| anyhow!("session {}: no samples decoded", session.id))?;
        let record = capture
            .to_record(&session.name, true)
            .with_context(|| format!("session {}", session.name))?;
        let analysis = Options::default();
        let results = pipeline::analyze(&record, &analysis, &|| {})?;
        let document = json::document(&record, &analysis, &results);
        store.add_analysis(
            session.id,
            &serde_json::json!({ "command": "sweep", "options": format!("{analysis:?}") }),
            &document,
        )?;
        rows.push(SweepRow {
            settings: *s,
            session_id: session.id,
            session_name: session.name.clone(),
            lost: outcome.counts.samples_lost,
            results,
        });
    }
    Ok(rows)
}

/// The gyro bandwidth of a setting, Hz (what the paper names settings by).
fn bandwidth(s: &SensorSettings) -> f64 {
    s.dlpf.row().map_or(0.0, |r| r.gyro_bandwidth_hz)
}

/// `name`, or `name-2`, `name-3`... if taken.
fn unique_name(store: &Store, name: &str) -> Result<String> {
    let taken: Vec<String> = store.list()?.into_iter().map(|s| s.name).collect();
    Ok((1..)
        .map(|i| {
            if i == 1 {
                name.to_string()
            } else {
                format!("{name}-{i}")
            }
        })
        .find(|n| !taken.contains(n))
        .unwrap_or_else(|| name.to_string()))
}

/// The paper's Table 2: N, B, K per axis per setting, conventional units, with intervals.
pub fn table(rows: &[SweepRow]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\nNoise terms per setting (IEEE-952 fit to the overlapping Allan variance, 68.3 % intervals)"
    );
    let _ = writeln!(
        out,
        "{:<16} {:<5} {:>30} {:>30} {:>30}",
        "setting", "axis", "N", "B", "K"
    );
    for row in rows {
        let label = format!(
            "{}/{} Hz{}",
            Hz(row.settings.output_rate_hz()),
            Hz(bandwidth(&row.settings)),
            if aliases(&row.settings) { "*" } else { "" }
        );
        for r in &row.results {
            let Ok(fit) = &r.fit else { continue };
            if r.kind == units::SensorKind::Other {
                continue;
            }
            let cell = |term: NoiseTerm, t: &crate::analysis::fit::Term| {
                let c = |v| units::conventional(r.kind, term, v);
                format!(
                    "{} [{}..{}] {}",
                    sig(c(t.value).value, 3),
                    sig(c(t.lo).value, 2),
                    sig(c(t.hi).value, 2),
                    c(t.value).unit
                )
            };
            let _ = writeln!(
                out,
                "{:<16} {:<5} {:>30} {:>30} {:>30}",
                label,
                r.name,
                cell(NoiseTerm::N, &fit.n),
                cell(NoiseTerm::B, &fit.b),
                cell(NoiseTerm::K, &fit.k)
            );
        }
    }
    let _ = writeln!(
        out,
        "* bandwidth above half the output rate: noise above the Nyquist frequency folds back"
    );
    for row in rows {
        let _ = writeln!(
            out,
            "session {} '{}': {} samples lost",
            row.session_id, row.session_name, row.lost
        );
    }
    out
}

/// One figure per sensor, the Allan deviation of its x axis at every setting.
pub fn figures(rows: &[SweepRow]) -> Vec<Figure> {
    [
        ("Gyroscope", "gx", "rad/s"),
        ("Accelerometer", "ax", "m/s^2"),
    ]
    .iter()
    .map(|(title, axis, unit)| Figure {
        title: format!("{title}: every setting"),
        panels: vec![Panel {
            title: format!("{axis}, overlapping Allan deviation (shaded: confidence interval)"),
            x_label: "tau (s)".into(),
            y_label: format!("deviation ({unit})"),
            lines: rows
                .iter()
                .enumerate()
                .filter_map(|(i, row)| {
                    let r = row.results.iter().find(|r| r.name == *axis)?;
                    let d = &r.fit_curve;
                    Some(Line {
                        label: format!(
                            "{}/{} Hz",
                            Hz(row.settings.output_rate_hz()),
                            Hz(bandwidth(&row.settings))
                        ),
                        x: d.deviation.tau.clone(),
                        y: d.deviation.dev.clone(),
                        band: Some((d.intervals.lo.clone(), d.intervals.hi.clone())),
                        color: i,
                        dashed: false,
                    })
                })
                .collect(),
        }],
    })
    .collect()
}

/// The table and the figures on one self-contained page.
pub fn html(rows: &[SweepRow]) -> Result<String> {
    let mut h = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>imunoise sweep</title>\
         <style>body{font-family:sans-serif;max-width:1400px;margin:2em auto;padding:0 1em}\
         pre{background:#f7f7f7;padding:1em;overflow-x:auto}.svg svg{max-width:100%;height:auto}</style>\
         </head><body><h1>imunoise sweep</h1>\n",
    );
    let _ = writeln!(h, "<pre>{}</pre>", escape(&table(rows)));
    for figure in figures(rows) {
        let _ = writeln!(h, "<div class=\"svg\">{}</div>", plot::svg_string(&figure)?);
    }
    h.push_str("</body></html>\n");
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_and_errors_name_the_pair() {
        let s = parse_settings("200:256, 50:42").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].output_rate_hz(), 50.0);
        let e = parse_settings("200-42").unwrap_err().to_string();
        assert!(e.contains("'200-42': expected RATE:BANDWIDTH"), "{e}");
        let e = parse_settings("150:42").unwrap_err().to_string();
        assert!(e.contains("--settings 150:42"), "{e}");
    }
}

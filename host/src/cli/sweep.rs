//! `imunoise sweep`: the experiment of the MPU-6050 settings study
//! ([`imunoise::experiment::sweep`]) on a board or the virtual board, with a progress bar per
//! setting and Ctrl-C ending it cleanly; the tables on stdout, the figure and the page on
//! request.

use crate::cli::analyze::check_plot;
use crate::cli::capture::{
    SimBoardArgs, StopRuleArgs, VirtualBoardArgs, open_port, show, stop_failed, stop_on_ctrl_c,
};
use crate::cli::live_view::{LiveView, Mode};
use crate::cli::output;
use crate::cli::progress;
use crate::cli::simulate::parse_duration;
use crate::cli::stored::open_store;
use anyhow::{Context, Result, anyhow};
use imunoise::experiment::sweep::{self, Event, Plan, SweepRow, figures, html, table};
use imunoise::link::PortSpec;
use imunoise::link::plan::streamable;
use imunoise::link::replay::Speed;
use imunoise::recorder::live::LiveOptions;
use imunoise::report::plot;
use imunoise::store::Store;
use indicatif::ProgressBar;
use protocol::SensorSettings;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// The board: a serial port or `sim` for the virtual board
    #[arg(long)]
    pub port: String,
    /// Settings as RATE:BANDWIDTH, comma-separated (the settings study's four by default)
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
    #[command(flatten)]
    pub sim_board: SimBoardArgs,
    /// Session names are PREFIX-<rate>hz-<bandwidth>hz
    #[arg(long, default_value = "sweep")]
    pub prefix: String,
    /// Write the figure (Allan deviation of every setting) to PATH.svg or .png
    #[arg(long, value_name = "PATH")]
    pub plot: Option<PathBuf>,
    /// Write an HTML report (the table and the figures) to PATH
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub stop: StopRuleArgs,
    /// Print the sweep as JSON (each setting, its session and its analysis document, as
    /// `analyze --json` gives it) instead of the tables; notes go to stderr
    #[arg(long)]
    pub json: bool,
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
            let settings = SensorSettings::for_rate_and_bandwidth(rate, bw)
                .map_err(|e| anyhow!("--settings {rate}:{bw}: {e}"))?;
            streamable(settings.output_rate_hz())
                .map_err(|e| anyhow!("--settings {rate}:{bw}: {e}"))?;
            Ok(settings)
        })
        .collect()
}

pub fn run(args: &SweepArgs, store: Option<&Path>) -> Result<()> {
    let settings = parse_settings(&args.settings)?;
    let seconds = parse_duration(&args.duration).map_err(|e| anyhow!("--duration: {e}"))?;
    let live = args.stop.live_options(Some(seconds))?;
    if let Some(path) = &args.plot {
        check_plot(path)?;
    }
    if let Some(path) = &args.report {
        output::check_folder(path, "--report")?;
    }
    let store = open_store(store)?;
    let spec = PortSpec {
        port: &args.port,
        board: args.sim_board.board,
        speed: args.speed,
        model: args.virtual_board.model.as_deref(),
        seed: args.virtual_board.seed,
    };
    let rows = run_sweep(
        &store,
        &spec,
        &settings,
        (seconds, Some(live)),
        &args.prefix,
    )?;
    if args.json {
        println!("{:#}", sweep::document(&rows));
    } else {
        print!("{}", table(&rows));
    }
    let note = |line: String| {
        if args.json {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    };
    if let Some(path) = &args.plot {
        plot::write(path, &figures(&rows))?;
        note(format!("wrote figure: {}", path.display()));
    }
    if let Some(path) = &args.report {
        std::fs::write(path, html(&rows, "imunoise sweep")?)
            .with_context(|| format!("writing {}", path.display()))?;
        note(format!("wrote HTML report: {}", path.display()));
    }
    Ok(())
}

/// Capture, store and analyse each setting in turn on one board (the sweep's settings,
/// data per setting with the live view and stop rule, and session-name prefix), showing
/// each capture's progress.
pub fn run_sweep(
    store: &Store,
    spec: &PortSpec,
    settings: &[SensorSettings],
    (seconds, live): (f64, Option<LiveOptions>),
    prefix: &str,
) -> Result<Vec<SweepRow>> {
    let mut link = open_port(spec)?.link;
    let stop = stop_on_ctrl_c()?;
    let command: Vec<String> = std::env::args().skip(1).collect();
    let plan = Plan {
        settings,
        seconds,
        prefix,
        command: &command,
        live,
    };
    let mut bar: Option<(ProgressBar, LiveView)> = None;
    let rows = sweep::sweep(
        store,
        link.as_mut(),
        &plan,
        &stop,
        &mut |event| match event {
            Event::Setting {
                index,
                count,
                plan,
                link,
            } => eprintln!(
                "setting {}/{count}: {plan} for {seconds} s ({link})",
                index + 1
            ),
            Event::Capturing { samples } => {
                let (view, shown) =
                    LiveView::new(Mode::choose(false), &progress::bar(samples, "capturing"));
                bar = Some((shown, view));
            }
            Event::Progress(p) => {
                if let Some((bar, view)) = bar.as_mut() {
                    show(bar, p);
                    if let Some(s) = &p.live {
                        view.show(s);
                    }
                }
            }
            Event::Captured => {
                if let Some((bar, view)) = bar.take() {
                    view.finish();
                    bar.finish_and_clear();
                }
            }
            Event::StopFailed(e) => stop_failed(e),
        },
    )?;
    Ok(rows)
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

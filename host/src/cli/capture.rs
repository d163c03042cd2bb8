//! `imunoise capture`: record a session from a board's byte stream into the store, with a
//! live count of samples and losses; Ctrl-C ends it cleanly.
//!
//! The source is a [`Link`]; [`open_link`] is the one place a new source plugs in (the
//! serial port and the virtual board join there as `--port`).

use crate::cli::simulate::parse_duration;
use crate::cli::stored::open_store;
use crate::link::Link;
use crate::link::replay::{ReplayLink, Speed};
use crate::recorder::{self, Ending, Progress, RecordOptions};
use anyhow::{Context, Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

#[derive(clap::Args, Debug)]
pub struct CaptureArgs {
    /// Replay this capture file as if a board were sending it (demos, tests)
    #[arg(long, value_name = "FILE", required = true)]
    pub from_file: Option<PathBuf>,
    /// Replay speed: max, or a factor of the board's own timing (1 = real time)
    #[arg(long, default_value = "1", requires = "from_file")]
    pub speed: Speed,
    /// Session name (default: YYYYmmdd-HHMMSS-<rate>hz-<bandwidth>hz, UTC)
    #[arg(long)]
    pub name: Option<String>,
    /// A note kept with the session
    #[arg(long)]
    pub note: Option<String>,
    /// Stop after this much data: 2h, 30m, 90s (default: until the source ends or Ctrl-C)
    #[arg(long)]
    pub duration: Option<String>,
}

/// The link the arguments name.
fn open_link(args: &CaptureArgs) -> Result<Box<dyn Link>> {
    match &args.from_file {
        Some(path) => Ok(Box::new(
            ReplayLink::open(path, args.speed)
                .with_context(|| format!("--from-file {}", path.display()))?,
        )),
        None => bail!("give a source: --from-file FILE"),
    }
}

pub fn run(args: &CaptureArgs, store: Option<&Path>) -> Result<()> {
    let duration_s = args
        .duration
        .as_deref()
        .map(parse_duration)
        .transpose()
        .map_err(|e| anyhow!("--duration: {e}"))?;
    let mut link = open_link(args)?;
    let store = open_store(store)?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    let options = RecordOptions {
        name: args.name.clone(),
        notes: args.note.clone(),
        duration_s,
        keep_samples: false,
    };
    let bar = progress_bar();
    let outcome = recorder::record(link.as_mut(), &store, &options, &stop, &mut |p| {
        show(&bar, p)
    });
    bar.finish_and_clear();
    let outcome = outcome?;
    let session = store
        .get(outcome.session_id)?
        .ok_or_else(|| anyhow!("session {} vanished from the catalog", outcome.session_id))?;
    let c = &outcome.counts;
    println!(
        "session {} '{}' {}: {} samples received, {} lost in {} gap(s), {} restart(s), {} damaged frame(s); {} bytes in {}",
        session.id,
        session.name,
        session.state_text(),
        c.samples_received,
        c.samples_lost,
        c.gaps,
        c.restarts,
        c.frames_rejected,
        c.bytes,
        session.file.display()
    );
    match outcome.ending {
        Ending::LinkFailed(e) => Err(anyhow!(
            "{}: {e}; session {} kept as incomplete",
            link.describe(),
            session.id
        )),
        _ => Ok(()),
    }
}

fn progress_bar() -> ProgressBar {
    let bar = ProgressBar::new(0);
    if let Ok(style) =
        ProgressStyle::with_template("capturing [{bar:30}] {elapsed} (eta {eta}) {msg}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Elapsed and remaining time, samples, losses and data rate.
fn show(bar: &ProgressBar, p: &Progress) {
    if let Some(wanted) = p.samples_wanted {
        bar.set_length(wanted);
    }
    bar.set_position(p.samples_expected);
    let secs = p.elapsed.as_secs_f64().max(1e-3);
    bar.set_message(format!(
        "{} samples, {} lost, {} damaged frames, {:.1} kB/s",
        p.counts.samples_received,
        p.counts.samples_lost,
        p.counts.frames_rejected,
        p.counts.bytes as f64 / secs / 1e3
    ));
}

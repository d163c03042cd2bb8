//! `imunoise compare ID_OR_FILE...`: several sessions' (or files') IEEE-952 terms side by side
//! per channel, with intervals, and which sessions differ significantly
//! ([`imunoise::analysis::compare`] states the test).

use crate::cli::analyze::ReadArgs;
use crate::cli::stored;
use anyhow::{Context, Result};
use imunoise::analysis::compare::{self, SessionFits};
use imunoise::analysis::pipeline::{self, ChannelResult, Options};
use imunoise::report;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Two or more stored sessions (id or name) or files, each as `analyze` takes it
    #[arg(required = true, num_args = 2..)]
    pub inputs: Vec<PathBuf>,
    #[command(flatten)]
    pub read: ReadArgs,
    /// Compare only this channel (repeatable); default: every channel all inputs have
    #[arg(long = "column", value_name = "NAME")]
    pub columns: Vec<String>,
    /// Family-wise significance level of the verdicts (per channel and term)
    #[arg(long, default_value_t = 0.05)]
    pub alpha: f64,
    /// Confidence of the printed intervals (the test's standard errors come from them)
    #[arg(long, default_value_t = 0.683)]
    pub confidence: f64,
    /// Shortest tau of every noise fit in seconds (default: the latest of the automatic starts
    /// analyze would choose per record, so that every fit covers the same taus)
    #[arg(long, value_name = "SECONDS")]
    pub fit_tau_min: Option<f64>,
    /// Write the comparison as JSON to PATH (`-` for stdout, which then carries only the JSON)
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
}

pub fn run(args: &CompareArgs, store: Option<&Path>) -> Result<()> {
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        anyhow::bail!("--alpha {}: between 0 and 1 (e.g. 0.05)", args.alpha);
    }
    let options = Options {
        confidence: args.confidence,
        fit_tau_min: args.fit_tau_min,
        ..Options::default()
    };
    let load = args.read.load_options()?;
    let mut analysed: Vec<(String, Vec<ChannelResult>)> = Vec::new();
    for input in &args.inputs {
        let loaded = stored::load(input, &load, store)?.loaded;
        stored::print_notes(&loaded.notes);
        let record = loaded
            .record
            .select(&args.columns)
            .map_err(anyhow::Error::msg)
            .with_context(|| input.display().to_string())?;
        let bar = crate::cli::progress::bar(
            (record.channels.len() * pipeline::steps_per_channel(&options)) as u64,
            "analysing",
        );
        let results = pipeline::analyze(&record, &options, &|| bar.inc(1))
            .with_context(|| record.source.clone())?;
        bar.finish_and_clear();
        analysed.push((record.source, results));
    }
    let (labels, mut results): (Vec<String>, Vec<Vec<ChannelResult>>) =
        analysed.into_iter().unzip();
    if args.fit_tau_min.is_none()
        && let Some(start) = compare::align_fit_start(&mut results, args.confidence)
    {
        eprintln!("note: every fit starts at tau = {start} s (the latest automatic start)");
    }
    let sessions: Vec<SessionFits> = labels
        .into_iter()
        .zip(&results)
        .map(|(label, channels)| SessionFits { label, channels })
        .collect();
    let comparison = compare::compare(&sessions, args.alpha, args.confidence);
    if comparison.rows.is_empty() {
        anyhow::bail!(
            "no channel is in every input (channels: {})",
            comparison.skipped_channels.join(", ")
        );
    }
    let document = serde_json::json!({
        "tool": "imunoise",
        "version": env!("CARGO_PKG_VERSION"),
        "comparison": comparison,
    });
    match args.json.as_deref() {
        Some(p) if p.as_os_str() == "-" => {
            println!("{}", serde_json::to_string_pretty(&document)?);
        }
        other => {
            print!("{}", report::compare::render(&comparison));
            if let Some(path) = other {
                std::fs::write(path, serde_json::to_string_pretty(&document)? + "\n")
                    .with_context(|| format!("writing {}", path.display()))?;
                println!("wrote comparison JSON: {}", path.display());
            }
        }
    }
    Ok(())
}

//! `imunoise model INPUT`: fit -> simulate -> compare -> name the missing effect -> refit, on
//! one channel (see `model`).

use crate::cli::analyze::{ReadArgs, parse_bandwidth};
use crate::cli::stored;
use anyhow::{Context, Result};
use imunoise::analysis::pipeline::{Bandwidth, LowPassChoice};
use imunoise::model::{self, Settings, report};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ModelArgs {
    /// A capture file, a text/CSV table or a NumPy .npy; or a stored session's id or name
    pub input: PathBuf,
    #[command(flatten)]
    pub read: ReadArgs,
    /// The channel to model (default: the first gyro channel, else the first accelerometer
    /// channel, else the record's only other channel)
    #[arg(long)]
    pub column: Option<String>,
    /// The temperature channel (default: the record's temperature channel, if it has one):
    /// enables the temperature-coupling candidate
    #[arg(long)]
    pub temp_column: Option<String>,
    /// The sensor's low-pass -3 dB bandwidth in Hz, part of the model (`off` for none).
    /// Default: a capture's own settings, else a roll-off fitted to the spectrum, named as
    /// a step
    #[arg(long, value_name = "HZ|off", value_parser = parse_bandwidth)]
    pub bandwidth: Option<Bandwidth>,
    /// Write the outcome as JSON to PATH (`-` for stdout, which then carries only the JSON)
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write an HTML report (measured vs simulated band at every step) to PATH
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
    /// Seed of the first realisation (realisation i uses seed + i)
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated realisations per model
    #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u64).range(2..))]
    pub realisations: u64,
}

pub fn run(args: &ModelArgs, store: Option<&Path>) -> Result<()> {
    let stored::Input { loaded, .. } =
        stored::load(&args.input, &args.read.load_options()?, store)?;
    stored::print_notes(&loaded.notes);
    let record = loaded.record;
    let settings = Settings {
        realisations: args.realisations as usize,
        seed: args.seed,
        low_pass: LowPassChoice::chosen(args.bandwidth, loaded.settings),
    };
    let outcome = model::run(
        &record,
        args.column.as_deref(),
        args.temp_column.as_deref(),
        &settings,
    )
    .with_context(|| record.source.clone())?;
    let to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    if !to_stdout {
        print!("{}", report::table(&outcome));
    }
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report::document(&outcome))?;
        if to_stdout {
            println!("{text}");
        } else {
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        }
    }
    if let Some(path) = &args.report {
        let page = report::html(&outcome)?;
        std::fs::write(path, page).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote HTML report: {}", path.display());
    }
    Ok(())
}

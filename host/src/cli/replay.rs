//! `imunoise replay ID|FILE`: decode a stored raw capture again, from its bytes, and re-run
//! the analysis (same options and outputs as `analyze`); the analysis is kept with the
//! session. A newer imunoise can so re-read every capture it ever recorded.

use crate::cli::analyze::{AnalysisArgs, analyse};
use crate::cli::stored;
use anyhow::Result;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// A stored session's id or name, or a capture file (an existing path wins)
    pub input: PathBuf,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
}

pub fn run(args: &ReplayArgs, store: Option<&Path>) -> Result<()> {
    args.analysis.check()?;
    let stored::Input { loaded, session } =
        stored::load(&args.input, &args.analysis.read.load_options()?, store)?;
    let r = &loaded.record;
    eprintln!(
        "replayed {}: {} samples at {} Hz",
        r.source,
        r.len(),
        protocol::mpu6050::Hz(r.rate_hz)
    );
    stored::print_notes(&loaded.notes);
    let analysed = analyse(loaded, &args.analysis)?;
    stored::keep_analysis(session.as_ref(), &analysed.options, &analysed.document)
}

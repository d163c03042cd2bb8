//! `imunoise store check|repair`: the catalog against the files (module `store::integrity`).

use crate::cli::stored::{open_store, read_store};
use anyhow::{Result, bail};
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct StoreArgs {
    #[command(subcommand)]
    pub command: StoreCommand,
}

#[derive(clap::Subcommand, Debug)]
pub enum StoreCommand {
    /// Compare the catalog with the files: orphaned files, missing files, stale counts
    /// (exit 1 if anything disagrees)
    Check {
        /// Print JSON instead of text
        #[arg(long)]
        json: bool,
    },
    /// Give orphaned session files their catalog rows back and recount stale captures;
    /// never deletes anything
    Repair {
        /// Print JSON instead of text
        #[arg(long)]
        json: bool,
    },
}

pub fn run(args: &StoreArgs, store: Option<&Path>) -> Result<()> {
    match args.command {
        StoreCommand::Check { json } => {
            let store = read_store(store)?;
            let problems = store.check()?;
            if json {
                println!("{}", serde_json::to_string_pretty(&problems)?);
            } else if problems.is_empty() {
                println!(
                    "store {}: the catalog and the files agree",
                    store.dir().display()
                );
            } else {
                for p in &problems {
                    println!("{p}");
                }
            }
            if !problems.is_empty() {
                bail!(
                    "store {}: {} problem(s)",
                    store.dir().display(),
                    problems.len()
                );
            }
            Ok(())
        }
        StoreCommand::Repair { json } => {
            let store = open_store(store)?;
            let done = store.repair()?;
            if json {
                println!("{}", serde_json::to_string_pretty(&done)?);
            } else if done.is_empty() {
                println!("store {}: nothing to repair", store.dir().display());
            } else {
                for d in &done {
                    println!("{d}");
                }
            }
            // What a repair cannot mend (missing files, stray files) is still there.
            for p in store.check()? {
                eprintln!("left as is: {p}");
            }
            Ok(())
        }
    }
}

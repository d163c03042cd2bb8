//! `imunoise rm ID`: remove a session (its file, catalog row and analyses), after a
//! confirmation when a person is at the terminal.

use crate::cli::stored::open_store;
use anyhow::{Result, bail};
use std::io::{BufRead, IsTerminal, Write};
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct RmArgs {
    /// The session's id or name
    pub session: String,
    /// Remove without asking
    #[arg(long, short)]
    pub yes: bool,
}

pub fn run(args: &RmArgs, store: Option<&Path>) -> Result<()> {
    let store = open_store(store)?;
    let session = store.find(&args.session)?;
    if !args.yes {
        let stdin = std::io::stdin();
        if !stdin.is_terminal() {
            bail!(
                "removing session {} '{}' needs --yes (stdin is not a terminal to ask on)",
                session.id,
                session.name
            );
        }
        eprint!(
            "remove session {} '{}' and its file {}? [y/N] ",
            session.id,
            session.name,
            session.file.display()
        );
        std::io::stderr().flush()?;
        let mut answer = String::new();
        stdin.lock().read_line(&mut answer)?;
        if !matches!(answer.trim(), "y" | "Y" | "yes") {
            println!("kept session {}", session.id);
            return Ok(());
        }
    }
    store.remove(&session)?;
    println!("removed session {} '{}'", session.id, session.name);
    Ok(())
}

//! The command line: argument definitions and one module per subcommand.

mod analyze;
mod bench;
mod demo;
mod ports;
pub(crate) mod settings;
mod simulate;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "imunoise",
    version,
    about = "Characterise the stochastic noise of MEMS IMUs (MPU-6050): capture, Allan/PSD analysis, noise models"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Show what the sensor settings mean: the DLPF table, or the registers for a rate and bandwidth
    Settings(settings::SettingsArgs),
    /// A tour of what works today, on generated data: settings, framing, loss accounting
    Demo(demo::DemoArgs),
    /// Allan deviations with confidence intervals, PSD and IEEE-952 noise terms of a record
    Analyze(Box<analyze::AnalyzeArgs>),
    /// Time the analysis engine against allantools on the same generated data
    Bench(bench::BenchArgs),
    /// List serial ports (USB vendor/product, our board marked)
    Ports(ports::PortsArgs),
    /// Simulate an MPU-6050 at rest through its signal chain and write the samples (CSV)
    Simulate(simulate::SimulateArgs),
}

/// Run the CLI: errors go to stderr with their causes, and the exit code is 1.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Settings(args) => settings::run(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Analyze(args) => analyze::run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Ports(args) => ports::run(&args),
        Command::Simulate(args) => simulate::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

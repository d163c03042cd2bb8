//! The command line: argument definitions and one module per subcommand.

mod analyze;
mod bench;
mod bench_rosbag;
mod calibrate;
mod calibrations;
mod capture;
mod compare;
mod demo;
mod export;
mod import;
mod info;
mod live_view;
mod model;
mod output;
mod ports;
mod progress;
mod replay;
mod rm;
mod sessions;
pub(crate) mod settings;
pub(crate) mod show;
mod sim_device;
mod simulate;
mod stored;
mod sweep;
mod upkeep;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser, Debug)]
#[command(
    name = "imunoise",
    version,
    about = "Characterise the stochastic noise of MEMS IMUs (MPU-6050): capture, Allan/PSD analysis, noise models"
)]
pub struct Cli {
    /// The session store (default: $IMUNOISE_STORE, else the platform data directory,
    /// e.g. ~/.local/share/imunoise)
    #[arg(long, global = true, value_name = "DIR")]
    pub store: Option<std::path::PathBuf>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Show what the sensor settings mean: the DLPF table, or the registers for a rate and bandwidth
    Settings(settings::SettingsArgs),
    /// The whole chain with no hardware: the settings study's settings, a damaged framed stream accounted for, the study's experiment on the virtual board
    Demo(demo::DemoArgs),
    /// Allan deviations with confidence intervals, PSD and IEEE-952 noise terms of a record
    Analyze(Box<analyze::AnalyzeArgs>),
    /// Time the analysis engine against allantools on the same generated data
    Bench(bench::BenchArgs),
    /// A board's identity, protocol version, settings and counters (after a handshake)
    Info(info::InfoArgs),
    /// List serial ports (USB vendor/product, our board marked)
    Ports(ports::PortsArgs),
    /// Simulate an MPU-6050 at rest through its signal chain and write the samples (CSV, or the bytes a board would send)
    Simulate(simulate::SimulateArgs),
    /// Serve the simulated MPU-6050 to an I2C bus model in another process (the emulated board)
    #[command(name = "sim-device")]
    SimDevice(sim_device::SimDeviceArgs),
    /// Record a session into the store from a board (a serial port or the virtual board) or a replayed capture file
    Capture(capture::CaptureArgs),
    /// The paper's experiment: one session per setting, then N, B, K per axis per setting
    Sweep(sweep::SweepArgs),
    /// List the stored sessions
    Sessions(sessions::SessionsArgs),
    /// Everything about one session: metadata, losses, stored analyses
    Show(show::ShowArgs),
    /// Write a session's samples in SI units (CSV; gaps marked, never bridged)
    Export(export::ExportArgs),
    /// Make a session of a CSV/text, .npy or capture file
    Import(import::ImportArgs),
    /// Remove a session and its file
    Rm(rm::RmArgs),
    /// Decode a stored capture again and re-run the analysis (kept with the session)
    Replay(Box<replay::ReplayArgs>),
    /// Fit, simulate, compare, name the effect the noise model misses, add it and repeat
    Model(Box<model::ModelArgs>),
    /// Several sessions' noise terms side by side with intervals: which differ significantly
    Compare(Box<compare::CompareArgs>),
    /// Deterministic calibration: accelerometer six positions, gyro bias or rate table, temperature
    Calibrate(Box<calibrate::CalibrateArgs>),
    /// The stored calibrations (per board), or one in full
    Calibrations(calibrations::CalibrationsArgs),
    /// Check the store's catalog against its files, or repair it from them
    Store(upkeep::StoreArgs),
}

/// Run the CLI: errors go to stderr with their causes, and the exit code is 1.
pub fn main() -> ExitCode {
    quiet_on_closed_pipe();
    let cli = Cli::parse();
    let store = cli.store.as_deref();
    let result = match cli.command {
        Command::Settings(args) => settings::run(&args),
        Command::Demo(args) => demo::run(&args, store),
        Command::Analyze(args) => analyze::run(&args, store),
        Command::Bench(args) => bench::run(&args),
        Command::Info(args) => info::run(&args),
        Command::Ports(args) => ports::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::SimDevice(args) => sim_device::run(&args),
        Command::Capture(args) => capture::run(&args, store),
        Command::Sweep(args) => sweep::run(&args, store),
        Command::Sessions(args) => sessions::run(&args, store),
        Command::Show(args) => show::run(&args, store),
        Command::Export(args) => export::run(&args, store),
        Command::Import(args) => import::run(&args, store),
        Command::Rm(args) => rm::run(&args, store),
        Command::Replay(args) => replay::run(&args, store),
        Command::Model(args) => model::run(&args, store),
        Command::Compare(args) => compare::run(&args, store),
        Command::Calibrate(args) => calibrate::run(&args, store),
        Command::Calibrations(args) => calibrations::run(&args, store),
        Command::Store(args) => upkeep::run(&args, store),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader went away (`imunoise sessions | head -1`): nothing more to say.
        Err(error) if closed_pipe(&error) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", describe(&error));
            ExitCode::FAILURE
        }
    }
}

/// Whether `error` is a write to a pipe whose reader has gone.
fn closed_pipe(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// `println!` panics when stdout's reader has gone (Rust ignores SIGPIPE). A command whose
/// output nobody reads any more is done, not broken: end quietly, as `cat` would. Every
/// other panic is reported as before.
fn quiet_on_closed_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(0);
        }
        default(info);
    }));
}

/// An error and its causes, joined by ": ", each cause once: many errors already quote their
/// source in their own message, and printing the chain as well would say it twice.
fn describe(error: &anyhow::Error) -> String {
    let mut text = error.to_string();
    for cause in error.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text.push_str(": ");
            text.push_str(&cause);
        }
    }
    text
}

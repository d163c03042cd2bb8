//! `imunoise sim-device --stdio`: the simulated MPU-6050 for a bus model in another process
//! (the emulated RP2040 in `tests/emu/`), one line per I2C event ([`imunoise::sim::bus_server`]).

use anyhow::{Context, Result, bail};
use imunoise::sim::bus_server;
use imunoise::sim::device::{SimChip, SimMpu6050};
use imunoise::sim::model_file;
use std::io::{BufReader, BufWriter, Write};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimDeviceArgs {
    /// Serve the line protocol on standard input and output (the only transport)
    #[arg(long)]
    pub stdio: bool,
    /// The device's noise model (default: the built-in examples/mpu6050.toml); its
    /// `[faults]` table's sensor faults (clock, I2C outages, sensor resets, WHO_AM_I) apply,
    /// in the bus model's time (board reboots are the bus model's own business)
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Random seed of the noise processes
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the device's journal here: every FIFO reset and every sample made, raw counts
    #[arg(long, value_name = "FILE")]
    pub journal: Option<PathBuf>,
}

pub fn run(args: &SimDeviceArgs) -> Result<()> {
    if !args.stdio {
        bail!("give --stdio: the device is served on standard input and output");
    }
    let file = match &args.model {
        Some(path) => model_file::load_file(path)?,
        None => model_file::ModelFile {
            model: model_file::example(),
            faults: model_file::FaultPlan::default(),
        },
    };
    let mut device = SimMpu6050::new(file.model, args.seed);
    file.faults.apply_to_sensor(&mut device);
    let mut journal = match &args.journal {
        Some(path) => {
            device.keep_journal();
            let file = std::fs::File::create(path)
                .with_context(|| format!("--journal {}: cannot create", path.display()))?;
            Some(BufWriter::new(file))
        }
        None => None,
    };
    let input = BufReader::new(std::io::stdin().lock());
    let output = BufWriter::new(std::io::stdout().lock());
    bus_server::serve(
        &mut device,
        input,
        output,
        journal.as_mut().map(|j| j as &mut dyn Write),
    )
    .context("serving the simulated device")?;
    Ok(())
}

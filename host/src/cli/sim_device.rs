//! `imunoise sim-device --stdio`: the simulated chips of a board's I2C bus (an MPU-6050, or a
//! GY-85's ITG-3200 and ADXL345) for a bus model in another process (the emulated RP2040 in
//! `tests/emu/`), one line per I2C event ([`imunoise::sim::bus_server`]).

use anyhow::{Context, Result, bail};
use imunoise::link::setup::SimulatedBoard;
use imunoise::sim::model_file;
use imunoise::sim::{boards, bus_server};
use std::io::{BufReader, BufWriter, Write};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimDeviceArgs {
    /// Serve the line protocol on standard input and output (the only transport)
    #[arg(long)]
    pub stdio: bool,
    /// The chips on the bus: an MPU-6050 at 0x68, or a GY-85's ITG-3200 at 0x68 and ADXL345
    /// at 0x53
    #[arg(long, value_enum, default_value_t = SimulatedBoard::Mpu6050)]
    pub board: SimulatedBoard,
    /// The chips' noise model (default: the board's built-in example, examples/mpu6050.toml
    /// or examples/gy85.toml); its `[faults]` table's sensor faults (clock, I2C outages,
    /// sensor resets, WHO_AM_I) apply to every chip, in the bus model's time (board reboots
    /// are the bus model's own business)
    #[arg(long, value_name = "FILE")]
    pub model: Option<PathBuf>,
    /// Random seed of the noise processes
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the chips' journal here: every FIFO reset and every sample made, raw counts,
    /// each line ending with its chip's address
    #[arg(long, value_name = "FILE")]
    pub journal: Option<PathBuf>,
}

pub fn run(args: &SimDeviceArgs) -> Result<()> {
    if !args.stdio {
        bail!("give --stdio: the device is served on standard input and output");
    }
    let file = match &args.model {
        Some(path) => model_file::load_file(path)?,
        None => args.board.example_model_file(),
    };
    let mut bus = match args.board {
        SimulatedBoard::Mpu6050 => boards::mpu6050(file.model, args.seed, &file.faults),
        SimulatedBoard::Gy85 => boards::gy85(file.model, args.seed, &file.faults),
    };
    let mut journal = match &args.journal {
        Some(path) => {
            bus.keep_journals();
            let file = std::fs::File::create(path)
                .with_context(|| format!("--journal {}: cannot create", path.display()))?;
            Some(BufWriter::new(file))
        }
        None => None,
    };
    let input = BufReader::new(std::io::stdin().lock());
    let output = BufWriter::new(std::io::stdout().lock());
    bus_server::serve(
        &mut bus,
        input,
        output,
        journal.as_mut().map(|j| j as &mut dyn Write),
    )
    .context("serving the simulated chips")?;
    Ok(())
}

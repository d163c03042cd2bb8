//! The calibration rig ([`imunoise::calibration::rig`]) at a terminal: the person at a real
//! board is asked on stderr and answers with Enter on stdin; what the rig does is shown as
//! lines, a spinner and progress bars.

use super::BoardArgs;
use crate::cli::capture::{board_settings, open_port, progress_bar, show, stop_failed};
use crate::cli::progress::spinner;
use anyhow::{Context, Result, anyhow};
use imunoise::calibration::Sensor;
use imunoise::calibration::rig::{ATTEMPTS, Event, Operator, Rig, RigError};
use imunoise::link::PortSpec;
use imunoise::record::Record;
use imunoise::sim::imu::TrueInput;
use imunoise::store::{Board, Store};
use indicatif::ProgressBar;
use std::io::BufRead;

/// A board on the rig, its operator at this terminal.
pub struct Bench {
    rig: Rig<Terminal>,
}

impl Bench {
    pub fn open(port: &str, args: &BoardArgs) -> Result<Bench> {
        let settings =
            board_settings(args.rate, args.bandwidth, args.gyro_range, args.accel_range)?;
        let opened = open_port(&PortSpec {
            port,
            board: imunoise::link::setup::SimulatedBoard::Mpu6050,
            speed: args.speed,
            model: args.virtual_board.model.as_deref(),
            seed: args.virtual_board.seed,
        })?;
        Ok(Bench {
            rig: Rig::new(opened, settings, Terminal::default()),
        })
    }

    /// The board and its settings, as the first capture announced them.
    pub fn board(&self) -> Option<&Board> {
        self.rig.board.as_ref()
    }

    /// The sessions captured, by name.
    pub fn sessions(&self) -> &[String] {
        &self.rig.sessions
    }

    /// [`Rig::measure`]; `check` says why a capture is refused.
    pub fn measure(
        &mut self,
        store: &Store,
        seconds: f64,
        input: TrueInput,
        instruction: &str,
        steady: &[Sensor],
        check: &dyn Fn(&Record) -> Result<(), String>,
    ) -> Result<Record> {
        self.rig
            .measure(store, seconds, input, instruction, steady, &|r| {
                check(r).err()
            })
            .map_err(rig_error)
    }

    /// [`Rig::measure_at_rest`].
    pub fn measure_at_rest(
        &mut self,
        store: &Store,
        seconds: f64,
        instruction: &str,
    ) -> Result<Record> {
        self.rig
            .measure_at_rest(store, seconds, instruction)
            .map_err(rig_error)
    }
}

/// A capture too short for the stillness test is a matter of `--seconds`.
fn rig_error(e: RigError) -> anyhow::Error {
    match e {
        RigError::TooShort(e) => anyhow!("--seconds: {e}"),
        e => e.into(),
    }
}

/// The operator at this terminal, and what is drawn for them.
#[derive(Default)]
struct Terminal {
    spinner: Option<ProgressBar>,
    bar: Option<ProgressBar>,
}

impl Operator for Terminal {
    fn pose(&mut self, instruction: &str) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        eprintln!("{instruction}, hold it still, then press Enter");
        let mut line = String::new();
        let n = std::io::stdin()
            .lock()
            .read_line(&mut line)
            .context("reading the answer on stdin")?;
        if n == 0 {
            return Err(anyhow!(
                "no answer on stdin (end of input): the procedure needs a person to turn the board"
            )
            .into());
        }
        Ok(())
    }

    fn event(&mut self, event: Event<'_>) {
        match event {
            Event::Turned(instruction) => eprintln!("sim: {instruction}"),
            Event::Watching => {
                self.spinner = Some(spinner("waiting until the board is still".into()));
            }
            Event::Watched => {
                if let Some(spinner) = self.spinner.take() {
                    spinner.finish_and_clear();
                }
            }
            Event::NotStill(motion) => eprintln!("not still yet ({motion}); waiting"),
            Event::Capturing => self.bar = Some(progress_bar()),
            Event::Progress(p) => {
                if let Some(bar) = &self.bar {
                    show(bar, p);
                }
            }
            Event::Captured => {
                if let Some(bar) = self.bar.take() {
                    bar.finish_and_clear();
                }
            }
            Event::Retry { attempt, why } => {
                eprintln!("attempt {attempt} of {ATTEMPTS}: {why}; again");
            }
            Event::StopFailed(e) => stop_failed(e),
        }
    }
}

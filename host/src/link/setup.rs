//! Setting up a board to record from: the link a port name opens (a serial port, or `sim`
//! for the virtual board with its model, faults and seed), the check that the firmware
//! streams a setting, and the handshake, configuration and start every capture begins with.

use super::Link;
use super::board::{Board, BoardError};
use super::plan::{Plan, PlanError, Request};
use super::replay::Speed;
use super::serial::{SerialError, SerialLink};
use super::shared_bus::SharedBus;
use super::virtual_board::VirtualBoard;
use crate::sim::model_file::{self, FaultPlan, ModelFile, ModelFileError};
use protocol::{DeviceInfo, ErrorCode, SensorSettings};
use std::path::Path;
use std::time::Duration;

/// How long a serial port may vanish (a board rebooting and enumerating again takes a second
/// or two; a cable pulled and pushed back by hand, more) before the capture calls it gone.
pub const RECONNECT_WINDOW: Duration = Duration::from_secs(60);

/// Board ids of simulated boards: "SIM" in the top bytes, the seed below.
pub const SIMULATED_BOARD_ID: u64 = 0x5349_4D00_0000_0000;

/// The port name of the virtual board.
pub const VIRTUAL_PORT: &str = "sim";

/// The boards the simulator has (the virtual board's sensors, `simulate`'s outputs).
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SimulatedBoard {
    /// An MPU-6050 breakout (GY-521)
    #[default]
    Mpu6050,
    /// A GY-85: ITG-3200 gyro and ADXL345 accelerometer
    Gy85,
}

impl SimulatedBoard {
    /// The sensors the board lists, in order.
    pub fn sensors(self) -> &'static [protocol::SensorKind] {
        use protocol::SensorKind::*;
        match self {
            SimulatedBoard::Mpu6050 => &[Mpu6050],
            SimulatedBoard::Gy85 => &[Itg3200, Adxl345],
        }
    }

    /// The board's model file given none: its built-in example (`examples/mpu6050.toml` or
    /// `examples/gy85.toml`), which has no faults.
    pub fn example_model_file(self) -> ModelFile {
        ModelFile {
            model: match self {
                SimulatedBoard::Mpu6050 => model_file::example(),
                SimulatedBoard::Gy85 => model_file::example_gy85(),
            },
            faults: FaultPlan::default(),
        }
    }
}

/// A board to capture from: which port, which model and seed if it is the virtual one.
#[derive(Debug, Clone, Copy)]
pub struct PortSpec<'a> {
    /// A serial port's name, or [`VIRTUAL_PORT`].
    pub port: &'a str,
    /// The virtual board's sensors.
    pub board: SimulatedBoard,
    /// How fast the virtual board runs.
    pub speed: Speed,
    /// The virtual board's model file (default: the built-in example, which has no faults).
    pub model: Option<&'a Path>,
    /// The virtual board's random seed.
    pub seed: u64,
}

/// Why a port could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    #[error(transparent)]
    Serial(#[from] SerialError),
    #[error(transparent)]
    Model(#[from] ModelFileError),
}

/// An opened port.
pub struct Opened {
    pub link: Box<dyn Link>,
    /// The virtual board's sensor (to turn it by script); None for a serial port.
    pub sensor: Option<SharedBus>,
    /// Why the virtual board's sensor did not start: the firmware goes on, as a board does,
    /// and reports the error on Start.
    pub boot_error: Option<ErrorCode>,
}

/// Open a board's port: [`VIRTUAL_PORT`] is the virtual board, anything else a serial port
/// (which reconnects within [`RECONNECT_WINDOW`]).
pub fn open(spec: &PortSpec) -> Result<Opened, OpenError> {
    if spec.port != VIRTUAL_PORT {
        let link = SerialLink::open(spec.port)?.reconnect_within(RECONNECT_WINDOW);
        return Ok(Opened {
            link: Box::new(link),
            sensor: None,
            boot_error: None,
        });
    }
    let board = virtual_board(spec)?;
    Ok(Opened {
        sensor: Some(board.sensor().clone()),
        boot_error: board.boot_error(),
        link: Box::new(board),
    })
}

/// The virtual board of `spec`: its model file's model and `[faults]` (or the board's
/// built-in example, [`SimulatedBoard::example_model_file`]), and seed.
pub fn virtual_board(spec: &PortSpec) -> Result<VirtualBoard, ModelFileError> {
    let file = match spec.model {
        Some(path) => model_file::load_file(path)?,
        None => spec.board.example_model_file(),
    };
    let board_id = SIMULATED_BOARD_ID | spec.seed;
    let (model, seed, faults) = (file.model, spec.seed, &file.faults);
    Ok(match spec.board {
        SimulatedBoard::Mpu6050 => {
            VirtualBoard::with_faults(model, seed, board_id, spec.speed, faults)
        }
        SimulatedBoard::Gy85 => VirtualBoard::gy85(model, seed, board_id, spec.speed, faults),
    })
}

/// Handshake (protocol version), configure an MPU-6050 board to `settings` and start it;
/// the capture loop then records its `Info`, the acks and the samples. A board whose
/// sensor 0 is no MPU-6050 refuses the settings ([`start_board_for`] sets any board).
pub fn start_board(
    link: &mut dyn Link,
    settings: SensorSettings,
) -> Result<DeviceInfo, BoardError> {
    let mut board = Board::new(link);
    let info = board.handshake()?;
    set_and_start(&mut board, &Plan::mpu6050(settings))?;
    Ok(info)
}

/// Why a board could not be started.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error(transparent)]
    Board(#[from] BoardError),
    /// The request means nothing to one of the board's sensors.
    #[error("{link}: {source}")]
    Plan { link: String, source: PlanError },
}

/// Handshake, set every sensor the board lists from `request` ([`Plan::for_sensors`]) and
/// start it; the board's Info and the plan it was set to.
pub fn start_board_for(
    link: &mut dyn Link,
    request: &Request,
) -> Result<(DeviceInfo, Plan), StartError> {
    let describe = link.describe();
    let mut board = Board::new(link);
    let info = board.handshake()?;
    let plan =
        Plan::for_sensors(request, &info.sensor_list()).map_err(|source| StartError::Plan {
            link: describe,
            source,
        })?;
    set_and_start(&mut board, &plan)?;
    Ok((info, plan))
}

/// Set a handshaken board to `plan` and start it.
fn set_and_start(board: &mut Board, plan: &Plan) -> Result<(), BoardError> {
    // A board left streaming by an interrupted run must stop before it takes settings.
    board.stop()?;
    plan.apply(board)?;
    board.begin_stream()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_virtual_board_opens_with_its_sensor_and_starts() {
        let mut opened = open(&PortSpec {
            port: VIRTUAL_PORT,
            board: SimulatedBoard::Mpu6050,
            speed: Speed::Max,
            model: None,
            seed: 7,
        })
        .unwrap();
        assert!(opened.sensor.is_some());
        assert_eq!(opened.boot_error, None);
        let info = start_board(opened.link.as_mut(), SensorSettings::default()).unwrap();
        assert_eq!(info.board_id, SIMULATED_BOARD_ID | 7);
    }
}

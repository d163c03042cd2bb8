//! Setting up a board to record from: the link a port name opens (a serial port, or `sim`
//! for the virtual board with its model, faults and seed), the check that the firmware
//! streams a setting, and the handshake, configuration and start every capture begins with.

use super::Link;
use super::board::{Board, BoardError};
use super::replay::Speed;
use super::serial::{SerialError, SerialLink};
use super::shared_bus::SharedBus;
use super::virtual_board::VirtualBoard;
use crate::sim::model_file::{self, FaultPlan, ModelFile, ModelFileError};
use firmware::acquire::MAX_RATE_HZ;
use protocol::mpu6050::Hz;
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

/// A board to capture from: which port, which model and seed if it is the virtual one.
#[derive(Debug, Clone, Copy)]
pub struct PortSpec<'a> {
    /// A serial port's name, or [`VIRTUAL_PORT`].
    pub port: &'a str,
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

/// The virtual board of `spec`: its model file's model and `[faults]` (or the built-in
/// example, which has none), and seed.
pub fn virtual_board(spec: &PortSpec) -> Result<VirtualBoard, ModelFileError> {
    let file = match spec.model {
        Some(path) => model_file::load_file(path)?,
        None => ModelFile {
            model: model_file::example(),
            faults: FaultPlan::default(),
        },
    };
    Ok(VirtualBoard::with_faults(
        file.model,
        spec.seed,
        SIMULATED_BOARD_ID | spec.seed,
        spec.speed,
        &file.faults,
    ))
}

/// A setting the sensor takes but the board's firmware does not stream.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "{} Hz is above the board firmware's output-rate limit of {} Hz (the MPU-6050 itself can \
     be set to it: `imunoise settings` shows how)",
    Hz(*.rate_hz),
    Hz(MAX_RATE_HZ)
)]
pub struct NotStreamable {
    pub rate_hz: f64,
}

/// Whether the board's firmware streams `settings`: the sensor may be set faster than the
/// firmware's output-rate limit, the board not.
pub fn streamable(settings: &SensorSettings) -> Result<(), NotStreamable> {
    let rate_hz = settings.output_rate_hz();
    if rate_hz > MAX_RATE_HZ {
        return Err(NotStreamable { rate_hz });
    }
    Ok(())
}

/// Handshake (protocol version), configure and start a board; the capture loop then records
/// its `Info`, the acks and the samples.
pub fn start_board(
    link: &mut dyn Link,
    settings: SensorSettings,
) -> Result<DeviceInfo, BoardError> {
    let mut board = Board::new(link);
    let info = board.handshake()?;
    // A board left streaming by an interrupted run must stop before it takes settings.
    board.stop()?;
    board.configure(settings)?;
    board.begin_stream()?;
    Ok(info)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_virtual_board_opens_with_its_sensor_and_starts() {
        let mut opened = open(&PortSpec {
            port: VIRTUAL_PORT,
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

    #[test]
    fn rates_above_the_firmware_limit_are_refused() {
        let fast = SensorSettings::for_rate_and_bandwidth(2000.0, 256.0).unwrap();
        let e = streamable(&fast).unwrap_err();
        assert_eq!(e.rate_hz, 2000.0);
        assert!(e.to_string().starts_with("2000 Hz is above"), "{e}");
        assert_eq!(streamable(&SensorSettings::default()), Ok(()));
    }
}

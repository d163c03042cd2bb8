//! `imunoise info --port PORT`: who a board is (id, firmware and protocol version, sensor,
//! settings in force) and its counters, after the same handshake a capture does.

use crate::cli::capture::{SimBoardArgs, VirtualBoardArgs, open_port};
use crate::cli::show::board_counters;
use anyhow::Result;
use imunoise::link::PortSpec;
use imunoise::link::board::Board;
use imunoise::link::replay::Speed;
use imunoise::store::Board as StoredBoard;
use protocol::{PROTOCOL_VERSION, ResetReason, SensorInfo, SensorKind, Status};
use serde::Serialize;

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The board: a serial port (`imunoise ports` lists them) or `sim` for the virtual board
    #[arg(long)]
    pub port: String,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
    #[command(flatten)]
    pub sim_board: SimBoardArgs,
    /// Print JSON instead of text
    #[arg(long)]
    pub json: bool,
}

/// `info --json`: numbers a JSON reader takes as they are. The board id is a hex string
/// (above 2^53 a double loses its last digits), the settings are rates, bandwidths and
/// ranges with their units in the key names (as the store keeps a board).
#[derive(Serialize)]
struct InfoDocument<'a> {
    port: &'a str,
    host_protocol_version: u16,
    info: BoardInfo,
    status: Status,
}

#[derive(Serialize)]
struct BoardInfo {
    #[serde(flatten)]
    board: StoredBoard,
    who_am_i: u8,
    /// The chip WHO_AM_I names, if known.
    chip: Option<&'static str>,
    streaming: bool,
    max_samples_per_batch: u16,
    reset_reason: ResetReason,
    /// Every sensor the board found, by number, with its settings.
    sensors: Vec<SensorInfo>,
}

pub fn run(args: &InfoArgs) -> Result<()> {
    let mut link = open_port(&PortSpec {
        port: &args.port,
        board: args.sim_board.board,
        speed: Speed::Max,
        model: args.virtual_board.model.as_deref(),
        seed: args.virtual_board.seed,
    })?
    .link;
    let mut board = Board::new(link.as_mut());
    let info = board.handshake()?;
    let status = board.status()?;
    if args.json {
        let doc = InfoDocument {
            port: &args.port,
            host_protocol_version: PROTOCOL_VERSION,
            info: BoardInfo {
                board: StoredBoard::of(&info),
                who_am_i: info.who_am_i,
                chip: protocol::mpu6050::chip(info.who_am_i).map(|c| c.name),
                streaming: info.streaming,
                max_samples_per_batch: info.max_samples_per_batch,
                reset_reason: info.reset_reason,
                sensors: info.sensor_list().iter().copied().collect(),
            },
            status,
        };
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    let sensors: Vec<(String, String)> = match info.sensors.is_empty() && info.who_am_i == 0 {
        true => vec![("sensor".into(), "not answering".into())],
        false => info
            .sensor_list()
            .iter()
            .enumerate()
            .map(|(k, s)| (format!("sensor {k}"), describe_sensor(s)))
            .collect(),
    };
    let rows = [
        ("port", args.port.clone()),
        ("board id", format!("{:016x}", info.board_id)),
        ("firmware", info.firmware_version.to_string()),
        (
            "protocol version",
            format!("{} (host {PROTOCOL_VERSION})", info.protocol_version),
        ),
        ("streaming", info.streaming.to_string()),
        ("samples per batch", info.max_samples_per_batch.to_string()),
        ("started by", format!("{:?}", info.reset_reason)),
        ("uptime", format!("{:.3} s", status.uptime_us as f64 / 1e6)),
        ("counters", board_counters(&status)),
    ];
    let (head, tail) = rows.split_at(3);
    let sensor_rows = sensors.iter().map(|(k, v)| (k.as_str(), v.clone()));
    let rows = head
        .iter()
        .map(|(k, v)| (*k, v.clone()))
        .chain(sensor_rows)
        .chain(tail.iter().map(|(k, v)| (*k, v.clone())));
    for (key, value) in rows {
        println!("{key:<18} {value}");
    }
    Ok(())
}

/// "MPU-6050 at 0x68 (WHO_AM_I 0x68): 200 Hz output ...": the chip (an MPU-6050 clone by
/// the name its WHO_AM_I gives), its address, identity and settings.
fn describe_sensor(s: &SensorInfo) -> String {
    let name = match s.kind {
        SensorKind::Mpu6050 => protocol::mpu6050::chip(s.id).map_or("MPU-6050", |c| c.name),
        kind => kind.name(),
    };
    let register = match s.kind {
        SensorKind::Adxl345 => "DEVID",
        _ => "WHO_AM_I",
    };
    format!(
        "{name} at {:#04x} ({register} {:#04x}): {}",
        s.address, s.id, s.config
    )
}

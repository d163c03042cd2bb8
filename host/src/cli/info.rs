//! `imunoise info --port PORT`: who a board is (id, firmware and protocol version, sensor,
//! settings in force) and its counters, after the same handshake a capture does.

use crate::cli::capture::{VirtualBoardArgs, open_port};
use crate::cli::show::board_counters;
use anyhow::Result;
use imunoise::link::PortSpec;
use imunoise::link::board::Board;
use imunoise::link::replay::Speed;
use imunoise::store::Board as StoredBoard;
use protocol::{PROTOCOL_VERSION, ResetReason, Status};
use serde::Serialize;

#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// The board: a serial port (`imunoise ports` lists them) or `sim` for the virtual board
    #[arg(long)]
    pub port: String,
    #[command(flatten)]
    pub virtual_board: VirtualBoardArgs,
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
}

pub fn run(args: &InfoArgs) -> Result<()> {
    let mut link = open_port(&PortSpec {
        port: &args.port,
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
            },
            status,
        };
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    let sensor = match (info.who_am_i, protocol::mpu6050::chip(info.who_am_i)) {
        (0, _) => "not answering".to_string(),
        (who, Some(chip)) => format!("{} (WHO_AM_I {who:#04x})", chip.name),
        (who, None) => format!("unknown chip, WHO_AM_I {who:#04x}"),
    };
    let rows = [
        ("port", args.port.clone()),
        ("board id", format!("{:016x}", info.board_id)),
        ("firmware", info.firmware_version.to_string()),
        (
            "protocol version",
            format!("{} (host {PROTOCOL_VERSION})", info.protocol_version),
        ),
        ("sensor", sensor),
        ("settings", info.settings.to_string()),
        ("streaming", info.streaming.to_string()),
        ("samples per batch", info.max_samples_per_batch.to_string()),
        ("started by", format!("{:?}", info.reset_reason)),
        ("uptime", format!("{:.3} s", status.uptime_us as f64 / 1e6)),
        ("counters", board_counters(&status)),
    ];
    for (key, value) in rows {
        println!("{key:<18} {value}");
    }
    Ok(())
}

//! `imunoise info --port PORT`: who a board is (id, firmware and protocol version, sensor,
//! settings in force) and its counters, after the same handshake a capture does.

use crate::cli::capture::{PortSpec, VirtualBoardArgs, open_port};
use crate::cli::show::board_counters;
use crate::link::board::Board;
use crate::link::replay::Speed;
use anyhow::Result;
use protocol::PROTOCOL_VERSION;

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

pub fn run(args: &InfoArgs) -> Result<()> {
    let mut link = open_port(&PortSpec {
        port: &args.port,
        speed: Speed::Max,
        model: args.virtual_board.model.as_deref(),
        seed: args.virtual_board.seed,
    })?;
    let mut board = Board::new(link.as_mut());
    let info = board.handshake()?;
    let status = board.status()?;
    if args.json {
        let doc = serde_json::json!({
            "port": args.port,
            "host_protocol_version": PROTOCOL_VERSION,
            "info": info,
            "status": status,
        });
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

//! `imunoise ports`: the serial ports the OS lists, with USB vendor/product where it gives
//! them; our board is marked (and listed first).

use anyhow::Result;
use imunoise::link::serial::list_ports;

#[derive(clap::Args, Debug)]
pub struct PortsArgs {
    /// Print JSON instead of a table
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &PortsArgs) -> Result<()> {
    let ports = list_ports()?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&ports)?);
        return Ok(());
    }
    if ports.is_empty() {
        println!("no serial ports found (the virtual board is always available as --port sim)");
        return Ok(());
    }
    println!(
        "{:<24} {:<5} {:<9} {:<28} serial",
        "port", "kind", "vid:pid", "product"
    );
    for p in &ports {
        let ids = match (p.vid, p.pid) {
            (Some(v), Some(d)) => format!("{v:04x}:{d:04x}"),
            _ => "-".into(),
        };
        println!(
            "{:<24} {:<5} {:<9} {:<28} {}{}",
            p.name,
            p.kind,
            ids,
            p.product.as_deref().unwrap_or("-"),
            p.serial_number.as_deref().unwrap_or("-"),
            if p.imunoise_board {
                "   <- imunoise board"
            } else {
                ""
            }
        );
    }
    Ok(())
}

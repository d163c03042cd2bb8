//! `imunoise sessions`: the sessions in the store, one line each (or JSON).

use crate::cli::stored::{print_listing, read_store};
use anyhow::Result;
use imunoise::store::Session;
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct SessionsArgs {
    /// Print the sessions as JSON
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &SessionsArgs, store: Option<&Path>) -> Result<()> {
    let store = read_store(store)?;
    let sessions = store.list()?;
    print_listing(&sessions, args.json, &store, "sessions", table)
}

fn table(sessions: &[Session]) -> String {
    let header = [
        "id",
        "name",
        "start (UTC)",
        "duration",
        "wall",
        "rate/bw",
        "samples",
        "lost",
        "state",
    ];
    let rows: Vec<Vec<String>> = sessions
        .iter()
        .map(|s| {
            vec![
                s.id.to_string(),
                s.name.clone(),
                s.started_at
                    .get(..19)
                    .unwrap_or(&s.started_at)
                    .replace('T', " "),
                s.duration_s.map_or("-".into(), duration),
                s.wall_s.map_or("-".into(), duration),
                rate_bandwidth(s),
                s.counts.samples_received.to_string(),
                s.counts.samples_lost.to_string(),
                s.state_text(),
            ]
        })
        .collect();
    imunoise::report::table::aligned(&header, &rows)
}

/// `1h02m03s`, `4m05s`, `6.1s`.
pub fn duration(s: f64) -> String {
    let whole = s as u64;
    match whole {
        0..60 => format!("{s:.1}s"),
        60..3600 => format!("{}m{:02}s", whole / 60, whole % 60),
        _ => format!("{}h{:02}m{:02}s", whole / 3600, whole / 60 % 60, whole % 60),
    }
}

/// `200/42 Hz` (output rate / gyro bandwidth), or the rate alone for an import.
pub fn rate_bandwidth(s: &Session) -> String {
    use protocol::mpu6050::Hz;
    match (&s.board, s.rate_hz) {
        (Some(b), _) => match b.gyro_bandwidth_hz {
            Some(bw) => format!("{}/{} Hz", Hz(b.rate_hz), Hz(bw)),
            None => format!("{}/- Hz", Hz(b.rate_hz)),
        },
        (None, Some(rate)) => format!("{} Hz", Hz(rate)),
        (None, None) => "-".into(),
    }
}

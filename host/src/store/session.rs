//! A session as the catalog describes it, and the counts a capture keeps up to date.

use crate::capture::StreamDecoder;
use protocol::{DeviceInfo, SensorConfig, SensorKind, SensorSettings, Status};
use rusqlite::Row;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where a session's file came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The raw bytes a board sent (a capture file, `sessions/<id>.imucap`).
    Capture,
    /// A third-party file (CSV, text, `.npy`) copied verbatim, read again with the options
    /// it was imported with.
    Imported,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum State {
    Recording,
    Complete,
    Incomplete,
}

impl State {
    pub fn as_str(self) -> &'static str {
        match self {
            State::Recording => "recording",
            State::Complete => "complete",
            State::Incomplete => "incomplete",
        }
    }
}

/// The board a capture came from, as its Info announced it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Board {
    /// Hexadecimal (a u64 does not fit SQLite's integers).
    pub board_id: String,
    pub firmware_version: String,
    pub protocol_version: u16,
    pub rate_hz: f64,
    pub gyro_bandwidth_hz: Option<f64>,
    pub accel_bandwidth_hz: Option<f64>,
    pub dlpf_cfg: u8,
    pub smplrt_div: u8,
    pub gyro_range_dps: f64,
    pub accel_range_g: f64,
}

impl Board {
    /// The board and its sensors' settings as its Info states them. A GY-85 board's gyro
    /// columns are the ITG-3200's (rate, DLPF row, divider, its fixed 2000 deg/s range),
    /// its accel columns the ADXL345's (bandwidth rate / 2, range).
    pub fn of(info: &DeviceInfo) -> Board {
        let sensors = info.sensor_list();
        let mpu6050 = sensors.iter().find_map(|s| match s.config {
            SensorConfig::Mpu6050(settings) => Some(settings),
            _ => None,
        });
        let mut board = Board {
            board_id: format!("{:#018x}", info.board_id),
            firmware_version: info.firmware_version.to_string(),
            protocol_version: info.protocol_version,
            ..Board::mpu6050(&mpu6050.unwrap_or(info.settings))
        };
        let gyro_listed = sensors.iter().any(|s| s.kind != SensorKind::Adxl345);
        for sensor in sensors.iter() {
            match sensor.config {
                SensorConfig::Mpu6050(_) => {}
                SensorConfig::Itg3200(s) => {
                    board.rate_hz = s.output_rate_hz();
                    board.gyro_bandwidth_hz = s.bandwidth_hz();
                    board.dlpf_cfg = s.dlpf.bits();
                    board.smplrt_div = s.smplrt_div;
                    board.gyro_range_dps = protocol::itg3200::FULL_SCALE_DPS;
                }
                SensorConfig::Adxl345(s) => {
                    board.accel_bandwidth_hz = Some(s.bandwidth_hz());
                    board.accel_range_g = f64::from(s.range.full_scale_g());
                    if !gyro_listed {
                        board.rate_hz = s.output_rate_hz();
                    }
                }
            }
        }
        board
    }

    /// The settings columns of an MPU-6050 at `s`.
    fn mpu6050(s: &SensorSettings) -> Board {
        let row = s.dlpf.row();
        Board {
            board_id: String::new(),
            firmware_version: String::new(),
            protocol_version: 0,
            rate_hz: s.output_rate_hz(),
            gyro_bandwidth_hz: row.map(|r| r.gyro_bandwidth_hz),
            accel_bandwidth_hz: row.map(|r| r.accel_bandwidth_hz),
            dlpf_cfg: s.dlpf.bits(),
            smplrt_div: s.smplrt_div,
            gyro_range_dps: s.gyro_range.full_scale_dps(),
            accel_range_g: s.accel_range.full_scale_g(),
        }
    }
}

/// What a capture holds so far: kept up to date while recording, recomputed from the raw
/// file when a recording was interrupted.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Counts {
    /// Bytes in the session's file.
    pub bytes: u64,
    pub samples_received: u64,
    /// Samples the board numbered that never arrived (gaps in the indices).
    pub samples_lost: u64,
    pub gaps: u64,
    pub restarts: u64,
    pub out_of_order_batches: u64,
    pub frames_ok: u64,
    /// Frames rejected on the line (COBS, CRC, overlong, malformed).
    pub frames_rejected: u64,
    pub bytes_discarded: u64,
    /// The board's own counters (FIFO overflows, I2C errors, ...), last reported.
    pub board_status: Option<Status>,
}

impl Counts {
    pub fn of(decoder: &StreamDecoder, bytes: u64) -> Counts {
        // Every sensor's samples together.
        let a = decoder.totals();
        let stats = decoder.stats();
        Counts {
            bytes,
            samples_received: a.received,
            samples_lost: a.lost,
            gaps: a.gaps,
            restarts: decoder.restarts().len() as u64,
            out_of_order_batches: a.out_of_order_batches,
            frames_ok: stats.frames_ok,
            frames_rejected: stats.rejected(),
            bytes_discarded: stats.bytes_discarded,
            board_status: decoder.status().copied(),
        }
    }
}

/// How to read an imported file again: the options it was imported with.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ImportSpec {
    pub rate_hz: Option<f64>,
    /// The file's time column is ignored (`--ignore-time`).
    #[serde(default)]
    pub ignore_time: bool,
    pub names: Vec<String>,
    pub scales: Vec<(String, f64)>,
    /// A ROS bag's topic read (the one chosen at import, so that every reading takes it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub topic: Option<String>,
}

/// One row of the catalog.
#[derive(Debug, Clone, Serialize)]
pub struct Session {
    pub id: i64,
    pub name: String,
    pub kind: Kind,
    /// Absolute path of the session's file.
    pub file: PathBuf,
    pub started_at: String,
    pub ended_at: Option<String>,
    /// The record's length: samples received and lost over the output rate, seconds (the
    /// sensor's time, whatever the speed of the capture).
    pub duration_s: Option<f64>,
    /// Wall time from start to end (or to the last heartbeat while recording), seconds: a
    /// capture at `--speed max` or an import takes far less than its record's length.
    pub wall_s: Option<f64>,
    pub state: State,
    pub end_reason: Option<String>,
    pub board: Option<Board>,
    /// Output rate (a capture's board settings, or an imported file's rate).
    pub rate_hz: Option<f64>,
    pub counts: Counts,
    pub notes: Option<String>,
    pub import_source: Option<String>,
    pub import_options: Option<ImportSpec>,
}

impl Session {
    /// The state as shown to a user: `incomplete (interrupted)`, `complete (interrupted by
    /// the user)` say why.
    pub fn state_text(&self) -> String {
        match &self.end_reason {
            Some(reason) if self.state != State::Recording => {
                format!("{} ({reason})", self.state.as_str())
            }
            _ => self.state.as_str().to_string(),
        }
    }

    pub(super) const COLUMNS: &'static str = "id, name, kind, file, started_at, started_unix, \
        ended_at, ended_unix, heartbeat_unix, state, end_reason, board_id, firmware_version, \
        protocol_version, rate_hz, gyro_bandwidth_hz, accel_bandwidth_hz, dlpf_cfg, smplrt_div, \
        gyro_range_dps, accel_range_g, bytes, samples_received, samples_lost, gaps, restarts, \
        out_of_order_batches, frames_ok, frames_rejected, bytes_discarded, board_status, notes, \
        import_source, import_options";

    /// A row selected with [`Session::COLUMNS`]; `dir` is the store directory.
    pub(super) fn from_row(row: &Row, dir: &std::path::Path) -> rusqlite::Result<Session> {
        let kind: String = row.get("kind")?;
        let state: String = row.get("state")?;
        let started: f64 = row.get("started_unix")?;
        let ended: Option<f64> = row.get("ended_unix")?;
        let heartbeat: Option<f64> = row.get("heartbeat_unix")?;
        let file: String = row.get("file")?;
        let board_id: Option<String> = row.get("board_id")?;
        let board = match board_id {
            Some(board_id) => Some(Board {
                board_id,
                firmware_version: row.get("firmware_version")?,
                protocol_version: row.get("protocol_version")?,
                rate_hz: row.get("rate_hz")?,
                gyro_bandwidth_hz: row.get("gyro_bandwidth_hz")?,
                accel_bandwidth_hz: row.get("accel_bandwidth_hz")?,
                dlpf_cfg: row.get("dlpf_cfg")?,
                smplrt_div: row.get("smplrt_div")?,
                gyro_range_dps: row.get("gyro_range_dps")?,
                accel_range_g: row.get("accel_range_g")?,
            }),
            None => None,
        };
        let json = |column: &str| -> rusqlite::Result<Option<String>> { row.get(column) };
        let counts = Counts {
            bytes: row.get("bytes")?,
            samples_received: row.get("samples_received")?,
            samples_lost: row.get("samples_lost")?,
            gaps: row.get("gaps")?,
            restarts: row.get("restarts")?,
            out_of_order_batches: row.get("out_of_order_batches")?,
            frames_ok: row.get("frames_ok")?,
            frames_rejected: row.get("frames_rejected")?,
            bytes_discarded: row.get("bytes_discarded")?,
            board_status: json("board_status")?.and_then(|t| serde_json::from_str(&t).ok()),
        };
        let rate_hz: Option<f64> = row.get("rate_hz")?;
        let samples = counts.samples_received + counts.samples_lost;
        Ok(Session {
            duration_s: rate_hz.filter(|r| *r > 0.0).map(|r| samples as f64 / r),
            id: row.get("id")?,
            name: row.get("name")?,
            kind: if kind == "imported" {
                Kind::Imported
            } else {
                Kind::Capture
            },
            file: dir.join(file),
            started_at: row.get("started_at")?,
            ended_at: row.get("ended_at")?,
            wall_s: ended.or(heartbeat).map(|end| (end - started).max(0.0)),
            state: match state.as_str() {
                "recording" => State::Recording,
                "complete" => State::Complete,
                _ => State::Incomplete,
            },
            end_reason: row.get("end_reason")?,
            board,
            rate_hz,
            counts,
            notes: row.get("notes")?,
            import_source: row.get("import_source")?,
            import_options: json("import_options")?.and_then(|t| serde_json::from_str(&t).ok()),
        })
    }
}

/// One stored analysis of a session.
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    pub id: i64,
    pub created_at: String,
    pub options: serde_json::Value,
    pub document: serde_json::Value,
}

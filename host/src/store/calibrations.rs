//! The catalog's calibrations: one row per calibration made, keyed by board id, with the
//! settings in force and the sessions or files it came from. Rows are only added (a new
//! calibration supersedes, never overwrites, an old one).

use super::{Board, Store, StoreError, clock};
use crate::calibration::Calibration;
use rusqlite::{OptionalExtension, Row, params};
use serde::{Deserialize, Serialize};
use std::time::SystemTime;

/// The sensor settings a calibration was made with: bias and noise depend on the DLPF and
/// ranges, so applying it under other settings deserves a warning. A calibration made from
/// files knows only the rate (None: unknown).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSettings {
    pub rate_hz: f64,
    pub dlpf_cfg: Option<u8>,
    pub gyro_range_dps: Option<f64>,
    pub accel_range_g: Option<f64>,
}

impl CalibrationSettings {
    pub fn of(board: &Board) -> CalibrationSettings {
        CalibrationSettings {
            rate_hz: board.rate_hz,
            dlpf_cfg: Some(board.dlpf_cfg),
            gyro_range_dps: Some(board.gyro_range_dps),
            accel_range_g: Some(board.accel_range_g),
        }
    }

    /// Only the rate known (a calibration from files).
    pub fn rate_only(rate_hz: f64) -> CalibrationSettings {
        CalibrationSettings {
            rate_hz,
            dlpf_cfg: None,
            gyro_range_dps: None,
            accel_range_g: None,
        }
    }
}

impl std::fmt::Display for CalibrationSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let known = |v: Option<String>| v.unwrap_or_else(|| "?".into());
        write!(
            f,
            "{} Hz, DLPF_CFG {}, +-{} deg/s, +-{} g",
            self.rate_hz,
            known(self.dlpf_cfg.map(|v| v.to_string())),
            known(self.gyro_range_dps.map(|v| v.to_string())),
            known(self.accel_range_g.map(|v| v.to_string()))
        )
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StoredCalibration {
    pub id: i64,
    pub board_id: String,
    pub created_at: String,
    pub settings: CalibrationSettings,
    pub sources: Vec<String>,
    pub calibration: Calibration,
}

const COLUMNS: &str = "id, board_id, created_at, settings, sources, document";

impl Store {
    /// Keep a calibration for `board_id`; returns its id.
    pub fn add_calibration(
        &self,
        board_id: &str,
        settings: &CalibrationSettings,
        sources: &[String],
        calibration: &Calibration,
    ) -> Result<i64, StoreError> {
        let json = |v: serde_json::Result<String>| v.unwrap_or_else(|_| "null".into());
        self.conn
            .execute(
                "INSERT INTO calibrations (board_id, created_at, kind, settings, sources, document) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                params![
                    board_id,
                    clock::iso8601(SystemTime::now()),
                    calibration.kind.name(),
                    json(serde_json::to_string(settings)),
                    json(serde_json::to_string(sources)),
                    json(serde_json::to_string(calibration)),
                ],
            )
            .map_err(self.sql())?;
        Ok(self.conn.last_insert_rowid())
    }

    /// Calibrations, newest first: of one board, or all.
    pub fn calibrations(
        &self,
        board_id: Option<&str>,
    ) -> Result<Vec<StoredCalibration>, StoreError> {
        let sql = format!(
            "SELECT {COLUMNS} FROM calibrations WHERE ?1 IS NULL OR board_id = ?1 ORDER BY id DESC"
        );
        let mut stmt = self.conn.prepare(&sql).map_err(self.sql())?;
        let rows = stmt.query_map([board_id], from_row).map_err(self.sql())?;
        rows.collect::<Result<_, _>>().map_err(self.sql())
    }

    pub fn calibration(&self, id: i64) -> Result<Option<StoredCalibration>, StoreError> {
        let sql = format!("SELECT {COLUMNS} FROM calibrations WHERE id = ?1");
        self.conn
            .query_row(&sql, [id], from_row)
            .optional()
            .map_err(self.sql())
    }
}

/// A row; a JSON column that does not parse (a catalog edited by hand) is an error naming
/// the column, not a panic.
fn from_row(row: &Row) -> rusqlite::Result<StoredCalibration> {
    fn parse<T: serde::de::DeserializeOwned>(row: &Row, i: usize) -> rusqlite::Result<T> {
        let text: String = row.get(i)?;
        serde_json::from_str(&text).map_err(|e| {
            rusqlite::Error::FromSqlConversionFailure(i, rusqlite::types::Type::Text, Box::new(e))
        })
    }
    Ok(StoredCalibration {
        id: row.get(0)?,
        board_id: row.get(1)?,
        created_at: row.get(2)?,
        settings: parse(row, 3)?,
        sources: parse(row, 4)?,
        calibration: parse(row, 5)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Correction, Kind, Sensor};

    #[test]
    fn calibrations_are_kept_per_board_newest_first() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        let settings = CalibrationSettings::rate_only(100.0);
        let cal = |b: f64| Calibration {
            kind: Kind::Gyro,
            corrections: vec![Correction::bias_only(Sensor::Gyro, [b; 3], 25.0)],
            temperature: vec![],
            details: serde_json::json!({"note": "test"}),
        };
        let a = store
            .add_calibration("0x1", &settings, &["s1".into()], &cal(1.0))
            .unwrap();
        let b = store
            .add_calibration("0x2", &settings, &[], &cal(2.0))
            .unwrap();
        let c = store
            .add_calibration("0x1", &settings, &[], &cal(3.0))
            .unwrap();
        let board1 = store.calibrations(Some("0x1")).unwrap();
        assert_eq!(board1.iter().map(|s| s.id).collect::<Vec<_>>(), [c, a]);
        assert_eq!(board1[1].calibration, cal(1.0));
        assert_eq!(board1[1].sources, ["s1"]);
        assert_eq!(store.calibrations(None).unwrap().len(), 3);
        assert_eq!(store.calibration(b).unwrap().unwrap().board_id, "0x2");
        assert!(store.calibration(99).unwrap().is_none());
    }
}

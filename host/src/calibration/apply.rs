//! Correct a record in memory with a board's calibrations: per sensor,
//! `f_true = K^-1 (f_meas - b - [b_T(T) - b_T(T_cal)])`, b_T the temperature model's bias
//! part, T the sample's TEMP_OUT and T_cal the temperature the bias was measured at. The
//! stored data are never touched: this works on the decoded copy. [`latest`] picks a stored
//! session's board's newest calibrations from the store.

use super::temperature::TemperatureModel;
use super::{Calibration, Correction, Sensor};
use crate::record::Record;
use crate::store::{CalibrationSettings, Session, Store, StoreError};

/// What is applied to one board's records.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Applied {
    pub corrections: Vec<Correction>,
    pub temperature: Vec<TemperatureModel>,
}

impl Applied {
    /// From a board's calibrations, newest first: per sensor the newest bias, the newest
    /// matrix K (a static bias measured after a rate table keeps the table's K) and the
    /// newest temperature model.
    pub fn newest(calibrations: &[Calibration]) -> Applied {
        let mut applied = Applied::default();
        for c in calibrations {
            for k in &c.corrections {
                match applied
                    .corrections
                    .iter_mut()
                    .find(|x| x.sensor == k.sensor)
                {
                    None => applied.corrections.push(k.clone()),
                    Some(newer) if newer.matrix.is_none() => newer.matrix = k.matrix,
                    Some(_) => {}
                }
            }
            for t in &c.temperature {
                if !applied.temperature.iter().any(|x| x.sensor == t.sensor) {
                    applied.temperature.push(t.clone());
                }
            }
        }
        applied
    }

    pub fn is_empty(&self) -> bool {
        self.corrections.is_empty() && self.temperature.is_empty()
    }
}

/// Correct `record` in place; returns notes on what was applied and what could not be (a
/// sensor whose channels the record lacks, a temperature model without a `temp` channel).
pub fn apply(record: &mut Record, applied: &Applied) -> Result<Vec<String>, String> {
    let mut notes = Vec::new();
    let temp = record.channel("temp").map(|c| c.values.clone());
    for sensor in [Sensor::Gyro, Sensor::Accel] {
        let model = applied.temperature.iter().find(|t| t.sensor == sensor);
        let correction = applied
            .corrections
            .iter()
            .find(|c| c.sensor == sensor)
            .cloned()
            // A temperature model alone corrects the bias's drift about its reference.
            .or_else(|| model.map(|m| Correction::bias_only(sensor, [0.0; 3], m.reference_c)));
        let Some(correction) = correction else {
            continue;
        };
        let names = sensor.channels();
        let idx: Vec<usize> = names
            .iter()
            .filter_map(|n| record.channels.iter().position(|c| c.name == *n))
            .collect();
        if idx.len() != 3 {
            notes.push(format!(
                "{:?} calibration not applied: the record lacks some of {}",
                sensor,
                names.join(" ")
            ));
            continue;
        }
        let model = match (model, &temp) {
            (Some(_), None) => {
                notes.push(format!(
                    "{sensor:?} temperature model not applied: the record has no temp channel"
                ));
                None
            }
            (m, _) => m,
        };
        let from = if correction.temperature_c.is_finite() {
            correction.temperature_c
        } else {
            model.map_or(f64::NAN, |m| m.reference_c)
        };
        for i in 0..record.len() {
            let measured = [0, 1, 2].map(|a| record.channels[idx[a]].values[i]);
            let extra = match (model, &temp) {
                (Some(m), Some(t)) => m.shift(from, t[i]),
                _ => [0.0; 3],
            };
            let f = correction.correct(measured, extra).ok_or_else(|| {
                format!("the {sensor:?} calibration's matrix is singular: recalibrate")
            })?;
            for a in 0..3 {
                record.channels[idx[a]].values[i] = f[a];
            }
        }
        notes.push(format!(
            "{sensor:?} corrected: bias {}, scale and misalignment{}",
            fmt3(correction.bias, sensor.unit()),
            if model.is_some() {
                ", temperature drift"
            } else {
                ""
            }
        ));
    }
    Ok(notes)
}

/// Why a session's board has no calibration to apply.
#[derive(Debug, thiserror::Error)]
pub enum LatestError {
    #[error(
        "session {id} '{name}' has no board id (an imported file): calibrations are kept per board"
    )]
    NoBoard { id: i64, name: String },
    #[error("no calibration for board {0} (make one with `imunoise calibrate`)")]
    NoCalibration(String),
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// The newest calibrations of a session's board, as [`apply`] takes them, and a warning
/// for each one used that was made under other sensor settings than the session's.
pub fn latest(store: &Store, session: &Session) -> Result<(Applied, Vec<String>), LatestError> {
    let Some(board) = &session.board else {
        return Err(LatestError::NoBoard {
            id: session.id,
            name: session.name.clone(),
        });
    };
    let stored = store.calibrations(Some(&board.board_id))?;
    if stored.is_empty() {
        return Err(LatestError::NoCalibration(board.board_id.clone()));
    }
    let settings = CalibrationSettings::of(board);
    let cals: Vec<Calibration> = stored.iter().map(|c| c.calibration.clone()).collect();
    let applied = Applied::newest(&cals);
    let warnings = stored
        .iter()
        .filter(|c| c.settings != settings && uses(&applied, &c.calibration))
        .map(|c| {
            format!(
                "calibration {} was made at {}, this session is at {settings}",
                c.id, c.settings
            )
        })
        .collect();
    Ok((applied, warnings))
}

/// Whether `applied` took anything from `cal` (its bias, its matrix or its temperature model).
fn uses(applied: &Applied, cal: &Calibration) -> bool {
    cal.corrections.iter().any(|k| {
        applied.corrections.iter().any(|a| {
            a.sensor == k.sensor
                && (a.bias == k.bias || (k.matrix.is_some() && a.matrix == k.matrix))
        })
    }) || cal
        .temperature
        .iter()
        .any(|t| applied.temperature.contains(t))
}

fn fmt3(v: [f64; 3], unit: &str) -> String {
    format!("[{:.4e}, {:.4e}, {:.4e}] {unit}", v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::Kind;
    use crate::calibration::fit::apply_forward;
    use crate::calibration::temperature::AxisFit;
    use crate::record::Channel;

    #[test]
    fn correction_inverts_the_model_with_temperature() {
        let k = [[1.01, 0.002, 0.0], [0.0, 0.99, 0.001], [0.003, 0.0, 1.0]];
        let b = [0.02, -0.01, 0.005];
        let slope = 1e-3;
        let axis = AxisFit {
            c0: 0.0,
            c1: slope,
            c2: 0.0,
            quadratic: false,
            f_statistic: 0.0,
            p_value: 1.0,
            residual_rms: 0.0,
        };
        let model = TemperatureModel {
            sensor: Sensor::Gyro,
            reference_c: 28.0,
            min_c: 25.0,
            max_c: 31.0,
            blocks: 100,
            axes: [axis; 3],
        };
        // The bias b was measured at 25 degC; the samples are at 25, 30 degC.
        let truth = [[0.1, 0.2, 0.3], [-0.5, 0.0, 1.0]];
        let temps = [25.0, 30.0];
        let meas: Vec<[f64; 3]> = truth
            .iter()
            .zip(temps)
            .map(|(t, temp)| {
                let bt = b.map(|x| x + slope * (temp - 25.0));
                apply_forward(&k, bt, *t)
            })
            .collect();
        let col = |a: usize| meas.iter().map(|m| m[a]).collect::<Vec<_>>();
        let mut record = Record {
            source: "t".into(),
            rate_hz: 1.0,
            channels: vec![
                Channel::named("gx", col(0)),
                Channel::named("gy", col(1)),
                Channel::named("gz", col(2)),
                Channel::named("temp", temps.to_vec()),
            ],
        };
        let newer = Calibration {
            kind: Kind::Gyro,
            corrections: vec![Correction {
                sensor: Sensor::Gyro,
                bias: b,
                matrix: Some(k),
                temperature_c: 25.0,
            }],
            temperature: vec![],
            details: serde_json::Value::Null,
        };
        let older = Calibration {
            kind: Kind::Temperature,
            corrections: vec![Correction::bias_only(Sensor::Gyro, [9.0; 3], 25.0)],
            temperature: vec![model],
            details: serde_json::Value::Null,
        };
        let applied = Applied::newest(&[newer.clone(), older]);
        assert_eq!(applied.corrections.len(), 1);
        assert_eq!(applied.corrections[0].matrix, Some(k));
        // A newer static bias keeps the older K.
        let bias_now = Calibration {
            kind: Kind::Gyro,
            corrections: vec![Correction::bias_only(Sensor::Gyro, [1.0; 3], 25.0)],
            temperature: vec![],
            details: serde_json::Value::Null,
        };
        let both = Applied::newest(&[bias_now, newer.clone()]);
        assert_eq!(both.corrections[0].bias, [1.0; 3]);
        assert_eq!(both.corrections[0].matrix, Some(k));
        let notes = apply(&mut record, &applied).unwrap();
        assert!(notes[0].contains("temperature drift"), "{notes:?}");
        for (i, t) in truth.iter().enumerate() {
            for (channel, want) in record.channels.iter().zip(t) {
                assert!((channel.values[i] - want).abs() < 1e-12);
            }
        }
        // No accelerometer calibration: nothing else noted; a singular matrix is an error.
        assert_eq!(notes.len(), 1);
        let bad = Applied {
            corrections: vec![Correction {
                matrix: Some([[0.0; 3]; 3]),
                ..Correction::bias_only(Sensor::Gyro, [0.0; 3], 25.0)
            }],
            temperature: vec![],
        };
        assert!(apply(&mut record, &bad).unwrap_err().contains("singular"));
    }
}

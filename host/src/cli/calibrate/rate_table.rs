//! The rate table of `imunoise calibrate gyro`: clockwise and anticlockwise about each
//! axis, per-axis two-point and, with all three axes, the least-squares bias, scale factors
//! and misalignment ([`imunoise::calibration::fit`]).

use super::bench::Bench;
use super::{DEG, DEG_H, Provenance, mean_temperature, means};
use crate::cli::calibrations::describe_calibration;
use anyhow::{Context, Result, anyhow, bail};
use imunoise::calibration::fit::{FitError, Observation, fit_linear, two_point};
use imunoise::calibration::{AXES, Calibration, Correction, Kind, Sensor, identity};
use imunoise::record::Record;
use imunoise::sim::imu::{GravityAxis, TrueInput};
use imunoise::store::Store;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One commanded rate and the record taken at it.
pub struct Spin {
    axis: usize,
    rate_deg_s: f64,
    pub record: Record,
}

/// Spin the board at +rate and -rate about each axis in turn.
pub fn spin_on_bench(
    bench: &mut Bench,
    catalog: &Store,
    seconds: f64,
    rate_deg_s: f64,
) -> Result<Vec<Spin>> {
    if rate_deg_s.is_nan() || rate_deg_s <= 0.0 {
        bail!("--table-rate {rate_deg_s}: give a positive rate in deg/s");
    }
    let mut spins = Vec::new();
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let rate = sign * rate_deg_s;
            let mut input = TrueInput::at_rest(
                GravityAxis::default(),
                imunoise::calibration::gravity::STANDARD,
            );
            input.angular_rate[axis] = rate * DEG;
            let instruction = format!(
                "spin the rate table at {rate:+} deg/s about the board's {} axis",
                AXES[axis]
            );
            let check = |r: &Record| -> Result<(), String> {
                let m = means(r, Sensor::Gyro).map_err(|e| e.to_string())?;
                check_rate(m[axis], rate * DEG)
            };
            let record = bench.measure(
                catalog,
                seconds,
                input,
                &instruction,
                &[Sensor::Gyro],
                &check,
            )?;
            spins.push(Spin {
                axis,
                rate_deg_s: rate,
                record,
            });
        }
    }
    Ok(spins)
}

/// The reading must have the commanded sign and be within 20 % of it: the axis is the one
/// asked and the table turns at about the rate set (the scale factors sought are ~1 %).
fn check_rate(measured: f64, commanded: f64) -> Result<(), String> {
    if (measured / commanded - 1.0).abs() > 0.2 {
        return Err(format!(
            "the axis reads {:+.3} deg/s for a commanded {:+.3} deg/s (wrong axis or direction?)",
            measured / DEG,
            commanded / DEG
        ));
    }
    Ok(())
}

/// `AXIS RATE_DEG_S INPUT` per line (comma or whitespace separated, `#` comments).
pub fn read_table(
    path: &Path,
    provenance: &mut Provenance,
    store: Option<&Path>,
) -> Result<Vec<Spin>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--rate-table {}", path.display()))?;
    let mut spins = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let at = || format!("{}:{}", path.display(), n + 1);
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let [axis, rate, input] = fields[..] else {
            bail!(
                "{}: expected `AXIS RATE_DEG_S INPUT`, found {} field(s)",
                at(),
                fields.len()
            );
        };
        let axis = AXES
            .iter()
            .position(|a| a.eq_ignore_ascii_case(axis))
            .ok_or_else(|| anyhow!("{}: axis '{axis}': one of x, y, z", at()))?;
        let rate_deg_s: f64 = rate
            .parse()
            .ok()
            .filter(|r: &f64| r.is_finite() && *r != 0.0)
            .ok_or_else(|| anyhow!("{}: rate '{rate}': a non-zero number of deg/s", at()))?;
        let input_path = path.parent().unwrap_or(Path::new("")).join(input);
        let input_path = if input_path.exists() {
            input_path
        } else {
            PathBuf::from(input)
        };
        let record = provenance.load(&input_path, store).with_context(at)?;
        let m = means(&record, Sensor::Gyro)?;
        check_rate(m[axis], rate_deg_s * DEG).map_err(|e| anyhow!("{}: {e}", at()))?;
        spins.push(Spin {
            axis,
            rate_deg_s,
            record,
        });
    }
    if spins.is_empty() {
        bail!("--rate-table {}: no records listed", path.display());
    }
    Ok(spins)
}

pub fn solve_table(spins: &[Spin]) -> Result<(Calibration, String)> {
    let mut observations = Vec::new();
    for s in spins {
        let mut truth = [0.0; 3];
        truth[s.axis] = s.rate_deg_s * DEG;
        observations.push(Observation {
            label: format!("{} {:+} deg/s", AXES[s.axis], s.rate_deg_s),
            truth,
            measured: means(&s.record, Sensor::Gyro)?,
        });
    }
    let temperature_c = spins
        .iter()
        .map(|s| mean_temperature(&s.record))
        .sum::<f64>()
        / spins.len() as f64;
    // Per axis, each + rate with its - twin: bias = mean, scale factor = slope - 1.
    let mut pairs = Vec::new();
    for (i, p) in observations.iter().enumerate() {
        let Some(axis) = (0..3).find(|&a| p.truth[a] > 0.0) else {
            continue;
        };
        if let Some(m) = observations
            .iter()
            .find(|o| (o.truth[axis] + p.truth[axis]).abs() < 1e-12)
        {
            let t = two_point(p.measured[axis], m.measured[axis], p.truth[axis]);
            pairs.push((axis, spins[i].rate_deg_s, t));
        }
    }
    let mut text = format!(
        "gyro rate table, {} records, mean TEMP_OUT {temperature_c:.2} degC\n\
         clockwise/anticlockwise pairs (bias = (w+ + w-)/2, scale factor = (w+ - w- - 2w)/(2w)):\n",
        spins.len()
    );
    for (axis, rate, t) in &pairs {
        let _ = writeln!(
            text,
            "  {} at +-{rate} deg/s: bias {:+.5e} rad/s ({:+.2} deg/h)  scale factor {:+.1} ppm",
            AXES[*axis],
            t.bias,
            t.bias * DEG_H,
            t.scale_factor * 1e6
        );
    }
    let (correction, residuals) = match fit_linear(Sensor::Gyro, &observations, temperature_c) {
        Ok(fit) => {
            text += "least squares, ";
            (fit.correction, Some((fit.residuals, fit.residual_rms)))
        }
        Err(FitError::Degenerate | FitError::TooFew(_)) if !pairs.is_empty() => {
            text += "not all three axes turned: no misalignment; from the pairs, ";
            let (mut bias, mut matrix) = ([0.0; 3], identity());
            for (axis, _, t) in &pairs {
                bias[*axis] = t.bias;
                matrix[*axis][*axis] = 1.0 + t.scale_factor;
            }
            let k = Correction {
                sensor: Sensor::Gyro,
                bias,
                matrix: Some(matrix),
                temperature_c,
            };
            (k, None)
        }
        Err(e) => return Err(e.into()),
    };
    let calibration = Calibration {
        kind: Kind::Gyro,
        corrections: vec![correction],
        temperature: vec![],
        details: serde_json::json!({
            "pairs": pairs.iter().map(|(axis, rate, t)| serde_json::json!({
                "axis": AXES[*axis], "rate_deg_s": rate, "two_point": t
            })).collect::<Vec<_>>(),
            "observations": observations,
            "residuals_rad_s": residuals.as_ref().map(|r| &r.0),
            "residual_rms_rad_s": residuals.as_ref().map(|r| r.1),
        }),
    };
    text += &describe_calibration(&calibration);
    if let Some((_, rms)) = residuals {
        let _ = writeln!(text, "  residual RMS {rms:.2e} rad/s");
    }
    Ok((calibration, text))
}

//! `imunoise calibrate gyro`: the static bias with its Allan uncertainty
//! ([`crate::calibration::static_bias`]), or a rate table: clockwise and anticlockwise about
//! each axis, per-axis two-point and, with all three axes, the least-squares bias, scale
//! factors and misalignment ([`crate::calibration::fit`]).

use super::bench::Bench;
use super::{
    BoardArgs, OutputArgs, Provenance, board_or_files, columns, finish, mean_temperature, means,
};
use crate::calibration::fit::{FitError, Observation, fit_linear, two_point};
use crate::calibration::static_bias::{StaticBias, static_bias};
use crate::calibration::{AXES, Calibration, Correction, Kind, Sensor, identity};
use crate::cli::calibrations::describe_calibration;
use crate::cli::stored::open_store;
use crate::record::Record;
use crate::sim::imu::{GravityAxis, TrueInput};
use anyhow::{Context, Result, anyhow, bail};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const DEG: f64 = std::f64::consts::PI / 180.0;
/// rad/s to deg/h.
const DEG_H: f64 = 3600.0 / DEG;

#[derive(clap::Args, Debug)]
pub struct GyroArgs {
    #[command(flatten)]
    pub board: BoardArgs,
    /// Capture time, s: of the static record, or of each rate of a rate table
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// Static bias from this file or stored session instead of a board
    #[arg(long, value_name = "INPUT", conflicts_with = "rate_table")]
    pub from: Option<PathBuf>,
    /// Rate table with the board: +RATE and -RATE deg/s about each axis in turn (the
    /// virtual board is spun by script; a person sets a real table)
    #[arg(long, value_name = "DEG_S", requires = "port")]
    pub table_rate: Option<f64>,
    /// Rate table from records: a text file of lines `AXIS RATE_DEG_S INPUT` (x|y|z, the
    /// commanded rate, signed by the right-hand rule, and a file or stored session)
    #[arg(long, value_name = "FILE")]
    pub rate_table: Option<PathBuf>,
    #[command(flatten)]
    pub output: OutputArgs,
}

/// One commanded rate and the record taken at it.
struct Spin {
    axis: usize,
    rate_deg_s: f64,
    record: Record,
}

pub fn run(args: &GyroArgs, store: Option<&Path>) -> Result<()> {
    let files = args.from.is_some() || args.rate_table.is_some();
    let port = board_or_files(&args.board.port, files, "--from INPUT or --rate-table FILE")?;
    let catalog = open_store(store)?;
    let mut provenance = Provenance::default();
    let (calibration, text) = match (port, args.table_rate) {
        (Some(port), None) => {
            let mut bench = Bench::open(port, &args.board)?;
            let rest = TrueInput::at_rest(
                GravityAxis::default(),
                crate::calibration::gravity::STANDARD,
            );
            let record = bench.measure(
                &catalog,
                args.seconds,
                rest,
                "put the board at rest (any orientation)",
                &[Sensor::Gyro, Sensor::Accel],
                &|_| Ok(()),
            )?;
            provenance = Provenance::of_bench(&bench, record.rate_hz);
            solve_static(&record)?
        }
        (Some(port), Some(rate)) => {
            let mut bench = Bench::open(port, &args.board)?;
            let spins = spin_on_bench(&mut bench, &catalog, args.seconds, rate)?;
            provenance = Provenance::of_bench(&bench, spins[0].record.rate_hz);
            solve_table(&spins)?
        }
        (None, _) => match (&args.from, &args.rate_table) {
            (Some(input), _) => solve_static(&provenance.load(input, store)?)?,
            (None, Some(table)) => {
                let spins = read_table(table, &mut provenance, store)?;
                solve_table(&spins)?
            }
            (None, None) => bail!("give --from INPUT or --rate-table FILE"),
        },
    };
    finish(&catalog, &args.output, &provenance, &calibration, &text)
}

fn solve_static(record: &Record) -> Result<(Calibration, String)> {
    let values = columns(record, Sensor::Gyro)?;
    let biases: Vec<StaticBias> = values
        .iter()
        .zip(Sensor::Gyro.channels())
        .map(|(v, name)| {
            static_bias(v, record.rate_hz)
                .ok_or_else(|| anyhow!("{}: {name} has under 16 samples", record.source))
        })
        .collect::<Result<_>>()?;
    let temperature_c = mean_temperature(record);
    let correction = Correction::bias_only(
        Sensor::Gyro,
        [0, 1, 2].map(|i| biases[i].bias),
        temperature_c,
    );
    let mut text = format!(
        "gyro static bias over {:.1} s at {temperature_c:.2} degC; uncertainty (1 sigma) = the Allan deviation at tau = the record length (IEEE-952 fit)\n",
        biases[0].record_s
    );
    for (axis, b) in AXES.iter().zip(&biases) {
        let _ = writeln!(
            text,
            "  {axis}: bias {:+.5e} rad/s ({:+.2} deg/h) +- {:.2e} rad/s ({:.3} deg/h); the Allan minimum {:.2e} rad/s ({:.3} deg/h) at tau {:.1} s",
            b.bias,
            b.bias * DEG_H,
            b.uncertainty,
            b.uncertainty * DEG_H,
            b.best_adev,
            b.best_adev * DEG_H,
            b.best_tau_s
        );
    }
    let calibration = Calibration {
        kind: Kind::Gyro,
        corrections: vec![correction],
        temperature: vec![],
        details: serde_json::json!({ "static_bias_rad_s": biases }),
    };
    Ok((calibration, text))
}

/// Spin the board at +rate and -rate about each axis in turn.
fn spin_on_bench(
    bench: &mut Bench,
    catalog: &crate::store::Store,
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
                crate::calibration::gravity::STANDARD,
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
fn read_table(path: &Path, provenance: &mut Provenance, store: Option<&Path>) -> Result<Vec<Spin>> {
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

fn solve_table(spins: &[Spin]) -> Result<(Calibration, String)> {
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

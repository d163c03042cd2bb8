//! `imunoise calibrate accel`: the six static positions (module `calibration::fit`).

use super::bench::Bench;
use super::{BoardArgs, OutputArgs, Provenance, board_or_files, finish, mean_temperature, means};
use crate::cli::calibrations::describe_calibration;
use crate::cli::stored::open_store;
use anyhow::{Result, anyhow, bail};
use imunoise::calibration::fit::{Observation, axis_label, fit_linear, six_positions, two_point};
use imunoise::calibration::gravity::{STANDARD, normal_gravity};
use imunoise::calibration::still::check_orientation;
use imunoise::calibration::{AXES, Calibration, Kind, Sensor};
use imunoise::record::Record;
use imunoise::sim::imu::{GravityAxis, TrueInput};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct AccelArgs {
    #[command(flatten)]
    pub board: BoardArgs,
    /// Capture time per position, s
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// A position's record from a file or stored session instead of a board, e.g.
    /// `--position +x=up_x.csv` (repeat for all six: +x -x +y -y +z -z)
    #[arg(
        long = "position",
        value_name = "AXIS=INPUT",
        value_parser = parse_position,
        allow_hyphen_values = true
    )]
    pub positions: Vec<(GravityAxis, PathBuf)>,
    /// Local gravity, m/s^2 (default: standard gravity 9.80665)
    #[arg(long, conflicts_with = "latitude")]
    pub gravity: Option<f64>,
    /// Latitude, deg, for WGS84 normal gravity (with --height)
    #[arg(long, requires = "height")]
    pub latitude: Option<f64>,
    /// Height above the ellipsoid, m (with --latitude)
    #[arg(long, requires = "latitude")]
    pub height: Option<f64>,
    #[command(flatten)]
    pub output: OutputArgs,
}

fn parse_position(s: &str) -> Result<(GravityAxis, PathBuf), String> {
    let (axis, path) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}': expected AXIS=INPUT, e.g. +x=up_x.csv"))?;
    Ok((
        axis.parse::<GravityAxis>().map_err(|e| e.to_string())?,
        PathBuf::from(path),
    ))
}

/// The gravity the user gave, or WGS84 normal gravity, or standard gravity.
fn gravity(args: &AccelArgs) -> Result<f64> {
    let g = match (args.gravity, args.latitude, args.height) {
        (Some(g), _, _) => g,
        (None, Some(lat), Some(h)) => {
            if !(-90.0..=90.0).contains(&lat) {
                bail!("--latitude {lat}: must be within -90..90 deg");
            }
            normal_gravity(lat, h)
        }
        _ => STANDARD,
    };
    if !(9.7..=9.9).contains(&g) {
        bail!(
            "--gravity {g}: outside 9.7..9.9 m/s^2 (gravity at Earth's surface is 9.76..9.84 m/s^2)"
        );
    }
    Ok(g)
}

/// The six positions in order with their inputs, each given exactly once by `--position`.
fn positions(args: &AccelArgs) -> Result<Vec<(GravityAxis, &Path)>> {
    six_positions()
        .into_iter()
        .map(|(axis, negative)| {
            let wanted = GravityAxis { axis, negative };
            let mut given = args.positions.iter().filter(|(a, _)| *a == wanted);
            match (given.next(), given.next()) {
                (Some((_, path)), None) => Ok((wanted, path.as_path())),
                _ => bail!(
                    "--position {}=INPUT: give each of the six positions exactly once",
                    axis_label(axis, negative)
                ),
            }
        })
        .collect()
}

pub fn run(args: &AccelArgs, store: Option<&Path>) -> Result<()> {
    let g = gravity(args)?;
    let port = board_or_files(
        &args.board.port,
        !args.positions.is_empty(),
        "--position AXIS=INPUT for each of the six positions",
    )?;
    // All six named before the store is opened or any file read, so a missing one is said
    // at once.
    let positions = port.is_none().then(|| positions(args)).transpose()?;
    let catalog = open_store(store)?;
    let mut provenance = Provenance::default();
    let mut records = Vec::new();
    match port {
        Some(port) => {
            let mut bench = Bench::open(port, &args.board)?;
            for (axis, negative) in six_positions() {
                let label = axis_label(axis, negative);
                let input = TrueInput::at_rest(GravityAxis { axis, negative }, g);
                let check = |r: &Record| -> Result<(), String> {
                    let m = means(r, Sensor::Accel).map_err(|e| e.to_string())?;
                    check_orientation(m, axis, negative, g).map_err(|e| e.to_string())
                };
                let instruction = format!("turn the board so that {label} points up");
                let record = bench.measure(
                    &catalog,
                    args.seconds,
                    input,
                    &instruction,
                    &[Sensor::Gyro, Sensor::Accel],
                    &check,
                )?;
                records.push((axis, negative, record));
            }
            provenance = Provenance::of_bench(&bench, records[0].2.rate_hz);
        }
        None => {
            for (GravityAxis { axis, negative }, path) in positions.into_iter().flatten() {
                let label = axis_label(axis, negative);
                let record = provenance.load(path, store)?;
                let m = means(&record, Sensor::Accel)?;
                check_orientation(m, axis, negative, g)
                    .map_err(|e| anyhow!("--position {label}={}: {e}", path.display()))?;
                records.push((axis, negative, record));
            }
        }
    }
    let (calibration, text) = solve(&records, g)?;
    finish(&catalog, &args.output, &provenance, &calibration, &text)
}

/// Up/down per axis and the six-position least squares; the calibration and its table.
fn solve(records: &[(usize, bool, Record)], g: f64) -> Result<(Calibration, String)> {
    let mut observations = Vec::new();
    let mut temps = Vec::new();
    for (axis, negative, record) in records {
        let mut truth = [0.0; 3];
        truth[*axis] = if *negative { -g } else { g };
        observations.push(Observation {
            label: format!("{} up", axis_label(*axis, *negative)),
            truth,
            measured: means(record, Sensor::Accel)?,
        });
        temps.push(mean_temperature(record));
    }
    let temperature_c = temps.iter().sum::<f64>() / temps.len() as f64;
    let reading = |axis: usize, negative: bool| {
        observations
            .iter()
            .find(|o| o.truth[axis] * if negative { -1.0 } else { 1.0 } > 0.0)
            .map_or(f64::NAN, |o| o.measured[axis])
    };
    let up_down: Vec<_> = (0..3)
        .map(|a| two_point(reading(a, false), reading(a, true), g))
        .collect();
    let fit = fit_linear(Sensor::Accel, &observations, temperature_c)?;
    let mut text = format!(
        "accelerometer, six positions, g = {g:.6} m/s^2, mean TEMP_OUT {temperature_c:.2} degC\n\
         up/down (bias = (f_up + f_down)/2, scale factor = (f_up - f_down - 2g)/(2g)):\n"
    );
    for (axis, t) in AXES.iter().zip(&up_down) {
        let _ = writeln!(
            text,
            "  {axis}: f_up {:+.5} m/s^2  f_down {:+.5} m/s^2  bias {:+.5e} m/s^2  scale factor {:+.1} ppm",
            t.plus,
            t.minus,
            t.bias,
            t.scale_factor * 1e6
        );
    }
    text += "least squares, ";
    text += &describe_calibration(&Calibration {
        kind: Kind::Accel,
        corrections: vec![fit.correction.clone()],
        temperature: vec![],
        details: serde_json::Value::Null,
    });
    let _ = writeln!(
        text,
        "  residuals (measured - model), m/s^2; RMS {:.2e} m/s^2:",
        fit.residual_rms
    );
    for (o, r) in observations.iter().zip(&fit.residuals) {
        let _ = writeln!(
            text,
            "    {:<6} x {:+.2e}  y {:+.2e}  z {:+.2e}",
            o.label, r[0], r[1], r[2]
        );
    }
    let calibration = Calibration {
        kind: Kind::Accel,
        corrections: vec![fit.correction.clone()],
        temperature: vec![],
        details: serde_json::json!({
            "gravity_m_s2": g,
            "up_down": up_down,
            "observations": observations,
            "residuals_m_s2": fit.residuals,
            "residual_rms_m_s2": fit.residual_rms,
        }),
    };
    Ok((calibration, text))
}

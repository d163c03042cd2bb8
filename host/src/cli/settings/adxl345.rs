//! `imunoise settings --sensor adxl345`: the output data rates, or BW_RATE and DATA_FORMAT for
//! a rate. The bandwidth is always half the rate, so `--bandwidth` is only checked.

use super::{SettingsArgs, json_text, lines};
use anyhow::{Result, anyhow, bail};
use protocol::adxl345::settings::{LOW_POWER_CODES, TOP_RATE_CODE, rate_of_code};
use protocol::adxl345::{self, Adxl345Range, Adxl345Settings, reg};
use protocol::mpu6050::Hz;
use serde_json::json;

pub(super) fn run(args: &SettingsArgs) -> Result<String> {
    let Some(rate) = args.rate else {
        return Ok(if args.json {
            json_text(&table_json())
        } else {
            table_text()
        });
    };
    let mut s = Adxl345Settings::for_rate(rate, args.low_power)
        .map_err(|e| anyhow!("--sensor adxl345 --rate {rate}: {e}"))?;
    s.range = range(args.accel_range)?;
    if let Some(bandwidth) = args.bandwidth
        && (bandwidth - s.bandwidth_hz()).abs() > 1e-9 * s.bandwidth_hz()
    {
        bail!(
            "--sensor adxl345 --bandwidth {bandwidth}: the ADXL345's bandwidth is half its output rate, {} Hz at {} Hz",
            Hz(s.bandwidth_hz()),
            Hz(s.output_rate_hz())
        );
    }
    Ok(if args.json {
        json_text(&settings_json(&s))
    } else {
        settings_text(&s)
    })
}

/// `--accel-range G` for the ADXL345.
fn range(g: u32) -> Result<Adxl345Range> {
    Adxl345Range::from_full_scale_g(g)
        .ok_or_else(|| anyhow!("--accel-range {g}: the ADXL345's ranges are 2, 4, 8 and 16 g"))
}

/// Typical noise in mg rms from LSB rms at full resolution.
fn mg(lsb: f64) -> f64 {
    lsb * 1000.0 / adxl345::LSB_PER_G
}

fn settings_text(s: &Adxl345Settings) -> String {
    let (xy, z) = (s.noise_lsb_rms(false), s.noise_lsb_rms(true));
    lines(vec![
        s.to_string(),
        "registers:".to_string(),
        format!(
            "  BW_RATE     ({:#04x}) = {:#04x}  (rate code {}, {} power)",
            reg::BW_RATE,
            s.bw_rate(),
            s.rate_code,
            if s.low_power { "low" } else { "normal" }
        ),
        format!(
            "  DATA_FORMAT ({:#04x}) = {:#04x}  (FULL_RES, +/-{} g, {} LSB per g)",
            reg::DATA_FORMAT,
            s.data_format(),
            s.range.full_scale_g(),
            adxl345::LSB_PER_G
        ),
        format!(
            "typical noise (data sheet): {xy} LSB rms on x and y ({:.2} mg), {z} on z ({:.2} mg)",
            mg(xy),
            mg(z)
        ),
    ])
}

fn settings_json(s: &Adxl345Settings) -> serde_json::Value {
    json!({
        "sensor": "adxl345",
        "output_rate_hz": s.output_rate_hz(),
        "bandwidth_hz": s.bandwidth_hz(),
        "rate_code": s.rate_code,
        "low_power": s.low_power,
        "full_scale_g": s.range.full_scale_g(),
        "lsb_per_g": adxl345::LSB_PER_G,
        "noise_lsb_rms": { "x": s.noise_lsb_rms(false), "y": s.noise_lsb_rms(false), "z": s.noise_lsb_rms(true) },
        "registers": {
            "BW_RATE": s.bw_rate(),
            "DATA_FORMAT": s.data_format(),
        },
    })
}

/// Every rate code, fastest first, with its normal-power settings.
fn codes() -> impl Iterator<Item = Adxl345Settings> {
    (0..=TOP_RATE_CODE).rev().map(|rate_code| Adxl345Settings {
        rate_code,
        ..Adxl345Settings::default()
    })
}

fn table_text() -> String {
    let mut out = vec![
        "ADXL345 output data rates (data sheet rev. G, tables 7 and 8; noise: \"Noise Performance\")"
            .to_string(),
        format!(
            "{:>4} {:>9} {:>9} {:>9} {:>14} {:>10}",
            "code", "rate Hz", "BW Hz", "BW_RATE", "noise x,y LSB", "low power"
        ),
    ];
    for s in codes() {
        out.push(format!(
            "{:>4} {:>9} {:>9} {:>#9x} {:>14.3} {:>10}",
            s.rate_code,
            Hz(s.output_rate_hz()).to_string(),
            Hz(s.bandwidth_hz()).to_string(),
            s.bw_rate(),
            s.noise_lsb_rms(false),
            if LOW_POWER_CODES.contains(&s.rate_code) {
                "yes"
            } else {
                "-"
            }
        ));
    }
    out.push(format!(
        "output rate = {} Hz / 2^(15 - code); bandwidth = rate / 2; low power adds noise (1.8 LSB rms on x and y)",
        Hz(rate_of_code(TOP_RATE_CODE))
    ));
    lines(out)
}

fn table_json() -> serde_json::Value {
    let rows: Vec<_> = codes()
        .map(|s| {
            json!({
                "rate_code": s.rate_code,
                "output_rate_hz": s.output_rate_hz(),
                "bandwidth_hz": s.bandwidth_hz(),
                "bw_rate": s.bw_rate(),
                "noise_lsb_rms_xy": s.noise_lsb_rms(false),
                "noise_lsb_rms_z": s.noise_lsb_rms(true),
                "low_power_available": LOW_POWER_CODES.contains(&s.rate_code),
            })
        })
        .collect();
    json!({ "sensor": "adxl345", "rates": rows })
}

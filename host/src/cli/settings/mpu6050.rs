//! `imunoise settings --sensor mpu6050`: the DLPF table, or the exact register values for an
//! output rate and a bandwidth (with the nearest valid choices when there are none).

use super::{SettingsArgs, aliasing_note, json_text, lines, rate_span, required_bandwidth};
use anyhow::{Result, anyhow};
use protocol::mpu6050::{AccelRange, DLPF_TABLE, GyroRange, SensorSettings};
use serde_json::json;

pub(super) fn run(args: &SettingsArgs) -> Result<String> {
    let gyro_bandwidths = DLPF_TABLE
        .map(|r| r.gyro_bandwidth_hz.to_string())
        .join(" ");
    Ok(match required_bandwidth(args, &gyro_bandwidths)? {
        Some((rate, bandwidth)) => {
            let settings = SensorSettings::for_rate_and_bandwidth(rate, bandwidth)
                .map_err(|e| anyhow!("--rate {rate} --bandwidth {bandwidth}: {e}"))?
                .with_ranges(gyro_range(args.gyro_range)?, accel_range(args.accel_range)?);
            if args.json {
                json_text(&settings_json(&settings))
            } else {
                settings_text(&settings)
            }
        }
        None if args.json => json_text(&table_json()),
        None => table_text(),
    })
}

/// `--gyro-range DPS`: the range of that full scale.
pub fn gyro_range(dps: u32) -> Result<GyroRange> {
    GyroRange::from_full_scale_dps(dps).map_err(|e| anyhow!("--gyro-range {dps}: {e}"))
}

/// `--accel-range G`: the range of that full scale.
pub fn accel_range(g: u32) -> Result<AccelRange> {
    AccelRange::from_full_scale_g(g).map_err(|e| anyhow!("--accel-range {g}: {e}"))
}

fn settings_text(s: &SensorSettings) -> String {
    let r = s.registers();
    let mut out = vec![s.to_string(), "registers:".to_string()];
    out.push(format!(
        "  SMPLRT_DIV   (0x19) = {:#04x}  ({})",
        r.smplrt_div, r.smplrt_div
    ));
    out.push(format!(
        "  CONFIG       (0x1A) = {:#04x}  (DLPF_CFG {})",
        r.config,
        s.dlpf.bits()
    ));
    out.push(format!(
        "  GYRO_CONFIG  (0x1B) = {:#04x}  (FS_SEL {}, {} LSB per deg/s)",
        r.gyro_config,
        s.gyro_range.bits(),
        s.gyro_range.lsb_per_dps()
    ));
    out.push(format!(
        "  ACCEL_CONFIG (0x1C) = {:#04x}  (AFS_SEL {}, {} LSB per g)",
        r.accel_config,
        s.accel_range.bits(),
        s.accel_range.lsb_per_g()
    ));
    out.extend(aliasing_note(s.aliases(), s.output_rate_hz()));
    lines(out)
}

fn settings_json(s: &SensorSettings) -> serde_json::Value {
    let r = s.registers();
    let row = s.dlpf.row();
    json!({
        "output_rate_hz": s.output_rate_hz(),
        "dlpf_cfg": s.dlpf.bits(),
        "smplrt_div": s.smplrt_div,
        "gyro_internal_rate_hz": s.dlpf.gyro_internal_rate_hz(),
        "gyro_bandwidth_hz": row.map(|r| r.gyro_bandwidth_hz),
        "gyro_delay_ms": row.map(|r| r.gyro_delay_ms),
        "accel_bandwidth_hz": row.map(|r| r.accel_bandwidth_hz),
        "accel_delay_ms": row.map(|r| r.accel_delay_ms),
        "gyro_full_scale_dps": s.gyro_range.full_scale_dps(),
        "gyro_lsb_per_dps": s.gyro_range.lsb_per_dps(),
        "accel_full_scale_g": s.accel_range.full_scale_g(),
        "accel_lsb_per_g": s.accel_range.lsb_per_g(),
        "bandwidth_exceeds_half_rate": s.aliases(),
        "registers": {
            "SMPLRT_DIV": r.smplrt_div,
            "CONFIG": r.config,
            "GYRO_CONFIG": r.gyro_config,
            "ACCEL_CONFIG": r.accel_config,
        },
    })
}

fn table_text() -> String {
    let mut out =
        vec!["MPU-6050 digital low-pass filter (register map rev 4.2, register 26)".to_string()];
    out.push(format!(
        "{:>8} {:>12} {:>13} {:>13} {:>14} {:>15} {:>22}",
        "DLPF_CFG",
        "gyro BW Hz",
        "gyro delay ms",
        "accel BW Hz",
        "accel delay ms",
        "gyro int. Hz",
        "output rate Hz"
    ));
    for r in &DLPF_TABLE {
        let (lo, hi) = rate_span(r.gyro_internal_rate_hz);
        out.push(format!(
            "{:>8} {:>12} {:>13} {:>13} {:>14} {:>15} {:>22}",
            r.cfg.bits(),
            r.gyro_bandwidth_hz,
            r.gyro_delay_ms,
            r.accel_bandwidth_hz,
            r.accel_delay_ms,
            r.gyro_internal_rate_hz,
            format!("{lo}..{hi}")
        ));
    }
    out.push(format!(
        "{:>8} {:>12}  (reserved by the datasheet; gyro internal rate 8000 Hz)",
        7, "-"
    ));
    out.push(
        "output rate = gyro internal rate / (1 + SMPLRT_DIV), SMPLRT_DIV 0..255; the accelerometer samples at 1000 Hz"
            .to_string(),
    );
    lines(out)
}

fn table_json() -> serde_json::Value {
    let rows: Vec<_> = DLPF_TABLE
        .iter()
        .map(|r| {
            let (lo, hi) = rate_span(r.gyro_internal_rate_hz);
            json!({
                "dlpf_cfg": r.cfg.bits(),
                "gyro_bandwidth_hz": r.gyro_bandwidth_hz,
                "gyro_delay_ms": r.gyro_delay_ms,
                "accel_bandwidth_hz": r.accel_bandwidth_hz,
                "accel_delay_ms": r.accel_delay_ms,
                "gyro_internal_rate_hz": r.gyro_internal_rate_hz,
                "min_output_rate_hz": lo,
                "max_output_rate_hz": hi,
            })
        })
        .collect();
    json!({ "dlpf": rows })
}

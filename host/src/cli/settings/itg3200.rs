//! `imunoise settings --sensor itg3200`: the gyro's DLPF table, or SMPLRT_DIV and DLPF_FS for
//! an output rate and a bandwidth.

use super::{SettingsArgs, aliasing_note, json_text, lines, rate_span, required_bandwidth};
use anyhow::{Result, anyhow};
use protocol::itg3200::{self, Itg3200Settings, reg};
use protocol::mpu6050::DLPF_TABLE;
use serde_json::json;

pub(super) fn run(args: &SettingsArgs) -> Result<String> {
    let bandwidths = DLPF_TABLE
        .map(|r| r.gyro_bandwidth_hz.to_string())
        .join(" ");
    Ok(match required_bandwidth(args, &bandwidths)? {
        Some((rate, bandwidth)) => {
            let s = Itg3200Settings::for_rate_and_bandwidth(rate, bandwidth).map_err(|e| {
                anyhow!("--sensor itg3200 --rate {rate} --bandwidth {bandwidth}: {e}")
            })?;
            if args.json {
                json_text(&settings_json(&s))
            } else {
                settings_text(&s)
            }
        }
        None if args.json => json_text(&table_json()),
        None => table_text(),
    })
}

fn settings_text(s: &Itg3200Settings) -> String {
    let mut out = vec![
        s.to_string(),
        "registers:".to_string(),
        format!(
            "  SMPLRT_DIV ({:#04x}) = {:#04x}  ({})",
            reg::SMPLRT_DIV,
            s.smplrt_div,
            s.smplrt_div
        ),
        format!(
            "  DLPF_FS    ({:#04x}) = {:#04x}  (FS_SEL 3, DLPF_CFG {}; {} LSB per deg/s)",
            reg::DLPF_FS,
            s.dlpf_fs(),
            s.dlpf.bits(),
            itg3200::LSB_PER_DPS
        ),
    ];
    out.extend(aliasing_note(s.aliases(), s.output_rate_hz()));
    lines(out)
}

fn settings_json(s: &Itg3200Settings) -> serde_json::Value {
    json!({
        "sensor": "itg3200",
        "output_rate_hz": s.output_rate_hz(),
        "dlpf_cfg": s.dlpf.bits(),
        "smplrt_div": s.smplrt_div,
        "internal_rate_hz": s.dlpf.gyro_internal_rate_hz(),
        "bandwidth_hz": s.bandwidth_hz(),
        "full_scale_dps": 2000,
        "lsb_per_dps": itg3200::LSB_PER_DPS,
        "bandwidth_exceeds_half_rate": s.aliases(),
        "registers": {
            "SMPLRT_DIV": s.smplrt_div,
            "DLPF_FS": s.dlpf_fs(),
        },
    })
}

fn table_text() -> String {
    let mut out = vec![
        "ITG-3200 digital low-pass filter (PS-ITG-3200A rev 1.4, register 22; FS_SEL is always 3)"
            .to_string(),
        format!(
            "{:>8} {:>8} {:>12} {:>16} {:>8}",
            "DLPF_CFG", "BW Hz", "internal Hz", "output rate Hz", "DLPF_FS"
        ),
    ];
    for r in &DLPF_TABLE {
        let s = Itg3200Settings {
            dlpf: r.cfg,
            smplrt_div: 0,
        };
        let (lo, hi) = rate_span(r.gyro_internal_rate_hz);
        out.push(format!(
            "{:>8} {:>8} {:>12} {:>16} {:>#8x}",
            r.cfg.bits(),
            r.gyro_bandwidth_hz,
            r.gyro_internal_rate_hz,
            format!("{lo}..{hi}"),
            s.dlpf_fs()
        ));
    }
    out.push(
        "output rate = internal rate / (1 + SMPLRT_DIV), SMPLRT_DIV 0..255; no FIFO: the board reads each sample when RAW_DATA_RDY is set"
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
                "bandwidth_hz": r.gyro_bandwidth_hz,
                "internal_rate_hz": r.gyro_internal_rate_hz,
                "min_output_rate_hz": lo,
                "max_output_rate_hz": hi,
            })
        })
        .collect();
    json!({ "sensor": "itg3200", "dlpf": rows })
}

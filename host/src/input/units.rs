//! Units stated by a column name's suffix (`gx_dps`, `az_g`, `temp_C`) or in brackets
//! (`Gyroscope x (rad/s)`, `ax [m/s^2]`, `temp (°C)`): the values are converted to SI and
//! the unit is dropped from the name, so `gx_dps` becomes the angular-rate channel `gx` in
//! rad/s, and every conversion is reported.

use super::InputError;
use super::names::{bracketed, folded_unit};
use crate::record::{Channel, Quantity};
use serde::Serialize;
use std::path::Path;

/// Standard gravity, m/s^2 (CGPM 1901; NIST SP 330).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// A unit a suffix or a bracket names: its label, what it measures and its factor to SI.
struct Unit {
    suffixes: &'static [&'static str],
    /// Its spellings in brackets, as [`folded_unit`] folds them.
    bracketed: &'static [&'static str],
    label: &'static str,
    quantity: Quantity,
    to_si: f64,
}

/// Longer suffixes first where one ends another (`_degc` before `_c`).
const UNITS: [Unit; 6] = [
    Unit {
        suffixes: &["_dps", "_degps"],
        bracketed: &["deg/s", "dps", "degps", "degree/s", "degrees/s"],
        label: "deg/s",
        quantity: Quantity::AngularRate,
        to_si: std::f64::consts::PI / 180.0,
    },
    Unit {
        suffixes: &["_rads", "_rad_s"],
        bracketed: &["rad/s", "rads", "rad.s^-1", "rads^-1"],
        label: "rad/s",
        quantity: Quantity::AngularRate,
        to_si: 1.0,
    },
    Unit {
        suffixes: &["_mg"],
        bracketed: &["mg"],
        label: "mg",
        quantity: Quantity::Acceleration,
        to_si: STANDARD_GRAVITY * 1e-3,
    },
    Unit {
        suffixes: &["_g"],
        bracketed: &["g"],
        label: "g",
        quantity: Quantity::Acceleration,
        to_si: STANDARD_GRAVITY,
    },
    Unit {
        suffixes: &["_mps2", "_ms2"],
        bracketed: &["m/s^2", "m/s2", "m/s/s", "ms^-2", "m.s^-2", "mps2"],
        label: "m/s^2",
        quantity: Quantity::Acceleration,
        to_si: 1.0,
    },
    Unit {
        suffixes: &["_degc", "_c"],
        bracketed: &["degc", "c", "celsius", "degreesc"],
        label: "degC",
        quantity: Quantity::Temperature,
        to_si: 1.0,
    },
];

/// One column's conversion, as reported to the user.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnitConversion {
    /// The column's name in the input.
    pub column: String,
    /// The channel it became.
    pub channel: String,
    pub from: &'static str,
    pub to: &'static str,
    pub factor: f64,
}

impl std::fmt::Display for UnitConversion {
    /// `gx_dps: deg/s -> rad/s x 0.0174533`; a column already in SI says so.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.factor == 1.0 {
            write!(f, "{}: {} (SI as is)", self.column, self.from)
        } else {
            let factor: f64 = format!("{:.5e}", self.factor)
                .parse()
                .unwrap_or(self.factor);
            write!(
                f,
                "{}: {} -> {} x {factor}",
                self.column, self.from, self.to
            )
        }
    }
}

/// The unit `name`'s suffix or bracket states (matched without regard to case) and the name
/// without it; None when the name states no unit this knows or has nothing before it.
fn split(name: &str) -> Option<(&str, &'static Unit)> {
    if let Some((stem, written)) = bracketed(name) {
        let folded = folded_unit(written);
        return UNITS
            .iter()
            .find(|u| u.bracketed.contains(&folded.as_str()))
            .map(|unit| (stem, unit));
    }
    let lower = name.to_ascii_lowercase();
    UNITS.iter().find_map(|unit| {
        let suffix = unit
            .suffixes
            .iter()
            .find(|s| lower.len() > s.len() && lower.ends_with(*s))?;
        Some((&name[..name.len() - suffix.len()], unit))
    })
}

/// Channels from named columns: a unit suffix converts the values to SI and names the
/// channel by its stem; other names are taken as they are (their units guessed from the name,
/// [`Quantity::from_name`]). A suffix that contradicts its stem (`gx_g`) and two columns that
/// become one name are errors.
pub(super) fn channels(
    path: &Path,
    columns: Vec<(String, Vec<f64>)>,
) -> Result<(Vec<Channel>, Vec<UnitConversion>), InputError> {
    let mut channels: Vec<Channel> = Vec::with_capacity(columns.len());
    let mut conversions = Vec::new();
    for (column, mut values) in columns {
        let channel = match split(&column) {
            None => Channel::named(column, values),
            Some((stem, unit)) => {
                let named = Quantity::from_name(stem);
                if named != Quantity::Other && named != unit.quantity {
                    return Err(InputError::file(
                        path,
                        format!(
                            "column '{column}': '{stem}' names a channel in {} but the suffix says {}",
                            named.si_unit(),
                            unit.label
                        ),
                    ));
                }
                if unit.to_si != 1.0 {
                    values.iter_mut().for_each(|v| *v *= unit.to_si);
                }
                conversions.push(UnitConversion {
                    column: column.clone(),
                    channel: stem.to_string(),
                    from: unit.label,
                    to: unit.quantity.si_unit(),
                    factor: unit.to_si,
                });
                Channel {
                    name: stem.to_string(),
                    quantity: unit.quantity,
                    values,
                }
            }
        };
        if channels.iter().any(|c| c.name == channel.name) {
            return Err(InputError::file(
                path,
                format!("two columns are channel '{}'", channel.name),
            ));
        }
        channels.push(channel);
    }
    Ok((channels, conversions))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn convert(names: &[&str]) -> Result<(Vec<Channel>, Vec<UnitConversion>), InputError> {
        let columns = names.iter().map(|n| (n.to_string(), vec![2.0])).collect();
        channels(Path::new("u.csv"), columns)
    }

    #[test]
    fn suffixes_convert_to_si_and_name_the_channel() {
        let names = [
            "gx_dps",
            "gy_degps",
            "gz_rad_s",
            "wx_rads",
            "ax_g",
            "ay_mg",
            "az_mps2",
            "acc_x_ms2",
            "temp_C",
            "die_degC",
            "plain",
        ];
        let (channels, conversions) = convert(&names).unwrap();
        let got: Vec<(&str, &str, f64)> = channels
            .iter()
            .map(|c| (c.name.as_str(), c.unit(), c.values[0]))
            .collect();
        let deg = 2.0f64.to_radians();
        assert_eq!(
            got,
            [
                ("gx", "rad/s", deg),
                ("gy", "rad/s", deg),
                ("gz", "rad/s", 2.0),
                ("wx", "rad/s", 2.0),
                ("ax", "m/s^2", 2.0 * 9.80665),
                ("ay", "m/s^2", 2.0 * 9.80665e-3),
                ("az", "m/s^2", 2.0),
                ("acc_x", "m/s^2", 2.0),
                ("temp", "degC", 2.0),
                ("die", "degC", 2.0),
                ("plain", "u", 2.0),
            ]
        );
        assert_eq!(conversions.len(), 10);
        assert_eq!(
            conversions[0].to_string(),
            "gx_dps: deg/s -> rad/s x 0.0174533"
        );
        assert_eq!(
            conversions[5].to_string(),
            "ay_mg: mg -> m/s^2 x 0.00980665"
        );
        assert_eq!(conversions[8].to_string(), "temp_C: degC (SI as is)");
    }

    #[test]
    fn contradictions_and_collisions_are_errors() {
        let e = convert(&["gx_g"]).unwrap_err().to_string();
        assert_eq!(
            e,
            "u.csv: column 'gx_g': 'gx' names a channel in rad/s but the suffix says g"
        );
        let e = convert(&["gx_dps", "gx"]).unwrap_err().to_string();
        assert_eq!(e, "u.csv: two columns are channel 'gx'");
        // A bare suffix is a name, not a unit.
        let (c, conv) = convert(&["_g", "g"]).unwrap();
        assert_eq!(c[0].name, "_g");
        assert!(conv.is_empty());
    }
}

//! The decoded, columnar form every analysis takes: named channels of equally spaced samples
//! in SI units, whatever they came from (a text or NumPy file, a session, a simulation).

use serde::Serialize;

/// What a channel measures; decides its SI unit and how its noise terms are labelled in
/// conventional units (deg/h for a gyro, ug for an accelerometer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// Angular rate, rad/s.
    AngularRate,
    /// Specific force, m/s^2.
    Acceleration,
    /// Die temperature, degC.
    Temperature,
    /// Anything else, in the unit the input gave it (unknown to us).
    Other,
}

/// Words of a column name (split at anything but letters and digits, lower case) that make
/// it a temperature, a unit run into the word included (`tempC`).
const TEMPERATURE_WORDS: [&str; 6] = [
    "temp",
    "temperature",
    "tempc",
    "temperaturec",
    "tempdegc",
    "temperaturedegc",
];

impl Quantity {
    /// Recognise the usual IMU column names: `gx`, `gyro_x`, `wx`, `Gyroscope x` are rates;
    /// `ax`, `acc_x`, `accel_x`, `field.linear_acceleration.x` are accelerations; a name
    /// with the word `temp` or `temperature` in it (`imu_temp`, `tempC`, `field.temperature`)
    /// is the die temperature.
    pub fn from_name(name: &str) -> Quantity {
        let n = name.trim().to_ascii_lowercase();
        let axis = |prefixes: &[&str]| {
            prefixes.iter().any(|p| {
                n.strip_prefix(p)
                    .map(|rest| {
                        matches!(
                            rest.trim_start_matches(['_', '.', ' ', '-']),
                            "x" | "y" | "z"
                        )
                    })
                    .unwrap_or(false)
            })
        };
        // ROS's `field.angular_velocity.x` and the phone apps' `Gyroscope x` too.
        if axis(&[
            "g",
            "gyro",
            "gyr",
            "gyroscope",
            "w",
            "omega",
            "angular_velocity",
            "field.angular_velocity",
        ]) {
            Quantity::AngularRate
        } else if axis(&[
            "a",
            "acc",
            "accel",
            "accelerometer",
            "acceleration",
            "linear_acceleration",
            "field.linear_acceleration",
            // Kalibr's imu.csv: `omega_x` the rate, `alpha_x` the specific force.
            "alpha",
        ]) {
            Quantity::Acceleration
        } else if n
            .split(|c: char| !c.is_ascii_alphanumeric())
            .any(|word| TEMPERATURE_WORDS.contains(&word))
        {
            Quantity::Temperature
        } else {
            Quantity::Other
        }
    }

    /// The SI unit of the channel's values; `u` (unit of the input) for [`Quantity::Other`].
    pub fn si_unit(self) -> &'static str {
        match self {
            Quantity::AngularRate => "rad/s",
            Quantity::Acceleration => "m/s^2",
            Quantity::Temperature => "degC",
            Quantity::Other => "u",
        }
    }
}

/// One named channel of samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub name: String,
    pub quantity: Quantity,
    pub values: Vec<f64>,
}

impl Channel {
    /// Whether every sample equals the first (a channel with no noise to analyse); false for
    /// an empty channel.
    pub fn is_constant(&self) -> bool {
        self.values
            .first()
            .is_some_and(|v0| self.values.iter().all(|v| v == v0))
    }

    /// A channel whose quantity is guessed from its name ([`Quantity::from_name`]).
    pub fn named(name: impl Into<String>, values: Vec<f64>) -> Channel {
        let name = name.into();
        Channel {
            quantity: Quantity::from_name(&name),
            name,
            values,
        }
    }

    pub fn unit(&self) -> &'static str {
        self.quantity.si_unit()
    }
}

/// Equally spaced samples of several channels, all of the same length.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Where the record came from (a path, a session name), for messages and reports.
    pub source: String,
    pub rate_hz: f64,
    pub channels: Vec<Channel>,
}

/// A channel [`Record::select`] was asked for that the record does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--column {name}: no such channel in the input; it has {available}")]
pub struct NoSuchChannel {
    pub name: String,
    /// The record's channels, comma-separated.
    pub available: String,
}

impl Record {
    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |c| c.values.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn duration_s(&self) -> f64 {
        self.len() as f64 / self.rate_hz
    }

    pub fn channel(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }

    pub fn names(&self) -> Vec<&str> {
        self.channels.iter().map(|c| c.name.as_str()).collect()
    }

    /// Keep only the named channels, in the order given; an unknown name is an error that
    /// lists the channels there are.
    pub fn select(self, names: &[String]) -> Result<Record, NoSuchChannel> {
        if names.is_empty() {
            return Ok(self);
        }
        let available = self.names().join(", ");
        let mut channels = Vec::with_capacity(names.len());
        let mut pool = self.channels;
        for name in names {
            let at = pool
                .iter()
                .position(|c| &c.name == name)
                .ok_or_else(|| NoSuchChannel {
                    name: name.clone(),
                    available: available.clone(),
                })?;
            channels.push(pool.swap_remove(at));
        }
        Ok(Record {
            source: self.source,
            rate_hz: self.rate_hz,
            channels,
        })
    }

    /// Leave out the channels without noise — constant over the whole record: a dead axis, a
    /// temperature that never changed a count, a simulated group without noise — so that an
    /// analysis of every channel analyses the others; one warning per channel left out. When
    /// every channel is constant none is left out, and the analysis then says why it cannot
    /// start.
    pub fn leave_out_constant(&mut self) -> Vec<String> {
        if self.channels.iter().all(Channel::is_constant) {
            return Vec::new();
        }
        let (gone, kept): (Vec<Channel>, Vec<Channel>) = std::mem::take(&mut self.channels)
            .into_iter()
            .partition(Channel::is_constant);
        self.channels = kept;
        gone.iter()
            .map(|c| left_out_as_constant(&c.name, c.values[0], c.values.len()))
            .collect()
    }
}

/// The warning for a channel left out because it never changed.
pub fn left_out_as_constant(name: &str, value: f64, samples: usize) -> String {
    format!(
        "channel '{name}' is constant ({value} for all {samples} samples): left out, it has no noise to analyse"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_channels_are_left_out_with_a_warning_unless_all_are() {
        let channel = Channel::named;
        let mut record = Record {
            source: "r".into(),
            rate_hz: 10.0,
            channels: vec![
                channel("gx", vec![0.1, -0.2, 0.3]),
                channel("ax", vec![0.0; 3]),
                channel("temp", vec![25.5; 3]),
            ],
        };
        let warnings = record.leave_out_constant();
        assert_eq!(record.names(), ["gx"]);
        assert_eq!(warnings.len(), 2);
        assert!(warnings[1].contains("'temp' is constant (25.5 for all 3 samples)"));
        let mut quiet = Record {
            channels: vec![channel("ax", vec![1.0; 3])],
            ..record
        };
        assert!(quiet.leave_out_constant().is_empty());
        assert_eq!(quiet.names(), ["ax"]);
    }

    #[test]
    fn names_map_to_quantities() {
        for (name, q) in [
            ("gx", Quantity::AngularRate),
            ("Gyro_Z", Quantity::AngularRate),
            ("wy", Quantity::AngularRate),
            ("ax", Quantity::Acceleration),
            ("accel.y", Quantity::Acceleration),
            ("acc_z", Quantity::Acceleration),
            ("Gyroscope x", Quantity::AngularRate),
            ("field.angular_velocity.z", Quantity::AngularRate),
            ("field.linear_acceleration.y", Quantity::Acceleration),
            ("Accelerometer-Y", Quantity::Acceleration),
            ("omega_x", Quantity::AngularRate),
            ("alpha_z", Quantity::Acceleration),
            ("temp", Quantity::Temperature),
            ("temperature", Quantity::Temperature),
            ("imu_temp", Quantity::Temperature),
            ("die temp", Quantity::Temperature),
            ("tempC", Quantity::Temperature),
            ("Temperature_degC", Quantity::Temperature),
            ("field.temperature", Quantity::Temperature),
            ("gyro-temp", Quantity::Temperature),
            ("time", Quantity::Other),
            ("timestamp", Quantity::Other),
            ("attempts", Quantity::Other),
            ("tempo", Quantity::Other),
            ("gain", Quantity::Other),
            ("c0", Quantity::Other),
        ] {
            assert_eq!(Quantity::from_name(name), q, "{name}");
        }
    }

    #[test]
    fn select_keeps_order_and_names_missing_channels() {
        let r = Record {
            source: "x".into(),
            rate_hz: 10.0,
            channels: vec![
                Channel::named("gx", vec![1.0]),
                Channel::named("gy", vec![2.0]),
                Channel::named("ax", vec![3.0]),
            ],
        };
        let s = r.clone().select(&["ax".into(), "gx".into()]).unwrap();
        assert_eq!(s.names(), ["ax", "gx"]);
        let err = r.select(&["gz".into()]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "--column gz: no such channel in the input; it has gx, gy, ax"
        );
    }
}

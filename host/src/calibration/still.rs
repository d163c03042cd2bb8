//! Is the sensor still, and is it in the orientation asked for? Both judged from the data.
//!
//! **Still.** Each gyro and accelerometer channel is cut into 1 s windows; the difference d_k
//! of successive window means of a still sensor is noise with standard deviation
//! sqrt(2) sigma_A(1 s) (the Allan deviation at the window length, by definition). That
//! level is estimated robustly from the record itself, as median|d_k| / 0.6745 (the normal
//! distribution's median absolute value), so a few moving windows do not raise it. A window
//! step is motion when |d_k| exceeds 6 times that level (a still sensor does so with
//! probability 2e-9 per step: no false alarms over a session of checks) **and** a floor:
//! 0.2 deg/s for the gyro, 0.02 m/s^2 for the accelerometer (a 0.1 deg tilt change). The
//! floor is there because the median of a handful of windows can come out very low, and
//! because the floor's size of change is harmless: a hand turning a board moves its mean
//! rate by degrees per second and its accelerometer by tenths of m/s^2.
//!
//! **Orientation.** The mean specific force of a board at rest points up along the sensor's
//! axes (+g on the axis facing up). The asked axis must be within 20 deg of it (the six
//! positions are 90 deg apart, so a wrong face is always caught while a hand-held or
//! shimmed placement passes) and its magnitude within 10 % of g (else the data are not an
//! accelerometer at rest, or not in m/s^2).

use super::{Sensor, Vec3};
use crate::record::Record;
use serde::Serialize;

pub const WINDOW_S: f64 = 1.0;
/// Multiple of the robust noise level that counts as motion.
pub const MOTION_SIGMAS: f64 = 6.0;
/// Floors of the motion threshold: gyro rad/s (0.2 deg/s), accelerometer m/s^2.
pub const GYRO_FLOOR: f64 = 0.2 * std::f64::consts::PI / 180.0;
pub const ACCEL_FLOOR: f64 = 0.02;
/// Largest angle between the asked axis and the measured specific force, deg.
pub const MAX_TILT_DEG: f64 = 20.0;

/// The largest motion found, if any.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Motion {
    pub channel: String,
    /// Start of the window whose mean jumped, s from the record's start.
    pub at_s: f64,
    /// The jump of the window mean and the threshold it crossed (the channel's unit).
    pub change: f64,
    pub threshold: f64,
}

impl std::fmt::Display for Motion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the sensor moved: {} changed by {:.3e} (threshold {:.3e}) at {:.1} s",
            self.channel, self.change, self.threshold, self.at_s
        )
    }
}

/// A record too short for [`find_motion`] to judge: it needs three windows.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("{duration_s:.1} s is too short to judge stillness: at least {:.0} s", 3.0 * WINDOW_S)]
pub struct TooShortToJudge {
    pub duration_s: f64,
}

/// What the accelerometer shows instead of the asked orientation ([`check_orientation`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OrientationError {
    #[error(
        "asked for {asked} up: the accelerometer reads {norm:.3} m/s^2, not g = {g:.5} m/s^2 within 10 % (not at rest, or not in m/s^2?)"
    )]
    NotG { asked: String, norm: f64, g: f64 },
    #[error(
        "asked for {asked} up, but {found} is up ({angle:.1} deg from the vertical; {asked} is {tilt:.1} deg{})",
        if *.upside_down { ", upside down" } else { "" }
    )]
    Tilted {
        asked: String,
        found: String,
        /// deg.
        angle: f64,
        tilt: f64,
        upside_down: bool,
    },
}

/// The largest motion on the channels of `sensors` relative to its threshold, or None if
/// still. (On a rate table only the gyro should be steady: the accelerometer turns with
/// the table.) Records shorter than three windows cannot be judged: an error.
pub fn find_motion(record: &Record, sensors: &[Sensor]) -> Result<Option<Motion>, TooShortToJudge> {
    let w = ((record.rate_hz * WINDOW_S).round() as usize).max(1);
    let mut worst: Option<(f64, Motion)> = None;
    for channel in &record.channels {
        let floor = match sensors
            .iter()
            .find(|s| s.channels().contains(&channel.name.as_str()))
        {
            Some(Sensor::Gyro) => GYRO_FLOOR,
            Some(Sensor::Accel) => ACCEL_FLOOR,
            None => continue,
        };
        let means: Vec<f64> = channel
            .values
            .chunks_exact(w)
            .map(|c| c.iter().sum::<f64>() / w as f64)
            .collect();
        if means.len() < 3 {
            return Err(TooShortToJudge {
                duration_s: record.duration_s(),
            });
        }
        let d: Vec<f64> = means.windows(2).map(|p| p[1] - p[0]).collect();
        let mut abs: Vec<f64> = d.iter().map(|x| x.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let level = abs[abs.len() / 2] / 0.6745;
        let threshold = (MOTION_SIGMAS * level).max(floor);
        for (k, &dk) in d.iter().enumerate() {
            let ratio = dk.abs() / threshold;
            if ratio > 1.0 && worst.as_ref().is_none_or(|(r, _)| ratio > *r) {
                let motion = Motion {
                    channel: channel.name.clone(),
                    at_s: (k + 1) as f64 * w as f64 / record.rate_hz,
                    change: dk,
                    threshold,
                };
                worst = Some((ratio, motion));
            }
        }
    }
    Ok(worst.map(|(_, m)| m))
}

/// Which axis carries gravity: the axis of the largest component, its sign (true: the axis
/// points down) and the angle between that axis and the specific force, deg.
pub fn gravity_axis(mean_accel: Vec3) -> (usize, bool, f64) {
    let axis = (0..3)
        .max_by(|&i, &j| mean_accel[i].abs().total_cmp(&mean_accel[j].abs()))
        .unwrap_or(2);
    (axis, mean_accel[axis] < 0.0, angle_to(mean_accel, axis))
}

fn angle_to(f: Vec3, axis: usize) -> f64 {
    let norm = f.iter().map(|x| x * x).sum::<f64>().sqrt();
    (f[axis].abs() / norm).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Check that the sensor is at rest with `axis` up (`negative`: down), under gravity `g`;
/// the error says what the data show instead.
pub fn check_orientation(
    mean_accel: Vec3,
    axis: usize,
    negative: bool,
    g: f64,
) -> Result<(), OrientationError> {
    let norm = mean_accel.iter().map(|x| x * x).sum::<f64>().sqrt();
    let asked = super::fit::axis_label(axis, negative);
    if (norm / g - 1.0).abs() > 0.1 {
        return Err(OrientationError::NotG { asked, norm, g });
    }
    let (found, down, angle) = gravity_axis(mean_accel);
    let sign_ok = (mean_accel[axis] < 0.0) == negative;
    let tilt = angle_to(mean_accel, axis);
    if !sign_ok || tilt > MAX_TILT_DEG {
        return Err(OrientationError::Tilted {
            asked,
            found: super::fit::axis_label(found, down),
            angle,
            tilt,
            upside_down: !sign_ok,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Channel;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    const BOTH: [Sensor; 2] = [Sensor::Gyro, Sensor::Accel];

    /// 10 s at 100 Hz at rest with z up (gyro noise 0.001 rad/s, accel 0.02 m/s^2 per sample)
    /// and, if `turn`, a 0.5 s turn about x at 20 deg/s starting at 6 s.
    fn record(turn: bool) -> Record {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let g = Normal::new(0.0, 0.001).unwrap();
        let a = Normal::new(0.0, 0.02).unwrap();
        let n = 1000;
        let rate_x = |i: usize| {
            if turn && (600..650).contains(&i) {
                20f64.to_radians()
            } else {
                0.0
            }
        };
        let mut channels = Vec::new();
        for name in ["gx", "gy", "gz"] {
            let v = (0..n)
                .map(|i| g.sample(&mut rng) + if name == "gx" { rate_x(i) } else { 0.0 })
                .collect();
            channels.push(Channel::named(name, v));
        }
        // The turn tilts the board by 10 deg about x: gravity moves from z towards y.
        let tilt = |i: usize| {
            if turn && i >= 625 {
                10f64.to_radians()
            } else {
                0.0
            }
        };
        let comps = [
            |_: f64| 0.0,
            |t: f64| 9.81 * t.sin(),
            |t: f64| 9.81 * t.cos(),
        ];
        for (name, f) in ["ax", "ay", "az"].iter().zip(comps) {
            let v = (0..n).map(|i| f(tilt(i)) + a.sample(&mut rng)).collect();
            channels.push(Channel::named(*name, v));
        }
        Record {
            source: "test".into(),
            rate_hz: 100.0,
            channels,
        }
    }

    #[test]
    fn still_record_passes_and_a_turn_is_found_where_it_was() {
        assert_eq!(find_motion(&record(false), &BOTH).unwrap(), None);
        let m = find_motion(&record(true), &BOTH).unwrap().expect("motion");
        assert!((m.at_s - 6.0).abs() < 1.01, "{m}");
        // The 0.5 s at 20 deg/s lifts one window's gx mean by 10 deg/s = 0.17 rad/s, 50 times
        // its floor; the tilt moves ay by 1.7 m/s^2 in two half steps of 0.85, 42 times its
        // floor: gx is the worst.
        assert_eq!(m.channel, "gx", "{m}");
        // The accelerometer alone sees the tilt.
        let m = find_motion(&record(true), &[Sensor::Accel])
            .unwrap()
            .expect("tilt");
        assert_eq!(m.channel, "ay", "{m}");
        let short = Record {
            channels: vec![Channel::named("gx", vec![0.0; 150])],
            ..record(false)
        };
        assert_eq!(
            find_motion(&short, &BOTH).unwrap_err().to_string(),
            "1.5 s is too short to judge stillness: at least 3 s"
        );
    }

    #[test]
    fn orientation_is_checked_against_the_asked_axis() {
        let g = 9.80665;
        assert!(check_orientation([0.1, -0.2, 9.8], 2, false, g).is_ok());
        assert!(check_orientation([-9.7, 0.3, 0.5], 0, true, g).is_ok());
        let err = check_orientation([0.0, 9.8, 0.2], 2, false, g)
            .unwrap_err()
            .to_string();
        assert!(err.contains("asked for +z up, but +y is up"), "{err}");
        let err = check_orientation([0.0, 0.0, -9.8], 2, false, g)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("-z is up") && err.contains("upside down"),
            "{err}"
        );
        // 25 deg tilt: too far.
        let t = 25f64.to_radians();
        assert!(check_orientation([9.8 * t.sin(), 0.0, 9.8 * t.cos()], 2, false, g).is_err());
        let err = check_orientation([0.0, 0.0, 1.0], 2, false, g).unwrap_err();
        assert!(matches!(err, OrientationError::NotG { .. }), "{err}");
        assert_eq!(gravity_axis([0.2, -9.8, 0.1]).0, 1);
    }
}

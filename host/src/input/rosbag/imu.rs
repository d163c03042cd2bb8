//! `sensor_msgs/Imu` (ROS 1) and `sensor_msgs/msg/Imu` (ROS 2) decoded by hand from their
//! message definitions, so no ROS install is needed. Both are
//!
//! ```text
//! std_msgs/Header header          ROS 1: uint32 seq, time stamp (uint32 secs, uint32 nsecs),
//!                                        string frame_id
//!                                 ROS 2: builtin_interfaces/Time stamp (int32 sec,
//!                                        uint32 nanosec), string frame_id
//! geometry_msgs/Quaternion orientation            float64 x, y, z, w
//! float64[9] orientation_covariance
//! geometry_msgs/Vector3 angular_velocity          float64 x, y, z (rad/s)
//! float64[9] angular_velocity_covariance
//! geometry_msgs/Vector3 linear_acceleration       float64 x, y, z (m/s^2)
//! float64[9] linear_acceleration_covariance
//! ```
//!
//! ROS 1 serialises these little-endian and packed, with strings as a u32 length and the
//! bytes (wiki.ros.org/msg, "Serialization"); ROS 2 uses CDR ([`super::cdr`]). The message
//! definition's own comment says a covariance whose first element is -1 marks its field as
//! not provided.

use super::cdr::Cdr;

/// The Imu message type's names in ROS 1 and ROS 2.
pub(super) const TYPE_NAMES: [&str; 2] = ["sensor_msgs/Imu", "sensor_msgs/msg/Imu"];

/// What the analysis takes from one Imu message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ImuMessage {
    /// The header stamp, ns since the epoch (0 when the publisher left it unset).
    pub stamp_ns: i64,
    /// Angular velocity, rad/s.
    pub gyro: [f64; 3],
    /// Linear acceleration, m/s^2.
    pub accel: [f64; 3],
    /// The angular velocity's covariance says it is not provided.
    pub gyro_absent: bool,
    /// The linear acceleration's covariance says it is not provided.
    pub accel_absent: bool,
}

/// The primitives an Imu is made of, in one serialisation.
trait Fields {
    /// The header's stamp in ns (ROS 1 reads the `seq` before it).
    fn stamp_ns(&mut self) -> Result<i64, String>;
    fn f64(&mut self, what: &str) -> Result<f64, String>;
    fn skip_string(&mut self, what: &str) -> Result<(), String>;
}

impl Fields for Cdr<'_> {
    fn stamp_ns(&mut self) -> Result<i64, String> {
        let sec = self.i32("header.stamp.sec")?;
        let nanosec = self.u32("header.stamp.nanosec")?;
        Ok(i64::from(sec) * 1_000_000_000 + i64::from(nanosec))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Cdr::f64(self, what)
    }
    fn skip_string(&mut self, what: &str) -> Result<(), String> {
        Cdr::skip_string(self, what)
    }
}

/// A cursor over a ROS 1 serialised message: little-endian, no padding.
struct Ros1<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Ros1<'_> {
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let bytes = self
            .bytes
            .get(self.at..self.at + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| self.short(what, self.at + N))?;
        self.at += N;
        Ok(bytes)
    }

    fn short(&self, what: &str, needed: usize) -> String {
        format!(
            "ROS 1 message ends at byte {} but {what} needs {needed}",
            self.bytes.len()
        )
    }

    fn u32(&mut self, what: &str) -> Result<u32, String> {
        self.take::<4>(what).map(u32::from_le_bytes)
    }
}

impl Fields for Ros1<'_> {
    fn stamp_ns(&mut self) -> Result<i64, String> {
        self.u32("header.seq")?;
        let secs = self.u32("header.stamp.secs")?;
        let nsecs = self.u32("header.stamp.nsecs")?;
        Ok(i64::from(secs) * 1_000_000_000 + i64::from(nsecs))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        self.take::<8>(what).map(f64::from_le_bytes)
    }
    fn skip_string(&mut self, what: &str) -> Result<(), String> {
        let len = self.u32(what)? as usize;
        let end = self.at.saturating_add(len);
        if end > self.bytes.len() {
            return Err(self.short(what, end));
        }
        self.at = end;
        Ok(())
    }
}

/// A ROS 1 serialised Imu.
pub(super) fn decode_ros1(bytes: &[u8]) -> Result<ImuMessage, String> {
    decode(&mut Ros1 { bytes, at: 0 })
}

/// A CDR-encoded (ROS 2) Imu.
pub(super) fn decode_cdr(bytes: &[u8]) -> Result<ImuMessage, String> {
    decode(&mut Cdr::new(bytes)?)
}

fn decode(fields: &mut impl Fields) -> Result<ImuMessage, String> {
    let stamp_ns = fields.stamp_ns()?;
    fields.skip_string("header.frame_id")?;
    skip(fields, 4 + 9, "orientation")?;
    let gyro = vector(fields, "angular_velocity")?;
    let gyro_absent = covariance_absent(fields, "angular_velocity_covariance")?;
    let accel = vector(fields, "linear_acceleration")?;
    let accel_absent = covariance_absent(fields, "linear_acceleration_covariance")?;
    Ok(ImuMessage {
        stamp_ns,
        gyro,
        accel,
        gyro_absent,
        accel_absent,
    })
}

fn skip(fields: &mut impl Fields, count: usize, what: &str) -> Result<(), String> {
    for _ in 0..count {
        fields.f64(what)?;
    }
    Ok(())
}

fn vector(fields: &mut impl Fields, what: &str) -> Result<[f64; 3], String> {
    Ok([fields.f64(what)?, fields.f64(what)?, fields.f64(what)?])
}

/// Reads a 3x3 covariance; true when its first element is -1 (the field is not provided).
fn covariance_absent(fields: &mut impl Fields, what: &str) -> Result<bool, String> {
    let first = fields.f64(what)?;
    skip(fields, 8, what)?;
    Ok(first == -1.0)
}

/// Serialisers of an Imu, the inverse of the decoders, for the bag writers ([`super::write`]).
pub(super) mod encode {
    /// One message's content for the encoders.
    pub struct Imu<'a> {
        pub seq: u32,
        pub stamp_ns: i64,
        pub frame_id: &'a str,
        pub gyro: [f64; 3],
        pub accel: [f64; 3],
    }

    impl Imu<'_> {
        /// The float64 fields after the header: orientation not provided (-1), the two
        /// vectors with zero covariances.
        fn floats(&self) -> Vec<f64> {
            let mut out = vec![0.0, 0.0, 0.0, 1.0, -1.0];
            out.extend([0.0; 8]);
            out.extend(self.gyro);
            out.extend([0.0; 9]);
            out.extend(self.accel);
            out.extend([0.0; 9]);
            out
        }

        fn secs(&self) -> (i64, u32) {
            (
                self.stamp_ns.div_euclid(1_000_000_000),
                self.stamp_ns.rem_euclid(1_000_000_000) as u32,
            )
        }
    }

    /// ROS 1 serialisation.
    pub fn ros1(imu: &Imu) -> Vec<u8> {
        let (secs, nsecs) = imu.secs();
        let mut out = Vec::new();
        out.extend(imu.seq.to_le_bytes());
        out.extend((secs as u32).to_le_bytes());
        out.extend(nsecs.to_le_bytes());
        out.extend((imu.frame_id.len() as u32).to_le_bytes());
        out.extend(imu.frame_id.as_bytes());
        imu.floats()
            .iter()
            .for_each(|f| out.extend(f.to_le_bytes()));
        out
    }

    /// CDR (classic, 8-byte alignment), little- or big-endian.
    pub fn cdr(imu: &Imu, little_endian: bool) -> Vec<u8> {
        let mut body: Vec<u8> = Vec::new();
        let word = |v: u32| {
            if little_endian {
                v.to_le_bytes()
            } else {
                v.to_be_bytes()
            }
        };
        let (secs, nsecs) = imu.secs();
        body.extend(word(secs as i32 as u32));
        body.extend(word(nsecs));
        body.extend(word(imu.frame_id.len() as u32 + 1));
        body.extend(imu.frame_id.as_bytes());
        body.push(0);
        for f in imu.floats() {
            body.resize(body.len().next_multiple_of(8), 0);
            body.extend(if little_endian {
                f.to_le_bytes()
            } else {
                f.to_be_bytes()
            });
        }
        let mut out = vec![0, u8::from(little_endian), 0, 0];
        out.extend(body);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> encode::Imu<'static> {
        encode::Imu {
            seq: 9,
            stamp_ns: 1_700_000_000_123_456_789,
            frame_id: "imu_link",
            gyro: [0.1, -0.2, 0.3],
            accel: [0.01, 0.02, 9.81],
        }
    }

    #[test]
    fn both_serialisations_decode_to_the_values_written() {
        let want = ImuMessage {
            stamp_ns: 1_700_000_000_123_456_789,
            gyro: [0.1, -0.2, 0.3],
            accel: [0.01, 0.02, 9.81],
            gyro_absent: false,
            accel_absent: false,
        };
        let imu = sample();
        assert_eq!(decode_ros1(&encode::ros1(&imu)).unwrap(), want);
        assert_eq!(decode_cdr(&encode::cdr(&imu, true)).unwrap(), want);
        assert_eq!(decode_cdr(&encode::cdr(&imu, false)).unwrap(), want);
        // An empty frame id moves the doubles' padding.
        let bare = encode::Imu {
            frame_id: "",
            ..sample()
        };
        assert_eq!(decode_cdr(&encode::cdr(&bare, true)).unwrap(), want);
    }

    #[test]
    fn truncated_messages_name_the_field() {
        let bytes = encode::ros1(&sample());
        let err = decode_ros1(&bytes[..bytes.len() - 80]).unwrap_err();
        assert!(err.contains("linear_acceleration"), "{err}");
        let bytes = encode::cdr(&sample(), true);
        let err = decode_cdr(&bytes[..10]).unwrap_err();
        assert!(err.contains("header.stamp.nanosec"), "{err}");
    }
}

//! The OMG CDR encoding ROS 2 serialises messages with (DDS-XTypes 1.3, 7.4; the RTPS 2.5
//! encapsulation identifiers, 10.5): a 4-byte encapsulation header names the byte order and
//! the CDR version, then each primitive sits at an offset (from the end of that header) that
//! is a multiple of its size, capped at 8 in classic CDR and at 4 in XCDR2.

/// A cursor over one CDR-encoded message.
pub(super) struct Cdr<'a> {
    body: &'a [u8],
    at: usize,
    little_endian: bool,
    /// The largest alignment a primitive takes: 8 (CDR) or 4 (XCDR2).
    max_align: usize,
}

impl<'a> Cdr<'a> {
    /// The message after its encapsulation header; an error names a header this reader does not
    /// know (a parameter list, whose members would need the type's member ids).
    pub(super) fn new(bytes: &'a [u8]) -> Result<Cdr<'a>, String> {
        let Some((header, body)) = bytes.split_first_chunk::<4>() else {
            return Err(format!(
                "{} bytes: too short for a CDR encapsulation header",
                bytes.len()
            ));
        };
        // RTPS 2.5 Table 10.3: CDR_BE 0x0000, CDR_LE 0x0001, PLAIN_CDR2_BE 0x0006,
        // PLAIN_CDR2_LE 0x0007, DELIMITED_CDR2_BE 0x0008, DELIMITED_CDR2_LE 0x0009.
        let (little_endian, max_align) = match [header[0], header[1]] {
            [0, 0] => (false, 8),
            [0, 1] => (true, 8),
            [0, 6] => (false, 4),
            [0, 7] => (true, 4),
            other => {
                return Err(format!(
                    "CDR encapsulation 0x{:02x}{:02x} is not plain CDR (little- or big-endian)",
                    other[0], other[1]
                ));
            }
        };
        Ok(Cdr {
            body,
            at: 0,
            little_endian,
            max_align,
        })
    }

    /// The next `N` bytes after aligning to `min(N, max_align)`.
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], String> {
        let align = N.min(self.max_align);
        let start = self.at.next_multiple_of(align);
        let bytes = self
            .body
            .get(start..start + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| self.short(what, start + N))?;
        self.at = start + N;
        Ok(bytes)
    }

    fn short(&self, what: &str, needed: usize) -> String {
        format!(
            "CDR message ends at byte {} but {what} needs {}",
            self.body.len() + 4,
            needed + 4
        )
    }

    pub(super) fn u32(&mut self, what: &str) -> Result<u32, String> {
        let b = self.take::<4>(what)?;
        Ok(if self.little_endian {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    pub(super) fn i32(&mut self, what: &str) -> Result<i32, String> {
        let b = self.take::<4>(what)?;
        Ok(if self.little_endian {
            i32::from_le_bytes(b)
        } else {
            i32::from_be_bytes(b)
        })
    }

    pub(super) fn f64(&mut self, what: &str) -> Result<f64, String> {
        let b = self.take::<8>(what)?;
        Ok(if self.little_endian {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }

    /// A string: a u32 length counting the terminating NUL, then the bytes. Only skipped past:
    /// the Imu's frame id names the sensor's frame, which the analysis does not use.
    pub(super) fn skip_string(&mut self, what: &str) -> Result<(), String> {
        let len = self.u32(what)? as usize;
        let end = self.at.saturating_add(len);
        if end > self.body.len() {
            return Err(self.short(what, end));
        }
        self.at = end;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_follows_the_encapsulation() {
        // Little-endian CDR: a u32 at 0, then an f64 aligned to 8 (4 bytes of padding).
        let mut le = vec![0, 1, 0, 0, 7, 0, 0, 0, 0xff, 0xff, 0xff, 0xff];
        le.extend(2.5f64.to_le_bytes());
        let mut c = Cdr::new(&le).unwrap();
        assert_eq!(c.u32("n").unwrap(), 7);
        assert_eq!(c.f64("x").unwrap(), 2.5);
        // Big-endian XCDR2: an f64 right after a u32 (alignment capped at 4).
        let mut be = vec![0, 6, 0, 0, 0, 0, 0, 7];
        be.extend(2.5f64.to_be_bytes());
        let mut c = Cdr::new(&be).unwrap();
        assert_eq!(c.u32("n").unwrap(), 7);
        assert_eq!(c.f64("x").unwrap(), 2.5);
    }

    #[test]
    fn short_and_unknown_inputs_say_what_is_missing() {
        assert!(Cdr::new(&[0, 1]).err().unwrap().contains("too short"));
        let err = Cdr::new(&[0, 3, 0, 0]).err().unwrap();
        assert!(err.contains("0x0003"), "{err}");
        let mut c = Cdr::new(&[0, 1, 0, 0, 1, 0]).unwrap();
        let err = c.u32("the stamp").unwrap_err();
        assert_eq!(err, "CDR message ends at byte 6 but the stamp needs 8");
        let mut c = Cdr::new(&[0, 1, 0, 0, 200, 0, 0, 0]).unwrap();
        assert!(c.skip_string("frame_id").is_err());
    }
}

//! The portable part of the imunoise firmware: everything that does not touch RP2040
//! peripherals, written against embedded-hal 1.0 traits so that it runs unchanged on the
//! board, on the host's virtual board and in tests. `no_std`, no allocation.
#![no_std]
#![forbid(unsafe_code)]
// Nothing on the data path may panic: errors are values sent to the other side.
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod acquire;
pub mod adxl345;
pub mod chip;
pub mod control;
pub mod driver;
pub mod itg3200;
pub mod recovery;
pub mod registers;
pub mod reply;
pub mod run_state;
pub mod sensor;
pub mod slot;
pub mod stream;
pub mod timing;

pub use control::{BoardConfig, Firmware};
pub use driver::BusClear;
pub use timing::Clock;

use protocol::FirmwareVersion;

/// This firmware's version, from the crate version (one source of truth: Cargo.toml).
pub const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u16(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: parse_u16(env!("CARGO_PKG_VERSION_MINOR")),
    patch: parse_u16(env!("CARGO_PKG_VERSION_PATCH")),
};

/// Decimal digits to u16 at compile time (a non-digit or overflow fails the build).
const fn parse_u16(digits: &str) -> u16 {
    let bytes = digits.as_bytes();
    assert!(!bytes.is_empty(), "empty version component");
    let mut value: u32 = 0;
    let mut i = 0;
    while i < bytes.len() {
        let d = bytes[i];
        assert!(d.is_ascii_digit(), "version component is not a number");
        value = value * 10 + (d - b'0') as u32;
        assert!(value <= u16::MAX as u32, "version component exceeds u16");
        i += 1;
    }
    value as u16
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;

    #[test]
    fn version_comes_from_cargo() {
        let text = format!(
            "{}.{}.{}",
            FIRMWARE_VERSION.major, FIRMWARE_VERSION.minor, FIRMWARE_VERSION.patch
        );
        assert_eq!(text, env!("CARGO_PKG_VERSION"));
        assert_eq!(parse_u16("65535"), u16::MAX);
        assert_eq!(parse_u16("007"), 7);
    }
}

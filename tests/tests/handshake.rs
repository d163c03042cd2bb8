//! The host refuses a board of another protocol version with a clear error, and accepts
//! one of its own.

use imunoise::link::handshake::{HandshakeError, accept_info};
use protocol::{DeviceInfo, DeviceMessage, FirmwareVersion, PROTOCOL_VERSION, SensorSettings};

fn info_body(protocol_version: u16) -> Vec<u8> {
    let info = DeviceInfo {
        protocol_version,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 0xE660_5838_4B2C_2A21,
        who_am_i: 0x68,
        settings: SensorSettings::default(),
        streaming: false,
        max_samples_per_batch: 32,
        reset_reason: protocol::ResetReason::Unknown,
        sensors: protocol::SensorList::default(),
    };
    postcard::to_allocvec(&DeviceMessage::Info(info)).unwrap()
}

#[test]
fn same_version_is_accepted() {
    let info = accept_info(&info_body(PROTOCOL_VERSION)).unwrap();
    assert_eq!(info.board_id, 0xE660_5838_4B2C_2A21);
    assert_eq!(info.settings, SensorSettings::default());
}

#[test]
fn newer_board_asks_to_update_the_host() {
    let err = accept_info(&info_body(PROTOCOL_VERSION + 1)).unwrap_err();
    assert!(
        matches!(err, HandshakeError::VersionMismatch { board, host, .. } if board == PROTOCOL_VERSION + 1 && host == PROTOCOL_VERSION)
    );
    let text = err.to_string();
    assert!(
        text.contains(&format!("board speaks version {}", PROTOCOL_VERSION + 1)),
        "{text}"
    );
    assert!(text.contains("update imunoise"), "{text}");
}

#[test]
fn older_board_asks_to_flash_the_firmware() {
    let err = accept_info(&info_body(PROTOCOL_VERSION - 1)).unwrap_err();
    assert!(err.to_string().contains("flash the firmware"), "{err}");
}

/// A future board's Info may carry fields this host does not know; the version is still
/// read and the mismatch reported (not a decoding error).
#[test]
fn future_layouts_still_report_the_version() {
    let mut body = vec![0u8]; // variant 0: Info
    body.extend_from_slice(&postcard::to_allocvec(&(PROTOCOL_VERSION + 7)).unwrap());
    body.extend_from_slice(&[0xFF, 0xFF, 0x01, 0x02]);
    assert!(matches!(
        accept_info(&body),
        Err(HandshakeError::VersionMismatch { board, .. }) if board == PROTOCOL_VERSION + 7
    ));
}

#[test]
fn other_messages_are_not_info() {
    let pong = postcard::to_allocvec(&DeviceMessage::Pong { seq: 1 }).unwrap();
    assert_eq!(accept_info(&pong), Err(HandshakeError::NotInfo));
    let mut truncated = info_body(PROTOCOL_VERSION);
    truncated.truncate(4);
    assert_eq!(
        accept_info(&truncated),
        Err(HandshakeError::Undecodable(PROTOCOL_VERSION))
    );
}

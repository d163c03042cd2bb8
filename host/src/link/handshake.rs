//! The first exchange with a board: ask for [`protocol::DeviceInfo`] and refuse to go on if
//! the board speaks another protocol version, with an error that says which side to update.

use protocol::{DeviceInfo, DeviceMessage, PROTOCOL_VERSION, peek_info_version};

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum HandshakeError {
    #[error(
        "protocol version mismatch: the board speaks version {board}, this imunoise speaks version {host}; {advice}"
    )]
    VersionMismatch {
        board: u16,
        host: u16,
        advice: &'static str,
    },
    #[error("the board's reply to get-info is not an info message")]
    NotInfo,
    #[error(
        "the board's info message does not decode, although its protocol version ({0}) matches"
    )]
    Undecodable(u16),
}

/// Check the body of the board's reply to get-info and return its info.
///
/// The version is read before the rest is decoded ([`peek_info_version`]), so a board of any
/// protocol version gets a clear mismatch error rather than a decoding failure.
pub fn accept_info(body: &[u8]) -> Result<DeviceInfo, HandshakeError> {
    let board = peek_info_version(body).ok_or(HandshakeError::NotInfo)?;
    if board != PROTOCOL_VERSION {
        return Err(HandshakeError::VersionMismatch {
            board,
            host: PROTOCOL_VERSION,
            advice: if board > PROTOCOL_VERSION {
                "update imunoise (the host)"
            } else {
                "flash the firmware that matches this imunoise"
            },
        });
    }
    match postcard::from_bytes::<DeviceMessage>(body) {
        Ok(DeviceMessage::Info(info)) => Ok(info),
        Ok(_) => Err(HandshakeError::NotInfo),
        Err(_) => Err(HandshakeError::Undecodable(board)),
    }
}

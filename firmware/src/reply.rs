//! What the board sends besides samples ([`Reply`], small enough to wait in a queue for the
//! link), and how any message leaves as a numbered frame ([`send`]).

use protocol::frame::{MAX_WIRE_LEN, encode};
use protocol::{DeviceInfo, DeviceMessage, ErrorCode, Status};

/// Every message except sample batches: small, so a few can wait for the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reply {
    Info(DeviceInfo),
    Ack {
        seq: u16,
    },
    Nack {
        seq: u16,
        error: ErrorCode,
    },
    Status(Status),
    Pong {
        seq: u16,
    },
    /// Sensor `sensor`'s run ended with `error`.
    Fault {
        sensor: u8,
        error: ErrorCode,
    },
    Recovered {
        sensor: u8,
        attempts: u16,
        resumed_at_index: u64,
    },
}

impl From<Reply> for DeviceMessage {
    fn from(r: Reply) -> Self {
        match r {
            Reply::Info(i) => DeviceMessage::Info(i),
            Reply::Ack { seq } => DeviceMessage::Ack { seq },
            Reply::Nack { seq, error } => DeviceMessage::Nack { seq, error },
            Reply::Status(s) => DeviceMessage::Status(s),
            Reply::Pong { seq } => DeviceMessage::Pong { seq },
            Reply::Fault { sensor, error } => DeviceMessage::fault_of(sensor, error),
            Reply::Recovered {
                sensor,
                attempts,
                resumed_at_index,
            } => DeviceMessage::recovered_of(sensor, attempts, resumed_at_index),
        }
    }
}

/// Encode one message as a frame numbered `counter` ([`protocol::DeviceFrame`]) and offer it
/// to the link; the number is used up only if the link takes the frame, so a jump in the
/// numbers the host sees is a frame lost after it left the board.
pub fn send(
    out: &mut impl FnMut(&[u8]) -> bool,
    counter: &mut u32,
    message: &DeviceMessage,
) -> bool {
    let mut buf = [0u8; MAX_WIRE_LEN];
    match encode(&(message, *counter), &mut buf) {
        Ok(len) => {
            let taken = out(&buf[..len]);
            if taken {
                *counter = counter.wrapping_add(1);
            }
            taken
        }
        // Cannot happen for our messages (a test checks the largest batch fits).
        Err(_) => false,
    }
}

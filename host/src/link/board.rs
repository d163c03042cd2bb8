//! Commanding a board over any [`Link`]: the handshake (info and protocol version), configure,
//! and the start and stop of a stream, each waiting for its ack with a timeout.
//!
//! The start of a stream asks for the board's info again right before `Start`: the capture
//! file then begins with an `Info` that carries the settings actually in force, which is
//! what gives the samples their meaning when the file is decoded later.

use super::Link;
use super::handshake::{HandshakeError, accept_info};
use protocol::frame::{self, FrameDecoder, MAX_WIRE_LEN};
use protocol::{Command, DeviceInfo, DeviceMessage, ErrorCode, Request, SensorSettings, Status};
use std::time::{Duration, Instant};

/// How long a board may take to answer a command.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(3);

#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    #[error(
        "{link}: no answer to {command} within {} s (is it an imunoise board, and not busy with another program?)",
        REPLY_TIMEOUT.as_secs()
    )]
    Timeout { link: String, command: &'static str },
    #[error("{link}: {source}")]
    Handshake {
        link: String,
        source: HandshakeError,
    },
    #[error("{link} refused {command}: {error}")]
    Refused {
        link: String,
        command: &'static str,
        error: ErrorCode,
    },
    #[error("{link}: {source}")]
    Io {
        link: String,
        source: std::io::Error,
    },
}

/// A board on a link, with the sequence numbers of the commands sent to it.
pub struct Board<'a> {
    link: &'a mut dyn Link,
    seq: u16,
    decoder: FrameDecoder,
}

impl<'a> Board<'a> {
    pub fn new(link: &'a mut dyn Link) -> Self {
        Board {
            link,
            seq: 0,
            decoder: FrameDecoder::new(),
        }
    }

    /// Ask for the board's info and check its protocol version.
    pub fn handshake(&mut self) -> Result<DeviceInfo, BoardError> {
        self.send(Command::GetInfo)?;
        let link = self.link.describe();
        let mut found = None;
        self.wait(|body| match accept_info(body) {
            Ok(info) => {
                found = Some(Ok(info));
                true
            }
            Err(HandshakeError::NotInfo) => false,
            Err(e) => {
                found = Some(Err(e));
                true
            }
        })?;
        match found {
            Some(Ok(info)) => Ok(info),
            Some(Err(source)) => Err(BoardError::Handshake { link, source }),
            None => Err(BoardError::Timeout {
                link,
                command: "get-info",
            }),
        }
    }

    /// Configure the sensor (the board must not be streaming).
    pub fn configure(&mut self, settings: SensorSettings) -> Result<(), BoardError> {
        self.command(Command::Configure(settings), "configure")
    }

    /// Stop streaming; a board that was not streaming is fine.
    pub fn stop(&mut self) -> Result<(), BoardError> {
        match self.command(Command::Stop, "stop") {
            Err(BoardError::Refused {
                error: ErrorCode::NotStreaming,
                ..
            }) => Ok(()),
            other => other,
        }
    }

    /// Ask for the board's counters (samples acquired, lost, dropped; errors).
    pub fn status(&mut self) -> Result<Status, BoardError> {
        self.send(Command::GetStatus)?;
        let mut found = None;
        self.wait(|body| match postcard::from_bytes::<DeviceMessage>(body) {
            Ok(DeviceMessage::Status(s)) => {
                found = Some(s);
                true
            }
            _ => false,
        })?;
        found.ok_or_else(|| BoardError::Timeout {
            link: self.link.describe(),
            command: "get status",
        })
    }

    /// Ask for info and start streaming, without reading the replies: the capture loop
    /// records them (the file must begin with the board's `Info`).
    pub fn begin_stream(&mut self) -> Result<(), BoardError> {
        self.send(Command::GetInfo)?;
        self.send(Command::Start).map(|_| ())
    }

    /// Send a command and wait for its ack.
    pub fn command(&mut self, command: Command, name: &'static str) -> Result<(), BoardError> {
        let seq = self.send(command)?;
        let mut outcome = None;
        self.wait(|body| match postcard::from_bytes::<DeviceMessage>(body) {
            Ok(DeviceMessage::Ack { seq: s }) if s == seq => {
                outcome = Some(Ok(()));
                true
            }
            Ok(DeviceMessage::Nack { seq: s, error }) if s == seq => {
                outcome = Some(Err(error));
                true
            }
            _ => false,
        })?;
        let link = self.link.describe();
        match outcome {
            Some(Ok(())) => Ok(()),
            Some(Err(error)) => Err(BoardError::Refused {
                link,
                command: name,
                error,
            }),
            None => Err(BoardError::Timeout {
                link,
                command: name,
            }),
        }
    }

    fn send(&mut self, command: Command) -> Result<u16, BoardError> {
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_WIRE_LEN];
        let request = Request {
            seq: self.seq,
            command,
        };
        // A request is a few bytes: it always fits a frame.
        let n = frame::encode(&request, &mut buf).unwrap_or(0);
        self.link
            .write_all(&buf[..n])
            .map_err(|source| BoardError::Io {
                link: self.link.describe(),
                source,
            })?;
        Ok(self.seq)
    }

    /// Read frames until `done` accepts one or the reply timeout passes.
    fn wait(&mut self, mut done: impl FnMut(&[u8]) -> bool) -> Result<(), BoardError> {
        let deadline = Instant::now() + REPLY_TIMEOUT;
        let mut buf = [0u8; 4096];
        while Instant::now() < deadline {
            let n = self
                .link
                .read(&mut buf, Duration::from_millis(50))
                .map_err(|source| BoardError::Io {
                    link: self.link.describe(),
                    source,
                })?;
            for &byte in &buf[..n] {
                if let Some(Ok(body)) = self.decoder.push(byte)
                    && done(body)
                {
                    return Ok(());
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::virtual_board::{Speed, VirtualBoard};
    use crate::sim::imu::ImuModel;

    #[test]
    fn handshake_configure_and_refusals_on_the_virtual_board() {
        let mut vb = VirtualBoard::new(ImuModel::default(), 1, 7, Speed::Max).unwrap();
        let mut board = Board::new(&mut vb);
        let info = board.handshake().unwrap();
        assert_eq!(info.board_id, 7);
        let s = SensorSettings::for_rate_and_bandwidth(200.0, 42.0).unwrap();
        board.configure(s).unwrap();
        board.stop().unwrap(); // not streaming: fine
        // 8 kHz output is beyond what the firmware drains over 400 kHz I2C.
        let fast = SensorSettings::for_rate_and_bandwidth(8000.0, 256.0).unwrap();
        let err = board.configure(fast).unwrap_err().to_string();
        assert!(
            err.starts_with("the virtual board (--port sim) refused configure:"),
            "{err}"
        );
    }

    /// A link that never answers.
    struct Silent;
    impl Link for Silent {
        fn read(&mut self, _: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
            std::thread::sleep(timeout.min(Duration::from_millis(5)));
            Ok(0)
        }
        fn write_all(&mut self, _: &[u8]) -> std::io::Result<()> {
            Ok(())
        }
        fn describe(&self) -> String {
            "/dev/silent".into()
        }
    }

    #[test]
    fn a_silent_port_times_out_with_a_clear_error() {
        let mut link = Silent;
        let err = Board::new(&mut link).handshake().unwrap_err().to_string();
        assert!(
            err.starts_with("/dev/silent: no answer to get-info within 3 s"),
            "{err}"
        );
    }
}

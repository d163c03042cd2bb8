//! The serial transport: the board is a USB CDC serial port (firmware/board: VID:PID
//! 16c0:27dd, manufacturer "imunoise", product "imunoise MPU-6050 logger", serial number =
//! flash unique id). Listing ports shows USB vendor/product where the OS gives them and
//! recognises our board by its product string: 16c0:27dd is a VID:PID pair shared by many
//! CDC-ACM devices (V-USB's free IDs), so the pair alone names no device.

use std::io::{Read, Write};
use std::time::Duration;

/// Our board's USB vendor and product ids: a pair shared by CDC-ACM devices (module docs),
/// so a port is ours only if its product string says so too.
pub const BOARD_VID_PID: (u16, u16) = (0x16c0, 0x27dd);
/// Our board's USB product string.
pub const BOARD_PRODUCT: &str = "imunoise MPU-6050 logger";

/// A serial port the OS lists.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PortInfo {
    pub name: String,
    /// "usb", "pci", "bluetooth" or "unknown".
    pub kind: &'static str,
    pub vid: Option<u16>,
    pub pid: Option<u16>,
    pub manufacturer: Option<String>,
    pub product: Option<String>,
    pub serial_number: Option<String>,
    /// Our board, by its product string (the VID:PID pair is shared).
    pub imunoise_board: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum SerialError {
    #[error("listing serial ports: {0}")]
    List(String),
    #[error(
        "{port}: {message} (is the board plugged in? `imunoise ports` lists the ports; on Linux your user may need the dialout group)"
    )]
    Open { port: String, message: String },
    #[error("{port}: {source}")]
    Io {
        port: String,
        source: std::io::Error,
    },
}

/// The ports the OS knows, ours first.
pub fn list_ports() -> Result<Vec<PortInfo>, SerialError> {
    let ports = serialport::available_ports().map_err(|e| SerialError::List(e.to_string()))?;
    let mut out: Vec<PortInfo> = ports
        .into_iter()
        .map(|p| match p.port_type {
            serialport::SerialPortType::UsbPort(usb) => {
                let ours = usb.product.as_deref() == Some(BOARD_PRODUCT);
                PortInfo {
                    name: p.port_name,
                    kind: "usb",
                    vid: Some(usb.vid),
                    pid: Some(usb.pid),
                    manufacturer: usb.manufacturer,
                    product: usb.product,
                    serial_number: usb.serial_number,
                    imunoise_board: ours,
                }
            }
            other => PortInfo {
                name: p.port_name,
                kind: match other {
                    serialport::SerialPortType::PciPort => "pci",
                    serialport::SerialPortType::BluetoothPort => "bluetooth",
                    _ => "unknown",
                },
                vid: None,
                pid: None,
                manufacturer: None,
                product: None,
                serial_number: None,
                imunoise_board: false,
            },
        })
        .collect();
    out.sort_by_key(|p| (!p.imunoise_board, p.name.clone()));
    Ok(out)
}

/// An open serial port.
pub struct SerialLink {
    name: String,
    port: Box<dyn serialport::SerialPort>,
}

impl SerialLink {
    /// Open `name` (e.g. /dev/ttyACM0, COM3, or a pseudo-terminal). The baud rate is
    /// irrelevant to USB CDC but set for the benefit of real UARTs and pty bridges.
    pub fn open(name: &str) -> Result<SerialLink, SerialError> {
        let port = serialport::new(name, 115_200)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| SerialError::Open {
                port: name.to_string(),
                message: e.to_string(),
            })?;
        Ok(SerialLink {
            name: name.to_string(),
            port,
        })
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Read what is there, waiting at most `timeout`; 0 bytes on timeout. A vanished device
    /// is an error naming the port.
    pub fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, SerialError> {
        self.port
            .set_timeout(timeout)
            .map_err(|e| self.io(std::io::Error::other(e.to_string())))?;
        match self.port.read(buf) {
            Ok(0) => Err(self.io(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the device closed the port (unplugged?)",
            ))),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
            Err(e) => Err(self.io(e)),
        }
    }

    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), SerialError> {
        self.port
            .write_all(bytes)
            .and_then(|()| self.port.flush())
            .map_err(|e| self.io(e))
    }

    fn io(&self, source: std::io::Error) -> SerialError {
        SerialError::Io {
            port: self.name.clone(),
            source,
        }
    }
}

impl super::Link for SerialLink {
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        SerialLink::read(self, buf, timeout).map_err(std::io::Error::other)
    }

    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        SerialLink::write_all(self, bytes).map_err(std::io::Error::other)
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_port_is_a_clear_error() {
        let Err(err) = SerialLink::open("/dev/imunoise-no-such-port") else {
            panic!("opened a port that does not exist");
        };
        let text = err.to_string();
        assert!(text.starts_with("/dev/imunoise-no-such-port: "), "{text}");
        assert!(text.contains("imunoise ports"), "{text}");
    }

    #[test]
    fn listing_does_not_fail() {
        // Containers may have no serial ports at all; listing must still work.
        let ports = list_ports().unwrap();
        assert!(ports.iter().all(|p| !p.name.is_empty()));
    }
}

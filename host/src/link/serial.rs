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
///
/// **Reconnecting.** A board that reboots (its watchdog, a brown-out) leaves the USB bus and
/// comes back: the port vanishes and reappears, often under the same name, sometimes under
/// another. With [`SerialLink::reconnect_within`], a port that fails is looked for again —
/// by its USB serial number (the board id) if it had one, else by its name — every 200 ms;
/// meanwhile reads find nothing and writes go nowhere, so the capture loop sees silence and
/// its watcher starts the board again once it is back ([`super::keepalive`]). Only when the
/// port stays away longer than the window is the failure an error.
pub struct SerialLink {
    name: String,
    port: Option<Box<dyn serialport::SerialPort>>,
    /// The USB serial number of the port as first opened.
    usb_serial: Option<String>,
    reconnect_window: Option<Duration>,
    /// When the port failed, and how.
    lost: Option<(std::time::Instant, String)>,
    last_attempt: Option<std::time::Instant>,
    reconnects: u32,
}

/// How often a vanished port is looked for.
const RECONNECT_POLL: Duration = Duration::from_millis(200);

impl SerialLink {
    /// Open `name` (e.g. /dev/ttyACM0, COM3, or a pseudo-terminal). The baud rate is
    /// irrelevant to USB CDC but set for the benefit of real UARTs and pty bridges.
    pub fn open(name: &str) -> Result<SerialLink, SerialError> {
        let port = open_port(name).map_err(|e| SerialError::Open {
            port: name.to_string(),
            message: e.to_string(),
        })?;
        let usb_serial = list_ports().ok().and_then(|ports| {
            ports
                .into_iter()
                .find(|p| p.name == name)
                .and_then(|p| p.serial_number)
        });
        Ok(SerialLink {
            name: name.to_string(),
            port: Some(port),
            usb_serial,
            reconnect_window: None,
            lost: None,
            last_attempt: None,
            reconnects: 0,
        })
    }

    /// Ride through the port vanishing for up to `window` (see the type's docs).
    pub fn reconnect_within(mut self, window: Duration) -> Self {
        self.reconnect_window = Some(window);
        self
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Times the port vanished and was found again.
    pub fn reconnects(&self) -> u32 {
        self.reconnects
    }

    /// Read what is there, waiting at most `timeout`; 0 bytes on timeout (or while a
    /// vanished port is looked for). A vanished device is an error naming the port.
    pub fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, SerialError> {
        let Some(port) = self.port.as_mut() else {
            self.look_for_port(timeout)?;
            return Ok(0);
        };
        let result = port
            .set_timeout(timeout)
            .map_err(|e| std::io::Error::other(e.to_string()))
            .and_then(|()| match port.read(buf) {
                Ok(0) => Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "the device closed the port (unplugged?)",
                )),
                Ok(n) => Ok(n),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
                Err(e) => Err(e),
            });
        result.or_else(|e| self.failed(e).map(|()| 0))
    }

    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), SerialError> {
        let Some(port) = self.port.as_mut() else {
            // Nobody to send to: the watcher sends again once the board is back.
            return self.look_for_port(Duration::ZERO);
        };
        let result = port.write_all(bytes).and_then(|()| port.flush());
        result.or_else(|e| self.failed(e))
    }

    /// The port failed with `error`: an error, or (reconnecting) the start of the search.
    fn failed(&mut self, error: std::io::Error) -> Result<(), SerialError> {
        if self.reconnect_window.is_none() {
            return Err(self.io(error));
        }
        self.port = None;
        self.lost = Some((std::time::Instant::now(), error.to_string()));
        Ok(())
    }

    /// One look for the vanished port (at most every [`RECONNECT_POLL`]), waiting up to
    /// `timeout` first; an error once the window has passed.
    fn look_for_port(&mut self, timeout: Duration) -> Result<(), SerialError> {
        let (since, reason) = self.lost.clone().unwrap_or_else(|| {
            (
                std::time::Instant::now(),
                "the port is not open".to_string(),
            )
        });
        let window = self.reconnect_window.unwrap_or_default();
        if self
            .last_attempt
            .is_some_and(|t| t.elapsed() < RECONNECT_POLL)
        {
            std::thread::sleep(timeout.min(RECONNECT_POLL));
        }
        self.last_attempt = Some(std::time::Instant::now());
        let name = self
            .usb_serial
            .as_ref()
            .and_then(|serial| {
                list_ports()
                    .ok()?
                    .into_iter()
                    .find(|p| p.serial_number.as_ref() == Some(serial) && p.kind == "usb")
            })
            .map_or_else(|| self.name.clone(), |p| p.name);
        if let Ok(port) = open_port(&name) {
            self.port = Some(port);
            self.name = name;
            self.lost = None;
            self.reconnects += 1;
            return Ok(());
        }
        if since.elapsed() > window {
            return Err(self.io(std::io::Error::other(format!(
                "{reason}; not back after {} s",
                window.as_secs()
            ))));
        }
        Ok(())
    }

    fn io(&self, source: std::io::Error) -> SerialError {
        SerialError::Io {
            port: self.name.clone(),
            source,
        }
    }
}

fn open_port(name: &str) -> serialport::Result<Box<dyn serialport::SerialPort>> {
    serialport::new(name, 115_200)
        .timeout(Duration::from_millis(100))
        .open()
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

    /// A port that vanishes and comes back (a pseudo-terminal whose master closes, then a
    /// new one behind the same name) is found again; reads meanwhile find nothing; one that
    /// stays away is an error once the window has passed.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_vanished_port_is_found_again() {
        use nix::pty::openpty;
        use nix::unistd::{ttyname, write};
        use std::time::Instant;
        let dir = tempfile::tempdir().unwrap();
        let name = dir.path().join("board");
        let pty = || {
            let p = openpty(None, None).unwrap();
            let path = ttyname(&p.slave).unwrap();
            (p, path)
        };
        let point = |target: &std::path::Path| {
            let _ = std::fs::remove_file(&name);
            std::os::unix::fs::symlink(target, &name).unwrap();
        };
        let (first, path) = pty();
        point(&path);
        let mut link = SerialLink::open(name.to_str().unwrap())
            .unwrap()
            .reconnect_within(Duration::from_secs(2));
        let mut buf = [0u8; 16];
        write(&first.master, b"abc").unwrap();
        assert_eq!(link.read(&mut buf, Duration::from_millis(500)).unwrap(), 3);
        // The board goes away: reads find nothing, writes go nowhere, no error yet.
        drop(first);
        assert_eq!(link.read(&mut buf, Duration::from_millis(50)).unwrap(), 0);
        link.write_all(b"lost").unwrap();
        // It comes back behind the same name.
        let (second, path) = pty();
        point(&path);
        let deadline = Instant::now() + Duration::from_secs(2);
        while link.reconnects() == 0 && Instant::now() < deadline {
            assert_eq!(link.read(&mut buf, Duration::from_millis(50)).unwrap(), 0);
        }
        assert_eq!(link.reconnects(), 1);
        write(&second.master, b"xyz").unwrap();
        assert_eq!(link.read(&mut buf, Duration::from_millis(500)).unwrap(), 3);
        assert_eq!(&buf[..3], b"xyz");
        // Gone for good: an error naming the port once the window has passed.
        drop(second);
        let _ = std::fs::remove_file(&name);
        let started = Instant::now();
        let err = loop {
            match link.read(&mut buf, Duration::from_millis(50)) {
                Ok(n) => assert_eq!(n, 0),
                Err(e) => break e,
            }
            assert!(started.elapsed() < Duration::from_secs(5), "never gave up");
        };
        assert!(started.elapsed() >= Duration::from_secs(2));
        let text = err.to_string();
        assert!(text.starts_with(name.to_str().unwrap()), "{text}");
        assert!(text.contains("not back after 2 s"), "{text}");
    }

    #[test]
    fn listing_does_not_fail() {
        // Containers may have no serial ports at all; listing must still work.
        let ports = list_ports().unwrap();
        assert!(ports.iter().all(|p| !p.name.is_empty()));
    }
}

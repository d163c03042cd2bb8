//! The USB side of the link: whole frames into a ring buffer, the ring into the CDC port as
//! fast as the host reads. A frame that does not fit is refused (the firmware then drops and
//! counts a sample batch, or keeps a reply for later), so a host that stops reading never
//! blocks acquisition.

use usb_device::bus::UsbBus;
use usbd_serial::SerialPort;

/// 4 KiB: about 130 ms of 1 kHz samples, enough to ride out a host's scheduling hiccups.
const TX_CAPACITY: usize = 4096;

pub struct TxQueue {
    ring: heapless::Deque<u8, TX_CAPACITY>,
}

impl TxQueue {
    pub fn new() -> Self {
        TxQueue {
            ring: heapless::Deque::new(),
        }
    }

    /// Queue a whole frame, or refuse it whole.
    /// Forget what is queued (the host is gone).
    pub fn clear(&mut self) {
        self.ring.clear();
    }

    pub fn push_frame(&mut self, frame: &[u8]) -> bool {
        if TX_CAPACITY - self.ring.len() < frame.len() {
            return false;
        }
        for &b in frame {
            // Cannot fail: room checked above.
            let _ = self.ring.push_back(b);
        }
        true
    }

    /// Hand the CDC class what it takes now (it buffers a packet or two); never waits.
    pub fn write_to<B: UsbBus>(&mut self, serial: &mut SerialPort<'_, B>) {
        while !self.ring.is_empty() {
            let (head, _) = self.ring.as_slices();
            match serial.write(head) {
                Ok(n) if n > 0 => {
                    for _ in 0..n {
                        self.ring.pop_front();
                    }
                }
                _ => return,
            }
        }
    }
}

/// A u64 as 16 hex digits (the USB serial number string).
pub fn hex16(v: u64) -> heapless::String<16> {
    let mut s = heapless::String::new();
    for shift in (0..16).rev() {
        let digit = ((v >> (shift * 4)) & 0xF) as u8;
        let c = if digit < 10 {
            b'0' + digit
        } else {
            b'a' + digit - 10
        };
        let _ = s.push(char::from(c));
    }
    s
}

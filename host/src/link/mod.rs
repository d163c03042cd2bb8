//! Talking to a board: the byte transport ([`transport::Link`]) and its sources (a replayed
//! capture file now; the serial port and the virtual board join here), the handshake, and
//! exact sample accounting (see DESIGN.md, the sample's journey).

pub mod accounting;
pub mod board;
pub mod handshake;
pub mod replay;
pub mod serial;
pub mod transport;
pub mod virtual_board;

pub use transport::Link;

//! Talking to a board: the byte transport ([`transport::Link`]) and its sources (a serial
//! port, the virtual board, a replayed capture file), opening a port by name and starting a
//! board on it ([`setup`]) with each of its sensors set from one request ([`plan`]), the handshake and commands, the watcher that keeps a capture
//! going through board restarts ([`keepalive`]), and exact sample accounting.

pub mod accounting;
pub mod board;
pub mod handshake;
pub mod keepalive;
pub mod plan;
pub mod replay;
pub mod serial;
pub mod setup;
pub mod shared_bus;
pub mod transport;
pub mod virtual_board;

pub use setup::{Opened, PortSpec, open, start_board};
pub use transport::Link;

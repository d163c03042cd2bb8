//! Talking to a board: the handshake and exact sample accounting now; the serial transport
//! and the virtual board join here (see DESIGN.md, the sample's journey).

pub mod accounting;
pub mod handshake;
pub mod serial;
pub mod virtual_board;

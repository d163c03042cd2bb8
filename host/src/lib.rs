//! imunoise, the host side: talk to the board, keep sessions, analyse IMU noise.
//!
//! The CLI (`src/main.rs`) is a thin layer over this library; every command's work lives in
//! [`cli`], and the pieces it calls are the modules below.

pub mod analysis;
pub mod calibration;
pub mod capture;
pub mod cli;
pub mod input;
pub mod link;
pub mod model;
pub mod record;
pub mod recorder;
pub mod report;
pub mod sim;
pub mod store;

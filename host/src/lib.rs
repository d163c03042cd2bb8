//! imunoise, the host side: talk to the board, keep sessions, analyse IMU noise.
//!
//! The `imunoise` command (`src/main.rs` and its private `cli` module) is a thin layer over
//! this library: it parses arguments, draws progress and prints, and every workflow it runs
//! is one of the modules below. The library reads no stdin and prints nothing; built with
//! `--no-default-features` it needs none of the command line's dependencies.

pub mod analysis;
pub mod calibration;
pub mod capture;
pub mod experiment;
pub mod input;
pub mod link;
pub mod model;
pub mod record;
pub mod recorder;
pub mod report;
pub mod sim;
pub mod store;

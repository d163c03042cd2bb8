//! The simulated sensor: noise synthesis ([`noise`]), the die temperature ([`temperature`]),
//! the MPU-6050's digital low-pass filter ([`dlpf`]) and signal chain ([`chain`]), the six
//! axes ([`imu`]), narrow-band lines for tests ([`mod@line`]), the model file ([`model_file`]),
//! the simulated I2C chips ([`device`]), the boards' buses of them ([`boards`]), the GY-85's
//! pair at its outputs ([`gy85`]) and the line protocol for a bus model in another process
//! ([`bus_server`]).

pub mod boards;
pub mod bus_server;
pub mod chain;
pub mod device;
pub mod dlpf;
pub mod gy85;
pub mod imu;
pub mod line;
pub mod model_file;
pub mod noise;
pub mod temperature;

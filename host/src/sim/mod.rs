//! The simulated sensor: noise synthesis ([`noise`]), the die temperature ([`temperature`]),
//! the MPU-6050's digital low-pass filter ([`dlpf`]) and signal chain ([`chain`]), the six
//! axes ([`imu`]), the model file ([`model_file`]) and the simulated I2C device ([`device`]).

pub mod chain;
pub mod device;
pub mod dlpf;
pub mod imu;
pub mod model_file;
pub mod noise;
pub mod temperature;

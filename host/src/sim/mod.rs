//! The simulated sensor: noise synthesis (more of the MPU-6050's signal chain arrives with
//! the simulator issue).

pub mod noise;

//! Shared pieces of the integration tests: proptest strategies that generate every protocol
//! message with arbitrary field values, helpers to frame message streams, and the simulated
//! chips' models.

pub mod models;
pub mod strategies;
pub mod streams;

//! Shared pieces of the integration tests: proptest strategies that generate every protocol
//! message with arbitrary field values, and helpers to frame message streams.

pub mod strategies;
pub mod streams;

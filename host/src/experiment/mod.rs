//! Experiments: a board run through several sensor settings, each captured into the store
//! and analysed, and the results read against a published study ([`sweep`]).

pub mod sweep;

//! Command-line front ends.
pub mod sim;

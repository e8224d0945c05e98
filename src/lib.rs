//! omcl: Open-vocabulary Monte Carlo Localization.
pub mod geometry;
pub mod io;
pub mod raycast;
pub mod sim;

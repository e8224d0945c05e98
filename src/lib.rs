//! omcl: Open-vocabulary Monte Carlo Localization.
pub mod geometry;
pub mod io;
pub mod map;
pub mod raycast;
pub mod sim;

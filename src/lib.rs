//! omcl: Open-vocabulary Monte Carlo Localization.
pub mod eval;
pub mod geometry;
pub mod io;
pub mod raycast;
pub mod trajectory;

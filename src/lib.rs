//! omcl: Open-vocabulary Monte Carlo Localization.
pub mod encode;
pub mod eval;
pub mod experiment;
pub mod frame;
pub mod geometry;
pub mod io;
pub mod map;
pub mod mapping;
pub mod mcl;
pub mod morton;
pub mod plot;
pub mod raycast;
pub mod scene;
pub mod serve;
pub mod session;
pub mod sim;
pub mod trajectory;

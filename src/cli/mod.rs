//! Command-line front end: argument parsing and printing; the work is done by
//! the library.
pub mod eval;

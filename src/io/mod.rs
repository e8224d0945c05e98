//! Reading and writing files: parsing only, no math beyond it.
pub mod npy;
pub mod rgb;

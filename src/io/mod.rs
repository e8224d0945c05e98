//! Reading and writing files: parsing only, no math beyond it.
pub mod npy;
pub mod poses;

// Point clouds and RGB-D (helper `cloud`).
pub mod cloud;
pub mod kitti;
pub mod labels;
pub mod las;
pub mod ply;
pub mod rgbd;
pub mod scannet;

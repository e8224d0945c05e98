//! Reading and writing files: parsing only, no math beyond it.
pub mod atomic;
pub mod bounded_png;
pub mod bounded_read;
pub mod npy;
pub mod poses;
pub mod rgb;

// Point clouds and RGB-D (helper `cloud`).
pub mod cloud;
pub mod formats;
pub mod kitti;
pub mod kitti_camera;
pub mod labels;
pub mod las;
pub mod ply;
pub mod rgbd;
pub mod scannet;
pub mod sevenscenes;

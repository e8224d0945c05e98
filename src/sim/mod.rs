//! Synthetic worlds and sensors: the built-in benchmark and the embedded
//! default.
//!
//! Worlds are lists of labelled primitives ([`world`]) voxelized into
//! labelled surface cells; [`indoor`] builds indoor worlds of three kinds
//! (a corridor apartment, an open-plan home, an office floor of identical
//! offices), [`outdoor`] streets along a real driving path. Class embeddings with the similarity structure
//! of real CLIP text space come from [`embeddings`]; [`features`] turns label
//! images into per-pixel features that err the way open-vocabulary encoders
//! do. [`paths`] makes camera paths and odometry, [`render`] casts camera and
//! LiDAR rays through the project's ray caster, and [`files`] writes the
//! results in the real datasets' layouts.
mod building;
pub mod consistency;
mod corridor;
pub mod dataset;
pub mod embeddings;
pub mod features;
pub mod files;
mod furniture;
pub mod indoor;
pub mod lidar;
pub mod offices;
mod open_plan;
pub mod outdoor;
pub mod paths;
pub mod render;
pub mod world;

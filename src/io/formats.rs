//! Which reader a point-cloud file needs: the formats, told apart by the
//! user or by the file's extension, and the one dispatch to their readers.
//! Apart from [`super::cloud`] (the type every reader returns), so that the
//! readers depend on it and this file on them, without a cycle.

use std::path::Path;

use super::cloud::{CloudError, PointCloud};

/// On-disk point-cloud formats the readers understand.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFormat {
    /// PLY, any encoding ([`super::ply::read_ply`]).
    Ply,
    /// LAS or LAZ ([`super::las::read_las`]).
    Las,
    /// KITTI velodyne `.bin`, float32 x y z reflectance
    /// ([`super::kitti::read_velodyne_bin`]).
    KittiBin,
    /// ScanNet float32 x y z r g b `.bin`
    /// ([`super::scannet::read_scannet_xyzrgb_bin`]).
    ScannetBin,
}

impl CloudFormat {
    /// The format a file extension implies: `.ply`, `.las`, `.laz`. A `.bin`
    /// is ambiguous (KITTI or ScanNet) and gives `None`: say which.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Some(CloudFormat::Ply),
            "las" | "laz" => Some(CloudFormat::Las),
            _ => None,
        }
    }
}

/// Reads a point cloud in `format`, or in the format its extension implies.
pub fn read_point_cloud(
    path: &Path,
    format: Option<CloudFormat>,
) -> Result<PointCloud, CloudError> {
    if !path.exists() {
        return Err(CloudError::format(path, "no such file or folder"));
    }
    let format = format
        .or_else(|| CloudFormat::from_path(path))
        .ok_or_else(|| {
            CloudError::format(
                path,
                "cannot tell the format from the extension (.ply, .las, .laz); \
             for a .bin pass --format kitti (a Velodyne scan) or --format scannet",
            )
        })?;
    match format {
        CloudFormat::Ply => super::ply::read_ply(path),
        CloudFormat::Las => super::las::read_las(path),
        CloudFormat::KittiBin => super::kitti::read_velodyne_bin(path),
        CloudFormat::ScannetBin => super::scannet::read_scannet_xyzrgb_bin(path),
    }
}

//! The real ScanNet scan (mmdetection3d demo data) and bad input.
mod common;

use common::{assert_err_names, shared, truncated_copy};
use omcl::io::scannet::read_scannet_xyzrgb_bin;

#[test]
fn real_scan_reads() {
    let p = shared("pointclouds/scannet_scene0000_00_xyzrgb.bin");
    let c = read_scannet_xyzrgb_bin(&p).unwrap();
    assert_eq!(c.len(), 40_684);
    // An indoor room: a few metres across, floor to ceiling under 4 m.
    let mut lo = [f64::MAX; 3];
    let mut hi = [f64::MIN; 3];
    for p in &c.points {
        for (k, v) in p.iter().enumerate() {
            lo[k] = lo[k].min(*v);
            hi[k] = hi[k].max(*v);
        }
    }
    for (k, (l, h)) in lo.iter().zip(&hi).enumerate() {
        let extent = h - l;
        assert!(extent > 1.0 && extent < 15.0, "axis {k}: {extent}");
    }
    assert!(hi[2] - lo[2] < 4.0);
    let colors = c.colors.unwrap();
    let distinct: std::collections::HashSet<_> = colors.iter().collect();
    assert!(distinct.len() > 1000, "{}", distinct.len());
}

#[test]
fn bad_files_are_named() {
    let src = shared("pointclouds/scannet_scene0000_00_xyzrgb.bin");
    let d = tempfile::tempdir().unwrap();
    let p = truncated_copy(&src, d.path(), "cut.bin", 24 * 100 + 10);
    assert_err_names(
        read_scannet_xyzrgb_bin(&p).unwrap_err(),
        &p,
        "multiple of 24",
    );
    let mut bytes = std::fs::read(&src).unwrap();
    bytes.truncate(24 * 10);
    bytes[24 * 3 + 12..24 * 3 + 16].copy_from_slice(&300.0f32.to_le_bytes());
    let p = d.path().join("colour.bin");
    std::fs::write(&p, &bytes).unwrap();
    assert_err_names(read_scannet_xyzrgb_bin(&p).unwrap_err(), &p, "point 3");
    bytes[24 * 3 + 12..24 * 3 + 16].copy_from_slice(&3.0f32.to_le_bytes());
    bytes[24 * 5..24 * 5 + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let p = d.path().join("inf.bin");
    std::fs::write(&p, &bytes).unwrap();
    assert_err_names(read_scannet_xyzrgb_bin(&p).unwrap_err(), &p, "point 5");
    let p = d.path().join("empty.bin");
    std::fs::write(&p, b"").unwrap();
    assert_err_names(read_scannet_xyzrgb_bin(&p).unwrap_err(), &p, "empty");
}

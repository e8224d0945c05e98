//! LAS/LAZ reading against files written by laspy (tests/data/io) and real
//! files from laspy's and las-rs's test data (../shared/data/las).
mod common;

use std::collections::BTreeSet;

use common::{assert_err_names, expected_rows, local, shared, truncated_copy};
use omcl::io::las::read_las;

fn check_against_laspy(file: &str, with_rgb: bool) {
    let path = local(file);
    let c = read_las(&path).unwrap();
    let rows = expected_rows(&path);
    assert_eq!(c.len(), rows.len());
    let labels = c.labels.as_ref().unwrap();
    for (i, r) in rows.iter().enumerate() {
        for (k, (got, want)) in c.points[i].iter().zip(r).enumerate() {
            // Both apply scale and offset to the same integers.
            assert!((got - want).abs() < 1e-9, "point {i} axis {k}");
        }
        assert_eq!(labels[i], r[3] as u32, "class {i}");
        if with_rgb {
            let col = c.colors.as_ref().unwrap()[i];
            assert_eq!(col, [r[4] as u8, r[5] as u8, r[6] as u8], "colour {i}");
        }
    }
    assert_eq!(c.colors.is_some(), with_rgb);
}

#[test]
fn laspy_las_12_with_rgb() {
    check_against_laspy("laspy_pf3_rgb.las", true);
}

#[test]
fn laspy_laz_with_rgb() {
    check_against_laspy("laspy_pf3_rgb.laz", true);
}

#[test]
fn laspy_las_14_extended_classification() {
    check_against_laspy("laspy_14_pf6_extended_class.las", false);
    let c = read_las(&local("laspy_14_pf6_extended_class.las")).unwrap();
    assert!(c.labels.unwrap().iter().any(|&l| l > 31));
}

fn classes(c: &omcl::io::cloud::PointCloud) -> BTreeSet<u32> {
    c.labels.as_ref().unwrap().iter().copied().collect()
}

#[test]
fn real_files_all_read() {
    let dir = shared("las");
    let autzen = read_las(&dir.join("autzen_trim.laz")).unwrap();
    assert!(autzen.len() > 100_000, "{}", autzen.len());
    assert_eq!(classes(&autzen), BTreeSet::from([1, 2]));
    let col = autzen.colors.as_ref().unwrap();
    assert!(col.iter().any(|c| c != &col[0]), "colours all equal");
    let tile = read_las(&dir.join("32-1-472-150-76.laz")).unwrap();
    assert_eq!(tile.len(), 5658);
    assert_eq!(classes(&tile), BTreeSet::from([1, 2, 7, 9]));
    let veg = read_las(&dir.join("vegetation_1_3.las")).unwrap();
    assert!(classes(&veg).contains(&11));
    let v14 = read_las(&dir.join("test1_4.las")).unwrap();
    assert!(!v14.is_empty());
    // The LAZ decoder must reproduce the uncompressed file exactly.
    let las = read_las(&dir.join("simple.las")).unwrap();
    let laz = read_las(&dir.join("simple.laz")).unwrap();
    assert_eq!(las.len(), 1065);
    assert_eq!(las, laz);
    // Aerial data: coordinates are georeferenced and spread over the tile.
    let xs: Vec<f64> = autzen.points.iter().map(|p| p[0]).collect();
    let (lo, hi) = xs
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo > 10.0 && lo.abs() > 1000.0, "{lo} {hi}");
}

#[test]
fn truncated_and_corrupt_files_name_the_file() {
    let d = tempfile::tempdir().unwrap();
    let src = local("laspy_pf3_rgb.las");
    let len = std::fs::metadata(&src).unwrap().len() as usize;
    let p = truncated_copy(&src, d.path(), "cut.las", len - 100);
    assert_err_names(read_las(&p).unwrap_err(), &p, "truncated");
    let p = truncated_copy(&src, d.path(), "header_only.las", 100);
    assert_err_names(read_las(&p).unwrap_err(), &p, "not a LAS/LAZ file");
    let lz = local("laspy_pf3_rgb.laz");
    let len = std::fs::metadata(&lz).unwrap().len() as usize;
    let p = truncated_copy(&lz, d.path(), "cut.laz", len - 300);
    assert_err_names(read_las(&p).unwrap_err(), &p, "truncated or corrupt");
    let p = d.path().join("garbage.las");
    let mut garbage = b"LASF".to_vec();
    garbage.extend((0..600u32).map(|i| (i * 37 % 251) as u8));
    std::fs::write(&p, garbage).unwrap();
    assert_err_names(read_las(&p).unwrap_err(), &p, "not a LAS/LAZ file");
    // A valid header whose point-data offset (bytes 96..100) is corrupt.
    let mut bytes = std::fs::read(&src).unwrap();
    bytes[96..100].copy_from_slice(&1_000_000_000u32.to_le_bytes());
    let p = d.path().join("bad_offset.las");
    std::fs::write(&p, bytes).unwrap();
    assert_err_names(read_las(&p).unwrap_err(), &p, "beyond the end");
    // Scale factors (f64 at bytes 131, 139, 147) and offsets (155, 163,
    // 171) no survey has: each named (a zero x scale mapped every x to
    // the offset, a 1e300 one put points beyond any map).
    for (at, value, why) in [
        (131, 0.0, "x scale factor 0.0"),
        (139, 1e300, "y scale factor 1e300"),
        (147, f64::NAN, "z scale factor NaN"),
        (155, 1e300, "x offset 1e300"),
        (171, f64::INFINITY, "z offset inf"),
    ] {
        let mut bytes = std::fs::read(&src).unwrap();
        bytes[at..at + 8].copy_from_slice(&f64::to_le_bytes(value));
        let p = d.path().join(format!("header_{at}.las"));
        std::fs::write(&p, bytes).unwrap();
        assert_err_names(read_las(&p).unwrap_err(), &p, why);
    }
    let missing = d.path().join("missing.las");
    assert_err_names(read_las(&missing).unwrap_err(), &missing, "");
}

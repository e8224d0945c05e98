//! PLY reading against files written by plyfile (tests/data/io), writing,
//! and bad input.
mod common;

use common::{assert_err_names, expected_rows, local, truncated_copy};
use omcl::io::cloud::PointCloud;
use omcl::io::ply::{read_ply, write_ply};

fn check_xyz_rgb_label(file: &str) {
    let path = local(file);
    let c = read_ply(&path).unwrap();
    let rows = expected_rows(&path);
    assert_eq!(c.len(), rows.len());
    let colors = c.colors.as_ref().unwrap();
    let labels = c.labels.as_ref().unwrap();
    for (i, r) in rows.iter().enumerate() {
        // float32 in the file: both sides hold the same f32, exactly.
        assert_eq!(c.points[i], [r[0], r[1], r[2]], "point {i}");
        assert_eq!(
            colors[i],
            [r[3] as u8, r[4] as u8, r[5] as u8],
            "colour {i}"
        );
        assert_eq!(labels[i], r[6] as u32, "label {i}");
    }
    assert!(c.features.is_none());
}

#[test]
fn plyfile_ascii_with_colour_and_label() {
    check_xyz_rgb_label("plyfile_ascii_rgb_label.ply");
}

#[test]
fn plyfile_big_endian_with_extra_property_and_scalar_label() {
    check_xyz_rgb_label("plyfile_binbe_rgb_scalar_label.ply");
}

#[test]
fn plyfile_little_endian_double_class_features_and_faces() {
    let path = local("plyfile_binle_double_class_feat.ply");
    let c = read_ply(&path).unwrap();
    let rows = expected_rows(&path);
    assert_eq!(c.len(), rows.len());
    let (dim, f) = c.features.as_ref().unwrap();
    assert_eq!(*dim, 4);
    assert!(c.colors.is_none());
    for (i, r) in rows.iter().enumerate() {
        for (got, want) in c.points[i].iter().zip(r) {
            assert!((got - want).abs() <= 1e-12 * want.abs(), "point {i}");
        }
        assert_eq!(c.labels.as_ref().unwrap()[i], r[3] as u32);
        for (k, (got, want)) in f[i * 4..i * 4 + 4].iter().zip(&r[4..8]).enumerate() {
            assert!((*got as f64 - want).abs() < 1e-6, "feature {i},{k}");
        }
    }
}

#[test]
fn written_file_reads_back_and_overwrites_atomically() {
    let d = tempfile::tempdir().unwrap();
    let src = read_ply(&local("plyfile_ascii_rgb_label.ply")).unwrap();
    let out = d.path().join("map.ply");
    std::fs::write(&out, b"old contents").unwrap();
    write_ply(&out, &src).unwrap();
    assert_eq!(read_ply(&out).unwrap(), src);
    // A rejected cloud leaves the existing file untouched.
    let mut bad = src.clone();
    bad.points[3][0] = f64::NAN;
    assert!(write_ply(&out, &bad).is_err());
    assert_eq!(read_ply(&out).unwrap(), src);
    let names: Vec<_> = std::fs::read_dir(d.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "temporary file left behind");
}

#[test]
fn truncated_binary_names_file_and_vertex() {
    let d = tempfile::tempdir().unwrap();
    let src = local("plyfile_binle_double_class_feat.ply");
    let len = std::fs::metadata(&src).unwrap().len() as usize;
    // Drop the faces (2 x 13 bytes) and 20.5 vertex records (42 bytes each).
    let p = truncated_copy(&src, d.path(), "cut.ply", len - 2 * 13 - 20 * 42 - 21);
    let e = read_ply(&p).unwrap_err();
    assert_err_names(e, &p, "truncated");
}

#[test]
fn truncated_ascii_names_file() {
    let d = tempfile::tempdir().unwrap();
    let src = local("plyfile_ascii_rgb_label.ply");
    let text = std::fs::read_to_string(&src).unwrap();
    let keep = text.len()
        - text
            .lines()
            .rev()
            .take(5)
            .map(|l| l.len() + 1)
            .sum::<usize>();
    let p = truncated_copy(&src, d.path(), "cut_ascii.ply", keep);
    assert_err_names(read_ply(&p).unwrap_err(), &p, "truncated");
    // A record cut mid-line has too few numbers.
    let p = d.path().join("cut_line.ply");
    std::fs::write(&p, format!("{}1.5 2.5\n", &text[..keep])).unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "vertex 32");
}

#[test]
fn corrupt_header_and_garbage_name_file() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("bad_format.ply");
    std::fs::write(
        &p,
        b"ply\nformat binary_sideways 1.0\nelement vertex 1\nend_header\n",
    )
    .unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "header");
    let p = d.path().join("garbage.ply");
    std::fs::write(&p, [0x89u8, 0x50, 0x4e, 0x47, 0, 1, 2, 3, 255, 254]).unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "header");
    let p = d.path().join("no_z.ply");
    std::fs::write(
        &p,
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n",
    )
    .unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "'z'");
    let p = d.path().join("bad_number.ply");
    std::fs::write(
        &p,
        b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
          property float z\nend_header\n1 2 3\n1 zwei 3\n",
    )
    .unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "vertex 1");
    let missing = d.path().join("missing.ply");
    assert_err_names(read_ply(&missing).unwrap_err(), &missing, "");
}

#[test]
fn non_finite_points_name_file_and_index() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("nan.ply");
    std::fs::write(
        &p,
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
          property float z\nend_header\n1 2 3\n4 5 6\n7 nan 9\n",
    )
    .unwrap();
    // ply-rs-bw's ASCII grammar has no "nan": a parse error at the record.
    assert_err_names(read_ply(&p).unwrap_err(), &p, "vertex 2");
    // Binary infinity passes the parser and is caught by validation.
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n\
        property float y\nproperty float z\nend_header\n"
        .to_vec();
    for v in [0.0f32, 1.0, 2.0, f32::INFINITY, 0.0, 0.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let p = d.path().join("inf.ply");
    std::fs::write(&p, bytes).unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "point 1");
}

#[test]
fn empty_cloud_is_an_error() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("empty.ply");
    write_ply(&p, &PointCloud::default()).unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "empty");
}

#[test]
fn features_attach_from_npy_with_dimension_checks() {
    let d = tempfile::tempdir().unwrap();
    let mut c = read_ply(&local("plyfile_ascii_rgb_label.ply")).unwrap();
    let n = c.len();
    let ok = d.path().join("feat.npy");
    let data: Vec<f32> = (0..n * 3).map(|i| i as f32).collect();
    omcl::io::npy::write_npy(&ok, &[n, 3], &data).unwrap();
    c.attach_features_npy(&ok).unwrap();
    assert_eq!(c.features, Some((3, data)));
    let rows = d.path().join("wrong_rows.npy");
    omcl::io::npy::write_npy(&rows, &[n - 1, 3], &vec![0.0; (n - 1) * 3]).unwrap();
    assert_err_names(
        c.attach_features_npy(&rows).unwrap_err(),
        &rows,
        "feature rows",
    );
    let flat = d.path().join("flat.npy");
    omcl::io::npy::write_npy(&flat, &[n * 3], &vec![0.0; n * 3]).unwrap();
    assert_err_names(c.attach_features_npy(&flat).unwrap_err(), &flat, "2-D");
    let nan = d.path().join("nan.npy");
    let mut v = vec![0.0; n * 3];
    v[7] = f32::NAN;
    omcl::io::npy::write_npy(&nan, &[n, 3], &v).unwrap();
    assert_err_names(c.attach_features_npy(&nan).unwrap_err(), &nan, "point 2");
}

#[test]
fn format_dispatch_by_extension() {
    use omcl::io::formats::{CloudFormat, read_point_cloud};
    let ply = read_point_cloud(&local("plyfile_ascii_rgb_label.ply"), None).unwrap();
    assert_eq!(ply.len(), 37);
    let laz = read_point_cloud(&local("laspy_pf3_rgb.laz"), None).unwrap();
    assert_eq!(laz.len(), 53);
    // A .bin is KITTI's or ScanNet's: the reader asks which (a file that
    // is there; a path that is not is named as such).
    let d = tempfile::tempdir().unwrap();
    let bin = d.path().join("scan.bin");
    std::fs::write(&bin, [0u8; 16]).unwrap();
    assert_err_names(
        read_point_cloud(&bin, None).unwrap_err(),
        &bin,
        "kitti or scannet",
    );
    let gone = d.path().join("gone.bin");
    assert_err_names(
        read_point_cloud(&gone, None).unwrap_err(),
        &gone,
        "no such file or folder",
    );
    // An explicit format wins over the extension.
    let e = read_point_cloud(&local("laspy_pf3_rgb.las"), Some(CloudFormat::Ply)).unwrap_err();
    assert_err_names(e, &local("laspy_pf3_rgb.las"), "header");
}

#[test]
fn windows_line_endings_in_ascii() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("crlf.ply");
    std::fs::write(
        &p,
        b"ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\nproperty float y\r\n\
          property float z\r\nproperty uchar class\r\nend_header\r\n1 2 3 4\r\n5 6 7 8\r\n",
    )
    .unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [5.0, 6.0, 7.0]]);
    assert_eq!(c.labels, Some(vec![4, 8]));
}

mod roundtrip {
    use super::*;
    use proptest::prelude::*;

    fn cloud_strategy() -> impl Strategy<Value = PointCloud> {
        (1usize..40, 0usize..4, any::<bool>(), any::<bool>()).prop_flat_map(
            |(n, dim, has_rgb, has_label)| {
                (
                    proptest::collection::vec(prop::array::uniform3(-1e7f64..1e7), n),
                    proptest::collection::vec(prop::array::uniform3(any::<u8>()), n),
                    proptest::collection::vec(any::<u32>(), n),
                    proptest::collection::vec(-1e3f32..1e3, n * dim),
                )
                    .prop_map(move |(points, rgb, labels, feats)| PointCloud {
                        points,
                        labels: has_label.then_some(labels),
                        colors: has_rgb.then_some(rgb),
                        features: (dim > 0).then_some((dim, feats)),
                    })
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn binary_write_read_is_lossless(cloud in cloud_strategy()) {
            let d = tempfile::tempdir().unwrap();
            let p = d.path().join("r.ply");
            write_ply(&p, &cloud).unwrap();
            prop_assert_eq!(read_ply(&p).unwrap(), cloud);
        }
    }
}

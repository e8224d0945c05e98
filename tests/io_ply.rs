//! PLY reading against files written by plyfile (tests/data/io), writing,
//! and bad input.
mod common;

use common::{assert_err_names, expected_rows, local, truncated_copy};
use omcl::io::cloud::PointCloud;
use omcl::io::ply::{PlyOptions, read_ply, read_ply_with, write_ply};

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
    // A line the parser cannot read: named with its text, on one line,
    // without the parser's state dumped after it.
    let p = d.path().join("negative_count.ply");
    std::fs::write(
        &p,
        b"ply\nformat ascii 1.0\nelement vertex -1\nproperty float x\nend_header\n",
    )
    .unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(
        e.contains("Line 3") && e.contains("(the line: 'element vertex -1')"),
        "{e}"
    );
    assert!(!e.contains('\n') && !e.contains("ParseError"), "{e}");
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
    // An element without properties before the vertices takes no bytes in
    // a binary file, whatever count it declares (2^64 - 1 looped for ever).
    let p = d.path().join("empty_element.ply");
    let header = "element junk 18446744073709551615\nelement vertex 1\nproperty float x\n\
                  property float y\nproperty float z\n";
    std::fs::write(&p, binary_ply(header, &le(&[1.0, 2.0, 3.0]))).unwrap();
    assert_eq!(read_ply(&p).unwrap().points, vec![[1.0, 2.0, 3.0]]);
}

/// A binary little-endian PLY: `header` lines between `ply`/`format` and
/// `end_header`, then `body`.
fn binary_ply(header: &str, body: &[u8]) -> Vec<u8> {
    let mut b = format!("ply\nformat binary_little_endian 1.0\n{header}end_header\n").into_bytes();
    b.extend_from_slice(body);
    b
}

fn le(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn note_count(c: &PointCloud, path: &std::path::Path, parts: &[&str]) -> usize {
    let name = path.display().to_string();
    c.notes
        .iter()
        .filter(|n| n.starts_with(&name) && parts.iter().all(|p| n.contains(p)))
        .count()
}

#[test]
fn non_finite_points_are_left_out_with_their_rows_and_a_note() {
    let d = tempfile::tempdir().unwrap();
    // ASCII as PCL and Open3D write invalid points (glibc prints "-nan"),
    // with colour, label and feature columns that must stay aligned; the
    // left-out vertex's label (-1) is not even looked at.
    let p = d.path().join("nan.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         property int label\nproperty float f0\nend_header\n\
         1 2 3 10 11 12 1 0.5\nnan nan nan 0 0 0 -1 0\n4 -nan 6 20 21 22 2 1.5\n\
         7 8 9 30 31 32 3 2.5\n1 inf 1 0 0 0 4 0\n-Infinity 0 0 0 0 0 5 0\n",
    )
    .unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [7.0, 8.0, 9.0]]);
    assert_eq!(c.labels, Some(vec![1, 3]));
    assert_eq!(c.colors, Some(vec![[10, 11, 12], [30, 31, 32]]));
    assert_eq!(c.features, Some((1, vec![0.5, 2.5])));
    assert_eq!(
        note_count(&c, &p, &["4 of 6 vertices", "non-finite", "left out"]),
        1,
        "{:?}",
        c.notes
    );
    // Where they were, so that a `--features` file made for the whole file
    // (a row a vertex) skips their rows as it does for withheld LAS points.
    assert_eq!(c.left_out, vec![1, 2, 4, 5]);
    let mut c = PointCloud {
        features: None,
        ..c
    };
    let npy = d.path().join("f.npy");
    let rows: Vec<f32> = (0..6).flat_map(|i| [i as f32, 10.0 * i as f32]).collect();
    omcl::io::npy::write_npy(&npy, &[6, 2], &rows).unwrap();
    c.attach_features_npy(&npy).unwrap();
    assert_eq!(c.features, Some((2, vec![0.0, 0.0, 3.0, 30.0])));
    // Binary, fixed records (the bulk decoder) and with a list property
    // (record by record): NaN and infinity alike.
    for with_list in [false, true] {
        let header = format!(
            "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             property ushort label\n{}",
            if with_list {
                "property list uchar int extra\n"
            } else {
                ""
            }
        );
        let mut body = Vec::new();
        for (i, xyz) in [
            [0.0, 1.0, 2.0],
            [f32::NAN; 3],
            [3.0, f32::INFINITY, 0.0],
            [4.0, 5.0, 6.0],
        ]
        .iter()
        .enumerate()
        {
            body.extend(le(xyz));
            body.extend((10 * i as u16).to_le_bytes());
            if with_list {
                body.push(1);
                body.extend(7i32.to_le_bytes());
            }
        }
        let p = d.path().join(format!("nan_{with_list}.ply"));
        std::fs::write(&p, binary_ply(&header, &body)).unwrap();
        let c = read_ply(&p).unwrap();
        assert_eq!(
            c.points,
            vec![[0.0, 1.0, 2.0], [4.0, 5.0, 6.0]],
            "list {with_list}"
        );
        assert_eq!(c.labels, Some(vec![0, 30]), "list {with_list}");
        assert_eq!(c.left_out, vec![1, 2], "list {with_list}");
        assert_eq!(note_count(&c, &p, &["2 of 4 vertices"]), 1, "{:?}", c.notes);
    }
    // Nothing but invalid points: empty, and said why.
    let p = d.path().join("all_nan.ply");
    std::fs::write(
        &p,
        b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
          property float z\nend_header\nnan nan nan\nnan nan nan\n",
    )
    .unwrap();
    assert_err_names(
        read_ply(&p).unwrap_err(),
        &p,
        "all 2 vertices have a non-finite",
    );
}

#[test]
fn label_properties_in_cloudcompare_and_other_spellings() {
    let d = tempfile::tempdir().unwrap();
    for name in [
        "scalar_Classification",
        "scalar_class",
        "SCALAR_LABEL",
        "Label",
        "Classification",
        "semantic",
        "scalar_semantic_label",
    ] {
        let p = d.path().join(format!("{name}.ply"));
        std::fs::write(
            &p,
            format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                 property float z\nproperty float {name}\nend_header\n0 0 0 6\n1 1 1 2\n"
            ),
        )
        .unwrap();
        assert_eq!(read_ply(&p).unwrap().labels, Some(vec![6, 2]), "{name}");
        // The bulk binary decoder matches the same names.
        let header = format!(
            "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
             property float {name}\n"
        );
        std::fs::write(&p, binary_ply(&header, &le(&[0.0, 0.0, 0.0, 9.0]))).unwrap();
        assert_eq!(read_ply(&p).unwrap().labels, Some(vec![9]), "{name}");
    }
    // Names that only look alike are other scalar fields.
    for name in ["scalar_Intensity", "labels_x", "scalar_", "subclass"] {
        let p = d.path().join("other.ply");
        let header = format!(
            "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
             property float {name}\n"
        );
        std::fs::write(&p, binary_ply(&header, &le(&[0.0, 0.0, 0.0, 9.0]))).unwrap();
        assert_eq!(read_ply(&p).unwrap().labels, None, "{name}");
    }
    // Two of them: which one is meant is not guessed.
    let p = d.path().join("two.ply");
    let header = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
                  property float scalar_Classification\nproperty uchar label\n";
    let mut body = le(&[0.0, 0.0, 0.0, 9.0]);
    body.push(1);
    std::fs::write(&p, binary_ply(header, &body)).unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "several label properties");
    assert!(
        read_ply(&p)
            .unwrap_err()
            .to_string()
            .contains("--label-property")
    );
    // Named, either is read and the other ignored.
    let with = |name: &str| {
        let opts = PlyOptions {
            label_property: Some(name.into()),
        };
        read_ply_with(&p, &opts)
    };
    assert_eq!(with("scalar_Classification").unwrap().labels, Some(vec![9]));
    assert_eq!(with("label").unwrap().labels, Some(vec![1]));
    // A name matches in any letter case when only one property has it.
    assert_eq!(with("LABEL").unwrap().labels, Some(vec![1]));
}

/// `--label-property`: a property of another name (DALES's `sem_class`,
/// beside its `ins_class`) read as the labels, ASCII and binary; a name
/// the vertex lacks is refused listing what it has; coordinates are not
/// labels.
#[test]
fn a_named_label_property_is_read_as_the_labels() {
    let d = tempfile::tempdir().unwrap();
    let header = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
                  property float intensity\nproperty int sem_class\nproperty int ins_class\n";
    let ascii = d.path().join("dales_ascii.ply");
    std::fs::write(
        &ascii,
        format!("ply\nformat ascii 1.0\n{header}end_header\n0 0 0 0.5 4 17\n1 2 3 0.25 8 18\n"),
    )
    .unwrap();
    let binary = d.path().join("dales_binary.ply");
    let mut body = Vec::new();
    for (xyz, i, sem, ins) in [
        ([0.0f32, 0.0, 0.0], 0.5f32, 4i32, 17i32),
        ([1.0, 2.0, 3.0], 0.25, 8, 18),
    ] {
        body.extend(le(&[xyz[0], xyz[1], xyz[2], i]));
        body.extend(sem.to_le_bytes());
        body.extend(ins.to_le_bytes());
    }
    std::fs::write(&binary, binary_ply(header, &body)).unwrap();
    let opts = |n: &str| PlyOptions {
        label_property: Some(n.into()),
    };
    for p in [&ascii, &binary] {
        // Without the option, no labels: sem_class is not a known name.
        assert_eq!(read_ply(p).unwrap().labels, None);
        let c = read_ply_with(p, &opts("sem_class")).unwrap();
        assert_eq!(c.labels, Some(vec![4, 8]), "{}", p.display());
        assert_eq!(c.points[1], [1.0, 2.0, 3.0]);
        let c = read_ply_with(p, &opts("ins_class")).unwrap();
        assert_eq!(c.labels, Some(vec![17, 18]));
        let e = read_ply_with(p, &opts("semantic")).unwrap_err();
        assert_err_names(&e, p, "no vertex property 'semantic'");
        assert!(
            e.to_string()
                .contains("x, y, z, intensity, sem_class, ins_class"),
            "{e}"
        );
        let e = read_ply_with(p, &opts("z")).unwrap_err();
        assert_err_names(e, p, "not labels");
    }
}

#[test]
fn sixteen_bit_and_float_colours_scale_to_eight_bits() {
    let d = tempfile::tempdir().unwrap();
    let rgb16 = [[0u16, 255, 256], [65535, 32768, 511]];
    let want16 = vec![[0u8, 0, 1], [255, 128, 1]];
    for with_list in [false, true] {
        let header = format!(
            "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n{}\
             property ushort red\nproperty ushort green\nproperty ushort blue\n",
            if with_list {
                "property list uchar uchar extra\n"
            } else {
                ""
            }
        );
        let mut body = Vec::new();
        for c in rgb16 {
            body.extend(le(&[1.0, 2.0, 3.0]));
            if with_list {
                body.extend([2, 7, 7]);
            }
            body.extend(c.iter().flat_map(|v| v.to_le_bytes()));
        }
        let p = d.path().join(format!("u16_{with_list}.ply"));
        std::fs::write(&p, binary_ply(&header, &body)).unwrap();
        let c = read_ply(&p).unwrap();
        assert_eq!(c.colors, Some(want16.clone()), "list {with_list}");
        assert!(c.notes.is_empty(), "{:?}", c.notes);
    }
    let p = d.path().join("u16.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
         property float z\nproperty ushort red\nproperty ushort green\nproperty ushort blue\n\
         end_header\n0 0 0 0 255 256\n0 0 0 65535 32768 511\n",
    )
    .unwrap();
    assert_eq!(read_ply(&p).unwrap().colors, Some(want16));
    // 0-255 stored in 16 bits (no value above 255 in the file, as many
    // writers do): taken as it is, not as the high byte (black). One value
    // above 255 anywhere makes the whole file 16-bit.
    for (rows, want) in [
        (
            "0 0 0 0 128 255\n0 0 0 10 20 30\n",
            [[0u8, 128, 255], [10, 20, 30]],
        ),
        ("0 0 0 0 128 255\n0 0 0 10 20 256\n", [[0, 0, 0], [0, 0, 1]]),
    ] {
        std::fs::write(
            &p,
            format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                 property float z\nproperty ushort red\nproperty ushort green\n\
                 property ushort blue\nend_header\n{rows}"
            ),
        )
        .unwrap();
        assert_eq!(read_ply(&p).unwrap().colors, Some(want.to_vec()), "{rows}");
        let bin = d.path().join("u16_8bit.ply");
        let header = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
                      property ushort red\nproperty ushort green\nproperty ushort blue\n";
        let mut body = Vec::new();
        for line in rows.lines() {
            let v: Vec<u16> = line
                .split(' ')
                .skip(3)
                .map(|t| t.parse().unwrap())
                .collect();
            body.extend(le(&[0.0, 0.0, 0.0]));
            body.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        }
        std::fs::write(&bin, binary_ply(header, &body)).unwrap();
        assert_eq!(
            read_ply(&bin).unwrap().colors,
            Some(want.to_vec()),
            "binary {rows}"
        );
    }
    // A `uchar` channel beside `ushort` ones stays 8-bit whatever they hold.
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty ushort green\nproperty ushort blue\n\
         end_header\n0 0 0 200 1000 0\n0 0 0 7 20 30\n",
    )
    .unwrap();
    assert_eq!(
        read_ply(&p).unwrap().colors,
        Some(vec![[200, 3, 0], [7, 0, 0]])
    );
    // Float and double 0-1 (Open3D writes double): times 255, rounded;
    // outside 0-1 clamped, and said.
    let p = d.path().join("unit.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nproperty double red\nproperty double green\nproperty float blue\n\
         end_header\n0 0 0 0 0.5 1\n0 0 0 0.2 0.998 0.003\n0 0 0 1.5 -0.25 nan\n",
    )
    .unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(
        c.colors,
        Some(vec![[0, 128, 255], [51, 254, 1], [255, 0, 0]])
    );
    assert_eq!(
        note_count(&c, &p, &["3 float colour values", "clamped"]),
        1,
        "{:?}",
        c.notes
    );
    let header = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
                  property float red\nproperty float green\nproperty float blue\n";
    let body = le(&[
        0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.2, 0.998, 0.003,
    ]);
    std::fs::write(&p, binary_ply(header, &body)).unwrap();
    let c = read_ply(&p).unwrap();
    assert_eq!(c.colors, Some(vec![[0, 128, 255], [51, 254, 1]]));
    assert!(c.notes.is_empty(), "{:?}", c.notes);
}

#[test]
fn unusable_colour_types_are_named_in_ply_words() {
    let d = tempfile::tempdir().unwrap();
    for (t, word) in [
        ("int", "int"),
        ("char", "char"),
        ("list uchar uchar", "list uchar uchar"),
    ] {
        let p = d.path().join("int_red.ply");
        std::fs::write(
            &p,
            format!(
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                 property float z\nproperty {t} red\nproperty uchar green\nproperty uchar blue\n\
                 end_header\n0 0 0 1 2 3\n"
            ),
        )
        .unwrap();
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("int_red.ply")
                && e.contains("'red'")
                && e.contains(&format!("type {word};"))
                && e.contains("ushort"),
            "{e}"
        );
        assert!(!e.contains("Scalar") && !e.contains("Some("), "{e}");
    }
    let p = d.path().join("int_x.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n",
    )
    .unwrap();
    assert_err_names(
        read_ply(&p).unwrap_err(),
        &p,
        "'x' has type int, expected float or double",
    );
}

#[test]
fn files_that_are_not_ply_say_what_they_look_like() {
    let d = tempfile::tempdir().unwrap();
    // A LAS file renamed .ply (it failed as "stream did not contain valid
    // UTF-8").
    let p = d.path().join("scan.ply");
    std::fs::copy(local("laspy_pf3_rgb.las"), &p).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(
        e.contains("scan.ply")
            && e.contains("not a PLY file")
            && e.contains("starts like a LAS/LAZ file")
            && e.contains("--format las"),
        "{e}"
    );
    assert!(!e.contains("UTF-8"), "{e}");
    let p = d.path().join("text.ply");
    std::fs::write(&p, "1 2 3\n4 5 6\n").unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(
        e.contains("text.ply") && e.contains("does not start with the \"ply\" header line"),
        "{e}"
    );
    assert!(!e.contains("starts like"), "{e}");
    let p = d.path().join("empty.ply");
    std::fs::write(&p, "").unwrap();
    assert_err_names(read_ply(&p).unwrap_err(), &p, "not a PLY file: it is empty");
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
        "--format kitti (a Velodyne scan) or --format scannet",
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
                        notes: Vec::new(),
                        left_out: Vec::new(),
                        georef: None,
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

/// UTM coordinates stored as `float`: at 630 km neighbouring values are
/// 6 cm apart, coarser than a street map's voxels, and the reader says so;
/// the same points as `double`, or small `float` ones, get no note.
#[test]
fn float_coordinates_far_from_zero_get_a_precision_note() {
    let d = tempfile::tempdir().unwrap();
    let write = |name: &str, ty: &str, x: f64| {
        let p = d.path().join(name);
        std::fs::write(
            &p,
            format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty {ty} x\nproperty {ty} y\n\
                 property {ty} z\nend_header\n{x} 10 1\n{} 10 1\n",
                x + 0.5
            ),
        )
        .unwrap();
        (p.clone(), read_ply(&p).unwrap())
    };
    let (p, c) = write("utm.ply", "float", 630_000.0);
    assert_eq!(
        note_count(
            &c,
            &p,
            &["float (32-bit)", "reach 63000", "0.06", "m apart", "double"]
        ),
        1,
        "{:?}",
        c.notes
    );
    for (name, ty, x) in [
        ("utm64.ply", "double", 630_000.0),
        ("local.ply", "float", 5_000.0),
    ] {
        let (_, c) = write(name, ty, x);
        assert!(c.notes.is_empty(), "{name}: {:?}", c.notes);
    }
}

/// A body written little-endian under a big-endian header reads as
/// absurd floats: said, naming the file; the right header (and the real
/// big-endian file of plyfile) says nothing.
#[test]
fn a_body_in_the_other_byte_order_is_noted() {
    let d = tempfile::tempdir().unwrap();
    let header = "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n";
    let body = le(&[
        0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.3, 1.2, 10.0,
    ]);
    let right = d.path().join("le.ply");
    std::fs::write(&right, binary_ply(header, &body)).unwrap();
    let c = read_ply(&right).unwrap();
    assert_eq!(note_count(&c, &right, &["byte order"]), 0, "{:?}", c.notes);
    let wrong = d.path().join("be.ply");
    let mut bytes = binary_ply(header, &body);
    let at = bytes
        .windows(13)
        .position(|w| w == b"little_endian")
        .unwrap();
    bytes.splice(at..at + 13, b"big_endian".iter().copied());
    std::fs::write(&wrong, bytes).unwrap();
    let c = read_ply(&wrong).unwrap();
    assert_eq!(
        note_count(
            &c,
            &wrong,
            &["nonzero coordinates are below 1e-30", "byte order"]
        ),
        1,
        "{:?}",
        c.notes
    );
    let real = read_ply(&local("plyfile_binbe_rgb_scalar_label.ply")).unwrap();
    assert!(
        !real.notes.iter().any(|n| n.contains("byte order")),
        "{:?}",
        real.notes
    );
}

/// A vertex without x, y or z is refused naming the axis and listing the
/// properties it has (they had not been listed), so a file with other
/// coordinate names says what to rename.
#[test]
fn a_vertex_without_coordinates_lists_what_it_has() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("lonlat.ply");
    std::fs::write(
        &p,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty double lon\nproperty double lat\n\
         property float height\nproperty uchar red\nend_header\n1 2 3 4\n",
    )
    .unwrap();
    let e = read_ply(&p).unwrap_err();
    assert_err_names(&e, &p, "lacks a scalar 'x' property");
    assert!(
        e.to_string()
            .contains("the vertex has lon, lat, height, red"),
        "{e}"
    );
}

//! A map built from a georeferenced survey keeps its CRS: `map info`
//! names it, `map ground` keeps it, and `map query`/`map export` to LAS or
//! LAZ write the voxels back in the survey's units with its CRS records,
//! on real LAS/LAZ files (GeoTIFF keys in metres, GeoTIFF in feet, WKT in
//! US survey feet with z in metres).

mod common;

use common::{omcl, shared};

use std::collections::BTreeMap;
use std::path::Path;

/// The `LASF_Projection` records of a LAS file: id to bytes.
fn crs_records(path: &Path) -> BTreeMap<u16, Vec<u8>> {
    let r = las::Reader::from_path(path).unwrap();
    r.header()
        .all_vlrs()
        .filter(|v| v.user_id == "LASF_Projection")
        .map(|v| (v.record_id, v.data.clone()))
        .collect()
}

/// The points of a LAS file in its own units, with intensity and point
/// source id, and its header.
fn las_points(path: &Path) -> (las::Header, Vec<las::Point>) {
    let mut r = las::Reader::from_path(path).unwrap();
    let data = r.read_all().unwrap();
    let pts: Vec<las::Point> = data.points().map(Result::unwrap).collect();
    (r.header().clone(), pts)
}

/// The voxel centres (metres) and rows of a map file.
fn centres(map: &Path) -> Vec<([f64; 3], u32)> {
    let m = omcl::map::load(map).unwrap();
    let g = *m.grid();
    m.cells()
        .iter()
        .zip(m.rows())
        .map(|(&c, &r)| (g.center(c).into(), r))
        .collect()
}

fn build(source: &Path, out: &Path) {
    let r = omcl(&[
        "map",
        "cloud",
        source.to_str().unwrap(),
        "--classes",
        "asprs",
        "--resolution",
        "0.5",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(r.ok(), "{}", r.text());
}

/// `omcl map export MAP -o OUT`.
fn export(map: &Path, out: &Path) -> common::Run {
    let (map, out) = (map.to_str().unwrap(), out.to_str().unwrap());
    omcl(&["map", "export", map, "-o", out])
}

/// `omcl map query MAP WORD --classes asprs -o OUT`.
fn query(map: &Path, word: &str, out: &Path) -> common::Run {
    omcl(&[
        "map",
        "query",
        map.to_str().unwrap(),
        word,
        "--classes",
        "asprs",
        "-o",
        out.to_str().unwrap(),
    ])
}

fn info(map: &Path) -> serde_json::Value {
    let r = omcl(&["map", "info", map.to_str().unwrap(), "--json"]);
    assert!(r.ok(), "{}", r.text());
    serde_json::from_str(&r.stdout).unwrap()
}

/// Checks that `written` holds the voxels of `map`, each at its centre
/// once converted from the file's units by `metres_per_unit`, with its row
/// as point source id; returns the points by row.
fn assert_voxels_in_survey_units(
    written: &Path,
    map: &Path,
    metres_per_unit: [f64; 2],
) -> Vec<las::Point> {
    let (h, pts) = las_points(written);
    // The header's bounds hold the stored points, at most a step beyond
    // them (the las crate rounds them outwards).
    let b = h.bounds();
    let t = h.transforms();
    for (v, lo, hi, step) in [
        (
            pts.iter().map(|p| p.x).collect::<Vec<_>>(),
            b.min.x,
            b.max.x,
            t.x.scale,
        ),
        (
            pts.iter().map(|p| p.y).collect(),
            b.min.y,
            b.max.y,
            t.y.scale,
        ),
        (
            pts.iter().map(|p| p.z).collect(),
            b.min.z,
            b.max.z,
            t.z.scale,
        ),
    ] {
        let (vlo, vhi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        assert!(lo <= vlo && vhi <= hi, "{vlo} {vhi} outside {lo} {hi}");
        assert!(
            vlo - lo <= step * 1.01 && hi - vhi <= step * 1.01,
            "{vlo} {vhi} vs {lo} {hi}"
        );
    }
    let want = centres(map);
    assert_eq!(pts.len(), want.len());
    for (p, (c, row)) in pts.iter().zip(&want) {
        let [xy, z] = metres_per_unit;
        let got = [p.x * xy, p.y * xy, p.z * z];
        for a in 0..3 {
            // The file's step is 1 mm of its units.
            assert!((got[a] - c[a]).abs() < 1e-3, "{got:?} vs {c:?}");
        }
        assert_eq!(u32::from(p.point_source_id), *row);
        assert_eq!((p.return_number, p.number_of_returns), (1, 1));
    }
    pts
}

#[test]
fn geotiff_keys_in_metres_come_back_with_the_export() {
    let dir = tempfile::tempdir().unwrap();
    let src = shared("las/32-1-472-150-76.laz");
    let map = dir.path().join("m.omcl");
    build(&src, &map);
    let i = info(&map);
    let crs = &i["crs"];
    assert_eq!(
        crs["name"],
        "UTM sone 32, basert på EUREF89 (ETRS89/UTM) (EPSG:25832, vertical EPSG:5941)"
    );
    assert_eq!(crs["governing"], "GeoTIFF");
    assert_eq!(crs["records"], serde_json::json!([34735, 34736, 34737]));
    assert_eq!(i["version"], "3");
    let text = omcl(&["map", "info", map.to_str().unwrap()]).stdout;
    assert!(text.contains("the survey's: metres"), "{text}");

    let out = dir.path().join("e.las");
    let r = export(&map, &out);
    assert!(r.ok(), "{}", r.text());
    let (h, _) = las_points(&out);
    assert_eq!((h.version().major, h.version().minor), (1, 2));
    assert!(!h.has_wkt_crs());
    assert_eq!(crs_records(&out), crs_records(&src));
    assert_voxels_in_survey_units(&out, &map, [1.0, 1.0]);

    // Read back by omcl, the export is a survey in the same CRS again.
    let again = dir.path().join("again.omcl");
    build(&out, &again);
    assert_eq!(info(&again)["crs"], *crs);

    // An export never replaces the survey (a LAS omcl did not write) nor
    // a map; an earlier export it replaces.
    let survey = dir.path().join("survey.laz");
    std::fs::copy(&src, &survey).unwrap();
    let before = std::fs::read(&survey).unwrap();
    for target in [&survey, &again] {
        let r = export(&map, target);
        assert_eq!(r.code, Some(1), "{}", r.text());
        assert!(r.stderr.contains("would replace"), "{}", r.text());
    }
    assert_eq!(std::fs::read(&survey).unwrap(), before);
    // Nor a PLY omcl did not write (the cloud a map came from), nor a file
    // of another kind by a LAS name.
    let ply = dir.path().join("cloud.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 0\nend_header\n",
    )
    .unwrap();
    let notes = dir.path().join("notes.las");
    std::fs::write(&notes, "my notes\n").unwrap();
    for target in [&ply, &notes] {
        let before = std::fs::read(target).unwrap();
        let r = export(&map, target);
        assert_eq!(r.code, Some(1), "{}", r.text());
        assert!(r.stderr.contains("omcl did not write"), "{}", r.text());
        assert_eq!(std::fs::read(target).unwrap(), before);
    }
    // A name of another format is refused, not given a PLY.
    for (name, words) in [
        ("heat.txt", "names a .txt file"),
        ("heat", "has no extension"),
    ] {
        let target = dir.path().join(name);
        let r = export(&map, &target);
        assert_eq!(r.code, Some(1), "{}", r.text());
        assert!(r.stderr.contains(words), "{}", r.text());
        assert!(r.stderr.contains(".ply, .las or .laz"), "{}", r.text());
        assert!(!target.exists());
    }
    // An earlier PLY export is replaced.
    let mine = dir.path().join("mine.ply");
    assert!(export(&map, &mine).ok());
    assert!(export(&map, &mine).ok());
    let r = export(&map, &out);
    assert!(r.ok(), "{}", r.text());
}

#[test]
fn an_empty_crs_record_and_a_user_written_geotiff_read_back() {
    // GeoTIFF keys of EPSG:32633 in metres, and an empty citation record
    // (34737 with no bytes): the map keeps both and reads back.
    let dir = tempfile::tempdir().unwrap();
    let las_path = dir.path().join("t.las");
    let keys: Vec<u16> = vec![
        1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32633, 3076, 0, 1, 9001,
    ];
    let vlr = |id: u16, data: Vec<u8>| las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id: id,
        description: String::new(),
        data,
    };
    let mut b = las::Builder::from((1, 2));
    let t = |offset: f64| las::Transform {
        scale: 0.001,
        offset,
    };
    b.transforms = las::Vector {
        x: t(500_000.0),
        y: t(5_000_000.0),
        z: t(0.0),
    };
    b.vlrs = vec![
        vlr(34735, keys.iter().flat_map(|k| k.to_le_bytes()).collect()),
        vlr(34737, Vec::new()),
    ];
    let mut w = las::Writer::from_path(&las_path, b.into_header().unwrap()).unwrap();
    // Every other point ASPRS class 12 (overlap: code 12 in format 0, a
    // flag to the las crate), the rest ground; one a voxel.
    for i in 0..50 {
        w.write_point(las::Point {
            x: 500_000.0 + f64::from(i),
            y: 5_000_000.0,
            z: 100.0,
            classification: las::point::Classification::new(2).unwrap(),
            is_overlap: i % 2 == 1,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
    let map = dir.path().join("m.omcl");
    build(&las_path, &map);
    let crs = &info(&map)["crs"];
    assert_eq!(crs["name"], "a GeoTIFF CRS (EPSG:32633)");
    assert_eq!(crs["records"], serde_json::json!([34735, 34737]));
    let out = dir.path().join("e.las");
    let r = export(&map, &out);
    assert!(r.ok(), "{}", r.text());
    assert_eq!(crs_records(&out), crs_records(&las_path));
    // The classes come back, overlap included (the export had failed on
    // class 12).
    for p in las_points(&out).1 {
        let odd = (p.x - 500_000.0).round() as i64 % 2 == 1;
        assert_eq!(p.is_overlap, odd, "{p:?}");
        if !odd {
            assert_eq!(u8::from(p.classification), 2, "{p:?}");
        }
    }
}

#[test]
fn wkt_in_us_survey_feet_is_written_back_in_feet_as_las_1_4() {
    let dir = tempfile::tempdir().unwrap();
    let src = shared("las/test1_4.las");
    let map = dir.path().join("m.omcl");
    build(&src, &map);
    let crs = &info(&map)["crs"];
    assert_eq!(
        crs["name"],
        "NAD83(HARN) / New Mexico Central (ftUS) (EPSG:2903)"
    );
    assert_eq!(crs["governing"], "WKT");
    let ft = 1200.0 / 3937.0;
    let f = crs["metres_per_unit"].as_array().unwrap();
    assert!((f[0].as_f64().unwrap() - ft).abs() < 1e-15 && f[1] == 1.0);

    let out = dir.path().join("heat.laz");
    let r = query(&map, "ground", &out);
    assert!(r.ok(), "{}", r.text());
    let (h, _) = las_points(&out);
    assert_eq!((h.version().major, h.version().minor), (1, 4));
    assert!(h.has_wkt_crs() && h.point_format().is_compressed);
    assert_eq!(crs_records(&out), crs_records(&src));
    assert_voxels_in_survey_units(&out, &map, [ft, 1.0]);
}

#[test]
fn feet_heat_map_carries_similarity_as_intensity_and_ground_keeps_the_crs() {
    let dir = tempfile::tempdir().unwrap();
    let src = shared("las/autzen_trim.laz");
    let map = dir.path().join("m.omcl");
    build(&src, &map);
    let crs = info(&map)["crs"].clone();
    assert_eq!(
        crs["name"],
        "NAD_1983_HARN_Lambert_Conformal_Conic (user-defined projection)"
    );
    assert_eq!(crs["governing"], "GeoTIFF");

    let out = dir.path().join("heat.las");
    let r = query(&map, "ground", &out);
    assert!(r.ok(), "{}", r.text());
    let pts = assert_voxels_in_survey_units(&out, &map, [0.3048, 0.3048]);
    // The survey has GeoTIFF keys and a WKT record; the export, a LAS 1.2
    // file, the governing GeoTIFF ones only ("not both", LAS 1.4).
    let mut geotiff = crs_records(&src);
    assert!(geotiff.remove(&2112).is_some());
    assert_eq!(crs_records(&out), geotiff);
    // Each voxel's intensity is its row's cosine to "ground", times
    // 65535: the row of the pure ground class gives 65535, and every other
    // row its cosine to that row.
    let mut by_row: BTreeMap<u16, Vec<u16>> = BTreeMap::new();
    for p in &pts {
        by_row
            .entry(p.point_source_id)
            .or_default()
            .push(p.intensity);
    }
    assert!(by_row.len() >= 2, "{:?}", by_row.keys());
    let m = omcl::map::load(&map).unwrap();
    let level = |v: &Vec<u16>| {
        assert!(v.iter().all(|&i| i == v[0]), "one intensity a row");
        v[0]
    };
    let ground: Vec<u16> = by_row
        .iter()
        .filter(|(_, v)| level(v) == 65535)
        .map(|(r, _)| *r)
        .collect();
    assert_eq!(ground.len(), 1, "{by_row:?}");
    let g = m.db().row(ground[0] as usize).to_vec();
    for (&r, v) in &by_row {
        let cos: f32 = m
            .db()
            .row(r as usize)
            .iter()
            .zip(&g)
            .map(|(a, b)| a * b)
            .sum();
        let want = (cos.clamp(0.0, 1.0) * 65535.0).round() as i32;
        assert!(
            (i32::from(level(v)) - want).abs() <= 1,
            "row {r}: {} vs {want}",
            level(v)
        );
    }

    // A PLY carries no CRS: the note says so and names the way.
    let ply = dir.path().join("heat.ply");
    let r = query(&map, "ground", &ply);
    assert!(r.ok(), "{}", r.text());
    assert!(
        r.output().contains("NAD_1983_HARN_Lambert_Conformal_Conic")
            && r.output().contains(".las or .laz"),
        "{}",
        r.output()
    );

    // Grounding replaces the rows, not the place.
    let grounded = dir.path().join("g.omcl");
    let r = omcl(&[
        "map",
        "ground",
        map.to_str().unwrap(),
        "ground",
        "building",
        "--classes",
        "asprs",
        "-o",
        grounded.to_str().unwrap(),
    ]);
    assert!(r.ok(), "{}", r.text());
    assert_eq!(info(&grounded)["crs"], crs);
}

#[test]
fn a_survey_without_crs_stays_a_local_frame() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("m.omcl");
    build(&shared("las/simple.las"), &map);
    assert!(info(&map)["crs"].is_null());
    let text = omcl(&["map", "info", map.to_str().unwrap()]).stdout;
    assert!(text.contains("none stated"), "{text}");
    let out = dir.path().join("e.laz");
    let r = export(&map, &out);
    assert!(r.ok(), "{}", r.text());
    assert!(crs_records(&out).is_empty());
    assert_voxels_in_survey_units(&out, &map, [1.0, 1.0]);
}

/// A map built on the built-in ASPRS list names its rows' classes in `map
/// info`, and its LAS export carries them as classification: every voxel
/// whose survey points are of one class gets that class, a voxel of
/// several classes (its row a mix) one of them, and a note counts those.
#[test]
fn asprs_classes_are_named_and_exported_as_classification() {
    let dir = tempfile::tempdir().unwrap();
    let src = shared("las/32-1-472-150-76.laz");
    let map = dir.path().join("m.omcl");
    build(&src, &map);
    let i = info(&map);
    let named: Vec<(u64, String)> = i["top_row_classes"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r["classes"].as_array().unwrap().clone())
        .map(|c| {
            (
                c["id"].as_u64().unwrap(),
                c["name"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let mut ids: Vec<u64> = named.iter().map(|c| c.0).collect();
    ids.sort();
    // The survey holds classes 1, 2, 9 and 7 (noise, left out of maps).
    assert_eq!(ids, [1, 2, 9], "{named:?}");
    assert!(named.contains(&(9, "water".into())), "{named:?}");

    // The survey's classes by voxel (metres: no unit conversion).
    let origin: Vec<f64> = i["origin_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let key = |p: [f64; 3]| -> [i64; 3] {
        std::array::from_fn(|a| ((p[a] - origin[a]) / 0.5).floor() as i64)
    };
    let mut truth: BTreeMap<[i64; 3], std::collections::BTreeSet<u8>> = BTreeMap::new();
    for p in las_points(&src).1 {
        let c = u8::from(p.classification);
        if c != 7 {
            truth.entry(key([p.x, p.y, p.z])).or_default().insert(c);
        }
    }
    let out = dir.path().join("e.las");
    let r = export(&map, &out);
    assert!(r.ok(), "{}", r.text());
    let pts = assert_voxels_in_survey_units(&out, &map, [1.0, 1.0]);
    let (mut single, mut several) = (0, 0);
    for p in &pts {
        let c = u8::from(p.classification);
        let want = &truth[&key([p.x, p.y, p.z])];
        assert!(
            want.contains(&c),
            "voxel of classes {want:?} exported as {c}"
        );
        if want.len() == 1 {
            single += 1;
        } else {
            several += 1;
        }
    }
    assert_eq!(single + several, pts.len());
    assert!(single > 4000 && several > 0, "{single} {several}");
    // The note counts the voxels of a mixed row: at most those of several
    // classes (a voxel of a few points of a second class can stay within
    // tau of the first's row).
    let mixed: usize = r
        .stderr
        .split("note: ")
        .find_map(|n| {
            n.split_once(" of ")
                .map(|(a, _)| a.rsplit(' ').next().unwrap().to_string())
        })
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{}", r.text()));
    assert!(
        mixed > 0 && mixed <= several,
        "{mixed} of {several}: {}",
        r.text()
    );
}

//! LAS/LAZ reading against files written by laspy (tests/data/io) and real
//! files from laspy's and las-rs's test data (../shared/data/las).
mod common;

use std::collections::BTreeSet;
use std::path::Path;

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
    // None of the real files has records past its declared count...
    for f in ["simple.las", "vegetation_1_3.las", "test1_4.las"] {
        let c = read_las(&dir.join(f)).unwrap();
        assert!(
            !c.notes.iter().any(|n| n.contains("more whole point")),
            "{f}: {:?}",
            c.notes
        );
    }
    // A version byte of 9 (or minor 7) is named as the version.
    let tmp0 = tempfile::tempdir().unwrap();
    for (at, value, shown) in [(24usize, 9u8, "9.2"), (25, 7, "1.7")] {
        let p = tmp0.path().join(format!("v{value}.las"));
        let mut bytes = std::fs::read(dir.join("simple.las")).unwrap();
        bytes[at] = value;
        std::fs::write(&p, &bytes).unwrap();
        let e = read_las(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("LAS version {shown} is not one")),
            "{e}"
        );
    }
    // ...and one whose header says 10 of its 1,065 reads 10, with a note.
    let tmp = tempfile::tempdir().unwrap();
    let short = tmp.path().join("short_count.las");
    let mut bytes = std::fs::read(dir.join("simple.las")).unwrap();
    bytes[107..111].copy_from_slice(&10u32.to_le_bytes());
    std::fs::write(&short, &bytes).unwrap();
    let c = read_las(&short).unwrap();
    assert_eq!(c.len(), 10);
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("1055 more whole point records follow the 10")),
        "{:?}",
        c.notes
    );
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

// ---- Units, withheld points: files the tests write with the `las` crate,
// ---- and the real files in their own units.

/// A `LASF_Projection` record.
fn projection(record_id: u16, data: Vec<u8>) -> las::Vlr {
    las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id,
        description: String::new(),
        data,
    }
}

fn wkt(text: &str) -> las::Vlr {
    let mut data = text.as_bytes().to_vec();
    data.push(0);
    projection(2112, data)
}

/// A GeoKeyDirectory: (key, location, count, value) entries.
fn geokeys(keys: &[(u16, u16, u16, u16)]) -> las::Vlr {
    let mut words = vec![1u16, 1, 0, keys.len() as u16];
    for &(k, l, c, v) in keys {
        words.extend([k, l, c, v]);
    }
    projection(34735, words.iter().flat_map(|w| w.to_le_bytes()).collect())
}

/// One point the tests write: position (file units), class, withheld.
type Rec = ([f64; 3], u8, bool);

/// Writes `points` as LAS `version` in point `format` (LAZ when the name
/// ends in `.laz`), with `vlrs`; colour, when the format has it, is
/// `1000 * index` on every channel.
fn write_las(path: &Path, version: (u8, u8), format: u8, vlrs: Vec<las::Vlr>, points: &[Rec]) {
    let wkt_bit = vlrs.iter().any(|v| v.record_id == 2112);
    write_las_bit(path, version, format, vlrs, points, wkt_bit);
}

/// [`write_las`] with the header's WKT bit as given (formats 6-10 set it
/// whatever `wkt_bit` says).
fn write_las_bit(
    path: &Path,
    version: (u8, u8),
    format: u8,
    vlrs: Vec<las::Vlr>,
    points: &[Rec],
    wkt_bit: bool,
) {
    let mut b = las::Builder::from(version);
    b.point_format = las::point::Format::new(format).unwrap();
    b.has_wkt_crs = wkt_bit;
    b.vlrs = vlrs;
    let header = b.into_header().unwrap();
    let has_color = header.point_format().has_color;
    let mut w = las::Writer::from_path(path, header).unwrap();
    for (i, &(p, class, withheld)) in points.iter().enumerate() {
        let c = 1000 * i as u16;
        w.write_point(las::Point {
            x: p[0],
            y: p[1],
            z: p[2],
            classification: las::point::Classification::new(class).unwrap(),
            is_withheld: withheld,
            gps_time: Some(0.0),
            color: has_color.then_some(las::Color::new(c, c, c)),
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

/// Three points in file units, none withheld.
const THREE: [Rec; 3] = [
    ([1000.0, 2000.0, 100.0], 2, false),
    ([1010.5, 2003.25, 101.0], 2, false),
    ([990.0, 1999.0, 99.5], 6, false),
];

fn assert_scaled(c: &omcl::io::cloud::PointCloud, xy: f64, z: f64) {
    assert_eq!(c.len(), THREE.len());
    for (got, (want, _, _)) in c.points.iter().zip(&THREE) {
        let want = [want[0] * xy, want[1] * xy, want[2] * z];
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 1e-9, "{got:?} vs {want:?}");
        }
    }
}

fn has_note(c: &omcl::io::cloud::PointCloud, path: &Path, parts: &[&str]) {
    let name = path.display().to_string();
    assert!(
        c.notes
            .iter()
            .any(|n| n.starts_with(&name) && parts.iter().all(|p| n.contains(p))),
        "no note with {parts:?}: {:?}",
        c.notes
    );
}

const US_FOOT: f64 = 1200.0 / 3937.0;

#[test]
fn autzen_in_international_feet_comes_out_in_metres_with_a_note() {
    let path = shared("las/autzen_trim.laz");
    let c = read_las(&path).unwrap();
    // The same points as the `las` crate decodes them, times 0.3048 (the
    // file's GeoTIFF ProjLinearUnitsGeoKey 9002 and WKT UNIT["foot",0.3048];
    // no vertical unit: z in feet too). Its header's WKT bit is not set,
    // so the GeoTIFF keys are the ones read, and named.
    let raw = las::Reader::from_path(&path).unwrap().read_all().unwrap();
    let (xs, ys, zs): (Vec<f64>, Vec<f64>, Vec<f64>) =
        (raw.x().collect(), raw.y().collect(), raw.z().collect());
    assert_eq!(c.len(), xs.len());
    for (i, p) in c.points.iter().enumerate() {
        assert_eq!(
            *p,
            [xs[i] * 0.3048, ys[i] * 0.3048, zs[i] * 0.3048],
            "point {i}"
        );
    }
    // Autzen stadium, Eugene (Oregon): about 120 to 160 m above sea level.
    let (lo, hi) = c
        .points
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[2]), b.max(p[2])));
    assert!(lo > 110.0 && hi < 170.0, "z {lo} to {hi} m");
    assert_eq!(c.notes.len(), 1, "{:?}", c.notes);
    has_note(
        &c,
        &path,
        &[
            "international feet",
            "GeoTIFF ProjLinearUnitsGeoKey 9002",
            "converted to metres",
        ],
    );
}

#[test]
fn real_files_in_metres_or_without_crs_have_no_notes() {
    for f in [
        "32-1-472-150-76.laz",
        "simple.las",
        "simple.laz",
        "vegetation_1_3.las",
    ] {
        let c = read_las(&shared("las").join(f)).unwrap();
        assert!(c.notes.is_empty(), "{f}: {:?}", c.notes);
    }
}

#[test]
fn test1_4_in_us_survey_feet_with_a_vertical_unit_whose_name_and_factor_disagree() {
    // WKT: PROJCS[... UNIT["US survey foot",0.3048006096012192] ...,
    // VERTCS[... UNIT["US survey foot",1.0] ...]] nested inside it.
    let path = shared("las/test1_4.las");
    let c = read_las(&path).unwrap();
    let raw = las::Reader::from_path(&path).unwrap().read_all().unwrap();
    for ((p, x), z) in c.points.iter().zip(raw.x()).zip(raw.z()) {
        assert!((p[0] - x * US_FOOT).abs() < 1e-9, "{} {x}", p[0]);
        assert_eq!(p[2], z);
    }
    has_note(
        &c,
        &path,
        &["x and y in US survey feet", "z in metres", "VERTCS UNIT"],
    );
    has_note(&c, &path, &["z: ", "factor 1", "the factor was used"]);
}

/// A file name, its CRS records, the factors to metres expected for x and
/// y and for z, and what the note must say (nothing: no note).
type UnitCase = (&'static str, Vec<las::Vlr>, f64, f64, Vec<&'static str>);

#[test]
fn crs_units_stated_by_wkt_or_geotiff_keys_are_converted() {
    let d = tempfile::tempdir().unwrap();
    let compound = r#"COMPD_CS["NAD83 / Oregon GIC Lambert (ft) + NAVD88 height",PROJCS["NAD83 / Oregon GIC Lambert (ft)",GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic_2SP"],PARAMETER["false_easting",1312335.958],UNIT["foot",0.3048],AXIS["Easting",EAST],AXIS["Northing",NORTH]],VERT_CS["NAVD88 height",VERT_DATUM["North American Vertical Datum 1988",2005],UNIT["metre",1],AXIS["Gravity-related height",UP]]]"#;
    // WKT 2, units on the axes; the false easting's metres must not count.
    let wkt2 = r#"PROJCRS["NAD83 / Texas Central (ftUS)",BASEGEOGCRS["NAD83",DATUM["North American Datum 1983",ELLIPSOID["GRS 1980",6378137,298.257222101,LENGTHUNIT["metre",1]]],PRIMEM["Greenwich",0,ANGLEUNIT["degree",0.0174532925199433]]],CONVERSION["SPCS83 Texas Central zone (US Survey feet)",METHOD["Lambert Conic Conformal (2SP)",ID["EPSG",9802]],PARAMETER["False easting",2296583.333,LENGTHUNIT["metre",1]]],CS[Cartesian,2],AXIS["easting (X)",east,ORDER[1],LENGTHUNIT["US survey foot",0.304800609601219]],AXIS["northing (Y)",north,ORDER[2],LENGTHUNIT["US survey foot",0.304800609601219]],ID["EPSG",2277]]"#;
    let mut doubles = projection(34736, 0.5f64.to_le_bytes().to_vec());
    doubles.data.extend(2.0f64.to_le_bytes());
    let cases: Vec<UnitCase> = vec![
        (
            "compound.las",
            vec![wkt(compound)],
            0.3048,
            1.0,
            vec![
                "x and y in international feet",
                "z in metres (WKT VERT_CS UNIT[\"metre\",1])",
            ],
        ),
        (
            "wkt2.las",
            vec![wkt(wkt2)],
            0.304800609601219,
            0.304800609601219,
            vec![
                "coordinates in US survey feet",
                "LENGTHUNIT[\"US survey foot\"",
            ],
        ),
        (
            "geotiff_us_feet.las",
            vec![geokeys(&[
                (1024, 0, 1, 1),
                (3072, 0, 1, 2277),
                (3076, 0, 1, 9003),
                (4099, 0, 1, 9001),
            ])],
            US_FOOT,
            1.0,
            vec![
                "US survey feet (GeoTIFF ProjLinearUnitsGeoKey 9003)",
                "z in metres",
            ],
        ),
        (
            "geotiff_user_unit.laz",
            vec![
                geokeys(&[(1024, 0, 1, 1), (3076, 0, 1, 32767), (3077, 34736, 1, 1)]),
                doubles,
            ],
            2.0,
            2.0,
            vec!["units of 2 m (GeoTIFF ProjLinearUnitSizeGeoKey 2)"],
        ),
        (
            "geotiff_metres.las",
            vec![geokeys(&[
                (1024, 0, 1, 1),
                (3072, 0, 1, 32633),
                (3076, 0, 1, 9001),
            ])],
            1.0,
            1.0,
            vec![],
        ),
        // The CRS by its EPSG code alone (as many writers leave it): the
        // code's unit, z in it too (NAD83 / Texas Central (ftUS)).
        (
            "geotiff_code_only.las",
            vec![geokeys(&[(1024, 0, 1, 1), (3072, 0, 1, 2277)])],
            US_FOOT,
            US_FOOT,
            vec!["US survey feet (GeoTIFF ProjectedCRSGeoKey 2277: EPSG's US survey foot)"],
        ),
        (
            "geotiff_code_only_metres.las",
            vec![geokeys(&[(1024, 0, 1, 1), (3072, 0, 1, 32633)])],
            1.0,
            1.0,
            vec![],
        ),
        ("no_crs.las", vec![], 1.0, 1.0, vec![]),
    ];
    for (name, vlrs, xy, z, parts) in cases {
        let path = d.path().join(name);
        write_las(&path, (1, 2), 1, vlrs, &THREE);
        let c = read_las(&path).unwrap();
        assert_scaled(&c, xy, z);
        if parts.is_empty() {
            assert!(c.notes.is_empty(), "{name}: {:?}", c.notes);
        } else {
            assert_eq!(c.notes.len(), 1, "{name}: {:?}", c.notes);
            has_note(&c, &path, &parts);
        }
    }
    // WKT in feet and GeoTIFF keys in metres in one file: the header's WKT
    // bit chooses (the LAS specification's rule); formats 6-10 always set
    // it. With the bit and a WKT that does not parse, the keys tell.
    let metre_keys = || geokeys(&[(1024, 0, 1, 1), (3072, 0, 1, 32633), (3076, 0, 1, 9001)]);
    let feet = r#"PROJCS["x",UNIT["foot",0.3048]]"#;
    for (name, version, format, bit, wkt_text, xy) in [
        ("both_bit.las", (1, 4), 1, true, feet, 0.3048),
        ("both_no_bit.las", (1, 4), 1, false, feet, 1.0),
        ("both_legacy.las", (1, 2), 1, false, feet, 1.0),
        ("both_format6.las", (1, 4), 6, false, feet, 0.3048),
        (
            "both_bit_broken.las",
            (1, 4),
            1,
            true,
            r#"PROJCS["cut""#,
            1.0,
        ),
    ] {
        let path = d.path().join(name);
        write_las_bit(
            &path,
            version,
            format,
            vec![wkt(wkt_text), metre_keys()],
            &THREE,
            bit,
        );
        let c = read_las(&path).unwrap();
        assert_scaled(&c, xy, xy);
        assert_eq!(c.notes.is_empty(), xy == 1.0, "{name}: {:?}", c.notes);
    }
    // WKT that does not parse: metres assumed, and said.
    let path = d.path().join("broken_wkt.las");
    write_las(
        &path,
        (1, 4),
        6,
        vec![wkt(r#"PROJCS["cut",UNIT["foot",0.3048]"#)],
        &THREE,
    );
    let c = read_las(&path).unwrap();
    assert_scaled(&c, 1.0, 1.0);
    has_note(&c, &path, &["could not be parsed", "taken as metres"]);
}

#[test]
fn geographic_coordinates_and_unknown_units_are_refused_by_name() {
    let d = tempfile::tempdir().unwrap();
    let geog = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]]"#;
    let geog2 = r#"COMPOUNDCRS["WGS 84 + EGM96 height",GEOGCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563]]],CS[ellipsoidal,2],AXIS["latitude",north],AXIS["longitude",east],ANGLEUNIT["degree",0.0174532925199433]],VERTCRS["EGM96 height",VDATUM["EGM96 geoid"],CS[vertical,1],AXIS["gravity-related height (H)",up,LENGTHUNIT["metre",1]]]]"#;
    let cases = [
        (
            "geog_wkt.las",
            vec![wkt(geog)],
            vec![
                "geographic",
                "WKT GEOGCS[\"WGS 84\"]",
                "degrees",
                "reproject",
                "metres",
            ],
        ),
        (
            "geog_wkt2.las",
            vec![wkt(geog2)],
            vec!["geographic", "GEOGCRS", "reproject"],
        ),
        (
            "geog_geotiff.las",
            vec![geokeys(&[(1024, 0, 1, 2), (2048, 0, 1, 4326)])],
            vec!["geographic", "GTModelTypeGeoKey 2", "reproject"],
        ),
        (
            "geog_no_model.las",
            vec![geokeys(&[(2048, 0, 1, 4326)])],
            vec![
                "geographic",
                "GeodeticCRSGeoKey without a projected CRS",
                "reproject",
            ],
        ),
        (
            "unknown_unit.las",
            vec![geokeys(&[(1024, 0, 1, 1), (3076, 0, 1, 9102)])],
            vec!["ProjLinearUnitsGeoKey", "9102", "reproject"],
        ),
    ];
    for (name, vlrs, parts) in cases {
        let path = d.path().join(name);
        write_las(&path, (1, 2), 1, vlrs, &THREE);
        let e = read_las(&path).unwrap_err().to_string();
        assert!(e.starts_with(&path.display().to_string()), "{e}");
        for p in parts {
            assert!(e.contains(p), "{name}: no {p:?} in {e}");
        }
    }
    // A vertical unit code omcl does not know, under known horizontal
    // feet: read, z in feet too, with a note.
    let path = d.path().join("odd_vertical.las");
    let keys = geokeys(&[(1024, 0, 1, 1), (3076, 0, 1, 9002), (4099, 0, 1, 9102)]);
    write_las(&path, (1, 2), 1, vec![keys], &THREE);
    let c = read_las(&path).unwrap();
    has_note(
        &c,
        &path,
        &[
            "VerticalUnitsGeoKey",
            "9102",
            "z taken in the horizontal unit",
        ],
    );
    let z0 = THREE[0].0[2] * 0.3048;
    assert!((c.points[0][2] - z0).abs() < 1e-6, "{:?}", c.points[0]);
}

#[test]
fn withheld_points_are_left_out_with_a_note() {
    let d = tempfile::tempdir().unwrap();
    let points: Vec<Rec> = (0..7)
        .map(|i| ([i as f64, 2.0 * i as f64, 0.5], i as u8, i % 3 == 1))
        .collect();
    // Formats 0-5 keep the flag in bit 7 of the classification byte, 6-10
    // in the classification flags: both, plain and compressed.
    for (name, version, format) in [
        ("w3.las", (1, 2), 3),
        ("w3.laz", (1, 2), 3),
        ("w6.las", (1, 4), 6),
        ("w7.laz", (1, 4), 7),
    ] {
        let path = d.path().join(name);
        write_las(&path, version, format, vec![], &points);
        let c = read_las(&path).unwrap();
        let kept = [0usize, 2, 3, 5, 6];
        assert_eq!(
            c.points,
            kept.map(|i| [i as f64, 2.0 * i as f64, 0.5]),
            "{name}"
        );
        assert_eq!(c.labels, Some(kept.map(|i| i as u32).to_vec()), "{name}");
        if let Some(col) = &c.colors {
            // 16-bit values above 255: the high byte.
            let want: Vec<[u8; 3]> = kept.iter().map(|&i| [((1000 * i) >> 8) as u8; 3]).collect();
            assert_eq!(col, &want, "{name}");
        }
        assert_eq!(c.colors.is_some(), format != 6, "{name}");
        assert_eq!(c.notes.len(), 1, "{name}: {:?}", c.notes);
        has_note(&c, &path, &["2 of 7 points", "withheld", "left out"]);
        assert_eq!(c.left_out, vec![1, 4], "{name}");
        // Features made for the file, a row a point of it: the withheld
        // points' rows go with them; a row a kept point is taken as it is.
        let mut c = c;
        let npy = d.path().join(format!("{name}.npy"));
        let rows: Vec<f32> = (0..7).flat_map(|i| [i as f32, 1.0]).collect();
        omcl::io::npy::write_npy(&npy, &[7, 2], &rows).unwrap();
        let mut of_file = c.clone();
        of_file.attach_features_npy(&npy).unwrap();
        let want: Vec<f32> = kept.iter().flat_map(|&i| [i as f32, 1.0]).collect();
        assert_eq!(of_file.features, Some((2, want)), "{name}");
        omcl::io::npy::write_npy(&npy, &[5, 2], &rows[..10]).unwrap();
        c.attach_features_npy(&npy).unwrap();
        omcl::io::npy::write_npy(&npy, &[6, 2], &rows[..12]).unwrap();
        let e = c.attach_features_npy(&npy).unwrap_err().to_string();
        assert!(
            e.contains("6 feature rows for a cloud of 5 points (7 in the file; 2 left out"),
            "{e}"
        );
    }
    let all: Vec<Rec> = THREE.iter().map(|&(p, c, _)| (p, c, true)).collect();
    let path = d.path().join("all_withheld.las");
    write_las(&path, (1, 2), 1, vec![], &all);
    assert_err_names(
        read_las(&path).unwrap_err(),
        &path,
        "all 3 points are flagged withheld",
    );
}

//! Writing points as LAS/LAZ in a survey's own CRS: coordinates back in
//! its units and its CRS records copied, so that what is written from a
//! map (a heat map, an export) lays over the survey in GIS tools.

use std::path::Path;

use las::{Builder, Color, Point, Transform, Vector, Vlr, Writer};

use crate::io::cloud::CloudError;
use crate::map::Georef;

/// Points to write: positions in metres (a map's frame) with a colour
/// each, and optionally an intensity and a point source id each.
#[derive(Debug, Clone, Default)]
pub struct LasPoints {
    pub points: Vec<[f64; 3]>,
    pub colors: Vec<[u8; 3]>,
    /// LAS intensity (0-65535), e.g. a similarity.
    pub intensity: Option<Vec<u16>>,
    /// LAS point source id, e.g. a feature row.
    pub source_id: Option<Vec<u16>>,
    /// LAS classification (ASPRS codes, at most 31 in the legacy point
    /// formats `write_las` uses without a WKT CRS); 0 without.
    pub classification: Option<Vec<u8>>,
}

/// Coarsest coordinate step written, metres (a millimetre).
const STEP_M: f64 = 0.001;

/// The scale and offset that hold `lo..=hi` (in units of `metres_per_unit`
/// m) in 32-bit integers: the power of ten at or below [`STEP_M`] in those
/// units (0.001 for metres and feet, 1e-6 for kilometres),
/// coarser by tens for a larger extent; the offset a whole number at or
/// below `lo`.
fn transform(lo: f64, hi: f64, metres_per_unit: f64) -> Transform {
    let offset = lo.floor();
    let mut scale = 10f64.powi((STEP_M / metres_per_unit).log10().floor() as i32);
    while (hi - offset) / scale > f64::from(i32::MAX) - 1.0 {
        scale *= 10.0;
    }
    Transform { scale, offset }
}

/// Writes `pts` to `path` (LAZ when its name ends in `.laz`), atomically.
/// With `georef`, coordinates are converted back into the survey's units
/// and its governing CRS records copied: LAS 1.4 (point format 7, WKT bit
/// set) with the WKT record when it governs, else LAS 1.2 (point format 2)
/// with the GeoTIFF records (keys, doubles, citations). Without, LAS 1.2
/// in metres, no CRS record.
pub fn write_las(path: &Path, pts: &LasPoints, georef: Option<&Georef>) -> Result<(), CloudError> {
    let err = |reason: String| CloudError::format(path, reason);
    let laz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
    let source: Vec<[f64; 3]> = match georef {
        Some(g) => pts.points.iter().map(|&p| g.to_source(p)).collect(),
        None => pts.points.clone(),
    };
    let wkt = georef.is_some_and(Georef::wkt_governs);
    let mut b = Builder::from(if wkt { (1, 4) } else { (1, 2) });
    b.point_format =
        las::point::Format::new(if wkt { 7 } else { 2 }).map_err(|e| err(e.to_string()))?;
    b.point_format.is_compressed = laz;
    b.has_wkt_crs = wkt;
    b.generating_software = format!("omcl {}", env!("CARGO_PKG_VERSION"));
    if let Some(g) = georef {
        // The governing kind only: LAS 1.4 allows "GeoTIFF or WKT, but
        // not both", and a reader of a 1.2 file ignores a WKT record.
        b.vlrs = g
            .records
            .iter()
            .filter(|(id, _)| (*id == 2112) == wkt)
            .map(|(id, data)| Vlr {
                user_id: "LASF_Projection".into(),
                record_id: *id,
                description: String::new(),
                data: data.clone(),
            })
            .collect();
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &source {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    if source.is_empty() {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    let [xy, z] = georef.map_or([1.0, 1.0], |g| g.metres_per_unit);
    b.transforms = Vector {
        x: transform(lo[0], hi[0], xy),
        y: transform(lo[1], hi[1], xy),
        z: transform(lo[2], hi[2], z),
    };
    let header = b.into_header().map_err(|e| err(e.to_string()))?;
    let bytes = {
        let cursor = std::io::Cursor::new(Vec::new());
        let mut w = Writer::new(cursor, header).map_err(|e| err(e.to_string()))?;
        for (i, p) in source.iter().enumerate() {
            let c = pts.colors.get(i).copied().unwrap_or([0; 3]);
            // 8-bit colour spread over 16 bits, as LAS expects.
            let wide = |v: u8| u16::from(v) * 257;
            // ASPRS class 12 (overlap) is a flag to the las crate: it
            // writes code 12 in the legacy formats, and in format 7
            // "unclassified" with the overlap bit, as LAS 1.4 has it.
            let code = pts.classification.as_ref().map_or(0, |v| v[i]);
            let (classification, is_overlap) = match code {
                12 => (las::point::Classification::Unclassified, true),
                c => (
                    las::point::Classification::new(c).map_err(|e| err(e.to_string()))?,
                    false,
                ),
            };
            w.write_point(Point {
                x: p[0],
                y: p[1],
                z: p[2],
                intensity: pts.intensity.as_ref().map_or(0, |v| v[i]),
                point_source_id: pts.source_id.as_ref().map_or(0, |v| v[i]),
                classification,
                is_overlap,
                color: Some(Color::new(wide(c[0]), wide(c[1]), wide(c[2]))),
                gps_time: wkt.then_some(0.0),
                // One return a pulse: the spec's numbers start at 1.
                return_number: 1,
                number_of_returns: 1,
                ..Default::default()
            })
            .map_err(|e| err(e.to_string()))?;
        }
        w.into_inner().map_err(|e| err(e.to_string()))?.into_inner()
    };
    crate::io::atomic::write(path, &bytes).map_err(|e| CloudError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transform_holds_the_extent_in_32_bits_at_a_millimetre_or_finer() {
        let t = transform(1_234_567.891, 1_234_600.0, 1.0);
        assert_eq!((t.scale, t.offset), (0.001, 1_234_567.0));
        // 5,000 km at 1 mm would overflow: 1 cm steps.
        let t = transform(0.0, 5.0e6, 1.0);
        assert!((t.scale - 0.01).abs() < 1e-15, "{}", t.scale);
        assert!((5.0e6 - t.offset) / t.scale <= f64::from(i32::MAX));
        // Feet: 0.001 ft (0.3 mm); kilometres: 1e-6 km (1 mm), not 1 m.
        let t = transform(2_000_000.0, 2_001_000.0, 0.3048);
        assert!((t.scale - 1e-3).abs() < 1e-18, "{}", t.scale);
        let t = transform(500.0, 501.0, 1000.0);
        assert!((t.scale - 1e-6).abs() < 1e-20, "{}", t.scale);
    }
}

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
}

/// Finest coordinate step written, in the file's units.
const FINEST_SCALE: f64 = 0.001;

/// The scale and offset that hold `lo..=hi` in 32-bit integers: steps of
/// [`FINEST_SCALE`], coarser by tens for a larger extent; the offset a
/// whole number at or below `lo`.
fn transform(lo: f64, hi: f64) -> Transform {
    let offset = lo.floor();
    let mut scale = FINEST_SCALE;
    while (hi - offset) / scale > f64::from(i32::MAX) - 1.0 {
        scale *= 10.0;
    }
    Transform { scale, offset }
}

/// Writes `pts` to `path` (LAZ when its name ends in `.laz`), atomically.
/// With `georef`, coordinates are converted back into the survey's units
/// and its CRS records copied: LAS 1.4 (point format 7, WKT bit set) when
/// its WKT record governs, else LAS 1.2 (point format 2) with its GeoTIFF
/// keys. Without, LAS 1.2 in metres, no CRS record.
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
        b.vlrs = g
            .records
            .iter()
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
    b.transforms = Vector {
        x: transform(lo[0], hi[0]),
        y: transform(lo[1], hi[1]),
        z: transform(lo[2], hi[2]),
    };
    let header = b.into_header().map_err(|e| err(e.to_string()))?;
    let bytes = {
        let cursor = std::io::Cursor::new(Vec::new());
        let mut w = Writer::new(cursor, header).map_err(|e| err(e.to_string()))?;
        for (i, p) in source.iter().enumerate() {
            let c = pts.colors.get(i).copied().unwrap_or([0; 3]);
            // 8-bit colour spread over 16 bits, as LAS expects.
            let wide = |v: u8| u16::from(v) * 257;
            w.write_point(Point {
                x: p[0],
                y: p[1],
                z: p[2],
                intensity: pts.intensity.as_ref().map_or(0, |v| v[i]),
                point_source_id: pts.source_id.as_ref().map_or(0, |v| v[i]),
                color: Some(Color::new(wide(c[0]), wide(c[1]), wide(c[2]))),
                gps_time: wkt.then_some(0.0),
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
    fn the_transform_holds_the_extent_in_32_bits() {
        let t = transform(1_234_567.891, 1_234_600.0);
        assert_eq!((t.scale, t.offset), (0.001, 1_234_567.0));
        // 5,000 km at 1 mm would overflow: 1 cm steps.
        let t = transform(0.0, 5.0e6);
        assert_eq!(t.scale, 0.01);
        assert!((5.0e6 - t.offset) / t.scale <= f64::from(i32::MAX));
    }
}

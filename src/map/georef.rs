//! Where a map lies on the earth: the coordinate reference system (CRS)
//! of the survey it was built from, kept so that what is written from the
//! map (a query's heat map, an export as LAS) overlays the survey again.
//!
//! omcl does not reproject. A map's coordinates are the source's, in
//! metres: a source in feet was scaled on reading, by
//! [`Georef::metres_per_unit`]. The CRS records are kept as the source
//! stated them (LAS `LASF_Projection` records: OGC WKT 2112, GeoTIFF keys
//! 34735, doubles 34736 and texts 34737) and written back unchanged.
//!
//! In a map file (version 3) a georeference is five header fields,
//! [`FIELDS`], all covered by the checksum; a map without one leaves them
//! out.

/// Record ids of the CRS records a georeference keeps: OGC math transform
/// WKT (2111), OGC coordinate system WKT (2112), GeoTIFF key directory
/// (34735), doubles (34736) and ASCII texts (34737).
pub const CRS_RECORD_IDS: [u16; 5] = [2111, 2112, 34735, 34736, 34737];

/// The map file's header fields of a georeference, in checksum order.
pub const FIELDS: [&str; 5] = [
    "crs",
    "crs_records",
    "crs_wkt",
    "metres_per_unit_xy",
    "metres_per_unit_z",
];

/// The source CRS of a map built from a georeferenced survey.
#[derive(Debug, Clone, PartialEq)]
pub struct Georef {
    /// The CRS in words, as the source names it, e.g.
    /// `NAD83(HARN) / New Mexico Central (ftUS) (EPSG:2903)`.
    pub crs: String,
    /// The source's CRS records, `(record id, bytes)`, sorted by id, each
    /// id one of [`CRS_RECORD_IDS`].
    pub records: Vec<(u16, Vec<u8>)>,
    /// Whether the WKT record governs (the LAS header's WKT bit), rather
    /// than the GeoTIFF keys.
    pub wkt: bool,
    /// Metres per source unit: `[x and y, z]` (1 for a survey in metres).
    pub metres_per_unit: [f64; 2],
}

/// What is wrong with a georeference's header fields: the field and what
/// it should be.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldProblem {
    pub field: &'static str,
    /// The value found; `None` when the field is missing.
    pub value: Option<String>,
    pub expected: &'static str,
}

impl Georef {
    /// A map coordinate (metres) in the source's units.
    pub fn to_source(&self, p: [f64; 3]) -> [f64; 3] {
        let [xy, z] = self.metres_per_unit;
        [p[0] / xy, p[1] / xy, p[2] / z]
    }

    /// Whether the WKT record governs rather than the GeoTIFF keys (the
    /// LAS rule: WKT when the WKT bit is set, either when alone).
    pub fn wkt_governs(&self) -> bool {
        let has = |id: u16| self.records.iter().any(|r| r.0 == id);
        has(2112) && (self.wkt || !has(34735))
    }

    /// The header fields, [`FIELDS`] in order.
    pub fn to_fields(&self) -> [String; 5] {
        let records: Vec<String> = self
            .records
            .iter()
            .map(|(id, bytes)| format!("{id}:{}", hex(bytes)))
            .collect();
        [
            self.crs.clone(),
            records.join(" "),
            self.wkt.to_string(),
            format!("{:?}", self.metres_per_unit[0]),
            format!("{:?}", self.metres_per_unit[1]),
        ]
    }

    /// Reads the header fields (`field` gives a field's value, `None` when
    /// absent): `Ok(None)` when none of [`FIELDS`] is there, an error
    /// naming the field when some are missing or any is not valid.
    pub fn from_fields<'a>(
        field: impl Fn(&str) -> Option<&'a str>,
    ) -> Result<Option<Georef>, FieldProblem> {
        if FIELDS.iter().all(|f| field(f).is_none()) {
            return Ok(None);
        }
        let get = |name: &'static str, expected: &'static str| {
            field(name).ok_or(FieldProblem {
                field: name,
                value: None,
                expected,
            })
        };
        let bad = |field: &'static str, value: &str, expected: &'static str| FieldProblem {
            field,
            value: Some(value.to_string()),
            expected,
        };
        const TEXT: &str = "the CRS in words (present with the other crs fields)";
        let crs = get("crs", TEXT)?;
        if crs.trim().is_empty() {
            return Err(bad("crs", crs, TEXT));
        }
        const RECORDS: &str = "CRS records as `id:hex` separated by spaces, ids among 2111, 2112, 34735-34737, \
             ascending, at least one";
        let text = get("crs_records", RECORDS)?;
        let mut records: Vec<(u16, Vec<u8>)> = Vec::new();
        for item in text.split(' ') {
            let parsed = item
                .split_once(':')
                .and_then(|(id, data)| Some((id.parse::<u16>().ok()?, unhex(data)?)))
                .filter(|(id, _)| CRS_RECORD_IDS.contains(id))
                .filter(|(id, _)| records.last().is_none_or(|(last, _)| last < id));
            match parsed {
                Some(r) => records.push(r),
                None => return Err(bad("crs_records", text, RECORDS)),
            }
        }
        const WKT: &str = "true or false";
        let wkt_text = get("crs_wkt", WKT)?;
        let wkt = wkt_text
            .parse::<bool>()
            .map_err(|_| bad("crs_wkt", wkt_text, WKT))?;
        const FACTOR: &str = "metres per source unit, a finite number above 0";
        let factor = |name: &'static str| {
            let t = get(name, FACTOR)?;
            t.parse::<f64>()
                .ok()
                .filter(|m| m.is_finite() && *m > 0.0)
                .ok_or_else(|| bad(name, t, FACTOR))
        };
        Ok(Some(Georef {
            crs: crs.to_string(),
            records,
            wkt,
            metres_per_unit: [factor("metres_per_unit_xy")?, factor("metres_per_unit_z")?],
        }))
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Hex digits to bytes; empty text is an empty record.
fn unhex(text: &str) -> Option<Vec<u8>> {
    if !text.len().is_multiple_of(2) {
        return None;
    }
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(text.get(i..i + 2)?, 16).ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn sample() -> Georef {
        Georef {
            crs: "NAD83(HARN) / New Mexico Central (ftUS) (EPSG:2903)".into(),
            records: vec![
                (2112, b"PROJCS[\"x\"]".to_vec()),
                (34735, vec![1, 0, 1, 0]),
                (34737, Vec::new()),
            ],
            wkt: true,
            metres_per_unit: [1200.0 / 3937.0, 1.0],
        }
    }

    fn fields(g: &Georef) -> HashMap<&'static str, String> {
        FIELDS.into_iter().zip(g.to_fields()).collect()
    }

    #[test]
    fn fields_read_back_exactly() {
        let g = sample();
        let f = fields(&g);
        let back = Georef::from_fields(|k| f.get(k).map(String::as_str)).unwrap();
        assert_eq!(back, Some(g));
        assert_eq!(Georef::from_fields(|_| None).unwrap(), None);
    }

    #[test]
    fn source_units_undo_the_scaling() {
        let g = sample();
        let ft = 1200.0 / 3937.0;
        let p = g.to_source([3.0 * ft, -6.0 * ft, 2.5]);
        assert!((p[0] - 3.0).abs() < 1e-12 && (p[1] + 6.0).abs() < 1e-12 && p[2] == 2.5);
    }

    #[test]
    fn a_missing_or_damaged_field_is_named() {
        let g = sample();
        for (field, value) in [
            ("crs", None),
            ("crs_records", Some("2112:zz")),
            ("crs_records", Some("34735:00 2112:00")),
            ("crs_records", Some("7:00")),
            ("crs_records", Some("2112:0")),
            ("crs_records", Some("")),
            ("crs_wkt", Some("yes")),
            ("metres_per_unit_xy", Some("0")),
            ("metres_per_unit_z", Some("NaN")),
            ("metres_per_unit_z", None),
        ] {
            let mut f = fields(&g);
            match value {
                Some(v) => f.insert(field, v.to_string()),
                None => f.remove(field),
            };
            let e = Georef::from_fields(|k| f.get(k).map(String::as_str)).unwrap_err();
            assert_eq!(e.field, field, "{field} = {value:?}");
        }
    }
}

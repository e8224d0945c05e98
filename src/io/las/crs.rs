//! The linear units of a LAS file's coordinates, from the coordinate
//! reference system its records state: OGC WKT (`LASF_Projection` record
//! 2112) or GeoTIFF keys (record 34735, doubles in 34736), the header's
//! WKT bit choosing when a file has both.
//! Parsing only, no EPSG database: a unit is the file's own, or, for a
//! GeoTIFF CRS named by its EPSG code alone, the code's unit from the
//! table in `epsg.rs` (made from EPSG's dataset).

use super::epsg;
use las::{Header, Vlr};

/// A linear unit and where the file states it.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Unit {
    /// Metres per unit.
    pub metres: f64,
    /// The file's own words, e.g. `WKT UNIT["foot",0.3048]` or
    /// `GeoTIFF ProjLinearUnitsGeoKey 9002`.
    pub source: String,
}

/// What a file's CRS records say about its coordinates' units.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Units {
    /// No CRS record: metres assumed, nothing to tell.
    Unstated,
    /// The horizontal unit, and the vertical one if stated apart
    /// (otherwise z counts in the horizontal unit); `remarks` are
    /// doubts worth a note (a unit's name and factor disagreeing).
    Stated {
        xy: Unit,
        z: Option<Unit>,
        remarks: Vec<String>,
    },
    /// A CRS record that does not tell the unit (unreadable, or no unit
    /// in it): metres assumed; why, for the note.
    Unknown(String),
}

/// EPSG linear units of measure: code, metres per unit, plural name.
/// GeoTIFF uses these codes (9001-9003 nearly always).
const EPSG_UNITS: [(u16, f64, &str); 14] = [
    (9001, 1.0, "metres"),
    (9002, 0.3048, "international feet"),
    (9003, 1200.0 / 3937.0, "US survey feet"),
    (9005, 0.304_797_265_4, "Clarke's feet"),
    (9014, 1.8288, "fathoms"),
    (9030, 1852.0, "nautical miles"),
    (9033, 79_200.0 / 3937.0, "US survey chains"),
    (9034, 792.0 / 3937.0, "US survey links"),
    (9035, 6_336_000.0 / 3937.0, "US survey miles"),
    (9036, 1000.0, "kilometres"),
    (9093, 1609.344, "statute miles"),
    (9096, 0.9144, "yards"),
    (9097, 20.1168, "chains"),
    (9098, 0.201_168, "links"),
];

fn same_factor(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-8 * b.abs()
}

fn is_metre(m: f64) -> bool {
    same_factor(m, 1.0)
}

/// "international feet" for 0.3048, or "units of 0.5 m".
pub(super) fn unit_words(metres: f64) -> String {
    if let Some((_, _, w)) = EPSG_UNITS.iter().find(|(_, m, _)| same_factor(metres, *m)) {
        return w.to_string();
    }
    match epsg::LENGTH_UNITS.iter().find(|u| same_factor(metres, u.1)) {
        Some((_, _, name)) => format!("units of {metres} m (EPSG's {name})"),
        None => format!("units of {metres} m"),
    }
}

/// Metres per unit of a unit name WKT writers use, when the name alone
/// says (OGC, EPSG and ESRI spellings).
fn factor_of_name(name: &str) -> Option<f64> {
    let key: String = name
        .chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect();
    match key.as_str() {
        "metre" | "meter" | "metres" | "meters" | "m" => Some(1.0),
        "foot" | "feet" | "ft" | "internationalfoot" | "footinternational" => Some(0.3048),
        "ussurveyfoot" | "ussurveyfeet" | "footus" | "ftus" | "usfoot" | "usft"
        | "footussurvey" => Some(1200.0 / 3937.0),
        _ => None,
    }
}

/// Scale factors to metres (`[x and y, z]`) and the notes that say
/// what was done, each naming the file (`name`).
pub(super) fn to_metres(name: &str, units: &Units) -> ([f64; 2], Vec<String>) {
    match units {
        Units::Unstated => ([1.0, 1.0], Vec::new()),
        Units::Unknown(why) => (
            [1.0, 1.0],
            vec![format!(
                "{name}: {why}; its coordinates were taken as metres"
            )],
        ),
        Units::Stated { xy, z, remarks } => {
            let mut notes: Vec<String> = remarks.iter().map(|r| format!("{name}: {r}")).collect();
            let zu = z.as_ref().unwrap_or(xy);
            if !(is_metre(xy.metres) && is_metre(zu.metres)) {
                notes.push(match z {
                    None => format!(
                        "{name}: coordinates in {} ({}) converted to metres",
                        unit_words(xy.metres),
                        xy.source
                    ),
                    Some(z) if same_factor(z.metres, xy.metres) => format!(
                        "{name}: coordinates in {} ({}; z: {}) converted to metres",
                        unit_words(xy.metres),
                        xy.source,
                        z.source
                    ),
                    Some(z) => format!(
                        "{name}: x and y in {} ({}), z in {} ({}); converted to metres",
                        unit_words(xy.metres),
                        xy.source,
                        unit_words(z.metres),
                        z.source
                    ),
                });
            }
            // Within rounding of a metre is a metre: exactly 1, no note.
            let factor = |m: f64| if is_metre(m) { 1.0 } else { m };
            ([factor(xy.metres), factor(zu.metres)], notes)
        }
    }
}

fn projection_record(header: &Header, id: u16) -> Option<&Vlr> {
    header
        .all_vlrs()
        .find(|v| v.record_id == id && v.user_id.eq_ignore_ascii_case("LASF_Projection"))
}

/// The units `header`'s CRS records state; an error (the reason, for a
/// message naming the file) for coordinates that cannot be made metres:
/// a geographic CRS (degrees) or a unit code this module does not know.
/// When a file has both, the header's global encoding chooses, as the LAS
/// specification does: WKT when its WKT bit is set (always in point
/// formats 6-10), else the GeoTIFF keys. Either is read when it is the
/// only one, and when the chosen one cannot be read, the other may still
/// tell.
pub(super) fn units(header: &Header) -> Result<Units, String> {
    let wkt = || projection_record(header, 2112).map(|v| wkt_units(&v.data));
    let geotiff = || {
        projection_record(header, 34735)
            .map(|keys| geotiff_units(&keys.data, projection_record(header, 34736)))
    };
    let (first, second): (&dyn Fn() -> _, &dyn Fn() -> _) = if header.has_wkt_crs() {
        (&wkt, &geotiff)
    } else {
        (&geotiff, &wkt)
    };
    match first() {
        Some(Ok(Units::Unknown(why))) => match second() {
            Some(Ok(Units::Unknown(_))) | None => Ok(Units::Unknown(why)),
            Some(other) => other,
        },
        Some(chosen) => chosen,
        None => second().unwrap_or(Ok(Units::Unstated)),
    }
}

const REPROJECT: &str = "reproject the cloud to a projected CRS in metres (UTM, say; \
                         PDAL and LAStools do it) first";

// ---- GeoTIFF keys ------------------------------------------------------

/// A GeoKeyDirectory (record 34735): u16 little-endian, a 4-value header
/// then 4 values a key: id, location, count, value (or offset).
struct GeoKeys<'a>(&'a [u8]);

impl GeoKeys<'_> {
    fn word(&self, i: usize) -> Option<u16> {
        self.0
            .get(2 * i..2 * i + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    }

    /// Number of keys; `None` when the directory is truncated.
    fn count(&self) -> Option<u16> {
        self.word(3)
    }

    /// Key `id`: (location, count, value); location 0 holds the value
    /// itself, 34736 and 34737 an index into those records.
    fn key(&self, id: u16) -> Option<(u16, u16, u16)> {
        (0..self.count()? as usize).find_map(|k| {
            let at = 4 + 4 * k;
            (self.word(at)? == id).then_some((
                self.word(at + 1)?,
                self.word(at + 2)?,
                self.word(at + 3)?,
            ))
        })
    }

    /// A key whose value is a short.
    fn short(&self, id: u16) -> Option<u16> {
        self.key(id).and_then(|(loc, _, v)| (loc == 0).then_some(v))
    }

    /// A key whose value is a double of record 34736 (`doubles`).
    fn double(&self, id: u16, doubles: Option<&Vlr>) -> Option<f64> {
        let (loc, _, index) = self.key(id)?;
        let at = 8 * index as usize;
        (loc == 34736)
            .then(|| doubles?.data.get(at..at + 8))
            .flatten()
            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    }

    /// A key whose value is text of record 34737 (`texts`, Latin-1 as
    /// GeoTIFF writes it): its first part, up to the `|` that ends a
    /// part.
    fn text(&self, id: u16, texts: Option<&Vlr>) -> Option<String> {
        let (loc, count, offset) = self.key(id)?;
        let bytes = texts?
            .data
            .get(offset as usize..offset as usize + count as usize)?;
        (loc == 34737).then(|| {
            let t: String = bytes.iter().map(|&b| char::from(b)).collect();
            let first = t.split(['|', '\0']).next().unwrap_or_default();
            first.trim().to_string()
        })
    }
}

/// Reads the units of a GeoKeyDirectory (`keys`).
fn geotiff_units(keys: &[u8], doubles: Option<&Vlr>) -> Result<Units, String> {
    let keys = GeoKeys(keys);
    if keys.count().is_none() {
        return Ok(Units::Unknown(
            "its GeoTIFF key directory (record 34735) is truncated".into(),
        ));
    }
    let short = |id: u16| keys.short(id);
    let double = |id: u16| keys.double(id, doubles);
    let model = short(1024);
    // Without a model type, a geographic CRS key (GeodeticCRSGeoKey 2048)
    // and no projected one (3072) is a geographic CRS too.
    let geographic_only = model.is_none() && short(2048).is_some() && short(3072).is_none();
    if model == Some(2) || geographic_only {
        let why = match model {
            Some(_) => "GeoTIFF GTModelTypeGeoKey 2",
            None => "GeoTIFF GeodeticCRSGeoKey without a projected CRS",
        };
        return Err(format!(
            "coordinates are longitude and latitude in degrees (a geographic CRS: \
             {why}), not metres: {REPROJECT}"
        ));
    }
    // Geocentric CRSs state their unit in GeogLinearUnitsGeoKey.
    let (unit_key, unit_key_name) = if model == Some(3) {
        (2052, "GeogLinearUnitsGeoKey")
    } else {
        (3076, "ProjLinearUnitsGeoKey")
    };
    // The unit EPSG gives the projected CRS the keys name, if any.
    let crs = short(3072).filter(|_| model != Some(3));
    let implied_xy = crs.and_then(|c| epsg_crs_unit(&epsg::PROJECTED, c, "ProjectedCRSGeoKey"));
    let mut remarks = Vec::new();
    // The horizontal unit, or why it is not known.
    let xy: Result<Unit, String> = match short(unit_key).filter(|&c| c != 0) {
        Some(32767) => match double(3077) {
            Some(m) if m.is_finite() && m > 0.0 => Ok(Unit {
                metres: m,
                source: format!("GeoTIFF ProjLinearUnitSizeGeoKey {m}"),
            }),
            Some(m) => Err(format!(
                "its GeoTIFF CRS has a user-defined linear unit of size {m} m, not a length"
            )),
            None => Err("its GeoTIFF CRS has a user-defined linear unit without a size".into()),
        },
        Some(code) => match (epsg_unit(code, unit_key_name), &implied_xy) {
            (Some(unit), _) => {
                remarks.extend(disagreement(&unit, implied_xy.as_ref()));
                Ok(unit)
            }
            // A unit code EPSG does not have, beside a CRS code it has:
            // the CRS's unit, said.
            (None, Some(implied)) => {
                remarks.push(format!(
                    "its GeoTIFF {unit_key_name} {code} is not an EPSG length unit; {} was \
                     used",
                    implied.source
                ));
                Ok(implied.clone())
            }
            (None, None) => {
                return Err(format!(
                    "its GeoTIFF {unit_key_name} gives the unit code {code}, not a length unit \
                     of EPSG's: {REPROJECT}"
                ));
            }
        },
        // The CRS's code alone: its unit is EPSG's (most writers state
        // both, some only the code).
        None => implied_xy.clone().ok_or_else(|| match short(3072) {
            Some(32767) => "its GeoTIFF CRS is user-defined (ProjectedCRSGeoKey 32767) \
                            and states no linear unit (ProjLinearUnitsGeoKey)"
                .to_string(),
            Some(crs) => format!(
                "its GeoTIFF ProjectedCRSGeoKey {crs} is not a projected CRS of EPSG's \
                 dataset and it states no linear unit (ProjLinearUnitsGeoKey)"
            ),
            None => "its GeoTIFF keys state no linear unit".to_string(),
        }),
    };
    // A vertical unit omcl does not know leaves z as the horizontal unit,
    // with a remark, rather than refusing a file whose x and y are known.
    let implied_z =
        short(4096).and_then(|c| epsg_crs_unit(&epsg::VERTICAL, c, "VerticalCSTypeGeoKey"));
    let z = match short(4099).filter(|&c| c != 0) {
        Some(code) => match (epsg_unit(code, "VerticalUnitsGeoKey"), implied_z) {
            (Some(u), implied) => {
                remarks.extend(disagreement(&u, implied.as_ref()));
                Some(u)
            }
            (None, Some(implied)) => {
                remarks.push(format!(
                    "its GeoTIFF VerticalUnitsGeoKey {code} is not an EPSG length unit; {} \
                     was used",
                    implied.source
                ));
                Some(implied)
            }
            (None, None) => {
                remarks.push(format!(
                    "its GeoTIFF VerticalUnitsGeoKey gives the unit code {code}, not a length \
                     unit of EPSG's; z taken in the horizontal unit"
                ));
                None
            }
        },
        None => implied_z,
    };
    let xy = match (xy, &z) {
        (Ok(u), _) => u,
        // x and y unknown, z stated: z still counts in its unit (a file of
        // an EPSG code and a vertical CRS in feet had its heights read as
        // metres), x and y are taken as metres, and that is said.
        (Err(why), Some(_)) => {
            remarks.push(format!("{why}; x and y were taken as metres"));
            Unit {
                metres: 1.0,
                source: "taken as metres".into(),
            }
        }
        (Err(why), None) => return Ok(Units::Unknown(why)),
    };
    Ok(Units::Stated { xy, z, remarks })
}

/// The unit EPSG gives the CRS of `code` (a projected or vertical one,
/// per `table`), named by GeoTIFF key `key`; `None` for a code EPSG does
/// not have (a user-defined 32767, an ESRI code).
fn epsg_crs_unit(table: &[(u16, u16, u8)], code: u16, key: &str) -> Option<Unit> {
    let i = table.partition_point(|&(_, last, _)| last < code);
    let &(first, _, unit) = table.get(i).filter(|&&(first, _, _)| first <= code)?;
    debug_assert!(first <= code);
    let (name, metres) = epsg::UNITS[usize::from(unit)];
    // The factor GeoTIFF's own unit code gives, where one does (PROJ's US
    // survey foot is 1200/3937 but for the last bit): a file stating
    // `ProjLinearUnitsGeoKey 9003` and one leaving it to the code agree.
    let metres = EPSG_UNITS
        .iter()
        .map(|&(_, m, _)| m)
        .find(|&m| same_factor(m, metres))
        .unwrap_or(metres);
    Some(Unit {
        metres,
        source: format!("GeoTIFF {key} {code}: EPSG's {name}"),
    })
}

/// A remark when a unit key and the unit EPSG gives the named CRS
/// differ: the key is followed, as GDAL and libgeotiff do.
fn disagreement(key: &Unit, implied: Option<&Unit>) -> Option<String> {
    let implied = implied.filter(|i| !same_factor(i.metres, key.metres))?;
    Some(format!(
        "{} ({}) disagrees with {}; the unit key was followed",
        key.source,
        unit_words(key.metres),
        implied.source
    ))
}

/// The EPSG length unit of GeoTIFF unit code `code` (key `key`), if EPSG
/// has it.
fn epsg_unit(code: u16, key: &str) -> Option<Unit> {
    let metres = EPSG_UNITS
        .iter()
        .find(|(c, _, _)| *c == code)
        .map(|&(_, m, _)| m)
        .or_else(|| {
            let i = epsg::LENGTH_UNITS
                .binary_search_by_key(&code, |u| u.0)
                .ok()?;
            Some(epsg::LENGTH_UNITS[i].1)
        })?;
    Some(Unit {
        metres,
        source: format!("GeoTIFF {key} {code}"),
    })
}

// ---- OGC WKT -----------------------------------------------------------

/// A WKT value: `KEYWORD[args]` (or with parentheses), a quoted text,
/// or a bare number or word, unparsed.
#[derive(Debug, PartialEq)]
pub(super) enum Wkt {
    Node(String, Vec<Wkt>),
    Text(String),
    Bare(String),
}

impl Wkt {
    fn key(&self) -> Option<&str> {
        match self {
            Wkt::Node(k, _) => Some(k),
            _ => None,
        }
    }
    fn children(&self) -> impl Iterator<Item = &Wkt> {
        let args: &[Wkt] = match self {
            Wkt::Node(_, args) => args,
            _ => &[],
        };
        args.iter().filter(|a| a.key().is_some())
    }
    fn child(&self, keys: &[&str]) -> Option<&Wkt> {
        self.children().find(|c| {
            c.key()
                .is_some_and(|k| keys.iter().any(|w| w.eq_ignore_ascii_case(k)))
        })
    }
    /// The first argument, when it is a quoted text (the name).
    fn name(&self) -> &str {
        match self {
            Wkt::Node(_, args) => match args.first() {
                Some(Wkt::Text(t)) => t,
                _ => "",
            },
            _ => "",
        }
    }
}

/// Nesting deeper than real CRSs go (about 6) is refused, so that a
/// hostile record cannot exhaust the stack.
const MAX_DEPTH: usize = 32;

/// Parses WKT 1 or 2 text; `None` when it is not well formed.
pub(super) fn parse_wkt(text: &str) -> Option<Wkt> {
    let mut p = WktParser {
        s: text.as_bytes(),
        i: 0,
    };
    p.value(0)
}

struct WktParser<'a> {
    s: &'a [u8],
    i: usize,
}

impl WktParser<'_> {
    fn skip_space(&mut self) {
        while self.s.get(self.i).is_some_and(u8::is_ascii_whitespace) {
            self.i += 1;
        }
    }

    fn value(&mut self, depth: usize) -> Option<Wkt> {
        if depth > MAX_DEPTH {
            return None;
        }
        self.skip_space();
        if *self.s.get(self.i)? == b'"' {
            return self.text().map(Wkt::Text);
        }
        let start = self.i;
        while self
            .s
            .get(self.i)
            .is_some_and(|c| c.is_ascii_alphanumeric() || b"_.+-".contains(c))
        {
            self.i += 1;
        }
        if start == self.i {
            return None;
        }
        let word = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
        self.skip_space();
        if !matches!(self.s.get(self.i), Some(b'[' | b'(')) {
            return Some(Wkt::Bare(word));
        }
        self.i += 1;
        let mut args = Vec::new();
        loop {
            self.skip_space();
            if args.is_empty() && matches!(self.s.get(self.i), Some(b']' | b')')) {
                self.i += 1;
                break;
            }
            args.push(self.value(depth + 1)?);
            self.skip_space();
            match self.s.get(self.i)? {
                b',' => self.i += 1,
                b']' | b')' => {
                    self.i += 1;
                    break;
                }
                _ => return None,
            }
        }
        Some(Wkt::Node(word, args))
    }

    /// A quoted text; `""` inside stands for one quote.
    fn text(&mut self) -> Option<String> {
        self.i += 1;
        let mut out = Vec::new();
        loop {
            let c = *self.s.get(self.i)?;
            self.i += 1;
            if c == b'"' {
                if self.s.get(self.i) == Some(&b'"') {
                    out.push(b'"');
                    self.i += 1;
                } else {
                    break;
                }
            } else {
                out.push(c);
            }
        }
        Some(String::from_utf8_lossy(&out).into_owned())
    }
}

const PROJECTED: [&str; 3] = ["PROJCS", "PROJCRS", "PROJECTEDCRS"];
const GEOGRAPHIC: [&str; 3] = ["GEOGCS", "GEOGCRS", "GEOGRAPHICCRS"];
/// WKT 2 geodetic CRSs: geographic with an ellipsoidal coordinate
/// system, geocentric with a Cartesian one.
const GEODETIC: [&str; 2] = ["GEODCRS", "GEODETICCRS"];
const GEOCENTRIC: [&str; 1] = ["GEOCCS"];
const VERTICAL: [&str; 4] = ["VERT_CS", "VERTCS", "VERTCRS", "VERTICALCRS"];
const COMPOUND: [&str; 2] = ["COMPD_CS", "COMPOUNDCRS"];
const UNIT: [&str; 2] = ["UNIT", "LENGTHUNIT"];

fn is(node: &Wkt, keys: &[&str]) -> bool {
    node.key()
        .is_some_and(|k| keys.iter().any(|w| w.eq_ignore_ascii_case(k)))
}

fn is_geographic(node: &Wkt) -> bool {
    is(node, &GEOGRAPHIC)
        || (is(node, &GEODETIC) && node.child(&["CS"]).is_none_or(|cs| match cs {
            Wkt::Node(_, args) => {
                matches!(args.first(), Some(Wkt::Bare(t)) if t.eq_ignore_ascii_case("ellipsoidal"))
            }
            _ => false,
        }))
}

/// The length unit a CRS node states for its coordinates: its own
/// `UNIT`/`LENGTHUNIT`, else (WKT 2) its first axis's. Never a nested
/// CRS's (a PROJCS's GEOGCS counts in degrees) nor a parameter's.
fn length_unit(node: &Wkt) -> Option<&Wkt> {
    node.child(&UNIT)
        .or_else(|| node.child(&["AXIS"]).and_then(|a| a.child(&UNIT)))
}

/// A WKT unit node as a [`Unit`], with a remark when its name says
/// another factor than its number; `what` is "x and y" or "z".
fn wkt_unit(
    unit: &Wkt,
    prefix: &str,
    what: &str,
    remarks: &mut Vec<String>,
) -> Result<Unit, String> {
    let Wkt::Node(key, args) = unit else {
        return Err(String::new());
    };
    let name = unit.name();
    let raw = match args.get(1) {
        Some(Wkt::Bare(n)) => n.as_str(),
        _ => "",
    };
    let source = format!("WKT {prefix}{key}[\"{name}\",{raw}]");
    let metres = raw
        .parse::<f64>()
        .ok()
        .filter(|m| m.is_finite() && *m > 0.0)
        .ok_or_else(|| format!("its {source} gives no positive length factor"))?;
    if let Some(named) = factor_of_name(name)
        && !same_factor(metres, named)
    {
        remarks.push(format!(
            "{what}: {source} names a unit of {named} m but gives the factor {metres}; \
             the factor was used"
        ));
    }
    Ok(Unit { metres, source })
}

/// Reads the units of WKT text (`data`, NUL-terminated by LAS writers).
fn wkt_units(data: &[u8]) -> Result<Units, String> {
    let end = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let text = String::from_utf8_lossy(&data[..end]);
    let Some(parsed) = parse_wkt(&text) else {
        return Ok(Units::Unknown(
            "its WKT coordinate system (record 2112) could not be parsed".into(),
        ));
    };
    let mut root = &parsed;
    // WKT 2 BOUNDCRS: the data are in the source CRS.
    if is(root, &["BOUNDCRS"]) {
        match root.child(&["SOURCECRS"]).and_then(|s| s.children().next()) {
            Some(source) => root = source,
            None => return Ok(Units::Unknown("its WKT BOUNDCRS has no source CRS".into())),
        }
    }
    let (horizontal, vertical) = if is(root, &COMPOUND) {
        (
            root.children().find(|c| {
                is(c, &PROJECTED) || is(c, &GEOCENTRIC) || is(c, &GEOGRAPHIC) || is(c, &GEODETIC)
            }),
            root.child(&VERTICAL),
        )
    } else {
        // Some writers nest the VERT_CS inside the PROJCS.
        (Some(root), root.child(&VERTICAL))
    };
    let Some(horizontal) = horizontal else {
        return Ok(Units::Unknown(
            "its WKT coordinate system has no horizontal part".into(),
        ));
    };
    let key = horizontal.key().unwrap_or_default();
    if is_geographic(horizontal) {
        return Err(format!(
            "coordinates are longitude and latitude in degrees (a geographic CRS: WKT \
             {key}[\"{}\"]), not metres: {REPROJECT}",
            horizontal.name()
        ));
    }
    let mut remarks = Vec::new();
    let Some(unit) = length_unit(horizontal) else {
        return Ok(Units::Unknown(format!(
            "its WKT coordinate system {key}[\"{}\"] states no length unit",
            horizontal.name()
        )));
    };
    let xy = match wkt_unit(unit, "", "x and y", &mut remarks) {
        Ok(u) => u,
        Err(why) => return Ok(Units::Unknown(why)),
    };
    let z = match vertical.and_then(|v| Some((v, length_unit(v)?))) {
        Some((v, unit)) => {
            let prefix = format!("{} ", v.key().unwrap_or_default());
            match wkt_unit(unit, &prefix, "z", &mut remarks) {
                Ok(u) => Some(u),
                Err(why) => return Ok(Units::Unknown(why)),
            }
        }
        None => None,
    };
    Ok(Units::Stated { xy, z, remarks })
}

/// Whether the WKT record governs a file's CRS rather than the GeoTIFF
/// keys (the LAS rule, as [`units`] applies it; either when alone).
fn wkt_governs(header: &Header) -> bool {
    projection_record(header, 2112).is_some()
        && (header.has_wkt_crs() || projection_record(header, 34735).is_none())
}

/// The file's CRS in words: the governing record's name and codes, e.g.
/// `NAD83(HARN) / New Mexico Central (ftUS) (EPSG:2903)` or `UTM sone 32,
/// basert på EUREF89 (ETRS89/UTM) (EPSG:25832, vertical EPSG:5941)`;
/// `None` without a CRS record.
pub(super) fn describe(header: &Header) -> Option<String> {
    if wkt_governs(header) {
        return projection_record(header, 2112).map(|v| describe_wkt(&v.data));
    }
    let keys = GeoKeys(&projection_record(header, 34735)?.data);
    let texts = projection_record(header, 34737);
    let name = [3073, 1026, 2049]
        .into_iter()
        .find_map(|id| keys.text(id, texts).filter(|t| !t.trim().is_empty()))
        .map(|t| printable(&t));
    let code = |id: u16| keys.short(id).filter(|c| (1..32767).contains(c));
    let mut codes = Vec::new();
    // A projected CRS's own code; a user-defined one (32767) has none,
    // and its datum's geographic code (2048) is not the CRS's.
    match keys.short(3072) {
        Some(32767) => codes.push("user-defined projection".to_string()),
        Some(_) => codes.extend(code(3072).map(|c| format!("EPSG:{c}"))),
        None if keys.short(1024) != Some(1) => {
            codes.extend(code(2048).map(|c| format!("EPSG:{c}")))
        }
        None => {}
    }
    if let Some(c) = code(4096) {
        codes.push(format!("vertical EPSG:{c}"));
    }
    let name = name.unwrap_or_else(|| "a GeoTIFF CRS".to_string());
    Some(if codes.is_empty() {
        name
    } else {
        format!("{name} ({})", codes.join(", "))
    })
}

/// `text` fit for a terminal line: control characters (an escape
/// sequence, a line break in a citation) as `?`, and at most 200
/// characters (a 3 MB name was printed whole).
fn printable(text: &str) -> String {
    const MAX: usize = 200;
    let mut out: String = text
        .chars()
        .take(MAX)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().nth(MAX).is_some() {
        out.push_str("...");
    }
    out
}

/// A WKT record's CRS in words: its name and authority code.
fn describe_wkt(data: &[u8]) -> String {
    let end = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    let Some(root) = parse_wkt(&String::from_utf8_lossy(&data[..end])) else {
        return "a WKT CRS (record 2112) omcl cannot parse".to_string();
    };
    let name = match root.name().trim() {
        "" => root.key().unwrap_or("WKT").to_string(),
        n => n.to_string(),
    };
    let code = root.child(&["AUTHORITY", "ID"]).and_then(|id| match id {
        Wkt::Node(_, args) => match (args.first(), args.get(1)) {
            (Some(Wkt::Text(a)), Some(Wkt::Text(c) | Wkt::Bare(c))) => Some(format!("{a}:{c}")),
            _ => None,
        },
        _ => None,
    });
    // Printable and short as a whole: the authority and code are the
    // file's text too.
    printable(&match code {
        Some(c) => format!("{name} ({c})"),
        None => name,
    })
}

/// Every CRS record of the file (`LASF_Projection`, ids
/// [`crate::map::georef::CRS_RECORD_IDS`]), the first of each id, sorted:
/// what a map keeps to write its CRS back.
/// A WKT record is cut after its terminating NUL (what follows is
/// padding), and a record still larger than [`MAX_KEPT_RECORD`] is not
/// kept: a map's header holds them, and a 55 MB padded WKT record made
/// the map unwritable after the whole build.
pub(super) fn all_records(header: &Header) -> super::CrsRecords {
    let mut r: super::CrsRecords = Vec::new();
    for id in crate::map::georef::CRS_RECORD_IDS {
        if let Some(v) = projection_record(header, id) {
            let mut data = v.data.as_slice();
            if id == 2112
                && let Some(nul) = data.iter().position(|&b| b == 0)
            {
                data = &data[..=nul];
            }
            if data.len() <= MAX_KEPT_RECORD {
                r.push((id, data.to_vec()));
            }
        }
    }
    r
}

/// The largest CRS record a map keeps, bytes (a WKT is a few KiB).
pub(super) const MAX_KEPT_RECORD: usize = 1 << 20;

/// The records that state the file's coordinate reference system, as
/// [`units`] chooses them: the WKT record (2112) when the header's WKT bit
/// is set or there are no GeoTIFF keys, else the GeoTIFF keys (34735) and
/// doubles (34736), not the free-text strings (34737, citations); each
/// with its bytes, sorted by id; empty without. Tiles of one survey carry
/// the same; the other kind of record, which the file's readers ignore,
/// and the citations may differ between writers.
pub(super) fn records(header: &Header) -> super::CrsRecords {
    let all: Vec<&Vlr> = header
        .all_vlrs()
        .filter(|v| v.user_id.eq_ignore_ascii_case("LASF_Projection"))
        .collect();
    let governing: &[u16] = if wkt_governs(header) {
        &[2112]
    } else {
        &[34735, 34736]
    };
    let mut r: super::CrsRecords = all
        .iter()
        .filter(|v| governing.contains(&v.record_id))
        .map(|v| (v.record_id, v.data.clone()))
        .collect();
    r.sort();
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn wkt_parses_quotes_parentheses_and_bare_words() {
        let w = parse_wkt(r#"LOCAL_CS["a ""quoted"" name", UNIT ("Foot_US", 0.3048006096012192), AXIS["x",EAST]]"#)
            .unwrap();
        let Wkt::Node(k, args) = &w else {
            panic!("{w:?}")
        };
        assert_eq!(k, "LOCAL_CS");
        assert_eq!(args[0], Wkt::Text("a \"quoted\" name".into()));
        assert_eq!(
            args[1],
            Wkt::Node(
                "UNIT".into(),
                vec![
                    Wkt::Text("Foot_US".into()),
                    Wkt::Bare("0.3048006096012192".into())
                ]
            )
        );
        assert_eq!(
            args[2],
            Wkt::Node(
                "AXIS".into(),
                vec![Wkt::Text("x".into()), Wkt::Bare("EAST".into())]
            )
        );
        for bad in ["", "PROJCS[", "PROJCS[\"a\"", "PROJCS[\"a\" \"b\"]", "[1]"] {
            assert_eq!(parse_wkt(bad), None, "{bad}");
        }
        // Deeper than any CRS: refused, not a stack overflow.
        let deep = format!("{}1{}", "A[".repeat(10_000), "]".repeat(10_000));
        assert_eq!(parse_wkt(&deep), None);
    }

    #[test]
    fn esri_names_and_local_systems() {
        // ESRI writes Foot_US; a LOCAL_CS counts in its own UNIT.
        let u = wkt_units(br#"PROJCS["NAD_1983_StatePlane_Texas_Central_FIPS_4203_Feet",GEOGCS["GCS_North_American_1983",UNIT["Degree",0.0174532925199433]],PARAMETER["False_Easting",2296583.333333333],UNIT["Foot_US",0.3048006096012192]]"#).unwrap();
        let Units::Stated { xy, z, remarks } = u else {
            panic!("{u:?}")
        };
        assert!(same_factor(xy.metres, 1200.0 / 3937.0) && z.is_none() && remarks.is_empty());
        let u = wkt_units(br#"LOCAL_CS["site grid",UNIT["metre",1]]"#).unwrap();
        assert!(matches!(u, Units::Stated { xy, .. } if xy.metres == 1.0));
        // A unit that is not a positive length: not guessed.
        let u = wkt_units(br#"PROJCS["x",UNIT["foot",0]]"#).unwrap();
        assert!(
            matches!(u, Units::Unknown(ref why) if why.contains("no positive")),
            "{u:?}"
        );
        let u = wkt_units(br#"PROJCS["x",PROJECTION["Mercator"]]"#).unwrap();
        assert!(
            matches!(u, Units::Unknown(ref why) if why.contains("no length unit")),
            "{u:?}"
        );
    }

    fn key_bytes(words: &[u16]) -> Vec<u8> {
        words.iter().flat_map(|k| k.to_le_bytes()).collect()
    }

    #[test]
    fn a_vertical_unit_counts_when_the_horizontal_one_is_not_stated() {
        // A user-defined CRS (no ProjLinearUnitsGeoKey), vertical EPSG 5703
        // in international feet (VerticalUnitsGeoKey 9002).
        let keys = key_bytes(&[
            1u16, 1, 0, 3, 3072, 0, 1, 32767, 4096, 0, 1, 5703, 4099, 0, 1, 9002,
        ]);
        let u = geotiff_units(&keys, None).unwrap();
        let Units::Stated { xy, z, remarks } = u else {
            panic!("{u:?}")
        };
        assert_eq!(xy.metres, 1.0);
        assert_eq!(z.map(|z| z.metres), Some(0.3048));
        assert!(
            remarks.iter().any(|r| r.contains("taken as metres")),
            "{remarks:?}"
        );
        // EPSG 5703 is in metres: the key and the code disagree, said.
        assert!(
            remarks.iter().any(|r| r.contains(
                "VerticalUnitsGeoKey 9002 (international feet) disagrees with \
                 GeoTIFF VerticalCSTypeGeoKey 5703: EPSG's metre"
            )),
            "{remarks:?}"
        );
        // Without a vertical unit either: unknown, as before.
        let keys = key_bytes(&[1u16, 1, 0, 1, 3072, 0, 1, 32767]);
        assert!(matches!(
            geotiff_units(&keys, None).unwrap(),
            Units::Unknown(ref why) if why.contains("user-defined")
        ));
        // A code EPSG does not have (ESRI's 102100), likewise.
        let keys = key_bytes(&[1u16, 1, 0, 1, 3072, 0, 1, 40000]);
        assert!(matches!(
            geotiff_units(&keys, None).unwrap(),
            Units::Unknown(ref why) if why.contains("40000 is not a projected CRS")
        ));
    }

    #[test]
    fn a_crs_named_by_its_epsg_code_alone_has_the_code_s_unit() {
        let stated = |words: &[u16]| match geotiff_units(&key_bytes(words), None).unwrap() {
            Units::Stated { xy, z, remarks } => (xy, z, remarks),
            u => panic!("{u:?}"),
        };
        // NAD83 / California zone 3 (ftUS), no unit key: US survey feet,
        // z in them too (no vertical CRS).
        let (xy, z, remarks) = stated(&[1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 2227]);
        assert_eq!(xy.metres, 1200.0 / 3937.0);
        assert_eq!(
            xy.source,
            "GeoTIFF ProjectedCRSGeoKey 2227: EPSG's US survey foot"
        );
        assert!(z.is_none() && remarks.is_empty(), "{z:?} {remarks:?}");
        let ([h, v], notes) = to_metres("a.las", &Units::Stated { xy, z, remarks });
        assert_eq!([h, v], [1200.0 / 3937.0; 2]);
        assert_eq!(
            notes,
            [
                "a.las: coordinates in US survey feet (GeoTIFF ProjectedCRSGeoKey 2227: \
              EPSG's US survey foot) converted to metres"
            ]
        );
        // Arizona Central (ft): international feet; UTM 10N: metres.
        assert_eq!(stated(&[1, 1, 0, 1, 3072, 0, 1, 2223]).0.metres, 0.3048);
        assert_eq!(stated(&[1, 1, 0, 1, 3072, 0, 1, 32610]).0.metres, 1.0);
        // NAVD88 height (ftUS), EPSG 6360, without VerticalUnitsGeoKey.
        let (xy, z, _) = stated(&[1, 1, 0, 2, 3072, 0, 1, 26910, 4096, 0, 1, 6360]);
        assert_eq!(
            (xy.metres, z.map(|z| z.metres)),
            (1.0, Some(1200.0 / 3937.0))
        );
        // A unit key that contradicts the code is followed, with a remark.
        let (xy, _, remarks) = stated(&[1, 1, 0, 2, 3072, 0, 1, 2227, 3076, 0, 1, 9001]);
        assert_eq!(xy.metres, 1.0);
        assert_eq!(
            remarks,
            [
                "GeoTIFF ProjLinearUnitsGeoKey 9001 (metres) disagrees with GeoTIFF \
              ProjectedCRSGeoKey 2227: EPSG's US survey foot; the unit key was followed"
            ]
        );
        // The table's edges: its first and last runs, codes between runs.
        assert!(epsg_crs_unit(&epsg::PROJECTED, epsg::PROJECTED[0].0, "k").is_some());
        let last = epsg::PROJECTED[epsg::PROJECTED.len() - 1].1;
        assert!(epsg_crs_unit(&epsg::PROJECTED, last, "k").is_some());
        assert!(epsg_crs_unit(&epsg::PROJECTED, last + 1, "k").is_none());
        assert!(epsg_crs_unit(&epsg::PROJECTED, 0, "k").is_none());
        assert!(epsg_crs_unit(&epsg::PROJECTED, 2181, "k").is_none());
        // A deprecated code: NAD83 / Indiana East (ftUS), still in old files.
        assert_eq!(
            stated(&[1, 1, 0, 1, 3072, 0, 1, 2244]).0.metres,
            1200.0 / 3937.0
        );
        // A unit key of EPSG's beyond the common ones (Gold Coast foot,
        // 9094) is read; one EPSG lacks beside a known CRS gives way to
        // the CRS's unit, with a remark, for x, y and z.
        let gold = stated(&[1, 1, 0, 2, 3072, 0, 1, 2136, 3076, 0, 1, 9094]);
        assert!(
            (gold.0.metres - 0.304_799_710_181_508_8).abs() < 1e-12,
            "{gold:?}"
        );
        assert!(gold.2.is_empty(), "{gold:?}");
        assert!(unit_words(gold.0.metres).contains("EPSG's Gold Coast foot"));
        let (xy, z, remarks) = stated(&[
            1, 1, 0, 3, 3072, 0, 1, 2227, 3076, 0, 1, 9999, 4099, 0, 1, 9998,
        ]);
        assert_eq!(xy.metres, 1200.0 / 3937.0);
        assert!(z.is_none(), "{z:?}");
        assert!(
            remarks[0].contains("ProjLinearUnitsGeoKey 9999 is not an EPSG length unit")
                && remarks[0].contains("ProjectedCRSGeoKey 2227: EPSG's US survey foot was used"),
            "{remarks:?}"
        );
        assert!(
            remarks[1].contains("z taken in the horizontal unit"),
            "{remarks:?}"
        );
        let (_, z, remarks) = stated(&[
            1, 1, 0, 3, 3072, 0, 1, 26910, 4096, 0, 1, 6360, 4099, 0, 1, 9998,
        ]);
        assert_eq!(z.map(|z| z.metres), Some(1200.0 / 3937.0));
        assert!(
            remarks[0].contains("VerticalCSTypeGeoKey 6360"),
            "{remarks:?}"
        );
        assert!(epsg::PROJECTED.windows(2).all(|w| w[0].1 < w[1].0));
        assert!(epsg::VERTICAL.windows(2).all(|w| w[0].1 < w[1].0));
    }

    #[test]
    fn a_wkt_name_is_printable_authority_and_code_included() {
        let code = "9".repeat(5000);
        let wkt = format!("PROJCS[\"x\",AUTHORITY[\"EPSG\x1b[31mRED\n\",\"{code}\"]]");
        let d = describe_wkt(wkt.as_bytes());
        assert!(
            d.len() <= 203 && !d.contains('\x1b') && !d.contains('\n'),
            "{d}"
        );
        assert!(d.starts_with("x (EPSG?[31mRED?:999"), "{d}");
    }

    #[test]
    fn padded_and_oversized_crs_records_are_not_kept_whole() {
        let evlr = |id: u16, data: Vec<u8>| Vlr {
            user_id: "LASF_Projection".into(),
            record_id: id,
            description: String::new(),
            data,
        };
        let wkt = br#"PROJCS["x",UNIT["metre",1]]"#.to_vec();
        let mut padded = wkt.clone();
        padded.push(0);
        padded.resize(2 << 20, 0);
        let mut b = las::Builder::from((1, 4));
        b.point_format = las::point::Format::new(6).unwrap();
        b.evlrs = vec![evlr(2112, padded), evlr(34737, vec![b'a'; 2 << 20])];
        let h = b.into_header().unwrap();
        let kept = all_records(&h);
        let mut want = wkt;
        want.push(0);
        assert_eq!(kept, vec![(2112, want)]);
    }

    #[test]
    fn names_are_printable_and_short() {
        assert_eq!(printable("evil\x1b[31mRED\r\nX"), "evil?[31mRED??X");
        let long = "a".repeat(1000);
        assert_eq!(printable(&long).len(), 203);
        assert_eq!(
            printable("UTM sone 32, basert på"),
            "UTM sone 32, basert på"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn arbitrary_crs_records_never_panic(
            text in "[A-Z_\\[\\](),\" 0-9.e-]{0,120}",
            keys in proptest::collection::vec(any::<u8>(), 0..80),
            doubles in proptest::collection::vec(any::<u8>(), 0..40),
        ) {
            let _ = wkt_units(text.as_bytes());
            let d = Vlr { user_id: "LASF_Projection".into(), record_id: 34736, description: String::new(), data: doubles };
            let _ = geotiff_units(&keys, Some(&d));
            let _ = geotiff_units(&keys, None);
        }
    }
}

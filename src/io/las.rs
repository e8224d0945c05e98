//! LAS / LAZ point clouds (ASPRS LAS 1.0-1.4, LAZ through the `las` crate's
//! pure-Rust `laz` decoder).
//!
//! Coordinates come out with the header's scale and offset applied, in the
//! file's coordinate reference system, converted to metres when the CRS
//! its records state (OGC WKT, or GeoTIFF keys) counts in another linear
//! unit (feet, US survey feet, ...), with a note saying so. A geographic
//! CRS (degrees) is refused: reproject such a cloud first. A file without
//! a CRS record is taken to be in metres. Points flagged withheld (deleted)
//! are left out, with a note counting them. The classification code
//! becomes the label. Colour, when the point format has it, is 16 bits a
//! channel by the specification, but many writers store 0-255 in those 16
//! bits: when no channel in the file exceeds 255 the values are taken as
//! 8-bit, otherwise the high byte is kept.

use std::io::{Seek, SeekFrom};
use std::path::{Path, PathBuf};

use las::{PointDataBuilder, Reader};

use crate::io::cloud::{CloudError, PointCloud};
use crate::map::Georef;

/// Points decoded per batch, at most: bounds the reader's point buffer.
const BATCH: u64 = 1 << 18;
/// Bytes of raw point records decoded per batch, at most (a record may
/// declare up to 65,535 bytes).
const BATCH_BYTES: u64 = 16 << 20;
/// Points a byte of LAZ data can hold, at most. LAZ stores the first point
/// of every chunk raw and costs a fraction of a byte for each further
/// point; real files hold 1 to 3 points a byte. A header that claims more
/// is corrupt, and its count must not size memory.
const LAZ_POINTS_PER_BYTE: u64 = 256;

fn las_err(path: &Path, e: las::Error) -> CloudError {
    match e {
        las::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            CloudError::format(path, format!("truncated or corrupt LAS/LAZ file: {io}"))
        }
        // The LAZ decoder wraps short reads in its own error type.
        other if other.to_string().contains("failed to fill whole buffer") => {
            CloudError::format(path, format!("truncated or corrupt LAS/LAZ file: {other}"))
        }
        other => CloudError::format(path, format!("not a readable LAS/LAZ file: {other}")),
    }
}

/// Checks the raw header against the file size so that a truncated or
/// garbage file gets a precise message instead of a short read later.
/// Returns the file's size and whether its points are LAZ-compressed.
/// Returns the file's size, whether it is compressed, and a note when
/// whole point records follow the declared ones (a count too small: only
/// the declared ones are read).
fn check_raw_header(
    path: &Path,
    file: &mut std::fs::File,
) -> Result<(u64, bool, Option<String>), CloudError> {
    let size = file.metadata().map_err(|e| CloudError::io(path, e))?.len();
    let raw = las::raw::Header::read_from(&mut *file).map_err(|e| {
        CloudError::format(
            path,
            format!("not a LAS/LAZ file, or its header is truncated ({e})"),
        )
    })?;
    if &raw.file_signature != b"LASF" {
        return Err(CloudError::format(
            path,
            "not a LAS/LAZ file (no LASF signature)",
        ));
    }
    let (major, minor) = (raw.version.major, raw.version.minor);
    if major != 1 || minor > 4 {
        return Err(CloudError::format(
            path,
            format!(
                "LAS version {major}.{minor} is not one this reader knows (1.0 to 1.4): a \
                 newer format, or a corrupt header"
            ),
        ));
    }
    let n = raw
        .large_file
        .map(|l| l.number_of_point_records)
        .filter(|&n| n > 0)
        .unwrap_or(raw.number_of_point_records as u64);
    // Coordinates are integers times the scale plus the offset: a zero
    // scale put every x at the offset, a huge one every point far away.
    for (axis, scale, offset) in [
        ("x", raw.x_scale_factor, raw.x_offset),
        ("y", raw.y_scale_factor, raw.y_offset),
        ("z", raw.z_scale_factor, raw.z_offset),
    ] {
        if !(scale.is_finite() && scale > 0.0 && scale <= 1e3) {
            return Err(CloudError::format(
                path,
                format!(
                    "corrupt header: {axis} scale factor {scale:?} is not a number in (0, 1000]"
                ),
            ));
        }
        let far = crate::geometry::MAX_COORDINATE_M;
        if !(offset.is_finite() && offset.abs() <= far) {
            return Err(CloudError::format(
                path,
                format!(
                    "corrupt header: {axis} offset {offset:?} is not a finite number of metres within {far:e} of 0"
                ),
            ));
        }
    }
    // Bits 6 and 7 of the format byte mark LAZ compression.
    let compressed = raw.point_data_record_format & 0xC0 != 0;
    let start = raw.offset_to_point_data as u64;
    if start > size {
        return Err(CloudError::format(
            path,
            format!("point data offset {start} lies beyond the end of the {size}-byte file"),
        ));
    }
    check_vlrs(path, file, &raw, size)?;
    let need = (raw.point_data_record_length as u64).saturating_mul(n);
    if compressed {
        let data = size - start;
        if n > data.saturating_mul(LAZ_POINTS_PER_BYTE) {
            return Err(CloudError::format(
                path,
                format!(
                    "corrupt LAZ header: it declares {n} points, more than {data} bytes of \
                     compressed data can hold"
                ),
            ));
        }
        check_laz_chunk_table(path, file, start, size, raw.point_data_record_length)?;
    } else if start.saturating_add(need) > size {
        return Err(CloudError::format(
            path,
            format!(
                "truncated: header declares {n} points of {} bytes from offset {start}, \
                 but the file has {size} bytes",
                raw.point_data_record_length
            ),
        ));
    }
    let note = (!compressed)
        .then(|| surplus_records(&raw, n, start, size))
        .flatten()
        .map(|extra| {
            format!(
                "{}: {extra} more whole point records follow the {n} the header declares: \
                 only the declared {n} are read (a point count written too small?)",
                path.display()
            )
        });
    // The checks above moved the cursor: the decoder starts at byte 0.
    file.seek(SeekFrom::Start(0))
        .map_err(|e| CloudError::io(path, e))?;
    Ok((size, compressed, note))
}

/// Whole point records between the declared ones' end and the point
/// data's end (the first EVLR or waveform record, else the file's end),
/// when there are any.
fn surplus_records(raw: &las::raw::Header, n: u64, start: u64, size: u64) -> Option<u64> {
    let record = (raw.point_data_record_length as u64).max(1);
    let mut end = size;
    let after = [
        raw.evlr.as_ref().map(|e| e.start_of_first_evlr),
        raw.start_of_waveform_data_packet_record,
    ];
    for at in after.into_iter().flatten() {
        if at > start && at < end {
            end = at;
        }
    }
    let data_end = start.saturating_add(record.saturating_mul(n));
    let extra = end.saturating_sub(data_end) / record;
    (extra > 0).then_some(extra)
}

/// Reads `buf.len()` bytes at byte `at` of `file` (`None` past the end).
fn read_at(file: &mut std::fs::File, at: u64, buf: &mut [u8]) -> Option<()> {
    use std::io::Read;
    file.seek(SeekFrom::Start(at)).ok()?;
    file.read_exact(buf).ok()
}

/// Walks the variable-length records (54-byte headers, 16-bit lengths, after
/// the public header) and the extended ones (60-byte headers, 64-bit
/// lengths, from `start_of_first_evlr`): the `las` crate sizes a buffer from
/// each length before reading it, so every record must lie inside the file.
fn check_vlrs(
    path: &Path,
    file: &mut std::fs::File,
    raw: &las::raw::Header,
    size: u64,
) -> Result<(), CloudError> {
    // A record's length field sits 20 bytes into its header.
    let mut at_len = |at: u64, wide: bool| -> Option<u64> {
        let mut b = [0u8; 8];
        let n = if wide { 8 } else { 2 };
        read_at(file, at + 20, &mut b[..n])?;
        Some(u64::from_le_bytes(b))
    };
    let mut walk = |what: &str, mut at: u64, count: u64, head: u64, wide: bool| {
        for i in 0..count {
            let len = at
                .checked_add(head)
                .filter(|&end| end <= size)
                .and_then(|_| at_len(at, wide));
            let end = len.and_then(|l| at.checked_add(head)?.checked_add(l));
            match end {
                Some(end) if end <= size => at = end,
                _ => {
                    return Err(CloudError::format(
                        path,
                        format!(
                            "corrupt header: {what} {i} of {count} at byte {at} runs past the end \
                             of the {size}-byte file"
                        ),
                    ));
                }
            }
        }
        Ok(())
    };
    walk(
        "variable-length record",
        raw.header_size as u64,
        raw.number_of_variable_length_records as u64,
        54,
        false,
    )?;
    if let Some(e) = &raw.evlr {
        walk(
            "extended variable-length record",
            e.start_of_first_evlr,
            e.number_of_evlrs as u64,
            60,
            true,
        )?;
    }
    Ok(())
}

/// The LAZ chunk table's entry count sizes the decoder's table before any
/// entry is read: check it against the data that could hold the chunks (each
/// chunk stores its first point raw, so a chunk takes at least one record's
/// bytes).
fn check_laz_chunk_table(
    path: &Path,
    file: &mut std::fs::File,
    start: u64,
    size: u64,
    record_length: u16,
) -> Result<(), CloudError> {
    let mut read_u64_at = |at: u64| -> Option<u64> {
        let mut b = [0u8; 8];
        read_at(file, at, &mut b)?;
        Some(u64::from_le_bytes(b))
    };
    // The first 8 bytes of the point data give the table's offset; -1 means
    // "written at the end": the last 8 bytes of the file then give it.
    let Some(mut table) = read_u64_at(start) else {
        return Ok(());
    };
    if table as i64 == -1 && size >= 8 {
        table = read_u64_at(size - 8).unwrap_or(0);
    }
    let result = if table > start && table.saturating_add(8) <= size {
        read_u64_at(table).map(|v| (v >> 32) as u32 as u64)
    } else {
        // No table (the decoder then reads the points sequentially).
        None
    };
    if let Some(chunks) = result {
        let room = (table - start) / (record_length as u64).max(1);
        if chunks > room {
            return Err(CloudError::format(
                path,
                format!(
                    "corrupt LAZ chunk table: {chunks} chunks declared, but the {} bytes of \
                     point data hold at most {room}",
                    table - start
                ),
            ));
        }
    }
    Ok(())
}

/// Reads every point of a `.las` or `.laz` file that is not withheld, in
/// metres ([`PointCloud::notes`] says what was converted or left out).
pub fn read_las(path: &Path) -> Result<PointCloud, CloudError> {
    let mut chunks = LasChunks::open(path)?;
    let name = path.display().to_string();
    let cap = chunks.declared().min(1 << 20) as usize;
    let mut points = Vec::with_capacity(cap);
    let mut labels = Vec::with_capacity(cap);
    let mut rgb16: Vec<[u16; 3]> = Vec::with_capacity(if chunks.has_color() { cap } else { 0 });
    let mut left_out = Vec::new();
    while let Some(c) = chunks.next_chunk()? {
        points.extend_from_slice(&c.points);
        labels.extend_from_slice(&c.labels);
        rgb16.extend_from_slice(&c.rgb16);
        left_out.extend_from_slice(&c.withheld);
    }
    let n = chunks.declared();
    let mut notes = chunks.notes().to_vec();
    let withheld = left_out.len();
    if withheld > 0 {
        if points.is_empty() {
            return Err(CloudError::Empty {
                source_name: name,
                reason: format!("all {n} points are flagged withheld (deleted)"),
            });
        }
        notes.push(withheld_note(&name, withheld as u64, n));
    }
    let colors = chunks.has_color().then(|| {
        let eight_bit = rgb16.iter().all(|c| c.iter().all(|&v| v <= 255));
        rgb16
            .iter()
            .map(|c| {
                if eight_bit {
                    [c[0] as u8, c[1] as u8, c[2] as u8]
                } else {
                    [(c[0] >> 8) as u8, (c[1] >> 8) as u8, (c[2] >> 8) as u8]
                }
            })
            .collect()
    });
    let cloud = PointCloud {
        points,
        labels: Some(labels),
        colors,
        features: None,
        notes,
        left_out,
        georef: chunks.georef().cloned(),
    };
    cloud.validate(&name)?;
    cloud.non_empty(&name, "the file holds no points")
}

/// ASPRS classes 7 (low point, noise) and 18 (high noise): outliers, left
/// out unless asked for (`--keep-all`).
pub fn is_asprs_noise(class: u32) -> bool {
    matches!(class, 7 | 18)
}

/// The note on points flagged withheld.
pub fn withheld_note(name: &str, withheld: u64, of: u64) -> String {
    format!(
        "{name}: {withheld} of {of} points are flagged withheld (deleted by the \
         producer) and were left out"
    )
}

/// A LAS/LAZ file read a batch of points at a time, so that a file of
/// any size can be mapped in the memory of one batch ([`read_las`] reads
/// it whole). Its header is checked against the file's size on
/// [`LasChunks::open`], as for [`read_las`].
pub struct LasChunks {
    path: PathBuf,
    reader: Reader,
    batch: las::PointData,
    batch_points: u64,
    declared: u64,
    read: u64,
    kept: u64,
    to_metres: [f64; 2],
    extended: bool,
    has_color: bool,
    notes: Vec<String>,
    crs: CrsRecords,
    georef: Option<Georef>,
}

/// A LAS file's `LASF_Projection` records (its coordinate reference
/// system as stated): record id and bytes, sorted by id.
pub type CrsRecords = Vec<(u16, Vec<u8>)>;

/// One batch of a [`LasChunks`] file: the points not withheld, in metres,
/// with their classification codes and (when the format has colour) their
/// 16-bit colours, in the file's order.
#[derive(Debug, Default)]
pub struct LasChunk {
    /// Index of the chunk's first kept point among the file's kept points.
    pub first_kept: u64,
    /// Coordinates, metres.
    pub points: Vec<[f64; 3]>,
    /// Classification codes.
    pub labels: Vec<u32>,
    /// Colours as stored (16 bits a channel; empty without colour).
    pub rgb16: Vec<[u16; 3]>,
    /// Record indices (in the file) of the points flagged withheld.
    pub withheld: Vec<usize>,
}

impl LasChunks {
    /// Opens `path`, checks its header and reads its CRS.
    pub fn open(path: &Path) -> Result<Self, CloudError> {
        // Open ourselves so a missing file is an I/O error, not a format error.
        let mut file = std::fs::File::open(path).map_err(|e| CloudError::io(path, e))?;
        let (size, compressed, surplus) = check_raw_header(path, &mut file)?;
        let mut chunks =
            contain_decoder_panic(path, || Self::open_checked(path, file, size, compressed))?;
        chunks.notes.extend(surplus);
        Ok(chunks)
    }

    fn open_checked(
        path: &Path,
        file: std::fs::File,
        size: u64,
        compressed: bool,
    ) -> Result<Self, CloudError> {
        let reader = Reader::new(std::io::BufReader::with_capacity(1 << 20, file))
            .map_err(|e| las_err(path, e))?;
        let name = path.display().to_string();
        let units = crs::units(reader.header()).map_err(|reason| CloudError::Invalid {
            source_name: name.clone(),
            reason,
        })?;
        let (to_metres, notes) = crs::to_metres(&name, &units);
        let n = reader.header().number_of_points();
        let format = reader.header().point_format();
        let record = format.len().max(1) as u64;
        // The crate's count (legacy or 64-bit field, by version) against the
        // size once more: it is the one the reading trusts.
        let limit = if compressed {
            size.saturating_mul(LAZ_POINTS_PER_BYTE)
        } else {
            size / record
        };
        if n > limit {
            return Err(CloudError::format(
                path,
                format!(
                    "corrupt header: {n} points declared, the {size}-byte file holds at most {limit}"
                ),
            ));
        }
        Ok(Self {
            path: path.to_path_buf(),
            batch: PointDataBuilder::new().for_header(reader.header()).build(),
            batch_points: BATCH.min(BATCH_BYTES / record).max(1),
            declared: n,
            read: 0,
            kept: 0,
            to_metres,
            extended: format.is_extended,
            has_color: format.has_color,
            notes,
            crs: crs::records(reader.header()),
            georef: crs::describe(reader.header()).map(|crs| Georef {
                crs,
                records: crs::all_records(reader.header()),
                wkt: reader.header().has_wkt_crs(),
                metres_per_unit: to_metres,
            }),
            reader,
        })
    }

    /// Decodes at most `points` records a batch (at least 1; the default
    /// is 262,144, fewer for long records): the memory a batch takes.
    pub fn with_batch_points(mut self, points: u64) -> Self {
        self.batch_points = self.batch_points.min(points.max(1));
        self
    }

    /// Point records the header declares (withheld ones included).
    pub fn declared(&self) -> u64 {
        self.declared
    }

    /// Point records read so far.
    pub fn read(&self) -> u64 {
        self.read
    }

    /// Whether the point format carries colour.
    pub fn has_color(&self) -> bool {
        self.has_color
    }

    /// What was converted on the way (units), one line each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The CRS records that govern, to compare tiles' (the WKT record or
    /// the GeoTIFF ones, as the units are read; sorted by id, with their
    /// bytes; empty without).
    pub fn crs_records(&self) -> &[(u16, Vec<u8>)] {
        &self.crs
    }

    /// The file's CRS, with every CRS record and the scale to metres
    /// applied; `None` when it states none.
    pub fn georef(&self) -> Option<&Georef> {
        self.georef.as_ref()
    }

    /// The next batch, `None` after the last point; an error names the
    /// file (a truncated or corrupt one included) and ends the reading.
    pub fn next_chunk(&mut self) -> Result<Option<LasChunk>, CloudError> {
        if self.read >= self.declared {
            return Ok(None);
        }
        let path = self.path.clone();
        contain_decoder_panic(&path, || self.decode_batch().map(Some))
    }

    fn decode_batch(&mut self) -> Result<LasChunk, CloudError> {
        let path = &self.path;
        let n = self.declared;
        let got = self
            .reader
            .fill_points(self.batch_points.min(n - self.read), &mut self.batch)
            .map_err(|e| las_err(path, e))?;
        if got == 0 {
            return Err(CloudError::format(
                path,
                format!(
                    "truncated: header declares {n} points, file holds {}",
                    self.read
                ),
            ));
        }
        let first = self.read as usize;
        self.read += got;
        let batch = &self.batch;
        let [xy_to_m, z_to_m] = self.to_metres;
        let extended = self.extended;
        let mut chunk = LasChunk {
            first_kept: self.kept,
            points: Vec::with_capacity(got as usize),
            labels: Vec::with_capacity(got as usize),
            rgb16: Vec::with_capacity(if self.has_color { got as usize } else { 0 }),
            withheld: Vec::new(),
        };
        let mut rgb = batch.rgb();
        let kept = batch
            .raw_bytes()
            .chunks_exact(batch.record_len().max(1))
            .map(|r| !is_withheld(r, extended));
        let columns = batch
            .x()
            .zip(batch.y())
            .zip(batch.z())
            .zip(batch.classification())
            .zip(kept);
        for (i, ((((x, y), z), class), keep)) in columns.enumerate() {
            let colour = rgb.as_mut().and_then(Iterator::next);
            if !keep {
                chunk.withheld.push(first + i);
                continue;
            }
            chunk.points.push([x * xy_to_m, y * xy_to_m, z * z_to_m]);
            chunk.labels.push(u32::from(class));
            if let Some((r, g, b)) = colour {
                chunk.rgb16.push([r, g, b]);
            }
        }
        self.kept += chunk.points.len() as u64;
        Ok(chunk)
    }
}

/// Runs `f`, reporting a panic of the `laz` decoder (which asserts on some
/// corrupt streams instead of returning an error) like any other corrupt
/// file. The binary's panic hook keeps the decoder's message off the
/// terminal.
fn contain_decoder_panic<T>(
    path: &Path,
    f: impl FnOnce() -> Result<T, CloudError>,
) -> Result<T, CloudError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(CloudError::format(
            path,
            format!("corrupt LAZ point data (the decoder stopped: {why})"),
        ))
    })
}

/// The withheld flag of a raw point record: bit 7 of byte 15 (the
/// classification byte) in formats 0-5, bit 2 of byte 15 (the
/// classification flags) in formats 6-10.
fn is_withheld(record: &[u8], extended: bool) -> bool {
    let flags = record.get(15).copied().unwrap_or(0);
    if extended {
        flags & 0x04 != 0
    } else {
        flags & 0x80 != 0
    }
}

/// A length unit in words: "international feet" for 0.3048 (metres per
/// unit), "US survey feet", or "units of 0.5 m".
pub fn unit_words(metres: f64) -> String {
    crs::unit_words(metres)
}

/// The units of a LAS file's coordinates (see the module's own page).
mod crs;
mod epsg;
mod write;

pub use write::{LasPoints, write_las};

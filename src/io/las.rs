//! LAS / LAZ point clouds (ASPRS LAS 1.0-1.4, LAZ through the `las` crate's
//! pure-Rust `laz` decoder).
//!
//! Coordinates come out with the header's scale and offset applied, in the
//! file's coordinate reference system (usually projected metres). The
//! classification code becomes the label. Colour, when the point format has
//! it, is 16 bits a channel by the specification, but many writers store
//! 0-255 in those 16 bits: when no channel in the file exceeds 255 the
//! values are taken as 8-bit, otherwise the high byte is kept.

use std::io::{Seek, SeekFrom};
use std::path::Path;

use las::{PointDataBuilder, Reader};

use crate::io::cloud::{CloudError, PointCloud};

/// Points decoded per batch: bounds the reader's byte buffer.
const BATCH: u64 = 1 << 18;

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
fn check_raw_header(path: &Path, file: &mut std::fs::File) -> Result<(), CloudError> {
    let size = file.metadata().map_err(|e| CloudError::io(path, e))?.len();
    let raw = las::raw::Header::read_from(&mut *file).map_err(|e| {
        CloudError::format(
            path,
            format!("not a LAS/LAZ file, or its header is truncated ({e})"),
        )
    })?;
    file.seek(SeekFrom::Start(0))
        .map_err(|e| CloudError::io(path, e))?;
    if &raw.file_signature != b"LASF" {
        return Err(CloudError::format(
            path,
            "not a LAS/LAZ file (no LASF signature)",
        ));
    }
    let n = raw
        .large_file
        .map(|l| l.number_of_point_records)
        .filter(|&n| n > 0)
        .unwrap_or(raw.number_of_point_records as u64);
    // Bits 6 and 7 of the format byte mark LAZ compression.
    let compressed = raw.point_data_record_format & 0xC0 != 0;
    let start = raw.offset_to_point_data as u64;
    if start > size {
        return Err(CloudError::format(
            path,
            format!("point data offset {start} lies beyond the end of the {size}-byte file"),
        ));
    }
    let need = (raw.point_data_record_length as u64).saturating_mul(n);
    if !compressed && start.saturating_add(need) > size {
        return Err(CloudError::format(
            path,
            format!(
                "truncated: header declares {n} points of {} bytes from offset {start}, \
                 but the file has {size} bytes",
                raw.point_data_record_length
            ),
        ));
    }
    Ok(())
}

/// Reads every point of a `.las` or `.laz` file.
pub fn read_las(path: &Path) -> Result<PointCloud, CloudError> {
    // Open ourselves so a missing file is an I/O error, not a format error.
    let mut file = std::fs::File::open(path).map_err(|e| CloudError::io(path, e))?;
    check_raw_header(path, &mut file)?;
    let mut reader = Reader::new(std::io::BufReader::with_capacity(1 << 20, file))
        .map_err(|e| las_err(path, e))?;
    let n = reader.header().number_of_points();
    let has_color = reader.header().point_format().has_color;
    // The header's count is untrusted: cap the up-front reservation.
    let cap = n.min(1 << 24) as usize;
    let mut points = Vec::with_capacity(cap);
    let mut labels = Vec::with_capacity(cap);
    let mut rgb16: Vec<[u16; 3]> = Vec::with_capacity(if has_color { cap } else { 0 });
    let mut batch = PointDataBuilder::new().for_header(reader.header()).build();
    let mut read = 0u64;
    while read < n {
        let got = reader
            .fill_points(BATCH.min(n - read), &mut batch)
            .map_err(|e| las_err(path, e))?;
        if got == 0 {
            return Err(CloudError::format(
                path,
                format!("truncated: header declares {n} points, file holds {read}"),
            ));
        }
        read += got;
        points.extend(
            batch
                .x()
                .zip(batch.y())
                .zip(batch.z())
                .map(|((x, y), z)| [x, y, z]),
        );
        labels.extend(batch.classification().map(u32::from));
        if let Some(c) = batch.rgb() {
            rgb16.extend(c.map(|(r, g, b)| [r, g, b]));
        }
    }
    let colors = has_color.then(|| {
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
    };
    cloud.validate(&path.display().to_string())?;
    cloud.non_empty(&path.display().to_string(), "the file holds no points")
}

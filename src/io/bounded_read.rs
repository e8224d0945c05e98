//! Whole-file reads with a bound: `/dev/zero` or `/dev/urandom` given as a
//! pose file, a class list or a map grew the process until memory ran out
//! (4.2 GB in 2.5 s under a 6 GB limit). Text inputs are read up to
//! [`MAX_TEXT_BYTES`]; binary inputs (maps, plans, arrays, scans) must be
//! regular files, whose length is known before reading.

use std::io::{self, Read};
use std::path::Path;

/// Largest text input (pose files, intrinsics, class lists, tokens):
/// 256 MiB, about 2.5 million TUM pose lines.
pub const MAX_TEXT_BYTES: u64 = 256 << 20;

/// The bytes of `path`, refused past `max` bytes (a regular file's length
/// is checked first; a device or a pipe is read until `max` + 1 bytes).
pub fn read_capped(path: &Path, max: u64) -> io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a folder, not a file",
        ));
    }
    if meta.is_file() && meta.len() > max {
        return Err(too_long(max));
    }
    let mut bytes = Vec::with_capacity(if meta.is_file() {
        meta.len() as usize
    } else {
        0
    });
    file.take(max + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(too_long(max));
    }
    Ok(bytes)
}

fn too_long(max: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "more than {} MiB: not a file of this kind (a device, or a runaway file?)",
            max >> 20
        ),
    )
}

/// A text input of at most [`MAX_TEXT_BYTES`], as UTF-8, without a
/// leading byte-order mark (some editors write one; `intrinsics.txt` with
/// one read as "'\u{feff}48' is not a finite number").
pub fn read_text(path: &Path) -> io::Result<String> {
    let mut text = String::from_utf8(read_capped(path, MAX_TEXT_BYTES)?).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            "not a text file (not valid UTF-8: binary data, such as a map, an image or a scan?)",
        )
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

/// A binary input that must be a regular file (its length known before
/// reading: a map, a plan, an array, a scan); a device, a pipe or a
/// folder is refused.
pub fn read_regular(path: &Path) -> io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            if meta.is_dir() {
                "is a folder, not a file"
            } else {
                "is not a regular file (a device or a pipe)"
            },
        ));
    }
    read_capped(path, u64::MAX - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_long_files_are_refused_within_the_bound() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "0 1 2\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "0 1 2\n");
        assert_eq!(read_regular(&p).unwrap(), b"0 1 2\n");
        // Past the bound: a file by its length, a device by reading.
        assert!(
            read_capped(&p, 5)
                .unwrap_err()
                .to_string()
                .contains("more than")
        );
        let e = read_capped(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert!(e.to_string().contains("more than 1 MiB"), "{e}");
        let e = read_text(Path::new("/dev/zero")).unwrap_err();
        assert!(e.to_string().contains("more than 256 MiB"), "{e}");
        // Binary inputs must be regular files.
        let e = read_regular(Path::new("/dev/zero")).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        for e in [
            read_regular(dir.path()),
            read_text(dir.path()).map(String::into_bytes),
        ] {
            assert!(e.unwrap_err().to_string().contains("folder"));
        }
        // A byte-order mark is dropped.
        std::fs::write(&p, "\u{feff}48 48\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "48 48\n");
        // Not UTF-8.
        std::fs::write(&p, [0xff, 0xfe, 0x00]).unwrap();
        assert!(read_text(&p).is_err());
    }
}

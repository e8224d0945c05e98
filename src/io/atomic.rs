//! Atomic file output, shared by every writer: the bytes go to a temporary
//! file in the target's directory, which is flushed, synced and renamed
//! onto the target. Readers see the old file or the whole new one; after
//! an error the target is untouched and the temporary file is removed.
//!
//! A symbolic link is written through, and a character device or a named
//! pipe (`-o /dev/null`) written into, never replaced by a regular file.
//!
//! The temporary file is created as any new file is (mode 0666 less the
//! process umask, so 0644 under the usual umask 022), not private as
//! `tempfile` makes it by default: maps, trajectories and figures are for
//! sharing.
//!
//! A temporary file being written is registered for removal on an
//! interrupt ([`remove_on_interrupt`]), as is a folder a command made and
//! is filling: the command line's Ctrl-C and SIGTERM handler calls
//! [`remove_interrupted`] before it exits, so an interrupted command
//! leaves neither a hidden `.omcl-*.tmp` nor a half-filled new folder.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Paths to remove if the process is interrupted.
static ON_INTERRUPT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Folders to remove if the process is interrupted while they are empty.
static ON_INTERRUPT_IF_EMPTY: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Set once [`remove_interrupted`] has begun.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether the process is being interrupted ([`remove_interrupted`] has
/// begun): an error the command then meets may be the clean-up's doing
/// and is not worth reporting.
pub fn interrupted() -> bool {
    INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst)
}

/// Removes its path from the interrupt list when dropped.
#[derive(Debug)]
#[must_use = "the path is removed on an interrupt only while the guard lives"]
pub struct RemoveOnInterrupt(PathBuf, &'static Mutex<Vec<PathBuf>>);

/// Registers `path` (a file, or a folder and what is in it) for removal
/// if the process is interrupted while the returned guard lives.
pub fn remove_on_interrupt(path: &Path) -> RemoveOnInterrupt {
    register(path, &ON_INTERRUPT)
}

/// Registers the folder `path` for removal if the process is interrupted
/// while the returned guard lives and the folder is then empty (a
/// command's output folder, made and not yet written into; what it holds
/// by then, a long run's partial results, stays).
pub fn remove_if_empty_on_interrupt(path: &Path) -> RemoveOnInterrupt {
    register(path, &ON_INTERRUPT_IF_EMPTY)
}

fn register(path: &Path, list: &'static Mutex<Vec<PathBuf>>) -> RemoveOnInterrupt {
    let mut l = list.lock().unwrap_or_else(|e| e.into_inner());
    l.push(path.to_path_buf());
    RemoveOnInterrupt(path.to_path_buf(), list)
}

impl Drop for RemoveOnInterrupt {
    fn drop(&mut self) {
        let mut list = self.1.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = list.iter().rposition(|p| *p == self.0) {
            list.remove(i);
        }
    }
}

/// Removes every path registered with [`remove_on_interrupt`] whose guard
/// still lives, and keeps the list locked, so that no new one starts: for
/// a signal handler that then ends the process.
pub fn remove_interrupted() {
    INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
    let list = ON_INTERRUPT.lock().unwrap_or_else(|e| e.into_inner());
    remove_all(&list);
    let if_empty = ON_INTERRUPT_IF_EMPTY
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    for p in if_empty.iter() {
        // `remove_dir` leaves a folder with anything in it.
        let _ = std::fs::remove_dir(p);
    }
    // Held until the process ends.
    std::mem::forget(list);
    std::mem::forget(if_empty);
}

/// Removes each of `paths` that is there: a folder with what is in it,
/// a file, or a link (not what it points to).
fn remove_all(paths: &[PathBuf]) {
    for p in paths {
        // A folder may gain a file while it is emptied (the command
        // writes on until the process ends): a few tries.
        for _ in 0..5 {
            let done = match std::fs::symlink_metadata(p) {
                Ok(m) if m.is_dir() => std::fs::remove_dir_all(p).is_ok(),
                Ok(_) => std::fs::remove_file(p).is_ok(),
                Err(_) => true,
            };
            if done {
                break;
            }
        }
    }
}

/// Writes `path` atomically with `fill`, which writes the contents into a
/// buffered writer. A symbolic link is written through (its final target
/// is replaced; the link stays), a character device or a named pipe
/// (`/dev/null`, a FIFO a reader waits on) is written into directly, not
/// replaced; a folder or another kind of file is refused.
pub fn write_with(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&File>) -> io::Result<()>,
) -> io::Result<()> {
    let target = follow_links(path)?;
    match std::fs::metadata(&target) {
        Ok(m) if m.is_file() => {}
        Ok(m) if m.is_dir() => {
            return Err(io::Error::new(
                io::ErrorKind::IsADirectory,
                "is a folder, not a file",
            ));
        }
        Ok(m) => {
            use std::os::unix::fs::FileTypeExt;
            let t = m.file_type();
            if !(t.is_char_device() || t.is_fifo()) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "is neither a regular file, a character device nor a named pipe",
                ));
            }
            let f = std::fs::OpenOptions::new().write(true).open(&target)?;
            let mut w = BufWriter::with_capacity(1 << 16, &f);
            fill(&mut w)?;
            return w.flush();
        }
        Err(_) => {}
    }
    replace_file(&target, fill)
}

/// The folder that `path` is or would be created in, when it is marked
/// read-only (no write bit for anyone): the nearest folder that exists on
/// the way up from `path` (itself, if it is one). A shared data folder
/// (mode 555) stays as it is even for root, whom permissions do not stop.
pub fn read_only_folder(path: &Path) -> Option<(std::path::PathBuf, u32)> {
    use std::os::unix::fs::PermissionsExt;
    let mut at = Some(path);
    while let Some(d) = at {
        let d = if d.as_os_str().is_empty() {
            Path::new(".")
        } else {
            d
        };
        if let Ok(m) = std::fs::metadata(d)
            && m.is_dir()
        {
            let mode = m.permissions().mode() & 0o777;
            return (mode & 0o222 == 0).then(|| (d.to_path_buf(), mode));
        }
        at = d.parent();
    }
    None
}

/// [`read_only_folder`] as an error.
fn refuse_read_only(path: &Path) -> io::Result<()> {
    match read_only_folder(path) {
        None => Ok(()),
        Some((dir, mode)) => Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!(
                "its folder {} is marked read-only (mode {mode:o}); omcl does not write there, \
                 even as root",
                dir.display()
            ),
        )),
    }
}

/// Creates the folder `dir` and its parents, unless the folder they would
/// go in is marked read-only ([`read_only_folder`]).
pub fn create_folder(dir: &Path) -> io::Result<()> {
    if !dir.is_dir() {
        refuse_read_only(dir)?;
    }
    std::fs::create_dir_all(dir)
}

/// `path` with its symbolic links followed to the last one's target
/// (which need not exist yet).
pub fn follow_links(path: &Path) -> io::Result<std::path::PathBuf> {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let t = std::fs::read_link(&p)?;
                p = match p.parent() {
                    Some(d) if t.is_relative() => d.join(t),
                    _ => t,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// The atomic write itself: a temporary file beside `path`, renamed onto
/// it.
fn replace_file(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&File>) -> io::Result<()>,
) -> io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    refuse_read_only(dir)?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(".omcl-").suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    // Made and registered under the interrupt list's lock, so that an
    // interrupt cannot come between the two.
    let (tmp, _interrupt) = {
        let mut list = ON_INTERRUPT.lock().unwrap_or_else(|e| e.into_inner());
        let tmp = builder.tempfile_in(dir)?;
        list.push(tmp.path().to_path_buf());
        let guard = RemoveOnInterrupt(tmp.path().to_path_buf(), &ON_INTERRUPT);
        (tmp, guard)
    };
    {
        let mut w = BufWriter::with_capacity(1 << 16, tmp.as_file());
        fill(&mut w)?;
        w.flush()?;
    }
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Writes `bytes` to `path` atomically.
pub fn write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interrupt_list_holds_what_is_being_written_and_removes_it() {
        let dir = tempfile::tempdir().unwrap();
        let (file, folder) = (dir.path().join(".omcl-x.tmp"), dir.path().join("labels_2"));
        std::fs::write(&file, b"half").unwrap();
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("000000.png"), b"x").unwrap();
        let listed = |p: &Path| ON_INTERRUPT.lock().unwrap().iter().any(|q| q == p);
        let (g1, g2) = (remove_on_interrupt(&file), remove_on_interrupt(&folder));
        assert!(listed(&file) && listed(&folder));
        drop(g1);
        assert!(!listed(&file) && listed(&folder));
        remove_all(&[file.clone(), folder.clone(), dir.path().join("never there")]);
        assert!(!file.exists() && !folder.exists() && dir.path().exists());
        drop(g2);
        assert!(!listed(&folder));
    }

    #[test]
    fn replaces_whole_files_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write(&p, b"old").unwrap();
        write(&p, b"new contents").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new contents");
        // A failing writer leaves the old file and no temporary behind.
        let err = write_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "disk on fire");
        assert_eq!(std::fs::read(&p).unwrap(), b"new contents");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["a.txt"]);
        // A missing directory is an error, not a panic.
        assert!(write(&dir.path().join("no/such/dir/b.txt"), b"x").is_err());
    }

    #[test]
    fn links_are_written_through_and_special_files_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // A link to an existing file, and a dangling one (relative).
        std::fs::write(d.join("t.txt"), b"old").unwrap();
        std::os::unix::fs::symlink("t.txt", d.join("link")).unwrap();
        write(&d.join("link"), b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(d.join("link"))
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(d.join("t.txt")).unwrap(), b"new");
        std::os::unix::fs::symlink("later.txt", d.join("dangling")).unwrap();
        write(&d.join("dangling"), b"made").unwrap();
        assert_eq!(std::fs::read(d.join("later.txt")).unwrap(), b"made");
        assert!(
            std::fs::symlink_metadata(d.join("dangling"))
                .unwrap()
                .file_type()
                .is_symlink()
        );
        // A named pipe is written into, and stays a pipe.
        let fifo = d.join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo).unwrap())
        };
        write(&fifo, b"through the pipe").unwrap();
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        use std::os::unix::fs::FileTypeExt;
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
        // A folder is refused and left as it was.
        std::fs::create_dir(d.join("sub")).unwrap();
        let e = write(&d.join("sub"), b"x").unwrap_err();
        assert!(e.to_string().contains("folder"), "{e}");
        assert!(d.join("sub").is_dir());
        // Nothing else was left behind.
        let mut names: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(
            names,
            ["dangling", "later.txt", "link", "pipe", "sub", "t.txt"]
        );
    }

    /// Files are created with the usual mode (0666 less the umask), not the
    /// 0600 of temporary files.
    #[cfg(unix)]
    #[test]
    fn files_are_readable_by_others_under_the_default_umask() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.bin");
        write(&p, b"x").unwrap();
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        // The group/other read bits follow the umask; the owner's are set.
        let probe = dir.path().join("probe");
        std::fs::write(&probe, b"x").unwrap();
        let expected = std::fs::metadata(&probe).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, expected, "{mode:o} vs {expected:o}");
        assert_eq!(mode & 0o600, 0o600);
    }

    /// A folder marked read-only (mode 555, as shared data) is not written
    /// into, even by root, whom permissions do not stop: no file, no new
    /// folder; a link out of it to a writable place is followed.
    #[test]
    fn read_only_folders_are_left_as_they_are() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let ro = dir.path().join("ro");
        let w = dir.path().join("w");
        std::fs::create_dir(&ro).unwrap();
        std::fs::create_dir(&w).unwrap();
        std::fs::write(ro.join("kept.txt"), b"theirs").unwrap();
        std::os::unix::fs::symlink(w.join("out.txt"), ro.join("link.txt")).unwrap();
        std::os::unix::fs::symlink(ro.join("kept.txt"), w.join("into_ro.txt")).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        let e = write(&ro.join("kept.txt"), b"mine").unwrap_err();
        let e2 = write(&w.join("into_ro.txt"), b"mine").unwrap_err();
        let e3 = create_folder(&ro.join("new/deeper")).unwrap_err();
        let through = write(&ro.join("link.txt"), b"through the link");
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
        for e in [e, e2, e3] {
            assert_eq!(e.kind(), io::ErrorKind::PermissionDenied, "{e}");
            assert!(e.to_string().contains("read-only (mode 555)"), "{e}");
        }
        assert_eq!(std::fs::read(ro.join("kept.txt")).unwrap(), b"theirs");
        assert!(!ro.join("new").exists());
        through.unwrap();
        assert_eq!(
            std::fs::read(w.join("out.txt")).unwrap(),
            b"through the link"
        );
        assert_eq!(read_only_folder(&w.join("x")), None);
    }
}

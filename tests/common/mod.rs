//! Helpers shared by the integration tests: running the `omcl` binary, the
//! shared real data and the `io_*` tests' committed files and checks.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// What a run of the `omcl` binary gave.
pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

impl Run {
    /// Exit status 0.
    pub fn ok(&self) -> bool {
        self.code == Some(0)
    }
    /// Exit code, standard output and standard error, for failure messages.
    pub fn text(&self) -> String {
        format!(
            "exit {:?}\n--- stdout\n{}--- stderr\n{}",
            self.code, self.stdout, self.stderr
        )
    }
    /// Standard output, then standard error: what a user sees.
    pub fn output(&self) -> String {
        format!("{}{}", self.stdout, self.stderr)
    }
}

/// Runs the crate's `omcl` binary with `args` and waits for it.
pub fn omcl(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(args)
        .output()
        .expect("run omcl");
    Run {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// A path under `../shared/data`, the real data recorded by others that
/// the tests read. Its absence is a failure, never a skip, wherever the
/// tests run.
pub fn shared(rel: &str) -> PathBuf {
    let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")).join(rel);
    assert!(
        p.exists(),
        "{} is missing: the tests need ../shared/data beside the crate",
        p.display()
    );
    p
}

/// A committed test file under `tests/data/io`.
pub fn local(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/io")).join(name)
}

/// Rows of a whitespace-separated numeric `.expected.txt` file.
pub fn expected_rows(data_file: &Path) -> Vec<Vec<f64>> {
    let mut p = data_file.as_os_str().to_owned();
    p.push(".expected.txt");
    std::fs::read_to_string(&p)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split_whitespace().map(|s| s.parse().unwrap()).collect())
        .collect()
}

/// Copies the first `keep` bytes of `src` to `dir/name` and returns the path.
pub fn truncated_copy(src: &Path, dir: &Path, name: &str, keep: usize) -> PathBuf {
    let bytes = std::fs::read(src).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, &bytes[..keep.min(bytes.len())]).unwrap();
    p
}

/// Asserts the error's message names the file (by its file name) and
/// contains `what`.
pub fn assert_err_names<E: std::fmt::Display>(e: E, file: &Path, what: &str) {
    let msg = e.to_string();
    eprintln!("error message: {msg}");
    let name = file.file_name().unwrap().to_string_lossy();
    assert!(
        msg.contains(name.as_ref()),
        "error does not name {name}: {msg}"
    );
    assert!(msg.contains(what), "error lacks '{what}': {msg}");
}

/// The size of the tests' tiny bench runs (`omcl bench`'s and `omcl sweep
/// plan`'s options): 6 frames, maps from 20, 64 particles x 128 rays.
pub const TINY_RUN: [&str; 8] = [
    "--frames",
    "6",
    "--map-frames",
    "20",
    "--particles",
    "64",
    "--rays",
    "128",
];

//! A short, deterministic fuzz run of every parser (the long runs are
//! AFL++'s, see `fuzz/README.md`): each seed of `fuzz/corpus/<target>/` and
//! `OMCL_FUZZ_ITERS` (default 1500) mutations of them go through the target.
//! A finding is a panic, an abort, or one allocation above [`CAP`] bytes,
//! which this binary's allocator refuses: it prints the target and the
//! input, then aborts, so the test fails with the input in its output.
//! Every crash the long runs find is kept in `fuzz/corpus/<target>/` and so
//! replayed here.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[path = "../fuzz/src/targets.rs"]
mod targets;
use targets::Target;

/// The largest single allocation a parser may make for a fuzz input (all
/// inputs are at most a few hundred kilobytes).
const CAP: usize = 64 << 20;

struct CappedAlloc;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; refuses (null) sizes above CAP,
// which makes the standard library abort with the size in its message.
unsafe impl GlobalAlloc for CappedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > CAP {
            report(layout.size());
            return std::ptr::null_mut();
        }
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > CAP {
            report(layout.size());
            return std::ptr::null_mut();
        }
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > CAP {
            report(new_size);
            return std::ptr::null_mut();
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOC: CappedAlloc = CappedAlloc;

thread_local! {
    /// The target and input under test, for the report.
    static CURRENT: std::cell::RefCell<(String, Vec<u8>)> =
        const { std::cell::RefCell::new((String::new(), Vec::new())) };
}

fn report(size: usize) {
    // No allocation here: the allocator is refusing one.
    CURRENT.with(|c| {
        if let Ok(c) = c.try_borrow() {
            // Straight to the file descriptor: the test harness captures
            // `eprintln!`, and an abort loses what it captured.
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "FUZZ FINDING: target {} asked for {size} bytes (cap {CAP}); input ({} bytes): {:02x?}",
                c.0,
                c.1.len(),
                &c.1[..c.1.len().min(4096)]
            );
        }
    });
}

fn corpus_dir(t: Target) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(t.name())
}

fn seeds(t: Target) -> Vec<Vec<u8>> {
    let dir = corpus_dir(t);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("corpus {} missing: {e}", dir.display()))
        .map(|e| e.expect("corpus entry").path())
        .collect();
    files.sort();
    let seeds: Vec<Vec<u8>> = files
        .iter()
        .map(|p| std::fs::read(p).expect("corpus file"))
        .collect();
    assert!(!seeds.is_empty(), "corpus {} is empty", dir.display());
    seeds
}

/// Numbers that break size arithmetic, as text and as bytes.
const TEXT_NUMBERS: [&str; 10] = [
    "4000000000",
    "18446744073709551615",
    "-1",
    "0",
    "nan",
    "inf",
    "1e309",
    "-0",
    "99999999999999999999999",
    "2147483648",
];
const WORDS: [u32; 8] = [
    0,
    1,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0xffff,
    0x1000_0000,
    4_000_000_000,
];

/// One random edit of `data` (byte, word, text-number, splice and length
/// mutations, as a byte-level fuzzer's havoc stage does).
fn mutate(rng: &mut ChaCha8Rng, data: &mut Vec<u8>, other: &[u8]) {
    let len = data.len();
    match rng.random_range(0..9) {
        0 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] ^= 1 << rng.random_range(0..8);
        }
        1 if len > 0 => {
            let i = rng.random_range(0..len);
            data[i] = [0u8, 0xff, 0x7f, 0x80, b'9', b' ', b'\n'][rng.random_range(0..7)];
        }
        2 if len >= 4 => {
            let i = rng.random_range(0..len - 3);
            let w = WORDS[rng.random_range(0..WORDS.len())];
            data[i..i + 4].copy_from_slice(&w.to_le_bytes());
        }
        3 => {
            // Replace a run of digits with a hostile number.
            let starts: Vec<usize> = (0..len)
                .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
                .collect();
            if let Some(&s) = starts.get(rng.random_range(0..starts.len().max(1))) {
                let e = (s..len).find(|&i| !data[i].is_ascii_digit()).unwrap_or(len);
                let n = TEXT_NUMBERS[rng.random_range(0..TEXT_NUMBERS.len())];
                data.splice(s..e, n.bytes());
            }
        }
        4 if len > 0 => data.truncate(rng.random_range(0..len)),
        5 if len > 1 => {
            let a = rng.random_range(0..len);
            let b = (a + rng.random_range(1..64)).min(len);
            data.drain(a..b);
        }
        6 if len > 0 => {
            let a = rng.random_range(0..len);
            let b = (a + rng.random_range(1..64)).min(len);
            let copy = data[a..b].to_vec();
            let at = rng.random_range(0..=len);
            data.splice(at..at, copy);
        }
        7 if !other.is_empty() => {
            // Splice: our head, another seed's tail.
            let a = rng.random_range(0..=len);
            let b = rng.random_range(0..other.len());
            data.truncate(a);
            data.extend_from_slice(&other[b..]);
        }
        _ => {
            let at = rng.random_range(0..=len);
            let n = rng.random_range(1..8);
            let bytes: Vec<u8> = (0..n).map(|_| rng.random()).collect();
            data.splice(at..at, bytes);
        }
    }
}

fn iterations() -> usize {
    std::env::var("OMCL_FUZZ_ITERS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1500)
}

/// Runs one target: every seed, then `iterations()` mutated inputs.
/// Returns (inputs run, inputs accepted).
fn fuzz(t: Target) -> (usize, usize) {
    let seeds = seeds(t);
    let mut rng = ChaCha8Rng::seed_from_u64(0x0fc1 ^ t as u64);
    let mut run = 0;
    let mut accepted = 0;
    let mut one = |input: &[u8]| {
        CURRENT.with(|c| {
            let mut c = c.borrow_mut();
            c.0.clear();
            c.0.push_str(t.name());
            c.1.clear();
            c.1.extend_from_slice(input);
        });
        let ok = std::panic::catch_unwind(|| targets::run(t, input)).unwrap_or_else(|_| {
            panic!(
                "target {} panicked on input ({} bytes): {:02x?}",
                t.name(),
                input.len(),
                &input[..input.len().min(4096)]
            )
        });
        run += 1;
        accepted += ok as usize;
    };
    for s in &seeds {
        one(s);
    }
    for _ in 0..iterations() {
        let mut data = seeds[rng.random_range(0..seeds.len())].clone();
        let other = &seeds[rng.random_range(0..seeds.len())];
        for _ in 0..rng.random_range(1..6) {
            mutate(&mut rng, &mut data, other);
        }
        one(&data);
    }
    targets::cleanup();
    (run, accepted)
}

macro_rules! fuzz_tests {
    ($($name:ident => $target:expr,)*) => {$(
        #[test]
        fn $name() {
            let (run, accepted) = fuzz($target);
            eprintln!("{}: {run} inputs, {accepted} accepted", $target.name());
            assert!(run > iterations());
            // The seeds are valid files: a target that accepts nothing has
            // lost its reader (or its seeds), and would fuzz error paths only.
            assert!(accepted > 0, "{}: no input accepted", $target.name());
        }
    )*};
}

fuzz_tests! {
    fuzz_ply => Target::Ply,
    fuzz_ply_header => Target::PlyHeader,
    fuzz_las => Target::Las,
    fuzz_laz => Target::Laz,
    fuzz_las_header => Target::LasHeader,
    fuzz_kitti_bin => Target::KittiBin,
    fuzz_kitti_label => Target::KittiLabel,
    fuzz_kitti_calib => Target::KittiCalib,
    fuzz_poses_tum => Target::PosesTum,
    fuzz_poses_kitti => Target::PosesKitti,
    fuzz_times => Target::Times,
    fuzz_scannet => Target::Scannet,
    fuzz_npy => Target::Npy,
    fuzz_npy_header => Target::NpyHeader,
    fuzz_png_depth => Target::PngDepth,
    fuzz_png_label => Target::PngLabel,
    fuzz_png_rgb => Target::PngRgb,
    fuzz_image_bytes => Target::ImageBytes,
    fuzz_png_header => Target::PngHeader,
    fuzz_intrinsics => Target::Intrinsics,
    fuzz_model_card => Target::ModelCard,
    fuzz_class_table => Target::ClassTable,
    fuzz_omcl_map => Target::OmclMap,
    fuzz_floor_plan => Target::FloorPlan,
    fuzz_floor_plan_fields => Target::FloorPlanFields,
}

#[test]
fn every_target_has_a_test_and_a_corpus() {
    for t in Target::ALL {
        assert_eq!(Target::from_name(t.name()), Some(t));
        assert!(corpus_dir(t).is_dir(), "no corpus for {}", t.name());
    }
}

//! Bad input across the command line, as a probe of every subcommand found
//! it on 2026-11-27: outputs over the files a command reads (class lists,
//! embeddings, models, images, manifests) are refused and the file is left
//! as it was; values that cannot mean anything (a stride larger than the
//! image, zero frames, a step of 0, a score of 5, a Slurm time limit of
//! `bogus`, a newline in a job name) are refused by option name before
//! any work; an odometry shorter than the sequence is refused, not a
//! shorter run; outputs that could not be written at the end are refused
//! at the start.

mod common;

use std::path::{Path, PathBuf};

use common::{Run, omcl, shared};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// The run was refused: a non-zero exit (1 for the command's own checks,
/// 2 for clap's), no panic, and every needle in its message.
fn refused(r: &Run, code: i32, needles: &[&str]) {
    assert_eq!(r.code, Some(code), "exit status:\n{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    for n in needles {
        assert!(r.stderr.contains(n), "no {n:?} in:\n{}", r.stderr);
    }
}

/// A tiny synthetic sequence with its class table and map.
struct Fixture {
    dir: tempfile::TempDir,
}

impl Fixture {
    fn new() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let f = Fixture { dir };
        let seq = f.path("seq");
        let r = omcl(&[
            "sim",
            "indoor",
            "--out",
            s(&seq),
            "--frames",
            "6",
            "--width",
            "64",
            "--height",
            "64",
            "--rooms",
            "2",
            "--resolution",
            "0.1",
        ]);
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        let r = omcl(&[
            "map",
            "rgbd",
            s(&seq),
            "--out",
            s(&f.path("map.omcl")),
            "--resolution",
            "0.1",
        ]);
        assert_eq!(r.code, Some(0), "{}", r.stderr);
        for name in ["classes.txt", "embeddings.npy"] {
            std::fs::copy(seq.join(name), f.path(name)).unwrap();
        }
        f
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `omcl localize` on the sequence and map into `est`, 16 particles x
    /// 16 rays, and `extra`.
    fn localize(&self, est: &Path, extra: &[&str]) -> Run {
        let (seq, map) = (self.path("seq"), self.path("map.omcl"));
        let mut args = vec![
            "localize",
            "--map",
            s(&map),
            "--sequence",
            s(&seq),
            "--out",
            s(est),
            "--particles",
            "16",
            "--rays",
            "16",
        ];
        args.extend(extra);
        omcl(&args)
    }
}

/// Runs `args` and checks it was refused naming `option` and that `input`
/// kept its bytes.
fn refused_keeping(args: &[&str], input: &Path, needles: &[&str]) {
    let before = std::fs::read(input).unwrap();
    let r = omcl(args);
    refused(&r, 1, needles);
    assert!(
        std::fs::read(input).unwrap() == before,
        "{} was changed by {args:?}",
        input.display()
    );
}

/// A one-run sweep manifest at `manifest` (its folder made if missing).
fn plan_sweep(manifest: &Path) {
    let r = omcl(&[
        "sweep",
        "plan",
        "table1",
        "--out",
        s(manifest),
        "--sequences",
        "1",
        "--frames",
        "5",
        "--map-frames",
        "5",
        "--variants",
        "OMCL_GT",
    ]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
}

#[test]
fn outputs_over_what_a_command_reads_are_refused_and_the_input_kept() {
    let f = Fixture::new();
    let (seq, map) = (f.path("seq"), f.path("map.omcl"));
    let (classes, emb) = (f.path("classes.txt"), f.path("embeddings.npy"));
    let table = ["--classes", s(&classes), "--embeddings", s(&emb)];
    // Map building with a class table: --out over the table's features.
    let mut args = vec!["map", "rgbd", s(&seq), "--out", s(&emb)];
    args.extend(table);
    refused_keeping(&args, &emb, &["--out is the --embeddings", "replace"]);
    let mut args = vec!["map", "rgbd", s(&seq), "--out", s(&classes)];
    args.extend(table);
    refused_keeping(&args, &classes, &["--out is the --classes list"]);
    // Grounding and querying: --out over the words' table or prompt file.
    let mut args = vec!["map", "ground", s(&map), "wall", "--out", s(&emb)];
    args.extend(table);
    refused_keeping(&args, &emb, &["--out is the --embeddings"]);
    let prompts = f.path("prompts.txt");
    std::fs::write(&prompts, "wall\n").unwrap();
    let mut args = vec![
        "map",
        "ground",
        s(&map),
        "--prompt-file",
        s(&prompts),
        "--out",
        s(&prompts),
    ];
    args.extend(table);
    refused_keeping(&args, &prompts, &["--out is the --prompt-file"]);
    let mut args = vec!["map", "query", s(&map), "wall", "--out", s(&classes)];
    args.extend(table);
    refused_keeping(&args, &classes, &["--out is the --classes list"]);

    // Encoders: the model, its card and the image are inputs.
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/encode");
    let work = f.path("models");
    std::fs::create_dir(&work).unwrap();
    for name in ["tiny_text.onnx", "tiny_text.card.json"] {
        std::fs::copy(models.join(name), work.join(name)).unwrap();
    }
    let text = work.join("tiny_text.onnx");
    let card = work.join("tiny_text.card.json");
    refused_keeping(
        &[
            "encode",
            "text",
            "--model",
            s(&text),
            "wall",
            "--out",
            s(&text),
        ],
        &text,
        &["--out is the --model"],
    );
    refused_keeping(
        &[
            "encode",
            "text",
            "--model",
            s(&text),
            "wall",
            "--out",
            s(&card),
        ],
        &card,
        &["--out is the --model's card"],
    );
    let image = seq.join("rgb/000000.png");
    refused_keeping(
        &[
            "encode",
            "image",
            "--model",
            s(&text),
            s(&image),
            "--out",
            s(&image),
        ],
        &image,
        &["--out is the image"],
    );
    let est = f.path("est.txt");
    refused_keeping(
        &[
            "localize",
            "--map",
            s(&map),
            "--sequence",
            s(&seq),
            "--text-model",
            s(&text),
            "--out",
            s(&card),
        ],
        &card,
        &["--out is the --text-model's card"],
    );
    assert!(!est.exists());

    // A colour model over a 7-Scenes frame it is fitted on.
    let scenes = f.path("s7");
    std::fs::create_dir(&scenes).unwrap();
    let real = shared("rgbd_7scenes");
    for name in ["camera-intrinsics.txt", "frame-000000.color.jpg"] {
        std::fs::copy(real.join(name), scenes.join(name)).unwrap();
    }
    let frame = scenes.join("frame-000000.color.jpg");
    refused_keeping(
        &[
            "encode",
            "colour-model",
            "--frames",
            s(&scenes),
            "--out",
            s(&frame),
        ],
        &frame,
        &["--out would be read as part of the sequence"],
    );

    // A sweep's batch script over its manifest.
    let manifest = f.path("plan/m.jsonl");
    plan_sweep(&manifest);
    refused_keeping(
        &["sweep", "slurm", s(&manifest), "--script", s(&manifest)],
        &manifest,
        &["--script is the manifest"],
    );
}

#[test]
fn values_that_cannot_mean_anything_are_refused_by_name() {
    let f = Fixture::new();
    let seq = f.path("seq");
    let est = f.path("est.txt");
    let localize = |extra: &[&str]| f.localize(&est, extra);
    // A feature stride larger than the image panicked in the simulator.
    let r = omcl(&[
        "sim",
        "indoor",
        "--out",
        s(&f.path("big-stride")),
        "--frames",
        "2",
        "--width",
        "16",
        "--height",
        "16",
        "--features",
        "--feature-stride",
        "1000",
    ]);
    refused(&r, 1, &["--feature-stride 1000", "16 x 16"]);
    assert!(!f.path("big-stride").exists());
    for (extra, needle) in [
        (&["--frame-step", "0"][..], "--frame-step"),
        (&["--frames", "0"], "--frames"),
        (&["--miss-score", "5"], "--miss-score"),
        (&["--prompt-rho", "nan"], "--prompt-rho"),
        (&["--init-pose", "1 2 3 0 0 0 1 5"], "expected 7 numbers"),
    ] {
        let r = localize(extra);
        let code = if needle.starts_with("--") { 2 } else { 1 };
        refused(&r, code, &[needle]);
        assert!(!est.exists(), "{extra:?} wrote {}", est.display());
    }
    let r = omcl(&[
        "map",
        "rgbd",
        s(&seq),
        "--out",
        s(&f.path("x.omcl")),
        "--frame-step",
        "0",
    ]);
    refused(&r, 2, &["--frame-step"]);
    let poses = seq.join("poses.txt");
    let r = omcl(&["eval", "ape", s(&poses), s(&poses), "--t-max-diff", "inf"]);
    refused(&r, 2, &["--t-max-diff"]);
    let r = omcl(&[
        "encode",
        "text",
        "--model",
        "x.onnx",
        "wall",
        "--out",
        "x.npy",
        "--threads",
        "999999",
    ]);
    refused(&r, 2, &["--threads"]);
    let r = omcl(&[
        "sweep",
        "plan",
        "table1",
        "--out",
        s(&f.path("m.jsonl")),
        "--frames",
        "0",
    ]);
    refused(&r, 2, &["--frames"]);
    // Counts that size allocations or loops, on the command line and in
    // --set (each aborted or ran for ever: `--frames 1000000000` asked for
    // 56 GB, `--set sampling.rays=100000000000` for 800 GB, `--starts
    // 1000000000` looped; `--set sensor.miss_score=5` ran).
    let bench = |extra: &[&str]| {
        let mut args = vec![
            "bench",
            "table1",
            "--sequences",
            "1",
            "-o",
            "/nonexistent/out",
        ];
        args.extend_from_slice(extra);
        omcl(&args)
    };
    refused(&bench(&["--frames", "1000000000"]), 2, &["--frames"]);
    refused(
        &bench(&["--map-frames", "1000000000"]),
        2,
        &["--map-frames"],
    );
    refused(&bench(&["--starts", "1000000000"]), 2, &["--starts"]);
    refused(&bench(&["--starts", "0"]), 2, &["--starts"]);
    refused(&bench(&["--localize-every", "0"]), 2, &["--localize-every"]);
    for (set, field) in [
        ("sampling.rays=100000000000", "sampling.rays"),
        (
            "anneal={\"layers\":4000000000,\"first\":0.5,\"jitter\":0.3,\"expand\":1}",
            "anneal.layers",
        ),
        ("sensor.miss_score=5", "sensor.miss_score"),
        ("motion.sigma_translation=1e300", "motion.sigma_translation"),
        ("sampling.stride=0", "sampling.stride"),
    ] {
        refused(&bench(&["--set", set]), 1, &["--set", field]);
    }
    let r = omcl(&[
        "encode",
        "colour-model",
        "--frames",
        s(&shared("rgbd_7scenes")),
        "--dim",
        "10000000000",
        "--out",
        s(&f.path("c.onnx")),
    ]);
    refused(&r, 2, &["--dim", "2..=4096"]);
    assert!(!f.path("c.onnx").exists());

    // A driving path shorter than the frames asked for.
    let path = f.path("path3.txt");
    let gt = std::fs::read_to_string(shared("trajectories/KITTI_00_gt.txt")).unwrap();
    let three: String = gt.lines().take(3).map(|l| format!("{l}\n")).collect();
    std::fs::write(&path, three).unwrap();
    let r = omcl(&[
        "sim",
        "outdoor",
        "--out",
        s(&f.path("street")),
        "--path",
        s(&path),
        "--frames",
        "5",
        "--azimuth-steps",
        "64",
        "--resolution",
        "0.5",
    ]);
    refused(&r, 1, &[s(&path), "--frames 5", "at most --frames 3"]);
    assert!(!f.path("street").exists());

    // A class list naming one id twice, an id past u32.
    let list = f.path("dup.txt");
    std::fs::write(&list, "0 wall\n0 floor\n").unwrap();
    let r = omcl(&["map", "classes", s(&list)]);
    refused(&r, 1, &[s(&list), "line 2", "given twice"]);
    // An all-zero embedding row has no direction: the file and row named.
    let zero = f.path("zero.npy");
    let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 2), }";
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    let pad = 64 - (10 + header.len() + 1) % 64;
    npy.extend_from_slice(&((header.len() + pad + 1) as u16).to_le_bytes());
    npy.extend_from_slice(header.as_bytes());
    npy.extend(std::iter::repeat_n(b' ', pad));
    npy.push(b'\n');
    for v in [1.0f32, 0.0, 0.0, 0.0] {
        npy.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(&zero, npy).unwrap();
    let two = f.path("two.txt");
    std::fs::write(&two, "0 wall\n1 floor\n").unwrap();
    let map_with = |emb: &Path| {
        omcl(&[
            "map",
            "rgbd",
            s(&seq),
            "--out",
            s(&f.path("z.omcl")),
            "--classes",
            s(&two),
            "--embeddings",
            s(emb),
        ])
    };
    refused(
        &map_with(&zero),
        1,
        &[s(&zero), "row 1", "floor", "all zeros"],
    );
    // A row whose length f32 cannot hold (it localized to nonsense, and
    // mapping said "feature 1 is zero or not finite" naming neither).
    let mut huge = std::fs::read(&zero).unwrap();
    let at = huge.len() - 8;
    huge[at..at + 4].copy_from_slice(&1e38f32.to_le_bytes());
    huge[at + 4..].copy_from_slice(&1e38f32.to_le_bytes());
    std::fs::write(&zero, huge).unwrap();
    refused(
        &map_with(&zero),
        1,
        &[s(&zero), "row 1", "floor", "f32 cannot hold"],
    );
    // A model that is not there is named, not its card.
    let r = omcl(&[
        "encode",
        "text",
        "--model",
        s(&f.path("nope.onnx")),
        "wall",
        "--out",
        s(&f.path("w.npy")),
    ]);
    // With where models come from (the README's clip_text.onnx is not
    // in the repository).
    refused(
        &r,
        1,
        &[
            s(&f.path("nope.onnx")),
            "no such model file",
            "tools/README_encoders.md",
        ],
    );
    assert!(!r.stderr.contains("card"), "{}", r.stderr);
}

#[test]
fn an_odometry_shorter_than_the_sequence_is_refused_not_a_shorter_run() {
    let f = Fixture::new();
    let odom = f.path("seq/odometry.txt");
    let text = std::fs::read_to_string(&odom).unwrap();
    let two: String = text.lines().take(2).map(|l| format!("{l}\n")).collect();
    std::fs::write(&odom, two).unwrap();
    let est = f.path("est.txt");
    let r = f.localize(&est, &[]);
    refused(
        &r,
        1,
        &[
            "the odometry gives 2 poses for 6 frames",
            "--frames 2",
            s(&odom),
            "--odom-first",
        ],
    );
    assert!(!est.exists());
    // Asking for those two is fine.
    let r = f.localize(&est, &["--frames", "2"]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert_eq!(std::fs::read_to_string(&est).unwrap().lines().count(), 2);
}

#[test]
fn outputs_that_could_not_be_written_are_refused_before_the_work() {
    let f = Fixture::new();
    let (seq, map) = (f.path("seq"), f.path("map.omcl"));
    let est = f.path("est.txt");
    for (option, value, needle) in [
        ("--plot", f.path("p.xyz"), ".png or .svg"),
        ("--metrics", f.path("nodir/m.json"), "does not exist"),
        ("--diagnostics", f.path("seq"), "is a folder"),
    ] {
        let r = omcl(&[
            "localize",
            "--map",
            s(&map),
            "--sequence",
            s(&seq),
            "--out",
            s(&est),
            option,
            s(&value),
        ]);
        refused(&r, 1, &[option, needle]);
        assert!(!est.exists(), "{option}: --out written before the refusal");
    }
    let r = omcl(&[
        "map",
        "rgbd",
        s(&seq),
        "--out",
        s(&f.path("nodir/map.omcl")),
    ]);
    refused(&r, 1, &["--out's folder", "does not exist"]);
    let file = f.path("a-file");
    std::fs::write(&file, "x").unwrap();
    // map classes makes its folder (as sim does) but not over a file.
    let r = omcl(&[
        "map",
        "classes",
        "semantickitti",
        "--out",
        s(&f.path("newdir")),
    ]);
    assert_eq!(r.code, Some(0), "{}", r.text());
    assert!(f.path("newdir/classes.txt").exists() && f.path("newdir/embeddings.npy").exists());
    let r = omcl(&["map", "classes", "semantickitti", "--out", s(&file)]);
    refused(&r, 1, &["a-file", "--out names a folder"]);
    let r = omcl(&["demo", "--out", s(&file)]);
    refused(&r, 1, &["a-file", "--out names a folder"]);
}

#[test]
fn slurm_options_sbatch_would_reject_are_refused_and_nothing_written() {
    let f = Fixture::new();
    let manifest = f.path("plan/m.jsonl");
    plan_sweep(&manifest);
    let script = f.path("plan/sweep.sbatch");
    for (extra, needle) in [
        (&["--time", "bogus"][..], "--time \"bogus\""),
        (&["--mem-mb", "0"], "--mem-mb 0"),
        (&["--max-array-size", "0"], "--max-array-size 0"),
        (&["--job-name", "x\necho INJECTED"], "--job-name"),
    ] {
        let mut args = vec!["sweep", "slurm", s(&manifest)];
        args.extend(extra);
        let r = omcl(&args);
        refused(&r, 1, &[needle]);
        assert!(!script.exists(), "{extra:?}: a script was written");
        assert!(!f.path("plan/logs").exists(), "{extra:?}: logs/ was made");
    }
    let r = omcl(&["sweep", "slurm", s(&manifest), "--time", "2-12:00"]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let text = std::fs::read_to_string(&script).unwrap();
    assert!(text.contains("#SBATCH --time=2-12:00\n"), "{text}");
}

#[test]
fn a_kitti_folder_without_calib_says_so() {
    let f = Fixture::new();
    let seq = f.path("00");
    std::fs::create_dir(&seq).unwrap();
    let real = shared("semantickitti/sequences/00");
    for name in ["poses.txt", "times.txt"] {
        std::fs::copy(real.join(name), seq.join(name)).unwrap();
    }
    std::fs::create_dir(seq.join("labels_2")).unwrap();
    let r = omcl(&[
        "localize",
        "--map",
        s(&f.path("map.omcl")),
        "--sequence",
        s(&seq),
        "--out",
        s(&f.path("est.txt")),
    ]);
    refused(&r, 1, &[s(&seq), "calib.txt", "KITTI"]);
}

/// A typo in the path, or the KITTI dataset's root given for one of its
/// sequences, is named as such (it was "intrinsics.txt: No such file" or
/// "cannot tell the format from the extension").
#[test]
fn a_missing_folder_or_the_dataset_root_is_named_as_such() {
    let f = Fixture::new();
    let root = f.path("dataset");
    std::fs::create_dir_all(root.join("sequences/00")).unwrap();
    std::fs::create_dir_all(root.join("sequences/08")).unwrap();
    let typo = f.path("sequences0");
    let est = f.path("est.txt");
    let map = f.path("map.omcl");
    let localize = |seq: &Path| {
        omcl(&[
            "localize",
            "--map",
            s(&map),
            "--sequence",
            s(seq),
            "--out",
            s(&est),
        ])
    };
    refused(&localize(&typo), 1, &[s(&typo), "no such folder"]);
    let one = root.join("sequences/00");
    refused(&localize(&root), 1, &[s(&root), "dataset's root", s(&one)]);
    let new_map = f.path("new.omcl");
    let cloud = |input: &Path| omcl(&["map", "cloud", s(input), "-o", s(&new_map)]);
    refused(&cloud(&typo), 1, &[s(&typo), "no such file or folder"]);
    refused(&cloud(&root), 1, &[s(&root), "dataset's root"]);
    let r = omcl(&["map", "rgbd", s(&typo), "-o", s(&new_map)]);
    refused(&r, 1, &[s(&typo), "no such folder"]);
    assert!(!est.exists() && !new_map.exists());
    // A sequence in the odometry benchmark's layout (poses beside the
    // sequences, not in them), the sequences/ folder and a folder inside a
    // sequence given to localize, and a sequence with no camera frames.
    let seq = root.join("sequences/00");
    let calib = shared("semantickitti/sequences/00/calib.txt");
    std::fs::copy(&calib, seq.join("calib.txt")).unwrap();
    std::fs::create_dir_all(seq.join("velodyne")).unwrap();
    std::fs::create_dir_all(root.join("poses")).unwrap();
    std::fs::write(root.join("poses/00.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\n").unwrap();
    refused(
        &cloud(&seq),
        1,
        &[
            "poses.txt",
            "odometry benchmark's layout",
            s(&root.join("poses/00.txt")),
        ],
    );
    let sequences = root.join("sequences");
    refused(
        &localize(&sequences),
        1,
        &["a folder of KITTI sequences", s(&seq)],
    );
    refused(
        &localize(&seq.join("velodyne")),
        1,
        &["a folder inside the KITTI sequence", s(&seq)],
    );
    refused(
        &localize(&seq),
        1,
        &[
            "no camera-2 frames",
            "labels_2/",
            "omcl map project",
            "--use-features",
        ],
    );
    assert!(!est.exists() && !new_map.exists());
}

#[test]
fn serve_names_unreadable_tls_files_and_one_port_for_both_planes() {
    let f = Fixture::new();
    let token = f.path("token.txt");
    std::fs::write(&token, "token-0123456789abcdefgh\n").unwrap();
    let map = format!("room={}", s(&f.path("map.omcl")));
    let pem = f.path("garbage.pem");
    std::fs::write(&pem, "not a PEM file\n").unwrap();
    let serve = |extra: &[&str]| {
        let mut args = vec!["serve", "--map", &map, "--token-file", s(&token)];
        args.extend(extra);
        omcl(&args)
    };
    let r = serve(&["--tls-cert", s(&pem), "--tls-key", s(&pem)]);
    refused(&r, 1, &["--tls-cert", "--tls-key", s(&pem)]);
    let r = serve(&["--grpc", "127.0.0.1:50999", "--http", "127.0.0.1:50999"]);
    refused(&r, 1, &["--grpc and --http", "two ports"]);
    // A drain timeout past what a clock can add panicked at shutdown; it
    // is refused as the other durations are.
    let r = serve(&["--drain-timeout-s", "1.5e19"]);
    refused(
        &r,
        2,
        &[
            "--drain-timeout-s",
            "is out of range: 0..=1000000000000 is accepted",
        ],
    );
}

/// A point's feature is a direction: an all-zero row of `--features` for
/// a point kept for the map is refused naming the file, nothing written;
/// rows of points the map drops anyway (SemanticKITTI's unlabeled points)
/// may be zero.
#[test]
fn all_zero_point_features_are_named_with_their_file() {
    let d = tempfile::tempdir().unwrap();
    let ply = common::local("plyfile_ascii_rgb_label.ply");
    let n = omcl::io::ply::read_ply(&ply).unwrap().len();
    let feats = d.path().join("zero_row.npy");
    let mut v: Vec<f32> = (0..n * 3).map(|i| 1.0 + i as f32).collect();
    v[3..6].fill(0.0);
    omcl::io::npy::write_npy(&feats, &[n, 3], &v).unwrap();
    let out = d.path().join("m.omcl");
    let r = omcl(&[
        "map",
        "cloud",
        s(&ply),
        "--features",
        s(&feats),
        "-o",
        s(&out),
    ]);
    refused(
        &r,
        1,
        &[
            "zero_row.npy",
            &format!("all-zero feature rows for 1 of the {n} points kept"),
            "point 1 of those kept",
        ],
    );
    assert!(!out.exists());

    // A KITTI scan whose unlabeled points have zero rows: they are dropped
    // before the map, which is built.
    let seq = shared("semantickitti/sequences/00");
    let scan = seq.join("velodyne/000000.bin");
    let labels = seq.join("labels/000000.label");
    let cloud = omcl::io::kitti::read_labelled_scan(&scan, Some(&labels)).unwrap();
    let kept: Vec<bool> = cloud
        .labels
        .as_ref()
        .unwrap()
        .iter()
        .map(|&l| !omcl::io::labels::is_dropped_semantic_kitti(l))
        .collect();
    assert!(kept.iter().any(|k| !k), "no dropped point in the scan");
    let v: Vec<f32> = kept
        .iter()
        .flat_map(|&k| if k { [1.0, 0.5] } else { [0.0, 0.0] })
        .collect();
    omcl::io::npy::write_npy(&feats, &[kept.len(), 2], &v).unwrap();
    let r = omcl(&[
        "map",
        "cloud",
        s(&scan),
        "--format",
        "kitti",
        "--labels",
        s(&labels),
        "--features",
        s(&feats),
        "--resolution",
        "0.5",
        "-o",
        s(&out),
    ]);
    assert!(r.ok(), "{}", r.text());
    assert!(out.exists());
}

/// `omcl map classes semantickitti | head -1`: output into a pipe whose
/// reader has gone ends quietly with 141 (as the pipe's signal would), not
/// a panic and its backtrace.
#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["map", "classes", "semantickitti"])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

/// Outputs into a folder marked read-only (the shared data's mode 555) are
/// refused first, even as root: a simulation's folder, and a file reached
/// through a link into such a folder.
#[test]
fn outputs_into_read_only_folders_are_refused() {
    use std::os::unix::fs::PermissionsExt;
    let f = Fixture::new();
    let ro = f.path("ro");
    std::fs::create_dir(&ro).unwrap();
    std::fs::write(ro.join("theirs.json"), b"{}").unwrap();
    let link = f.path("metrics.json");
    std::os::unix::fs::symlink(ro.join("theirs.json"), &link).unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    let sim = ro.join("sim");
    let r = omcl(&["sim", "indoor", "--out", s(&sim), "--frames", "2"]);
    let est = f.path("est.txt");
    let r2 = f.localize(&est, &["--metrics", s(&link)]);
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
    refused(&r, 1, &[s(&ro), "read-only (mode 555)"]);
    refused(&r2, 1, &[s(&ro), "read-only (mode 555)", "metrics.json"]);
    assert!(!sim.exists() && !est.exists());
    assert_eq!(std::fs::read(ro.join("theirs.json")).unwrap(), b"{}");
}

/// Standard error redirected, as in a batch job's log: progress comes as
/// plain lines (every `OMCL_PROGRESS_EVERY_S`, here every update), not
/// nothing, and a last one when the work is done; by default a short
/// command's log holds none.
#[test]
fn progress_goes_into_logs_as_plain_lines() {
    let f = Fixture::new();
    let run = |every: Option<&str>, out: &Path| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"));
        c.args(["sim", "outdoor", "--out", s(out), "--frames", "3"]);
        c.args(["--resolution", "0.4", "--azimuth-steps", "256"]);
        if let Some(e) = every {
            c.env("OMCL_PROGRESS_EVERY_S", e);
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{o:?}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let logged = run(Some("0"), &f.path("a"));
    assert!(
        logged
            .lines()
            .any(|l| l.starts_with("scanning: ") && l.contains("/3 frames (elapsed")),
        "{logged}"
    );
    assert!(
        logged
            .lines()
            .any(|l| l.starts_with("scanning: 3/3 frames (done in ")),
        "{logged}"
    );
    let quiet = run(None, &f.path("b"));
    assert!(!quiet.contains("scanning"), "{quiet}");
    // A single cloud's mapping counts its points (a spinner had said
    // nothing of how far it was).
    let ply = f.path("feat.ply");
    let mut t = String::from(
        "ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\nproperty float y\n\
         property float z\nproperty float f0\nproperty float f1\nend_header\n",
    );
    for i in 0..100 {
        t.push_str(&format!("{} 0.5 0.5 1 {}\n", i as f32 * 0.1, i % 3));
    }
    std::fs::write(&ply, t).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(["map", "cloud", s(&ply), "-o", s(&f.path("feat.omcl"))])
        .env("OMCL_PROGRESS_EVERY_S", "0")
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert!(
        e.lines()
            .any(|l| l.starts_with("mapping: 100/100 points (done in ")),
        "{e}"
    );
}

#[test]
fn text_outputs_never_replace_a_map_or_binary_file() {
    let f = Fixture::new();
    // A copy of the map as -o, a PNG as --metrics: refused, kept.
    let victim = f.path("victim.omcl");
    std::fs::copy(f.path("map.omcl"), &victim).unwrap();
    let before = std::fs::read(&victim).unwrap();
    let r = f.localize(&victim, &[]);
    refused(&r, 1, &[s(&victim), "--out", "a map file"]);
    assert_eq!(std::fs::read(&victim).unwrap(), before);
    let png = f.path("figure.png");
    let png_bytes = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec();
    std::fs::write(&png, &png_bytes).unwrap();
    let r = f.localize(&f.path("est.txt"), &["--metrics", s(&png)]);
    refused(&r, 1, &[s(&png), "--metrics", "not text"]);
    assert_eq!(std::fs::read(&png).unwrap(), png_bytes);
    assert!(!f.path("est.txt").exists());
    // An earlier estimate is replaced as before; other text only with
    // --force (since 2026-11-29).
    let est = f.path("old.txt");
    std::fs::write(&est, "0 1 2 3 0 0 0 1\n").unwrap();
    let r = f.localize(&est, &[]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    let note = f.path("note.txt");
    std::fs::write(&note, "a note\n").unwrap();
    let r = f.localize(&note, &[]);
    refused(&r, 1, &[s(&note), "--out", "is not a trajectory"]);
    assert_eq!(std::fs::read_to_string(&note).unwrap(), "a note\n");
    let r = f.localize(&note, &["--force"]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    // eval's --json likewise.
    let gt = f.path("seq/poses.txt");
    let r = omcl(&["eval", "ape", s(&gt), s(&est), "--json", s(&victim)]);
    refused(&r, 1, &[s(&victim), "--json", "a map file"]);
    assert_eq!(std::fs::read(&victim).unwrap(), before);
}

#[test]
fn odometry_and_prompt_options_that_would_be_ignored_are_refused() {
    let f = Fixture::new();
    let est = f.path("est.txt");
    let odom = f.path("seq/odometry.txt");
    // --odom-from-gt with a file: which one was meant is unclear.
    let r = f.localize(&est, &["--odom-from-gt", "--odometry", s(&odom)]);
    refused(&r, 2, &["--odom-from-gt", "--odometry"]);
    // Noise shapes odometry from ground truth only; the sequence's
    // odometry.txt is replayed as it is.
    let r = f.localize(&est, &["--odom-noise-m", "0.3"]);
    refused(&r, 1, &["--odom-noise-m", s(&odom), "--odom-from-gt"]);
    let r = f.localize(&est, &["--odom-from-gt", "--odom-noise-m", "0.3"]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    // --odom-first picks a row of a file that is not read.
    let r = f.localize(&est, &["--odom-from-gt", "--odom-first", "2"]);
    refused(&r, 1, &["--odom-first 2", "none is read"]);
    // --prompt without --init prompt.
    let r = f.localize(&est, &["--prompt", "floor"]);
    refused(&r, 1, &["--prompt", "--init prompt"]);
}

#[test]
fn the_suggested_link_for_the_benchmark_layout_works_as_typed() {
    // Relative paths, as a user types them from the dataset's parent: the
    // link the message suggests must point at the poses from where it
    // lies (a relative target is read from the link's own folder).
    let f = Fixture::new();
    let root = f.path("dataset");
    let seq = root.join("sequences/00");
    std::fs::create_dir_all(seq.join("velodyne")).unwrap();
    std::fs::create_dir_all(root.join("poses")).unwrap();
    let calib = shared("semantickitti/sequences/00/calib.txt");
    std::fs::copy(&calib, seq.join("calib.txt")).unwrap();
    std::fs::write(root.join("poses/00.txt"), "1 0 0 0 0 1 0 0 0 0 1 0\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
        .current_dir(f.path(""))
        .args(["map", "cloud", "dataset/sequences/00", "-o", "m.omcl"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{err}");
    let at = err.find("(ln -s ").expect("a link to make") + 1;
    let cmd = &err[at..at + err[at..].find(')').unwrap()];
    let ok = std::process::Command::new("sh")
        .current_dir(f.path(""))
        .args(["-c", cmd])
        .status()
        .unwrap();
    assert!(ok.success(), "{cmd}");
    assert_eq!(
        std::fs::read_to_string(seq.join("poses.txt")).unwrap(),
        "1 0 0 0 0 1 0 0 0 0 1 0\n",
        "{cmd}"
    );
}

#[test]
fn a_bad_label_image_late_in_an_rgbd_folder_fails_the_run_before_the_work() {
    let f = Fixture::new();
    let late = f.path("seq/labels/000004.png");
    let bytes = std::fs::read(&late).unwrap();
    std::fs::write(&late, &bytes[..bytes.len() / 2]).unwrap();
    let est = f.path("est.txt");
    let r = f.localize(&est, &[]);
    refused(&r, 1, &["000004.png", "truncated"]);
    assert!(!r.stdout.contains("frames/s"), "{}", r.stdout);
    assert!(!est.exists());
    // A run over the frames before it reads no more and is not refused.
    let r = f.localize(&est, &["--frames", "4"]);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
}

/// `--encoder` names are stored in the map and printed back: an empty
/// one, one with a newline or a terminal escape, or one of 201
/// characters is refused; `--depth-scale 0` is the option's fault, not
/// the first frame's.
#[test]
fn stored_names_and_scales_are_checked_as_options() {
    let f = Fixture::new();
    let out = f.path("m.omcl");
    let long = "n".repeat(201);
    for (name, why) in [
        ("", "cannot be empty"),
        ("evil\n\x1b[31mred", "control characters"),
        (long.as_str(), "at most 200"),
    ] {
        let r = omcl(&[
            "map",
            "cloud",
            s(&f.path("nothing.ply")),
            "--encoder",
            name,
            "-o",
            s(&out),
        ]);
        refused(&r, 2, &["--encoder", why]);
    }
    let r = omcl(&[
        "map",
        "rgbd",
        s(&f.path("seq")),
        "--depth-scale",
        "0",
        "-o",
        s(&out),
    ]);
    refused(&r, 2, &["--depth-scale", "0 is not above 0"]);
    assert!(!out.exists());
}

/// A KITTI scan mapped through `--classes` without a label file names
/// where the labels were looked for and `--labels` (the error had told
/// to use `--classes`, given, and spoke of PLY files).
#[test]
fn a_kitti_scan_without_its_labels_says_where_they_were_looked_for() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scans/000001.bin");
    std::fs::create_dir(dir.path().join("scans")).unwrap();
    std::fs::copy(
        shared("semantickitti/sequences/00/velodyne/000001.bin"),
        &scan,
    )
    .unwrap();
    let out = dir.path().join("m.omcl");
    let r = omcl(&[
        "map",
        "cloud",
        s(&scan),
        "--format",
        "kitti",
        "--classes",
        "semantickitti",
        "-o",
        s(&out),
    ]);
    refused(
        &r,
        1,
        &["scans/000001.label", "labels/000001.label", "--labels FILE"],
    );
    assert!(!out.exists());
}

//! `omcl sweep` on the local path: plan, run (idempotent), status and
//! collect, and what bad input does: a manifest line from another omcl
//! version, a corrupt result file and a missing map each give an error
//! naming the run and the file, and collect still writes the rest.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn omcl(args: &[&str]) -> (Output, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    (o, text)
}

/// Three tiny Table I runs of OMCL_GT_exact (seeds 1000 to 1002).
fn plan(dir: &Path) -> String {
    let m = dir.join("m.jsonl");
    let m = m.to_str().unwrap();
    let args = plan_args(m, "3");
    let (o, text) = omcl(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{text}");
    assert!(text.contains("planned 3 runs"), "{text}");
    m.to_string()
}

fn ids(manifest: &str) -> Vec<String> {
    std::fs::read_to_string(manifest)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["id"].as_str().unwrap().to_string()
        })
        .collect()
}

fn result_file(dir: &Path, id: &str) -> std::path::PathBuf {
    dir.join("results")
        .join(&id[..2])
        .join(format!("{id}.json"))
}

#[test]
fn runs_are_idempotent_and_bad_input_names_the_run_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let m = plan(dir.path());
    let ids = ids(&m);
    assert_eq!(ids.len(), 3);

    let (o, text) = omcl(&["sweep", "status", &m]);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("3 runs: 0 done, 0 failed, 3 missing"),
        "{text}"
    );
    assert!(text.contains("missing runs: 0-2"), "{text}");
    // A script that must not collect before the sweep is whole.
    let (o, text) = omcl(&["sweep", "status", &m, "--complete"]);
    assert_eq!(o.status.code(), Some(4), "{text}");
    assert!(
        text.contains("error: the sweep is not complete: 3 of 3 runs missing"),
        "{text}"
    );
    // A results folder that is not there (a typo) is named.
    let nowhere = dir.path().join("no_such_results");
    let (o, text) = omcl(&[
        "sweep",
        "status",
        &m,
        "--results",
        nowhere.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("no_such_results does not exist yet"),
        "{text}"
    );
    // A pool of workers larger than the sweep: the extra ones have
    // nothing to do, which is no failure.
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "5", "--stride", "10"]);
    assert!(o.status.success(), "{text}");
    assert!(text.contains("none of the 3 runs"), "{text}");
    let file = dir.path().join("notes.txt");
    std::fs::write(&file, b"not a folder").unwrap();
    let (o, text) = omcl(&["sweep", "run", &m, "--cache", file.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("notes.txt: the map cache is a folder"),
        "{text}"
    );
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "5"]);
    assert_eq!(o.status.code(), Some(3), "{text}");
    assert!(text.contains("run index 5 is out of range"), "{text}");

    // One run by index, then all: the first is not computed again.
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "1"]);
    assert!(o.status.success(), "{text}");
    let first = std::fs::read(result_file(dir.path(), &ids[1])).unwrap();
    let (o, text) = omcl(&["sweep", "run", &m, "--jobs", "2"]);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("run 1 (table1 OMCL_GT_exact) sequence 1001"),
        "{text}"
    );
    assert!(text.contains("(result there)"), "{text}");
    assert_eq!(
        std::fs::read(result_file(dir.path(), &ids[1])).unwrap(),
        first
    );
    let (o, text) = omcl(&["sweep", "status", &m, "--complete"]);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("3 runs: 3 done, 0 failed, 0 missing"),
        "{text}"
    );
    // One map per world, built once, in the cache beside the manifest.
    let maps = std::fs::read_dir(dir.path().join("cache"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension() == Some("omcl".as_ref()))
        .count();
    assert_eq!(maps, 3);

    let out = dir.path().join("tables");
    let (o, text) = omcl(&["sweep", "collect", &m, "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{text}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("table1.json")).unwrap()).unwrap();
    assert_eq!(rows[0]["per_sequence"].as_array().unwrap().len(), 3);
    assert!(out.join("figure4_OMCL_GT_exact.png").exists());
    // What a collect wrote is recorded, and the next collect into the
    // folder removes it first: one sweep's tables never stand beside
    // another's (an earlier sweep's figure of another variant, here).
    let stamp = std::fs::read_to_string(out.join("collected.txt")).unwrap();
    assert!(stamp.lines().any(|l| l == "table1.json"), "{stamp}");
    std::fs::write(out.join("figure4_OMCL_Other.png"), b"an older sweep's").unwrap();
    std::fs::write(
        out.join("collected.txt"),
        stamp + "figure4_OMCL_Other.png\n",
    )
    .unwrap();
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    // While another collect writes into the folder (it holds the folder's
    // lock), a second one is refused and changes nothing.
    {
        let held = std::fs::File::create(out.join(".omcl-collect.lock")).unwrap();
        held.try_lock().unwrap();
        let (o, text) = omcl(&["sweep", "collect", &m, "-o", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(1), "{text}");
        assert!(text.contains("another omcl sweep collect"), "{text}");
        assert!(out.join("figure4_OMCL_Other.png").exists());
    }
    let (o, text) = omcl(&["sweep", "collect", &m, "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{text}");
    assert!(!out.join("figure4_OMCL_Other.png").exists());
    assert!(out.join("table1.json").exists() && out.join("notes.txt").exists());
    // Tables no collect recorded: refused unless --force, and kept.
    let theirs = dir.path().join("theirs");
    std::fs::create_dir(&theirs).unwrap();
    std::fs::write(theirs.join("bench.md"), b"another sweep's table").unwrap();
    let (o, text) = omcl(&["sweep", "collect", &m, "-o", theirs.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("bench.md") && text.contains("--force"),
        "{text}"
    );
    assert!(!theirs.join("table1.json").exists());
    let (o, text) = omcl(&[
        "sweep",
        "collect",
        &m,
        "-o",
        theirs.to_str().unwrap(),
        "--force",
    ]);
    assert!(o.status.success(), "{text}");
    assert!(theirs.join("table1.json").exists() && theirs.join("bench.md").exists());

    // Corrupt run 0's result; make run 2's manifest line another version's.
    let bad_result = result_file(dir.path(), &ids[0]);
    std::fs::write(&bad_result, b"{\"id\": \"trunc").unwrap();
    let text_m = std::fs::read_to_string(&m).unwrap();
    let version = env!("CARGO_PKG_VERSION");
    let mut lines: Vec<String> = text_m.lines().map(String::from).collect();
    lines[3] = lines[3].replace(&format!("\"omcl\":\"{version}\""), "\"omcl\":\"0.0.1-old\"");
    std::fs::write(&m, lines.join("\n") + "\n").unwrap();

    // A run whose manifest line is unusable cannot succeed on a retry:
    // exit 3, which the Slurm script does not requeue.
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "2"]);
    assert_eq!(o.status.code(), Some(3), "{text}");
    assert!(
        text.contains("cannot run") && text.contains("line 4"),
        "{text}"
    );
    // Failed runs: listed, and the exit code says so (for scripts).
    let (o, text) = omcl(&["sweep", "status", &m]);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("3 runs: 1 done, 2 failed, 0 missing") && text.contains("2 of 3 runs failed"),
        "{text}"
    );

    let out2 = dir.path().join("tables2");
    let (o, text) = omcl(&["sweep", "collect", &m, "-o", out2.to_str().unwrap()]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains(&ids[0]) && text.contains("corrupt result file"),
        "{text}"
    );
    assert!(text.contains(bad_result.to_str().unwrap()), "{text}");
    assert!(
        text.contains(&ids[2]) && text.contains("omcl 0.0.1-old") && text.contains("line 4"),
        "{text}"
    );
    assert!(text.contains("2 of 3 runs have no result"), "{text}");
    // The rest of the table is written: run 1 alone, equal to before.
    let rows2: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out2.join("table1.json")).unwrap()).unwrap();
    let per = rows2[0]["per_sequence"].as_array().unwrap();
    assert_eq!(per.len(), 1);
    assert_eq!(per[0]["errors_m"], rows[0]["per_sequence"][1]["errors_m"]);
    let md = std::fs::read_to_string(out2.join("table1.md")).unwrap();
    assert!(md.contains("## Failed runs (2 of 3"), "{md}");

    // Running the other version's line is an error naming line and run.
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "2"]);
    assert!(!o.status.success(), "{text}");
    assert!(text.contains("line 4") && text.contains(&ids[2]), "{text}");

    // A missing map with --no-build-maps: the run and the map file named,
    // a failure note left, no result.
    let empty = dir.path().join("no-maps");
    let (o, text) = omcl(&[
        "sweep",
        "run",
        &m,
        "--index",
        "0",
        "--no-build-maps",
        "--cache",
        empty.to_str().unwrap(),
    ]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains(&format!("run {}: map file", ids[0]))
            && text.contains(empty.to_str().unwrap())
            && text.contains("is missing"),
        "{text}"
    );
    let (_, text) = omcl(&["sweep", "status", &m]);
    assert!(
        text.contains(".failed") && text.contains("is missing"),
        "{text}"
    );
}

/// `sweep plan` never replaces a file holding anything but the very plan
/// it makes (a pose file was replaced by a manifest, exit 0) unless
/// `--force`, says so when the plan is already there, and names the
/// experiments only `omcl bench` runs (they planned 0 runs, exit 0).
#[test]
fn plans_replace_nothing_unasked_and_name_in_process_experiments() {
    let dir = tempfile::tempdir().unwrap();
    let m = plan(dir.path());
    let before = std::fs::read(&m).unwrap();
    // The same plan again: left as it is.
    let again = plan_args(&m, "3");
    let (o, text) = omcl(&again.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        o.status.success() && text.contains("already holds this plan"),
        "{text}"
    );
    assert_eq!(std::fs::read(&m).unwrap(), before);
    // Another plan over it: refused, then replaced with --force.
    let other = plan_args(&m, "2");
    let (o, text) = omcl(&other.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains("another plan (3 runs)") && text.contains("--force"),
        "{text}"
    );
    assert_eq!(std::fs::read(&m).unwrap(), before);
    let mut forced = other.clone();
    forced.push("--force".into());
    let (o, text) = omcl(&forced.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        o.status.success() && text.contains("planned 2 runs"),
        "{text}"
    );
    // A file that is not a manifest: refused, untouched.
    let poses = dir.path().join("poses.txt");
    std::fs::write(&poses, "0 0 0 0 0 0 0 1\n").unwrap();
    let over = plan_args(poses.to_str().unwrap(), "1");
    let (o, text) = omcl(&over.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!o.status.success(), "{text}");
    assert!(text.contains("something other than a manifest"), "{text}");
    assert_eq!(
        std::fs::read_to_string(&poses).unwrap(),
        "0 0 0 0 0 0 0 1\n"
    );
    // A folder as -o: said so (it was "something other than a manifest").
    let (o, text) = omcl(
        &plan_args(dir.path().to_str().unwrap(), "1")
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("is a folder") && text.contains("manifest.jsonl"),
        "{text}"
    );
    // A misspelt variant beside a right one is named, not dropped.
    let typo = dir.path().join("typo.jsonl");
    let mut args = plan_args(typo.to_str().unwrap(), "1");
    let v = args.iter().position(|a| a == "OMCL_GT_exact").unwrap();
    args[v] = "OMCL_GT_exact,OMCL_Lseg".into();
    let (o, text) = omcl(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("\"OMCL_Lseg\" is not a variant") && text.contains("OMCL_LSeg"),
        "{text}"
    );
    assert!(!typo.exists());
    // Experiments that run in one process are named, nothing written.
    let fresh = dir.path().join("fresh.jsonl");
    for e in ["table4", "sevenscenes", "table1-floorplan"] {
        let (o, text) = omcl(&["sweep", "plan", e, "-o", fresh.to_str().unwrap()]);
        assert!(!o.status.success(), "{text}");
        assert!(text.contains(&format!("omcl bench {e}")), "{text}");
        assert!(!fresh.exists());
    }
}

/// Tiny Table I runs of OMCL_GT_exact from seed 1000 (`omcl bench`'s and
/// `omcl sweep plan`'s options), their count to follow.
fn tiny_table1() -> Vec<&'static str> {
    [
        &[
            "table1",
            "--variants",
            "OMCL_GT_exact",
            "--first-seed",
            "1000",
        ][..],
        &common::TINY_RUN,
        &["--sequences"],
    ]
    .concat()
}

fn plan_args(out: &str, sequences: &str) -> Vec<String> {
    [
        &["sweep", "plan"][..],
        &tiny_table1(),
        &[sequences, "-o", out],
    ]
    .concat()
    .into_iter()
    .map(String::from)
    .collect()
}

/// `omcl bench` starts afresh unless `--resume`, which reuses the runs
/// already in `<out>/sweep/`.
#[test]
fn bench_resumes_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let args = |resume: bool| {
        let mut v = [&["bench"][..], &tiny_table1(), &["1", "-o", out]].concat();
        if resume {
            v.push("--resume");
        }
        v
    };
    let (o, text) = omcl(&args(false));
    assert!(o.status.success(), "{text}");
    assert!(!text.contains("(result there)"), "{text}");
    let table = std::fs::read_to_string(dir.path().join("table1.json")).unwrap();
    let (o, text) = omcl(&args(true));
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("[1/1] run 0 (table1 OMCL_GT_exact) sequence 1000"),
        "{text}"
    );
    assert!(text.contains("(result there)"), "{text}");
    // The same result file, so the same table, speeds included.
    assert_eq!(
        std::fs::read_to_string(dir.path().join("table1.json")).unwrap(),
        table
    );
    let (o, text) = omcl(&args(false));
    assert!(o.status.success(), "{text}");
    assert!(!text.contains("(result there)"), "{text}");
}

/// `omcl bench -o DIR` does not wipe a sweep `omcl sweep plan` made in
/// `DIR/sweep/` (its manifest, results and maps) unless `--force`, nor
/// write into a folder another bench is writing into (its lock held).
#[test]
fn bench_leaves_a_planned_sweep_and_a_running_bench_alone() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let sweep = dir.path().join("sweep");
    let manifest = sweep.join("manifest.jsonl");
    let args: Vec<String> = plan_args(manifest.to_str().unwrap(), "2");
    let (o, text) = omcl(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{text}");
    let result = sweep.join("results").join("kept.json");
    std::fs::create_dir_all(result.parent().unwrap()).unwrap();
    std::fs::write(&result, "{}").unwrap();
    let planned = std::fs::read(&manifest).unwrap();
    let bench = |extra: &[&str]| {
        let v = [&["bench"][..], &tiny_table1(), &["1", "-o", out], extra].concat();
        omcl(&v)
    };
    let (o, text) = bench(&[]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains("no omcl bench made") && text.contains("--force"),
        "{text}"
    );
    assert_eq!(std::fs::read(&manifest).unwrap(), planned);
    assert!(result.exists());
    // A bench writing into the folder holds its lock: a second is refused.
    let (o, text) = bench(&["--force"]);
    assert!(o.status.success(), "{text}");
    assert!(!result.exists(), "--force replaces the planned sweep");
    let lock = std::fs::File::open(sweep.join("bench.lock")).unwrap();
    lock.lock().unwrap();
    let table = std::fs::read(dir.path().join("table1.json")).unwrap();
    let (o, text) = bench(&[]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains("another omcl bench is writing into it"),
        "{text}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("table1.json")).unwrap(),
        table
    );
    drop(lock);
    // Its own earlier sweep a bench replaces without being asked.
    let (o, text) = bench(&[]);
    assert!(o.status.success(), "{text}");
    // A sequence's folder is not a bench's.
    let seq = dir.path().join("seq");
    std::fs::create_dir(&seq).unwrap();
    std::fs::write(seq.join("intrinsics.txt"), "525 525 319.5 239.5 640 480\n").unwrap();
    let v = [
        &["bench"][..],
        &tiny_table1(),
        &["1", "-o", seq.to_str().unwrap()],
    ]
    .concat();
    let (o, text) = omcl(&v);
    assert!(!o.status.success(), "{text}");
    assert!(text.contains("a sequence's folder"), "{text}");
    assert_eq!(std::fs::read_dir(&seq).unwrap().count(), 1);
}

/// A manifest must be what its header plans: a header edited by hand (more
/// sequences than the lines hold) or a line from another plan is refused,
/// naming the line; a run's line written twice is a bad line, whose
/// advice is to plan again. A folder or a binary file given as the
/// manifest is named as such.
#[test]
fn a_manifest_edited_by_hand_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let m = plan(dir.path());
    let text_m = std::fs::read_to_string(&m).unwrap();
    let lines: Vec<&str> = text_m.lines().collect();
    let edited = dir.path().join("edited.jsonl");
    let write = |ls: &[String]| std::fs::write(&edited, ls.join("\n") + "\n").unwrap();
    let e = edited.to_str().unwrap();
    // The header says five sequences; three runs follow.
    let header = lines[0].replace("\"sequences\":3", "\"sequences\":5");
    assert_ne!(header, lines[0], "{}", lines[0]);
    let mut ls: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    ls[0] = header;
    write(&ls);
    let tables = dir.path().join("tables");
    for cmd in [
        &["status", e][..],
        &["run", e],
        &["collect", e, "-o", tables.to_str().unwrap()],
    ] {
        let (o, text) = omcl(&[&["sweep"][..], cmd].concat());
        let cmd = cmd[0];
        assert!(!o.status.success(), "{cmd}: {text}");
        assert!(
            text.contains("line 1") && text.contains("plan the sweep again"),
            "{cmd}: {text}"
        );
    }
    // A count edited to a billion is refused without planning it.
    let mut ls: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    ls[0] = lines[0].replace("\"sequences\":3", "\"sequences\":1000000000");
    write(&ls);
    let (o, text) = omcl(&["sweep", "status", e]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains("names 1000000000 sequences, more than the 3 run lines"),
        "{text}"
    );
    // The ablations run on --ablation-sequences, whatever --sequences
    // says: a plan of them alone with more sequences than runs is the
    // planner's own (it was refused as edited), and an edited ablation
    // count is refused as the sequences are.
    let abl = dir.path().join("ablation.jsonl");
    let a = abl.to_str().unwrap();
    let (o, text) = omcl(&[
        "sweep",
        "plan",
        "sampling",
        "--sequences",
        "30",
        "--frames",
        "4",
        "-o",
        a,
    ]);
    assert!(o.status.success(), "{text}");
    let planned: usize = text
        .split("planned ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!(planned < 30, "{text}");
    let (o, text) = omcl(&["sweep", "status", a]);
    assert!(o.status.success(), "{text}");
    assert!(text.contains(&format!("{planned} runs: 0 done")), "{text}");
    let abl_text = std::fs::read_to_string(&abl).unwrap();
    let abl_header = abl_text.lines().next().unwrap();
    let edited_abl = abl_header.replace("\"ablation_sequences\":3", "\"ablation_sequences\":100");
    assert_ne!(edited_abl, abl_header, "{abl_header}");
    std::fs::write(&abl, abl_text.replacen(abl_header, &edited_abl, 1)).unwrap();
    let (o, text) = omcl(&["sweep", "status", a]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains(&format!(
            "names 100 ablation sequences, more than the {planned} run lines"
        )),
        "{text}"
    );
    // Fewer particles in the header than the runs were planned with: each
    // run line is then not one the header plans.
    let mut ls: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let particles = ls[0].replace("\"particles\":64", "\"particles\":32");
    assert_ne!(particles, ls[0], "{}", ls[0]);
    ls[0] = particles;
    write(&ls);
    let (o, text) = omcl(&["sweep", "status", e]);
    assert!(!o.status.success(), "{text}");
    assert!(
        text.contains("line 2") && text.contains("not a run the header (line 1) plans"),
        "{text}"
    );
    // A line written twice, after two blank lines: the file's own line
    // numbers are named (header 1, blanks 2 and 3, runs 4 to 6, the
    // second copy of the second run 7).
    let mut ls: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    ls.insert(1, String::new());
    ls.insert(1, "  ".to_string());
    ls.push(lines[2].to_string());
    write(&ls);
    let (o, text) = omcl(&["sweep", "status", e]);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("4 runs: 0 done, 1 failed, 3 missing")
            && text.contains("again (its line is 5): a line written twice")
            && text.contains("line 7")
            && text.contains("it is a manifest line omcl cannot run: plan the sweep again"),
        "{text}"
    );
    // Not a manifest at all.
    let (o, text) = omcl(&["sweep", "run", dir.path().to_str().unwrap()]);
    assert!(!o.status.success(), "{text}");
    assert!(text.contains("a folder, not a sweep manifest"), "{text}");
    let binary = dir.path().join("map.omcl");
    std::fs::write(&binary, [0u8, 159, 146, 150, 255, 10]).unwrap();
    let (o, text) = omcl(&["sweep", "run", binary.to_str().unwrap()]);
    assert!(!o.status.success(), "{text}");
    assert!(text.contains("not a sweep manifest (not text"), "{text}");
}

/// Two workers on one manifest never compute a run twice: a run another
/// process holds the lock of is left to it (said, exit 0, no result), and
/// computed once the lock is free.
#[test]
fn a_run_another_process_is_computing_is_left_to_it() {
    let dir = tempfile::tempdir().unwrap();
    let m = plan(dir.path());
    let ids = ids(&m);
    let lock_path = result_file(dir.path(), &ids[1]).with_extension("lock");
    std::fs::create_dir_all(lock_path.parent().unwrap()).unwrap();
    let lock = std::fs::File::create(&lock_path).unwrap();
    lock.lock().unwrap();
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "1"]);
    assert!(o.status.success(), "{text}");
    assert!(text.contains("another process is running it"), "{text}");
    assert!(!result_file(dir.path(), &ids[1]).exists());
    drop(lock);
    let (o, text) = omcl(&["sweep", "run", &m, "--index", "1"]);
    assert!(o.status.success(), "{text}");
    assert!(result_file(dir.path(), &ids[1]).exists(), "{text}");
}

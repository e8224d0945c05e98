//! A sweep through a real Slurm job array on this machine: the one-node
//! cluster of `tools/slurm/start.sh` (Slurm and munge from Debian, started
//! by hand). Twenty short runs (Table I and II, two variants, five
//! sequences) go through `omcl sweep slurm --submit`; the collected tables
//! must equal the local path's (`omcl bench`) bit for bit, except the
//! measured speeds (steps/s and step times), which no two runs share. The
//! test cluster's MaxArraySize is 8, so the 20 runs go as three arrays. A
//! second submission is cancelled with `scancel` halfway, re-submitted
//! (only the missing runs), and must end identical to the first.
//!
//! If the cluster cannot start, the test fails with the daemons' logs.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const RUNS: usize = 20;
/// The test cluster's MaxArraySize: 20 runs need three arrays (ids 0 to 7).
const MAX_ARRAY: usize = 8;
/// Longest wait for an array to finish (a stuck cluster, not a speed
/// check: the arrays take well under a minute here).
const PATIENCE: Duration = Duration::from_secs(900);

fn omcl(args: &[&str]) -> (Output, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    (o, text)
}

fn sh(cmd: &str, args: &[&str]) -> String {
    match Command::new(cmd).args(args).output() {
        Ok(o) => {
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
        }
        Err(e) => format!("{cmd}: {e}"),
    }
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// What to look at when something went wrong: the queue, the node, the
/// daemons' logs and the tasks' logs.
fn diagnostics(logs: &Path) -> String {
    let mut s = format!(
        "squeue:\n{}\nsinfo:\n{}\n",
        sh("squeue", &[]),
        sh("sinfo", &["-N", "-l"])
    );
    let state = std::env::var("OMCL_SLURM_STATE").unwrap_or("/var/lib/omcl-slurm".into());
    for f in ["slurmctld.log", "slurmd.log"] {
        let p = Path::new(&state).join(f);
        let text = std::fs::read_to_string(&p).unwrap_or_default();
        let tail: Vec<&str> = text.lines().rev().take(30).collect();
        s += &format!("---- {}\n", p.display());
        for l in tail.iter().rev() {
            s += l;
            s.push('\n');
        }
    }
    if let Ok(rd) = std::fs::read_dir(logs) {
        for e in rd.flatten().take(6) {
            s += &format!(
                "---- {}\n{}\n",
                e.path().display(),
                std::fs::read_to_string(e.path()).unwrap_or_default()
            );
        }
    }
    s
}

fn start_cluster() {
    let o = Command::new("bash")
        .arg(repo().join("tools/slurm/start.sh"))
        .env("OMCL_SLURM_MAX_ARRAY", MAX_ARRAY.to_string())
        .output()
        .expect("running tools/slurm/start.sh");
    assert!(
        o.status.success(),
        "the one-node Slurm cluster did not start:\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `(done, failed, missing)` from `omcl sweep status`.
fn status(m: &str, results: &Path) -> (usize, usize, usize) {
    let (o, text) = omcl(&["sweep", "status", m, "--results", results.to_str().unwrap()]);
    assert!(o.status.success(), "{text}");
    let first = text.lines().next().unwrap_or("");
    let n: Vec<usize> = first
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(n.len(), 4, "{text}");
    (n[1], n[2], n[3])
}

/// Submits the runs still to do; returns the job ids.
fn submit(m: &str, results: &Path, cache: &Path, logs: &Path, concurrency: &str) -> Vec<String> {
    let (o, text) = omcl(&[
        "sweep",
        "slurm",
        m,
        "--submit",
        "--results",
        results.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
        "--logs",
        logs.to_str().unwrap(),
        "--cpus-per-task",
        "1",
        "--mem-mb",
        "1000",
        "--concurrency",
        concurrency,
        "--time",
        "00:10:00",
    ]);
    assert!(o.status.success(), "{text}\n{}", diagnostics(logs));
    let arrays = text
        .lines()
        .find_map(|l| {
            l.split(" in ")
                .nth(1)?
                .split(" array")
                .next()?
                .parse::<usize>()
                .ok()
        })
        .unwrap_or_else(|| panic!("no array count:\n{text}"));
    let line = text
        .lines()
        .find(|l| l.starts_with("submitted job(s) "))
        .unwrap_or_else(|| panic!("no job submitted:\n{text}"));
    let jobs: Vec<String> = line["submitted job(s) ".len()..]
        .split_whitespace()
        .map(String::from)
        .collect();
    assert_eq!(jobs.len(), arrays, "{text}");
    jobs
}

fn queued(jobs: &[String]) -> bool {
    let out = sh("squeue", &["-h", "-o", "%i", "-j", &jobs.join(",")]);
    out.lines()
        .any(|l| !l.trim().is_empty() && !l.contains("Invalid job id"))
}

/// Waits until the jobs have left the queue.
fn wait_jobs(jobs: &[String], logs: &Path) {
    let t = Instant::now();
    while queued(jobs) {
        assert!(
            t.elapsed() < PATIENCE,
            "jobs {jobs:?} still queued\n{}",
            diagnostics(logs)
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// JSON without the measured speeds.
fn without_timing(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(o) => {
            for k in ["step_seconds", "encoder_seconds", "fps", "fps_with_encoder"] {
                o.remove(k);
            }
            o.values_mut().for_each(without_timing);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(without_timing),
        _ => {}
    }
}

/// Markdown with Table I's two speed columns blanked.
fn md_without_timing(text: &str) -> String {
    text.lines()
        .map(|l| {
            let cells: Vec<&str> = l.split('|').collect();
            if cells.len() == 14 && l.starts_with("| OMCL") {
                let mut c = cells.clone();
                c[10] = " - ";
                c[11] = " - ";
                c.join("|")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn assert_same_tables(a: &Path, b: &Path) {
    for f in ["table1.json", "table2.json"] {
        let read = |d: &Path| {
            let mut v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(d.join(f)).unwrap()).unwrap();
            without_timing(&mut v);
            v
        };
        assert_eq!(read(a), read(b), "{f} differs between {a:?} and {b:?}");
    }
    let md = |d: &Path| md_without_timing(&std::fs::read_to_string(d.join("bench.md")).unwrap());
    assert_eq!(md(a), md(b));
    for v in ["OMCL_LSeg", "OMCL_GT_exact"] {
        for ext in ["png", "svg"] {
            let f = format!("figure4_{v}.{ext}");
            assert!(
                std::fs::read(a.join(&f)).unwrap() == std::fs::read(b.join(&f)).unwrap(),
                "{f} differs"
            );
        }
    }
}

fn plan() -> Vec<&'static str> {
    [
        &[
            "table1",
            "table2",
            "--variants",
            "OMCL_LSeg,OMCL_GT_exact",
            "--sequences",
            "5",
            "--first-seed",
            "1000",
        ][..],
        &common::TINY_RUN,
    ]
    .concat()
}

#[test]
fn a_sweep_through_a_slurm_job_array_equals_the_local_path() {
    start_cluster();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // The local path.
    let local = d.join("local");
    let (o, text) = omcl(&[&["bench"], &plan()[..], &["-o", local.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{text}");

    // The same sweep through a job array of 20 tasks, two at a time.
    let m = d.join("m.jsonl");
    let ms = m.to_str().unwrap();
    let (o, text) = omcl(&[&["sweep", "plan"], &plan()[..], &["-o", ms]].concat());
    assert!(o.status.success(), "{text}");
    assert!(text.contains(&format!("planned {RUNS} runs")), "{text}");
    let (cache, logs) = (d.join("cache"), d.join("logs"));
    let results = d.join("results");
    let jobs = submit(ms, &results, &cache, &logs, "2");
    assert_eq!(jobs.len(), RUNS.div_ceil(MAX_ARRAY), "one array per chunk");
    wait_jobs(&jobs, &logs);
    assert_eq!(status(ms, &results), (RUNS, 0, 0), "{}", diagnostics(&logs));
    let cluster = d.join("cluster");
    let (o, text) = omcl(&[
        "sweep",
        "collect",
        ms,
        "--results",
        results.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
        "-o",
        cluster.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{text}");
    assert_same_tables(&local, &cluster);
    // Every task logged under its job and array index.
    let task_logs = std::fs::read_dir(&logs).unwrap().count();
    assert_eq!(task_logs, RUNS, "{}", diagnostics(&logs));

    // Cancelled halfway, then re-submitted: only the missing runs run.
    let results2 = d.join("results2");
    let logs2 = d.join("logs2");
    let jobs = submit(ms, &results2, &cache, &logs2, "1");
    // Submitting again while they are queued would run their runs twice:
    // refused, naming the jobs, and the scripts the jobs run are left as
    // they are (the refused call asks for other options).
    let scripts: Vec<_> = std::fs::read_dir(m.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "sbatch" || x == "sh"))
        .collect();
    assert!(!scripts.is_empty());
    let before: Vec<Vec<u8>> = scripts.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let (o, text) = omcl(&[
        "sweep",
        "slurm",
        ms,
        "--submit",
        "--results",
        results2.to_str().unwrap(),
        "--logs",
        logs2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("still queued") && text.contains(&jobs[0]),
        "{text}"
    );
    for (p, b) in scripts.iter().zip(&before) {
        assert_eq!(&std::fs::read(p).unwrap(), b, "{} rewritten", p.display());
    }
    let t = Instant::now();
    while status(ms, &results2).0 < 4 {
        assert!(t.elapsed() < PATIENCE, "{}", diagnostics(&logs2));
        std::thread::sleep(Duration::from_millis(200));
    }
    let ids: Vec<&str> = jobs.iter().map(String::as_str).collect();
    let out = sh("scancel", &ids);
    assert!(out.trim().is_empty(), "scancel: {out}");
    wait_jobs(&jobs, &logs2);
    let (done, failed, missing) = status(ms, &results2);
    assert!(
        done < RUNS && missing > 0,
        "cancelled too late: {done} done"
    );
    assert_eq!(failed, 0);
    let (o, text) = omcl(&[
        "sweep",
        "slurm",
        ms,
        "--results",
        results2.to_str().unwrap(),
        "--logs",
        logs2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains(&format!("{done} done, {missing} to do")),
        "{text}"
    );
    let jobs = submit(ms, &results2, &cache, &logs2, "2");
    wait_jobs(&jobs, &logs2);
    assert_eq!(
        status(ms, &results2),
        (RUNS, 0, 0),
        "{}",
        diagnostics(&logs2)
    );
    let resumed = d.join("resumed");
    let (o, text) = omcl(&[
        "sweep",
        "collect",
        ms,
        "--results",
        results2.to_str().unwrap(),
        "--cache",
        cache.to_str().unwrap(),
        "-o",
        resumed.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{text}");
    assert_same_tables(&cluster, &resumed);
}

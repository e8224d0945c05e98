//! A sweep as Slurm job arrays: one `sbatch` script whose array task `t`
//! runs manifest entry `OMCL_SWEEP_OFFSET + t` with `omcl sweep run`, and
//! the submissions that cover the runs still to do: chunks of at most the
//! cluster's `MaxArraySize` indices, each with a `%P` concurrency limit.
//! A task whose run fails requeues itself (up to `retries` times); a
//! re-submission after cancellation or failures covers only the runs
//! without a result ([`super::sweep::status`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use super::sweep::SweepError;

/// What the array tasks ask for and where they write.
#[derive(Debug, Clone, PartialEq)]
pub struct SlurmOptions {
    /// The omcl binary the tasks run (absolute path on the shared file system).
    pub omcl: PathBuf,
    pub manifest: PathBuf,
    pub results: PathBuf,
    pub cache: PathBuf,
    /// Per-task logs: `<logs>/<job>_<task>.log`.
    pub logs: PathBuf,
    pub job_name: String,
    pub cpus_per_task: u32,
    /// Memory per task, MB.
    pub mem_mb: u64,
    /// Time limit per task (`sbatch --time`, e.g. `00:30:00`).
    pub time: String,
    pub partition: Option<String>,
    /// At most this many tasks of an array at once (`%P`).
    pub concurrency: Option<u32>,
    /// The cluster's `MaxArraySize`: array indices stay below it.
    pub max_array_size: usize,
    /// Requeues of a failed task before it stays failed.
    pub retries: u32,
}

impl SlurmOptions {
    /// Refuses what `sbatch` would reject or the script could not hold,
    /// by option name: a `--time` Slurm does not read, no memory, an array
    /// limit below 1, a concurrency of 0, and a job name or partition
    /// with whitespace or control characters (a newline would end the
    /// `#SBATCH` line and start a shell line).
    pub fn check(&self) -> Result<(), SweepError> {
        let bad = |s: &str| s.is_empty() || s.chars().any(|c| c.is_whitespace() || c.is_control());
        if bad(&self.job_name) {
            return Err(SweepError::Plan(format!(
                "--job-name {:?}: empty, or with whitespace or control characters",
                self.job_name
            )));
        }
        if let Some(p) = self.partition.as_deref().filter(|p| bad(p)) {
            return Err(SweepError::Plan(format!(
                "--partition {p:?}: empty, or with whitespace or control characters"
            )));
        }
        if !is_slurm_time(&self.time) {
            return Err(SweepError::Plan(format!(
                "--time {:?}: not a Slurm time limit (MINUTES, MINUTES:SECONDS, \
                 HOURS:MINUTES:SECONDS, DAYS-HOURS, DAYS-HOURS:MINUTES, \
                 DAYS-HOURS:MINUTES:SECONDS or UNLIMITED)",
                self.time
            )));
        }
        if self.mem_mb == 0 {
            return Err(SweepError::Plan(
                "--mem-mb 0: a task needs memory (Slurm reads 0 as all of a node's)".into(),
            ));
        }
        if self.max_array_size == 0 {
            return Err(SweepError::Plan(
                "--max-array-size 0: array ids must stay below it, so it is at least 1".into(),
            ));
        }
        if self.concurrency == Some(0) {
            return Err(SweepError::Plan(
                "--concurrency 0: no task would ever run".into(),
            ));
        }
        Ok(())
    }
}

/// Whether `t` is a time limit `sbatch --time` reads: `M`, `M:S`,
/// `H:M:S`, `D-H`, `D-H:M`, `D-H:M:S` (decimal numbers), or `UNLIMITED` /
/// `INFINITE`.
fn is_slurm_time(t: &str) -> bool {
    if t.eq_ignore_ascii_case("unlimited") || t.eq_ignore_ascii_case("infinite") {
        return true;
    }
    let num = |s: &str| !s.is_empty() && s.len() <= 9 && s.bytes().all(|b| b.is_ascii_digit());
    let (days, rest) = match t.split_once('-') {
        Some((d, r)) => (Some(d), r),
        None => (None, t),
    };
    let parts: Vec<&str> = rest.split(':').collect();
    days.is_none_or(num) && parts.len() <= 3 && parts.iter().all(|p| num(p))
}

/// One `sbatch` submission: runs `offset + t` for every `t` in `array`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Chunk {
    pub offset: usize,
    /// Task ids relative to `offset`, all below the array size limit.
    pub tasks: Vec<usize>,
}

impl Chunk {
    /// The `--array` value: ranges `a-b`, single ids, and `%P`.
    pub fn array_spec(&self, concurrency: Option<u32>) -> String {
        let mut s = ranges(&self.tasks);
        if let Some(p) = concurrency {
            let _ = write!(s, "%{p}");
        }
        s
    }
}

/// Splits run indices (sorted or not) into chunks of array ids below
/// `max_array_size` (Slurm's limit is exclusive: ids 0 ..= size - 1).
pub fn chunks(indices: &[usize], max_array_size: usize) -> Vec<Chunk> {
    let size = max_array_size.max(1);
    let mut sorted = indices.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut out: Vec<Chunk> = Vec::new();
    for i in sorted {
        let offset = i / size * size;
        match out.last_mut() {
            Some(c) if c.offset == offset => c.tasks.push(i - offset),
            _ => out.push(Chunk {
                offset,
                tasks: vec![i - offset],
            }),
        }
    }
    out
}

/// Sorted distinct ids as `0-3,7,9-10`.
pub fn ranges(ids: &[usize]) -> String {
    let mut s = String::new();
    let mut i = 0;
    while i < ids.len() {
        let mut j = i;
        while j + 1 < ids.len() && ids[j + 1] == ids[j] + 1 {
            j += 1;
        }
        if !s.is_empty() {
            s.push(',');
        }
        if j == i {
            let _ = write!(s, "{}", ids[i]);
        } else {
            let _ = write!(s, "{}-{}", ids[i], ids[j]);
        }
        i = j + 1;
    }
    s
}

fn quote(p: &Path) -> String {
    format!("'{}'", p.display().to_string().replace('\'', r"'\''"))
}

/// The batch script every chunk submits (the array and the offset are
/// given at submission).
pub fn script(o: &SlurmOptions) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(s, "#SBATCH --job-name={}", o.job_name);
    let _ = writeln!(s, "#SBATCH --cpus-per-task={}", o.cpus_per_task);
    let _ = writeln!(s, "#SBATCH --mem={}M", o.mem_mb);
    let _ = writeln!(s, "#SBATCH --time={}", o.time);
    if let Some(p) = &o.partition {
        let _ = writeln!(s, "#SBATCH --partition={p}");
    }
    let _ = writeln!(s, "#SBATCH --output={}/%A_%a.log", o.logs.display());
    s += "#SBATCH --open-mode=append\n#SBATCH --requeue\n";
    let _ = write!(
        s,
        r#"# omcl sweep: array task t runs manifest entry OMCL_SWEEP_OFFSET + t.
# Submitted by `omcl sweep slurm --submit` (or submit.sh beside this file).
set -u
index=$(( SLURM_ARRAY_TASK_ID + ${{OMCL_SWEEP_OFFSET:-0}} ))
export RAYON_NUM_THREADS="${{SLURM_CPUS_PER_TASK:-1}}"
echo "omcl sweep: job ${{SLURM_ARRAY_JOB_ID:-?}}_${{SLURM_ARRAY_TASK_ID}} run $index on $(hostname -s), restart ${{SLURM_RESTART_COUNT:-0}}"
{omcl} sweep run {manifest} --index "$index" --results {results} --cache {cache}
rc=$?
if [ "$rc" -eq 3 ]; then
  echo "omcl sweep: run $index cannot run (exit 3: its manifest line); not requeued" >&2
elif [ "$rc" -ne 0 ] && [ "${{SLURM_RESTART_COUNT:-0}}" -lt {retries} ]; then
  echo "omcl sweep: run $index failed (exit $rc); requeueing" >&2
  scontrol requeue "${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}"
fi
exit "$rc"
"#,
        omcl = quote(&o.omcl),
        manifest = quote(&o.manifest),
        results = quote(&o.results),
        cache = quote(&o.cache),
        retries = o.retries,
    );
    s
}

/// The `sbatch` arguments of one chunk's submission (script path last).
pub fn sbatch_args(chunk: &Chunk, o: &SlurmOptions, script: &Path) -> Vec<String> {
    vec![
        "--parsable".into(),
        format!("--array={}", chunk.array_spec(o.concurrency)),
        format!("--export=ALL,OMCL_SWEEP_OFFSET={}", chunk.offset),
        script.display().to_string(),
    ]
}

/// A shell script with the `sbatch` command of every chunk.
pub fn submit_script(chunks: &[Chunk], o: &SlurmOptions, script: &Path) -> String {
    let mut s =
        String::from("#!/bin/bash\n# Submits the runs still to do, chunk by chunk.\nset -e\n");
    for c in chunks {
        let args: Vec<String> = sbatch_args(c, o, script)
            .iter()
            .map(|a| format!("'{}'", a.replace('\'', r"'\''")))
            .collect();
        let _ = writeln!(s, "sbatch {}", args.join(" "));
    }
    s
}

/// The cluster's `MaxArraySize` (`scontrol show config`).
pub fn max_array_size() -> Result<usize, SweepError> {
    let out = run_tool(Command::new("scontrol").args(["show", "config"]))?;
    out.lines()
        .find_map(|l| {
            let (k, v) = l.split_once('=')?;
            (k.trim() == "MaxArraySize").then(|| v.trim().parse().ok())?
        })
        .ok_or_else(|| SweepError::Plan("scontrol show config: no MaxArraySize".into()))
}

/// Submits every chunk; returns the job ids.
pub fn submit(
    chunks: &[Chunk],
    o: &SlurmOptions,
    script: &Path,
) -> Result<Vec<String>, SweepError> {
    chunks
        .iter()
        .map(|c| {
            let out = run_tool(Command::new("sbatch").args(sbatch_args(c, o, script)))?;
            Ok(out.trim().split(';').next().unwrap_or("").to_string())
        })
        .collect()
}

/// The array jobs in the queue (pending or running) that run `script`
/// (`squeue`'s command column), by job id.
pub fn queued_jobs(script: &Path) -> Result<Vec<String>, SweepError> {
    let out = run_tool(Command::new("squeue").args(["--noheader", "--format=%F|%o"]))?;
    Ok(jobs_running(&out, script))
}

/// The job ids of `squeue --format=%F|%o` lines whose command is `script`.
fn jobs_running(squeue: &str, script: &Path) -> Vec<String> {
    let mut ids: Vec<String> = squeue
        .lines()
        .filter_map(|l| {
            let (id, command) = l.trim().split_once('|')?;
            (Path::new(command.trim()) == script).then(|| id.trim().to_string())
        })
        .collect();
    ids.sort();
    ids.dedup();
    ids
}

fn run_tool(cmd: &mut Command) -> Result<String, SweepError> {
    let name = format!("{cmd:?}");
    let out = cmd.output().map_err(|source| SweepError::Io {
        path: PathBuf::from(cmd.get_program()),
        source,
    })?;
    if !out.status.success() {
        return Err(SweepError::Plan(format!(
            "{name} failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queued_jobs_are_those_of_the_script() {
        let squeue = "1160|/tmp/a/sweep.sbatch\n1160|/tmp/a/sweep.sbatch\n1161|/tmp/b/sweep.sbatch\n\
                      1170|/tmp/a/sweep.sbatch\n";
        let a = Path::new("/tmp/a/sweep.sbatch");
        assert_eq!(jobs_running(squeue, a), vec!["1160", "1170"]);
        assert!(jobs_running("", a).is_empty());
    }

    #[test]
    fn ranges_by_hand() {
        assert_eq!(ranges(&[]), "");
        assert_eq!(ranges(&[4]), "4");
        assert_eq!(ranges(&[0, 1, 2, 3, 7, 9, 10]), "0-3,7,9-10");
    }

    /// 2,500 runs with MaxArraySize 1001: ids 0..=1000 per chunk, three
    /// chunks at offsets 0, 1001, 2002; missing runs only where asked.
    #[test]
    fn options_sbatch_would_reject_are_refused_by_name() {
        let good = SlurmOptions {
            omcl: "/bin/omcl".into(),
            manifest: "/m.jsonl".into(),
            results: "/r".into(),
            cache: "/c".into(),
            logs: "/l".into(),
            job_name: "omcl-sweep".into(),
            cpus_per_task: 2,
            mem_mb: 2000,
            time: "01:00:00".into(),
            partition: Some("debug".into()),
            concurrency: Some(4),
            max_array_size: 1001,
            retries: 2,
        };
        good.check().unwrap();
        for t in [
            "30",
            "30:00",
            "1:00:00",
            "2-0",
            "2-12:30",
            "2-12:30:00",
            "UNLIMITED",
        ] {
            SlurmOptions {
                time: t.into(),
                ..good.clone()
            }
            .check()
            .unwrap_or_else(|e| panic!("{t}: {e}"));
        }
        let refused = |o: SlurmOptions, option: &str| {
            let e = o.check().unwrap_err().to_string();
            assert!(e.contains(option), "{e}");
        };
        for t in [
            "bogus",
            "",
            "1:2:3:4",
            "-5",
            "1h",
            "1-2-3",
            "01:00:00\necho x",
        ] {
            refused(
                SlurmOptions {
                    time: t.into(),
                    ..good.clone()
                },
                "--time",
            );
        }
        refused(
            SlurmOptions {
                job_name: "x\necho INJECTED".into(),
                ..good.clone()
            },
            "--job-name",
        );
        refused(
            SlurmOptions {
                partition: Some("a b".into()),
                ..good.clone()
            },
            "--partition",
        );
        refused(
            SlurmOptions {
                mem_mb: 0,
                ..good.clone()
            },
            "--mem-mb",
        );
        refused(
            SlurmOptions {
                max_array_size: 0,
                ..good.clone()
            },
            "--max-array-size",
        );
        refused(
            SlurmOptions {
                concurrency: Some(0),
                ..good.clone()
            },
            "--concurrency",
        );
    }

    #[test]
    fn chunks_stay_below_the_array_limit() {
        let all: Vec<usize> = (0..2500).collect();
        let c = chunks(&all, 1001);
        assert_eq!(
            c.iter().map(|c| c.offset).collect::<Vec<_>>(),
            [0, 1001, 2002]
        );
        assert_eq!(c[0].tasks.len(), 1001);
        assert_eq!(*c[0].tasks.last().unwrap(), 1000);
        assert_eq!(c[2].tasks, (0..498).collect::<Vec<_>>());
        assert_eq!(c[0].array_spec(Some(8)), "0-1000%8");
        let c = chunks(&[1005, 3, 4, 2003, 5], 1001);
        assert_eq!(
            c,
            [
                Chunk {
                    offset: 0,
                    tasks: vec![3, 4, 5]
                },
                Chunk {
                    offset: 1001,
                    tasks: vec![4]
                },
                Chunk {
                    offset: 2002,
                    tasks: vec![1]
                },
            ]
        );
        assert_eq!(c[0].array_spec(None), "3-5");
    }

    #[test]
    fn the_script_runs_the_offset_entry_and_requeues() {
        let o = SlurmOptions {
            omcl: "/opt/omcl it's".into(),
            manifest: "/s/m.jsonl".into(),
            results: "/s/r".into(),
            cache: "/s/c".into(),
            logs: "/s/logs".into(),
            job_name: "omcl-sweep".into(),
            cpus_per_task: 2,
            mem_mb: 1500,
            time: "00:30:00".into(),
            partition: None,
            concurrency: Some(4),
            max_array_size: 1001,
            retries: 2,
        };
        let s = script(&o);
        assert!(s.contains("#SBATCH --mem=1500M\n"), "{s}");
        assert!(s.contains("#SBATCH --output=/s/logs/%A_%a.log\n"), "{s}");
        assert!(s.contains("index=$(( SLURM_ARRAY_TASK_ID + ${OMCL_SWEEP_OFFSET:-0} ))"));
        assert!(
            s.contains(r"'/opt/omcl it'\''s' sweep run '/s/m.jsonl' --index"),
            "{s}"
        );
        assert!(s.contains("-lt 2 ]"), "{s}");
        // The script's own logic, run by bash: a failed run is requeued,
        // one that cannot run (exit 3) is not. `omcl` and `scontrol` are
        // stand-ins that exit with a code and record the call.
        let d = tempfile::tempdir().unwrap();
        let calls = d.path().join("calls");
        let bin = d.path().join("bin");
        std::fs::create_dir(&bin).unwrap();
        let tool = |name: &str, body: &str| {
            let p = bin.join(name);
            std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
            p
        };
        let fake_omcl = tool("omcl", "exit \"$RUN_EXIT\"");
        tool("scontrol", &format!("echo \"$@\" >> '{}'", calls.display()));
        let o = SlurmOptions {
            omcl: fake_omcl,
            ..o
        };
        let path = d.path().join("job.sh");
        std::fs::write(&path, script(&o)).unwrap();
        for (exit, requeued) in [("1", true), ("3", false), ("0", false)] {
            let _ = std::fs::remove_file(&calls);
            let st = std::process::Command::new("bash")
                .arg(&path)
                .env("PATH", format!("{}:/usr/bin:/bin", bin.display()))
                .env("RUN_EXIT", exit)
                .env("SLURM_ARRAY_TASK_ID", "4")
                .env("SLURM_ARRAY_JOB_ID", "77")
                .env("SLURM_RESTART_COUNT", "0")
                .output()
                .unwrap();
            assert_eq!(st.status.code(), exit.parse().ok(), "{st:?}");
            let called = std::fs::read_to_string(&calls).unwrap_or_default();
            assert_eq!(
                called == "requeue 77_4\n",
                requeued,
                "exit {exit}: {called:?}"
            );
        }
        let a = sbatch_args(
            &Chunk {
                offset: 1001,
                tasks: vec![0, 1, 5],
            },
            &o,
            Path::new("/s/j.sh"),
        );
        assert_eq!(
            a,
            [
                "--parsable",
                "--array=0-1,5%4",
                "--export=ALL,OMCL_SWEEP_OFFSET=1001",
                "/s/j.sh"
            ]
        );
    }
}

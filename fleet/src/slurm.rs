//! Slurm as the batch engine: a manifest's tasks (a flight each, or a
//! share of a flight's detect) as one job array (`sbatch --array`), each
//! array task running `postflight batch task MANIFEST --index
//! $SLURM_ARRAY_TASK_ID`; and what the queue (`squeue`)
//! and, where accounting is on, `sacct` say about the tasks.
//!
//! Slurm runs the tasks on its nodes, so the program, the manifest, the
//! flights and the fleet directory must be at the same paths there (a
//! shared file system), as HPC centres have them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use postflight_core::RunDir;
use postflight_core::time::now_rfc3339;
use serde::{Deserialize, Serialize};

use crate::error::Error;

/// The fleet directory's Slurm files: the batch script, the submissions
/// and the tasks' logs.
pub const SLURM_DIR: &str = "slurm";
const SCRIPT: &str = "batch.sbatch";
const SUBMISSIONS: &str = "submissions.json";
const LOGS: &str = "logs";

/// One `sbatch` of tasks of a manifest.
#[derive(Debug, Clone)]
pub struct ArrayJob {
    /// The `postflight` program the tasks run.
    pub program: PathBuf,
    pub manifest: PathBuf,
    pub fleet: PathBuf,
    /// The manifest's tasks to run, by index.
    pub indices: Vec<usize>,
    /// At most this many tasks at once (`--array=...%N`).
    pub max_running: Option<usize>,
    /// Options passed to every task's `postflight batch task`.
    pub task_args: Vec<String>,
    /// More options for `sbatch` (`--partition=gpu`, `--time=2:00:00`).
    pub sbatch_args: Vec<String>,
}

/// A submitted array, as `submissions.json` keeps it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Submission {
    pub job: String,
    pub indices: Vec<usize>,
    pub submitted: String,
}

impl ArrayJob {
    /// The batch script: `#SBATCH` options, then the task.
    pub fn script(&self) -> String {
        let logs = self.fleet.join(SLURM_DIR).join(LOGS).join("%A_%a.out");
        let mut task = vec![
            self.program.display().to_string(),
            "batch".into(),
            "task".into(),
            self.manifest.display().to_string(),
            "--out".into(),
            self.fleet.display().to_string(),
        ];
        task.extend(self.task_args.iter().cloned());
        let task =
            shlex::try_join(task.iter().map(String::as_str)).expect("paths without NUL bytes");
        format!(
            "#!/bin/sh\n\
             # One array task per task of {manifest}: a flight, or a share of\n\
             # a flight's detect, numbered from 0 in manifest order. Written by\n\
             # `postflight batch run --engine slurm`; `postflight batch status` reads how they went.\n\
             #SBATCH --job-name=postflight-batch\n\
             #SBATCH --output={logs}\n\
             # A flight's stages use as many threads as Slurm gave the task CPUs.\n\
             export RAYON_NUM_THREADS=\"${{SLURM_CPUS_PER_TASK:-1}}\"\n\
             exec {task} --index \"$SLURM_ARRAY_TASK_ID\"\n",
            manifest = self.manifest.display(),
            logs = logs.display(),
        )
    }

    /// Submit the array; with `wait`, return only when every task has ended
    /// (`sbatch --wait`). The submission is recorded in the fleet directory.
    pub fn submit(&self, wait: bool) -> Result<Submission, Error> {
        let dir = RunDir::create(&self.fleet.join(SLURM_DIR))?;
        RunDir::create(&dir.file(LOGS))?;
        dir.write_text(SCRIPT, &self.script())?;
        let mut sbatch = Command::new("sbatch");
        sbatch
            .arg("--parsable")
            .arg(format!(
                "--array={}",
                array_spec(&self.indices, self.max_running)
            ))
            .args(&self.sbatch_args);
        if wait {
            sbatch.arg("--wait");
        }
        // Options go before the script: what follows it is the script's.
        sbatch.arg(dir.file(SCRIPT));
        self.start(sbatch, wait, &dir)
    }

    /// Run `sbatch`, recording the job as soon as it is known.
    fn start(&self, mut sbatch: Command, wait: bool, dir: &RunDir) -> Result<Submission, Error> {
        use std::io::{BufRead, BufReader};
        let mut child = sbatch
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .map_err(|e| Error::Slurm(format!("cannot run sbatch ({e}); --engine slurm needs Slurm's sbatch on PATH (on one machine, `scripts/setup --slurm` starts a local cluster)")))?;
        // `--parsable` prints "JOBID[;CLUSTER]" first; with `--wait` the
        // array runs before sbatch exits, and `batch status` should know it.
        let mut line = String::new();
        let stdout = child.stdout.take().expect("piped");
        BufReader::new(stdout)
            .read_line(&mut line)
            .map_err(|e| Error::Slurm(format!("reading sbatch's output: {e}")))?;
        let job = line
            .trim()
            .split(';')
            .next()
            .unwrap_or_default()
            .to_string();
        let submission = Submission {
            job: job.clone(),
            indices: self.indices.clone(),
            submitted: now_rfc3339(),
        };
        if !job.is_empty() {
            let mut all = submissions(&self.fleet)?;
            all.push(submission.clone());
            dir.write_json(SUBMISSIONS, &all)?;
        }
        let output = child
            .wait_with_output()
            .map_err(|e| Error::Slurm(format!("waiting for sbatch: {e}")))?;
        let stderr = String::from_utf8_lossy(&output.stderr);
        if job.is_empty() {
            return Err(Error::Slurm(format!(
                "sbatch refused the array: {}",
                stderr.trim()
            )));
        }
        // With --wait a failed task makes sbatch fail too; the tasks'
        // records say which, so that is not an error of submitting.
        if !output.status.success() && !wait {
            return Err(Error::Slurm(format!("sbatch failed: {}", stderr.trim())));
        }
        Ok(submission)
    }
}

/// The submissions made into `fleet`, oldest first.
pub fn submissions(fleet: &Path) -> Result<Vec<Submission>, Error> {
    let path = fleet.join(SLURM_DIR).join(SUBMISSIONS);
    Ok(crate::read_json_if_present(&path, "delete it")?.unwrap_or_default())
}

/// Slurm's `--array` value for `indices`: ranges joined by commas, and a
/// `%N` limit on tasks running at once.
pub fn array_spec(indices: &[usize], max_running: Option<usize>) -> String {
    use postflight_core::runs;
    let mut sorted = indices.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let spec = runs::write(&runs::consecutive(&sorted), "-", ",");
    match max_running {
        Some(n) => format!("{spec}%{n}"),
        None => spec,
    }
}

/// The array tasks Slurm still holds (pending or running), by
/// `JOBID_TASKID`, with their state (`PENDING`, `RUNNING`, ...). `None`
/// when `squeue` cannot be asked.
pub fn queue(jobs: &[&str]) -> Option<HashMap<String, String>> {
    if jobs.is_empty() {
        return Some(HashMap::new());
    }
    let output = Command::new("squeue")
        .args(["--noheader", "--array", "--format=%i %T"])
        .arg(format!("--jobs={}", jobs.join(",")))
        .output()
        .ok()?;
    // A job that has left the queue makes squeue fail ("Invalid job id").
    let text = String::from_utf8_lossy(&output.stdout);
    Some(
        text.lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(id, state)| (id.trim().to_string(), state.trim().to_string()))
            .collect(),
    )
}

/// How Slurm's accounting says an array task ended (`TIMEOUT`,
/// `OUT_OF_MEMORY`, `CANCELLED by 0`); `None` without accounting.
pub fn accounting(task: &str) -> Option<String> {
    let output = Command::new("sacct")
        .args(["--noheader", "--parsable2", "--format=State,ExitCode"])
        .arg(format!("--jobs={task}"))
        .output()
        .ok()?;
    if !output.status.success() {
        return None;
    }
    let text = String::from_utf8_lossy(&output.stdout);
    let first = text.lines().next()?;
    let (state, exit) = first.split_once('|')?;
    Some(format!("{state} (exit {exit})"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_specs_join_runs_of_indices_and_limit_running_tasks() {
        assert_eq!(array_spec(&[0, 1, 2], None), "0-2");
        assert_eq!(array_spec(&[5, 0, 2, 3, 9, 4], Some(2)), "0,2-5,9%2");
        assert_eq!(array_spec(&[7], None), "7");
    }

    #[test]
    fn the_batch_script_runs_the_task_for_the_array_index_with_quoted_paths() {
        let job = ArrayJob {
            program: "/opt/post flight/postflight".into(),
            manifest: "/data/fleet.toml".into(),
            fleet: "/data/out".into(),
            indices: vec![0, 1],
            max_running: None,
            task_args: vec!["--quiet".into()],
            sbatch_args: vec![],
        };
        let script = job.script();
        assert!(script.starts_with("#!/bin/sh\n"), "{script}");
        assert!(script.contains("#SBATCH --output=/data/out/slurm/logs/%A_%a.out\n"));
        assert!(script.contains(
            "exec '/opt/post flight/postflight' batch task /data/fleet.toml --out /data/out --quiet --index \"$SLURM_ARRAY_TASK_ID\"\n"
        ), "{script}");
    }
}

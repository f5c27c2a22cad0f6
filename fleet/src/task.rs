//! A batch task's record: `batch.json` in its flight's run directory
//! (`batch-share-K-of-N.json` for a share of the flight's detect), written
//! when the task starts and again when it ends, so that `postflight batch
//! status` reads how every flight went from the run directories alone,
//! whichever engine ran them.

use std::path::{Path, PathBuf};

use postflight_core::RunDir;
use postflight_core::outputs::detect::Shard;
use postflight_core::time::now_rfc3339;
use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::manifest::FlightEntry;

/// The record's file name in the run directory, for a whole flight's task.
pub const TASK_RECORD: &str = "batch.json";

/// A task's record file: [`TASK_RECORD`], or `batch-share-K-of-N.json`.
pub fn record_file(share: Option<Shard>) -> String {
    format!("{}.json", task_files(share))
}

/// A task's output, as a worker on this machine keeps it: `batch.log`, or
/// `batch-share-K-of-N.log`.
pub fn log_file(share: Option<Shard>) -> String {
    format!("{}.log", task_files(share))
}

/// The stem of a task's files.
fn task_files(share: Option<Shard>) -> String {
    match share {
        None => TASK_RECORD.trim_end_matches(".json").to_string(),
        Some(s) => format!("batch-share-{}-of-{}", s.index, s.count),
    }
}

/// Where a task stands, as it last wrote.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskState {
    Running,
    Finished,
    Failed,
}

/// `batch.json`: the last attempt at one flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TaskRecord {
    /// The flight's index in the manifest.
    pub index: usize,
    /// The manifest's structure id and date (`YYYY-MM-DD`) of the flight.
    pub structure: String,
    pub date: Option<String>,
    pub flight: PathBuf,
    /// The share of the flight's detect it ran; absent: the whole flight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub share: Option<Shard>,
    pub state: TaskState,
    /// Why it failed, in one line.
    pub error: Option<String>,
    /// RFC 3339, UTC.
    pub started: String,
    pub ended: Option<String>,
    pub seconds: Option<f64>,
    /// The stages this attempt ran; empty when the run was up to date.
    pub stages_run: Vec<String>,
    /// Where it ran: the host, its process, and the engine's name for it.
    pub host: String,
    pub pid: u32,
    pub worker: Worker,
    pub postflight_version: String,
}

/// Which engine ran a task, and its id there.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "engine", rename_all = "snake_case")]
pub enum Worker {
    /// A process on the host, started by `postflight batch run` or by hand.
    Local,
    /// A Slurm array task, `JOBID_TASKID`.
    Slurm { job: String },
    /// A pod of a Kubernetes Indexed Job.
    Kubernetes { pod: String },
}

impl Worker {
    /// The engine this process runs under, from the variables Slurm and
    /// Kubernetes set for their tasks.
    pub fn current() -> Self {
        let var = |name| std::env::var(name).ok().filter(|v| !v.is_empty());
        if let (Some(job), Some(task)) = (var("SLURM_ARRAY_JOB_ID"), var("SLURM_ARRAY_TASK_ID")) {
            return Self::Slurm {
                job: format!("{job}_{task}"),
            };
        }
        if var("JOB_COMPLETION_INDEX").is_some() {
            return Self::Kubernetes {
                pod: var("HOSTNAME").unwrap_or_default(),
            };
        }
        Self::Local
    }
}

impl TaskRecord {
    /// A task starting on `entry` (or a `share` of it) in this process.
    pub fn start(entry: &FlightEntry, share: Option<Shard>) -> Self {
        Self {
            index: entry.index,
            structure: entry.structure.clone(),
            date: entry.date.map(|d| d.to_string()),
            flight: entry.flight.clone(),
            share,
            state: TaskState::Running,
            error: None,
            started: now_rfc3339(),
            ended: None,
            seconds: None,
            stages_run: Vec::new(),
            host: host_name(),
            pid: std::process::id(),
            worker: Worker::current(),
            postflight_version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }

    /// The task ended after `seconds`: finished having run `stages_run`,
    /// or failed with `error` (its first line is kept).
    pub fn end(mut self, seconds: f64, outcome: Result<Vec<String>, String>) -> Self {
        self.ended = Some(now_rfc3339());
        self.seconds = Some(seconds);
        match outcome {
            Ok(stages) => {
                self.state = TaskState::Finished;
                self.stages_run = stages;
            }
            Err(error) => {
                self.state = TaskState::Failed;
                self.error = Some(error.lines().next().unwrap_or_default().to_string());
            }
        }
        self
    }

    /// The record of the task on `run` (or a `share` of it), `None` when
    /// no such task has started there.
    pub fn read(run: &Path, share: Option<Shard>) -> Result<Option<Self>, Error> {
        crate::read_json_if_present(
            &run.join(record_file(share)),
            "delete it and run the flight again",
        )
    }

    /// How the tasks on `run` went, in one record: the whole flight's task,
    /// else of its shares' a failed one, else a running one, else the last
    /// to end (the one that ran the later stages).
    pub fn of_run(run: &Path) -> Result<Option<Self>, Error> {
        if let Some(whole) = Self::read(run, None)? {
            return Ok(Some(whole));
        }
        let mut shares = Vec::new();
        for entry in std::fs::read_dir(run).into_iter().flatten().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if name.starts_with("batch-share-") && name.ends_with(".json") {
                shares.extend(crate::read_json_if_present::<Self>(
                    &entry.path(),
                    "delete it and run the share again",
                )?);
            }
        }
        let by = |state| shares.iter().find(|r: &&Self| r.state == state).cloned();
        Ok(by(TaskState::Failed)
            .or_else(|| by(TaskState::Running))
            .or_else(|| shares.iter().max_by(|a, b| a.ended.cmp(&b.ended)).cloned()))
    }

    /// Write it into `run` (created if missing), whole or not at all.
    pub fn write(&self, run: &Path) -> Result<(), Error> {
        Ok(RunDir::create(run)?.write_json(&record_file(self.share), self)?)
    }

    /// Whether the process that wrote "running" is still at it, where this
    /// host can tell: `None` for another host's process or an engine's task
    /// (the engine knows).
    pub fn local_process_alive(&self) -> Option<bool> {
        if self.worker != Worker::Local || self.host != host_name() {
            return None;
        }
        // A live process with this pid that is a postflight task (pids are reused).
        let cmdline = std::fs::read(format!("/proc/{}/cmdline", self.pid)).unwrap_or_default();
        let args: Vec<&[u8]> = cmdline.split(|b| *b == 0).collect();
        let program = args
            .first()
            .map(|a| Path::new(std::str::from_utf8(a).unwrap_or("")));
        let is_postflight = program
            .and_then(Path::file_name)
            .is_some_and(|n| n.to_string_lossy().starts_with("postflight"));
        Some(is_postflight && args.windows(2).any(|w| w == [&b"batch"[..], &b"task"[..]]))
    }
}

/// This host's name, as Linux gives it.
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_task_keeps_the_first_line_of_its_error() {
        let record = TaskRecord::start(&FlightEntry::example(2), None)
            .end(1.5, Err("stage ingest failed: x\nmore".into()));
        assert_eq!(record.state, TaskState::Failed);
        assert_eq!(record.error.as_deref(), Some("stage ingest failed: x"));
        let dir = tempfile::tempdir().unwrap();
        record.write(dir.path()).unwrap();
        assert_eq!(TaskRecord::read(dir.path(), None).unwrap(), Some(record));
    }

    #[test]
    fn a_run_in_shares_is_as_its_failed_share_else_its_last_to_end() {
        let dir = tempfile::tempdir().unwrap();
        let share = |index| Some(Shard { index, count: 3 });
        let entry = FlightEntry::example(0);
        let mut first = TaskRecord::start(&entry, share(1)).end(2.0, Ok(vec!["ingest".into()]));
        first.ended = Some("2026-11-28T10:00:00Z".into());
        let mut last = TaskRecord::start(&entry, share(2)).end(2.0, Ok(vec!["report".into()]));
        last.ended = Some("2026-11-28T10:05:00Z".into());
        for r in [&first, &last] {
            r.write(dir.path()).unwrap();
        }
        assert!(dir.path().join("batch-share-2-of-3.json").is_file());
        assert_eq!(
            (record_file(None), log_file(share(2))),
            (
                TASK_RECORD.to_string(),
                "batch-share-2-of-3.log".to_string()
            )
        );
        assert_eq!(TaskRecord::of_run(dir.path()).unwrap(), Some(last));
        let failed = TaskRecord::start(&entry, share(3)).end(1.0, Err("no".into()));
        failed.write(dir.path()).unwrap();
        assert_eq!(TaskRecord::of_run(dir.path()).unwrap(), Some(failed));
    }

    #[test]
    fn a_running_record_of_a_process_that_is_gone_is_not_alive() {
        let mut record = TaskRecord::start(&FlightEntry::example(2), None);
        record.worker = Worker::Local;
        record.pid = u32::MAX - 1;
        assert_eq!(record.local_process_alive(), Some(false));
        record.pid = std::process::id();
        // This test binary is not a postflight task.
        assert_eq!(record.local_process_alive(), Some(false));
        record.host = "another-host".into();
        assert_eq!(record.local_process_alive(), None);
    }
}

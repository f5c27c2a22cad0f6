//! Where every flight of a manifest stands: its task record in its run
//! directory, and for flights submitted to Slurm what the queue (and
//! accounting, where it is on) says.

use std::path::Path;

use crate::error::Error;
use crate::manifest::{FlightEntry, Manifest, Task};
use crate::slurm;
use crate::task::{TaskRecord, TaskState, Worker};

/// One flight's state, or one task's.
#[derive(Debug, Clone, PartialEq)]
pub enum FlightState {
    /// No task has started on it.
    NotRun,
    /// Submitted to Slurm, waiting in its queue as `job`.
    Queued { job: String },
    /// A task is at work on it.
    Running { since: String, host: String },
    /// Its run is complete; `stages_run` of the last attempt (none: it was
    /// already up to date).
    Finished { seconds: f64, stages_run: usize },
    /// The last attempt failed with this one-line error.
    Failed { error: String },
    /// Its record says running but its task is gone (killed, out of time
    /// or memory): what is known of how it ended.
    Lost { why: String },
}

impl FlightState {
    /// A word for tables: `not run`, `queued`, `running`, `finished`,
    /// `failed`, `lost`.
    pub fn word(&self) -> &'static str {
        match self {
            Self::NotRun => "not run",
            Self::Queued { .. } => "queued",
            Self::Running { .. } => "running",
            Self::Finished { .. } => "finished",
            Self::Failed { .. } => "failed",
            Self::Lost { .. } => "lost",
        }
    }

    /// Failed or lost: what `--only-failed` runs again.
    pub fn needs_rerun(&self) -> bool {
        matches!(self, Self::Failed { .. } | Self::Lost { .. })
    }
}

/// A flight of the manifest and its state, from its tasks'.
#[derive(Debug, Clone)]
pub struct FlightStatus {
    pub entry: FlightEntry,
    pub state: FlightState,
    /// Its one task, or a task per share of its detect.
    pub tasks: Vec<TaskStatus>,
}

/// A task of the manifest, its state and its record.
#[derive(Debug, Clone)]
pub struct TaskStatus {
    pub task: Task,
    pub state: FlightState,
    pub record: Option<TaskRecord>,
}

impl FlightStatus {
    /// For a flight in shares: how many of its tasks have finished, of how many.
    pub fn shares_done(&self) -> Option<(usize, usize)> {
        let finished = |t: &&TaskStatus| matches!(t.state, FlightState::Finished { .. });
        (self.tasks.len() > 1)
            .then(|| (self.tasks.iter().filter(finished).count(), self.tasks.len()))
    }
}

/// The state of every flight of `manifest` in `fleet`.
pub fn status(manifest: &Manifest, fleet: &Path) -> Result<Vec<FlightStatus>, Error> {
    let submissions = slurm::submissions(fleet)?;
    let jobs: Vec<&str> = submissions.iter().map(|s| s.job.as_str()).collect();
    let queue = slurm::queue(&jobs).unwrap_or_default();
    let tasks = manifest.tasks();
    manifest
        .flights
        .iter()
        .map(|entry| {
            let dir = entry.run_dir(fleet);
            let tasks = tasks
                .iter()
                .filter(|t| t.flight == entry.index)
                .map(|task| {
                    let record = TaskRecord::read(&dir, task.share)?;
                    // The latest submission of this task, if Slurm still holds it.
                    let queued = submissions
                        .iter()
                        .rev()
                        .find(|s| s.indices.contains(&task.index))
                        .map(|s| format!("{}_{}", s.job, task.index))
                        .and_then(|id| queue.get(&id).map(|state| (id, state.clone())));
                    Ok(TaskStatus {
                        task: *task,
                        state: state_of(record.as_ref(), queued),
                        record,
                    })
                })
                .collect::<Result<Vec<_>, Error>>()?;
            Ok(FlightStatus {
                entry: entry.clone(),
                state: flight_state(&tasks),
                tasks,
            })
        })
        .collect()
}

/// A flight's state from its tasks': one task's own; of shares, a failed
/// or lost one's (naming it), else running, else queued, else finished
/// when every share has, else not run.
fn flight_state(tasks: &[TaskStatus]) -> FlightState {
    if let [one] = tasks {
        return one.state.clone();
    }
    let share = |t: &TaskStatus| {
        t.task
            .share
            .map(|s| format!("share {s}: "))
            .unwrap_or_default()
    };
    let first = |is: fn(&FlightState) -> bool| tasks.iter().find(|t| is(&t.state));
    if let Some(t) = first(FlightState::needs_rerun) {
        return match &t.state {
            FlightState::Failed { error } => FlightState::Failed {
                error: format!("{}{error}", share(t)),
            },
            FlightState::Lost { why } => FlightState::Lost {
                why: format!("{}{why}", share(t)),
            },
            other => other.clone(),
        };
    }
    let running = |s: &FlightState| matches!(s, FlightState::Running { .. });
    let queued = |s: &FlightState| matches!(s, FlightState::Queued { .. });
    if let Some(t) = first(running).or_else(|| first(queued)) {
        return t.state.clone();
    }
    let finished: Vec<_> = tasks
        .iter()
        .filter_map(|t| match t.state {
            FlightState::Finished {
                seconds,
                stages_run,
            } => Some((seconds, stages_run)),
            _ => None,
        })
        .collect();
    if finished.len() < tasks.len() {
        return FlightState::NotRun;
    }
    FlightState::Finished {
        seconds: finished.iter().map(|f| f.0).fold(0.0, f64::max),
        stages_run: finished.iter().map(|f| f.1).sum(),
    }
}

/// A flight's state from its record and, when Slurm holds a task for it,
/// that task and its queue state.
fn state_of(record: Option<&TaskRecord>, queued: Option<(String, String)>) -> FlightState {
    if let Some((job, state)) = &queued {
        let recorded_by_it = record.is_some_and(|r| r.worker == Worker::Slurm { job: job.clone() });
        if state == "PENDING" || !recorded_by_it {
            return FlightState::Queued { job: job.clone() };
        }
    }
    let Some(r) = record else {
        return FlightState::NotRun;
    };
    match r.state {
        TaskState::Finished => FlightState::Finished {
            seconds: r.seconds.unwrap_or(0.0),
            stages_run: r.stages_run.len(),
        },
        TaskState::Failed => FlightState::Failed {
            error: r.error.clone().unwrap_or_default(),
        },
        TaskState::Running => {
            let running = FlightState::Running {
                since: r.started.clone(),
                host: r.host.clone(),
            };
            match (&r.worker, queued.is_some(), r.local_process_alive()) {
                (Worker::Slurm { .. }, true, _) => running,
                (Worker::Slurm { job }, false, _) => FlightState::Lost {
                    why: slurm::accounting(job).map_or_else(
                        || format!("Slurm task {job} left the queue without finishing (cancelled, out of time or memory?)"),
                        |end| format!("Slurm task {job} ended {end}"),
                    ),
                },
                (_, _, Some(false)) => FlightState::Lost {
                    why: format!("its process {} on {} is gone", r.pid, r.host),
                },
                _ => running,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::manifest::FlightEntry;

    fn record(state: TaskState, worker: Worker) -> TaskRecord {
        let mut r = TaskRecord::start(&FlightEntry::example(0), None);
        r.state = state;
        r.worker = worker;
        r
    }

    #[test]
    fn a_flight_resubmitted_to_slurm_is_queued_whatever_its_last_attempt_said() {
        let failed = record(TaskState::Failed, Worker::Local);
        let pending = Some(("7_0".to_string(), "PENDING".to_string()));
        assert_eq!(
            state_of(Some(&failed), pending.clone()),
            FlightState::Queued { job: "7_0".into() }
        );
        assert_eq!(
            state_of(None, pending),
            FlightState::Queued { job: "7_0".into() }
        );
    }

    #[test]
    fn a_running_slurm_task_is_running_while_queued_and_lost_when_gone() {
        let running = record(TaskState::Running, Worker::Slurm { job: "7_0".into() });
        let in_queue = Some(("7_0".to_string(), "RUNNING".to_string()));
        assert!(matches!(
            state_of(Some(&running), in_queue),
            FlightState::Running { .. }
        ));
        match state_of(Some(&running), None) {
            FlightState::Lost { why } => assert!(why.contains("7_0"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_flight_in_shares_is_failed_by_one_share_and_finished_by_all() {
        let task = |index, state| TaskStatus {
            task: Task {
                index: index as usize,
                flight: 0,
                share: Some(postflight_core::outputs::detect::Shard { index, count: 3 }),
            },
            state,
            record: None,
        };
        let done = || FlightState::Finished {
            seconds: 2.0,
            stages_run: 1,
        };
        let mut tasks = vec![
            task(1, done()),
            task(2, done()),
            task(3, FlightState::NotRun),
        ];
        assert_eq!(flight_state(&tasks), FlightState::NotRun);
        tasks[2].state = FlightState::Failed {
            error: "stage x failed".into(),
        };
        assert_eq!(
            flight_state(&tasks),
            FlightState::Failed {
                error: "share 3/3: stage x failed".into()
            }
        );
        tasks[2].state = done();
        assert_eq!(
            flight_state(&tasks),
            FlightState::Finished {
                seconds: 2.0,
                stages_run: 3
            }
        );
    }

    #[test]
    fn finished_and_failed_records_say_so_and_only_failures_need_a_rerun() {
        let finished = state_of(Some(&record(TaskState::Finished, Worker::Local)), None);
        assert_eq!(finished.word(), "finished");
        assert!(!finished.needs_rerun());
        let failed = state_of(Some(&record(TaskState::Failed, Worker::Local)), None);
        assert!(failed.needs_rerun());
        assert_eq!(state_of(None, None), FlightState::NotRun);
    }
}

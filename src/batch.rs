//! `postflight batch`: the flights of a manifest, each one `postflight run`
//! into `FLEET_DIR/<structure>/<date or name>/` (a flight with `shards`
//! as that many tasks, each a share of its detect), on this machine (a
//! worker process per task) or as a Slurm job array; `status` reads how
//! each went, `k8s` writes the Kubernetes Indexed Job; and `postflight
//! fleet`, the fleet's tables and index page.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use clap::{Args, Subcommand, ValueEnum};
use fleet::manifest::Task;
use fleet::status::{FlightState, FlightStatus, status};
use fleet::{FlightEntry, Manifest, TaskRecord};
use postflight_core::outputs::detect::Shard;
use postflight_core::{PlanFile, YawUnit};

use crate::config::RunConfig;
use crate::pipeline::{self, RunInputs};

#[derive(Subcommand)]
pub enum BatchCommand {
    /// Run every flight of a manifest (TOML or CSV: structure, flight,
    /// date or name, and optionally map, plan, yaw, targets, model, config,
    /// shards), each into FLEET_DIR/<structure>/<date or name>/. A flight
    /// with `shards = N` runs as N tasks, each a share of its detect (the
    /// stages before it once, the later ones once, by the task finishing
    /// the last share). Finished work is skipped, interrupted work resumes,
    /// a failing task is recorded while the others go on.
    Run(BatchRunArgs),
    /// Run one task of a manifest (a flight, or a share of a flight's
    /// detect): what each worker, Slurm array task or Kubernetes pod runs.
    Task(TaskArgs),
    /// Where every flight of a manifest stands, and how many shares of a
    /// flight in shares are done (from the run directories, and Slurm's
    /// queue for submitted tasks).
    Status(FleetArgs),
    /// Write a Kubernetes Indexed Job running a manifest's tasks, one pod
    /// each (apply it with `kubectl apply -f`).
    K8s(K8sArgs),
}

#[derive(Args)]
pub struct FleetArgs {
    /// The manifest (.toml, else CSV).
    manifest: PathBuf,
    /// Fleet directory: one run directory per flight.
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
pub struct BatchRunArgs {
    #[command(flatten)]
    fleet: FleetArgs,
    /// Where the flights run: worker processes on this machine, or a Slurm
    /// job array (`sbatch --array`).
    #[arg(long, value_enum, default_value_t = Engine::Local)]
    engine: Engine,
    /// Tasks at once [default: 1 on this machine; Slurm's choice].
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// Only the tasks whose last attempt failed or was lost.
    #[arg(long)]
    only_failed: bool,
    /// With Slurm: wait until every task has ended, then show how they went.
    #[arg(long)]
    wait: bool,
    /// With Slurm: an option for sbatch (repeatable), e.g. `--sbatch-arg=--partition=gpu`.
    #[arg(long, value_name = "ARG", allow_hyphen_values = true)]
    sbatch_arg: Vec<String>,
    /// ONNX Runtime library for every flight's detect stage.
    #[arg(long, value_name = "PATH")]
    onnxruntime: Option<PathBuf>,
}

#[derive(Clone, Copy, ValueEnum)]
enum Engine {
    Local,
    Slurm,
}

#[derive(Args)]
pub struct TaskArgs {
    #[command(flatten)]
    fleet: FleetArgs,
    /// The task's index, from 0: the flight's row in the manifest when no
    /// flight is in shards (in a Kubernetes Indexed Job, its completion
    /// index).
    #[arg(long, env = "JOB_COMPLETION_INDEX")]
    index: usize,
    /// ONNX Runtime library for the detect stage.
    #[arg(long, value_name = "PATH")]
    onnxruntime: Option<PathBuf>,
}

#[derive(Args)]
pub struct K8sArgs {
    /// The manifest, at the path the pods see it.
    manifest: PathBuf,
    /// Fleet directory, at the path the pods see it.
    #[arg(long)]
    out: PathBuf,
    /// Container image with `postflight` on its PATH.
    #[arg(long)]
    image: String,
    /// The Job's name.
    #[arg(long, default_value = "postflight-batch")]
    name: String,
    /// Pods at once.
    #[arg(long, default_value_t = 2, value_name = "N")]
    jobs: usize,
    /// PersistentVolumeClaim holding the flights, the manifest and the fleet directory.
    #[arg(long, value_name = "CLAIM")]
    volume_claim: Option<String>,
    /// Where the claim is mounted (and the pods' working directory).
    #[arg(long, default_value = "/data", value_name = "PATH")]
    mount_path: String,
    /// Each pod's CPU request.
    #[arg(long, default_value = "2")]
    cpu: String,
    /// Each pod's memory request and limit.
    #[arg(long, default_value = "3Gi")]
    memory: String,
}

pub fn run(command: &BatchCommand, quiet: bool) -> anyhow::Result<()> {
    match command {
        BatchCommand::Run(args) => batch_run(args, quiet),
        BatchCommand::Task(args) => task(args, quiet),
        BatchCommand::Status(args) => print_status(args),
        BatchCommand::K8s(args) => k8s(args),
    }
}

/// The config file a `batch task` command's flight uses, to word settings by.
pub fn task_config(command: &BatchCommand) -> Option<PathBuf> {
    let BatchCommand::Task(args) = command else {
        return None;
    };
    let manifest = Manifest::load(&args.fleet.manifest).ok()?;
    let task = manifest.task(args.index).ok()?;
    manifest.flights[task.flight].config.clone()
}

/// `batch task`: one flight or share, recorded in its run directory as it
/// starts and ends.
fn task(args: &TaskArgs, quiet: bool) -> anyhow::Result<()> {
    let manifest = Manifest::load(&args.fleet.manifest)?;
    let task = manifest.task(args.index)?;
    let entry = &manifest.flights[task.flight];
    let dir = entry.run_dir(&args.fleet.out);
    let record = TaskRecord::start(entry, task.share);
    record.write(&dir)?;
    let started = Instant::now();
    let outcome = run_flight(entry, &dir, task.share, args.onnxruntime.clone(), quiet);
    let steps = outcome
        .as_ref()
        .map(Clone::clone)
        .map_err(|e| format!("{e:#}"));
    record
        .end(started.elapsed().as_secs_f64(), steps)
        .write(&dir)?;
    outcome.map(|_| ())
}

/// `postflight run` on a manifest's flight, or its `share` of the flight:
/// what it did (stages, and shares of detect).
fn run_flight(
    entry: &FlightEntry,
    out: &Path,
    share: Option<Shard>,
    onnxruntime: Option<PathBuf>,
    quiet: bool,
) -> anyhow::Result<Vec<String>> {
    let targets = match &entry.targets {
        None => coverage::Targets::Plan,
        Some(p) if p.extension().is_some_and(|e| e == "json") => {
            coverage::Targets::Boxes(p.clone())
        }
        Some(p) => coverage::Targets::Cloud(p.clone()),
    };
    let yaw = if entry.yaw_degrees {
        YawUnit::Degrees
    } else {
        YawUnit::Radians
    };
    let inputs = RunInputs {
        // A directory holds the flight's sorties.
        flights: ingest::sources_in(&entry.flight)?,
        map: entry.map.clone(),
        plan: entry.plan.clone().map(|path| PlanFile { path, yaw }),
        targets,
        model: entry.model.clone(),
        onnxruntime,
        config: RunConfig::load_or_default(entry.config.as_deref())?,
        out: out.to_owned(),
        force: None,
        previous: None,
    };
    let steps = match share {
        None => pipeline::run(&inputs, quiet)?
            .into_iter()
            .map(pipeline::Step::Stage)
            .collect(),
        Some(shard) => pipeline::run_share(&inputs, shard, quiet)?,
    };
    Ok(steps.iter().map(ToString::to_string).collect())
}

/// `batch run`: the flights to run, then the engine.
fn batch_run(args: &BatchRunArgs, quiet: bool) -> anyhow::Result<()> {
    let manifest = Manifest::load(&args.fleet.manifest)?;
    let fleet_dir = std::path::absolute(&args.fleet.out)?;
    let before = status(&manifest, &fleet_dir)?;
    let chosen = chosen_tasks(&before, args.only_failed, quiet);
    if chosen.is_empty() {
        if !quiet {
            println!("batch: nothing to run");
        }
        return Ok(());
    }
    match args.engine {
        Engine::Local => run_here(&manifest, &fleet_dir, &chosen, args, quiet),
        Engine::Slurm => submit_to_slurm(&manifest, &fleet_dir, &chosen, args, quiet),
    }
}

/// The tasks to run: all, or only those that failed; never one at work.
fn chosen_tasks(flights: &[FlightStatus], only_failed: bool, quiet: bool) -> Vec<Task> {
    flights
        .iter()
        .flat_map(|f| f.tasks.iter().map(move |t| (&f.entry, t)))
        .filter(|(entry, t)| {
            let busy = matches!(
                t.state,
                FlightState::Running { .. } | FlightState::Queued { .. }
            );
            if busy && !quiet {
                println!(
                    "{}: {}, left alone",
                    task_label(entry, &t.task),
                    t.state.word()
                );
            }
            !busy && (!only_failed || t.state.needs_rerun())
        })
        .map(|(_, t)| t.task)
        .collect()
}

/// How messages name a task: its flight's label, and its share.
fn task_label(entry: &FlightEntry, task: &Task) -> String {
    match task.share {
        None => entry.label(),
        Some(s) => format!("{} share {s}", entry.label()),
    }
}

/// Run the chosen tasks here, `--jobs` worker processes at a time, each
/// `postflight batch task` with its output in the run directory's
/// `batch.log` (`batch-share-K-of-N.log` for a share).
fn run_here(
    manifest: &Manifest,
    fleet_dir: &Path,
    chosen: &[Task],
    args: &BatchRunArgs,
    quiet: bool,
) -> anyhow::Result<()> {
    let jobs = args.jobs.unwrap_or(1).clamp(1, chosen.len());
    // Each flight's stages use every core they are given; share them.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = (cores / jobs).max(1);
    let program = std::env::current_exe()?;
    let started = Instant::now();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let failed = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| {
                while let Some(task) = chosen.get(next.fetch_add(1, Ordering::SeqCst)) {
                    let entry = &manifest.flights[task.flight];
                    let outcome = run_worker(&program, manifest, fleet_dir, task, args, threads);
                    let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                    let line = format!(
                        "[{n}/{}] {}: {}",
                        chosen.len(),
                        task_label(entry, task),
                        outcome_text(&outcome)
                    );
                    if outcome.is_err() {
                        failed.lock().expect("no worker panics").push(entry.label());
                        eprintln!("{line}");
                    } else if !quiet {
                        println!("{line}");
                    }
                }
            });
        }
    });
    let mut failed = failed.into_inner().expect("no worker panics");
    let seconds = started.elapsed().as_secs_f64();
    if !quiet {
        println!(
            "batch: {} of {} finished in {seconds:.0} s ({jobs} at a time); tables of the fleet: `postflight fleet {}`",
            chosen.len() - failed.len(),
            tasks(chosen),
            fleet_dir.display()
        );
    }
    failed.sort();
    failed.dedup();
    failures(&failed, &args.fleet)
}

/// One worker: `postflight batch task` for `task`, then its record.
fn run_worker(
    program: &Path,
    manifest: &Manifest,
    fleet_dir: &Path,
    task: &Task,
    args: &BatchRunArgs,
    threads: usize,
) -> Result<TaskRecord, String> {
    let dir = manifest.flights[task.flight].run_dir(fleet_dir);
    let log_path = dir.join(fleet::task::log_file(task.share));
    let log = std::fs::create_dir_all(&dir)
        .and_then(|()| std::fs::File::create(&log_path))
        .map_err(|e| format!("cannot write {}: {e}", log_path.display()))?;
    let mut worker = Command::new(program);
    worker
        .arg("--quiet")
        .args(["batch", "task"])
        .arg(&manifest.path)
        .arg("--out")
        .arg(fleet_dir)
        .arg("--index")
        .arg(task.index.to_string())
        .env("RAYON_NUM_THREADS", threads.to_string())
        .stdin(Stdio::null())
        .stdout(log.try_clone().map_err(|e| e.to_string())?)
        .stderr(log);
    if let Some(ort) = &args.onnxruntime {
        worker.arg("--onnxruntime").arg(ort);
    }
    let exit = worker
        .status()
        .map_err(|e| format!("cannot start {}: {e}", program.display()))?;
    let record = TaskRecord::read(&dir, task.share).map_err(|e| e.to_string())?;
    match record {
        Some(r) if r.state == fleet::TaskState::Finished && exit.success() => Ok(r),
        Some(r) if r.state == fleet::TaskState::Failed => Err(r.error.unwrap_or_default()),
        _ => Err(format!(
            "its task ended ({exit}) without recording how; see {}",
            log_path.display()
        )),
    }
}

fn outcome_text(outcome: &Result<TaskRecord, String>) -> String {
    match outcome {
        Ok(r) if r.stages_run.is_empty() => "up to date".into(),
        Ok(r) => format!(
            "finished in {:.0} s ({})",
            r.seconds.unwrap_or(0.0),
            r.stages_run.join(", ")
        ),
        Err(e) => format!("failed: {e}"),
    }
}

/// An error naming the failed flights and how to run them again.
fn failures(failed: &[String], fleet: &FleetArgs) -> anyhow::Result<()> {
    if failed.is_empty() {
        return Ok(());
    }
    anyhow::bail!(
        "{} failed ({}); `postflight batch status {} --out {}` shows why, and `postflight batch run ... --only-failed` runs them again once fixed",
        flights(failed.len()),
        failed.join(", "),
        fleet.manifest.display(),
        fleet.out.display()
    )
}

/// Submit the chosen tasks as one Slurm job array.
fn submit_to_slurm(
    manifest: &Manifest,
    fleet_dir: &Path,
    chosen: &[Task],
    args: &BatchRunArgs,
    quiet: bool,
) -> anyhow::Result<()> {
    let mut task_args = vec!["--quiet".to_string()];
    if let Some(ort) = &args.onnxruntime {
        task_args.push("--onnxruntime".into());
        task_args.push(std::path::absolute(ort)?.display().to_string());
    }
    let indices: Vec<usize> = chosen.iter().map(|t| t.index).collect();
    let job = fleet::slurm::ArrayJob {
        program: std::env::current_exe()?,
        manifest: manifest.path.clone(),
        fleet: fleet_dir.to_owned(),
        indices: indices.clone(),
        max_running: args.jobs,
        task_args,
        sbatch_args: args.sbatch_arg.clone(),
    };
    let submission = job.submit(args.wait)?;
    if !quiet {
        println!(
            "batch: submitted {} as Slurm job {} (array {})",
            tasks(chosen),
            submission.job,
            fleet::slurm::array_spec(&indices, args.jobs)
        );
    }
    if !args.wait {
        if !quiet {
            println!(
                "follow it with `postflight batch status {} --out {}`",
                args.fleet.manifest.display(),
                args.fleet.out.display()
            );
        }
        return Ok(());
    }
    let after = status(manifest, fleet_dir)?;
    let failed: Vec<String> = after
        .iter()
        .filter(|f| {
            let ran = chosen.iter().any(|t| t.flight == f.entry.index);
            ran && !matches!(f.state, FlightState::Finished { .. })
        })
        .map(|f| f.entry.label())
        .collect();
    if !quiet {
        print_table(&after);
    }
    failures(&failed, &args.fleet)
}

/// `batch status`.
fn print_status(args: &FleetArgs) -> anyhow::Result<()> {
    let manifest = Manifest::load(&args.manifest)?;
    let flights = status(&manifest, &std::path::absolute(&args.out)?)?;
    print_table(&flights);
    Ok(())
}

/// One line per flight, then the counts.
fn print_table(flights: &[FlightStatus]) {
    let width = flights
        .iter()
        .map(|f| f.entry.label().len())
        .max()
        .unwrap_or(0);
    for f in flights {
        let mut detail = match &f.state {
            FlightState::NotRun => String::new(),
            FlightState::Queued { job } => format!("Slurm task {job}"),
            FlightState::Running { since, host } => format!("since {since} on {host}"),
            FlightState::Finished { seconds, .. } => format!("{seconds:.0} s"),
            FlightState::Failed { error } => error.clone(),
            FlightState::Lost { why } => why.clone(),
        };
        if let Some((done, all)) = f.shares_done() {
            let shares = format!("{done} of {all} shares done");
            detail = [shares, detail]
                .into_iter()
                .filter(|d| !d.is_empty())
                .collect::<Vec<_>>()
                .join("; ");
        }
        println!("{:width$}  {:8}  {detail}", f.entry.label(), f.state.word());
    }
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for f in flights {
        match counts.iter_mut().find(|(w, _)| *w == f.state.word()) {
            Some((_, n)) => *n += 1,
            None => counts.push((f.state.word(), 1)),
        }
    }
    let counts: Vec<String> = counts.iter().map(|(w, n)| format!("{n} {w}")).collect();
    println!("{}: {}", self::flights(flights.len()), counts.join(", "));
}

/// "1 flight", "3 flights".
fn flights(n: usize) -> String {
    format!("{n} flight{}", if n == 1 { "" } else { "s" })
}

/// "3 flights"; with shares, "4 tasks (1 flight)".
fn tasks(chosen: &[Task]) -> String {
    let mut of: Vec<usize> = chosen.iter().map(|t| t.flight).collect();
    of.dedup();
    match chosen.len() == of.len() {
        true => flights(of.len()),
        false => format!("{} tasks ({})", chosen.len(), flights(of.len())),
    }
}

/// `batch k8s`: the Indexed Job on standard output.
fn k8s(args: &K8sArgs) -> anyhow::Result<()> {
    let manifest = Manifest::load(&args.manifest)?;
    let job = fleet::kubernetes::IndexedJob {
        name: args.name.clone(),
        image: args.image.clone(),
        manifest: args.manifest.display().to_string(),
        fleet: args.out.display().to_string(),
        tasks: manifest.tasks().len(),
        parallelism: args.jobs,
        volume_claim: args.volume_claim.clone(),
        mount_path: args.mount_path.clone(),
        cpu: args.cpu.clone(),
        memory: args.memory.clone(),
        task_args: vec!["--quiet".into()],
    };
    print!("{}", job.yaml());
    Ok(())
}

/// `postflight fleet`: the fleet's tables and index page.
pub fn fleet_tables(fleet_dir: &Path, quiet: bool) -> anyhow::Result<()> {
    let runs = fleet::tables::runs(fleet_dir)?;
    if runs.is_empty() {
        anyhow::bail!(
            "{} holds no runs (STRUCTURE/RUN/ directories with batch.json or pipeline.json); give the --out of `postflight batch run`",
            fleet_dir.display()
        );
    }
    let out = fleet_dir.join(fleet::tables::files::DIR);
    let written = fleet::tables::write(&runs, &out, &fleet::index::page(&runs))?;
    if !quiet {
        println!(
            "fleet: {} flights ({} with coverage, {} defect candidates, {} element record rows) in {}; open {}",
            written.flights,
            written.coverage,
            written.defects,
            written.elements,
            out.display(),
            out.join(fleet::tables::files::INDEX).display()
        );
    }
    Ok(())
}

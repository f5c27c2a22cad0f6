//! `postflight run`: every stage in order on one flight, each reading the
//! previous stages' files in the run directory. Each completed stage is
//! logged with a fingerprint of its settings, its input files' contents and
//! the previous stage's fingerprint (`pipeline.json`); a stage whose
//! fingerprint still matches is skipped, so a re-run does only what changed
//! and an interrupted run resumes at the stage it was cut off in.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use postflight_core::outputs::detect::Shard;
use postflight_core::outputs::ingest::{IngestSummary, files as ingest_files};
use postflight_core::run_log::{InputFile, RUN_LOG, sha256};
use postflight_core::time::now_rfc3339;
use postflight_core::{PlanFile, RunDir, RunLog, Stage, StageRecord};

use crate::config::RunConfig;
use crate::stages;

/// What `postflight run` was given.
#[derive(Debug, Clone)]
pub struct RunInputs {
    /// The flight's recordings (one, or one per sortie or drone).
    pub flights: Vec<PathBuf>,
    pub map: Option<PathBuf>,
    pub plan: Option<PlanFile>,
    /// The structure to inspect: the plan's target voxels, or a file's.
    pub targets: coverage::Targets,
    /// The detector; `None`: the reference detector for simulated flights,
    /// written into the run directory.
    pub model: Option<PathBuf>,
    pub onnxruntime: Option<PathBuf>,
    pub config: RunConfig,
    pub out: PathBuf,
    /// Rerun from this stage on, whatever the log says.
    pub force: Option<Stage>,
    /// An earlier run of the structure whose record fills what this flight
    /// missed (`[record] not_inspected = "previous"`).
    pub previous: Option<PathBuf>,
}

/// Run every stage that is not up to date; the stages that ran.
pub fn run(inputs: &RunInputs, quiet: bool) -> anyhow::Result<Vec<Stage>> {
    let steps = run_steps(inputs, None, quiet)?;
    Ok(steps
        .into_iter()
        .filter_map(|s| match s {
            Step::Stage(stage) => Some(stage),
            Step::Share(_) => None,
        })
        .collect())
}

/// One of several processes sharing the flight's detect (`postflight batch`
/// with `shards`): the stages before detect, run by the first to get
/// there; this share of the detect; and, in the process finishing the
/// last share, the shares merged and every later stage. What it did.
pub fn run_share(inputs: &RunInputs, shard: Shard, quiet: bool) -> anyhow::Result<Vec<Step>> {
    run_steps(inputs, Some(shard), quiet)
}

/// What a run did: a stage, or a share of the flight's detect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    Stage(Stage),
    Share(Shard),
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Stage(stage) => f.write_str(stage.name()),
            Self::Share(shard) => write!(f, "detect share {shard}"),
        }
    }
}

fn run_steps(inputs: &RunInputs, share: Option<Shard>, quiet: bool) -> anyhow::Result<Vec<Step>> {
    let started = Instant::now();
    check_inputs(inputs)?;
    let dir = RunDir::create(&inputs.out)?;
    // The shares of a flight run side by side: one at a time reads and
    // changes the log (and runs the stages before and after detect).
    let mut lock = share.map(|_| RunLock::take(&dir)).transpose()?;
    write_reference_model(inputs)?;
    let mut log = open_log(&dir)?;
    // Input files already hashed, by this run or logged by earlier ones.
    let mut known: Vec<InputFile> = log
        .stages
        .iter()
        .flat_map(|r| r.inputs.values().cloned())
        .collect();
    let mut previous = String::new();
    let mut ran = Vec::new();
    for stage in Stage::ALL {
        let Some(stage_inputs) = stage_inputs(stage, inputs)? else {
            forget_without_targets(stage, &mut log, &dir, quiet)?;
            continue;
        };
        let (fingerprint, read) = fingerprint(stage, stage_inputs, &previous, &mut known)?;
        let forced = inputs.force.is_some_and(|f| stage >= f);
        if !forced && is_up_to_date(stage, &fingerprint, &log, &dir) {
            if !quiet {
                println!(
                    "{}: up to date, skipped (`--force {}` reruns it)",
                    stage.name(),
                    stage.name()
                );
            }
        } else if let (Stage::Detect, Some(shard)) = (stage, share) {
            let share = DetectShare {
                shard,
                fingerprint: &fingerprint,
                read,
            };
            if !share.run(inputs, &mut log, &dir, &mut lock, &mut ran, quiet)? {
                return Ok(ran);
            }
        } else {
            let seconds = run_logged(stage, inputs, &mut log, &dir, quiet)?;
            log.stages.push(StageRecord {
                stage: stage.name().to_string(),
                fingerprint: fingerprint.clone(),
                inputs: read,
                seconds,
                finished: now_rfc3339(),
            });
            log.write(&dir)?;
            ran.push(Step::Stage(stage));
        }
        previous = fingerprint;
    }
    if !quiet {
        println!("{}", processed(&dir, started.elapsed().as_secs_f64())?);
    }
    Ok(ran)
}

/// The run directory held by one process at a time: an advisory lock on
/// `pipeline.lock`, which the system lets go when the process ends, however
/// it ends.
struct RunLock {
    _held: std::fs::File,
}

impl RunLock {
    const FILE: &str = "pipeline.lock";

    /// Wait for the run directory, then hold it.
    fn take(dir: &RunDir) -> anyhow::Result<Self> {
        let path = dir.file(Self::FILE);
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .and_then(|f| f.lock().map(|()| f))
            .map_err(|e| {
                anyhow::anyhow!(
                    "cannot lock {} ({e}); the run directory must be on a file system with file locks",
                    path.display()
                )
            })?;
        Ok(Self { _held: file })
    }
}

/// One share of the flight's detect, to run under the detect stage's
/// `fingerprint`.
struct DetectShare<'a> {
    shard: Shard,
    fingerprint: &'a str,
    /// The detect stage's input files, for its record once merged.
    read: BTreeMap<String, InputFile>,
}

impl DetectShare<'_> {
    /// Run the share unless done under this fingerprint (the directory let
    /// go meanwhile, so the others run theirs), then, if every share is
    /// done, merge them as the detect stage. Whether the detect stage is
    /// complete.
    fn run(
        self,
        inputs: &RunInputs,
        log: &mut RunLog,
        dir: &RunDir,
        lock: &mut Option<RunLock>,
        ran: &mut Vec<Step>,
        quiet: bool,
    ) -> anyhow::Result<bool> {
        let Self {
            shard,
            fingerprint,
            read,
        } = self;
        let key = shard.to_string();
        let done = log
            .detect_shares
            .get(&key)
            .is_some_and(|f| f == fingerprint)
            && dir.file(&shard.summary()).is_file();
        if done {
            if !quiet {
                println!("detect share {shard}: done already, skipped");
            }
        } else {
            // The detections are about to change: the flight's detect of
            // other settings and the later stages' files go, and the
            // shares done under other settings.
            log.stages.retain(|r| r.stage != Stage::Detect.name());
            for later in Stage::ALL.iter().filter(|s| **s > Stage::Detect) {
                log.forget(later.name());
                dir.clear(*later)?;
            }
            log.detect_shares.retain(|_, f| f == fingerprint);
            log.write(dir)?;
            *lock = None;
            let mut options = detect_run(inputs);
            options.shard = Some(shard);
            stages::detect(&options, quiet).map_err(|e| {
                anyhow::anyhow!(
                    "detect share {shard} failed: {e:#}\nthe other shares and the stages before detect are intact in {}; fix the cause and rerun this share",
                    inputs.out.display()
                )
            })?;
            *lock = Some(RunLock::take(dir)?);
            *log = open_log(dir)?;
            log.detect_shares.insert(key, fingerprint.to_string());
            log.write(dir)?;
            ran.push(Step::Share(shard));
        }
        // The last share's process may have merged them already.
        if is_up_to_date(Stage::Detect, fingerprint, log, dir) {
            return Ok(true);
        }
        let left: Vec<String> = (1..=shard.count)
            .map(|index| Shard {
                index,
                count: shard.count,
            })
            .filter(|s| {
                log.detect_shares.get(&s.to_string()).map(String::as_str) != Some(fingerprint)
            })
            .map(|s| s.to_string())
            .collect();
        if !left.is_empty() {
            if !quiet {
                println!(
                    "detect: share {shard} done; {} to go (the last to finish merges them and runs the later stages)",
                    left.join(", ")
                );
            }
            return Ok(false);
        }
        let merged = stages::merge(&inputs.out, quiet)?;
        log.stages.retain(|r| r.stage != Stage::Detect.name());
        log.stages.push(StageRecord {
            stage: Stage::Detect.name().to_string(),
            fingerprint: fingerprint.to_string(),
            inputs: read,
            seconds: merged.seconds,
            finished: now_rfc3339(),
        });
        log.write(dir)?;
        ran.push(Step::Stage(Stage::Detect));
        Ok(true)
    }
}

/// How long the run took against how long the flight flew: "processed
/// 583 s of flight in 41 s, 7% of its flying time".
fn processed(dir: &RunDir, seconds: f64) -> anyhow::Result<String> {
    let ingest: IngestSummary = dir.read_json(ingest_files::SUMMARY)?;
    let flown = ingest.duration_s;
    let share = if flown > 0.0 {
        format!(", {:.0}% of its flying time", 100.0 * seconds / flown)
    } else {
        String::new()
    };
    Ok(format!(
        "processed {flown:.0} s of flight in {seconds:.0} s{share}"
    ))
}

/// Every input file given exists, and each recording is given once,
/// before anything is written.
fn check_inputs(inputs: &RunInputs) -> anyhow::Result<()> {
    ingest::stage::check_recordings(&inputs.flights)?;
    // A directory among the flights is a photo folder, listed already.
    let flights = inputs
        .flights
        .iter()
        .filter(|f| !f.is_dir())
        .map(|f| ("--flight", Some(f.as_path())));
    let given = flights.chain([
        ("--model", inputs.model.as_deref()),
        ("--map", inputs.map.as_deref()),
        ("--plan", inputs.plan.as_ref().map(|p| p.path.as_path())),
        ("the targets file", inputs.targets.file()),
    ]);
    for (what, path) in given {
        if let Some(p) = path.filter(|p| !p.is_file()) {
            anyhow::bail!("{what} {} is not a file; check the path", p.display());
        }
    }
    if let Some(map) = &inputs.map {
        postflight_core::map::PointCloud::check_placeable(map)?;
    }
    // A plan that cannot be read, or a path without targets, would fail
    // coverage only after ingest and detection.
    if let Some(plan) = &inputs.plan {
        let plan = plan.load()?;
        if inputs.targets == coverage::Targets::Plan {
            targets::plan_targets(Some(&plan))?;
        }
    }
    Ok(())
}

impl RunInputs {
    /// The plan as localise takes it: a plan.json names the structure's
    /// voxels; a waypoint path does not.
    fn structure_plan(&self) -> Option<&PlanFile> {
        self.plan.as_ref().filter(|p| !p.is_path())
    }

    /// The detector to run: the one given, else the reference detector in
    /// the run directory.
    fn model_path(&self) -> PathBuf {
        self.model
            .clone()
            .unwrap_or_else(|| self.out.join("reference-model.onnx"))
    }
}

/// Without a model given, write the reference detector where
/// [`RunInputs::model_path`] finds it.
fn write_reference_model(inputs: &RunInputs) -> anyhow::Result<()> {
    if inputs.model.is_some() {
        return Ok(());
    }
    tracing::warn!(
        "no --model: using the reference detector, made for simulated flights; give --model for a real flight"
    );
    crate::demo::write_reference_model(&inputs.model_path())
}

/// The run's log (empty for a new run), stamped with this version.
fn open_log(dir: &RunDir) -> anyhow::Result<RunLog> {
    let mut log = RunLog::read(dir).map_err(|e| {
        anyhow::anyhow!(
            "{e}; delete {} to start the run afresh",
            dir.file(RUN_LOG).display()
        )
    })?;
    log.postflight_version = env!("CARGO_PKG_VERSION").to_string();
    Ok(log)
}

/// Without a plan or targets there is nothing to judge coverage against:
/// leave no stale results from an earlier run with them.
fn forget_without_targets(
    stage: Stage,
    log: &mut RunLog,
    dir: &RunDir,
    quiet: bool,
) -> anyhow::Result<()> {
    log.forget(stage.name());
    dir.clear(stage)?;
    if !quiet {
        println!(
            "{}: skipped (needs --plan, or --target-boxes, --target-cloud or --target-map)",
            stage.name()
        );
    }
    Ok(())
}

/// The stage's fingerprint (its settings, its input files' contents and the
/// previous stage's fingerprint) and the input files it read, by role.
fn fingerprint(
    stage: Stage,
    StageInputs { settings, files }: StageInputs,
    previous: &str,
    known: &mut Vec<InputFile>,
) -> anyhow::Result<(String, BTreeMap<String, InputFile>)> {
    let mut read = BTreeMap::new();
    for (role, path) in files {
        let file = InputFile::describe(&path, known)?;
        known.push(file.clone());
        read.insert(role.to_string(), file);
    }
    // Contents, not places: a moved input does not rerun a stage.
    let contents: BTreeMap<&String, &String> = read.iter().map(|(r, f)| (r, &f.sha256)).collect();
    let fingerprint = sha256(
        serde_json::json!({
            "stage": stage.name(),
            "postflight": env!("CARGO_PKG_VERSION"),
            "settings": settings,
            "inputs": contents,
            "previous": previous,
        })
        .to_string()
        .as_bytes(),
    );
    Ok((fingerprint, read))
}

/// The log holds this stage with the same fingerprint and its summary is
/// still there.
fn is_up_to_date(stage: Stage, fingerprint: &str, log: &RunLog, dir: &RunDir) -> bool {
    log.record(stage.name())
        .is_some_and(|r| r.fingerprint == fingerprint)
        && dir.file(stage.summary_file()).is_file()
}

/// Run the stage, logged as running while it does; its duration in seconds.
fn run_logged(
    stage: Stage,
    inputs: &RunInputs,
    log: &mut RunLog,
    dir: &RunDir,
    quiet: bool,
) -> anyhow::Result<f64> {
    // From here on this stage and every later one must run again: their
    // files go, so a failure here leaves none that claims the old results.
    for later in Stage::ALL.iter().filter(|s| **s >= stage) {
        log.forget(later.name());
        dir.clear(*later)?;
    }
    log.running = Some(stage.name().to_string());
    log.write(dir)?;
    let start = Instant::now();
    run_stage(stage, inputs, quiet).map_err(|e| {
        // Nothing of a failed stage stays to be taken for its results.
        let _ = dir.clear(stage);
        anyhow::anyhow!(
            "stage {} failed: {e:#}\nthe results of the stages before it are intact in {}; fix the cause and rerun the same command to resume from {}",
            stage.name(),
            inputs.out.display(),
            stage.name()
        )
    })?;
    log.running = None;
    Ok(start.elapsed().as_secs_f64())
}

/// The detect stage's options, for the whole flight.
fn detect_run(i: &RunInputs) -> stages::DetectRun {
    i.config.detect_options(
        &i.out,
        &i.model_path(),
        i.onnxruntime.as_deref(),
        i.map.as_deref(),
        i.structure_plan(),
    )
}

/// What a stage's fingerprint covers besides the previous stage.
struct StageInputs {
    /// The options it runs with, without their paths.
    settings: serde_json::Value,
    /// Its input files from outside the run directory, by role.
    files: Vec<(String, PathBuf)>,
}

/// The options a stage runs with.
enum StageOptions {
    Ingest(ingest::IngestOptions),
    Detect(stages::DetectRun),
    Localise(localise::LocaliseOptions),
    Coverage(coverage::CoverageOptions),
    Replan(replan::ReplanOptions),
    Record(record::RecordOptions),
    Report(reports::ReportOptions),
}

impl StageOptions {
    /// The options `postflight run` gives the stage.
    fn new(stage: Stage, i: &RunInputs) -> anyhow::Result<Self> {
        let c = &i.config;
        let (run, map) = (i.out.as_path(), i.map.as_deref());
        Ok(match stage {
            Stage::Ingest => Self::Ingest(c.ingest_options(&i.flights, run)),
            Stage::Detect => Self::Detect(detect_run(i)),
            Stage::Localise => {
                Self::Localise(c.localise_options(run, map, i.structure_plan(), i.targets.clone()))
            }
            Stage::Coverage => {
                Self::Coverage(c.coverage_options(run, map, i.plan.as_ref(), i.targets.clone()))
            }
            Stage::Replan => Self::Replan(c.replan_options(run, map)),
            Stage::Record => Self::Record(c.record_options(run, i.previous.as_deref())?),
            Stage::Report => Self::Report(reports::ReportOptions {
                run: run.to_owned(),
            }),
        })
    }

    /// The options as the fingerprint hashes them: every setting, no path.
    fn settings(&self) -> serde_json::Value {
        let value = match self {
            Self::Ingest(o) => serde_json::to_value(o),
            Self::Detect(o) => serde_json::to_value(o),
            Self::Localise(o) => serde_json::to_value(o),
            Self::Coverage(o) => serde_json::to_value(o),
            Self::Replan(o) => serde_json::to_value(o),
            Self::Record(o) => serde_json::to_value(o),
            Self::Report(_) => Ok(serde_json::Value::Null),
        };
        value.expect("options serialise to JSON")
    }

    fn run(&self, quiet: bool) -> anyhow::Result<()> {
        match self {
            Self::Ingest(o) => stages::ingest(o, quiet),
            Self::Detect(o) => stages::detect(o, quiet),
            Self::Localise(o) => stages::localise(o, quiet),
            Self::Coverage(o) => stages::coverage(o, quiet),
            Self::Replan(o) => stages::replan(o, quiet),
            Self::Record(o) => stages::record(o, quiet),
            Self::Report(o) => stages::report(o, quiet),
        }
    }
}

/// A stage's inputs; `None` when it cannot run with what the run was given.
fn stage_inputs(stage: Stage, i: &RunInputs) -> anyhow::Result<Option<StageInputs>> {
    if matches!(stage, Stage::Coverage | Stage::Replan | Stage::Record) && !has_targets(i) {
        return Ok(None);
    }
    let settings = StageOptions::new(stage, i)?.settings();
    let c = &i.config;
    let map = i.map.iter().map(|m| ("map", m.clone()));
    let files: Vec<(&str, PathBuf)> = match stage {
        Stage::Ingest => {
            let calibration = c.ingest.camera_info_file.iter();
            let calibration = calibration.map(|f| ("camera_info", f.clone()));
            return Ok(Some(StageInputs {
                settings,
                files: flight_roles(&i.flights)
                    .chain(calibration.map(|(r, f)| (r.to_string(), f)))
                    .collect(),
            }));
        }
        // The map and plan choose the tiles to run.
        Stage::Detect => std::iter::once(("model", i.model_path()))
            .chain(
                c.detect
                    .embeddings
                    .iter()
                    .map(|e| ("embeddings", e.clone())),
            )
            .chain(
                c.detect
                    .area_model
                    .iter()
                    .map(|m| ("area_model", m.clone())),
            )
            .chain(map)
            .chain(i.structure_plan().map(|p| ("plan", p.path.clone())))
            .collect(),
        Stage::Localise => map
            .chain(i.structure_plan().map(|p| ("plan", p.path.clone())))
            .chain(i.targets.file().map(|p| ("targets", p.to_path_buf())))
            .collect(),
        Stage::Coverage => i
            .plan
            .iter()
            .map(|p| ("plan", p.path.clone()))
            .chain(i.targets.file().map(|p| ("targets", p.to_path_buf())))
            .chain(map)
            .collect(),
        Stage::Replan => map.collect(),
        // The decisions are in its settings; the earlier record is a file.
        Stage::Record => i
            .previous
            .iter()
            .map(|p| {
                (
                    "previous record",
                    p.join(postflight_core::outputs::record::files::ELEMENTS),
                )
            })
            .collect(),
        Stage::Report => Vec::new(),
    };
    let files = files.into_iter().map(|(r, f)| (r.to_string(), f)).collect();
    Ok(Some(StageInputs { settings, files }))
}

/// The recordings by role: `flight`, then `flight 2`, `flight 3`... in the
/// order given (the order is the recordings' numbering in the run).
fn flight_roles(flights: &[PathBuf]) -> impl Iterator<Item = (String, PathBuf)> + '_ {
    (1..).zip(flights).map(|(n, f)| match n {
        1 => ("flight".to_string(), f.clone()),
        n => (format!("flight {n}"), f.clone()),
    })
}

/// Coverage and replanning need a structure to inspect: a plan's target
/// voxels or a targets file.
fn has_targets(i: &RunInputs) -> bool {
    i.plan.is_some() || i.targets != coverage::Targets::Plan
}

fn run_stage(stage: Stage, i: &RunInputs, quiet: bool) -> anyhow::Result<()> {
    StageOptions::new(stage, i)?.run(quiet)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::FULL;

    /// What each stage's fingerprint hashes of the options `config` gives it.
    fn fingerprinted(config: RunConfig) -> Vec<(Stage, serde_json::Value)> {
        let inputs = RunInputs {
            flights: vec!["flight.mcap".into()],
            map: None,
            plan: Some(PlanFile::new("plan.json")),
            targets: coverage::Targets::Plan,
            model: None,
            onnxruntime: None,
            config,
            out: "run".into(),
            force: None,
            previous: None,
        };
        Stage::ALL
            .iter()
            .map(|s| (*s, StageOptions::new(*s, &inputs).unwrap().settings()))
            .collect()
    }

    #[test]
    fn every_setting_reruns_the_stages_that_use_it_and_no_other() {
        let full = RunConfig::parse(FULL).unwrap();
        let values = serde_json::to_value(&full).unwrap();
        let defaults = fingerprinted(RunConfig::default());
        for (table, key) in full.keys_set() {
            let one = serde_json::json!({ &table: { &key: values[&table][&key] } });
            let config: RunConfig = serde_json::from_value(one).unwrap();
            let changed: Vec<Stage> = fingerprinted(config)
                .into_iter()
                .zip(&defaults)
                .filter(|((_, set), (_, default))| set != default)
                .map(|((stage, _), _)| stage)
                .collect();
            let users = match table.as_str() {
                "ingest" => vec![Stage::Ingest],
                "detect" => vec![Stage::Detect],
                "localise" => vec![Stage::Localise],
                // Detect chooses the best views of each patch by the View
                // model, and localise judges each view by it too.
                "view" => vec![Stage::Detect, Stage::Localise, Stage::Coverage],
                // Localise puts each candidate in a condition state, and
                // the record each element's cracks.
                "condition" => vec![Stage::Localise, Stage::Record],
                "record" => vec![Stage::Record],
                "coverage" => vec![Stage::Coverage],
                "replan" => vec![Stage::Replan],
                // `postflight compare` reads it; no stage of a run does.
                "compare" => vec![],
                other => panic!("[{other}] is no stage's"),
            };
            assert_eq!(changed, users, "[{table}] {key}");
        }
    }
}

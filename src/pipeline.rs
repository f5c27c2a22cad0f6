//! `postflight run`: every stage in order on one flight, each reading the
//! previous stages' files in the run directory. Each completed stage is
//! logged with a fingerprint of its settings, its input files' contents and
//! the previous stage's fingerprint (`pipeline.json`); a stage whose
//! fingerprint still matches is skipped, so a re-run does only what changed
//! and an interrupted run resumes at the stage it was cut off in.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use ingest::run_log::{InputFile, now_rfc3339, sha256, sha256_file};
use ingest::{RunDir, RunLog, StageRecord};

use crate::config::RunConfig;
use crate::stages;

/// The stages of a run, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum Stage {
    Ingest,
    Detect,
    Localise,
    Coverage,
    Replan,
    Report,
}

impl Stage {
    pub const ALL: [Self; 6] = [
        Self::Ingest,
        Self::Detect,
        Self::Localise,
        Self::Coverage,
        Self::Replan,
        Self::Report,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::Ingest => "ingest",
            Self::Detect => "detect",
            Self::Localise => "localise",
            Self::Coverage => "coverage",
            Self::Replan => "replan",
            Self::Report => "report",
        }
    }

    /// The file a stage writes last: it exists exactly when the stage completed.
    fn summary_file(self) -> &'static str {
        match self {
            Self::Ingest => ingest::run_dir::files::INGEST,
            Self::Detect => detect::stage::files::SUMMARY,
            Self::Localise => localise::stage::files::SUMMARY,
            Self::Coverage => coverage::stage::files::SUMMARY,
            Self::Replan => coverage::replan::files::PLAN,
            Self::Report => reports::stage::files::SUMMARY,
        }
    }
}

/// What `postflight run` was given.
#[derive(Debug, Clone)]
pub struct RunInputs {
    pub flight: PathBuf,
    pub map: Option<PathBuf>,
    pub plan: Option<PathBuf>,
    pub model: PathBuf,
    pub onnxruntime: Option<PathBuf>,
    pub config: RunConfig,
    pub out: PathBuf,
    /// Rerun from this stage on, whatever the log says.
    pub force: Option<Stage>,
}

/// Run every stage that is not up to date.
pub fn run(inputs: &RunInputs, quiet: bool) -> anyhow::Result<()> {
    for (what, path) in [
        ("--flight", Some(&inputs.flight)),
        ("--model", Some(&inputs.model)),
    ]
    .into_iter()
    .chain([
        ("--map", inputs.map.as_ref()),
        ("--plan", inputs.plan.as_ref()),
    ]) {
        if let Some(p) = path.filter(|p| !p.is_file()) {
            anyhow::bail!("{what} {} is not a file; check the path", p.display());
        }
    }
    let dir = RunDir::create(&inputs.out)?;
    let mut log = RunLog::read(&dir).map_err(|e| {
        anyhow::anyhow!(
            "{e}; delete {} to start the run afresh",
            dir.file(ingest::run_log::RUN_LOG).display()
        )
    })?;
    log.postflight_version = env!("CARGO_PKG_VERSION").to_string();
    let mut hashes = FileHashes::default();
    let mut previous = String::new();
    for stage in Stage::ALL {
        let (settings, files) = stage_inputs(stage, inputs);
        let Some(settings) = settings else {
            // Without a plan there is nothing to judge coverage against:
            // leave no stale results from an earlier run with one.
            log.forget(stage.name());
            dir.remove(stage.summary_file())?;
            if !quiet {
                println!("{}: skipped (needs --plan)", stage.name());
            }
            continue;
        };
        let mut input_hashes = BTreeMap::new();
        for (label, path) in &files {
            input_hashes.insert(label.to_string(), hashes.get(path)?);
        }
        let fingerprint = sha256(
            serde_json::json!({
                "stage": stage.name(),
                "postflight": env!("CARGO_PKG_VERSION"),
                "settings": settings,
                "inputs": input_hashes,
                "previous": previous,
            })
            .to_string()
            .as_bytes(),
        );
        let forced = inputs.force.is_some_and(|f| stage >= f);
        let done = log
            .record(stage.name())
            .is_some_and(|r| r.fingerprint == fingerprint)
            && dir.file(stage.summary_file()).is_file();
        if done && !forced {
            if !quiet {
                println!(
                    "{}: up to date, skipped (`--force {}` reruns it)",
                    stage.name(),
                    stage.name()
                );
            }
            previous = fingerprint;
            continue;
        }
        // From here on this stage and every later one must run again.
        for later in Stage::ALL.iter().filter(|s| **s >= stage) {
            log.forget(later.name());
        }
        log.running = Some(stage.name().to_string());
        log.write(&dir)?;
        let start = Instant::now();
        run_stage(stage, inputs, quiet).map_err(|e| {
            anyhow::anyhow!(
                "stage {} failed: {e:#}\nthe results of the stages before it are intact in {}; fix the cause and rerun the same command to resume from {}",
                stage.name(),
                inputs.out.display(),
                stage.name()
            )
        })?;
        log.running = None;
        log.stages.push(StageRecord {
            stage: stage.name().to_string(),
            fingerprint: fingerprint.clone(),
            inputs: files
                .iter()
                .map(|(label, path)| {
                    let file = InputFile {
                        path: std::path::absolute(path).unwrap_or_else(|_| path.clone()),
                        sha256: input_hashes[*label].clone(),
                    };
                    (label.to_string(), file)
                })
                .collect(),
            seconds: start.elapsed().as_secs_f64(),
            finished: now_rfc3339(),
        });
        log.write(&dir)?;
        previous = fingerprint;
    }
    Ok(())
}

/// A stage's settings (as they enter its fingerprint; `None`: the stage
/// cannot run with these inputs) and its input files from outside the run.
fn stage_inputs(
    stage: Stage,
    i: &RunInputs,
) -> (Option<serde_json::Value>, Vec<(&'static str, PathBuf)>) {
    let c = &i.config;
    let mut files: Vec<(&'static str, PathBuf)> = Vec::new();
    let settings = match stage {
        Stage::Ingest => {
            files.push(("flight", i.flight.clone()));
            serde_json::to_value(&c.ingest)
        }
        Stage::Detect => {
            files.push(("model", i.model.clone()));
            if let Some(e) = &c.detect.embeddings {
                files.push(("embeddings", e.clone()));
            }
            serde_json::to_value(&c.detect)
        }
        Stage::Localise => {
            files.extend(i.map.iter().map(|m| ("map", m.clone())));
            files.extend(i.plan.iter().map(|p| ("plan", p.clone())));
            serde_json::to_value(&c.localise)
        }
        Stage::Coverage => {
            let Some(plan) = &i.plan else {
                return (None, files);
            };
            files.push(("plan", plan.clone()));
            files.extend(i.map.iter().map(|m| ("map", m.clone())));
            serde_json::to_value((&c.view, &c.coverage))
        }
        Stage::Replan => {
            if i.plan.is_none() {
                return (None, files);
            }
            files.extend(i.map.iter().map(|m| ("map", m.clone())));
            serde_json::to_value(&c.replan)
        }
        Stage::Report => Ok(serde_json::Value::Null),
    };
    (Some(settings.expect("settings serialise to JSON")), files)
}

fn run_stage(stage: Stage, i: &RunInputs, quiet: bool) -> anyhow::Result<()> {
    let c = &i.config;
    let (run, map, plan) = (i.out.as_path(), i.map.as_deref(), i.plan.as_deref());
    match stage {
        Stage::Ingest => stages::ingest(&c.ingest_options(&i.flight, run), quiet).map(drop),
        Stage::Detect => stages::detect(
            &c.detect_options(run, &i.model, i.onnxruntime.as_deref()),
            quiet,
        )
        .map(drop),
        Stage::Localise => stages::localise(&c.localise_options(run, map, plan), quiet).map(drop),
        Stage::Coverage => {
            let plan = plan.expect("coverage runs with a plan");
            stages::coverage(&c.coverage_options(run, map, plan), quiet).map(drop)
        }
        Stage::Replan => stages::replan(&c.replan_options(run, map)?, quiet).map(drop),
        Stage::Report => stages::report(
            &reports::ReportOptions {
                run: run.to_owned(),
            },
            quiet,
        )
        .map(drop),
    }
}

/// Content hashes of input files, each file read once per run.
#[derive(Default)]
struct FileHashes(BTreeMap<PathBuf, String>);

impl FileHashes {
    fn get(&mut self, path: &Path) -> anyhow::Result<String> {
        if let Some(h) = self.0.get(path) {
            return Ok(h.clone());
        }
        let h = sha256_file(path)?;
        self.0.insert(path.to_owned(), h.clone());
        Ok(h)
    }
}

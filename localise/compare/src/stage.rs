//! `postflight compare --before RUN_A --after RUN_B`: register the maps,
//! classify every candidate's change, write `changes.json` and
//! `changes.parquet` into the later run.

use std::path::{Path, PathBuf};
use std::time::Instant;

use postflight_core::map::SlamMap;
use postflight_core::outputs::changes::{
    ChangeKind, ChangesSummary, RegistrationRecord, write_changes,
};
use postflight_core::outputs::coverage::{CoverageSummary, files as coverage_files, read_coverage};
use postflight_core::outputs::localise::read_defects;
use postflight_core::serde_pose::PoseJson;
use postflight_core::{Flight, RunDir, Stage};

use crate::changes::{Inspected, MatchOptions, changes};
use crate::error::CompareError;
use crate::register::{RegisterOptions, Registration, register};

/// What to compare.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// The earlier run and the later one (which gets the results).
    pub before: PathBuf,
    pub after: PathBuf,
    pub register: RegisterOptions,
    pub matching: MatchOptions,
}

impl CompareOptions {
    pub fn new(before: PathBuf, after: PathBuf) -> Self {
        Self {
            before,
            after,
            register: RegisterOptions::default(),
            matching: MatchOptions::default(),
        }
    }
}

/// Compare the runs; the summary written.
pub fn compare(options: &CompareOptions) -> Result<ChangesSummary, CompareError> {
    let started = Instant::now();
    let before = RunDir::open(&options.before, Stage::Localise)?;
    let after = RunDir::open(&options.after, Stage::Coverage)?;
    after.require(Stage::Localise)?;
    let registration = register_maps(&before, &after, options)?;
    let inspected_after = inspected(&after)?.expect("coverage completed");
    let inspected_before = inspected(&before)?;
    let changes = changes(
        &read_defects(&before)?,
        &read_defects(&after)?,
        &registration.transform,
        &inspected_after,
        inspected_before.as_ref(),
        &options.matching,
    );
    let counts = ChangeKind::ALL
        .iter()
        .map(|k| {
            (
                k.as_str().to_string(),
                changes.iter().filter(|c| c.change == *k).count(),
            )
        })
        .collect();
    let summary = ChangesSummary {
        before: absolute(&options.before),
        before_flight_start: Flight::load(before.path())?.summary.start_time,
        after: absolute(&options.after),
        registration: registration_record(&registration),
        counts,
        changes,
        seconds: started.elapsed().as_secs_f64(),
    };
    after.remove(postflight_core::outputs::changes::files::SUMMARY)?;
    write_changes(&after, &summary)?;
    Ok(summary)
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_owned())
}

/// The earlier run's map registered onto the later one's.
fn register_maps(
    before: &RunDir,
    after: &RunDir,
    options: &CompareOptions,
) -> Result<Registration, CompareError> {
    let map = |run: &RunDir| -> Result<SlamMap, CompareError> {
        let given = coverage_map(run)?;
        let flight = Flight::load(run.path())?;
        Ok(ingest::reopen::load_map(&flight, given.as_deref(), None)?.0)
    };
    register(&map(before)?, &map(after)?, &options.register).map_err(|cause| {
        CompareError::Register {
            before: options.before.clone(),
            after: options.after.clone(),
            cause,
        }
    })
}

/// The map file the run's coverage judged against (`None`: the recorded one).
fn coverage_map(run: &RunDir) -> Result<Option<PathBuf>, CompareError> {
    Ok(run
        .summary::<CoverageSummary>(Stage::Coverage)?
        .and_then(|s| s.map))
}

/// A run's coverage, when it has one.
fn inspected(run: &RunDir) -> Result<Option<Inspected>, CompareError> {
    let Some(summary) = run.summary::<CoverageSummary>(Stage::Coverage)? else {
        return Ok(None);
    };
    let records = read_coverage(run, coverage_files::TABLE)?;
    Ok(Some(Inspected::new(&summary, &records)))
}

fn registration_record(r: &Registration) -> RegistrationRecord {
    let (roll, pitch, yaw) = r.transform.rotation.euler_angles();
    RegistrationRecord {
        transform: PoseJson::from(&r.transform),
        yaw_deg: yaw.to_degrees(),
        pitch_deg: pitch.to_degrees(),
        roll_deg: roll.to_degrees(),
        rms_m: r.rms_m,
        overlap_pct: 100.0 * r.overlap,
        iterations: r.iterations,
    }
}

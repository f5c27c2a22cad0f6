//! `postflight compare --before RUN_A --after RUN_B`: register the maps,
//! classify every candidate's change, write `changes.json` and
//! `changes.parquet` into the later run.

use std::path::{Path, PathBuf};
use std::time::Instant;

use postflight_core::map::SlamMap;
use postflight_core::outputs::changes::{
    ChangeKind, ChangesSummary, ElementChange, RegistrationRecord, write_changes,
};
use postflight_core::outputs::coverage::{CoverageSummary, files as coverage_files, read_coverage};
use postflight_core::outputs::localise::{LocaliseSummary, read_defects};
use postflight_core::outputs::record::{ElementRecord, RecordSummary, files as record_files};
use postflight_core::serde_pose::PoseJson;
use postflight_core::{Flight, RunDir, Stage, ViewModel};

use crate::changes::{Earlier, Inspected, MatchOptions, changes};
use crate::error::CompareError;
use crate::settings::CompareConfig;
use crate::sight::FramesInView;
use postflight_core::map::register::{RegisterOptions, Registration, register};

/// What to compare.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// The earlier run and the later one (which gets the results).
    pub before: PathBuf,
    pub after: PathBuf,
    pub register: RegisterOptions,
    pub settings: CompareConfig,
}

impl CompareOptions {
    pub fn new(before: PathBuf, after: PathBuf) -> Self {
        Self {
            before,
            after,
            register: RegisterOptions::default(),
            settings: CompareConfig::default(),
        }
    }
}

/// Compare the runs; the summary written.
pub fn compare(options: &CompareOptions) -> Result<ChangesSummary, CompareError> {
    let started = Instant::now();
    options.settings.check()?;
    let before = Side::read(&options.before, Stage::Localise)?;
    let after = Side::read(&options.after, Stage::Coverage)?;
    let before_map = before.map()?;
    let registration =
        register(&before_map, &after.map()?, &options.register).map_err(|cause| {
            CompareError::Register {
                before: options.before.clone(),
                after: options.after.clone(),
                cause,
            }
        })?;
    let inspected_after = after.inspected.as_ref().expect("coverage completed");
    let matching = MatchOptions::with_link_distance(
        options
            .settings
            .link_distance_m
            .unwrap_or(before.link_distance_m.max(after.link_distance_m)),
    );
    let frames_before = before
        .view
        .as_ref()
        .map(|view| FramesInView::new(&before.flight, before_map, view))
        .transpose()?;
    let changes = changes(
        &read_defects(&before.flight.run)?,
        &read_defects(&after.flight.run)?,
        &registration.transform,
        inspected_after,
        &Earlier {
            inspected: before.inspected.as_ref(),
            frames: frames_before.as_ref(),
        },
        &matching,
    );
    let counts = ChangeKind::ALL
        .iter()
        .map(|&k| (k, changes.iter().filter(|c| c.change == k).count()))
        .collect();
    let summary = ChangesSummary {
        before: absolute(&options.before),
        before_flight_start: before.flight.summary.start_time.clone(),
        after: absolute(&options.after),
        registration: registration_record(&registration),
        counts,
        changes,
        elements: element_changes(&before.flight.run, &after.flight.run)?,
        seconds: started.elapsed().as_secs_f64(),
    };
    let run = &after.flight.run;
    run.remove(postflight_core::outputs::changes::files::SUMMARY)?;
    write_changes(run, &summary)?;
    Ok(summary)
}

/// The two runs' element records paired, where both have one.
fn element_changes(before: &RunDir, after: &RunDir) -> Result<Vec<ElementChange>, CompareError> {
    let rows = |run: &RunDir| -> Result<Option<Vec<ElementRecord>>, CompareError> {
        match run.summary::<RecordSummary>(Stage::Record)? {
            Some(_) => Ok(Some(run.read_rows(record_files::ELEMENTS)?)),
            None => Ok(None),
        }
    };
    Ok(match (rows(before)?, rows(after)?) {
        (Some(b), Some(a)) => ElementChange::pair(&b, &a),
        _ => Vec::new(),
    })
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_owned())
}

/// One of the two runs, read once: its flight, and its coverage with the
/// map file it judged against.
struct Side {
    flight: Flight,
    /// The map file coverage used (`None`: the flight's recorded map).
    map: Option<PathBuf>,
    inspected: Option<Inspected>,
    /// The View model its coverage judged by.
    view: Option<ViewModel>,
    /// How far apart its localise fused views of one crack, metres.
    link_distance_m: f64,
}

impl Side {
    /// The run at `path`, which must have completed `stage` and localise.
    fn read(path: &Path, stage: Stage) -> Result<Self, CompareError> {
        let run = RunDir::open(path, stage)?;
        let coverage = run.summary::<CoverageSummary>(Stage::Coverage)?;
        let inspected = match &coverage {
            Some(summary) => {
                let records = read_coverage(&run, coverage_files::TABLE)?;
                Some(Inspected::new(summary, &records))
            }
            None => None,
        };
        run.require(Stage::Localise)?;
        let localise: LocaliseSummary = run.read_json(Stage::Localise.summary_file())?;
        Ok(Self {
            flight: Flight::load(path)?,
            view: coverage.as_ref().map(|c| c.view),
            map: coverage.and_then(|c| c.map),
            inspected,
            link_distance_m: localise.link_distance_m,
        })
    }

    fn map(&self) -> Result<SlamMap, CompareError> {
        Ok(ingest::reopen::load_map(&self.flight, self.map.as_deref(), None)?.0)
    }
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

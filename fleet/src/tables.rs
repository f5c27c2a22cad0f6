//! The fleet's tables, `FLEET_DIR/fleet/`: every flight's defect
//! candidates (`defects.parquet`, one row per candidate, the columns of
//! each run's own table), element record (`elements.parquet`, one row per
//! element and per defect under it, as each run's own), coverage
//! (`coverage.parquet`) and run (`flights.parquet`), one row per flight. Each is a directory of Hive
//! partitions by structure (`defects.parquet/structure=bridge-a/part-0.parquet`),
//! so DuckDB and polars read the whole fleet with one glob:
//!
//! ```sql
//! SELECT structure, date, count(*) FROM
//!   read_parquet('fleet/defects.parquet/**/*.parquet', hive_partitioning=true)
//! GROUP BY ALL;
//! ```
//!
//! Every row names its flight by `date` (`YYYY-MM-DD`, empty for a run not
//! made by `postflight batch`), `flight` (the recording) and `run` (its run
//! directory within the fleet directory).

use std::path::{Path, PathBuf};

use polars::prelude::*;
use postflight_core::outputs::coverage::{CoverageFigures, CoverageSummary};
use postflight_core::outputs::localise::{DefectRecord, files as localise_files};
use postflight_core::outputs::record::{ElementRecord, files as record_files};
use postflight_core::outputs::report::RunSummary;
use postflight_core::run_log::RUN_LOG;
use postflight_core::table::Row;
use postflight_core::{RunDir, Stage};

use crate::error::Error;
use crate::slurm::SLURM_DIR;
use crate::task::{TASK_RECORD, TaskRecord};

/// The fleet's outputs, in the fleet directory.
pub mod files {
    /// The directory holding the tables and the index page.
    pub const DIR: &str = "fleet";
    pub const DEFECTS: &str = "defects.parquet";
    pub const ELEMENTS: &str = "elements.parquet";
    pub const COVERAGE: &str = "coverage.parquet";
    pub const FLIGHTS: &str = "flights.parquet";
    pub const INDEX: &str = "index.html";
    /// Each partition's one file.
    pub const PART: &str = "part-0.parquet";
}

/// One run directory of the fleet and what it holds.
#[derive(Debug, Clone)]
pub struct FleetRun {
    pub structure: String,
    /// Its directory within the fleet directory: `<structure>/<date or name>`.
    pub run: String,
    pub dir: PathBuf,
    /// How the batch task on it went; `None` for a run made by hand.
    pub record: Option<TaskRecord>,
    /// `summary.json`, once the report stage has run.
    pub summary: Option<RunSummary>,
    pub coverage: Option<CoverageSummary>,
}

impl FleetRun {
    pub fn date(&self) -> Option<&str> {
        self.record.as_ref().and_then(|r| r.date.as_deref())
    }

    /// The flight recording, as the task or the report names it (several
    /// recordings separated by `;`).
    pub fn flight(&self) -> Option<String> {
        let record = self.record.as_ref().map(|r| r.flight.display().to_string());
        let summary = self.summary.as_ref().map(|s| {
            let paths: Vec<String> = s
                .recordings
                .iter()
                .map(|p| p.display().to_string())
                .collect();
            paths.join(";")
        });
        record.or(summary)
    }

    /// How it went: as its task recorded, or for a run made by hand by
    /// whether its report exists.
    pub fn state(&self) -> RunState {
        use crate::task::TaskState;
        match (self.record.as_ref().map(|r| r.state), &self.summary) {
            (Some(TaskState::Finished), _) => RunState::Finished,
            (Some(TaskState::Failed), _) => RunState::Failed,
            (Some(TaskState::Running), _) => RunState::Running,
            (None, Some(_)) => RunState::Complete,
            (None, None) => RunState::Incomplete,
        }
    }
}

postflight_core::kind! {
    /// How a run of the fleet stands.
    pub enum RunState("run state") {
        /// Its task finished.
        Finished = "finished",
        /// Its task failed (the error is on record).
        Failed = "failed",
        /// Its task is at work, or was when it last wrote.
        Running = "running",
        /// Made by hand (no task), and its report exists.
        Complete = "complete",
        /// Made by hand, and without a report.
        Incomplete = "incomplete",
    }
}

/// Every run directory of the fleet (`<structure>/<run>/` holding a task
/// record or a run log), by structure, then date and name.
pub fn runs(fleet: &Path) -> Result<Vec<FleetRun>, Error> {
    let mut runs = Vec::new();
    for structure in subdirectories(fleet)? {
        let name = file_name(&structure);
        if name == files::DIR || name == SLURM_DIR {
            continue;
        }
        for dir in subdirectories(&structure)? {
            // A flight in shares has a run log from its first task on.
            let is_run = dir.join(TASK_RECORD).is_file() || dir.join(RUN_LOG).is_file();
            if is_run {
                runs.push(read_run(&name, dir)?);
            }
        }
    }
    runs.sort_by(|a, b| (&a.structure, a.date(), &a.run).cmp(&(&b.structure, b.date(), &b.run)));
    Ok(runs)
}

fn read_run(structure: &str, dir: PathBuf) -> Result<FleetRun, Error> {
    let run_dir = RunDir::create(&dir)?;
    Ok(FleetRun {
        structure: structure.to_string(),
        run: format!("{structure}/{}", file_name(&dir)),
        record: TaskRecord::of_run(&dir)?,
        summary: run_dir.summary(Stage::Report)?,
        coverage: run_dir.summary(Stage::Coverage)?,
        dir,
    })
}

/// The directories in `dir` not starting with a dot, sorted.
fn subdirectories(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let entries = std::fs::read_dir(dir).map_err(|cause| postflight_core::Error::Open {
        path: dir.to_owned(),
        cause,
    })?;
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_dir() && !file_name(p).starts_with('.'))
        .collect();
    dirs.sort();
    Ok(dirs)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// What `write` wrote: rows per table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Written {
    pub flights: usize,
    pub coverage: usize,
    pub defects: usize,
    pub elements: usize,
}

/// Write the fleet's tables for `runs` into `out` (`FLEET_DIR/fleet`),
/// replacing what was there once all are written. An `out` holding anything
/// this function does not write is refused, never deleted.
pub fn write(runs: &[FleetRun], out: &Path, index_html: &str) -> Result<Written, Error> {
    check_replaceable(out)?;
    let parent = out.parent().unwrap_or(Path::new("."));
    let staging = tempfile::Builder::new()
        .prefix(&format!(".{}.", file_name(out)))
        .tempdir_in(parent)
        .map_err(|cause| postflight_core::Error::Write {
            path: parent.to_owned(),
            cause,
        })?;
    let dir = RunDir::create(staging.path())?;
    let built =
        |name: &str, table: PolarsResult<DataFrame>| table.map_err(table_error(&dir.file(name)));
    let tables = [
        (files::FLIGHTS, built(files::FLIGHTS, flights_table(runs))?),
        (
            files::COVERAGE,
            built(files::COVERAGE, coverage_table(runs))?,
        ),
        (files::DEFECTS, defects_table(runs)?),
        (files::ELEMENTS, elements_table(runs)?),
    ];
    let mut rows = [0; 4];
    for ((name, table), rows) in tables.iter().zip(&mut rows) {
        *rows = table.height();
        write_partitioned(&dir.file(name), table)?;
    }
    dir.write_text(files::INDEX, index_html)?;
    remove_dir(out)?;
    std::fs::rename(staging.keep(), out).map_err(|cause| postflight_core::Error::Write {
        path: out.to_owned(),
        cause,
    })?;
    Ok(Written {
        flights: rows[0],
        coverage: rows[1],
        defects: rows[2],
        elements: rows[3],
    })
}

/// What `write` puts in its directory, and all it may replace there.
const WRITTEN: [&str; 5] = [
    files::DEFECTS,
    files::ELEMENTS,
    files::COVERAGE,
    files::FLIGHTS,
    files::INDEX,
];

/// `out` is missing or holds only what `write` writes.
fn check_replaceable(out: &Path) -> Result<(), Error> {
    let entries = match std::fs::read_dir(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        entries => entries.map_err(|cause| postflight_core::Error::Open {
            path: out.to_owned(),
            cause,
        })?,
    };
    let foreign = entries
        .filter_map(Result::ok)
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .find(|name| !WRITTEN.contains(&name.as_str()));
    match foreign {
        Some(name) => Err(Error::NotOurs {
            dir: out.to_owned(),
            entry: name,
        }),
        None => Ok(()),
    }
}

fn remove_dir(dir: &Path) -> Result<(), Error> {
    match std::fs::remove_dir_all(dir) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(postflight_core::Error::Write {
            path: dir.to_owned(),
            cause: e,
        }
        .into()),
        _ => Ok(()),
    }
}

/// A polars error as an error of the table at `path`.
fn table_error(path: &Path) -> impl Fn(PolarsError) -> Error {
    move |cause| {
        postflight_core::Error::Table {
            path: path.to_owned(),
            cause,
        }
        .into()
    }
}

/// `table` as Hive partitions by its `structure` column, which the
/// directory names carry instead of the files.
fn write_partitioned(dir: &Path, table: &DataFrame) -> Result<(), Error> {
    let structure_parts = |table: &DataFrame| -> PolarsResult<Vec<(String, DataFrame)>> {
        let structures = table.column("structure")?.str()?;
        let mut names: Vec<&str> = structures.iter().flatten().collect();
        names.sort_unstable();
        names.dedup();
        names
            .into_iter()
            .map(|name| {
                let part = table.filter(&structures.equal(name))?.drop("structure")?;
                Ok((name.to_string(), part))
            })
            .collect()
    };
    for (structure, part) in structure_parts(table).map_err(table_error(dir))? {
        RunDir::create(&dir.join(format!("structure={structure}")))?
            .write_table(files::PART, Ok(part))?;
    }
    Ok(())
}

postflight_core::table! {
    /// The columns naming each row's flight.
    pub struct FlightId {
        structure: String,
        /// `YYYY-MM-DD`; none for a run not made by `postflight batch`.
        date: Option<String>,
        /// The recording.
        flight: Option<String>,
        /// Its run directory within the fleet directory.
        run: String,
    }
}

impl FlightId {
    fn of(run: &FleetRun) -> Self {
        Self {
            structure: run.structure.clone(),
            date: run.date().map(str::to_string),
            flight: run.flight(),
            run: run.run.clone(),
        }
    }
}

postflight_core::table! {
    /// One row of `flights.parquet`: a run, how it went and its figures
    /// (none before its report).
    pub struct FlightRow {
        flight: FlightId,
        state: RunState,
        error: Option<String>,
        last_attempt: Option<String>,
        /// Seconds the stages of its current results took.
        processing_s: Option<f64>,
        flight_start: Option<String>,
        duration_s: Option<f64>,
        truncated: Option<bool>,
        frames: Option<u64>,
        frames_with_pose: Option<u64>,
        detections: Option<u64>,
        defects: Option<u64>,
        inspected_pct: Option<f64>,
        planned_inspected_pct: Option<f64>,
        replan_length_m: Option<f64>,
        replan_sorties: Option<u64>,
        /// Its report, relative to the fleet directory.
        report: Option<String>,
        postflight_version: Option<String>,
    }
}

impl FlightRow {
    fn of(run: &FleetRun) -> Self {
        let record = run.record.as_ref();
        let s = run.summary.as_ref();
        let coverage = s.and_then(|s| s.coverage.as_ref());
        let replan = s.and_then(|s| s.replan.as_ref());
        Self {
            flight: FlightId::of(run),
            state: run.state(),
            error: record.and_then(|r| r.error.clone()),
            last_attempt: record.map(|r| r.started.clone()),
            processing_s: s.map(|s| s.timings_s.values().sum()),
            flight_start: s.map(|s| s.flight_start.clone()),
            duration_s: s.map(|s| s.duration_s),
            truncated: s.map(|s| s.truncated),
            frames: s.map(|s| s.frames),
            frames_with_pose: s.map(|s| s.frames_with_pose),
            detections: s.and_then(|s| s.detections),
            defects: s.and_then(|s| s.defects),
            inspected_pct: coverage.map(|c| c.inspected_pct),
            planned_inspected_pct: coverage.and_then(|c| c.planned_inspected_pct),
            replan_length_m: replan.map(|r| r.length_m),
            replan_sorties: replan.map(|r| r.sorties as u64),
            report: s.map(|_| {
                format!(
                    "{}/{}",
                    run.run,
                    postflight_core::outputs::report::files::REPORT
                )
            }),
            postflight_version: s.map(|s| s.versions.postflight.clone()),
        }
    }
}

postflight_core::table! {
    /// One row of the fleet's `coverage.parquet`: a run whose coverage
    /// stage completed, its `coverage.json` in figures.
    pub struct CoverageRow {
        flight: FlightId,
        coverage: CoverageFigures,
    }
}

postflight_core::table! {
    /// One row of the fleet's `defects.parquet`: a run's candidate, as its
    /// own `defects.parquet` holds it.
    pub struct FleetDefectRow {
        flight: FlightId,
        defect: DefectRecord,
    }
}

/// `flights.parquet`: one row per run.
fn flights_table(runs: &[FleetRun]) -> PolarsResult<DataFrame> {
    let rows: Vec<FlightRow> = runs.iter().map(FlightRow::of).collect();
    FlightRow::frame(&rows)
}

/// `coverage.parquet`: one row per run whose coverage stage completed.
fn coverage_table(runs: &[FleetRun]) -> PolarsResult<DataFrame> {
    let rows: Vec<CoverageRow> = runs
        .iter()
        .filter_map(|r| {
            r.coverage.as_ref().map(|c| CoverageRow {
                flight: FlightId::of(r),
                coverage: c.figures.clone(),
            })
        })
        .collect();
    CoverageRow::frame(&rows)
}

postflight_core::table! {
    /// One row of the fleet's `elements.parquet`: a row of a run's element
    /// record, as its own `elements.parquet` holds it.
    pub struct FleetElementRow {
        flight: FlightId,
        element: ElementRecord,
    }
}

/// The rows of each run's table `file`, once its `stage` has completed,
/// each with its flight.
fn runs_rows<R: Row>(
    runs: &[FleetRun],
    stage: Stage,
    file: &str,
) -> Result<Vec<(FlightId, R)>, Error> {
    let mut rows = Vec::new();
    let completed = runs
        .iter()
        .filter_map(|r| RunDir::open(&r.dir, stage).ok().map(|d| (r, d)));
    for (run, dir) in completed {
        let table: Vec<R> = dir.read_rows(file).map_err(|e| Error::Fleet {
            path: run.dir.join(file),
            why: format!(
                "{e} (written by another postflight version?); rerun `postflight run` on it"
            ),
        })?;
        rows.extend(table.into_iter().map(|row| (FlightId::of(run), row)));
    }
    Ok(rows)
}

/// `defects.parquet`: every run's own candidates, its flight's columns first.
fn defects_table(runs: &[FleetRun]) -> Result<DataFrame, Error> {
    let rows: Vec<FleetDefectRow> = runs_rows(runs, Stage::Localise, localise_files::DEFECTS)?
        .into_iter()
        .map(|(flight, defect)| FleetDefectRow { flight, defect })
        .collect();
    FleetDefectRow::frame(&rows).map_err(table_error(Path::new(files::DEFECTS)))
}

/// `elements.parquet`: every run's own element record, its flight's
/// columns first.
fn elements_table(runs: &[FleetRun]) -> Result<DataFrame, Error> {
    let rows: Vec<FleetElementRow> = runs_rows(runs, Stage::Record, record_files::ELEMENTS)?
        .into_iter()
        .map(|(flight, element)| FleetElementRow { flight, element })
        .collect();
    FleetElementRow::frame(&rows).map_err(table_error(Path::new(files::ELEMENTS)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tables_replace_only_what_they_wrote() {
        let fleet = tempfile::tempdir().unwrap();
        let out = fleet.path().join(files::DIR);
        write(&[], &out, "<p>one</p>").unwrap();
        write(&[], &out, "<p>two</p>").unwrap();
        let index = std::fs::read_to_string(out.join(files::INDEX)).unwrap();
        assert_eq!(index, "<p>two</p>");
        // A structure named `fleet`, run by hand: its runs are never deleted.
        let run = out.join("2026-01-01");
        std::fs::create_dir_all(&run).unwrap();
        std::fs::write(run.join(RUN_LOG), "{}").unwrap();
        let e = write(&[], &out, "<p>three</p>").unwrap_err().to_string();
        assert!(
            e.contains("holds 2026-01-01, which `postflight fleet` did not write"),
            "{e}"
        );
        assert!(run.join(RUN_LOG).is_file());
        let left: Vec<_> = std::fs::read_dir(fleet.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "no staging directory left behind");
    }
}

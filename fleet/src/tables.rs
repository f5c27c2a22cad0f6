//! The fleet's tables, `FLEET_DIR/fleet/`: every flight's defect
//! candidates (`defects.parquet`, one row per candidate, the columns of
//! each run's own table), coverage (`coverage.parquet`) and run
//! (`flights.parquet`), one row per flight. Each is a directory of Hive
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
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::outputs::localise::files as localise_files;
use postflight_core::outputs::report::RunSummary;
use postflight_core::run_log::RUN_LOG;
use postflight_core::{RunDir, Stage};

use crate::error::Error;
use crate::slurm::SLURM_DIR;
use crate::task::{TASK_RECORD, TaskRecord};

/// The fleet's outputs, in the fleet directory.
pub mod files {
    /// The directory holding the tables and the index page.
    pub const DIR: &str = "fleet";
    pub const DEFECTS: &str = "defects.parquet";
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

    /// The flight recording, as the task or the report names it.
    pub fn flight(&self) -> Option<String> {
        let record = self.record.as_ref().map(|r| &r.flight);
        let summary = self.summary.as_ref().map(|s| &s.flight);
        record.or(summary).map(|p| p.display().to_string())
    }

    /// `finished`, `failed`, `running`, or `complete` for a run made by
    /// hand whose report exists (`incomplete` otherwise).
    pub fn state(&self) -> &'static str {
        use crate::task::TaskState;
        match (self.record.as_ref().map(|r| r.state), &self.summary) {
            (Some(TaskState::Finished), _) => "finished",
            (Some(TaskState::Failed), _) => "failed",
            (Some(TaskState::Running), _) => "running",
            (None, Some(_)) => "complete",
            (None, None) => "incomplete",
        }
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
        record: TaskRecord::read(&dir)?,
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
    ];
    let mut rows = [0; 3];
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
    })
}

/// What `write` puts in its directory, and all it may replace there.
const WRITTEN: [&str; 4] = [
    files::DEFECTS,
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

/// The columns naming each row's flight.
fn flight_columns<'a>(runs: impl Iterator<Item = &'a FleetRun> + Clone) -> Vec<Column> {
    vec![
        Column::new(
            "structure".into(),
            runs.clone()
                .map(|r| r.structure.as_str())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "date".into(),
            runs.clone().map(FleetRun::date).collect::<Vec<_>>(),
        ),
        Column::new(
            "flight".into(),
            runs.clone().map(FleetRun::flight).collect::<Vec<_>>(),
        ),
        Column::new(
            "run".into(),
            runs.map(|r| r.run.as_str()).collect::<Vec<_>>(),
        ),
    ]
}

/// `flights.parquet`: one row per run, how it went and its figures.
fn flights_table(runs: &[FleetRun]) -> PolarsResult<DataFrame> {
    let height = runs.len();
    let record = |f: fn(&TaskRecord) -> Option<String>| {
        runs.iter()
            .map(|r| r.record.as_ref().and_then(f))
            .collect::<Vec<_>>()
    };
    let summary_f64 = |f: fn(&RunSummary) -> Option<f64>| from_summary(runs, f);
    let summary_u64 = |f: fn(&RunSummary) -> Option<u64>| from_summary(runs, f);
    let mut columns = flight_columns(runs.iter());
    columns.extend([
        Column::new(
            "state".into(),
            runs.iter().map(FleetRun::state).collect::<Vec<_>>(),
        ),
        Column::new("error".into(), record(|r| r.error.clone())),
        Column::new("last_attempt".into(), record(|r| Some(r.started.clone()))),
        Column::new(
            "processing_s".into(),
            summary_f64(|s| Some(s.timings_s.values().sum())),
        ),
        Column::new(
            "flight_start".into(),
            from_summary(runs, |s| Some(s.flight_start.clone())),
        ),
        Column::new("duration_s".into(), summary_f64(|s| Some(s.duration_s))),
        Column::new(
            "truncated".into(),
            from_summary(runs, |s| Some(s.truncated)),
        ),
        Column::new("frames".into(), summary_u64(|s| Some(s.frames))),
        Column::new(
            "frames_with_pose".into(),
            summary_u64(|s| Some(s.frames_with_pose)),
        ),
        Column::new("detections".into(), summary_u64(|s| s.detections)),
        Column::new("defects".into(), summary_u64(|s| s.defects)),
        Column::new(
            "inspected_pct".into(),
            summary_f64(|s| s.coverage.as_ref().map(|c| c.inspected_pct)),
        ),
        Column::new(
            "planned_inspected_pct".into(),
            summary_f64(|s| s.coverage.as_ref().and_then(|c| c.planned_inspected_pct)),
        ),
        Column::new(
            "replan_length_m".into(),
            summary_f64(|s| s.replan.as_ref().map(|r| r.length_m)),
        ),
        Column::new(
            "replan_sorties".into(),
            summary_u64(|s| s.replan.as_ref().map(|r| r.sorties as u64)),
        ),
        Column::new(
            "report".into(),
            runs.iter()
                .map(|r| {
                    r.summary.as_ref().map(|_| {
                        format!(
                            "{}/{}",
                            r.run,
                            postflight_core::outputs::report::files::REPORT
                        )
                    })
                })
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "postflight_version".into(),
            from_summary(runs, |s| Some(s.versions.postflight.clone())),
        ),
    ]);
    DataFrame::new(height, columns)
}

/// One value per run from its report's summary (none before the report).
fn from_summary<T>(runs: &[FleetRun], f: impl Fn(&RunSummary) -> Option<T>) -> Vec<Option<T>> {
    runs.iter()
        .map(|r| r.summary.as_ref().and_then(&f))
        .collect()
}

/// `coverage.parquet`: one row per run whose coverage stage completed.
fn coverage_table(runs: &[FleetRun]) -> PolarsResult<DataFrame> {
    let covered: Vec<(&FleetRun, &CoverageSummary)> = runs
        .iter()
        .filter_map(|r| r.coverage.as_ref().map(|c| (r, c)))
        .collect();
    let count = |name: &str, f: fn(&CoverageSummary) -> Option<usize>| {
        Column::new(
            name.into(),
            covered
                .iter()
                .map(|(_, c)| f(c).map(|n| n as u64))
                .collect::<Vec<_>>(),
        )
    };
    let real = |name: &str, f: fn(&CoverageSummary) -> Option<f64>| {
        Column::new(
            name.into(),
            covered.iter().map(|(_, c)| f(c)).collect::<Vec<_>>(),
        )
    };
    let mut columns = flight_columns(covered.iter().map(|(r, _)| *r));
    columns.extend([
        real("resolution_m", |c| Some(c.resolution_m)),
        count("target_voxels", |c| Some(c.target_voxels)),
        count("planned_voxels", |c| c.planned_voxels),
        count("inspected_voxels", |c| Some(c.inspected_voxels)),
        real("inspected_pct", |c| Some(c.inspected_pct)),
        real("planned_inspected_pct", |c| c.planned_inspected_pct),
        count("planned_missed_voxels", |c| c.planned_missed_voxels),
        count("gap_voxels", |c| Some(c.gap_voxels)),
        count("uninspectable_voxels", |c| Some(c.uninspectable_voxels)),
        count("exposed_faces", |c| Some(c.exposed_faces)),
        count("inspected_faces", |c| Some(c.inspected_faces)),
        real("face_area_coverage_pct", |c| Some(c.face_area_coverage_pct)),
        count("shots_total", |c| Some(c.shots_total)),
        count("shots_usable", |c| Some(c.shots_usable)),
    ]);
    DataFrame::new(covered.len(), columns)
}

/// `defects.parquet`: every run's own `defects.parquet`, its flight's
/// columns first.
fn defects_table(runs: &[FleetRun]) -> Result<DataFrame, Error> {
    let mut all = DataFrame::new(0, flight_columns(std::iter::empty()))
        .map_err(table_error(Path::new(files::DEFECTS)))?;
    // A run's candidates count once its localise stage has completed.
    let localised = runs
        .iter()
        .filter_map(|r| RunDir::open(&r.dir, Stage::Localise).ok().map(|d| (r, d)));
    for (i, (run, dir)) in localised.enumerate() {
        let named = dir.read_table(localise_files::DEFECTS, |defects| {
            let flight = flight_columns(std::iter::repeat_n(run, defects.height()));
            let columns = flight.into_iter().chain(defects.columns().iter().cloned());
            DataFrame::new(defects.height(), columns.collect())
        })?;
        if i == 0 {
            all = named;
        } else if let Err(e) = all.vstack_mut(&named) {
            return Err(Error::Fleet {
                path: run.dir.join(localise_files::DEFECTS),
                why: format!(
                    "{e}: its columns differ from the runs' before it (written by another postflight version?); rerun `postflight run` on it"
                ),
            });
        }
    }
    Ok(all)
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

//! What a run directory holds: each stage's summary and the tables the
//! reports draw from, read once. A stage that has not run is `None`, so a
//! report can be made at any point of the pipeline.

use std::path::{Path, PathBuf};

use coverage::{CoverageSummary, ReplanSummary};
use detect::DetectSummary;
use ingest::{Flight, IngestError, RunDir, RunLog};
use localise::{DefectRecord, LocaliseSummary};
use polars::prelude::*;
use serde::Deserialize;

use crate::error::ReportError;

/// Coverage status of a target voxel, as the report colours it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum VoxelStatus {
    Inspected,
    /// Planned and not inspected: the flight missed it.
    PlannedMissed,
    /// Not planned and not inspected, but a flight could inspect it.
    NotPlanned,
    /// No free standpoint can inspect it under the View model.
    Uninspectable,
}

impl VoxelStatus {
    pub const ALL: [Self; 4] = [
        Self::Inspected,
        Self::PlannedMissed,
        Self::NotPlanned,
        Self::Uninspectable,
    ];

    /// A name for files and entity paths.
    pub fn key(self) -> &'static str {
        match self {
            Self::Inspected => "inspected",
            Self::PlannedMissed => "planned_missed",
            Self::NotPlanned => "not_planned",
            Self::Uninspectable => "uninspectable",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Self::Inspected => "inspected",
            Self::PlannedMissed => "planned, missed",
            Self::NotPlanned => "not planned, not inspected",
            Self::Uninspectable => "uninspectable",
        }
    }
}

/// One target voxel of `coverage.parquet`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetVoxel {
    pub index: [i32; 3],
    /// Centre, world frame, metres.
    pub centre: [f64; 3],
    pub status: VoxelStatus,
}

/// Everything the stages of one run wrote.
pub struct RunResults {
    /// The ingested flight (its summary, frames, cameras, trajectory and
    /// recording) and the run directory.
    pub flight: Flight,
    pub detect: Option<DetectSummary>,
    pub localise: Option<LocaliseSummary>,
    /// Defect candidates, in the order localise wrote them.
    pub defects: Vec<DefectRecord>,
    pub coverage: Option<CoverageSummary>,
    pub voxels: Vec<TargetVoxel>,
    pub replan: Option<ReplanSummary>,
    pub log: RunLog,
}

#[derive(Deserialize)]
struct DefectsFile {
    defects: Vec<DefectRecord>,
}

impl RunResults {
    /// Read the run directory at `path` (ingest must have completed).
    pub fn read(path: &Path) -> Result<Self, ReportError> {
        let flight = Flight::load(path)?;
        let dir = &flight.run;
        // A stage's other files count only once its summary says it completed.
        let localise: Option<LocaliseSummary> =
            optional_json(dir, localise::stage::files::SUMMARY)?;
        let defects = match localise {
            Some(_) => {
                dir.read_json::<DefectsFile>(localise::stage::files::DEFECTS_JSON)?
                    .defects
            }
            None => Vec::new(),
        };
        let coverage: Option<CoverageSummary> =
            optional_json(dir, coverage::stage::files::SUMMARY)?;
        let voxels = if coverage.is_some() {
            let table = dir.read_table(coverage::stage::files::TABLE)?;
            target_voxels(&table).map_err(|why| ReportError::Table {
                path: dir.file(coverage::stage::files::TABLE),
                why: format!("{why}; rerun `postflight coverage`"),
            })?
        } else {
            Vec::new()
        };
        Ok(Self {
            detect: optional_json(dir, detect::stage::files::SUMMARY)?,
            localise,
            defects,
            coverage,
            voxels,
            replan: optional_json(dir, coverage::replan::files::PLAN)?,
            log: RunLog::read(dir)?,
            flight,
        })
    }

    /// The run directory.
    pub fn dir(&self) -> &RunDir {
        &self.flight.run
    }

    /// A file of the run directory.
    pub fn file(&self, name: &str) -> PathBuf {
        self.dir().file(name)
    }

    /// Defect candidates in review order: the likeliest and largest first
    /// (fused confidence times length, cracks of unknown length counted 5 cm).
    pub fn defects_for_review(&self) -> Vec<&DefectRecord> {
        self.review_order()
            .into_iter()
            .map(|i| &self.defects[i])
            .collect()
    }

    /// The same order as indices into `defects`.
    pub fn review_order(&self) -> Vec<usize> {
        let d = &self.defects;
        let mut order: Vec<usize> = (0..d.len()).collect();
        order.sort_by(|&a, &b| {
            review_priority(&d[b])
                .total_cmp(&review_priority(&d[a]))
                .then_with(|| d[a].id.cmp(&d[b].id))
        });
        order
    }
}

/// A stage's JSON file, `None` when the stage has not written it.
fn optional_json<T: serde::de::DeserializeOwned>(
    dir: &RunDir,
    name: &str,
) -> Result<Option<T>, IngestError> {
    if dir.file(name).is_file() {
        dir.read_json(name).map(Some)
    } else {
        Ok(None)
    }
}

/// How urgently a candidate needs a reviewer's eye.
pub fn review_priority(d: &DefectRecord) -> f64 {
    d.confidence * d.length_m.unwrap_or(0.0).max(0.05)
}

fn target_voxels(df: &DataFrame) -> Result<Vec<TargetVoxel>, PolarsError> {
    let int = |name: &str| -> Result<Vec<i32>, PolarsError> {
        let c = df.column(name)?.cast(&DataType::Int32)?;
        Ok(c.i32()?.into_no_null_iter().collect())
    };
    let float = |name: &str| -> Result<Vec<f64>, PolarsError> {
        Ok(df.column(name)?.f64()?.into_no_null_iter().collect())
    };
    let flag = |name: &str| -> Result<Vec<Option<bool>>, PolarsError> {
        Ok(df.column(name)?.bool()?.iter().collect())
    };
    let (ix, iy, iz) = (int("voxel_x")?, int("voxel_y")?, int("voxel_z")?);
    let (x, y, z) = (float("x")?, float("y")?, float("z")?);
    let (planned, inspected, uninspectable) =
        (flag("planned")?, flag("inspected")?, flag("uninspectable")?);
    Ok((0..df.height())
        .map(|i| TargetVoxel {
            index: [ix[i], iy[i], iz[i]],
            centre: [x[i], y[i], z[i]],
            status: if inspected[i] == Some(true) {
                VoxelStatus::Inspected
            } else if uninspectable[i] == Some(true) {
                VoxelStatus::Uninspectable
            } else if planned[i] == Some(true) {
                VoxelStatus::PlannedMissed
            } else {
                VoxelStatus::NotPlanned
            },
        })
        .collect())
}

//! What the localise stage writes: `observations.parquet` (one row per
//! detection, placed or not, with the reason), `defects.parquet` (one row
//! per candidate, its best view inline), `defects.json` (the candidates
//! with every supporting view, for people, coverage and the review queue),
//! a JPEG crop per candidate, and its summary `localise.json`. Columns are
//! flat, angles in degrees, lengths in metres.
//!
//! A `gsd_mm` here is a view's oblique GSD (see
//! [`ViewRecord::oblique_gsd_mm`]), coarser than the View model's
//! fronto-parallel GSD of the coverage tables for any view not face on.

use std::collections::HashMap;
use std::path::PathBuf;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::{parsed, required, required3};
use crate::detection::BoxXyxy;
use crate::error::Error;
use crate::map::{FaceSide, VoxelIndex};
use crate::run_dir::RunDir;

/// Files of the localise stage.
pub mod files {
    pub const OBSERVATIONS: &str = "observations.parquet";
    pub const DEFECTS: &str = "defects.parquet";
    pub const DEFECTS_JSON: &str = "defects.json";
    /// Directory of candidate crops, `<id>.jpg`.
    pub const CROPS: &str = "defects";
    pub const SUMMARY: &str = "localise.json";
}

/// What became of a detection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Outcome {
    /// Placed on the structure.
    Placed,
    /// Its frame has no pose (none recorded near the frame time).
    NoPose,
    /// Its camera has no intrinsics.
    NoIntrinsics,
    /// Its rays met no mapped surface within range.
    NoSurface,
    /// Its rays met a mapped surface that is not the structure to inspect.
    Obstacle,
}

impl Outcome {
    pub const ALL: [Self; 5] = [
        Self::Placed,
        Self::NoPose,
        Self::NoIntrinsics,
        Self::NoSurface,
        Self::Obstacle,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Placed => "placed",
            Outcome::NoPose => "no_pose",
            Outcome::NoIntrinsics => "no_intrinsics",
            Outcome::NoSurface => "no_surface",
            Outcome::Obstacle => "obstacle",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.as_str() == s)
    }
}

/// Detections of each outcome.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Outcomes {
    pub placed: u64,
    pub no_pose: u64,
    pub no_intrinsics: u64,
    pub no_surface: u64,
    pub obstacle: u64,
}

/// `localise.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LocaliseSummary {
    /// The map file, or the recorded topic.
    pub map: String,
    pub map_points: usize,
    pub map_voxels: usize,
    pub voxel_size_m: f64,
    /// The plan whose target voxels are the structure, if one was given.
    pub plan: Option<PathBuf>,
    pub max_range_m: f64,
    pub link_distance_m: f64,
    pub detections: u64,
    pub outcomes: Outcomes,
    /// Detections placed by their traced centre line (the rest by their box).
    pub traced: u64,
    /// Share of cast detections (pose and intrinsics known) whose rays met the map.
    pub hit_share: f64,
    pub defects: u64,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// One detection as `observations.parquet` holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct ObservationRecord {
    pub frame: u32,
    pub time_ns: i64,
    /// The detection's box, frame pixels.
    pub bbox: BoxXyxy,
    /// The detector's score.
    pub score: f32,
    pub outcome: Outcome,
    /// Where it lies on the structure, for a placed detection.
    pub placed: Option<PlacedRecord>,
    /// Centre-line pixels traced in the image (0: placed by its box).
    pub traced_px: u32,
    /// The box or the traced crack touches the image border.
    pub clipped: bool,
    /// The candidate it supports.
    pub defect: Option<String>,
}

/// A placed detection's crack on the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedRecord {
    /// Centroid of the crack on the surface, world frame, metres.
    pub centre: [f64; 3],
    /// Unit normal of the surface, facing the camera.
    pub normal: [f64; 3],
    pub voxel: VoxelIndex,
    pub face: FaceSide,
    pub range_m: f64,
    pub incidence_deg: f64,
    /// See [`ViewRecord::oblique_gsd_mm`].
    pub oblique_gsd_mm: f64,
    pub length_m: Option<f64>,
    /// Farthest crack point from the centre, metres.
    pub radius_m: f64,
}

/// One view of a defect candidate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ViewRecord {
    pub frame: u32,
    pub time_ns: i64,
    /// `[x0, y0, x1, y1]`, frame pixels.
    pub bbox: [f32; 4],
    pub score: f32,
    pub range_m: f64,
    pub incidence_deg: f64,
    /// The view's oblique GSD: the pixel's footprint on the surface along
    /// its most stretched direction, millimetres (`gsd_mm` in the files).
    #[serde(rename = "gsd_mm")]
    pub oblique_gsd_mm: f64,
    pub length_m: Option<f64>,
    /// The box touches the image border.
    pub clipped: bool,
}

/// A rule of the View model a view breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewFault {
    /// Farther than the distance band.
    TooFar,
    /// Nearer than the distance band.
    TooClose,
    /// Seen more obliquely than the largest incidence.
    TooOblique,
    /// GSD coarser than the View model's target.
    TooCoarse,
    /// The frame is motion-blurred beyond the threshold.
    Blurred,
}

impl ViewFault {
    pub const ALL: [Self; 5] = [
        Self::TooFar,
        Self::TooClose,
        Self::TooOblique,
        Self::TooCoarse,
        Self::Blurred,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Self::TooFar => "too_far",
            Self::TooClose => "too_close",
            Self::TooOblique => "too_oblique",
            Self::TooCoarse => "too_coarse",
            Self::Blurred => "blurred",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.as_str() == s)
    }

    /// Faults as the tables write them: their names joined by `,` (empty
    /// for none).
    pub fn list(faults: &[Self]) -> String {
        let names: Vec<&str> = faults.iter().map(|f| f.as_str()).collect();
        names.join(",")
    }

    /// The faults of a [`list`](Self::list).
    pub fn parse_list(s: &str) -> PolarsResult<Vec<Self>> {
        s.split(',')
            .filter(|f| !f.is_empty())
            .map(|f| {
                Self::parse(f).ok_or_else(|| polars_err!(ComputeError: "unknown view fault {f:?}"))
            })
            .collect()
    }
}

/// Whether a candidate's length was measured, and if not, why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LengthStatus {
    /// From at least one view that shows the whole crack.
    Measured,
    /// Only from views the image border cuts: the crack is at least this long.
    Partial,
    /// Every view is too oblique to measure on.
    TooOblique,
    /// No view traced the crack's line (its boxes placed it).
    NotTraced,
    /// The only traced views are far away and cut by the image border.
    FarAndCut,
}

impl LengthStatus {
    pub const ALL: [Self; 5] = [
        Self::Measured,
        Self::Partial,
        Self::TooOblique,
        Self::NotTraced,
        Self::FarAndCut,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Self::Measured => "measured",
            Self::Partial => "partial",
            Self::TooOblique => "too_oblique",
            Self::NotTraced => "not_traced",
            Self::FarAndCut => "far_and_cut",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|l| l.as_str() == s)
    }

    /// Why there is no length, for people; `None` when there is one.
    pub fn missing_reason(self) -> Option<&'static str> {
        match self {
            Self::Measured | Self::Partial => None,
            Self::TooOblique => Some("every view is too oblique to measure on"),
            Self::NotTraced => Some("no view traced the crack's line"),
            Self::FarAndCut => Some("its only traced views are far and cut by the image border"),
        }
    }
}

/// How far a candidate's evidence can be trusted, and what it lacks.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Evidence {
    /// The View model's rules the best view breaks; empty when it meets them.
    pub view_faults: Vec<ViewFault>,
    /// The best view's GSD as the View model measures it (fronto-parallel
    /// at its range), millimetres; see [`ViewRecord::oblique_gsd_mm`] for
    /// the footprint along the surface.
    pub view_gsd_mm: f64,
    /// The best frame's motion blur, pixels; `None` when its exposure time
    /// is unknown (blur not judged).
    pub blur_px: Option<f64>,
    pub length: LengthStatus,
    /// Narrowest crack width the best view can measure, millimetres: two
    /// of its pixels along the surface. A narrower crack (a hairline at a
    /// few mm/px) shows as a line below a pixel wide, and its width is not
    /// measured from this flight.
    pub min_measurable_width_mm: f64,
    /// Weak evidence (the best view breaks the View model, or no length):
    /// the spot belongs in the follow-up flight.
    pub reshoot: bool,
}

impl Evidence {
    /// The narrowest measurable width spans this many pixels.
    pub const MIN_WIDTH_PX: f64 = 2.0;
}

/// One defect candidate in `defects.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct DefectRecord {
    pub id: String,
    /// The structure element it is on (`pier 2`), as coverage names the
    /// voxels there; none without targets, or off them.
    pub element: Option<String>,
    /// Where it is: `pier 2, east face, 1.4 m above its base`.
    pub place: Option<String>,
    /// World frame, metres.
    pub position: [f64; 3],
    pub normal: [f64; 3],
    pub extent_min: [f64; 3],
    pub extent_max: [f64; 3],
    pub voxel: [i32; 3],
    pub face: FaceSide,
    pub length_m: Option<f64>,
    pub length_views: u32,
    pub frames: u32,
    pub confidence: f64,
    pub max_score: f64,
    pub evidence: Evidence,
    /// JPEG of the best view, relative to the run directory (none when its
    /// image could not be decoded).
    pub crop: Option<String>,
    pub best: ViewRecord,
    /// Every supporting view, in frame order.
    pub views: Vec<ViewRecord>,
}

/// Write `defects.parquet` and `defects.json` (the same candidates; the
/// JSON with every supporting view).
pub fn write_defects(run: &RunDir, defects: &[DefectRecord]) -> Result<(), Error> {
    run.write_table(files::DEFECTS, defects_table(defects))?;
    // Through a JSON value, whose numbers are f64: a score (f32) is written
    // as the f64 it widens to, the value a reader of the Parquet tables sees.
    run.write_json(
        files::DEFECTS_JSON,
        &serde_json::json!({ "defects": defects }),
    )
}

/// Read `defects.parquet`, each candidate's supporting views taken from
/// `observations.parquet` (the placed detections naming it): the same
/// records `defects.json` holds, from the tables.
pub fn read_defects_table(run: &RunDir) -> Result<Vec<DefectRecord>, Error> {
    let mut views: HashMap<String, Vec<ViewRecord>> = HashMap::new();
    for o in read_observations(run)? {
        if let (Some(defect), Some(view)) = (&o.defect, ViewRecord::of(&o)) {
            views.entry(defect.clone()).or_default().push(view);
        }
    }
    run.read_table(files::DEFECTS, |df| {
        defects_from(df, &|id| views.get(id).cloned().unwrap_or_default())
    })
}

impl ViewRecord {
    /// A placed observation as a view of its candidate (`None` unplaced).
    pub fn of(o: &ObservationRecord) -> Option<Self> {
        let p = o.placed?;
        let b = o.bbox;
        Some(Self {
            frame: o.frame,
            time_ns: o.time_ns,
            bbox: [b.x0, b.y0, b.x1, b.y1],
            score: o.score,
            range_m: p.range_m,
            incidence_deg: p.incidence_deg,
            oblique_gsd_mm: p.oblique_gsd_mm,
            length_m: p.length_m,
            clipped: o.clipped,
        })
    }
}

/// Read `defects.json`: the candidates with every supporting view.
pub fn read_defects(run: &RunDir) -> Result<Vec<DefectRecord>, Error> {
    run.read_json::<DefectsFile>(files::DEFECTS_JSON)
        .map(|f| f.defects)
}

#[derive(Deserialize)]
struct DefectsFile {
    defects: Vec<DefectRecord>,
}

/// Write `observations.parquet`.
pub fn write_observations(run: &RunDir, observations: &[ObservationRecord]) -> Result<(), Error> {
    run.write_table(files::OBSERVATIONS, observations_table(observations))
}

/// Read `observations.parquet`.
pub fn read_observations(run: &RunDir) -> Result<Vec<ObservationRecord>, Error> {
    run.read_table(files::OBSERVATIONS, observations_from)
}

fn xyz(name: &str, values: impl Iterator<Item = Option<[f64; 3]>>) -> Vec<Column> {
    let mut columns: [Vec<Option<f64>>; 3] = Default::default();
    for v in values {
        for (a, c) in columns.iter_mut().enumerate() {
            c.push(v.map(|v| v[a]));
        }
    }
    ["x", "y", "z"]
        .iter()
        .zip(columns)
        .map(|(axis, c)| Column::new(format!("{name}{axis}").into(), c))
        .collect()
}

/// `observations.parquet`: every detection, placed or not, with the reason.
fn observations_table(o: &[ObservationRecord]) -> PolarsResult<DataFrame> {
    let placed = |f: &dyn Fn(&PlacedRecord) -> f64| {
        o.iter()
            .map(|o| o.placed.as_ref().map(f))
            .collect::<Vec<Option<f64>>>()
    };
    let bbox = |f: &dyn Fn(&BoxXyxy) -> f32| o.iter().map(|o| f(&o.bbox)).collect::<Vec<f32>>();
    let mut columns = vec![
        Column::new(
            "frame".into(),
            o.iter().map(|o| o.frame).collect::<Vec<u32>>(),
        ),
        Column::new(
            "time_ns".into(),
            o.iter().map(|o| o.time_ns).collect::<Vec<i64>>(),
        ),
        Column::new("x0".into(), bbox(&|b| b.x0)),
        Column::new("y0".into(), bbox(&|b| b.y0)),
        Column::new("x1".into(), bbox(&|b| b.x1)),
        Column::new("y1".into(), bbox(&|b| b.y1)),
        Column::new(
            "score".into(),
            o.iter().map(|o| o.score).collect::<Vec<f32>>(),
        ),
        Column::new(
            "outcome".into(),
            o.iter().map(|o| o.outcome.as_str()).collect::<Vec<&str>>(),
        ),
    ];
    columns.extend(xyz("", o.iter().map(|o| o.placed.map(|p| p.centre))));
    columns.extend(xyz("n", o.iter().map(|o| o.placed.map(|p| p.normal))));
    for (a, axis) in ["x", "y", "z"].iter().enumerate() {
        columns.push(Column::new(
            format!("voxel_{axis}").into(),
            o.iter()
                .map(|o| o.placed.map(|p| p.voxel.0[a]))
                .collect::<Vec<Option<i32>>>(),
        ));
    }
    columns.extend([
        Column::new(
            "face".into(),
            o.iter()
                .map(|o| o.placed.map(|p| p.face.name()))
                .collect::<Vec<Option<&str>>>(),
        ),
        Column::new("range_m".into(), placed(&|p| p.range_m)),
        Column::new("incidence_deg".into(), placed(&|p| p.incidence_deg)),
        Column::new("gsd_mm".into(), placed(&|p| p.oblique_gsd_mm)),
        Column::new(
            "length_m".into(),
            o.iter()
                .map(|o| o.placed.and_then(|p| p.length_m))
                .collect::<Vec<Option<f64>>>(),
        ),
        Column::new("radius_m".into(), placed(&|p| p.radius_m)),
        Column::new(
            "traced_px".into(),
            o.iter().map(|o| o.traced_px).collect::<Vec<u32>>(),
        ),
        Column::new(
            "clipped".into(),
            o.iter().map(|o| o.clipped).collect::<Vec<bool>>(),
        ),
        Column::new(
            "defect".into(),
            o.iter()
                .map(|o| o.defect.as_deref())
                .collect::<Vec<Option<&str>>>(),
        ),
    ]);
    DataFrame::new(o.len(), columns)
}

fn observations_from(df: &DataFrame) -> PolarsResult<Vec<ObservationRecord>> {
    let f32s = |name: &str| df.column(name).and_then(|c| c.f32());
    let f64s = |name: &str| df.column(name).and_then(|c| c.f64());
    let i32s = |name: &str| df.column(name).and_then(|c| c.i32());
    let (frame, time) = (df.column("frame")?.u32()?, df.column("time_ns")?.i64()?);
    let (x0, y0, x1, y1, score) = (
        f32s("x0")?,
        f32s("y0")?,
        f32s("x1")?,
        f32s("y1")?,
        f32s("score")?,
    );
    let (outcome, face, defect) = (
        df.column("outcome")?.str()?,
        df.column("face")?.str()?,
        df.column("defect")?.str()?,
    );
    let centre = [f64s("x")?, f64s("y")?, f64s("z")?];
    let normal = [f64s("nx")?, f64s("ny")?, f64s("nz")?];
    let voxel = [i32s("voxel_x")?, i32s("voxel_y")?, i32s("voxel_z")?];
    let (range, incidence, gsd, length, radius) = (
        f64s("range_m")?,
        f64s("incidence_deg")?,
        f64s("gsd_mm")?,
        f64s("length_m")?,
        f64s("radius_m")?,
    );
    let (traced, clipped) = (
        df.column("traced_px")?.u32()?,
        df.column("clipped")?.bool()?,
    );
    (0..df.height())
        .map(|i| {
            let xyz = |c: &[&Float64Chunked; 3]| -> Option<[f64; 3]> {
                Some([c[0].get(i)?, c[1].get(i)?, c[2].get(i)?])
            };
            let face_column = face;
            let placed = match (xyz(&[centre[0], centre[1], centre[2]]), face.get(i)) {
                (Some(centre), Some(_)) => Some(PlacedRecord {
                    centre,
                    normal: required3(normal, i)?,
                    voxel: VoxelIndex(required3(voxel, i)?),
                    face: parsed(face_column, i, FaceSide::parse)?,
                    range_m: required(range, i)?,
                    incidence_deg: required(incidence, i)?,
                    oblique_gsd_mm: required(gsd, i)?,
                    length_m: length.get(i),
                    radius_m: required(radius, i)?,
                }),
                _ => None,
            };
            Ok(ObservationRecord {
                frame: required(frame, i)?,
                time_ns: required(time, i)?,
                bbox: BoxXyxy {
                    x0: required(x0, i)?,
                    y0: required(y0, i)?,
                    x1: required(x1, i)?,
                    y1: required(y1, i)?,
                },
                score: required(score, i)?,
                outcome: parsed(outcome, i, Outcome::parse)?,
                placed,
                traced_px: required(traced, i)?,
                clipped: required(clipped, i)?,
                defect: defect.get(i).map(str::to_string),
            })
        })
        .collect()
}

/// `defects.parquet`: one row per candidate, its best view inline.
fn defects_table(defects: &[DefectRecord]) -> PolarsResult<DataFrame> {
    let d = defects;
    let f = |get: &dyn Fn(&DefectRecord) -> f64| d.iter().map(get).collect::<Vec<f64>>();
    let text = |get: &dyn Fn(&DefectRecord) -> Option<&str>| {
        d.iter().map(get).collect::<Vec<Option<&str>>>()
    };
    let mut columns = vec![
        Column::new(
            "id".into(),
            d.iter().map(|d| d.id.as_str()).collect::<Vec<&str>>(),
        ),
        Column::new("element".into(), text(&|d| d.element.as_deref())),
        Column::new("place".into(), text(&|d| d.place.as_deref())),
    ];
    columns.extend(xyz("", d.iter().map(|d| Some(d.position))));
    columns.extend(xyz("n", d.iter().map(|d| Some(d.normal))));
    columns.extend(xyz("min_", d.iter().map(|d| Some(d.extent_min))));
    columns.extend(xyz("max_", d.iter().map(|d| Some(d.extent_max))));
    for (a, axis) in ["x", "y", "z"].iter().enumerate() {
        columns.push(Column::new(
            format!("voxel_{axis}").into(),
            d.iter().map(|d| d.voxel[a]).collect::<Vec<i32>>(),
        ));
    }
    columns.extend([
        Column::new(
            "face".into(),
            d.iter().map(|d| d.face.name()).collect::<Vec<&str>>(),
        ),
        Column::new(
            "length_m".into(),
            d.iter().map(|d| d.length_m).collect::<Vec<Option<f64>>>(),
        ),
        Column::new(
            "length_views".into(),
            d.iter().map(|d| d.length_views).collect::<Vec<u32>>(),
        ),
        Column::new(
            "frames".into(),
            d.iter().map(|d| d.frames).collect::<Vec<u32>>(),
        ),
        Column::new("confidence".into(), f(&|d| d.confidence)),
        Column::new("max_score".into(), f(&|d| d.max_score)),
        Column::new(
            "view_faults".into(),
            d.iter()
                .map(|d| ViewFault::list(&d.evidence.view_faults))
                .collect::<Vec<String>>(),
        ),
        Column::new("view_gsd_mm".into(), f(&|d| d.evidence.view_gsd_mm)),
        Column::new(
            "blur_px".into(),
            d.iter()
                .map(|d| d.evidence.blur_px)
                .collect::<Vec<Option<f64>>>(),
        ),
        Column::new(
            "length_status".into(),
            d.iter()
                .map(|d| d.evidence.length.as_str())
                .collect::<Vec<&str>>(),
        ),
        Column::new(
            "min_measurable_width_mm".into(),
            f(&|d| d.evidence.min_measurable_width_mm),
        ),
        Column::new(
            "reshoot".into(),
            d.iter().map(|d| d.evidence.reshoot).collect::<Vec<bool>>(),
        ),
        Column::new(
            "best_frame".into(),
            d.iter().map(|d| d.best.frame).collect::<Vec<u32>>(),
        ),
        Column::new("best_range_m".into(), f(&|d| d.best.range_m)),
        Column::new("best_incidence_deg".into(), f(&|d| d.best.incidence_deg)),
        Column::new("best_gsd_mm".into(), f(&|d| d.best.oblique_gsd_mm)),
    ]);
    for (k, name) in ["best_x0", "best_y0", "best_x1", "best_y1"]
        .iter()
        .enumerate()
    {
        columns.push(Column::new(
            (*name).into(),
            d.iter().map(|d| d.best.bbox[k]).collect::<Vec<f32>>(),
        ));
    }
    columns.push(Column::new(
        "crop".into(),
        d.iter()
            .map(|d| d.crop.as_deref())
            .collect::<Vec<Option<&str>>>(),
    ));
    DataFrame::new(d.len(), columns)
}

fn defects_from(
    df: &DataFrame,
    views: &dyn Fn(&str) -> Vec<ViewRecord>,
) -> PolarsResult<Vec<DefectRecord>> {
    let f64s = |name: &str| df.column(name).and_then(|c| c.f64());
    let f32s = |name: &str| df.column(name).and_then(|c| c.f32());
    let u32s = |name: &str| df.column(name).and_then(|c| c.u32());
    let i32s = |name: &str| df.column(name).and_then(|c| c.i32());
    let triple = |prefix: &str| -> PolarsResult<[&Float64Chunked; 3]> {
        Ok([
            f64s(&format!("{prefix}x"))?,
            f64s(&format!("{prefix}y"))?,
            f64s(&format!("{prefix}z"))?,
        ])
    };
    let (id, face, crop) = (
        df.column("id")?.str()?,
        df.column("face")?.str()?,
        df.column("crop")?.str()?,
    );
    // Runs localised before elements were named have neither column.
    let optional = |name: &str| df.column(name).ok().map(|c| c.str()).transpose();
    let (element, place) = (optional("element")?, optional("place")?);
    let (position, normal) = (triple("")?, triple("n")?);
    let (extent_min, extent_max) = (triple("min_")?, triple("max_")?);
    let voxel = [i32s("voxel_x")?, i32s("voxel_y")?, i32s("voxel_z")?];
    let (length, length_views) = (f64s("length_m")?, u32s("length_views")?);
    let (frames, confidence, max_score) =
        (u32s("frames")?, f64s("confidence")?, f64s("max_score")?);
    let best_frame = u32s("best_frame")?;
    let (faults, length_status) = (
        df.column("view_faults")?.str()?,
        df.column("length_status")?.str()?,
    );
    let (view_gsd, blur, min_width) = (
        f64s("view_gsd_mm")?,
        f64s("blur_px")?,
        f64s("min_measurable_width_mm")?,
    );
    let reshoot = df.column("reshoot")?.bool()?;
    let best_box = [
        f32s("best_x0")?,
        f32s("best_y0")?,
        f32s("best_x1")?,
        f32s("best_y1")?,
    ];
    (0..df.height())
        .map(|i| {
            let id = required(id, i)?.to_string();
            let views = views(&id);
            let frame = required(best_frame, i)?;
            let bbox = best_box.map(|c| c.get(i));
            let best = views
                .iter()
                .find(|v| v.frame == frame && bbox == v.bbox.map(Some))
                .cloned()
                .ok_or_else(|| {
                    polars_err!(ComputeError: "candidate {id}'s best view is not among its observations")
                })?;
            let text = |c: Option<&StringChunked>| c.and_then(|c| c.get(i)).map(str::to_string);
            Ok(DefectRecord {
                element: text(element),
                place: text(place),
                position: required3(position, i)?,
                normal: required3(normal, i)?,
                extent_min: required3(extent_min, i)?,
                extent_max: required3(extent_max, i)?,
                voxel: required3(voxel, i)?,
                face: parsed(face, i, FaceSide::parse)?,
                length_m: length.get(i),
                length_views: required(length_views, i)?,
                frames: required(frames, i)?,
                confidence: required(confidence, i)?,
                max_score: required(max_score, i)?,
                evidence: Evidence {
                    view_faults: ViewFault::parse_list(required(faults, i)?)?,
                    view_gsd_mm: required(view_gsd, i)?,
                    blur_px: blur.get(i),
                    length: parsed(length_status, i, LengthStatus::parse)?,
                    min_measurable_width_mm: required(min_width, i)?,
                    reshoot: required(reshoot, i)?,
                },
                crop: crop.get(i).map(str::to_string),
                best,
                views,
                id,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observation(frame: u32, placed: bool, defect: Option<&str>) -> ObservationRecord {
        ObservationRecord {
            frame,
            time_ns: 1_000 * i64::from(frame),
            bbox: BoxXyxy {
                x0: 10.0 + frame as f32,
                y0: 20.0,
                x1: 60.5,
                y1: 44.25,
            },
            score: 0.5 + 0.01 * frame as f32,
            outcome: if placed {
                Outcome::Placed
            } else {
                Outcome::NoSurface
            },
            placed: placed.then(|| PlacedRecord {
                centre: [1.0, 2.0, f64::from(frame)],
                normal: [-1.0, 0.0, 0.0],
                voxel: VoxelIndex([2, 4, 6]),
                face: FaceSide::NegX,
                range_m: 3.5,
                incidence_deg: 12.0,
                oblique_gsd_mm: 3.8,
                length_m: frame.is_multiple_of(2).then_some(0.42),
                radius_m: 0.2,
            }),
            traced_px: 17 * frame,
            clipped: frame == 3,
            defect: defect.map(str::to_string),
        }
    }

    #[test]
    fn the_tables_round_trip_and_hold_what_the_json_holds() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        let observations = vec![
            observation(1, true, Some("2_4_6-x")),
            observation(2, false, None),
            observation(3, true, Some("2_4_6-x")),
            observation(4, true, Some("9_9_9+z")),
        ];
        write_observations(&run, &observations).unwrap();
        assert_eq!(read_observations(&run).unwrap(), observations);
        let defect = |id: &str, frames: &[u32], best: u32| {
            let views: Vec<ViewRecord> = observations
                .iter()
                .filter(|o| frames.contains(&o.frame))
                .filter_map(ViewRecord::of)
                .collect();
            // One candidate on an element, one off the structure.
            let on = frames.len() > 1;
            DefectRecord {
                id: id.into(),
                element: on.then(|| "pier 1".into()),
                place: on.then(|| "pier 1, east face, 1.4 m above its base".into()),
                position: [1.0, 2.0, 2.5],
                normal: [-1.0, 0.0, 0.0],
                extent_min: [0.9, 1.8, 2.0],
                extent_max: [1.1, 2.2, 3.0],
                voxel: [2, 4, 6],
                face: FaceSide::NegX,
                length_m: Some(0.42),
                length_views: 1,
                frames: views.len() as u32,
                confidence: 0.8,
                max_score: 0.53,
                evidence: Evidence {
                    view_faults: if best == 3 {
                        vec![ViewFault::TooFar, ViewFault::Blurred]
                    } else {
                        Vec::new()
                    },
                    view_gsd_mm: 3.5,
                    blur_px: (best == 3).then_some(4.5),
                    length: LengthStatus::Measured,
                    min_measurable_width_mm: 7.6,
                    reshoot: best == 3,
                },
                crop: Some(format!("defects/{id}.jpg")),
                best: views.iter().find(|v| v.frame == best).unwrap().clone(),
                views,
            }
        };
        let defects = vec![defect("2_4_6-x", &[1, 3], 3), defect("9_9_9+z", &[4], 4)];
        write_defects(&run, &defects).unwrap();
        assert_eq!(read_defects(&run).unwrap(), defects);
        assert_eq!(read_defects_table(&run).unwrap(), defects);
    }
}

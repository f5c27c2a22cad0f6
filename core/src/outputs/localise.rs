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

use polars::prelude::{PolarsResult, polars_err};
use serde::{Deserialize, Serialize};

use super::detect::DetectionCells;
use crate::condition::ConditionState;
use crate::detection::BoxXyxy;
use crate::error::Error;
use crate::map::{FaceSide, VoxelIndex};
use crate::run_dir::RunDir;
use crate::trace::Trace;
use crate::view::Miss;

/// Files of the localise stage.
pub mod files {
    pub const OBSERVATIONS: &str = "observations.parquet";
    pub const DEFECTS: &str = "defects.parquet";
    pub const DEFECTS_JSON: &str = "defects.json";
    /// Directory of candidate crops, `<id>.jpg`.
    pub const CROPS: &str = "defects";
    pub const SUMMARY: &str = "localise.json";

    /// A candidate's crop's file name in [`CROPS`].
    pub fn crop(id: &str) -> String {
        format!("{id}.jpg")
    }
}

crate::kind! {
    /// What became of a detection.
    pub enum Outcome("outcome") {
        /// Placed on the structure.
        Placed = "placed",
        /// Its frame has no pose (none recorded near the frame time).
        NoPose = "no_pose",
        /// Its camera has no intrinsics.
        NoIntrinsics = "no_intrinsics",
        /// Its rays met no mapped surface within range.
        NoSurface = "no_surface",
        /// Its rays met a mapped surface that is not the structure to inspect.
        Obstacle = "obstacle",
    }
}

/// Detections of each outcome.
pub type Outcomes = crate::kind::Counts<Outcome>;

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
    /// Candidates set aside as not cracks (formwork joints), not counted
    /// in `defects`.
    #[serde(default)]
    pub set_aside: Vec<SetAside>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// A group of views localise set aside: something a crack detector finds
/// that is not a crack. Its observations support no candidate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SetAside {
    pub reason: SetAsideReason,
    /// The id it would have had as a candidate.
    pub id: String,
    /// World frame, metres.
    pub position: [f64; 3],
    pub frames: u32,
    pub trace: Trace,
}

/// Why views were set aside.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SetAsideReason {
    /// Its views see a line straight over 15 cm or more, level or plumb:
    /// a formwork joint.
    Joint,
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

crate::kind! {
    /// Whether a candidate's length was measured, and if not, why.
    pub enum LengthStatus("length status") {
        /// From at least one view that shows the whole crack.
        Measured = "measured",
        /// Only from views the image border cuts: the crack is at least this long.
        Partial = "partial",
        /// Every view is too oblique to measure on.
        TooOblique = "too_oblique",
        /// Every view steep enough to measure on is blurred.
        Blurred = "blurred",
        /// No view traced the crack's line (its boxes placed it).
        NotTraced = "not_traced",
        /// The only traced views are far away and cut by the image border.
        FarAndCut = "far_and_cut",
    }
}

impl LengthStatus {
    /// Why there is no length, for people; `None` when there is one.
    pub fn missing_reason(self) -> Option<&'static str> {
        match self {
            Self::Measured | Self::Partial => None,
            Self::TooOblique => Some("every view is too oblique to measure on"),
            Self::Blurred => Some("every view steep enough to measure on is blurred"),
            Self::NotTraced => Some("no view traced the crack's line"),
            Self::FarAndCut => Some("its only traced views are far and cut by the image border"),
        }
    }
}

/// How far a candidate's evidence can be trusted, and what it lacks.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Evidence {
    /// The View model's rules the best view breaks; empty when it meets them.
    pub view_faults: Vec<Miss>,
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
    /// How far off `position` may be, metres (one standard deviation):
    /// its views' scatter about it over the square root of their number,
    /// and their cameras' position accuracy (a photo's RTK accuracy) in
    /// full, as RTK errors run from photo to photo; none from one view of
    /// a camera whose accuracy is unknown.
    #[serde(default)]
    pub position_uncertainty_m: Option<f64>,
    pub normal: [f64; 3],
    pub extent_min: [f64; 3],
    pub extent_max: [f64; 3],
    pub voxel: [i32; 3],
    pub face: FaceSide,
    pub length_m: Option<f64>,
    /// Views its trace (and length) is made of.
    pub length_views: u32,
    /// Its centre line on the structure, from its views' traces (empty
    /// where no view traced it); `length_m` is its length.
    #[serde(default)]
    pub trace: Trace,
    pub frames: u32,
    pub confidence: f64,
    pub max_score: f64,
    pub evidence: Evidence,
    /// Its width, where a view could measure across its centre line.
    #[serde(default)]
    pub width: Option<WidthRecord>,
    /// The condition state its width puts its length in (`[condition]`'s
    /// limits); none where the width is unknown or its bound straddles a
    /// limit.
    #[serde(default)]
    pub condition: Option<ConditionState>,
    /// JPEG of the best view, relative to the run directory (none when its
    /// image could not be decoded).
    pub crop: Option<String>,
    pub best: ViewRecord,
    /// Every supporting view, in frame order.
    pub views: Vec<ViewRecord>,
}

/// A crack's width as one view measures it; a candidate's is that of its
/// view with the fewest millimetres per pixel that measured it.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct WidthRecord {
    /// Widest (95th percentile along its centre line) and median width,
    /// millimetres; none when the crack is below the view's resolution.
    pub max_mm: Option<f64>,
    pub median_mm: Option<f64>,
    /// How far off `max_mm` may be, millimetres.
    pub uncertainty_mm: Option<f64>,
    /// Below resolution: narrower than this, millimetres.
    pub narrower_than_mm: Option<f64>,
    /// The view's millimetres on the surface per pixel across the crack.
    pub mm_per_px: f64,
}

/// Write `defects.parquet` and `defects.json` (the same candidates; the
/// JSON with every supporting view).
pub fn write_defects(run: &RunDir, defects: &[DefectRecord]) -> Result<(), Error> {
    let rows: Vec<DefectRow> = defects.iter().map(DefectRow::of).collect();
    run.write_rows(files::DEFECTS, &rows)?;
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
    let rows: Vec<DefectRow> = run.read_rows(files::DEFECTS)?;
    rows.into_iter()
        .map(|row| {
            let views = views.remove(&row.id).unwrap_or_default();
            row.record(views)
        })
        .collect::<PolarsResult<_>>()
        .map_err(|cause| Error::Table {
            path: run.file(files::DEFECTS),
            cause,
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
    let rows: Vec<ObservationRow> = observations.iter().map(ObservationRow::of).collect();
    run.write_rows(files::OBSERVATIONS, &rows)
}

/// Read `observations.parquet`.
pub fn read_observations(run: &RunDir) -> Result<Vec<ObservationRecord>, Error> {
    let rows: Vec<ObservationRow> = run.read_rows(files::OBSERVATIONS)?;
    rows.into_iter()
        .map(ObservationRow::record)
        .collect::<PolarsResult<_>>()
        .map_err(|cause| Error::Table {
            path: run.file(files::OBSERVATIONS),
            cause,
        })
}

crate::table! {
    /// One row of `observations.parquet`: a detection, placed or not, with
    /// the reason. The placement's columns are null for one not placed.
    pub struct ObservationRow {
        detection: DetectionCells,
        outcome: Outcome,
        /// The crack's centroid on the surface, world frame, metres.
        x: Option<f64>,
        y: Option<f64>,
        z: Option<f64>,
        /// The surface's unit normal, facing the camera.
        nx: Option<f64>,
        ny: Option<f64>,
        nz: Option<f64>,
        voxel_x: Option<i32>,
        voxel_y: Option<i32>,
        voxel_z: Option<i32>,
        face: Option<FaceSide>,
        range_m: Option<f64>,
        incidence_deg: Option<f64>,
        /// See [`ViewRecord::oblique_gsd_mm`].
        gsd_mm: Option<f64>,
        length_m: Option<f64>,
        radius_m: Option<f64>,
        traced_px: u32,
        clipped: bool,
        /// The candidate it supports.
        defect: Option<String>,
    }
}

impl ObservationRow {
    fn of(o: &ObservationRecord) -> Self {
        let p = o.placed.as_ref();
        let axis = |v: &dyn Fn(&PlacedRecord) -> [f64; 3], a: usize| p.map(|p| v(p)[a]);
        let voxel = |a: usize| p.map(|p| p.voxel.0[a]);
        Self {
            detection: DetectionCells::of(o.frame, o.time_ns, o.bbox, o.score),
            outcome: o.outcome,
            x: axis(&|p| p.centre, 0),
            y: axis(&|p| p.centre, 1),
            z: axis(&|p| p.centre, 2),
            nx: axis(&|p| p.normal, 0),
            ny: axis(&|p| p.normal, 1),
            nz: axis(&|p| p.normal, 2),
            voxel_x: voxel(0),
            voxel_y: voxel(1),
            voxel_z: voxel(2),
            face: p.map(|p| p.face),
            range_m: p.map(|p| p.range_m),
            incidence_deg: p.map(|p| p.incidence_deg),
            gsd_mm: p.map(|p| p.oblique_gsd_mm),
            length_m: p.and_then(|p| p.length_m),
            radius_m: p.map(|p| p.radius_m),
            traced_px: o.traced_px,
            clipped: o.clipped,
            defect: o.defect.clone(),
        }
    }

    fn record(self) -> PolarsResult<ObservationRecord> {
        let placed = match (self.x, self.y, self.z, self.face) {
            (Some(x), Some(y), Some(z), Some(face)) => {
                let frame = self.detection.frame;
                let need = |v: Option<f64>, what: &str| {
                    v.ok_or_else(|| {
                        polars_err!(ComputeError: "a detection of frame {frame} is placed but has no {what}")
                    })
                };
                let voxel = |v: Option<i32>| {
                    v.ok_or_else(|| {
                        polars_err!(ComputeError: "a detection of frame {frame} is placed but has no voxel")
                    })
                };
                Some(PlacedRecord {
                    centre: [x, y, z],
                    normal: [
                        need(self.nx, "normal")?,
                        need(self.ny, "normal")?,
                        need(self.nz, "normal")?,
                    ],
                    voxel: VoxelIndex([
                        voxel(self.voxel_x)?,
                        voxel(self.voxel_y)?,
                        voxel(self.voxel_z)?,
                    ]),
                    face,
                    range_m: need(self.range_m, "range_m")?,
                    incidence_deg: need(self.incidence_deg, "incidence_deg")?,
                    oblique_gsd_mm: need(self.gsd_mm, "gsd_mm")?,
                    length_m: self.length_m,
                    radius_m: need(self.radius_m, "radius_m")?,
                })
            }
            _ => None,
        };
        let d = self.detection;
        Ok(ObservationRecord {
            frame: d.frame,
            time_ns: d.time_ns,
            bbox: d.bbox(),
            score: d.score,
            outcome: self.outcome,
            placed,
            traced_px: self.traced_px,
            clipped: self.clipped,
            defect: self.defect,
        })
    }
}

crate::table! {
    /// One row of `defects.parquet`: a candidate, its best view inline
    /// (`best_*`); the same names in `candidates.csv`, the review's
    /// `accepted-defects` and the fleet's `defects.parquet`.
    pub struct DefectRow {
        id: String,
        /// See [`DefectRecord::element`].
        element: Option<String>,
        place: Option<String>,
        /// World frame, metres.
        x: f64,
        y: f64,
        z: f64,
        /// See [`DefectRecord::position_uncertainty_m`].
        position_uncertainty_m: Option<f64>,
        nx: f64,
        ny: f64,
        nz: f64,
        /// The extent of its views' cracks and its trace on the surface.
        min_x: f64,
        min_y: f64,
        min_z: f64,
        max_x: f64,
        max_y: f64,
        max_z: f64,
        voxel_x: i32,
        voxel_y: i32,
        voxel_z: i32,
        face: FaceSide,
        length_m: Option<f64>,
        length_views: u32,
        /// See [`DefectRecord::trace`]: WKT, `MULTILINESTRING Z`, metres.
        trace: Option<String>,
        frames: u32,
        confidence: f64,
        max_score: f64,
        view_faults: Vec<Miss>,
        view_gsd_mm: f64,
        blur_px: Option<f64>,
        length_status: LengthStatus,
        min_measurable_width_mm: f64,
        reshoot: bool,
        best_frame: u32,
        best_range_m: f64,
        best_incidence_deg: f64,
        /// The best view's oblique GSD.
        best_gsd_mm: f64,
        best_x0: f32,
        best_y0: f32,
        best_x1: f32,
        best_y1: f32,
        /// See [`WidthRecord`]; all null where no view measured across it.
        max_width_mm: Option<f64>,
        median_width_mm: Option<f64>,
        width_uncertainty_mm: Option<f64>,
        narrower_than_mm: Option<f64>,
        width_mm_per_px: Option<f64>,
        /// See [`DefectRecord::condition`].
        condition_state: Option<ConditionState>,
        crop: Option<String>,
    }
}

impl DefectRow {
    /// A candidate as its row.
    pub fn of(d: &DefectRecord) -> Self {
        let [x, y, z] = d.position;
        let [nx, ny, nz] = d.normal;
        let [min_x, min_y, min_z] = d.extent_min;
        let [max_x, max_y, max_z] = d.extent_max;
        let [voxel_x, voxel_y, voxel_z] = d.voxel;
        let [best_x0, best_y0, best_x1, best_y1] = d.best.bbox;
        let e = &d.evidence;
        Self {
            id: d.id.clone(),
            element: d.element.clone(),
            place: d.place.clone(),
            x,
            y,
            z,
            position_uncertainty_m: d.position_uncertainty_m,
            nx,
            ny,
            nz,
            min_x,
            min_y,
            min_z,
            max_x,
            max_y,
            max_z,
            voxel_x,
            voxel_y,
            voxel_z,
            face: d.face,
            length_m: d.length_m,
            length_views: d.length_views,
            trace: d.trace.wkt(),
            frames: d.frames,
            confidence: d.confidence,
            max_score: d.max_score,
            view_faults: e.view_faults.clone(),
            view_gsd_mm: e.view_gsd_mm,
            blur_px: e.blur_px,
            length_status: e.length,
            min_measurable_width_mm: e.min_measurable_width_mm,
            reshoot: e.reshoot,
            best_frame: d.best.frame,
            best_range_m: d.best.range_m,
            best_incidence_deg: d.best.incidence_deg,
            best_gsd_mm: d.best.oblique_gsd_mm,
            best_x0,
            best_y0,
            best_x1,
            best_y1,
            max_width_mm: d.width.and_then(|w| w.max_mm),
            median_width_mm: d.width.and_then(|w| w.median_mm),
            width_uncertainty_mm: d.width.and_then(|w| w.uncertainty_mm),
            narrower_than_mm: d.width.and_then(|w| w.narrower_than_mm),
            width_mm_per_px: d.width.map(|w| w.mm_per_px),
            condition_state: d.condition,
            crop: d.crop.clone(),
        }
    }

    /// The candidate, with its supporting `views` (its best view among them).
    fn record(self, views: Vec<ViewRecord>) -> PolarsResult<DefectRecord> {
        let bbox = [self.best_x0, self.best_y0, self.best_x1, self.best_y1];
        let trace = match &self.trace {
            Some(text) => Trace::from_wkt(text)
                .map_err(|why| polars_err!(ComputeError: "candidate {}'s trace: {why}", self.id))?,
            None => Trace::default(),
        };
        let best = views
            .iter()
            .find(|v| v.frame == self.best_frame && v.bbox == bbox)
            .cloned()
            .ok_or_else(|| {
                polars_err!(ComputeError: "candidate {}'s best view is not among its observations", self.id)
            })?;
        Ok(DefectRecord {
            id: self.id,
            element: self.element,
            place: self.place,
            position: [self.x, self.y, self.z],
            position_uncertainty_m: self.position_uncertainty_m,
            normal: [self.nx, self.ny, self.nz],
            extent_min: [self.min_x, self.min_y, self.min_z],
            extent_max: [self.max_x, self.max_y, self.max_z],
            voxel: [self.voxel_x, self.voxel_y, self.voxel_z],
            face: self.face,
            length_m: self.length_m,
            length_views: self.length_views,
            trace,
            frames: self.frames,
            confidence: self.confidence,
            max_score: self.max_score,
            evidence: Evidence {
                view_faults: self.view_faults,
                view_gsd_mm: self.view_gsd_mm,
                blur_px: self.blur_px,
                length: self.length_status,
                min_measurable_width_mm: self.min_measurable_width_mm,
                reshoot: self.reshoot,
            },
            width: self.width_mm_per_px.map(|mm_per_px| WidthRecord {
                max_mm: self.max_width_mm,
                median_mm: self.median_width_mm,
                uncertainty_mm: self.width_uncertainty_mm,
                narrower_than_mm: self.narrower_than_mm,
                mm_per_px,
            }),
            condition: self.condition_state,
            crop: self.crop,
            best,
            views,
        })
    }
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
                position_uncertainty_m: on.then_some(0.031),
                normal: [-1.0, 0.0, 0.0],
                extent_min: [0.9, 1.8, 2.0],
                extent_max: [1.1, 2.2, 3.0],
                voxel: [2, 4, 6],
                face: FaceSide::NegX,
                length_m: Some(0.42),
                length_views: 1,
                trace: Trace(if on {
                    vec![
                        vec![[1.0, 2.0, 2.3], [1.0, 2.1, 2.7]],
                        vec![[1.0, 2.05, 2.5], [1.0, 1.95, 2.6]],
                    ]
                } else {
                    Vec::new()
                }),
                frames: views.len() as u32,
                confidence: 0.8,
                max_score: 0.53,
                evidence: Evidence {
                    view_faults: if best == 3 {
                        vec![Miss::TooFar, Miss::Blurred]
                    } else {
                        Vec::new()
                    },
                    view_gsd_mm: 3.5,
                    blur_px: (best == 3).then_some(4.5),
                    length: LengthStatus::Measured,
                    min_measurable_width_mm: 7.6,
                    reshoot: best == 3,
                },
                // One measured, one below resolution.
                width: Some(WidthRecord {
                    max_mm: (best == 3).then_some(1.4),
                    median_mm: (best == 3).then_some(0.6),
                    uncertainty_mm: (best == 3).then_some(0.2),
                    narrower_than_mm: (best != 3).then_some(0.3),
                    mm_per_px: 1.1,
                }),
                condition: (best == 3).then_some(ConditionState::Poor),
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

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

use crate::condition::{ConditionState, StateCall};
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
    /// What the flight's widths were read against; none in runs from
    /// before it was written.
    #[serde(default)]
    pub widths: Option<FlightWidths>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// What a flight's crack widths were read against: the interior contrast
/// its resolved cracks show (a crack thinner than the blur is read by its
/// darkness over it, where neither it nor its photo has its own) and the
/// camera's blur.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct FlightWidths {
    /// The share of the surface's brightness a crack's interior lacks: the
    /// median of the flight's resolved cracks' (`flight`), else the
    /// setting's (`setting`).
    pub interior_darkness: f64,
    pub contrast_from: ContrastSource,
    /// Cracks (detections) whose resolved stretches said it.
    pub resolved_cracks: usize,
    /// The camera's blur, one standard deviation, pixels: the opening a
    /// crack's walls mean is read through it.
    pub blur_px: f64,
    /// How far off `blur_px` may be, pixels (one standard deviation).
    pub blur_uncertainty_px: f64,
    /// Where it came from.
    pub blur_from: BlurSource,
    /// Crossings of the flight's cracks it was read from (none for the
    /// setting or unknown).
    pub blur_samples: usize,
}

crate::kind! {
    /// Where a flight's camera blur came from.
    pub enum BlurSource("blur source") {
        /// The flight's lines thinner than the blur: their width at half
        /// depth is the blur's.
        ThinLines = "thin_lines",
        /// The walls of the flight's resolved cracks: each a step the blur
        /// spreads (its edge-spread function, as ISO 12233's slanted edge
        /// reads a lens).
        CrackWalls = "crack_walls",
        /// `[localise] camera_blur_px`, as the camera is declared.
        Setting = "setting",
        /// Nothing says it: a middling blur, uncertain by half, carried in
        /// the widths' uncertainty.
        Unknown = "unknown",
    }
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

crate::table! {
    /// One detection as `observations.parquet` holds it: placed or not,
    /// with the reason; the placement's columns are null for one not
    /// placed.
    pub struct ObservationRecord {
        frame: u32,
        time_ns: i64,
        /// The detection's box, frame pixels.
        bbox: BoxXyxy,
        /// The detector's score.
        score: f32,
        outcome: Outcome,
        /// Where it lies on the structure, for a placed detection.
        placed: Option<PlacedRecord> as ?,
        /// Centre-line pixels traced in the image (0: placed by its box).
        traced_px: u32,
        /// The box or the traced crack touches the image border.
        clipped: bool,
        /// The candidate it supports.
        defect: Option<String>,
    }
}

crate::table! {
    /// A placed detection's crack on the surface.
    #[derive(Copy)]
    pub struct PlacedRecord {
        /// Centroid of the crack on the surface, world frame, metres.
        centre: [f64; 3] as [x, y, z],
        /// Unit normal of the surface, facing the camera.
        normal: [f64; 3] as [nx, ny, nz],
        voxel: VoxelIndex,
        face: FaceSide,
        range_m: f64,
        incidence_deg: f64,
        /// See [`ViewRecord::oblique_gsd_mm`].
        oblique_gsd_mm: f64 as gsd_mm,
        length_m: Option<f64>,
        /// Farthest crack point from the centre, metres.
        radius_m: f64,
    }
}

crate::table! {
    /// One view of a defect candidate. As a group of columns (a
    /// candidate's best view in `defects.parquet`), its frame, geometry
    /// and box; the rest is in `observations.parquet`.
    #[derive(Serialize, Deserialize)]
    pub struct ViewRecord {
        frame: u32,
        range_m: f64,
        incidence_deg: f64,
        /// The view's oblique GSD: the pixel's footprint on the surface along
        /// its most stretched direction, millimetres (`gsd_mm` in the files).
        #[serde(rename = "gsd_mm")]
        oblique_gsd_mm: f64 as gsd_mm,
        /// `[x0, y0, x1, y1]`, frame pixels.
        bbox: [f32; 4] as [x0, y0, x1, y1],
        time_ns: i64 as _,
        score: f32 as _,
        length_m: Option<f64> as _,
        /// The box touches the image border.
        clipped: bool as _,
    }
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

crate::table! {
    /// How far a candidate's evidence can be trusted, and what it lacks.
    #[derive(Serialize, Deserialize)]
    pub struct Evidence {
        /// The View model's rules the best view breaks; empty when it meets them.
        view_faults: Vec<Miss>,
        /// The best view's GSD as the View model measures it (fronto-parallel
        /// at its range), millimetres; see [`ViewRecord::oblique_gsd_mm`] for
        /// the footprint along the surface.
        view_gsd_mm: f64,
        /// The best frame's motion blur, pixels; `None` when its exposure time
        /// is unknown (blur not judged).
        blur_px: Option<f64>,
        length: LengthStatus as length_status,
        /// Narrowest crack width the best view can measure, millimetres: two
        /// of its pixels along the surface. A narrower crack (a hairline at a
        /// few mm/px) shows as a line below a pixel wide, and its width is not
        /// measured from this flight.
        min_measurable_width_mm: f64,
        /// Weak evidence (the best view breaks the View model, or no length):
        /// the spot belongs in the follow-up flight.
        reshoot: bool,
    }
}

impl Evidence {
    /// The narrowest measurable width spans this many pixels.
    pub const MIN_WIDTH_PX: f64 = 2.0;
}

crate::table! {
    /// One defect candidate: a row of `defects.parquet` (its best view
    /// inline, `best_*`; the same columns in `candidates.csv`, the review's
    /// `accepted-defects` and the fleet's `defects.parquet`) and, with
    /// every supporting view, of `defects.json`.
    #[derive(Serialize, Deserialize)]
    pub struct DefectRecord {
        id: String,
        /// The structure element it is on (`pier 2`), as coverage names the
        /// voxels there; none without targets, or off them.
        element: Option<String>,
        /// Where it is: `pier 2, east face, 1.4 m above its base`.
        place: Option<String>,
        /// World frame, metres.
        position: [f64; 3] as [x, y, z],
        /// How far off `position` may be, metres (one standard deviation):
        /// its views' scatter about it over the square root of their number,
        /// and their cameras' position accuracy (a photo's RTK accuracy) in
        /// full, as RTK errors run from photo to photo; none from one view of
        /// a camera whose accuracy is unknown.
        #[serde(default)]
        position_uncertainty_m: Option<f64>,
        normal: [f64; 3] as [nx, ny, nz],
        /// The extent of its views' cracks and its trace on the surface.
        extent_min: [f64; 3] as [min_x, min_y, min_z],
        extent_max: [f64; 3] as [max_x, max_y, max_z],
        voxel: [i32; 3] as [voxel_x, voxel_y, voxel_z],
        face: FaceSide,
        length_m: Option<f64>,
        /// Views its trace (and length) is made of.
        length_views: u32,
        /// Its centre line on the structure, from its views' traces (empty
        /// where no view traced it); `length_m` is its length. WKT in the
        /// tables (`MULTILINESTRING Z`, metres).
        #[serde(default)]
        trace: Trace,
        frames: u32,
        confidence: f64,
        max_score: f64,
        evidence: Evidence,
        best: ViewRecord as "best_",
        /// Its width, where a view could measure across its centre line.
        #[serde(default)]
        width: Option<WidthRecord> as ?,
        /// The condition state its width puts its length in (`[condition]`'s
        /// limits), and how sure that is; none where the width is unknown or
        /// its bound straddles a limit.
        #[serde(flatten)]
        condition: Option<StateCall> as ?,
        /// JPEG of the best view, relative to the run directory (none when its
        /// image could not be decoded).
        crop: Option<String>,
        /// Every supporting view, in frame order (in the tables, the
        /// placed rows of `observations.parquet` that name it).
        views: Vec<ViewRecord> as _,
    }
}

crate::table! {
    /// A crack's width as one view measures it; a candidate's is that of its
    /// view with the fewest millimetres per pixel that measured it. Its
    /// columns are null where no view measured across the crack.
    #[derive(Copy, Default, Serialize, Deserialize)]
    pub struct WidthRecord {
        /// Its widest stretch's width (see [`WidestStretch`]; the median
        /// where no stretch is surely wider) and its median width,
        /// millimetres; none when the crack is below the view's resolution.
        max_mm: Option<f64> as max_width_mm,
        median_mm: Option<f64> as median_width_mm,
        /// How far off `max_mm` may be, millimetres (one standard
        /// deviation): the pixel grid's share, the walls' slope, the
        /// contrast a darkness width divides by, and the scatter of the
        /// points it is the median of.
        uncertainty_mm: Option<f64> as width_uncertainty_mm,
        /// Below resolution: narrower than this, millimetres.
        narrower_than_mm: Option<f64>,
        /// The view's millimetres on the surface per pixel across the crack.
        mm_per_px: f64 as width_mm_per_px,
        /// How the widest stretch was read: across its walls, from its
        /// darkness, or both (none below resolution).
        #[serde(default)]
        method: Option<WidthMethod> as width_method,
        /// Where the contrast its darkness was divided by came from (none
        /// where its walls alone measured it).
        #[serde(default)]
        contrast_from: Option<ContrastSource> as width_contrast_from,
        /// That contrast: the share of the surface's brightness a crack's
        /// interior lacks.
        #[serde(default)]
        interior_darkness: Option<f64> as width_interior_darkness,
        /// How well the crossings its widest stretch was read from fit a
        /// slot blurred by the camera (none below resolution).
        #[serde(default)]
        fit: Option<WidthFit> as width_fit,
        /// Where its widest stretch is; none where no stretch is surely
        /// wider than the crack's median (it is as wide along its length).
        #[serde(default)]
        widest: Option<WidestStretch> as ?,
    }
}

crate::table! {
    /// Where along a crack its widest stretch is: the stretch an inspector
    /// would put a gauge on.
    #[derive(Copy, Serialize, Deserialize)]
    pub struct WidestStretch {
        /// Its middle, world frame, metres.
        at: [f64; 3] as [widest_x, widest_y, widest_z],
        /// How far along the candidate's trace it is from the trace's first
        /// point, metres (none on a view's own width, or without a trace).
        #[serde(default)]
        along_m: Option<f64> as widest_along_m,
    }
}

crate::kind! {
    /// How a crack's width was read across it.
    pub enum WidthMethod("width method") {
        /// Across its walls: the opening of the blurred slot whose walls
        /// stand where its grey levels, walking in from either side, first
        /// reach half its depth: a crack several blurs wide.
        Walls = "walls",
        /// From its darkness: the light it takes away, summed across it,
        /// over the contrast between the surface and a crack's interior: a
        /// crack thinner than the blur, which never shows its interior's
        /// darkness.
        Darkness = "darkness",
        /// Both, each weighed by how far the crack resolves: a crack about
        /// as wide as the blur.
        WallsAndDarkness = "walls_and_darkness",
    }
}

crate::kind! {
    /// How well a crack's crossings fit the model its width is read by: a
    /// slot of its interior's darkness, as wide as its opening, blurred by
    /// the camera.
    pub enum WidthFit("width fit") {
        /// They fit it.
        Slot = "slot",
        /// Their walls spread wider than the blur explains: walls that slope
        /// (a V or U section) or darkened shoulders beside them; the opening
        /// may be wider than its walls at half depth, and the uncertainty
        /// says by how much.
        SlopingWalls = "sloping_walls",
        /// About as wide as the blur, their walls and their darkness read
        /// different widths beyond their uncertainties (a lighter interior,
        /// a second line, a stain beside it); the uncertainty covers both.
        WallsAndDarknessDisagree = "walls_and_darkness_disagree",
    }
}

crate::kind! {
    /// Where the contrast a darkness width divides by came from: cracks
    /// that resolve (wide enough to show a flat, dark interior), nearest
    /// first.
    pub enum ContrastSource("contrast source") {
        /// The crack's own resolved stretches.
        Crack = "crack",
        /// Other cracks of the same photo.
        Photo = "photo",
        /// The flight's cracks.
        Flight = "flight",
        /// None resolved: `[localise] crack_darkness`.
        Setting = "setting",
    }
}

impl DefectRecord {
    /// The condition state its width puts it in, if any.
    pub fn state(&self) -> Option<ConditionState> {
        self.condition.map(|c| c.state)
    }
}

/// Write `defects.parquet` and `defects.json` (the same candidates; the
/// JSON with every supporting view).
pub fn write_defects(run: &RunDir, defects: &[DefectRecord]) -> Result<(), Error> {
    run.write_rows(files::DEFECTS, defects)?;
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
    let defects: Vec<DefectRecord> = run.read_rows(files::DEFECTS)?;
    defects
        .into_iter()
        .map(|defect| {
            let views = views.remove(&defect.id).unwrap_or_default();
            defect.with_views(views)
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
    run.write_rows(files::OBSERVATIONS, observations)
}

/// Read `observations.parquet`.
pub fn read_observations(run: &RunDir) -> Result<Vec<ObservationRecord>, Error> {
    run.read_rows(files::OBSERVATIONS)
}

impl DefectRecord {
    /// The candidate as its table row reads, with its supporting `views`
    /// (its best view among them).
    fn with_views(self, views: Vec<ViewRecord>) -> PolarsResult<Self> {
        let best = views
            .iter()
            .find(|v| v.frame == self.best.frame && v.bbox == self.best.bbox)
            .cloned()
            .ok_or_else(|| {
                polars_err!(ComputeError: "candidate {}'s best view is not among its observations", self.id)
            })?;
        Ok(Self {
            best,
            views,
            ..self
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::Row;

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
                // One measured, its widest stretch at a place along it and
                // its state unsure, one below resolution.
                width: Some(WidthRecord {
                    max_mm: (best == 3).then_some(1.4),
                    median_mm: (best == 3).then_some(0.6),
                    uncertainty_mm: (best == 3).then_some(0.2),
                    narrower_than_mm: (best != 3).then_some(0.3),
                    mm_per_px: 1.1,
                    method: (best == 3).then_some(WidthMethod::WallsAndDarkness),
                    contrast_from: (best == 3).then_some(ContrastSource::Flight),
                    interior_darkness: (best == 3).then_some(0.9),
                    fit: (best == 3).then_some(WidthFit::SlopingWalls),
                    widest: (best == 3).then_some(WidestStretch {
                        at: [1.0, 2.05, 2.45],
                        along_m: Some(0.2),
                    }),
                }),
                condition: Some(if best == 3 {
                    StateCall {
                        state: ConditionState::Poor,
                        probability: 0.66,
                        other: Some(ConditionState::Fair),
                        other_probability: Some(0.34),
                    }
                } else {
                    StateCall {
                        state: ConditionState::Good,
                        probability: 1.0,
                        other: None,
                        other_probability: None,
                    }
                }),
                crop: Some(format!("defects/{id}.jpg")),
                best: views.iter().find(|v| v.frame == best).unwrap().clone(),
                views,
            }
        };
        let defects = vec![defect("2_4_6-x", &[1, 3], 3), defect("9_9_9+z", &[4], 4)];
        write_defects(&run, &defects).unwrap();
        assert_eq!(read_defects(&run).unwrap(), defects);
        assert_eq!(read_defects_table(&run).unwrap(), defects);
        // The state and how sure it is are columns of their own, and keys
        // of the candidate in the JSON, as the state always was.
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(run.file(files::DEFECTS_JSON)).unwrap()).unwrap();
        let first = &json["defects"][0];
        assert_eq!(
            (
                &first["condition"],
                &first["condition_probability"],
                &first["other_condition"]
            ),
            (
                &serde_json::json!("poor"),
                &serde_json::json!(0.66),
                &serde_json::json!("fair")
            )
        );
        let table = DefectRecord::frame(&defects).unwrap();
        for column in [
            "condition_state",
            "condition_probability",
            "other_condition_state",
            "other_condition_probability",
            "width_method",
            "width_contrast_from",
            "widest_x",
            "widest_along_m",
        ] {
            assert!(table.column(column).is_ok(), "{column}");
        }
    }
}

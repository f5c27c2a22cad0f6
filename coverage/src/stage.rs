//! The coverage stage: `postflight coverage --run RUN_DIR`. Judges every
//! exposed face of the target voxels against every usable frame of the
//! flight (and against the plan's viewpoints, for what was planned), and
//! writes `coverage.parquet` (one row per target voxel) and `coverage.json`.

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::time::Instant;

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::map::{SlamMap, VoxelGrid, VoxelIndex};
use postflight_core::outputs::coverage::{
    self as outputs, CoverageSummary, FocusCoverage, VoxelRecord, files,
};
use postflight_core::outputs::localise::read_defects;
use postflight_core::region::FocusModel;
use postflight_core::structure::Place;
use postflight_core::{Flight, FlownPlan, Intrinsics, PlanFile, RunDir, Stage, ViewModel};
use rayon::prelude::*;
pub use targets::plan_targets;
use targets::source::span;
use targets::{Found, Segmentation, TargetVoxels, Targets};

use crate::cover::{FaceCover, Shot};
use crate::error::CoverageError;
use crate::face::{Face, exposed_faces};
use crate::focus::{self, FaceModels};
use crate::reach::inspectable;
use crate::records::voxel_records;
use crate::settings::CoverageConfig;
use crate::shots::{FlightShots, camera_mount, flight_shots, lenses, viewpoint_shots};
use crate::summary::{Counts, summarise};
use crate::view::Miss;
use postflight_core::ViewSettings;

/// What coverage judges and how. Serialised, it is what the stage's
/// result depends on besides its input files (`postflight run`'s
/// fingerprint): the settings and how the plan's yaws read, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CoverageOptions {
    #[serde(skip)]
    pub run: PathBuf,
    /// The plan that was flown: its viewpoints (what was planned), and for
    /// a `plan.json` its targets, grid and View model.
    pub plan: Option<PlanFile>,
    /// Judge this plan's viewpoints instead of the flight's frames.
    pub viewpoints: Option<PlanFile>,
    /// The viewpoints' camera (a calibration file) instead of the flight's.
    pub viewpoint_camera: Option<PathBuf>,
    #[serde(skip)]
    pub map: Option<PathBuf>,
    pub targets: Targets,
    /// View model settings over the plan's (unset: the plan's, else defaults).
    pub view: ViewSettings,
    pub settings: CoverageConfig,
}

impl CoverageOptions {
    /// Coverage of `run` against the plan's targets, with the default settings.
    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            plan: None,
            viewpoints: None,
            viewpoint_camera: None,
            map: None,
            targets: Targets::Plan,
            view: ViewSettings::default(),
            settings: CoverageConfig::default(),
        }
    }
}

/// Faces per progress step.
const CHUNK: usize = 4096;
/// Judge the flight (or a plan's viewpoints) against the targets.
pub fn coverage(
    options: &CoverageOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<CoverageSummary, CoverageError> {
    let start = Instant::now();
    let flight = Flight::load(&options.run)?;
    let (table_name, summary_name) = if options.viewpoints.is_some() {
        (files::VIEWPOINTS_TABLE, files::VIEWPOINTS_SUMMARY)
    } else {
        (files::TABLE, files::SUMMARY)
    };
    // A failed rerun must not leave the last run's results looking current.
    flight.run.remove(summary_name)?;
    let plan = options.plan.as_ref().map(PlanFile::load).transpose()?;
    let view = options
        .view
        .apply(plan.as_ref().and_then(FlownPlan::view).unwrap_or_default());
    view.check()?;
    let focus = FocusModel::of(&options.settings.focus, view);
    focus::check(&focus)?;
    let scene = Scene::load(options, &flight, plan.as_ref())?;
    let models = FaceModels::new(view, &focus, &scene.faces, &scene.grid);
    let extrinsic = camera_mount(&flight);
    let shots = shots(options, &flight, &scene, &extrinsic)?;
    let need = views_needed(&scene.faces, &models, &options.settings, &flight.run)?;
    let plan_shots: Option<Vec<Shot>> = plan.as_ref().map(|p| viewpoint_shots(p, &extrinsic));
    let judged = judge(
        &scene,
        &need,
        &shots.shots,
        plan_shots.as_deref(),
        &models,
        progress,
    );
    cameras_in_reach(&scene, &shots.shots, &judged.flown, &view)?;
    let records = voxel_records(
        &scene.grid,
        &scene.targets,
        &scene.places,
        &scene.faces,
        &need,
        &judged.flown,
        &judged.planned,
        &judged.reachable,
        plan_shots.is_some(),
    );
    let counts = Counts::of(&records, &judged.flown, plan_shots.is_some());
    let seconds = start.elapsed().as_secs_f64();
    let mut summary = summarise(options, view, &scene, counts, &shots, &need, seconds);
    summary.focus = focus_coverage(focus, &records);
    outputs::write_coverage(&flight.run, table_name, &records, scene.grid.resolution)?;
    flight.run.write_json(summary_name, &summary)?;
    Ok(summary)
}

/// What is judged: the map, the target voxels and their exposed faces, and
/// the flight's lenses.
pub(crate) struct Scene {
    pub(crate) grid: VoxelGrid,
    pub(crate) map: SlamMap,
    pub(crate) targets: Vec<VoxelIndex>,
    pub(crate) target_set: HashSet<VoxelIndex>,
    /// Where the targets came from, for the summary.
    pub(crate) targets_name: String,
    /// The targets grouped into the structure's elements.
    pub(crate) elements: Segmentation,
    /// Each target's place on them.
    pub(crate) places: Vec<Place>,
    pub(crate) faces: Vec<Face>,
    pub(crate) lenses: Vec<Intrinsics>,
}

impl Scene {
    fn load(
        options: &CoverageOptions,
        flight: &Flight,
        plan: Option<&FlownPlan>,
    ) -> Result<Self, CoverageError> {
        let grid = plan.and_then(FlownPlan::grid);
        let (map, _) = ingest::load_map(flight, options.map.as_deref(), grid)?;
        let grid = map.voxels.grid;
        let Found {
            targets:
                TargetVoxels {
                    voxels: targets,
                    name: targets_name,
                    ..
                },
            elements,
        } = Found::find(&options.targets, plan, &map)?;
        let target_set: HashSet<VoxelIndex> = targets.iter().copied().collect();
        let faces = exposed_faces(&grid, &targets, &target_set);
        let places = places(&grid, &targets, &faces, &elements);
        Ok(Self {
            grid,
            map,
            targets,
            target_set,
            targets_name,
            elements,
            places,
            faces,
            lenses: match (&options.viewpoints, &options.viewpoint_camera) {
                (Some(_), Some(camera)) => {
                    vec![ingest::calibration::from_calibration_file(
                        camera,
                        &"--viewpoint-camera",
                    )?]
                }
                _ => lenses(flight)?,
            },
        })
    }
}

/// The shots: the flight's frames, or the viewpoints of a plan to check.
fn shots(
    options: &CoverageOptions,
    flight: &Flight,
    scene: &Scene,
    extrinsic: &Isometry3<f64>,
) -> Result<FlightShots, CoverageError> {
    match &options.viewpoints {
        Some(file) => Ok(FlightShots {
            shots: viewpoint_shots(&file.load()?, extrinsic),
            without_pose: 0,
            without_exposure: 0,
        }),
        None => {
            let shots = flight_shots(
                flight,
                &scene.lenses,
                &scene.map,
                options.settings.exposure_s,
            );
            if shots.shots.is_empty() {
                return Err(CoverageError::NoPoses);
            }
            Ok(shots)
        }
    }
}

/// Fail when every shot is farther from every face than the View model
/// allows: the flight and the targets are in different frames, most likely.
fn cameras_in_reach(
    scene: &Scene,
    shots: &[Shot],
    flown: &[FaceCover],
    view: &ViewModel,
) -> Result<(), CoverageError> {
    if shots.is_empty() || !flown.iter().all(|c| c.miss == Some(Miss::TooFar)) {
        return Ok(());
    }
    Err(CoverageError::CamerasTooFar {
        max_distance_m: view.max_distance_m,
        cameras: span(
            shots
                .iter()
                .map(|s| Point3::from(s.camera.translation.vector)),
        ),
        targets: span(scene.targets.iter().map(|v| scene.grid.center(*v))),
    })
}

/// Views each face needs: its View model's, and more around defect
/// candidates, if asked.
fn views_needed(
    faces: &[Face],
    models: &FaceModels,
    settings: &CoverageConfig,
    run: &RunDir,
) -> Result<Vec<u32>, CoverageError> {
    let defects: Vec<Point3<f64>> = match settings.views_near_defects {
        Some(_) => {
            run.require(Stage::Localise)
                .map_err(|_| CoverageError::NoDefects)?;
            read_defects(run)?
                .iter()
                .map(|d| Point3::from(d.position))
                .collect()
        }
        None => Vec::new(),
    };
    let radius = settings.defect_radius_m;
    Ok(faces
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let own = models.of(i).views_required;
            match settings.views_near_defects {
                Some(n) if defects.iter().any(|d| (d - f.centre).norm() <= radius) => n.max(own),
                _ => own,
            }
            .max(1)
        })
        .collect())
}

/// Every face judged against the flight's shots (and the plan's, for
/// what was planned), with whether a free standpoint could inspect it.
struct Judged {
    flown: Vec<FaceCover>,
    /// Empty without a plan.
    planned: Vec<FaceCover>,
    reachable: Vec<bool>,
}

#[allow(clippy::too_many_arguments)]
fn judge(
    scene: &Scene,
    need: &[u32],
    shots: &[Shot],
    plan_shots: Option<&[Shot]>,
    models: &FaceModels,
    progress: &mut dyn FnMut(u64, u64),
) -> Judged {
    let Scene {
        faces, lenses, map, ..
    } = scene;
    let total = faces.len() as u64;
    progress(0, total);
    let mut judged = Judged {
        flown: Vec::with_capacity(faces.len()),
        planned: Vec::new(),
        reachable: Vec::with_capacity(faces.len()),
    };
    let max_gsd_distance =
        |view: &ViewModel| view.max_gsd_mm / 1000.0 * lenses[0].fx.min(lenses[0].fy);
    for (start, (chunk, need)) in (0..)
        .step_by(CHUNK)
        .zip(faces.chunks(CHUNK).zip(need.chunks(CHUNK)))
    {
        let range = start..start + chunk.len();
        let got = models.cover(range.clone(), chunk, need, shots, lenses, map);
        judged.reachable.extend(
            chunk
                .par_iter()
                .zip(range.clone())
                .zip(&got)
                .map(|((f, i), c)| {
                    let view = models.of(i);
                    c.miss.is_none() || inspectable(f, map, view, max_gsd_distance(view))
                })
                .collect::<Vec<bool>>(),
        );
        judged.flown.extend(got);
        if let Some(ps) = plan_shots {
            judged
                .planned
                .extend(models.cover(range, chunk, need, ps, lenses, map));
        }
        progress(judged.flown.len() as u64, total);
    }
    judged
}

/// Each focus region with its target voxels and how many were inspected
/// (under its View model).
fn focus_coverage(focus: Vec<FocusModel>, records: &[VoxelRecord]) -> Vec<FocusCoverage> {
    let mut counts = vec![(0, 0); focus.len()];
    for r in records {
        if let Some(k) = FocusModel::holding(&focus, &Point3::from(r.centre)) {
            counts[k].0 += 1;
            counts[k].1 += usize::from(r.inspected);
        }
    }
    focus
        .into_iter()
        .zip(counts)
        .map(|(model, (target_voxels, inspected_voxels))| FocusCoverage {
            model,
            target_voxels,
            inspected_voxels,
        })
        .collect()
}

/// Each target's place on its element, facing the way its exposed faces
/// do together (up when they cancel out).
fn places(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    faces: &[Face],
    elements: &Segmentation,
) -> Vec<Place> {
    let mut facing: HashMap<VoxelIndex, Vector3<f64>> = HashMap::new();
    for f in faces {
        *facing.entry(f.voxel).or_insert_with(Vector3::zeros) += f.normal;
    }
    targets
        .iter()
        .zip(&elements.element_of)
        .map(|(v, &e)| {
            let normal = facing
                .get(v)
                .filter(|n| n.norm() > 1e-9)
                .copied()
                .unwrap_or_else(Vector3::z);
            elements.structure.place(e, &grid.center(*v), &normal)
        })
        .collect()
}

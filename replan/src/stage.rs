//! The replan stage, `postflight replan --run RUN_DIR`: the gaps of the
//! coverage stage to a follow-up flight, phase by phase (see the crate
//! docs), into `replan.json` and `replan.csv`.

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use coverage::face::exposed_faces;
use coverage::focus::FaceModels;
use coverage::stage::camera_mount;
use gtsp::SolveOptions;
use nalgebra::{Point3, Vector3};
use postflight_core::geo::GeoOrigin;
use postflight_core::map::{SlamMap, VoxelGrid, VoxelIndex};
use postflight_core::outputs::coverage::{self as coverage_outputs, CoverageSummary};
use postflight_core::outputs::localise::{self as localise_outputs, read_defects};
use postflight_core::outputs::replan::{
    DronePlan, GapChoice, ReplanSummary, ReshootSpot, Sortie, Uninspectable, Unplannable, Waypoint,
    files,
};
use postflight_core::region::FocusModel;
use postflight_core::{Flight, InvalidSetting, Key, RunDir, Stage, Viewpoint};

use crate::airspace::{Airspace, read_zones};
use crate::error::ReplanError;
use crate::free_space::{FreeSpace, length};
use crate::ground_station::{self, Placement};
use crate::settings::{ReplanConfig, keys};
use crate::tour::{Budget, Stops, Tour, TourError, plan_tour};
use crate::viewpoints::{
    Camera, Candidate, Clusters, candidates, clusters, one_face_for_several_views, set_cover,
};

/// What replan plans for and how. Serialised, it is what the stage's
/// result depends on besides its input files (`postflight run`'s
/// fingerprint): the settings, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ReplanOptions {
    #[serde(skip)]
    pub run: PathBuf,
    /// Map instead of the one coverage used.
    #[serde(skip)]
    pub map: Option<PathBuf>,
    pub settings: ReplanConfig,
}

impl ReplanOptions {
    /// Replan `run` with the default settings.
    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            map: None,
            settings: ReplanConfig::default(),
        }
    }

    /// What one battery allows a sortie.
    fn budget(&self) -> Budget {
        let s = &self.settings;
        Budget {
            max_length_m: s.max_sortie_length_m.unwrap_or(f64::INFINITY),
            max_time_s: s.battery_minutes * 60.0,
            speed_m_s: s.speed_m_s,
            hover_s: s.hover_s,
        }
    }

    /// The GTSP solver's settings; refused unless the time limit is a
    /// positive number of seconds.
    fn solver(&self) -> Result<SolveOptions, InvalidSetting> {
        let seconds = self.settings.solver_time_limit_s;
        InvalidSetting::check(
            seconds.is_finite() && seconds > 0.0,
            keys::solver_time_limit_s,
            seconds,
            "a positive number of seconds",
        )?;
        Ok(SolveOptions {
            time_limit: Some(Duration::from_secs_f64(seconds)),
            seed: self.settings.seed,
            ..SolveOptions::default()
        })
    }

    /// Refuse settings that cannot work.
    fn check(&self) -> Result<(), InvalidSetting> {
        let s = &self.settings;
        let at_least_0 = |key: Key, v: f64| InvalidSetting::check(v >= 0.0, key, v, "0 or more");
        at_least_0(keys::clearance_m, s.clearance_m)?;
        at_least_0(keys::hover_s, s.hover_s)?;
        InvalidSetting::check(s.drones >= 1, keys::drones, s.drones, "1 or more drones")?;
        InvalidSetting::check(
            s.battery_minutes.is_finite() && s.battery_minutes > 0.0,
            keys::battery_minutes,
            s.battery_minutes,
            "a positive number of minutes",
        )?;
        InvalidSetting::check(
            s.speed_m_s > 0.0,
            keys::speed_m_s,
            s.speed_m_s,
            "a positive number of metres per second",
        )?;
        if let Some(m) = s.max_sortie_length_m {
            InvalidSetting::check(
                m > 0.0,
                keys::max_sortie_length_m,
                m,
                "a positive number of metres",
            )?;
        }
        if let Some(o) = &s.geo_origin {
            InvalidSetting::check(
                o.check().is_ok(),
                keys::geo_origin,
                format!("{}, {}", o.position.latitude_deg, o.position.longitude_deg),
                "a latitude within ±90 and a longitude within ±180 degrees, all finite",
            )?;
        }
        if let Some(c) = s.ceiling_m {
            InvalidSetting::check(
                c > 0.0,
                keys::ceiling_m,
                c,
                "a positive number of metres above the take-off point",
            )?;
        }
        self.solver().map(|_| ())
    }
}

/// Plan the follow-up flight for the run's coverage gaps.
pub fn replan(
    options: &ReplanOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ReplanSummary, ReplanError> {
    let started = Instant::now();
    options.check()?;
    let flight = Flight::load(&options.run)?;
    let run = RunDir::open(&options.run, Stage::Coverage)?;
    run.remove(files::SUMMARY)?;
    let coverage: CoverageSummary = run.read_json(Stage::Coverage.summary_file())?;
    coverage.view.check()?;
    let grid = VoxelGrid::new(coverage.resolution_m, Point3::from(coverage.grid_origin));
    let chosen = choose_gaps(&run, options.settings.gaps)?;
    let (targets, gaps) = (&chosen.targets, &chosen.voxels);
    let launch = take_off(options, &flight)?;
    let mut summary = empty_plan(options, &coverage, launch, &chosen);
    (summary.geo_origin, summary.geo_origin_from) = geo_origin(options, &flight);
    let airspace = airspace(options, summary.geo_origin.as_ref(), launch)?;
    summary.keep_out = airspace.zones().to_vec();
    summary.ceiling_z_m = airspace.ceiling_z();
    let placement = summary.geo_origin.map(|origin| Placement {
        origin,
        launch,
        hover_s: options.settings.hover_s,
        speed_m_s: options.settings.speed_m_s,
        min_takeoff_m: options.settings.clearance_m,
        fence: airspace
            .zones()
            .iter()
            .filter(|z| z.is_column())
            .cloned()
            .collect(),
    });
    if placement.is_some() {
        summary.warnings.extend(unfenced(&airspace));
    }
    if gaps.is_empty() {
        return write(&run, summary, placement.as_ref(), started);
    }

    let given = options.map.as_ref().or(coverage.map.as_ref());
    let (map, _) = ingest::load_map(&flight, given.map(PathBuf::as_path), Some(grid))?;
    summary.frame_id = map.cloud.frame_id.clone();
    let phase = Instant::now();
    let space = FreeSpace::new(
        &map.voxels,
        options.settings.clearance_m,
        &[launch],
        airspace,
    );
    let home = clear_home(&space, &map, launch, &mut summary)?;
    summary.phases.clearance_s = phase.elapsed().as_secs_f64();

    let phase = Instant::now();
    let mut found = viewpoints(&flight, &coverage, &map, &space, targets, gaps, progress)?;
    one_face_for_several_views(&mut found, &chosen.views);
    summary.candidate_viewpoints = found.len();
    // One viewpoint serves every gap it inspects: the clusters hold only a
    // greedy set cover's viewpoints, so the tour needs no more of them.
    let cover = set_cover(&found, &chosen.views);
    summary.set_cover_viewpoints = cover.len();
    let mut clusters = clusters(gaps, &found, &cover, &chosen.views, |v| grid.center(v));
    summary.phases.viewpoints_s = phase.elapsed().as_secs_f64();
    // Stops: home, then the candidates.
    let points: Vec<Point3<f64>> = std::iter::once(home)
        .chain(found.iter().map(|c| Point3::from(c.viewpoint.position)))
        .collect();
    // One search from home: which candidates a path reaches, and how far
    // home is from each stop when sorties are split.
    let from_home = space.distances_from(&home);
    let Solved { tour, left_out } = solve(
        &points,
        &mut clusters,
        &space,
        &from_home,
        &options.solver()?,
    );
    summary.uninspectable_gaps = left_out
        .iter()
        .map(|(&g, &reason)| Uninspectable {
            voxel: gaps[g],
            reason,
        })
        .collect();
    let Some((tour, served)) = tour else {
        summary
            .warnings
            .push("no gap voxel can be inspected from a clear, reachable viewpoint".into());
        return write(&run, summary, placement.as_ref(), started);
    };

    summary.phases.solve_s = tour.stats.solve_seconds - tour.stats.paths_seconds;
    summary.phases.rounds = tour.stats.rounds;
    let phase = Instant::now();
    let drones = split_sorties(options, &tour, &points, &space, &map, &from_home)?;
    let waypoint = |i: usize| {
        let v = &found[tour.stops[i] - 1].viewpoint;
        let mut gap_voxels: Vec<VoxelIndex> = tour.serves[i]
            .iter()
            .map(|&k| gaps[clusters.gap[served[k]]])
            .collect();
        gap_voxels.sort_unstable();
        Waypoint {
            x: v.position[0],
            y: v.position[1],
            z: v.position[2],
            yaw: v.yaw,
            gimbal_pitch: v.gimbal_pitch,
            gap_voxels,
        }
    };
    for (drone, sorties) in (0u32..).zip(&drones) {
        for indices in sorties {
            let mut sortie = fly(options, &tour, &points, &space, indices, &waypoint);
            sortie.drone = drone;
            summary.sorties.push(sortie);
        }
    }
    summary.phases.paths_s = tour.stats.paths_seconds + phase.elapsed().as_secs_f64();
    summarise(&mut summary, tour);
    write(&run, summary, placement.as_ref(), started)
}

/// The map frame on the Earth: as set, else from the flight's GPS fixes;
/// and which it is.
fn geo_origin(options: &ReplanOptions, flight: &Flight) -> (Option<GeoOrigin>, Option<String>) {
    if let Some(origin) = options.settings.geo_origin {
        return (Some(origin), Some("settings".into()));
    }
    match &flight.summary.geo_origin {
        Some(fit) => (
            Some(fit.origin),
            Some(format!(
                "{} GPS fixes aligned to the trajectory, {:.2} m rms over {:.0} m",
                fit.fixes, fit.rms_m, fit.spread_m
            )),
        ),
        None => (None, None),
    }
}

/// The keep-out zones of the settings and the zones file (placed by the
/// geo origin), and the ceiling above the take-off point; refused when a
/// zone cannot be used or holds the take-off point.
fn airspace(
    options: &ReplanOptions,
    origin: Option<&GeoOrigin>,
    launch: Point3<f64>,
) -> Result<Airspace, ReplanError> {
    let s = &options.settings;
    let mut zones = Vec::new();
    for zone in &s.keep_out {
        zone.check(keys::keep_out)?;
        zones.push(zone.clone());
    }
    if let Some(path) = &s.keep_out_file {
        let origin =
            origin.ok_or_else(|| ReplanError::KeepOutWithoutGeoOrigin { path: path.clone() })?;
        let from_file =
            read_zones(path, origin, &launch).map_err(|why| ReplanError::KeepOutFile {
                path: path.clone(),
                why,
            })?;
        for zone in from_file {
            zone.check(keys::keep_out_file)?;
            zones.push(zone);
        }
    }
    let airspace = Airspace::new(zones, s.ceiling_m.map(|c| launch.z + c));
    if let Some(zone) = airspace.zone_at(&launch) {
        return Err(ReplanError::HomeInKeepOut {
            home: launch.coords.into(),
            zone: zone.name.clone(),
        });
    }
    Ok(airspace)
}

/// What the ground station's geofence cannot hold: a zone with heights
/// (fences are polygons at every altitude; writing it as one would bar the
/// flight from passing over or under it), and the ceiling (the vehicle's
/// own setting, PX4's `GF_MAX_VER_DIST` or ArduPilot's `FENCE_ALT_MAX`).
fn unfenced(airspace: &Airspace) -> Vec<String> {
    let mut warnings: Vec<String> = airspace
        .zones()
        .iter()
        .filter(|z| !z.is_column())
        .map(|z| {
            format!(
                "keep-out zone '{}' has an altitude band, which a QGroundControl geofence (polygons at every altitude) cannot hold: the plan keeps out of it, the missions' geofence does not",
                z.name
            )
        })
        .collect();
    if let Some(z) = airspace.ceiling_z() {
        warnings.push(format!(
            "the ceiling (map z {z:.1} m) is kept by the plan; set it on the vehicle too (PX4 GF_MAX_VER_DIST, ArduPilot FENCE_ALT_MAX): a QGroundControl plan file cannot hold it"
        ));
    }
    warnings
}

/// The voxels a follow-up flight goes back for.
struct ChosenGaps {
    /// Every target voxel (from `coverage.parquet`).
    targets: Vec<VoxelIndex>,
    /// Gap voxels coverage found (not inspected, not uninspectable).
    coverage_gaps: usize,
    /// The chosen gaps and the re-shoot spots' voxels, sorted, once each.
    voxels: Vec<VoxelIndex>,
    /// The views each of them needs (coverage's `views_required`: its View
    /// model's, or its focus region's, or more near a defect).
    views: Vec<u32>,
    reshoot: Vec<ReshootSpot>,
}

/// The gaps `choice` asks for, from `coverage.parquet`, with the voxels of
/// the candidates `defects.json` flags for a re-shoot.
fn choose_gaps(run: &RunDir, choice: GapChoice) -> Result<ChosenGaps, ReplanError> {
    let records = coverage_outputs::read_coverage(run, coverage_outputs::files::TABLE)?;
    let targets: Vec<VoxelIndex> = records.iter().map(|r| r.voxel).collect();
    let gaps = || records.iter().filter(|r| !r.inspected && !r.uninspectable);
    let coverage_gaps = gaps().count();
    let mut voxels: Vec<VoxelIndex> = match choice {
        // Without a plan nothing says what was planned: every gap was missed.
        GapChoice::Missed => gaps()
            .filter(|r| r.planned.unwrap_or(true))
            .map(|r| r.voxel)
            .collect(),
        GapChoice::All => gaps().map(|r| r.voxel).collect(),
        GapChoice::Reshoot => Vec::new(),
    };
    let reshoot: Vec<ReshootSpot> = if run.file(localise_outputs::files::DEFECTS_JSON).exists() {
        read_defects(run)?
            .into_iter()
            .filter(|d| d.evidence.reshoot)
            .map(|d| ReshootSpot {
                defect: d.id,
                voxel: VoxelIndex(d.voxel),
            })
            .collect()
    } else {
        Vec::new()
    };
    voxels.extend(reshoot.iter().map(|r| r.voxel));
    voxels.sort_unstable();
    voxels.dedup();
    let required: HashMap<VoxelIndex, u32> = records
        .iter()
        .map(|r| (r.voxel, r.views_required))
        .collect();
    let views = voxels
        .iter()
        .map(|v| required.get(v).copied().unwrap_or(1).max(1))
        .collect();
    Ok(ChosenGaps {
        targets,
        coverage_gaps,
        voxels,
        views,
        reshoot,
    })
}

/// Home: as given, else where the flight (its first recording) took off.
fn take_off(options: &ReplanOptions, flight: &Flight) -> Result<Point3<f64>, ReplanError> {
    match options.settings.home {
        Some(h) => Ok(Point3::from(h)),
        None => flight
            .trajectories
            .first()
            .map(|t| t.poses())
            .unwrap_or_default()
            .first()
            .map(|p| Point3::from(p.pose.translation.vector))
            .ok_or(ReplanError::NoTakeOff),
    }
}

/// The plan before anything is planned: the settings and the gaps.
fn empty_plan(
    options: &ReplanOptions,
    coverage: &CoverageSummary,
    home: Point3<f64>,
    chosen: &ChosenGaps,
) -> ReplanSummary {
    ReplanSummary {
        frame_id: "map".into(),
        resolution: coverage.resolution_m,
        origin: coverage.grid_origin,
        target_voxels: Vec::new(),
        viewpoints: Vec::new(),
        view: coverage.view,
        run: options.run.clone(),
        home: home.coords.into(),
        clearance_m: options.settings.clearance_m,
        speed_m_s: options.settings.speed_m_s,
        hover_s: options.settings.hover_s,
        max_sortie_length_m: options.settings.max_sortie_length_m,
        battery_minutes: options.settings.battery_minutes,
        gaps: options.settings.gaps,
        keep_out: Vec::new(),
        ceiling_z_m: None,
        coverage_gap_voxels: chosen.coverage_gaps,
        gap_voxels: chosen.voxels.len(),
        reshoot_spots: chosen.reshoot.clone(),
        planned_gap_voxels: 0,
        uninspectable_gaps: Vec::new(),
        candidate_viewpoints: 0,
        set_cover_viewpoints: 0,
        hover_time_s: 0.0,
        travel_time_s: 0.0,
        sorties: Vec::new(),
        waypoints: 0,
        length_m: 0.0,
        time_s: 0.0,
        drones: Vec::new(),
        mission_time_s: 0.0,
        closest_drones_m: None,
        solver: None,
        phases: Default::default(),
        geo_origin: None,
        geo_origin_from: None,
        ground_station_files: Vec::new(),
        seconds: 0.0,
        warnings: Vec::new(),
    }
}

/// Home itself when it keeps the clearance; else the first clear point
/// straight above it (a take-off point on the ground is too near the map).
fn clear_home(
    space: &FreeSpace,
    map: &SlamMap,
    home: Point3<f64>,
    summary: &mut ReplanSummary,
) -> Result<Point3<f64>, ReplanError> {
    if space.point_is_clear(&home) {
        return Ok(home);
    }
    let step = map.voxels.grid.resolution / 2.0;
    for k in 1..=(20.0 / step) as usize {
        let lifted = home + Vector3::z() * (k as f64 * step);
        if space.point_is_clear(&lifted) {
            summary.warnings.push(format!(
                "home ({:.1}, {:.1}, {:.1}) is within {} m of the map; sorties start and end {:.1} m above it",
                home.x, home.y, home.z, space.clearance_m, k as f64 * step
            ));
            summary.home = lifted.coords.into();
            return Ok(lifted);
        }
    }
    Err(ReplanError::HomeBlocked {
        home: home.coords.into(),
        clearance_m: space.clearance_m,
    })
}

/// Candidate viewpoints around the gap faces (clear of the map), each face
/// under its View model: the run's, or its focus region's.
fn viewpoints(
    flight: &Flight,
    coverage: &CoverageSummary,
    map: &SlamMap,
    space: &FreeSpace,
    targets: &[VoxelIndex],
    gaps: &[VoxelIndex],
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<Candidate>, ReplanError> {
    let lens = flight
        .cameras
        .first()
        .and_then(|c| c.intrinsics.as_ref())
        .ok_or(ReplanError::NoIntrinsics)?;
    let extrinsic = camera_mount(flight);
    let grid = map.voxels.grid;
    let target_set: HashSet<VoxelIndex> = targets.iter().copied().collect();
    let faces = exposed_faces(&grid, gaps, &target_set);
    let focus: Vec<FocusModel> = coverage.focus.iter().map(|f| f.model.clone()).collect();
    let models = FaceModels::new(coverage.view, &focus, &faces, &grid);
    let total = faces.len() as u64;
    progress(0, total);
    let done = AtomicU64::new(0);
    let mut found = Vec::new();
    for (view, mine) in models.groups() {
        let camera = Camera {
            lens,
            extrinsic: &extrinsic,
            view,
            max_distance_m: view
                .max_distance_m
                .min(view.max_gsd_mm / 1000.0 * lens.fx.min(lens.fy)),
        };
        let before = done.load(Ordering::Relaxed);
        let faces: Vec<_> = mine.iter().map(|&i| faces[i]).collect();
        found.extend(candidates(gaps, &faces, map, space, &camera, &|k| {
            done.fetch_max(before + k as u64, Ordering::Relaxed);
        }));
    }
    progress(done.load(Ordering::Relaxed), total);
    Ok(found)
}

/// The tour, and the gap voxels it leaves out.
struct Solved {
    /// The tour, and the clusters (indices) its stop clusters stand for;
    /// `None` when no gap voxel can be served.
    tour: Option<(Tour, Vec<usize>)>,
    left_out: BTreeMap<usize, Unplannable>,
}

/// The tour over the gap voxels that have candidates (for each of the
/// views they need), solved again without the candidates no
/// collision-free path reaches; and the gap voxels left out, with why.
/// `clusters` lose the unreachable candidates, and every cluster of a gap
/// left out. `from_home`: [`FreeSpace::distances_from`] home, `points[0]`.
fn solve(
    points: &[Point3<f64>],
    clusters: &mut Clusters,
    space: &FreeSpace,
    from_home: &HashMap<VoxelIndex, f64>,
    solver: &SolveOptions,
) -> Solved {
    let mut left_out: BTreeMap<usize, Unplannable> = BTreeMap::new();
    let gaps: BTreeSet<usize> = clusters.gap.iter().copied().collect();
    for g in gaps {
        let sizes = clusters
            .members
            .iter()
            .zip(&clusters.gap)
            .filter(|(_, of)| **of == g)
            .map(|(m, _)| m.len());
        let (empty, all) = sizes.fold((0, 0), |(e, a), n| (e + usize::from(n == 0), a + 1));
        if empty == all {
            left_out.insert(g, Unplannable::NoClearViewpoint);
        } else if empty > 0 {
            left_out.insert(g, Unplannable::TooFewViewpoints);
        }
    }
    leave_out(clusters, &left_out);
    // The candidates no path reaches, found by one search from home rather
    // than by the tour's failed legs (each a search of all reachable space).
    let lost: HashSet<usize> = clusters
        .members
        .iter()
        .flatten()
        .copied()
        .filter(|&k| !space.reaches(from_home, &points[0], &points[k + 1]))
        .collect();
    drop_candidates(clusters, &lost, &mut left_out);
    loop {
        let served: Vec<usize> = (0..clusters.members.len())
            .filter(|c| !clusters.members[*c].is_empty())
            .collect();
        if served.is_empty() {
            return Solved {
                tour: None,
                left_out,
            };
        }
        let stop_clusters: Vec<Vec<usize>> = served
            .iter()
            .map(|&c| clusters.members[c].iter().map(|k| k + 1).collect())
            .collect();
        let stops = Stops {
            points,
            clusters: &stop_clusters,
        };
        match plan_tour(&stops, space, solver) {
            Ok(tour) => {
                return Solved {
                    tour: Some((tour, served)),
                    left_out,
                };
            }
            Err(TourError::Unreachable(lost)) => {
                let lost: HashSet<usize> = lost.into_iter().map(|s| s - 1).collect();
                drop_candidates(clusters, &lost, &mut left_out);
            }
        }
    }
}

/// Removes the `lost` candidates from every cluster; a gap with a cluster
/// left with none is unreachable, and leaves the tour.
fn drop_candidates(
    clusters: &mut Clusters,
    lost: &HashSet<usize>,
    left_out: &mut BTreeMap<usize, Unplannable>,
) {
    for (members, &g) in clusters.members.iter_mut().zip(&clusters.gap) {
        let before = members.len();
        members.retain(|k| !lost.contains(k));
        if before > 0 && members.is_empty() {
            left_out.insert(g, Unplannable::Unreachable);
        }
    }
    leave_out(clusters, left_out);
}

/// Empties every cluster of the gaps left out: a gap short of a view is
/// not flown for at all.
fn leave_out(clusters: &mut Clusters, left_out: &BTreeMap<usize, Unplannable>) {
    for (members, g) in clusters.members.iter_mut().zip(&clusters.gap) {
        if left_out.contains_key(g) {
            members.clear();
        }
    }
}

/// The tour's stops (indices into it, from 1) per sortie, split so each
/// fits one battery (and the longest sortie, if set). Splitting bounds each
/// way home by the lattice distance (one search from home), then flies the
/// legs home it chose.
/// The tour's stops as each drone's sorties (one drone: the tour's
/// sorties; a team: [`crate::team::split`]).
fn split_sorties(
    options: &ReplanOptions,
    tour: &Tour,
    points: &[Point3<f64>],
    space: &FreeSpace,
    map: &SlamMap,
    from_home: &HashMap<VoxelIndex, f64>,
) -> Result<Vec<Vec<Vec<usize>>>, ReplanError> {
    let budget = options.budget();
    let home = points[0];
    let grid = map.voxels.grid;
    let home_m = |stop: usize| {
        let p = points[stop];
        if space.segment_is_clear(&home, &p) {
            return (p - home).norm();
        }
        // Rounding to millimetres per step: a little headroom.
        from_home
            .get(&grid.voxel_of(&p))
            .map_or(f64::INFINITY, |d| {
                (d + (p - grid.center(grid.voxel_of(&p))).norm()) * 1.001 + 0.01
            })
    };
    let drones = options.settings.drones as usize;
    let split = match drones {
        1 => crate::tour::sorties(tour, &budget, &home_m).map(|one| vec![one]),
        n => crate::team::split(tour, n, &budget, &home_m),
    };
    split.map_err(|(stop, round_trip_m)| ReplanError::SortieTooLong {
        point: points[stop].coords.into(),
        round_trip_m,
        round_trip_s: budget.time_s(round_trip_m, 1),
        max_m: budget.max_length_m,
        battery_minutes: options.settings.battery_minutes,
    })
}

/// One sortie over the tour's stops `indices`: home, the waypoints, home,
/// on collision-free legs.
fn fly(
    options: &ReplanOptions,
    tour: &Tour,
    points: &[Point3<f64>],
    space: &FreeSpace,
    indices: &[usize],
    waypoint: &dyn Fn(usize) -> Waypoint,
) -> Sortie {
    let home = points[0];
    let home_leg = |stop: usize| {
        space
            .path(&home, &points[stop])
            .expect("stops on the tour are reachable from home")
    };
    let first = indices[0];
    let last = *indices.last().expect("sorties are not empty");
    // Home to the first waypoint: the tour's own leg when it starts the tour.
    let mut legs: Vec<Vec<Point3<f64>>> = vec![if first == 1 {
        tour.legs[0].clone()
    } else {
        home_leg(tour.stops[first])
    }];
    for i in first..last {
        legs.push(tour.legs[i].clone());
    }
    legs.push(if last == tour.stops.len() - 1 {
        tour.legs[last].clone()
    } else {
        home_leg(tour.stops[last]).into_iter().rev().collect()
    });
    let waypoints: Vec<Waypoint> = indices.iter().map(|&i| waypoint(i)).collect();
    let mut path: Vec<Point3<f64>> = Vec::new();
    for leg in &legs {
        for p in leg {
            if path.last() != Some(p) {
                path.push(*p);
            }
        }
    }
    let length_m = length(&path);
    Sortie {
        drone: 0,
        time_s: options.budget().time_s(length_m, waypoints.len()),
        waypoints,
        path: path.iter().map(|p| p.coords.into()).collect(),
        length_m,
    }
}

/// The plan's totals, and its waypoints as an inspection plan's viewpoints.
fn summarise(summary: &mut ReplanSummary, tour: Tour) {
    for s in &summary.sorties {
        for w in &s.waypoints {
            summary.viewpoints.push(Viewpoint {
                position: [w.x, w.y, w.z],
                yaw: w.yaw,
                gimbal_pitch: w.gimbal_pitch,
            });
            summary.target_voxels.extend(&w.gap_voxels);
        }
    }
    summary.target_voxels.sort_unstable();
    // A gap needing several views is at as many waypoints.
    summary.target_voxels.dedup();
    summary.planned_gap_voxels = summary.target_voxels.len();
    summary.waypoints = summary.viewpoints.len();
    summary.length_m = summary.sorties.iter().map(|s| s.length_m).sum();
    summary.time_s = summary.sorties.iter().map(|s| s.time_s).sum();
    summary.drones = drone_plans(&summary.sorties);
    let stagger = crate::team::stagger(
        &summary.sorties,
        summary.speed_m_s,
        summary.hover_s,
        summary.clearance_m,
    );
    for (d, takeoff) in summary.drones.iter_mut().zip(stagger.takeoff_s) {
        d.takeoff_s = takeoff;
    }
    summary.closest_drones_m = stagger.closest_m;
    let ends = summary.drones.iter().map(|d| d.takeoff_s + d.time_s);
    summary.mission_time_s = ends.fold(0.0, f64::max);
    summary.hover_time_s = summary.hover_s * summary.waypoints as f64;
    summary.travel_time_s = summary.length_m / summary.speed_m_s;
    summary.solver = Some(tour.stats);
}

/// Each drone's share of the sorties.
fn drone_plans(sorties: &[Sortie]) -> Vec<DronePlan> {
    let mut drones: Vec<DronePlan> = Vec::new();
    for s in sorties {
        let at = s.drone as usize;
        while drones.len() <= at {
            drones.push(DronePlan {
                drone: drones.len() as u32,
                sorties: 0,
                waypoints: 0,
                length_m: 0.0,
                time_s: 0.0,
                takeoff_s: 0.0,
            });
        }
        let d = &mut drones[at];
        d.sorties += 1;
        d.waypoints += s.waypoints.len();
        d.length_m += s.length_m;
        d.time_s += s.time_s;
    }
    drones
}

/// Writes `replan.csv` (every point of every sortie's path, `X,Y,Z,Yaw`,
/// yaw of the waypoint being flown to), with a geo origin the missions, KML
/// and GeoJSON, and then `replan.json`.
fn write(
    run: &RunDir,
    mut summary: ReplanSummary,
    placement: Option<&Placement>,
    started: Instant,
) -> Result<ReplanSummary, ReplanError> {
    run.write_text(
        files::PATH_CSV,
        &ground_station::path_csv(&summary.sorties, &summary.frame_id),
    )?;
    remove_ground_station_files(run)?;
    let team = summary.drones.len() > 1;
    if team {
        for d in 0..summary.drones.len() {
            let own: Vec<Sortie> = summary
                .sorties
                .iter()
                .filter(|s| s.drone as usize == d)
                .cloned()
                .collect();
            let name = files::drone_path_csv(d);
            run.write_text(&name, &ground_station::path_csv(&own, &summary.frame_id))?;
        }
    }
    if let Some(placement) = placement.filter(|_| !summary.sorties.is_empty()) {
        let count = summary.sorties.len();
        let mut in_drone = 0;
        for (i, sortie) in summary.sorties.iter().enumerate() {
            let drone = sortie.drone as usize;
            let name = match team {
                false => files::mission(i, count),
                true => {
                    in_drone = if i > 0 && summary.sorties[i - 1].drone == sortie.drone {
                        in_drone + 1
                    } else {
                        0
                    };
                    files::drone_mission(drone, in_drone, summary.drones[drone].sorties)
                }
            };
            run.write_json(&name, &placement.mission(sortie))?;
            summary.ground_station_files.push(name);
        }
        run.write_text(files::KML, &placement.kml(&summary.sorties))?;
        run.write_json(files::GEOJSON, &placement.geojson(&summary.sorties))?;
        summary
            .ground_station_files
            .extend([files::KML.to_string(), files::GEOJSON.to_string()]);
    }
    summary.seconds = started.elapsed().as_secs_f64();
    run.write_json(files::SUMMARY, &summary)?;
    Ok(summary)
}

/// The last run's missions, KML and GeoJSON: a new plan may have fewer
/// sorties, or no geo origin.
fn remove_ground_station_files(run: &RunDir) -> Result<(), ReplanError> {
    let names = std::fs::read_dir(run.path())
        .map_err(|cause| postflight_core::Error::Open {
            path: run.path().to_owned(),
            cause,
        })?
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok());
    for name in names.filter(|n| files::is_mission(n) || files::is_drone_path_csv(n)) {
        run.remove(&name)?;
    }
    run.remove(files::KML)?;
    run.remove(files::GEOJSON)?;
    Ok(())
}

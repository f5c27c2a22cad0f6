//! The replan stage, `postflight replan --run RUN_DIR`: the gaps of the
//! coverage stage to a follow-up flight, phase by phase (see the crate
//! docs), into `replan.json` and `replan.csv`.

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use coverage::shots::camera_mount;
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
use postflight_core::{Flight, Intrinsics, InvalidSetting, RunDir, Stage, Viewpoint};

use crate::airspace::{Airspace, read_zones};
use crate::error::ReplanError;
use crate::free_space::{FreeSpace, length};
use crate::ground_station::{self, Placement};
use crate::route::{Route, Scene};
use crate::settings::{ReplanConfig, keys};
use crate::team::Member;
use crate::tour::Budget;
use crate::wpml;

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
        self.settings.check()?;
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
    let placement = summary
        .geo_origin
        .map(|origin| on_the_earth(options, origin, launch, &airspace));
    if placement.is_some() {
        summary.warnings.extend(unfenced(&airspace));
    }
    if gaps.is_empty() {
        return write(&run, summary, placement.as_ref(), started);
    }

    let lens = flight_lens(&flight)?;
    let team = team(options, launch, &lens)?;
    let given = options.map.as_ref().or(coverage.map.as_ref());
    let (map, _) = ingest::load_map(&flight, given.map(PathBuf::as_path), Some(grid))?;
    summary.frame_id = map.cloud.frame_id.clone();
    summary.warnings.extend(map.cloud.coarsened());
    let phase = Instant::now();
    let homes: Vec<Point3<f64>> = std::iter::once(launch)
        .chain(team.iter().map(|m| m.home))
        .collect();
    let space = FreeSpace::new(&map.voxels, options.settings.clearance_m, &homes, airspace)?;
    let home = clear_home(&space, &map, launch, &mut summary)?;
    summary.phases.clearance_s = phase.elapsed().as_secs_f64();

    let extrinsic = camera_mount(&flight);
    let scene = Scene {
        coverage: &coverage,
        map: &map,
        space: &space,
        targets: targets.iter().copied().collect(),
        focus: coverage.focus.iter().map(|f| f.model.clone()).collect(),
        extrinsic: &extrinsic,
        max_gimbal_up: options.settings.max_gimbal_up_deg.to_radians(),
        solver: options.solver()?,
    };
    let phase = Instant::now();
    let route = Route::plan(&scene, gaps.clone(), &chosen.views, &lens, home, progress);
    summary.candidate_viewpoints = route.found.len();
    summary.set_cover_viewpoints = route.set_cover;
    summary.phases.viewpoints_s = phase.elapsed().as_secs_f64();
    summary.uninspectable_gaps = left_out(&route);
    let Some((tour, _)) = &route.tour else {
        summary
            .warnings
            .push("no gap voxel can be inspected from a clear, reachable viewpoint".into());
        return write(&run, summary, placement.as_ref(), started);
    };
    summary.phases.solve_s = tour.stats.solve_seconds - tour.stats.paths_seconds;
    summary.phases.rounds = tour.stats.rounds;
    summary.solver = Some(tour.stats.clone());

    let phase = Instant::now();
    let shared = Shared {
        scene: &scene,
        route: &route,
        team: &team,
        chosen: &chosen,
        launch,
        lens: &lens,
    };
    shared.sorties(&mut summary)?;
    summary.phases.paths_s = tour.stats.paths_seconds + phase.elapsed().as_secs_f64();
    summarise(&mut summary, &team);
    write(&run, summary, placement.as_ref(), started)
}

/// Where the follow-up is on the Earth, for the ground station's missions.
fn on_the_earth(
    options: &ReplanOptions,
    origin: GeoOrigin,
    launch: Point3<f64>,
    airspace: &Airspace,
) -> Placement {
    Placement {
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
        dji_aircraft: options.settings.dji_aircraft,
    }
}

/// The route shared out to the team.
struct Shared<'a> {
    scene: &'a Scene<'a>,
    route: &'a Route,
    team: &'a [Member],
    chosen: &'a ChosenGaps,
    launch: Point3<f64>,
    lens: &'a Intrinsics,
}

impl Shared<'_> {
    /// The team's sorties into `summary`: the one tour cut into stretches
    /// where every drone shares the launch and lens, else each drone's
    /// gaps flown as a route of its own.
    fn sorties(&self, summary: &mut ReplanSummary) -> Result<(), ReplanError> {
        let (space, map) = (self.scene.space, self.scene.map);
        if self.team.iter().all(|m| m.shares(&self.launch, self.lens)) {
            let shares = split_sorties(self.team, self.route, space)?;
            for (drone, (member, sorties)) in (0u32..).zip(self.team.iter().zip(&shares)) {
                for indices in sorties {
                    summary
                        .sorties
                        .push(fly(member, drone, self.route, space, indices));
                }
            }
            return Ok(());
        }
        let (sorties, left) = own_routes(self.scene, self.route, self.team, self.chosen)?;
        summary.sorties = sorties;
        summary.uninspectable_gaps.extend(left);
        summary.uninspectable_gaps.sort_by_key(|u| u.voxel);
        summary.uninspectable_gaps.dedup_by_key(|u| u.voxel);
        for member in self.team.iter().filter(|m| m.home != self.launch) {
            let (_, by) = lift_home(space, map, member.home)?;
            if by > 0.0 {
                summary.warnings.push(format!(
                    "{}'s home is within {} m of the map; its sorties start and end {by:.1} m above it",
                    member.name, space.clearance_m
                ));
            }
        }
        Ok(())
    }
}

/// The flight's (first) camera's lens.
fn flight_lens(flight: &Flight) -> Result<Intrinsics, ReplanError> {
    flight
        .cameras
        .first()
        .and_then(|c| c.intrinsics.clone())
        .ok_or(ReplanError::NoIntrinsics)
}

/// The team: the `[[replan.drone]]` entries, each resolved over the
/// `[replan]` settings, or `drones` drones alike.
fn team(
    options: &ReplanOptions,
    launch: Point3<f64>,
    lens: &Intrinsics,
) -> Result<Vec<Member>, ReplanError> {
    let s = &options.settings;
    let budget = options.budget();
    if s.drone.is_empty() {
        return Ok((1..=s.drones)
            .map(|k| Member {
                name: format!("drone {k}"),
                home: launch,
                budget,
                battery_minutes: s.battery_minutes,
                lens: lens.clone(),
                camera: None,
            })
            .collect());
    }
    s.drone
        .iter()
        .map(|d| {
            let speed = d.speed_m_s.unwrap_or(s.speed_m_s);
            let minutes = d.battery_minutes.unwrap_or(s.battery_minutes);
            let lens = match &d.camera_info_file {
                Some(path) => ingest::calibration::from_calibration_file(
                    path,
                    &format!("{}'s camera_info_file in {}", d.name, keys::drone),
                )?,
                None => lens.clone(),
            };
            Ok(Member {
                name: d.name.clone(),
                home: d.home.map_or(launch, Point3::from),
                budget: Budget {
                    max_time_s: minutes * 60.0,
                    speed_m_s: speed,
                    ..budget
                },
                battery_minutes: minutes,
                lens,
                camera: d.camera_info_file.clone(),
            })
        })
        .collect()
}

/// The gaps a route leaves out, as replan.json lists them.
fn left_out(route: &Route) -> Vec<Uninspectable> {
    route
        .left_out
        .iter()
        .map(|(&g, &reason)| Uninspectable {
            voxel: route.gaps[g],
            reason,
        })
        .collect()
}

/// Rounds of [`own_routes`]' rebalancing.
const REBALANCE_ROUNDS: usize = 3;

/// Each drone's stretch of the team's route flown as a route of its own,
/// from its home with its camera: the sorties, and the gaps the drones'
/// routes leave out. The stretches were cut by times estimated on the
/// team's route (the flight's camera, the shared home), which a drone's
/// own route beats or misses; so the route is cut again with each drone's
/// estimates scaled by how far its own route's time was from the team's
/// mean, and the quickest mission of [`REBALANCE_ROUNDS`] is kept.
fn own_routes(
    scene: &Scene,
    route: &Route,
    team: &[Member],
    chosen: &ChosenGaps,
) -> Result<(Vec<Sortie>, Vec<Uninspectable>), ReplanError> {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let home_m = |stop: usize| route.home_m(scene.space, stop);
    let mut scale = vec![1.0f64; team.len()];
    let mut best: Option<(f64, Vec<Sortie>, Vec<Uninspectable>)> = None;
    for _ in 0..REBALANCE_ROUNDS {
        let budgets: Vec<Budget> = team
            .iter()
            .zip(&scale)
            .map(|(m, s)| Budget {
                speed_m_s: m.budget.speed_m_s / s,
                hover_s: m.budget.hover_s * s,
                ..m.budget
            })
            .collect();
        let shares = crate::team::split(tour, &budgets, &home_m)
            .map_err(|e| sortie_too_long(&team[0], &route.points, e))?;
        let mut own: Vec<(Vec<VoxelIndex>, Route)> = Vec::new();
        for (member, share) in team.iter().zip(&shares) {
            let gaps = share_gaps(route, share);
            own.push((gaps.clone(), own_route(scene, gaps, chosen, member)?));
        }
        second_chance(scene, team, chosen, &mut own)?;
        let (mut sorties, mut left) = (Vec::new(), Vec::new());
        let mut times = vec![0.0; team.len()];
        for (drone, (member, (_, own))) in (0u32..).zip(team.iter().zip(&own)) {
            left.extend(left_out(own));
            let Some((own_tour, _)) = &own.tour else {
                continue;
            };
            let cut = crate::tour::sorties(own_tour, &member.budget, &|stop| {
                own.home_m(scene.space, stop)
            })
            .map_err(|e| sortie_too_long(member, &own.points, e))?;
            for indices in &cut {
                let sortie = fly(member, drone, own, scene.space, indices);
                times[drone as usize] += sortie.time_s;
                sorties.push(sortie);
            }
        }
        left.sort_by_key(|u| u.voxel);
        left.dedup_by_key(|u| u.voxel);
        let mission = times.iter().copied().fold(0.0, f64::max);
        // Fewest gaps left out first, then the quickest.
        if best
            .as_ref()
            .is_none_or(|(m, _, l)| (left.len(), mission) < (l.len(), *m))
        {
            best = Some((mission, sorties, left));
        }
        let used: Vec<f64> = times.iter().copied().filter(|t| *t > 0.0).collect();
        let mean = used.iter().sum::<f64>() / used.len().max(1) as f64;
        for (s, t) in scale.iter_mut().zip(&times) {
            if *t > 0.0 && mean > 0.0 {
                *s *= t / mean;
            }
        }
    }
    let (_, sorties, left) = best.expect("at least one round");
    Ok((sorties, left))
}

/// The gap voxels the stops of `share` of the team's route serve.
fn share_gaps(team_route: &Route, share: &[Vec<usize>]) -> Vec<VoxelIndex> {
    let mut gaps: Vec<VoxelIndex> = share
        .iter()
        .flatten()
        .flat_map(|&i| team_route.waypoint(i).gap_voxels)
        .collect();
    gaps.sort_unstable();
    gaps.dedup();
    gaps
}

/// A drone's own route over `gaps` (sorted), from its home (lifted clear
/// as the team's is) with its camera.
fn own_route(
    scene: &Scene,
    gaps: Vec<VoxelIndex>,
    chosen: &ChosenGaps,
    member: &Member,
) -> Result<Route, ReplanError> {
    let views: Vec<u32> = gaps
        .iter()
        .map(|v| chosen.views[chosen.voxels.binary_search(v).expect("a chosen gap")])
        .collect();
    let (home, _) = lift_home(scene.space, scene.map, member.home)?;
    Ok(Route::plan(
        scene,
        gaps,
        &views,
        &member.lens,
        home,
        &mut |_, _| {},
    ))
}

/// Gaps a drone's camera cannot inspect (no clear viewpoint, or too few)
/// given to a drone with another camera: it plans its route again with
/// them, and keeps the new route when it inspects some.
fn second_chance(
    scene: &Scene,
    team: &[Member],
    chosen: &ChosenGaps,
    own: &mut [(Vec<VoxelIndex>, Route)],
) -> Result<(), ReplanError> {
    for d in 0..own.len() {
        let route = &own[d].1;
        let mut orphans: Vec<VoxelIndex> = route
            .left_out
            .iter()
            .filter(|(_, reason)| **reason != Unplannable::Unreachable)
            .map(|(&g, _)| route.gaps[g])
            .collect();
        for e in (0..own.len()).filter(|&e| team[e].lens != team[d].lens) {
            if orphans.is_empty() {
                break;
            }
            let mut gaps = own[e].0.clone();
            gaps.extend(&orphans);
            gaps.sort_unstable();
            gaps.dedup();
            let wider = own_route(scene, gaps.clone(), chosen, &team[e])?;
            let missed: HashSet<VoxelIndex> =
                wider.left_out.keys().map(|&g| wider.gaps[g]).collect();
            let taken: HashSet<VoxelIndex> = orphans
                .iter()
                .copied()
                .filter(|g| !missed.contains(g))
                .collect();
            if taken.is_empty() {
                continue;
            }
            orphans.retain(|g| !taken.contains(g));
            let gave = &mut own[d].1;
            let gave_gaps = gave.gaps.clone();
            gave.left_out.retain(|&g, _| !taken.contains(&gave_gaps[g]));
            own[e] = (gaps, wider);
        }
    }
    Ok(())
}

/// The map frame on the Earth: as set, else from the flight's GPS fixes;
/// and which it is.
fn geo_origin(options: &ReplanOptions, flight: &Flight) -> (Option<GeoOrigin>, Option<String>) {
    if let Some(origin) = options.settings.geo_origin {
        return (Some(origin), Some("settings".into()));
    }
    let photos = flight.summary.recordings.iter().any(|r| r.photos.is_some());
    match &flight.summary.geo_origin {
        Some(fit) if photos => (
            Some(fit.origin),
            Some("the geotagged photos' east-north-up frame".into()),
        ),
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
    let (lifted, by) = lift_home(space, map, home)?;
    if by > 0.0 {
        summary.warnings.push(format!(
            "home ({:.1}, {:.1}, {:.1}) is within {} m of the map; sorties start and end {by:.1} m above it",
            home.x, home.y, home.z, space.clearance_m
        ));
        summary.home = lifted.coords.into();
    }
    Ok(lifted)
}

/// `home`, or the first clear point straight above it, and how far above.
fn lift_home(
    space: &FreeSpace,
    map: &SlamMap,
    home: Point3<f64>,
) -> Result<(Point3<f64>, f64), ReplanError> {
    let step = map.voxels.grid.resolution / 2.0;
    (0..=(20.0 / step) as usize)
        .map(|k| k as f64 * step)
        .find(|by| space.point_is_clear(&(home + Vector3::z() * *by)))
        .map(|by| (home + Vector3::z() * by, by))
        .ok_or(ReplanError::HomeBlocked {
            home: home.coords.into(),
            clearance_m: space.clearance_m,
        })
}

/// The team's route's stops (indices into its tour, from 1) as each
/// drone's sorties, each within the drone's battery (and the longest
/// sortie, if set): one drone's, the tour's sorties; a team's,
/// [`crate::team::split`]. Splitting bounds each way home by the lattice
/// distance (one search from home), then flies the legs home it chose.
fn split_sorties(
    team: &[Member],
    route: &Route,
    space: &FreeSpace,
) -> Result<Vec<Vec<Vec<usize>>>, ReplanError> {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let home_m = |stop: usize| route.home_m(space, stop);
    let split = match team {
        [one] => crate::tour::sorties(tour, &one.budget, &home_m).map(|one| vec![one]),
        _ => {
            let budgets: Vec<Budget> = team.iter().map(|m| m.budget).collect();
            crate::team::split(tour, &budgets, &home_m)
        }
    };
    split.map_err(|e| sortie_too_long(&team[0], &route.points, e))
}

/// A stop whose round trip alone does not fit `member`'s battery.
fn sortie_too_long(
    member: &Member,
    points: &[Point3<f64>],
    (stop, round_trip_m): (usize, f64),
) -> ReplanError {
    ReplanError::SortieTooLong {
        point: points[stop].coords.into(),
        round_trip_m,
        round_trip_s: member.budget.time_s(round_trip_m, 1),
        max_m: member.budget.max_length_m,
        battery_minutes: member.battery_minutes,
    }
}

/// One sortie of drone `drone` over `route`'s tour stops `indices`: home,
/// the waypoints, home, on collision-free legs.
fn fly(member: &Member, drone: u32, route: &Route, space: &FreeSpace, indices: &[usize]) -> Sortie {
    let (tour, _) = route.tour.as_ref().expect("a route with a tour");
    let (home, points) = (route.home(), &route.points);
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
    let waypoints: Vec<Waypoint> = indices.iter().map(|&i| route.waypoint(i)).collect();
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
        drone,
        time_s: member.budget.time_s(length_m, waypoints.len()),
        waypoints,
        path: path.iter().map(|p| p.coords.into()).collect(),
        length_m,
    }
}

/// The plan's totals, and its waypoints as an inspection plan's viewpoints.
fn summarise(summary: &mut ReplanSummary, team: &[Member]) {
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
    summary.drones = drone_plans(&summary.sorties, team);
    let speeds: Vec<f64> = team.iter().map(|m| m.budget.speed_m_s).collect();
    let stagger = crate::team::stagger(
        &summary.sorties,
        &speeds,
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
    summary.travel_time_s = summary
        .drones
        .iter()
        .map(|d| d.length_m / d.speed_m_s)
        .sum();
}

/// Each drone's share of the sorties: a plan per member of the team, the
/// unused ones with none.
fn drone_plans(sorties: &[Sortie], team: &[Member]) -> Vec<DronePlan> {
    let mut drones: Vec<DronePlan> = (0u32..)
        .zip(team)
        .map(|(drone, m)| DronePlan {
            drone,
            name: m.name.clone(),
            home: m.home.coords.into(),
            speed_m_s: m.budget.speed_m_s,
            battery_minutes: m.battery_minutes,
            camera: m.camera.clone(),
            image_size: [m.lens.width, m.lens.height],
            focal_px: m.lens.fx,
            sorties: 0,
            waypoints: 0,
            length_m: 0.0,
            time_s: 0.0,
            takeoff_s: 0.0,
        })
        .collect();
    for s in sorties {
        let d = &mut drones[s.drone as usize];
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
            in_drone = match i > 0 && summary.sorties[i - 1].drone == sortie.drone {
                true => in_drone + 1,
                false => 0,
            };
            let name = |format| match team {
                false => files::mission(i, count, format),
                true => {
                    files::drone_mission(drone, in_drone, summary.drones[drone].sorties, format)
                }
            };
            let launch = Point3::from(summary.drones[drone].home);
            let qgc = name(files::Mission::QGroundControl);
            run.write_json(&qgc, &placement.mission(sortie, launch))?;
            let dji = name(files::Mission::DjiWpml);
            run.write_with(&dji, |file| {
                wpml::write_kmz(file, placement, sortie, launch).map_err(|cause| {
                    postflight_core::Error::Write {
                        path: run.file(&dji),
                        cause,
                    }
                })
            })?;
            summary.ground_station_files.extend([qgc, dji]);
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

//! The replan stage, `postflight replan --run RUN_DIR`: the gaps of the
//! coverage stage to a follow-up flight, phase by phase (see the crate
//! docs), into `replan.json` and `replan.csv`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use coverage::shots::camera_mount;
use gtsp::SolveOptions;
use nalgebra::Point3;
use postflight_core::geo::GeoOrigin;
use postflight_core::map::VoxelGrid;
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::outputs::replan::{ReplanSummary, files};
use postflight_core::{Flight, Intrinsics, InvalidSetting, RunDir, Stage};

use crate::airspace::{Airspace, airspace, unfenced};
use crate::error::ReplanError;
use crate::free_space::{FreeSpace, clear_home};
use crate::gaps::choose_gaps;
use crate::ground_station::Placement;
use crate::outputs::write;
use crate::route::{Route, Scene};
use crate::settings::{ReplanConfig, keys};
use crate::sorties::{Shared, left_out};
use crate::summary::{empty_plan, summarise};
use crate::team::members;
use crate::tour::Budget;

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
    let grid = VoxelGrid::new(
        coverage.figures.resolution_m,
        Point3::from(coverage.grid_origin),
    );
    let chosen = choose_gaps(&run, options.settings.gaps)?;
    let (targets, gaps) = (&chosen.targets, &chosen.voxels);
    let launch = take_off(options, &flight)?;
    let mut summary = empty_plan(options, &coverage, launch, &chosen);
    (summary.geo_origin, summary.geo_origin_from) = geo_origin(options, &flight);
    let airspace = airspace(&options.settings, summary.geo_origin.as_ref(), launch)?;
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
    let team = members(&options.settings, options.budget(), launch, &lens)?;
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

/// The flight's (first) camera's lens.
fn flight_lens(flight: &Flight) -> Result<Intrinsics, ReplanError> {
    flight
        .cameras
        .first()
        .and_then(|c| c.intrinsics.clone())
        .ok_or(ReplanError::NoIntrinsics)
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

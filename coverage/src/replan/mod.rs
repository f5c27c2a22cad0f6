//! The replanning stage: `postflight replan --run RUN_DIR`. From the gaps
//! the coverage stage found (target voxels not inspected that some free
//! standpoint could inspect), it draws candidate viewpoints, clusters them
//! per gap voxel, solves the follow-up tour as a GTSP from home and back
//! with lazy collision checks, splits it into sorties if asked, and writes
//! `replan.json` (also a plan `postflight coverage --viewpoints` can check)
//! and `replan.csv` (GATSBI's `X,Y,Z,Yaw` inspection path).

pub mod free_space;
pub mod tour;
pub mod viewpoints;

use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use ingest::map::{PointCloud, SlamMap, VoxelGrid, VoxelIndex};
use ingest::{Flight, ViewModel, Viewpoint};
use nalgebra::Point3;
use polars::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::CoverageError;
use crate::face::exposed_faces;
use crate::gtsp::SolveOptions;
use crate::stage::{camera_mount, check_view, files as coverage_files};
use free_space::{FreeSpace, length};
use tour::{ReplanSolverStats, Stops, TourError, plan_tour};
use viewpoints::{Camera, Candidate, candidates, clusters};

/// Files this stage writes in the run directory.
pub mod files {
    pub const PLAN: &str = "replan.json";
    pub const PATH_CSV: &str = "replan.csv";
}

#[derive(Debug, Clone)]
pub struct ReplanOptions {
    pub run: PathBuf,
    /// Map instead of the one coverage used.
    pub map: Option<PathBuf>,
    /// Take-off and landing point (default: the flight's first pose).
    pub home: Option<[f64; 3]>,
    /// Closest the vehicle may come to any occupied voxel, metres.
    pub clearance_m: f64,
    /// Longest sortie (battery), metres; `None`: one sortie.
    pub max_sortie_length_m: Option<f64>,
    /// Cruise speed for the time estimate, metres per second.
    pub speed_m_s: f64,
    /// Hover at each waypoint for the time estimate, seconds.
    pub hover_s: f64,
    /// GTSP solver settings (time limit per solve, seed, threads).
    pub solver: SolveOptions,
}

impl ReplanOptions {
    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            map: None,
            home: None,
            clearance_m: 1.0,
            max_sortie_length_m: None,
            speed_m_s: 2.0,
            hover_s: 2.0,
            solver: SolveOptions {
                time_limit: Some(Duration::from_secs(10)),
                ..SolveOptions::default()
            },
        }
    }
}

/// A stop of the follow-up flight.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Waypoint {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Heading about world z, radians (ROS: counter-clockwise from x).
    pub yaw: f64,
    /// Gimbal pitch, radians, positive looking down.
    pub gimbal_pitch: f64,
    /// Gap voxels inspected here (each gap voxel at exactly one waypoint).
    pub gap_voxels: Vec<VoxelIndex>,
}

/// One flight from home and back.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sortie {
    pub waypoints: Vec<Waypoint>,
    /// The collision-free path flown, home to home.
    pub path: Vec<[f64; 3]>,
    pub length_m: f64,
    /// Flying at the given speed plus hovering at each waypoint.
    pub time_s: f64,
}

/// A gap voxel the follow-up flight cannot inspect, and why.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Uninspectable {
    pub voxel: VoxelIndex,
    pub reason: Unplannable,
}

/// Why a gap voxel is left out of the follow-up flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Unplannable {
    /// No viewpoint that keeps the clearance inspects it.
    NoClearViewpoint,
    /// Such viewpoints exist, but no collision-free path leads to them from home.
    Unreachable,
}

/// `replan.json`. Its first fields make it an inspection plan (the gap
/// voxels it inspects as targets, the waypoints as viewpoints in flight
/// order), so `postflight coverage --viewpoints replan.json` checks it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReplanSummary {
    pub frame_id: String,
    pub resolution: f64,
    pub origin: [f64; 3],
    pub target_voxels: Vec<VoxelIndex>,
    pub viewpoints: Vec<Viewpoint>,
    pub view: ViewModel,
    pub run: PathBuf,
    pub home: [f64; 3],
    pub clearance_m: f64,
    pub speed_m_s: f64,
    pub hover_s: f64,
    pub max_sortie_length_m: Option<f64>,
    /// Gap voxels coverage found (not inspected, not uninspectable).
    pub gap_voxels: usize,
    /// Of those, the ones this plan inspects.
    pub planned_gap_voxels: usize,
    pub uninspectable_gaps: Vec<Uninspectable>,
    pub candidate_viewpoints: usize,
    pub sorties: Vec<Sortie>,
    pub waypoints: usize,
    pub length_m: f64,
    pub time_s: f64,
    pub solver: Option<ReplanSolverStats>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// What replanning needs from `coverage.json`.
#[derive(Deserialize)]
struct CoverageFacts {
    view: ViewModel,
    resolution_m: f64,
    grid_origin: Option<[f64; 3]>,
    map: Option<PathBuf>,
}

pub fn replan(
    options: &ReplanOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ReplanSummary, CoverageError> {
    let started = Instant::now();
    let flight = Flight::load(&options.run)?;
    let run = ingest::RunDir::open(&options.run, coverage_files::SUMMARY, "coverage")?;
    run.remove(files::PLAN)?;
    if !(options.clearance_m >= 0.0 && options.speed_m_s > 0.0 && options.hover_s >= 0.0) {
        return Err(CoverageError::Option(
            "--clearance and --hover must not be negative and --speed must be positive".into(),
        ));
    }
    if options
        .max_sortie_length_m
        .is_some_and(|m| m.is_nan() || m <= 0.0)
    {
        return Err(CoverageError::Option(
            "--max-sortie-length must be a positive number of metres".into(),
        ));
    }
    let facts: CoverageFacts = run.read_json(coverage_files::SUMMARY)?;
    let origin = facts.grid_origin.ok_or_else(|| {
        CoverageError::Option(format!(
            "{} was written by an older postflight without the voxel grid; rerun `postflight coverage`",
            run.file(coverage_files::SUMMARY).display()
        ))
    })?;
    check_view(&facts.view)?;
    let grid = VoxelGrid::new(facts.resolution_m, Point3::from(origin));
    let (targets, gaps) = read_gaps(&run.read_table(coverage_files::TABLE)?)?;

    let home = match options.home {
        Some(h) => Point3::from(h),
        None => flight
            .trajectory
            .poses()
            .first()
            .map(|p| Point3::from(p.pose.translation.vector))
            .ok_or_else(|| {
                CoverageError::Option("the flight has no poses to take off from; give the take-off point with --home X,Y,Z".into())
            })?,
    };
    let mut summary = ReplanSummary {
        frame_id: "map".into(),
        resolution: grid.resolution,
        origin,
        target_voxels: Vec::new(),
        viewpoints: Vec::new(),
        view: facts.view,
        run: options.run.clone(),
        home: home.coords.into(),
        clearance_m: options.clearance_m,
        speed_m_s: options.speed_m_s,
        hover_s: options.hover_s,
        max_sortie_length_m: options.max_sortie_length_m,
        gap_voxels: gaps.len(),
        planned_gap_voxels: 0,
        uninspectable_gaps: Vec::new(),
        candidate_viewpoints: 0,
        sorties: Vec::new(),
        waypoints: 0,
        length_m: 0.0,
        time_s: 0.0,
        solver: None,
        seconds: 0.0,
        warnings: Vec::new(),
    };
    if gaps.is_empty() {
        return write(&run, summary, started);
    }

    let cloud = match options.map.as_ref().or(facts.map.as_ref()) {
        Some(path) => PointCloud::load(path)?,
        None => flight.recorded_map()?.ok_or(CoverageError::NoMap)?,
    };
    summary.frame_id = cloud.frame_id.clone();
    let map = SlamMap::on_grid(cloud, grid).ok_or_else(|| {
        CoverageError::Option("the map has no points; pass a map with --map".into())
    })?;
    let space = FreeSpace::new(&map.voxels, options.clearance_m, &[home]);
    let home = clear_home(&space, &map, home, &mut summary)?;

    let lens = flight
        .cameras
        .first()
        .and_then(|c| c.intrinsics.as_ref())
        .ok_or_else(|| {
            CoverageError::Option(
                "the flight's camera has no intrinsics; rerun `postflight ingest` with --camera-info FILE".into(),
            )
        })?;
    let extrinsic = camera_mount(&flight);
    let view = facts.view;
    let camera = Camera {
        lens,
        extrinsic: &extrinsic,
        view: &view,
        max_distance_m: view
            .max_distance_m
            .min(view.max_gsd_mm / 1000.0 * lens.fx.min(lens.fy)),
    };
    let target_set: HashSet<VoxelIndex> = targets.iter().copied().collect();
    let faces = exposed_faces(&grid, &gaps, &target_set);
    let total = faces.len() as u64;
    progress(0, total);
    let done = std::sync::atomic::AtomicU64::new(0);
    let report = |k: usize| done.fetch_max(k as u64, std::sync::atomic::Ordering::Relaxed);
    let found: Vec<Candidate> = candidates(&gaps, &faces, &map, &space, &camera, &|k| {
        report(k);
    });
    progress(done.load(std::sync::atomic::Ordering::Relaxed), total);
    summary.candidate_viewpoints = found.len();
    let mut by_gap = clusters(&gaps, &found, |v| grid.center(v));
    let mut uninspectable: BTreeMap<usize, Unplannable> = BTreeMap::new();
    for (g, members) in by_gap.iter().enumerate() {
        if members.is_empty() {
            uninspectable.insert(g, Unplannable::NoClearViewpoint);
        }
    }

    // Stops: home, then the candidates.
    let points: Vec<Point3<f64>> = std::iter::once(home)
        .chain(found.iter().map(|c| Point3::from(c.viewpoint.position)))
        .collect();
    let tour = loop {
        let served: Vec<usize> = (0..gaps.len()).filter(|g| !by_gap[*g].is_empty()).collect();
        if served.is_empty() {
            break None;
        }
        let stop_clusters: Vec<Vec<usize>> = served
            .iter()
            .map(|&g| by_gap[g].iter().map(|k| k + 1).collect())
            .collect();
        let stops = Stops {
            points: &points,
            clusters: &stop_clusters,
        };
        match plan_tour(&stops, &space, &options.solver) {
            Ok(t) => break Some((t, served)),
            Err(TourError::Unreachable(lost)) => {
                let lost: HashSet<usize> = lost.into_iter().map(|s| s - 1).collect();
                for (g, members) in by_gap.iter_mut().enumerate() {
                    let before = members.len();
                    members.retain(|k| !lost.contains(k));
                    if before > 0 && members.is_empty() {
                        uninspectable.insert(g, Unplannable::Unreachable);
                    }
                }
            }
        }
    };
    summary.uninspectable_gaps = uninspectable
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
        return write(&run, summary, started);
    };

    // Sorties: the whole tour, or split for the battery. Splitting bounds
    // each way home by the lattice distance (one search from home), then
    // flies the legs home it chose.
    let split: Vec<Vec<usize>> = match options.max_sortie_length_m {
        None => vec![(1..tour.stops.len()).collect()],
        Some(max) => {
            let from_home = space.distances_from(&home);
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
            tour::sorties(&tour, max, &home_m).map_err(|(stop, round_trip)| {
                let p = points[stop];
                CoverageError::Option(format!(
                    "the viewpoint at ({:.1}, {:.1}, {:.1}) is a {round_trip:.0} m round trip from home, longer than --max-sortie-length {max}; raise it or move --home closer",
                    p.x, p.y, p.z
                ))
            })?
        }
    };
    let home_leg = |stop: usize| {
        space
            .path(&home, &points[stop])
            .expect("stops on the tour are reachable from home")
    };
    for indices in split {
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
        let waypoints: Vec<Waypoint> = indices
            .iter()
            .map(|&i| {
                let c = &found[tour.stops[i] - 1];
                let v = &c.viewpoint;
                let mut gap_voxels: Vec<VoxelIndex> =
                    tour.serves[i].iter().map(|&k| gaps[served[k]]).collect();
                gap_voxels.sort_unstable();
                Waypoint {
                    x: v.position[0],
                    y: v.position[1],
                    z: v.position[2],
                    yaw: v.yaw,
                    gimbal_pitch: v.gimbal_pitch,
                    gap_voxels,
                }
            })
            .collect();
        let mut path: Vec<Point3<f64>> = Vec::new();
        for leg in &legs {
            for p in leg {
                if path.last() != Some(p) {
                    path.push(*p);
                }
            }
        }
        let length_m = length(&path);
        summary.sorties.push(Sortie {
            time_s: length_m / options.speed_m_s + options.hover_s * waypoints.len() as f64,
            waypoints,
            path: path.iter().map(|p| p.coords.into()).collect(),
            length_m,
        });
    }
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
    summary.planned_gap_voxels = summary.target_voxels.len();
    summary.waypoints = summary.viewpoints.len();
    summary.length_m = summary.sorties.iter().map(|s| s.length_m).sum();
    summary.time_s = summary.sorties.iter().map(|s| s.time_s).sum();
    summary.solver = Some(tour.stats);
    write(&run, summary, started)
}

/// Target voxels and the gap voxels among them (sorted), from `coverage.parquet`.
fn read_gaps(table: &DataFrame) -> Result<(Vec<VoxelIndex>, Vec<VoxelIndex>), CoverageError> {
    let bad = |e: PolarsError| {
        CoverageError::Option(format!(
            "coverage.parquet is not the coverage stage's table ({e}); rerun `postflight coverage`"
        ))
    };
    let int = |name: &str| -> Result<Vec<i32>, CoverageError> {
        let c = table.column(name).map_err(bad)?.i32().map_err(bad)?.clone();
        Ok((0..c.len()).map(|i| c.get(i).unwrap_or_default()).collect())
    };
    let flag = |name: &str| -> Result<Vec<bool>, CoverageError> {
        let c = table
            .column(name)
            .map_err(bad)?
            .bool()
            .map_err(bad)?
            .clone();
        Ok((0..c.len()).map(|i| c.get(i).unwrap_or_default()).collect())
    };
    let (x, y, z) = (int("voxel_x")?, int("voxel_y")?, int("voxel_z")?);
    let (inspected, uninspectable) = (flag("inspected")?, flag("uninspectable")?);
    let targets: Vec<VoxelIndex> = (0..x.len())
        .map(|i| VoxelIndex([x[i], y[i], z[i]]))
        .collect();
    let mut gaps: Vec<VoxelIndex> = (0..x.len())
        .filter(|&i| !inspected[i] && !uninspectable[i])
        .map(|i| targets[i])
        .collect();
    gaps.sort_unstable();
    Ok((targets, gaps))
}

/// Home itself when it keeps the clearance; else the first clear point
/// straight above it (a take-off point on the ground is too near the map).
fn clear_home(
    space: &FreeSpace,
    map: &SlamMap,
    home: Point3<f64>,
    summary: &mut ReplanSummary,
) -> Result<Point3<f64>, CoverageError> {
    if space.point_is_clear(&home) {
        return Ok(home);
    }
    let step = map.voxels.grid.resolution / 2.0;
    for k in 1..=(20.0 / step) as usize {
        let lifted = home + nalgebra::Vector3::z() * (k as f64 * step);
        if space.point_is_clear(&lifted) {
            summary.warnings.push(format!(
                "home ({:.1}, {:.1}, {:.1}) is within {} m of the map; sorties start and end {:.1} m above it",
                home.x, home.y, home.z, space.clearance_m, k as f64 * step
            ));
            summary.home = lifted.coords.into();
            return Ok(lifted);
        }
    }
    Err(CoverageError::Option(format!(
        "home ({:.1}, {:.1}, {:.1}) and the 20 m above it are within {} m of the map; give a clear take-off point with --home X,Y,Z or a smaller --clearance",
        home.x, home.y, home.z, space.clearance_m
    )))
}

/// Writes `replan.csv` (every point of every sortie's path, `X,Y,Z,Yaw`,
/// yaw of the waypoint being flown to) and then `replan.json`.
fn write(
    run: &ingest::RunDir,
    mut summary: ReplanSummary,
    started: Instant,
) -> Result<ReplanSummary, CoverageError> {
    summary.seconds = started.elapsed().as_secs_f64();
    let mut text = String::from("X,Y,Z,Yaw\n");
    let mut row = |p: &[f64; 3], yaw: f64| {
        text += &format!("{:.3},{:.3},{:.3},{:.4}\n", p[0], p[1], p[2], yaw);
    };
    for sortie in &summary.sorties {
        let mut next = 0;
        let mut yaw = sortie.waypoints.first().map_or(0.0, |w| w.yaw);
        for p in &sortie.path {
            // Waypoints sharing a point are turned to there, one row each.
            let mut at_waypoint = false;
            while let Some(w) = sortie.waypoints.get(next).filter(|w| [w.x, w.y, w.z] == *p) {
                row(p, w.yaw);
                yaw = w.yaw;
                next += 1;
                at_waypoint = true;
            }
            if !at_waypoint {
                yaw = sortie.waypoints.get(next).map_or(yaw, |w| w.yaw);
                row(p, yaw);
            }
        }
    }
    run.write_text(files::PATH_CSV, &text)?;
    run.write_json(files::PLAN, &summary)?;
    Ok(summary)
}

//! One drone's route over a set of gap voxels: the candidate viewpoints
//! its camera has around them, their multi-cover and clusters, and the
//! GTSP tour from its home, solved again without the candidates no
//! collision-free path reaches.

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};

use coverage::face::exposed_faces;
use coverage::focus::FaceModels;
use gtsp::SolveOptions;
use nalgebra::{Isometry3, Point3};
use postflight_core::Intrinsics;
use postflight_core::map::{SlamMap, VoxelIndex};
use postflight_core::outputs::coverage::CoverageSummary;
use postflight_core::outputs::replan::{Unplannable, Waypoint};
use postflight_core::region::FocusModel;

use crate::free_space::FreeSpace;
use crate::tour::{Stops, Tour, TourError, plan_tour};
use crate::viewpoints::{
    Camera, Candidate, Clusters, candidates, clusters, one_face_for_several_views, set_cover,
};

/// What every route is planned in: the map, its free space, the targets
/// and the View models coverage judged by.
pub struct Scene<'a> {
    pub coverage: &'a CoverageSummary,
    pub map: &'a SlamMap,
    pub space: &'a FreeSpace<'a>,
    /// Every target voxel: a gap's faces toward another are not exposed.
    pub targets: HashSet<VoxelIndex>,
    pub focus: Vec<FocusModel>,
    /// Body to optical frame of the camera mount (every drone's gimbal).
    pub extrinsic: &'a Isometry3<f64>,
    /// How far above the horizon the gimbal can look, radians.
    pub max_gimbal_up: f64,
    pub solver: SolveOptions,
}

/// A route over `gaps` (indices below are into it).
pub struct Route {
    pub gaps: Vec<VoxelIndex>,
    /// Stops: home, then the candidates.
    pub points: Vec<Point3<f64>>,
    pub found: Vec<Candidate>,
    pub set_cover: usize,
    pub clusters: Clusters,
    /// The tour, and the clusters (indices) its stop clusters stand for.
    pub tour: Option<(Tour, Vec<usize>)>,
    pub left_out: BTreeMap<usize, Unplannable>,
    /// Lattice distances from home ([`FreeSpace::distances_from`]).
    pub from_home: HashMap<VoxelIndex, f64>,
}

impl Route {
    /// The route from `home` over `gaps` (sorted, each needing `views`) for
    /// a camera with `lens`.
    pub fn plan(
        scene: &Scene,
        gaps: Vec<VoxelIndex>,
        views: &[u32],
        lens: &Intrinsics,
        home: Point3<f64>,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Self {
        let grid = scene.map.voxels.grid;
        let mut found = viewpoints(scene, &gaps, lens, progress);
        one_face_for_several_views(&mut found, views);
        // One viewpoint serves every gap it inspects: the clusters hold only
        // a greedy cover's viewpoints, so the tour needs no more of them.
        let cover = set_cover(&found, views);
        let mut clusters = clusters(&gaps, &found, &cover, views, |v| grid.center(v));
        let points: Vec<Point3<f64>> = std::iter::once(home)
            .chain(found.iter().map(|c| Point3::from(c.viewpoint.position)))
            .collect();
        // One search from home: which candidates a path reaches, and how
        // far home is from each stop when sorties are split.
        let from_home = scene.space.distances_from(&home);
        let Solved { tour, left_out } = solve(
            &points,
            &mut clusters,
            scene.space,
            &from_home,
            &scene.solver,
        );
        Self {
            gaps,
            points,
            found,
            set_cover: cover.len(),
            clusters,
            tour,
            left_out,
            from_home,
        }
    }

    pub fn home(&self) -> Point3<f64> {
        self.points[0]
    }

    /// The waypoint at stop `i` of the tour, with the gap voxels it serves.
    pub fn waypoint(&self, i: usize) -> Waypoint {
        let (tour, served) = self.tour.as_ref().expect("a route with a tour");
        let v = &self.found[tour.stops[i] - 1].viewpoint;
        let mut gap_voxels: Vec<VoxelIndex> = tour.serves[i]
            .iter()
            .map(|&k| self.gaps[self.clusters.gap[served[k]]])
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
    }

    /// Distance from home to the tour's stop `stop` along free space, at
    /// most: straight when clear, else by the lattice.
    pub fn home_m(&self, space: &FreeSpace, stop: usize) -> f64 {
        let (home, p) = (self.home(), self.points[stop]);
        if space.segment_is_clear(&home, &p) {
            return (p - home).norm();
        }
        let grid = space.grid();
        // Rounding to millimetres per step: a little headroom.
        self.from_home
            .get(&grid.voxel_of(&p))
            .map_or(f64::INFINITY, |d| {
                (d + (p - grid.center(grid.voxel_of(&p))).norm()) * 1.001 + 0.01
            })
    }
}

/// Candidate viewpoints around the gap faces (clear of the map), each face
/// under its View model: the run's, or its focus region's.
fn viewpoints(
    scene: &Scene,
    gaps: &[VoxelIndex],
    lens: &Intrinsics,
    progress: &mut dyn FnMut(u64, u64),
) -> Vec<Candidate> {
    let (map, space, extrinsic) = (scene.map, scene.space, scene.extrinsic);
    let grid = map.voxels.grid;
    let faces = exposed_faces(&grid, gaps, &scene.targets);
    let models = FaceModels::new(scene.coverage.view, &scene.focus, &faces, &grid);
    let total = faces.len() as u64;
    progress(0, total);
    let done = AtomicU64::new(0);
    let mut found = Vec::new();
    for (view, mine) in models.groups() {
        let camera = Camera {
            lens,
            extrinsic,
            view,
            max_distance_m: view
                .max_distance_m
                .min(view.max_gsd_mm / 1000.0 * lens.fx.min(lens.fy)),
            max_gimbal_up: scene.max_gimbal_up,
        };
        let before = done.load(Ordering::Relaxed);
        let faces: Vec<_> = mine.iter().map(|&i| faces[i]).collect();
        found.extend(candidates(gaps, &faces, map, space, &camera, &|k| {
            done.fetch_max(before + k as u64, Ordering::Relaxed);
        }));
    }
    progress(done.load(Ordering::Relaxed), total);
    found
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

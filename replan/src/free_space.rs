//! Where the vehicle may fly: voxel centres at least a clearance away from
//! every occupied voxel (as a box, not its centre), with mapped ground
//! below, outside the keep-out zones and below the ceiling
//! ([`Airspace`]), and collision-free paths between them (A* over the 26-connected
//! free voxels, then shortened by line of sight, as theta* paths are);
//! home lifted clear of the map where it is too near it.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use nalgebra::{Point3, Vector3};
use postflight_core::map::{SlamMap, VoxelIndex, VoxelMap};
use postflight_core::outputs::replan::ReplanSummary;

use crate::airspace::Airspace;
use crate::error::ReplanError;

/// Free space around a voxel map, with a required clearance.
pub struct FreeSpace<'a> {
    map: &'a VoxelMap,
    /// Required distance from any occupied voxel's box, metres.
    pub clearance_m: f64,
    /// Segments are checked at points this far apart; a point between two
    /// checked points is at most half of it from one of them.
    step_m: f64,
    /// The voxels flown through: the map's extent and the given points in
    /// x and y (paths stay over the mapped ground), from the lowest map
    /// voxel up to [`HEADROOM_M`] above the highest.
    lo: [i32; 3],
    dims: [usize; 3],
    occupied: Vec<bool>,
    /// Distance from each voxel's centre to the nearest occupied box,
    /// capped at [`FreeSpace::horizon`].
    centre_distance: Vec<f32>,
    /// Lowest occupied voxel of each (x, y) column (`i32::MAX`: none).
    floor: Vec<i32>,
    airspace: Airspace,
}

/// Room kept above the map for paths that go over the structure, metres.
const HEADROOM_M: f64 = 10.0;

/// The most voxels the free space holds (five bytes each: a gigabyte).
pub const MAX_CELLS: usize = 200_000_000;

/// A free space that would hold more than [`MAX_CELLS`] voxels: the map
/// and the points it must hold (home) span too far at its resolution.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "the space to plan in, round the map and home, spans {:.0} x {:.0} x {:.0} m: more than {MAX_CELLS} voxels at {resolution_m} m; give a home near the map with {} (in the map frame, metres) or a coarser [coverage] resolution_m",
    extent_m[0], extent_m[1], extent_m[2], crate::settings::keys::home
)]
pub struct TooLarge {
    /// Its extent in x, y and z, metres.
    pub extent_m: [f64; 3],
    pub resolution_m: f64,
}

impl<'a> FreeSpace<'a> {
    pub fn new(
        map: &'a VoxelMap,
        clearance_m: f64,
        also_inside: &[Point3<f64>],
        airspace: Airspace,
    ) -> Result<Self, TooLarge> {
        let res = map.grid.resolution;
        // In i64: a point far off the map (a home given in the wrong
        // frame) spans more voxels than i32 counts.
        let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        let unbounded = |p: &Point3<f64>| {
            let v = (p - map.grid.origin) / res;
            [v.x, v.y, v.z].map(|x| x.floor() as i64)
        };
        let all = map
            .voxels()
            .map(|v| v.0.map(i64::from))
            .chain(also_inside.iter().map(unbounded));
        for v in all {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        if lo[0] > hi[0] {
            (lo, hi) = ([0; 3], [0; 3]);
        }
        // Saturating: a home at 1e300 m saturates its voxel at i64's end.
        hi[2] = hi[2].saturating_add((HEADROOM_M / res).ceil() as i64);
        let spans = [0, 1, 2].map(|k| hi[k].saturating_sub(lo[k]).saturating_add(1) as f64);
        let cells = spans.iter().product::<f64>();
        let in_i32 = lo.iter().chain(&hi).all(|v| i32::try_from(*v).is_ok());
        if cells > MAX_CELLS as f64 || !in_i32 {
            return Err(TooLarge {
                extent_m: spans.map(|n| n * res),
                resolution_m: res,
            });
        }
        let (lo, dims) = (lo.map(|v| v as i32), spans.map(|n| n as usize));
        let mut space = Self {
            map,
            clearance_m,
            step_m: res / 4.0,
            lo,
            dims,
            occupied: vec![false; dims[0] * dims[1] * dims[2]],
            centre_distance: Vec::new(),
            floor: vec![i32::MAX; dims[0] * dims[1]],
            airspace,
        };
        let horizon = space.horizon();
        let mut distance = vec![horizon as f32; space.occupied.len()];
        // Box distance from a voxel's centre to a voxel `offset` away.
        let reach = (horizon / res).ceil() as i32 + 1;
        let offsets: Vec<([i32; 3], f32)> = cube(reach)
            .map(|o| {
                let d = Vector3::from(o.map(|x| (f64::from(x).abs() - 0.5).max(0.0) * res));
                (o, d.norm() as f32)
            })
            .filter(|(_, d)| f64::from(*d) < horizon)
            .collect();
        for v in map.voxels() {
            if let Some(i) = space.slot(v) {
                space.occupied[i] = true;
                let column = i / dims[2];
                space.floor[column] = space.floor[column].min(v.0[2]);
            }
            for (o, d) in &offsets {
                let n = VoxelIndex([v.0[0] + o[0], v.0[1] + o[1], v.0[2] + o[2]]);
                if let Some(i) = space.slot(n) {
                    distance[i] = distance[i].min(*d);
                }
            }
        }
        space.centre_distance = distance;
        Ok(space)
    }

    /// Distances beyond this are not told apart: far enough to decide a
    /// voxel and every step out of it.
    fn horizon(&self) -> f64 {
        self.clearance_m + self.map.grid.resolution * 2.0
    }

    fn slot(&self, v: VoxelIndex) -> Option<usize> {
        let mut i = 0;
        for k in 0..3 {
            let x = v.0[k] - self.lo[k];
            if x < 0 || x as usize >= self.dims[k] {
                return None;
            }
            i = i * self.dims[k] + x as usize;
        }
        Some(i)
    }

    fn is_occupied(&self, v: VoxelIndex) -> bool {
        self.slot(v).is_some_and(|i| self.occupied[i])
    }

    /// Distance from `p` to the nearest occupied voxel's box, up to `limit`.
    pub fn distance_to_occupied(&self, p: &Point3<f64>, limit: f64) -> f64 {
        let res = self.map.grid.resolution;
        let centre = self.map.grid.voxel_of(p);
        let mut best = limit;
        for o in cube((limit / res).ceil() as i32 + 1) {
            let v = VoxelIndex([centre.0[0] + o[0], centre.0[1] + o[1], centre.0[2] + o[2]]);
            if self.is_occupied(v) {
                let c = self.map.grid.center(v);
                let d = ((p - c).abs() - Vector3::repeat(res / 2.0)).sup(&Vector3::zeros());
                best = best.min(d.norm());
            }
        }
        best
    }

    /// Whether `p` is at least `required` from every occupied box: at once
    /// from its voxel's centre distance when that is far enough, else by
    /// searching the voxels around it.
    fn keeps(&self, p: &Point3<f64>, required: f64) -> bool {
        let Some(i) = self.slot(self.map.grid.voxel_of(p)) else {
            return false;
        };
        let half_diagonal = self.map.grid.resolution * 3f64.sqrt() / 2.0;
        f64::from(self.centre_distance[i]) - half_diagonal >= required
            || self.distance_to_occupied(p, required) >= required
    }

    /// Whether a point is inside the flying volume and keeps the clearance
    /// (with the margin for checking segments at points), with mapped
    /// ground below it, in open airspace.
    pub fn point_is_clear(&self, p: &Point3<f64>) -> bool {
        self.keeps(p, self.clearance_m + self.step_m / 2.0)
            && self.mapped_below(p)
            && self.airspace.allows(p)
    }

    pub fn grid(&self) -> postflight_core::map::VoxelGrid {
        self.map.grid
    }

    /// Whether the map has something below `p`, within a voxel sideways
    /// (a sparse map has holes a plumb line can fall through): the vehicle
    /// stays over mapped ground, not out in unmapped space.
    fn mapped_below(&self, p: &Point3<f64>) -> bool {
        let v = self.map.grid.voxel_of(p);
        let (x, y) = (v.0[0] - self.lo[0], v.0[1] - self.lo[1]);
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                let (cx, cy) = (x + dx, y + dy);
                cx >= 0
                    && cy >= 0
                    && (cx as usize) < self.dims[0]
                    && (cy as usize) < self.dims[1]
                    && self.floor[cx as usize * self.dims[1] + cy as usize] < v.0[2]
            })
        })
    }

    /// Whether a voxel's centre is a place to fly through.
    fn voxel_is_clear(&self, v: VoxelIndex) -> bool {
        self.slot(v).is_some_and(|i| {
            f64::from(self.centre_distance[i]) >= self.clearance_m + self.step_m / 2.0
                && self.airspace.allows(&self.map.grid.center(v))
        })
    }

    /// Whether the straight segment keeps the clearance everywhere, stays
    /// in the flying volume and in open airspace.
    pub fn segment_is_clear(&self, a: &Point3<f64>, b: &Point3<f64>) -> bool {
        let length = (b - a).norm();
        let steps = (length / self.step_m).ceil().max(1.0) as usize;
        let required = self.clearance_m + self.step_m / 2.0;
        (0..=steps).all(|i| self.keeps(&(a + (b - a) * (i as f64 / steps as f64)), required))
            && self.airspace.allows_segment(a, b)
    }

    /// Whether the step between two neighbouring voxel centres is clear: at
    /// once when both centres are further from the map than the clearance
    /// plus half the step, and from the airspace's limits than half the
    /// step (every point of the step is within half of it of an end), else
    /// point by point.
    fn step_is_clear(&self, a: VoxelIndex, b: VoxelIndex, length: f64) -> bool {
        let (Some(i), Some(j)) = (self.slot(a), self.slot(b)) else {
            return false;
        };
        let (ca, cb) = (self.map.grid.center(a), self.map.grid.center(b));
        let nearest = f64::from(self.centre_distance[i].min(self.centre_distance[j]));
        (nearest - length / 2.0 >= self.clearance_m
            && self.airspace.clear_around(&ca, length / 2.0)
            && self.airspace.clear_around(&cb, length / 2.0))
            || self.segment_is_clear(&ca, &cb)
    }

    /// A collision-free path from `a` to `b` (both included), or `None`
    /// when `b` cannot be reached from `a`. The ends must be clear points.
    pub fn path(&self, a: &Point3<f64>, b: &Point3<f64>) -> Option<Vec<Point3<f64>>> {
        if self.segment_is_clear(a, b) {
            return Some(vec![*a, *b]);
        }
        let grid = self.map.grid;
        let (start, goal) = (grid.voxel_of(a), grid.voxel_of(b));
        // The ends join the lattice through their own voxels' centres.
        if !self.voxel_is_clear(start)
            || !self.voxel_is_clear(goal)
            || !self.segment_is_clear(a, &grid.center(start))
            || !self.segment_is_clear(&grid.center(goal), b)
        {
            return None;
        }
        let voxels = self.astar(start, goal)?;
        let mut points: Vec<Point3<f64>> = vec![*a];
        points.extend(voxels.iter().map(|v| grid.center(*v)));
        points.push(*b);
        Some(self.shorten(points))
    }

    /// A* over the 26-connected clear voxels.
    fn astar(&self, start: VoxelIndex, goal: VoxelIndex) -> Option<Vec<VoxelIndex>> {
        let best = self.search(start, 0, Some(goal));
        best.get(&goal)?;
        let mut out = vec![goal];
        let mut at = goal;
        while at != start {
            at = best[&at].1;
            out.push(at);
        }
        out.reverse();
        Some(out)
    }

    /// Lattice distances (metres) from `a` to every clear voxel reachable
    /// from it: the length of the unshortened path to each voxel's centre,
    /// so an upper bound on the length of [`FreeSpace::path`] to it.
    pub fn distances_from(&self, a: &Point3<f64>) -> HashMap<VoxelIndex, f64> {
        let grid = self.map.grid;
        let start = grid.voxel_of(a);
        if !self.voxel_is_clear(start) || !self.segment_is_clear(a, &grid.center(start)) {
            return HashMap::new();
        }
        let first = (a - grid.center(start)).norm();
        self.search(start, mm(first), None)
            .into_iter()
            .map(|(v, (g, _))| (v, g as f64 / 1000.0))
            .collect()
    }

    /// Whether [`FreeSpace::path`] from `a` can reach `b`, given
    /// `lattice`, the voxels [`FreeSpace::distances_from`] `a` reached: in
    /// a straight clear line, or joined to the lattice at a reached voxel.
    /// One search from `a` answers this for every `b`; a failed
    /// [`FreeSpace::path`] searches all the space it can reach.
    pub fn reaches(
        &self,
        lattice: &HashMap<VoxelIndex, f64>,
        a: &Point3<f64>,
        b: &Point3<f64>,
    ) -> bool {
        let goal = self.map.grid.voxel_of(b);
        (lattice.contains_key(&goal) && self.segment_is_clear(&self.map.grid.center(goal), b))
            || self.segment_is_clear(a, b)
    }

    /// Best-first search over the 26-connected clear voxels (costs in
    /// millimetres): A* to `goal`, stopping there, or Dijkstra over all.
    /// Returns each reached voxel's cost and predecessor.
    fn search(
        &self,
        start: VoxelIndex,
        start_cost: i64,
        goal: Option<VoxelIndex>,
    ) -> HashMap<VoxelIndex, (i64, VoxelIndex)> {
        let res = self.map.grid.resolution;
        let h = |v: VoxelIndex| {
            goal.map_or(0, |goal| {
                let d: Vector3<f64> =
                    Vector3::from(v.0).map(f64::from) - Vector3::from(goal.0).map(f64::from);
                mm(d.norm() * res)
            })
        };
        let mut open = BinaryHeap::new();
        let mut best: HashMap<VoxelIndex, (i64, VoxelIndex)> = HashMap::new();
        best.insert(start, (start_cost, start));
        open.push(Reverse((start_cost + h(start), start_cost, start.0)));
        while let Some(Reverse((_, g, v))) = open.pop() {
            let v = VoxelIndex(v);
            if Some(v) == goal {
                break;
            }
            if best.get(&v).is_some_and(|(known, _)| *known < g) {
                continue;
            }
            for n in v.neighbours() {
                let step = Vector3::from(n.0).map(f64::from) - Vector3::from(v.0).map(f64::from);
                let ng = g + mm(step.norm() * res);
                if best.get(&n).is_some_and(|(known, _)| *known <= ng) {
                    continue;
                }
                if !self.voxel_is_clear(n) || !self.step_is_clear(v, n, step.norm() * res) {
                    continue;
                }
                best.insert(n, (ng, v));
                open.push(Reverse((ng + h(n), ng, n.0)));
            }
        }
        best
    }

    /// Drops every point the path can skip in a clear straight line.
    fn shorten(&self, points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
        let mut out = vec![points[0]];
        let mut i = 0;
        while i + 1 < points.len() {
            let mut j = points.len() - 1;
            while j > i + 1 && !self.segment_is_clear(&points[i], &points[j]) {
                j -= 1;
            }
            out.push(points[j]);
            i = j;
        }
        out
    }
}

/// Metres to whole millimetres, the search's costs.
fn mm(d: f64) -> i64 {
    (d * 1000.0).round() as i64
}

/// Offsets of the cube of voxels `reach` around one.
fn cube(reach: i32) -> impl Iterator<Item = [i32; 3]> {
    (-reach..=reach).flat_map(move |x| {
        (-reach..=reach).flat_map(move |y| (-reach..=reach).map(move |z| [x, y, z]))
    })
}

/// Length of a polyline.
pub fn length(points: &[Point3<f64>]) -> f64 {
    points.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Home itself when it keeps the clearance; else the first clear point
/// straight above it (a take-off point on the ground is too near the map).
pub(crate) fn clear_home(
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
pub(crate) fn lift_home(
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

#[cfg(test)]
mod tests {
    use super::*;
    use postflight_core::map::VoxelGrid;

    /// Ground at z = 0 and a wall at x = 0 from y = -5 to 5, 10 m tall.
    fn wall() -> VoxelMap {
        let mut points = Vec::new();
        for x in -20..20 {
            for y in -20..20 {
                points.push(Point3::new(f64::from(x) * 0.5, f64::from(y) * 0.5, -0.25));
            }
        }
        for y in -10..10 {
            for z in 0..20 {
                points.push(Point3::new(
                    0.25,
                    f64::from(y) * 0.5 + 0.25,
                    f64::from(z) * 0.5 + 0.25,
                ));
            }
        }
        VoxelMap::from_points(VoxelGrid::new(0.5, Point3::origin()), &points, 1)
    }

    /// Distance to the nearest occupied box, over every occupied voxel.
    fn brute_distance(map: &VoxelMap, p: &Point3<f64>) -> f64 {
        map.voxels()
            .map(|v| {
                let c = map.grid.center(v);
                let d = ((p - c).abs() - Vector3::repeat(0.25)).sup(&Vector3::zeros());
                d.norm()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn a_path_round_a_wall_keeps_the_clearance_and_is_near_shortest() {
        let map = wall();
        // A point far off the map (a home in the wrong frame) is refused.
        for far in [1e12, 1e300] {
            let home = [Point3::new(far, 0.0, 0.0)];
            assert!(FreeSpace::new(&map, 1.0, &home, Airspace::default()).is_err());
        }
        let space = FreeSpace::new(&map, 1.0, &[], Airspace::default()).unwrap();
        let (a, b) = (Point3::new(-3.0, 0.0, 3.0), Point3::new(3.5, 0.0, 3.0));
        assert!(!space.segment_is_clear(&a, &b));
        let path = space.path(&a, &b).expect("round the wall");
        assert!(space.reaches(&space.distances_from(&a), &a, &b));
        for w in path.windows(2) {
            for i in 0..=100 {
                let p = w[0] + (w[1] - w[0]) * (f64::from(i) / 100.0);
                let d = brute_distance(&map, &p);
                assert!(d >= 1.0, "{p} is {d} m from the map");
            }
        }
        // Round the end of the wall (y = 5 or -5, plus clearance) or over it
        // (z = 10 plus clearance): at least 2 * hypot(3, 6) = 13.4 m; the
        // lattice path, shortened, should be close.
        let len = length(&path);
        assert!((13.0..16.0).contains(&len), "{len} m: {path:?}");
        // Within the clearance of the wall: not a place to fly.
        assert!(!space.point_is_clear(&Point3::new(-0.8, 0.0, 3.0)));
        assert!(space.point_is_clear(&Point3::new(-1.2, 0.0, 3.0)));
    }

    #[test]
    fn a_walled_in_point_cannot_be_reached() {
        let mut points = Vec::new();
        for x in -20..20 {
            for y in -20..20 {
                points.push(Point3::new(f64::from(x) * 0.5, f64::from(y) * 0.5, -0.25));
            }
        }
        // A closed box of 6 x 6 x 6 m round (10, 10, 3).
        for i in 0..13 {
            for j in 0..13 {
                let (u, v) = (f64::from(i) * 0.5 - 3.0, f64::from(j) * 0.5 - 3.0);
                for (x, y, z) in [
                    (-3.0, u, v),
                    (3.0, u, v),
                    (u, -3.0, v),
                    (u, 3.0, v),
                    (u, v, -3.0),
                    (u, v, 3.0),
                ] {
                    points.push(Point3::new(10.0 + x, 10.0 + y, 3.25 + z));
                }
            }
        }
        let map = VoxelMap::from_points(VoxelGrid::new(0.5, Point3::origin()), &points, 1);
        let space = FreeSpace::new(&map, 1.0, &[], Airspace::default()).unwrap();
        let inside = Point3::new(10.25, 10.25, 3.25);
        assert!(space.point_is_clear(&inside));
        let outside = Point3::new(-5.0, -5.0, 3.0);
        assert!(space.path(&outside, &inside).is_none());
        // One search from outside says the same as the failed path.
        let lattice = space.distances_from(&outside);
        assert!(!space.reaches(&lattice, &outside, &inside));
    }
}

//! The SLAM map: its points, their voxel occupancy and a KD-tree for
//! nearest-point queries.

pub mod cloud;
pub mod las;
mod las_sizes;
pub mod mesh;
pub mod octomap;
mod pcd;
pub mod plane;
mod ply;
pub mod raycast;
pub mod register;
pub mod side;
pub mod voxel;

use std::collections::HashMap;
use std::ops::Range;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

pub use cloud::PointCloud;
pub use raycast::VoxelHit;
pub use side::FaceSide;
pub use voxel::{VoxelGrid, VoxelIndex, VoxelMap};

/// Default voxel edge, metres (the resolution of the GATSBI work).
pub const DEFAULT_RESOLUTION: f64 = 0.5;

/// A map ready for geometric queries.
pub struct SlamMap {
    pub cloud: PointCloud,
    pub voxels: VoxelMap,
    tree: ImmutableKdTree<f64, 3>,
    /// Point indices grouped by voxel, and each voxel's range of them.
    by_voxel: Vec<u32>,
    ranges: HashMap<VoxelIndex, Range<usize>>,
}

/// A map point found by a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearestPoint {
    /// Index into the cloud's points.
    pub index: usize,
    pub point: Point3<f64>,
    pub distance: f64,
}

impl SlamMap {
    /// Voxelise the cloud at `resolution` (grid anchored at the world origin)
    /// and index its points. `None` for an empty cloud.
    pub fn new(cloud: PointCloud, resolution: f64) -> Option<Self> {
        Self::on_grid(cloud, VoxelGrid::new(resolution, Point3::origin()))
    }

    /// Voxelise the cloud on a given grid (a plan's, so voxel indices agree
    /// with it) and index its points. `None` for an empty cloud.
    pub fn on_grid(cloud: PointCloud, grid: VoxelGrid) -> Option<Self> {
        if cloud.is_empty() {
            return None;
        }
        let voxels = VoxelMap::from_points(grid, &cloud.points, 1);
        let coords: Vec<[f64; 3]> = cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree = ImmutableKdTree::new_from_slice(&coords).ok()?;
        let keys: Vec<VoxelIndex> = cloud.points.iter().map(|p| grid.voxel_of(p)).collect();
        let mut by_voxel: Vec<u32> = (0..cloud.points.len() as u32).collect();
        by_voxel.sort_by_key(|i| keys[*i as usize].0);
        let mut ranges = HashMap::with_capacity(voxels.len());
        let mut start = 0;
        for end in 1..=by_voxel.len() {
            let key = keys[by_voxel[start] as usize];
            if end == by_voxel.len() || keys[by_voxel[end] as usize] != key {
                ranges.insert(key, start..end);
                start = end;
            }
        }
        Some(Self {
            cloud,
            voxels,
            tree,
            by_voxel,
            ranges,
        })
    }

    /// The map points in a voxel.
    pub fn points_in(&self, v: VoxelIndex) -> impl Iterator<Item = &Point3<f64>> + '_ {
        let range = self.ranges.get(&v).cloned().unwrap_or(0..0);
        self.by_voxel[range]
            .iter()
            .map(|i| &self.cloud.points[*i as usize])
    }

    /// The map point nearest to `p`.
    pub fn nearest(&self, p: &Point3<f64>) -> NearestPoint {
        let hit = self
            .tree
            .query(&[p.x, p.y, p.z])
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        let index = hit.item as usize;
        NearestPoint {
            index,
            point: self.cloud.points[index],
            distance: hit.distance.sqrt(),
        }
    }

    /// The map point nearest to `p` if one is within `radius`: as fast far
    /// from the map as near it, where [`SlamMap::nearest`] searches much
    /// of the tree to find a far point (registration's outliers).
    pub fn nearest_within(&self, p: &Point3<f64>, radius: f64) -> Option<NearestPoint> {
        let hits = self
            .tree
            .query(&[p.x, p.y, p.z])
            .nearest_n::<SquaredEuclidean<f64>>(std::num::NonZeroUsize::MIN)
            .within(radius * radius)
            .execute();
        hits.first().map(|hit| {
            let index = hit.item as usize;
            NearestPoint {
                index,
                point: self.cloud.points[index],
                distance: hit.distance.sqrt(),
            }
        })
    }

    /// Visit the map points within `radius` of `p`, in no order (no
    /// allocation, no sort: for the hot loops of ray casting). Small radii
    /// scan the few voxels the ball touches, which beats a tree descent.
    pub fn visit_within(&self, p: &Point3<f64>, radius: f64, mut visit: impl FnMut(&Point3<f64>)) {
        let grid = self.voxels.grid;
        if radius > grid.resolution {
            self.tree
                .query(&[p.x, p.y, p.z])
                .within::<SquaredEuclidean<f64>>(radius * radius)
                .unsorted()
                .visit(|hit| visit(&self.cloud.points[hit.item as usize]));
            return;
        }
        let r = nalgebra::Vector3::repeat(radius);
        let (lo, hi) = (grid.voxel_of(&(p - r)).0, grid.voxel_of(&(p + r)).0);
        let r2 = radius * radius;
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    for q in self.points_in(VoxelIndex([x, y, z])) {
                        if (q - p).norm_squared() <= r2 {
                            visit(q);
                        }
                    }
                }
            }
        }
    }

    /// Map points within `radius` of `p`, nearest first.
    pub fn within(&self, p: &Point3<f64>, radius: f64) -> Vec<NearestPoint> {
        self.tree
            .query(&[p.x, p.y, p.z])
            .within::<SquaredEuclidean<f64>>(radius * radius)
            .execute()
            .into_iter()
            .map(|hit| NearestPoint {
                index: hit.item as usize,
                point: self.cloud.points[hit.item as usize],
                distance: hit.distance.sqrt(),
            })
            .collect()
    }
}

/// Several maps of one place as one: the first cloud's points, then each
/// other's points farther than `beyond_m` from every point taken so far
/// (the surface it adds). Maps that agree are not doubled where they do:
/// one SLAM session's map recorded at two times, or two sessions' maps
/// registered onto each other. `None` without clouds.
pub fn merged(clouds: Vec<PointCloud>, beyond_m: f64) -> Option<PointCloud> {
    let mut clouds = clouds.into_iter();
    let mut merged = clouds.next()?;
    for cloud in clouds {
        if cloud.grid != merged.grid {
            merged.grid = None;
        }
        let Some(taken) = SlamMap::on_grid(merged.clone(), VoxelGrid::default()) else {
            merged.points = cloud.points;
            continue;
        };
        let new = cloud.points.into_iter();
        let new = new.filter(|p| taken.nearest_within(p, beyond_m).is_none());
        merged.points.extend(new.collect::<Vec<_>>());
    }
    Some(merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_maps_keep_the_first_where_they_agree_and_add_what_is_new() {
        let wall = |x0: f64, shift: f64| -> PointCloud {
            let points = (0..20)
                .flat_map(|i| (0..20).map(move |j| (i, j)))
                .map(|(i, j)| {
                    Point3::new(x0 + f64::from(i) * 0.05 + shift, f64::from(j) * 0.05, 0.0)
                })
                .collect();
            PointCloud {
                points,
                ..PointCloud::default()
            }
        };
        let first = wall(0.0, 0.0);
        // The same wall 3 cm off (a registration's error), and one beside it.
        let again = wall(0.0, 0.03);
        let beside = wall(5.0, 0.0);
        let one = merged(vec![first.clone(), again, beside.clone()], 0.1).unwrap();
        assert_eq!(one.points.len(), first.points.len() + beside.points.len());
        assert_eq!(one.points[..first.points.len()], first.points[..]);
        assert!(merged(Vec::new(), 0.1).is_none());
    }

    #[test]
    fn nearest_and_radius_queries_match_brute_force() {
        let points: Vec<Point3<f64>> = (0..2000)
            .map(|i| {
                let t = f64::from(i);
                Point3::new((t * 0.37).sin() * 10.0, (t * 0.11).cos() * 7.0, t * 0.003)
            })
            .collect();
        let map = SlamMap::new(
            PointCloud {
                frame_id: "map".into(),
                points: points.clone(),
                grid: None,
                mesh_spacing_m: None,
            },
            DEFAULT_RESOLUTION,
        )
        .unwrap();
        for q in [Point3::new(0.0, 0.0, 0.0), Point3::new(3.0, -2.0, 4.0)] {
            let brute = points
                .iter()
                .map(|p| (p - q).norm())
                .fold(f64::INFINITY, f64::min);
            assert!((map.nearest(&q).distance - brute).abs() < 1e-9);
            let bounded = |r: f64| map.nearest_within(&q, r).map(|n| n.distance);
            assert_eq!(
                bounded(brute + 0.01).map(|d| (d - brute).abs() < 1e-9),
                Some(true)
            );
            assert_eq!(bounded(brute - 0.01), None);
            let n = points.iter().filter(|p| (*p - q).norm() <= 1.5).count();
            let within = map.within(&q, 1.5);
            assert_eq!(within.len(), n);
            assert!(within.windows(2).all(|w| w[0].distance <= w[1].distance));
        }
        // Points by voxel: each point in exactly its own voxel.
        let mut counted = 0;
        for v in map.voxels.voxels() {
            let inside: Vec<&Point3<f64>> = map.points_in(v).collect();
            assert_eq!(inside.len() as u32, map.voxels.points_in(v));
            assert!(inside.iter().all(|p| map.voxels.grid.voxel_of(p) == v));
            counted += inside.len();
        }
        assert_eq!(counted, points.len());
        // Visiting a ball, by voxels (small radius) or the tree (large), finds what a search does.
        for (q, r) in [
            (Point3::new(0.3, 2.0, 1.0), 0.4),
            (Point3::new(-4.0, 1.0, 2.0), 2.5),
        ] {
            let mut seen = Vec::new();
            map.visit_within(&q, r, |p| seen.push(*p));
            let mut expected: Vec<Point3<f64>> =
                map.within(&q, r).iter().map(|n| n.point).collect();
            let key = |p: &Point3<f64>| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
            seen.sort_by_key(key);
            expected.sort_by_key(key);
            assert!(!expected.is_empty());
            assert_eq!(seen, expected);
        }
        assert!(SlamMap::new(PointCloud::default(), 0.5).is_none());
    }
}

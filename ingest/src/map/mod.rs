//! The SLAM map: its points, their voxel occupancy and a KD-tree for
//! nearest-point queries.

pub mod cloud;
mod pcd;
mod ply;
pub mod pointcloud2;
pub mod raycast;
pub mod voxel;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

pub use cloud::PointCloud;
pub use raycast::VoxelHit;
pub use voxel::{VoxelGrid, VoxelIndex, VoxelMap};

/// Default voxel edge, metres (the resolution of the GATSBI work).
pub const DEFAULT_RESOLUTION: f64 = 0.5;

/// A map ready for geometric queries.
pub struct SlamMap {
    pub cloud: PointCloud,
    pub voxels: VoxelMap,
    tree: ImmutableKdTree<f64, 3>,
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
        Some(Self {
            cloud,
            voxels,
            tree,
        })
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

#[cfg(test)]
mod tests {
    use super::*;

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
            let n = points.iter().filter(|p| (*p - q).norm() <= 1.5).count();
            let within = map.within(&q, 1.5);
            assert_eq!(within.len(), n);
            assert!(within.windows(2).all(|w| w[0].distance <= w[1].distance));
        }
        assert!(SlamMap::new(PointCloud::default(), 0.5).is_none());
    }
}

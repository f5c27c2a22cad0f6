//! Rays through a voxel map (3D DDA, Amanatides & Woo 1987): the first
//! occupied voxel a camera ray meets, and whether a line of sight is clear.
//! Localisation casts detection rays with it; coverage checks occlusion.

use nalgebra::{Point3, Vector3};

use super::side::FaceSide;
use super::voxel::{VoxelIndex, VoxelMap};

/// Where a ray first enters an occupied voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VoxelHit {
    pub voxel: VoxelIndex,
    /// Distance from the ray origin to the entry point, metres.
    pub distance: f64,
    /// Entry point on the voxel's surface (the origin when it starts inside).
    pub point: Point3<f64>,
    /// The side the ray entered through; `None` when the origin is inside
    /// the voxel.
    pub face: Option<FaceSide>,
}

/// The voxels a ray passes through, in order, with the distance at which it
/// enters each and the face it enters through.
struct Walk {
    voxel: [i32; 3],
    step: [i32; 3],
    /// Distance along the ray to the next boundary on each axis.
    next: [f64; 3],
    /// Distance along the ray between boundaries on each axis.
    delta: [f64; 3],
    entered_at: f64,
    face: Option<FaceSide>,
}

impl Walk {
    fn new(map: &VoxelMap, origin: &Point3<f64>, dir: &Vector3<f64>) -> Self {
        let grid = map.grid;
        let start = grid.voxel_of(origin).0;
        let local = (origin - grid.origin) / grid.resolution;
        let mut step = [0; 3];
        let mut next = [f64::INFINITY; 3];
        let mut delta = [f64::INFINITY; 3];
        for a in 0..3 {
            if dir[a] > 0.0 {
                step[a] = 1;
                next[a] = (f64::from(start[a] + 1) - local[a]) * grid.resolution / dir[a];
                delta[a] = grid.resolution / dir[a];
            } else if dir[a] < 0.0 {
                step[a] = -1;
                next[a] = (f64::from(start[a]) - local[a]) * grid.resolution / dir[a];
                delta[a] = -grid.resolution / dir[a];
            }
        }
        Self {
            voxel: start,
            step,
            next,
            delta,
            entered_at: 0.0,
            face: None,
        }
    }

    /// Move into the next voxel along the ray.
    fn advance(&mut self) {
        let a = if self.next[0] <= self.next[1] && self.next[0] <= self.next[2] {
            0
        } else if self.next[1] <= self.next[2] {
            1
        } else {
            2
        };
        self.voxel[a] += self.step[a];
        self.entered_at = self.next[a];
        self.next[a] += self.delta[a];
        self.face = Some(FaceSide::from_axis(a, self.step[a] < 0));
    }
}

impl VoxelMap {
    /// The first occupied voxel along the ray from `origin` in `direction`
    /// (any length) within `max_range` metres.
    pub fn cast(
        &self,
        origin: &Point3<f64>,
        direction: &Vector3<f64>,
        max_range: f64,
    ) -> Option<VoxelHit> {
        self.cast_past(origin, direction, max_range, |_| false)
    }

    /// [`VoxelMap::cast`], passing through the occupied voxels `pass` accepts.
    pub fn cast_past(
        &self,
        origin: &Point3<f64>,
        direction: &Vector3<f64>,
        max_range: f64,
        pass: impl Fn(VoxelIndex) -> bool,
    ) -> Option<VoxelHit> {
        let dir = direction.try_normalize(1e-12)?;
        let mut walk = Walk::new(self, origin, &dir);
        while walk.entered_at <= max_range {
            let voxel = VoxelIndex(walk.voxel);
            if self.is_occupied(voxel) && !pass(voxel) {
                return Some(VoxelHit {
                    voxel,
                    distance: walk.entered_at,
                    point: origin + dir * walk.entered_at,
                    face: walk.face,
                });
            }
            walk.advance();
        }
        None
    }

    /// Whether the segment from `from` to `to` passes through no occupied
    /// voxel other than `target` (the voxel being looked at) and the voxel
    /// holding `from`.
    pub fn line_of_sight(&self, from: &Point3<f64>, to: &Point3<f64>, target: VoxelIndex) -> bool {
        let Some(dir) = (to - from).try_normalize(1e-12) else {
            return true;
        };
        let length = (to - from).norm();
        let start = self.grid.voxel_of(from);
        let mut walk = Walk::new(self, from, &dir);
        while walk.entered_at < length {
            let voxel = VoxelIndex(walk.voxel);
            if voxel == target {
                return true;
            }
            if voxel != start && self.is_occupied(voxel) {
                return false;
            }
            walk.advance();
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::voxel::VoxelGrid;

    /// A small xorshift so the test needs no dependency.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn map(rng: &mut Rng) -> VoxelMap {
        let grid = VoxelGrid::new(0.5, Point3::new(-0.3, 0.2, -1.1));
        let points: Vec<Point3<f64>> = (0..100)
            .map(|_| Point3::new(rng.next() * 6.0, rng.next() * 6.0, rng.next() * 6.0))
            .collect();
        VoxelMap::from_points(grid, &points, 1)
    }

    /// The first occupied voxel by marching in 1 mm steps.
    fn march(
        map: &VoxelMap,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        range: f64,
    ) -> Option<(VoxelIndex, f64)> {
        let d = d.normalize();
        (0..=(range / 1e-3) as usize)
            .map(|i| i as f64 * 1e-3)
            .map(|t| (map.grid.voxel_of(&(o + d * t)), t))
            .find(|(v, _)| map.is_occupied(*v))
    }

    #[test]
    fn cast_finds_the_first_occupied_voxel_as_marching_does() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut hits = 0;
        for _ in 0..10 {
            let map = map(&mut rng);
            for _ in 0..40 {
                let o = Point3::new(rng.next() * 6.0, rng.next() * 6.0, rng.next() * 6.0);
                let d = Vector3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
                let got = map.cast(&o, &d, 8.0);
                let want = march(&map, &o, &d, 8.0);
                match (got, want) {
                    (Some(hit), Some((voxel, t))) => {
                        hits += 1;
                        assert_eq!(hit.voxel, voxel);
                        assert!((hit.distance - t).abs() < 2e-3, "{hit:?} vs {t}");
                        // The entry point lies on the entered face.
                        if let Some(face) = hit.face {
                            let c = map.grid.center(hit.voxel);
                            let n = face.normal();
                            assert!(((hit.point - c).dot(&n) - 0.25).abs() < 1e-9);
                            assert!(n.dot(&d) < 0.0, "entered against the ray");
                        } else {
                            assert_eq!(map.grid.voxel_of(&o), hit.voxel);
                        }
                    }
                    (None, None) => {}
                    // Grazing a voxel corner within the march step.
                    (got, want) => assert!(
                        got.is_some_and(|h| h.distance > 7.99) || want.is_some_and(|w| w.1 > 7.99),
                        "{got:?} vs {want:?}"
                    ),
                }
            }
        }
        assert!(hits > 100, "the test should hit voxels: {hits}");
    }

    #[test]
    fn line_of_sight_is_blocked_only_by_voxels_in_between() {
        let grid = VoxelGrid::new(1.0, Point3::origin());
        let wall = Point3::new(5.5, 0.5, 0.5);
        let target = Point3::new(9.5, 0.5, 0.5);
        let map = VoxelMap::from_points(grid, &[wall, target], 1);
        let eye = Point3::new(0.5, 0.5, 0.5);
        let target_voxel = grid.voxel_of(&target);
        assert!(!map.line_of_sight(&eye, &target, target_voxel));
        let beside = Point3::new(0.5, 3.5, 0.5);
        assert!(map.line_of_sight(&beside, &Point3::new(9.5, 0.9, 0.5), target_voxel));
        // From the far side the wall is behind the target.
        assert!(map.line_of_sight(&Point3::new(14.5, 0.5, 0.5), &target, target_voxel));
        assert!(map.line_of_sight(&eye, &wall, grid.voxel_of(&wall)));
    }
}

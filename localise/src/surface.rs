//! Where a camera ray meets the mapped surface: the first occupied voxel
//! along the ray (3D DDA through the voxel map), refined to the plane fitted
//! to the map points there (KD-tree neighbours, least squares). A voxel is
//! half a metre; the plane puts the hit within the map's own noise.

use nalgebra::{Point3, Vector3};
use postflight_core::map::{FaceSide, SlamMap, VoxelIndex};

/// A ray's hit on the mapped surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    pub point: Point3<f64>,
    /// Unit normal of the surface there, facing the camera.
    pub normal: Vector3<f64>,
    /// Occupied voxel holding the surface point (just inside the surface).
    pub voxel: VoxelIndex,
    /// Distance from the camera, metres.
    pub range: f64,
    /// Angle between the normal and the direction back to the camera, radians.
    pub incidence: f64,
}

impl SurfaceHit {
    /// The hit at `point` on a surface with `normal` (facing the camera),
    /// seen from `origin`.
    pub fn new(
        map: &SlamMap,
        origin: &Point3<f64>,
        point: Point3<f64>,
        normal: Vector3<f64>,
    ) -> Self {
        let to_camera = origin - point;
        let grid = map.voxels.grid;
        Self {
            point,
            normal,
            voxel: grid.voxel_of(&(point - normal * (grid.resolution * 0.02))),
            range: to_camera.norm(),
            incidence: to_camera.normalize().dot(&normal).clamp(-1.0, 1.0).acos(),
        }
    }

    /// The voxel side the surface lies on: the axis the normal is closest
    /// to, with its sign (`+x`, `-z`, ...).
    pub fn face(&self) -> FaceSide {
        FaceSide::nearest(&self.normal)
    }

    /// Oblique ground sampling distance of a camera with focal length
    /// `f_px` pixels: the pixel's footprint on the surface along its most
    /// stretched direction, millimetres (the View model's GSD is the
    /// fronto-parallel one, `range / f`).
    pub fn oblique_gsd_mm(&self, f_px: f64) -> f64 {
        1000.0 * self.range / f_px / self.incidence.cos().max(0.05)
    }
}

/// Map points closer than this to a ray are where it meets the surface, metres.
/// Wide enough to hold several points of a sparse SLAM map.
const RAY_RADIUS: f64 = 0.12;
/// Neighbourhood a plane is fitted to, metres.
const PLANE_RADIUS: f64 = 0.3;
/// Points this far from a plane are not part of it, metres (the map's noise
/// is about 1.5 cm).
const PLANE_INLIER: f64 = 0.035;
/// Fewest points a plane is fitted to.
const PLANE_POINTS: usize = 6;

/// The first surface along the ray from `origin` in unit direction `dir`
/// within `max_range` metres.
pub fn cast(
    map: &SlamMap,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range: f64,
) -> Option<SurfaceHit> {
    let mut from = 0.0;
    // The first hit no plane confirms, used if no confirmed one follows.
    let mut unconfirmed: Option<SurfaceHit> = None;
    let mut passed = 0;
    while from < max_range && passed < MAX_UNCONFIRMED {
        let start = origin + dir * from;
        let Some(hit) = map.voxels.cast(&start, dir, max_range - from) else {
            break;
        };
        let entered = from + hit.distance;
        // Map points of this voxel near the ray: where the ray crosses a
        // surface, the points around the crossing are in a voxel it enters.
        let mut along: Vec<f64> = map
            .points_in(hit.voxel)
            .filter_map(|p| {
                let v = p - origin;
                let t = v.dot(dir);
                (t > 0.0 && (v - dir * t).norm_squared() < RAY_RADIUS * RAY_RADIUS).then_some(t)
            })
            .collect();
        if along.is_empty() {
            // The ray clips a corner of an occupied voxel whose points lie elsewhere.
            from = entered + exit_distance(map, hit.voxel, &(origin + dir * entered), dir);
            continue;
        }
        along.sort_by(f64::total_cmp);
        let first: Vec<f64> = along
            .iter()
            .copied()
            .take_while(|t| *t < along[0] + PLANE_RADIUS)
            .collect();
        let guess = origin + dir * first[first.len() / 2];
        match refine(map, origin, dir, guess) {
            (surface, true) => return Some(surface),
            (surface, false) => {
                // The ray passes an edge closely: look beyond this voxel.
                unconfirmed.get_or_insert(surface);
                passed += 1;
                from = entered + exit_distance(map, hit.voxel, &(origin + dir * entered), dir);
            }
        }
    }
    unconfirmed
}

/// Occupied voxels with points by the ray but no plane crossing it, passed
/// before the first of them is taken.
const MAX_UNCONFIRMED: usize = 10;

/// Distance along the ray from `p` (inside or on `voxel`) to where it leaves the voxel.
fn exit_distance(map: &SlamMap, voxel: VoxelIndex, p: &Point3<f64>, dir: &Vector3<f64>) -> f64 {
    let grid = map.voxels.grid;
    let lo = grid.origin.coords + Vector3::from(voxel.0).cast::<f64>() * grid.resolution;
    let mut exit = f64::INFINITY;
    for a in 0..3 {
        if dir[a].abs() > 1e-12 {
            let wall = if dir[a] > 0.0 {
                lo[a] + grid.resolution
            } else {
                lo[a]
            };
            exit = exit.min((wall - p[a]) / dir[a]);
        }
    }
    exit.max(0.0) + 1e-6
}

/// Intersect the ray with the surface around `guess`. Near an edge or a
/// corner the neighbourhood holds several planes: the surface is the one the
/// ray meets first where that plane has map points all around the crossing
/// (confirmed, `true`); a ray that passes just beside an edge has points on
/// one side only.
fn refine(
    map: &SlamMap,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    guess: Point3<f64>,
) -> (SurfaceHit, bool) {
    let mut near: Vec<Point3<f64>> = Vec::new();
    map.visit_within(&guess, PLANE_RADIUS, |p| near.push(*p));
    let planes = planes(&near);
    let crossing = |plane: &Plane| {
        let n = if plane.normal.dot(dir) > 0.0 {
            -plane.normal
        } else {
            plane.normal
        };
        let denom = n.dot(dir);
        let t = (plane.centre - origin).dot(&n) / denom;
        (denom < -1e-3 && t > 0.0).then(|| (t, origin + dir * t, n))
    };
    let mut best: Option<(f64, Point3<f64>, Vector3<f64>)> = None;
    for plane in &planes {
        let Some((t, p, n)) = crossing(plane) else {
            continue;
        };
        // A plane's extension into free space has no points where the ray
        // crosses it; beside its edge, points on one side only.
        let support: Vec<Vector3<f64>> = plane
            .inliers
            .iter()
            .map(|q| q - p)
            .filter(|d| d.norm() < SUPPORT_RADIUS)
            .collect();
        let offset = support.iter().sum::<Vector3<f64>>() / support.len().max(1) as f64;
        let around = support.len() >= 2 && offset.norm() < MAX_SUPPORT_OFFSET;
        if around && best.is_none_or(|b| t < b.0) {
            best = Some((t, p, n));
        }
    }
    let confirmed = best.is_some();
    // No plane has points around the crossing: the largest plane, else the points.
    let best = best
        .or_else(|| planes.first().and_then(crossing))
        .filter(|(_, p, _)| (p - guess).norm() < PLANE_RADIUS);
    let (point, normal) = best.map_or((guess, -dir), |(_, p, n)| (p, n));
    (SurfaceHit::new(map, origin, point, normal), confirmed)
}

/// A plane found among map points.
struct Plane {
    centre: Point3<f64>,
    normal: Vector3<f64>,
    inliers: Vec<Point3<f64>>,
}

/// Map points near where a ray crosses a plane that show the plane is there, metres.
const SUPPORT_RADIUS: f64 = 0.15;
/// Largest mean offset of those points from the crossing, metres: points
/// all around a crossing average out near it; beside a plane's edge they
/// lie on one side.
const MAX_SUPPORT_OFFSET: f64 = SUPPORT_RADIUS / 2.0;
/// Most planes looked for around one hit (a corner has three).
const MAX_PLANES: usize = 3;
/// Most sample draws per plane; fewer when the planes found so far leave
/// little doubt (adaptive RANSAC, 99% confidence).
const DRAWS: usize = 40;

/// The planes in a neighbourhood, largest first (RANSAC, then a least-squares
/// refit to each plane's inliers), with their inliers.
fn planes(points: &[Point3<f64>]) -> Vec<Plane> {
    let mut rest = points.to_vec();
    let mut found = Vec::new();
    // Deterministic draws: the same map and ray give the same hit.
    let mut state = 0x9E37_79B9_7F4A_7C15u64 ^ points.len() as u64;
    let mut draw = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    while found.len() < MAX_PLANES && rest.len() >= PLANE_POINTS {
        let mut best: Option<(usize, Point3<f64>, Vector3<f64>)> = None;
        let mut needed = DRAWS;
        let mut drawn = 0;
        while drawn < needed {
            drawn += 1;
            let (a, b, c) = (
                rest[draw(rest.len())],
                rest[draw(rest.len())],
                rest[draw(rest.len())],
            );
            let Some(n) = (b - a).cross(&(c - a)).try_normalize(1e-9) else {
                continue;
            };
            let count = rest
                .iter()
                .filter(|p| (*p - a).dot(&n).abs() < PLANE_INLIER)
                .count();
            if best.is_none_or(|b| count > b.0) {
                best = Some((count, a, n));
                let w = count as f64 / rest.len() as f64;
                let draws = (0.01f64).ln() / (1.0 - w.powi(3)).max(1e-12).ln();
                needed = needed.min(draws.ceil().max(1.0) as usize);
            }
        }
        let Some((count, a, n)) = best.filter(|b| b.0 >= PLANE_POINTS) else {
            break;
        };
        let (inliers, outliers): (Vec<Point3<f64>>, Vec<Point3<f64>>) = rest
            .iter()
            .partition(|p| (*p - a).dot(&n).abs() < PLANE_INLIER);
        debug_assert_eq!(inliers.len(), count);
        let (centre, normal) = fit_plane(&inliers).unwrap_or((a, n));
        found.push(Plane {
            centre,
            normal,
            inliers,
        });
        rest = outliers;
    }
    found
}

/// Least-squares plane through enough points: centroid and unit normal.
fn fit_plane(points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    if points.len() < PLANE_POINTS {
        return None;
    }
    postflight_core::map::plane::fit_plane(points)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use postflight_core::map::PointCloud;

    /// A wall in the plane x = 3 (points 5 cm apart, with 1 cm noise) and a
    /// post in front of part of it.
    pub(crate) fn wall() -> SlamMap {
        let mut points = Vec::new();
        let mut k = 0u32;
        for i in 0..200 {
            for j in 0..100 {
                k = k.wrapping_mul(1_103_515_245).wrapping_add(12345);
                let noise = f64::from(k >> 16) / 65536.0 * 0.02 - 0.01;
                points.push(Point3::new(
                    3.0 + noise,
                    -5.0 + f64::from(i) * 0.05,
                    f64::from(j) * 0.05,
                ));
            }
        }
        SlamMap::new(
            PointCloud {
                frame_id: "map".into(),
                points,
                grid: None,
                mesh_spacing_m: None,
            },
            0.5,
        )
        .unwrap()
    }

    #[test]
    fn a_ray_meets_the_wall_at_its_plane() {
        let map = wall();
        let origin = Point3::new(0.0, 0.3, 2.0);
        for target in [Point3::new(3.0, 0.3, 2.0), Point3::new(3.0, -2.1, 4.2)] {
            let dir = (target - origin).normalize();
            let hit = cast(&map, &origin, &dir, 20.0).unwrap();
            assert!(
                (hit.point - target).norm() < 0.02,
                "{:?} vs {target:?}",
                hit.point
            );
            assert!(hit.normal.dot(&-Vector3::x()) > 0.999);
            assert_eq!(hit.face(), "-x");
            assert_eq!(
                hit.voxel,
                VoxelIndex([
                    6,
                    (target.y / 0.5).floor() as i32,
                    (target.z / 0.5).floor() as i32
                ])
            );
            let expected = (dir.dot(&Vector3::x())).acos();
            assert!((hit.incidence - expected).abs() < 0.02);
            assert!((hit.range - (target - origin).norm()).abs() < 0.02);
        }
        // Away from the wall, and beyond range: nothing.
        assert!(cast(&map, &origin, &-Vector3::x(), 20.0).is_none());
        assert!(cast(&map, &origin, &Vector3::x(), 2.0).is_none());
        // GSD: 3 m at 1000 px focal length, face on, is 3 mm per pixel.
        let hit = cast(&map, &origin, &Vector3::x(), 20.0).unwrap();
        assert!((hit.oblique_gsd_mm(1000.0) - 3.0).abs() < 0.03);
    }
}

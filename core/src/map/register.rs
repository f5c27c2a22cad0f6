//! Registering two maps: the rigid motion that puts one SLAM frame onto
//! another (an earlier flight's onto a later one's, as `compare` does; a
//! sortie's onto the first sortie's, as `ingest` does when a SLAM system
//! started afresh after a landing). SLAM frames of a
//! gravity-aligned system (LIO-SAM, FAST-LIO) differ by a shift and a yaw,
//! so a coarse search over yaw with the centroids aligned gives the starts
//! (the best few yaws: a silo fits several) for point-to-plane ICP
//! (neighbours from the later map's KD-tree, each step a 6x6 least-squares
//! solve), which frees all six degrees; the start that ends with the most
//! of the earlier map on the later one wins.

use std::collections::HashMap;

use crate::map::plane::fit_plane;
use crate::map::{SlamMap, VoxelGrid};
use nalgebra::{Isometry3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6};

/// How a registration is done and judged.
#[derive(Debug, Clone, PartialEq)]
pub struct RegisterOptions {
    /// Edge of the voxels the earlier map is thinned to, metres.
    pub sample_m: f64,
    /// Radius of the later map's points a normal is fitted to, metres.
    pub normal_radius_m: f64,
    /// Correspondences further apart are outliers; ICP starts at the first
    /// and narrows to the last.
    pub max_distance_m: [f64; 3],
    /// A point of the earlier map lies on the later one within this, metres.
    pub inlier_m: f64,
    /// Points this far above the earlier map's ground count towards the
    /// overlap, metres (every flight's map has a flat ground).
    pub above_ground_m: f64,
    /// The least share of the earlier map's points on the later one to
    /// trust the registration.
    pub min_overlap: f64,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        Self {
            sample_m: 0.25,
            normal_radius_m: 0.3,
            max_distance_m: [2.0, 0.5, 0.15],
            inlier_m: 0.1,
            above_ground_m: 0.5,
            min_overlap: 0.3,
        }
    }
}

/// Where the earlier flight's frame is in the later one's, and how well
/// the maps agree there.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// `T_after_before`: a point `p` of the earlier map is at `transform * p`.
    pub transform: Isometry3<f64>,
    /// Point-to-plane distance of the inlier correspondences, RMS, metres.
    pub rms_m: f64,
    /// Share of the earlier map's (thinned) points above its ground within
    /// [`RegisterOptions::inlier_m`] of the later map.
    pub overlap: f64,
    /// The thinned earlier map's points above its ground that the overlap
    /// was judged on (a sample of them where a coarse search already found
    /// far too little), and those on the later map.
    pub points: usize,
    pub inliers: usize,
    pub iterations: usize,
    /// The coarse search's yaw, degrees.
    pub coarse_yaw_deg: f64,
}

/// Why two maps could not be registered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegisterError {
    #[error(
        "the maps overlap in only {:.0}% of the earlier map (at least {:.0}% is needed to trust the alignment); are both maps of the same structure?",
        overlap * 100.0,
        min * 100.0
    )]
    TooLittleOverlap { overlap: f64, min: f64 },
    #[error("the earlier map has too few points to register ({0})")]
    TooFewPoints(usize),
}

/// Register `before` onto `after`.
pub fn register(
    before: &SlamMap,
    after: &SlamMap,
    options: &RegisterOptions,
) -> Result<Registration, RegisterError> {
    let source = thin(&before.cloud.points, options.sample_m);
    if source.len() < 10 {
        return Err(RegisterError::TooFewPoints(source.len()));
    }
    // The fit is judged on the points above the ground: any two maps share
    // a flat ground.
    let structure = above_ground(&source, options.above_ground_m);
    let best = best_alignment(&source, &structure, after, options);
    let overlap = best.fit.overlap();
    if overlap < options.min_overlap {
        return Err(RegisterError::TooLittleOverlap {
            overlap,
            min: options.min_overlap,
        });
    }
    Ok(Registration {
        transform: best.transform,
        rms_m: best.fit.rms_m,
        overlap,
        points: best.fit.points,
        inliers: best.fit.inliers,
        iterations: best.iterations,
        coarse_yaw_deg: best.yaw.to_degrees(),
    })
}

/// Points a coarse start is refined and judged on: a few thousand fix six
/// degrees of freedom roughly as well as all of them, and a start that
/// fits nothing (maps of two structures) runs all its iterations.
const ROUGH_POINTS: usize = 2000;

/// The best registration of `source`, judged by how many of `structure`'s
/// points it puts on `after`. A structure that looks alike from many sides
/// (a silo) fits many coarse yaws about as well: each is refined roughly on
/// [`ROUGH_POINTS`] of the points, then the best two on all of them.
fn best_alignment(
    source: &[Point3<f64>],
    structure: &[Point3<f64>],
    after: &SlamMap,
    options: &RegisterOptions,
) -> Alignment {
    let mut normals = Normals::new(after, options.normal_radius_m);
    let rough_sample = |points: &[Point3<f64>]| {
        let step = points.len().div_ceil(ROUGH_POINTS).max(1);
        points.iter().step_by(step).copied().collect::<Vec<_>>()
    };
    let (probe, structure_probe) = (rough_sample(source), rough_sample(structure));
    let rough = &options.max_distance_m[..2];
    let mut starts: Vec<Alignment> = coarse_alignments(source, after, options)
        .into_iter()
        .map(|(start, yaw)| {
            let (transform, iterations) = icp(&probe, after, &mut normals, start, rough);
            let fit = fit(
                &structure_probe,
                after,
                &mut normals,
                &transform,
                options.inlier_m,
            );
            Alignment {
                transform,
                iterations,
                yaw,
                fit,
            }
        })
        .collect();
    starts.sort_by(|a, b| b.fit.better(&a.fit));
    // Far too little overlap from every start: maps of two structures,
    // which refining on all the points would not change.
    if starts[0].fit.overlap() < options.min_overlap / 2.0 {
        return starts.swap_remove(0);
    }
    starts
        .into_iter()
        .take(2)
        .map(|rough| {
            let (transform, iterations) = icp(
                source,
                after,
                &mut normals,
                rough.transform,
                &options.max_distance_m,
            );
            let fit = fit(structure, after, &mut normals, &transform, options.inlier_m);
            Alignment {
                transform,
                iterations,
                yaw: rough.yaw,
                fit,
            }
        })
        .max_by(|a, b| a.fit.better(&b.fit))
        .expect("at least one coarse alignment")
}

/// A registration tried: from the coarse `yaw`, ICP's transform and fit.
struct Alignment {
    transform: Isometry3<f64>,
    iterations: usize,
    yaw: f64,
    fit: Fit,
}

/// One point per occupied voxel of edge `edge`: the centroid of its points.
fn thin(points: &[Point3<f64>], edge: f64) -> Vec<Point3<f64>> {
    let grid = VoxelGrid::new(edge, Point3::origin());
    let mut sums: HashMap<[i32; 3], (Vector3<f64>, usize)> = HashMap::new();
    for p in points {
        let s = sums
            .entry(grid.voxel_of(p).0)
            .or_insert((Vector3::zeros(), 0));
        s.0 += p.coords;
        s.1 += 1;
    }
    let mut thinned: Vec<(&[i32; 3], Point3<f64>)> = sums
        .iter()
        .map(|(k, (sum, n))| (k, Point3::from(sum / *n as f64)))
        .collect();
    // In voxel order, so a registration is the same every run.
    thinned.sort_by_key(|(k, _)| **k);
    thinned.into_iter().map(|(_, p)| p).collect()
}

/// The later map's surface normals, fitted on demand and kept.
struct Normals<'a> {
    map: &'a SlamMap,
    radius: f64,
    known: HashMap<usize, Option<Vector3<f64>>>,
}

impl<'a> Normals<'a> {
    fn new(map: &'a SlamMap, radius: f64) -> Self {
        Self {
            map,
            radius,
            known: HashMap::new(),
        }
    }

    /// The normal of the surface at map point `index` (none where the
    /// points around it make no plane).
    fn at(&mut self, index: usize) -> Option<Vector3<f64>> {
        let (map, radius) = (self.map, self.radius);
        *self.known.entry(index).or_insert_with(|| {
            let near: Vec<Point3<f64>> = map
                .within(&map.cloud.points[index], radius)
                .iter()
                .map(|n| n.point)
                .collect();
            (near.len() >= 6)
                .then(|| fit_plane(&near))
                .flatten()
                .map(|(_, n)| n)
        })
    }
}

/// How many coarse yaws ICP refines.
const COARSE_STARTS: usize = 36;

/// The centroids aligned, at the yaws (of every 2 degrees) under which most
/// of `source` lies near `after`: the best few at least 10 degrees apart,
/// best first, each with its yaw.
fn coarse_alignments(
    source: &[Point3<f64>],
    after: &SlamMap,
    options: &RegisterOptions,
) -> Vec<(Isometry3<f64>, f64)> {
    let centroid = |points: &[Point3<f64>]| {
        Point3::from(points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64)
    };
    let (from, to) = (centroid(source), centroid(&after.cloud.points));
    // A few hundred points judge a yaw as well as all of them.
    let step = (source.len() / 400).max(1);
    let probe: Vec<Point3<f64>> = source.iter().step_by(step).copied().collect();
    let near = options.max_distance_m[1];
    let at_yaw = |yaw: f64| {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
        Isometry3::from_parts(
            Translation3::from(to.coords - rotation * from.coords),
            rotation,
        )
    };
    let score = |t: &Isometry3<f64>| {
        probe
            .iter()
            .map(|p| {
                after
                    .nearest_within(&(t * p), near)
                    .map_or(near, |q| q.distance)
            })
            .sum::<f64>()
    };
    let mut scored: Vec<(f64, f64)> = (0..180)
        .map(|k| f64::from(k) * 2f64.to_radians())
        .map(|yaw| (score(&at_yaw(yaw)), yaw))
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut starts: Vec<f64> = Vec::new();
    for (_, yaw) in scored {
        let apart = |other: &f64| {
            let d = (yaw - other).rem_euclid(std::f64::consts::TAU);
            d.min(std::f64::consts::TAU - d) >= 10f64.to_radians()
        };
        if starts.iter().all(apart) {
            starts.push(yaw);
        }
        if starts.len() == COARSE_STARTS {
            break;
        }
    }
    starts.into_iter().map(|yaw| (at_yaw(yaw), yaw)).collect()
}

/// Point-to-plane ICP from `start`, narrowing the outlier distance in
/// stages; the transform and the iterations it took.
fn icp(
    source: &[Point3<f64>],
    after: &SlamMap,
    normals: &mut Normals,
    start: Isometry3<f64>,
    max_distances_m: &[f64],
) -> (Isometry3<f64>, usize) {
    const MAX_ITERATIONS: usize = 30;
    let mut transform = start;
    let mut iterations = 0;
    for &max_distance in max_distances_m {
        for _ in 0..MAX_ITERATIONS {
            iterations += 1;
            let Some(step) = icp_step(source, after, normals, &transform, max_distance) else {
                break;
            };
            transform = step * transform;
            if step.translation.vector.norm() < 1e-5 && step.rotation.angle() < 1e-6 {
                break;
            }
        }
    }
    (transform, iterations)
}

/// One linearised point-to-plane step: the small motion that best brings
/// the transformed source points onto the planes of their nearest later
/// points (none without enough correspondences).
fn icp_step(
    source: &[Point3<f64>],
    after: &SlamMap,
    normals: &mut Normals,
    transform: &Isometry3<f64>,
    max_distance: f64,
) -> Option<Isometry3<f64>> {
    let mut ata = Matrix6::<f64>::zeros();
    let mut atb = Vector6::<f64>::zeros();
    let mut used = 0;
    for p in source {
        let p = transform * p;
        let Some(q) = after.nearest_within(&p, max_distance) else {
            continue;
        };
        let Some(n) = normals.at(q.index) else {
            continue;
        };
        // Residual (p - q) . n; d/d(omega, t) = (p x n, n).
        let row = Vector6::new(
            p.y * n.z - p.z * n.y,
            p.z * n.x - p.x * n.z,
            p.x * n.y - p.y * n.x,
            n.x,
            n.y,
            n.z,
        );
        let r = (p - q.point).dot(&n);
        ata += row * row.transpose();
        atb -= row * r;
        used += 1;
    }
    if used < 6 {
        return None;
    }
    let x = ata.cholesky()?.solve(&atb);
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2]));
    Some(Isometry3::from_parts(
        Translation3::new(x[3], x[4], x[5]),
        rotation,
    ))
}

/// The points more than `height` above the ground: the 5th percentile of
/// the heights (SLAM maps of a gravity-aligned system are z up).
fn above_ground(points: &[Point3<f64>], height: f64) -> Vec<Point3<f64>> {
    let mut z: Vec<f64> = points.iter().map(|p| p.z).collect();
    z.sort_by(f64::total_cmp);
    let ground = z.get(z.len() / 20).copied().unwrap_or(0.0);
    points
        .iter()
        .filter(|p| p.z > ground + height)
        .copied()
        .collect()
}

/// How well points lie on `after` under a transform.
struct Fit {
    inliers: usize,
    /// The points judged.
    points: usize,
    rms_m: f64,
}

impl Fit {
    /// The share of the points judged that lie on the map.
    fn overlap(&self) -> f64 {
        self.inliers as f64 / self.points.max(1) as f64
    }

    /// More inliers, then a smaller residual, is better.
    fn better(&self, other: &Fit) -> std::cmp::Ordering {
        self.inliers
            .cmp(&other.inliers)
            .then(other.rms_m.total_cmp(&self.rms_m))
    }
}

fn fit(
    points: &[Point3<f64>],
    after: &SlamMap,
    normals: &mut Normals,
    transform: &Isometry3<f64>,
    inlier_m: f64,
) -> Fit {
    let (mut inliers, mut squares) = (0, 0.0);
    for p in points {
        let p = transform * p;
        let Some(q) = after.nearest_within(&p, inlier_m) else {
            continue;
        };
        inliers += 1;
        let r = normals
            .at(q.index)
            .map_or(q.distance, |n| (p - q.point).dot(&n));
        squares += r * r;
    }
    Fit {
        inliers,
        points: points.len(),
        rms_m: if inliers > 0 {
            (squares / inliers as f64).sqrt()
        } else {
            f64::NAN
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::PointCloud;

    /// An L-shaped wall with a floor and a pillar: enough planes in every
    /// direction to pin all six degrees.
    fn structure() -> Vec<Point3<f64>> {
        let mut points = Vec::new();
        let mut jitter = 0.0_f64;
        let mut next = || {
            jitter = (jitter * 997.0 + 0.123).fract();
            (jitter - 0.5) * 0.01
        };
        for i in 0..80 {
            for j in 0..30 {
                let (a, b) = (f64::from(i) * 0.1, f64::from(j) * 0.1);
                points.push(Point3::new(a, next(), b));
                points.push(Point3::new(next(), a, b));
                points.push(Point3::new(a, b, next()));
                if i < 20 {
                    points.push(Point3::new(
                        4.0 + 0.5 * (a * 3.0).cos(),
                        3.0 + 0.5 * (a * 3.0).sin(),
                        b + next(),
                    ));
                }
            }
        }
        points
    }

    fn map(points: Vec<Point3<f64>>) -> SlamMap {
        SlamMap::new(
            PointCloud {
                points,
                ..Default::default()
            },
            0.5,
        )
        .unwrap()
    }

    #[test]
    fn icp_recovers_a_shift_and_a_yaw_to_millimetres() {
        let truth = Isometry3::from_parts(
            Translation3::new(0.5, -0.3, 0.1),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 10f64.to_radians()),
        );
        let before = structure();
        let after: Vec<Point3<f64>> = before.iter().map(|p| truth * p).collect();
        let r = register(&map(before), &map(after), &RegisterOptions::default()).unwrap();
        let error = r.transform.inverse() * truth;
        assert!(error.translation.vector.norm() < 0.005, "{error:?}");
        assert!(error.rotation.angle().to_degrees() < 0.05, "{error:?}");
        assert!(r.overlap > 0.95 && r.rms_m < 0.01, "{r:?}");
    }

    #[test]
    fn maps_of_different_places_are_refused_though_their_grounds_agree() {
        let before = structure();
        // The same ground, and on it a lone round pole instead of walls.
        let mut after: Vec<Point3<f64>> = before
            .iter()
            .filter(|p| p.z.abs() < 0.01)
            .copied()
            .collect();
        for i in 0..60 {
            for j in 0..30 {
                let a = f64::from(i) * std::f64::consts::TAU / 60.0;
                after.push(Point3::new(
                    3.0 + 0.3 * a.cos(),
                    3.0 + 0.3 * a.sin(),
                    f64::from(j) * 0.1,
                ));
            }
        }
        let e = register(&map(before), &map(after), &RegisterOptions::default()).unwrap_err();
        assert!(matches!(e, RegisterError::TooLittleOverlap { .. }), "{e}");
    }
}

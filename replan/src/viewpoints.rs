//! Candidate viewpoints for the gaps and their clusters, GATSBI-style:
//! around every exposed face of a gap voxel, the standpoints of `reach`
//! (across the distance band and the incidence limit) are moved to their
//! voxel's centre; each clear one becomes a viewpoint aimed at the face,
//! and the coverage stage's own View model judges which gap voxels it
//! inspects. A greedy set cover of the gaps keeps a few viewpoints
//! that inspect them all; a gap voxel's cluster is those of them that
//! inspect it.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashSet};

use coverage::cover::{Shot, judge};
use coverage::face::Face;
use coverage::reach::standpoints;
use coverage::stage::viewpoint_camera;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Isometry3, Point3};
use postflight_core::map::{SlamMap, VoxelIndex};
use postflight_core::{Intrinsics, ViewModel, Viewpoint};
use rayon::prelude::*;

use crate::free_space::FreeSpace;

/// A viewpoint that inspects at least one gap voxel.
#[derive(Debug, Clone)]
pub struct Candidate {
    pub viewpoint: Viewpoint,
    /// Gap voxels it inspects (indices into the gap list), ascending.
    pub inspects: Vec<usize>,
}

/// Largest cluster kept per gap voxel: the viewpoints inspecting the most
/// gap voxels, then the nearest...
pub const MAX_CLUSTER: usize = 12;
/// ...and fewer when there are many gaps, down to [`MIN_CLUSTER`], to keep
/// the GTSP's vertices (its costs are a dense matrix) about this many.
pub const VERTEX_BUDGET: usize = 4000;
pub const MIN_CLUSTER: usize = 2;

/// What the candidates need to know about the camera and the rules.
pub struct Camera<'a> {
    pub lens: &'a Intrinsics,
    /// Body to optical frame.
    pub extrinsic: &'a Isometry3<f64>,
    pub view: &'a ViewModel,
    /// The band's far edge, or nearer if the GSD target asks.
    pub max_distance_m: f64,
}

/// Yaw and gimbal pitch that put `target` on the optical axis of a camera
/// on a body at `body` (the mount's offset is allowed for).
pub fn aim(body: &Point3<f64>, target: &Point3<f64>, extrinsic: &Isometry3<f64>) -> Viewpoint {
    let mut v = Viewpoint {
        position: body.coords.into(),
        yaw: 0.0,
        gimbal_pitch: 0.0,
    };
    // The camera centre moves with the aim; a few rounds settle it.
    for _ in 0..4 {
        let centre = Point3::from(viewpoint_camera(&v, extrinsic).translation.vector);
        let d = (target - centre).normalize();
        v.yaw = d.y.atan2(d.x);
        v.gimbal_pitch = (-d.z).clamp(-1.0, 1.0).asin();
    }
    v
}

/// Viewpoints inspecting the gap voxels `gaps` through their exposed
/// `faces` (each face's voxel is one of `gaps`), from clear points of
/// `space`. `progress` is told faces done.
pub fn candidates(
    gaps: &[VoxelIndex],
    faces: &[Face],
    map: &SlamMap,
    space: &FreeSpace,
    camera: &Camera,
    progress: &(dyn Fn(usize) + Sync),
) -> Vec<Candidate> {
    let grid = map.voxels.grid;
    // Clear voxel centres near each face, aimed at it; one per (voxel, face).
    let done = std::sync::atomic::AtomicUsize::new(0);
    let mut aimed: Vec<(VoxelIndex, usize)> = faces
        .par_iter()
        .enumerate()
        .flat_map_iter(|(fi, face)| {
            let mut seen = HashSet::new();
            let out: Vec<(VoxelIndex, usize)> =
                standpoints(face, camera.view, camera.max_distance_m)
                    .into_iter()
                    .map(|p| grid.voxel_of(&p))
                    .filter(|v| seen.insert(*v) && space.point_is_clear(&grid.center(*v)))
                    .map(|v| (v, fi))
                    .collect();
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            out
        })
        .collect();
    aimed.sort_unstable_by_key(|(v, fi)| (v.0, *fi));

    let coords: Vec<[f64; 3]> = faces.iter().map(|f| f.centre.coords.into()).collect();
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(&coords) else {
        return Vec::new();
    };
    let gap_index = |v: VoxelIndex| gaps.binary_search(&v).expect("faces belong to gap voxels");
    let r2 = camera.view.max_distance_m * camera.view.max_distance_m;
    let mut found: Vec<Candidate> = aimed
        .par_iter()
        .filter_map(|&(v, fi)| {
            let viewpoint = aim(&grid.center(v), &faces[fi].centre, camera.extrinsic);
            let shot = Shot {
                id: 0,
                camera: viewpoint_camera(&viewpoint, camera.extrinsic),
                lens: 0,
                blur_px: Some(0.0),
            };
            let c = shot.camera.translation.vector;
            let mut inspects = Vec::new();
            tree.query(&[c.x, c.y, c.z])
                .within::<SquaredEuclidean<f64>>(r2)
                .unsorted()
                .visit(|hit| {
                    let face = &faces[hit.item as usize];
                    let lenses = std::slice::from_ref(camera.lens);
                    if judge(face, &shot, lenses, map, camera.view).is_ok() {
                        inspects.push(gap_index(face.voxel));
                    }
                });
            inspects.sort_unstable();
            inspects.dedup();
            (!inspects.is_empty()).then_some(Candidate {
                viewpoint,
                inspects,
            })
        })
        .collect();
    // The same voxel aimed at faces that give the same gaps: one is enough.
    found.dedup_by(|b, a| a.viewpoint.position == b.viewpoint.position && a.inspects == b.inspects);
    found
}

/// A greedy set cover of the gaps (`gaps` of them) by the candidates:
/// repeatedly the candidate inspecting the most gaps not yet inspected
/// (ties to the lower index). Returns the chosen candidates' indices.
///
/// Lazily: a candidate's count only falls as gaps are covered, so counts
/// are kept in a heap and recounted only when they come to the top.
pub fn set_cover(candidates: &[Candidate], gaps: usize) -> Vec<usize> {
    let mut open = vec![true; gaps];
    let open_count = |c: &Candidate, open: &[bool]| c.inspects.iter().filter(|g| open[**g]).count();
    let mut heap: BinaryHeap<(usize, Reverse<usize>)> = candidates
        .iter()
        .enumerate()
        .map(|(k, c)| (open_count(c, &open), Reverse(k)))
        .filter(|(n, _)| *n > 0)
        .collect();
    let mut chosen = Vec::new();
    while let Some((n, Reverse(k))) = heap.pop() {
        let now = open_count(&candidates[k], &open);
        if now < n {
            if now > 0 {
                heap.push((now, Reverse(k)));
            }
            continue;
        }
        for g in &candidates[k].inspects {
            open[*g] = false;
        }
        chosen.push(k);
    }
    chosen
}

/// The cluster of each gap voxel among the candidates `allowed` (indices):
/// up to [`MAX_CLUSTER`] of them (fewer for many gaps) that inspect it,
/// those inspecting most gap voxels first, then the nearest.
pub fn clusters(
    gaps: &[VoxelIndex],
    candidates: &[Candidate],
    allowed: &[usize],
    centre: impl Fn(VoxelIndex) -> Point3<f64>,
) -> Vec<Vec<usize>> {
    let mut by_gap: Vec<Vec<usize>> = vec![Vec::new(); gaps.len()];
    for &k in allowed {
        for &g in &candidates[k].inspects {
            by_gap[g].push(k);
        }
    }
    let keep = (VERTEX_BUDGET / gaps.len().max(1)).clamp(MIN_CLUSTER, MAX_CLUSTER);
    for (g, members) in by_gap.iter_mut().enumerate() {
        let at = centre(gaps[g]);
        members.sort_by(|&a, &b| {
            let (ca, cb) = (&candidates[a], &candidates[b]);
            let da = (Point3::from(ca.viewpoint.position) - at).norm();
            let db = (Point3::from(cb.viewpoint.position) - at).norm();
            cb.inspects
                .len()
                .cmp(&ca.inspects.len())
                .then(da.total_cmp(&db))
                .then(a.cmp(&b))
        });
        members.truncate(keep);
    }
    by_gap
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain greedy: recount every candidate each time.
    fn eager_set_cover(candidates: &[Candidate], gaps: usize) -> Vec<usize> {
        let mut open = vec![true; gaps];
        let mut chosen = Vec::new();
        loop {
            let best = candidates
                .iter()
                .enumerate()
                .map(|(k, c)| (c.inspects.iter().filter(|g| open[**g]).count(), k))
                .max_by(|a, b| a.0.cmp(&b.0).then(b.1.cmp(&a.1)));
            match best {
                Some((n, k)) if n > 0 => {
                    for g in &candidates[k].inspects {
                        open[*g] = false;
                    }
                    chosen.push(k);
                }
                _ => return chosen,
            }
        }
    }

    #[test]
    fn the_lazy_set_cover_chooses_as_the_plain_greedy_does() {
        // 300 candidates over 500 gaps, overlapping at random, many ties.
        let mut state = 12345u64;
        let mut next = |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let candidates: Vec<Candidate> = (0..300)
            .map(|_| {
                let mut inspects: Vec<usize> =
                    (0..1 + next(12)).map(|_| next(500) as usize).collect();
                inspects.sort_unstable();
                inspects.dedup();
                Candidate {
                    viewpoint: Viewpoint {
                        position: [0.0; 3],
                        yaw: 0.0,
                        gimbal_pitch: 0.0,
                    },
                    inspects,
                }
            })
            .collect();
        let lazy = set_cover(&candidates, 500);
        assert_eq!(lazy, eager_set_cover(&candidates, 500));
        assert!(lazy.len() > 50, "{}", lazy.len());
    }
}

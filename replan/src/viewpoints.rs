//! Candidate viewpoints for the gaps and their clusters, GATSBI-style:
//! around every exposed face of a gap voxel, the standpoints of `reach`
//! (across the distance band and the incidence limit) are moved to their
//! voxel's centre; each clear one becomes a viewpoint aimed at the face,
//! and the coverage stage's own View model judges which gap voxels it
//! inspects. A greedy set cover of the gaps keeps a few viewpoints
//! that inspect them all; a gap voxel's cluster is those of them that
//! inspect it.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap, HashSet};

use coverage::cover::{Shot, judge};
use coverage::face::Face;
use coverage::reach::standpoints;
use coverage::shots::viewpoint_camera;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Isometry3, Point3};
use postflight_core::FaceSide;
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
    /// The faces it inspects them through: (gap, side), ascending.
    pub faces: Vec<(usize, FaceSide)>,
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
    /// How far above the horizon the gimbal can look, radians.
    pub max_gimbal_up: f64,
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
            if -viewpoint.gimbal_pitch > camera.max_gimbal_up {
                return None;
            }
            let shot = Shot {
                id: 0,
                camera: viewpoint_camera(&viewpoint, camera.extrinsic),
                lens: 0,
                blur_px: Some(0.0),
            };
            let c = shot.camera.translation.vector;
            let mut faces_seen = Vec::new();
            tree.query(&[c.x, c.y, c.z])
                .within::<SquaredEuclidean<f64>>(r2)
                .unsorted()
                .visit(|hit| {
                    let face = &faces[hit.item as usize];
                    let lenses = std::slice::from_ref(camera.lens);
                    if judge(face, &shot, lenses, map, camera.view).is_ok() {
                        faces_seen.push((gap_index(face.voxel), face.side));
                    }
                });
            faces_seen.sort_unstable();
            let mut inspects: Vec<usize> = faces_seen.iter().map(|(g, _)| *g).collect();
            inspects.dedup();
            (!inspects.is_empty()).then_some(Candidate {
                viewpoint,
                inspects,
                faces: faces_seen,
            })
        })
        .collect();
    // The same voxel aimed at faces that give the same gaps: one is enough.
    found.dedup_by(|b, a| a.viewpoint.position == b.viewpoint.position && a.inspects == b.inspects);
    found
}

/// Views of a gap count only on one face (coverage counts views face by
/// face), so a gap needing several is seen through one face: the one
/// most candidates inspect. Other candidates no longer count for it.
pub fn one_face_for_several_views(candidates: &mut [Candidate], views: &[u32]) {
    let mut seen: HashMap<(usize, FaceSide), usize> = HashMap::new();
    for c in candidates.iter() {
        for &(g, side) in &c.faces {
            if views[g] > 1 {
                *seen.entry((g, side)).or_default() += 1;
            }
        }
    }
    let mut best: HashMap<usize, (usize, FaceSide)> = HashMap::new();
    for (&(g, side), &n) in &seen {
        let e = best.entry(g).or_insert((n, side));
        if (n, side) > *e {
            *e = (n, side);
        }
    }
    for c in candidates.iter_mut() {
        c.inspects.retain(|g| match best.get(g) {
            Some(&(_, side)) => c.faces.binary_search(&(*g, side)).is_ok(),
            None => true,
        });
    }
}

/// A greedy multi-cover of the gaps by the candidates: repeatedly the
/// candidate inspecting the most gaps that still need a view (ties to the
/// lower index), until each gap `g` has `views[g]` chosen candidates
/// inspecting it, or no candidate is left for it. Returns the chosen
/// candidates' indices.
///
/// Lazily: a candidate's count only falls as gaps get their views, so
/// counts are kept in a heap and recounted only when they come to the top.
pub fn set_cover(candidates: &[Candidate], views: &[u32]) -> Vec<usize> {
    let mut open: Vec<u32> = views.to_vec();
    let open_count =
        |c: &Candidate, open: &[u32]| c.inspects.iter().filter(|g| open[**g] > 0).count();
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
            open[*g] = open[*g].saturating_sub(1);
        }
        chosen.push(k);
    }
    chosen
}

/// The tour's clusters: for each gap voxel, as many as the views it needs,
/// of which the tour visits one each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Clusters {
    /// Each cluster's candidates (indices).
    pub members: Vec<Vec<usize>>,
    /// Each cluster's gap voxel (an index into the gap list).
    pub gap: Vec<usize>,
}

/// The clusters of each gap voxel among the candidates `allowed`
/// (indices): of those that inspect it, up to [`MAX_CLUSTER`] a view
/// (fewer for many gaps), those inspecting most gap voxels first, then the
/// nearest. A gap needing `views[g]` views gets that many clusters, none
/// sharing a candidate, so the tour takes as many distinct viewpoints;
/// the candidates are dealt to them in turn around the gap (by bearing),
/// so that each cluster has views from every side. A cluster may be empty:
/// fewer candidates than views.
pub fn clusters(
    gaps: &[VoxelIndex],
    candidates: &[Candidate],
    allowed: &[usize],
    views: &[u32],
    centre: impl Fn(VoxelIndex) -> Point3<f64>,
) -> Clusters {
    let mut by_gap: Vec<Vec<usize>> = vec![Vec::new(); gaps.len()];
    for &k in allowed {
        for &g in &candidates[k].inspects {
            by_gap[g].push(k);
        }
    }
    let wanted: usize = views.iter().map(|&v| v.max(1) as usize).sum();
    let keep = (VERTEX_BUDGET / wanted.max(1)).clamp(MIN_CLUSTER, MAX_CLUSTER);
    let mut out = Clusters::default();
    for (g, mut members) in by_gap.into_iter().enumerate() {
        let at = centre(gaps[g]);
        let position = |k: usize| Point3::from(candidates[k].viewpoint.position);
        members.sort_by(|&a, &b| {
            let (da, db) = ((position(a) - at).norm(), (position(b) - at).norm());
            candidates[b]
                .inspects
                .len()
                .cmp(&candidates[a].inspects.len())
                .then(da.total_cmp(&db))
                .then(a.cmp(&b))
        });
        let n = views[g].max(1) as usize;
        members.truncate(keep * n);
        if n > 1 {
            let bearing = |k: usize| {
                let d = position(k) - at;
                d.y.atan2(d.x)
            };
            members.sort_by(|&a, &b| bearing(a).total_cmp(&bearing(b)).then(a.cmp(&b)));
        }
        let mut dealt = vec![Vec::new(); n];
        for (i, k) in members.into_iter().enumerate() {
            dealt[i % n].push(k);
        }
        for cluster in dealt {
            out.members.push(cluster);
            out.gap.push(g);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain greedy: recount every candidate each time.
    fn eager_set_cover(candidates: &[Candidate], views: &[u32]) -> Vec<usize> {
        let mut open = views.to_vec();
        let mut chosen = Vec::new();
        loop {
            let best = candidates
                .iter()
                .enumerate()
                .filter(|(k, _)| !chosen.contains(k))
                .map(|(k, c)| (c.inspects.iter().filter(|g| open[**g] > 0).count(), k))
                .max_by(|a, b| a.0.cmp(&b.0).then(b.1.cmp(&a.1)));
            match best {
                Some((n, k)) if n > 0 => {
                    for g in &candidates[k].inspects {
                        open[*g] = open[*g].saturating_sub(1);
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
                    faces: inspects.iter().map(|&g| (g, FaceSide::PosX)).collect(),
                    inspects,
                }
            })
            .collect();
        let one = vec![1; 500];
        let lazy = set_cover(&candidates, &one);
        assert_eq!(lazy, eager_set_cover(&candidates, &one));
        assert!(lazy.len() > 50, "{}", lazy.len());
        // Some gaps needing two or three views: more candidates, each
        // chosen once, and every gap with its views where candidates allow.
        let views: Vec<u32> = (0..500).map(|g| 1 + (g % 3) as u32).collect();
        let multi = set_cover(&candidates, &views);
        assert_eq!(multi, eager_set_cover(&candidates, &views));
        assert!(multi.len() > lazy.len());
        let mut seen = vec![0u32; 500];
        let mut able = vec![0u32; 500];
        for c in &candidates {
            c.inspects.iter().for_each(|g| able[*g] += 1);
        }
        for k in &multi {
            candidates[*k].inspects.iter().for_each(|g| seen[*g] += 1);
        }
        for g in 0..500 {
            assert!(seen[g] >= views[g].min(able[g]), "gap {g}");
        }
    }

    #[test]
    fn a_gap_needing_two_views_gets_two_clusters_sharing_no_candidate() {
        // Eight candidates around one gap at the origin, and one gap beside.
        let around: Vec<Candidate> = (0..8)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::FRAC_PI_4;
                Candidate {
                    viewpoint: Viewpoint {
                        position: [3.0 * a.cos(), 3.0 * a.sin(), 0.0],
                        yaw: 0.0,
                        gimbal_pitch: 0.0,
                    },
                    inspects: if i == 0 { vec![0, 1] } else { vec![0] },
                    faces: Vec::new(),
                }
            })
            .collect();
        let gaps = [VoxelIndex([0, 0, 0]), VoxelIndex([1, 0, 0])];
        let all: Vec<usize> = (0..8).collect();
        let c = clusters(&gaps, &around, &all, &[2, 1], |_| Point3::origin());
        assert_eq!(c.gap, vec![0, 0, 1]);
        assert_eq!(c.members[2], vec![0]);
        let (a, b) = (&c.members[0], &c.members[1]);
        assert_eq!(a.len() + b.len(), 8);
        assert!(a.iter().all(|k| !b.contains(k)));
        // Dealt by bearing: each cluster has candidates on both sides.
        for side in [a, b] {
            let ys: Vec<f64> = side
                .iter()
                .map(|&k| around[k].viewpoint.position[1])
                .collect();
            assert!(
                ys.iter().any(|y| *y > 0.1) && ys.iter().any(|y| *y < -0.1),
                "{side:?}"
            );
        }
    }
}

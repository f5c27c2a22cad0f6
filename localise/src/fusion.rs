//! Multi-view fusion: observations of one crack from many frames become one
//! defect candidate. Two placed observations belong together when they lie
//! on the same surface (normals agree, planes coincide) and their extents on
//! it overlap or nearly touch, or sit on two faces meeting at an edge with
//! overlapping extents; candidates are the connected groups.

use std::collections::BTreeMap;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Point3, Vector3};
use postflight_core::map::{FaceSide, VoxelIndex};

use crate::evidence::evidence;
use crate::fused_line::{self, FusedLine, ViewLine};
use crate::observation::{Observation, Placement, measures_length};
use crate::settings::LocaliseConfig;
use crate::stats::median;
use crate::union_find::UnionFind;
use postflight_core::outputs::localise::{Evidence, LengthStatus, Outcome, WidthRecord};
use postflight_core::trace::Trace;
use postflight_core::view::Miss;

/// One physical crack, as the views of it agree.
#[derive(Debug, Clone)]
pub struct DefectCandidate {
    /// Stable name: the surface voxel and face, then a number when one face
    /// of a voxel holds several (`12_-3_4+x`, `12_-3_4+x.2`).
    pub id: String,
    pub position: Point3<f64>,
    /// How far off `position` may be, metres (see [`position_uncertainty`]).
    pub position_uncertainty_m: Option<f64>,
    /// Outward normal of the surface it is on.
    pub normal: Vector3<f64>,
    /// Corners of the axis-aligned box around its observed extent and its
    /// trace.
    pub extent: [Point3<f64>; 2],
    pub voxel: VoxelIndex,
    pub face: FaceSide,
    /// Estimated length, metres: along `trace`, from views
    /// `[localise] length_range_m` or closer (or, when none of those is
    /// complete, its complete views from farther); `None` with no view that
    /// could measure it (traced, not too oblique).
    pub length_m: Option<f64>,
    /// Views its trace is made of.
    pub length_views: u32,
    /// Its centre line on the structure (see [`fused_line`]).
    pub trace: Trace,
    /// Distinct frames that saw it.
    pub frames: u32,
    /// How much the views agree that this is a crack, 0 to 1 (see
    /// [`confidence`]).
    pub confidence: f64,
    pub max_score: f64,
    /// The observation (index) to show a reviewer: complete, then breaking
    /// fewest of the View model's rules, then the finest ground sampling
    /// distance (closest and most frontal).
    pub best: usize,
    /// The best view judged, the length's status, and whether to re-shoot
    /// (its `length` says measured, partial or why missing).
    pub evidence: Evidence,
    /// Its width, from the view that measures it finest (see [`width`]).
    pub width: Option<WidthRecord>,
    /// Indices of its observations, in frame order.
    pub observations: Vec<usize>,
}

/// Faces meeting at an edge are about 90 degrees apart; opposite sides of a
/// thin member are 180 (cosine of 100 degrees).
const EDGE_MIN_COS: f64 = -0.17;
/// A crack's extent larger than this is an error, metres (caps the search).
const MAX_RADIUS: f64 = 3.0;
/// How far behind a lone view's hit another candidate must be for the
/// view to be taken as that candidate's, metres: another surface.
const BEHIND_M: f64 = 0.3;

/// A view alone in its group whose line of sight passes close by an edge
/// can be placed on the edge's faces, in front of the crack it shows (a
/// millimetre of pose decides it). When its box holds the centre of a group
/// of several views farther along the line of sight (by more than
/// [`BEHIND_M`]), the view joins that group (the nearest such).
fn rejoin_lone_views(observations: &[Observation], placed: &[usize], groups: &mut UnionFind) {
    let placement = |a: usize| observations[placed[a]].placement.as_ref().expect("placed");
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for a in 0..placed.len() {
        members.entry(groups.root(a)).or_default().push(a);
    }
    let centres: Vec<(usize, Point3<f64>)> = members
        .iter()
        .filter(|(_, m)| m.len() >= 2)
        .map(|(&root, m)| {
            let sum: Vector3<f64> = m.iter().map(|&a| placement(a).centre.coords).sum();
            (root, Point3::from(sum / m.len() as f64))
        })
        .collect();
    for m in members.values().filter(|m| m.len() == 1) {
        let p = placement(m[0]);
        let along = |c: &Point3<f64>| (c - p.sight.origin).norm();
        let behind = centres
            .iter()
            .filter(|(_, c)| p.sight.holds(c) && along(c) > p.hit.range + BEHIND_M)
            .min_by(|x, y| along(&x.1).total_cmp(&along(&y.1)));
        if let Some(&(root, _)) = behind {
            groups.join(m[0], root);
        }
    }
}

/// Fuse the placed observations into candidates, in order of priority
/// (confidence, then length).
pub fn fuse(observations: &[Observation], options: &LocaliseConfig) -> Vec<DefectCandidate> {
    let placed: Vec<usize> = (0..observations.len())
        .filter(|i| observations[*i].outcome == Outcome::Placed)
        .collect();
    let placement = |i: usize| observations[i].placement.as_ref().expect("placed");
    let radius = |i: usize| placement(i).radius.min(MAX_RADIUS);
    let centres: Vec<[f64; 3]> = placed
        .iter()
        .map(|i| placement(*i).centre.coords.into())
        .collect();
    let mut groups = UnionFind::new(placed.len());
    if !placed.is_empty() {
        let tree: ImmutableKdTree<f64, 3> =
            ImmutableKdTree::new_from_slice(&centres).expect("finite observation centres");
        let min_cos = options.max_normal_angle_deg.to_radians().cos();
        for (a, &i) in placed.iter().enumerate() {
            let pa = placement(i);
            // Linked pairs are at most r_a + r_b + link apart: the one with
            // the larger radius finds the other within twice its own.
            let reach = 2.0 * radius(i) + options.link_distance_m;
            for near in tree
                .query(&centres[a])
                .within::<SquaredEuclidean<f64>>(reach * reach)
                .execute()
            {
                let b = near.item as usize;
                if b == a || groups.root(a) == groups.root(b) {
                    continue;
                }
                let pb = placement(placed[b]);
                let apart = (pb.centre - pa.centre).norm();
                let cos = pa.hit.normal.dot(&pb.hit.normal);
                let touch = radius(i) + radius(placed[b]);
                let joined = if cos >= min_cos {
                    // One surface: the planes coincide, the extents nearly touch.
                    (pb.centre - pa.centre).dot(&pa.hit.normal).abs() < options.link_distance_m
                        && apart <= touch + options.link_distance_m
                } else {
                    // Faces at an angle (never opposite sides of a web): rays
                    // grazing an edge place a crack on either face, so the
                    // extents themselves must overlap.
                    cos >= EDGE_MIN_COS && apart <= touch
                };
                if joined {
                    groups.join(a, b);
                }
            }
        }
    }
    rejoin_lone_views(observations, &placed, &mut groups);
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (a, &i) in placed.iter().enumerate() {
        members.entry(groups.root(a)).or_default().push(i);
    }
    let mut candidates: Vec<DefectCandidate> = members
        .into_values()
        .map(|mut group| {
            group.sort_by_key(|i| (observations[*i].detection.frame, *i));
            candidate(observations, group, options)
        })
        .collect();
    name(&mut candidates);
    candidates.sort_by(|a, b| {
        b.confidence
            .total_cmp(&a.confidence)
            .then(
                b.length_m
                    .unwrap_or(0.0)
                    .total_cmp(&a.length_m.unwrap_or(0.0)),
            )
            .then(a.id.cmp(&b.id))
    });
    candidates
}

fn candidate(
    observations: &[Observation],
    group: Vec<usize>,
    options: &LocaliseConfig,
) -> DefectCandidate {
    let placement = |i: usize| observations[i].placement.as_ref().expect("placed");
    let complete: Vec<usize> = group
        .iter()
        .copied()
        .filter(|i| !observations[*i].clipped)
        .collect();
    // Placed by its complete views where it has any: a view the image
    // border cuts places only part of the crack.
    let basis = if complete.is_empty() {
        &group
    } else {
        &complete
    };
    let place = Place::of(&basis.iter().map(|i| placement(*i)).collect::<Vec<_>>());
    let measured = length_views(&group, &complete, options.length_range_m, &placement);
    let lines: Vec<ViewLine> = measured
        .iter()
        .map(|i| {
            let p = placement(*i);
            ViewLine {
                trace: &p.trace,
                cut: &p.cut,
                frame: observations[*i].detection.frame,
                near: NEAR_PX * p.oblique_gsd_mm / 1000.0,
            }
        })
        .collect();
    let fused = fused_line::fuse(&lines, options.link_distance_m);
    // The views the trace was carried on with, cut by the image border, are
    // not in the basis: the extent covers the trace too.
    let extent = fused
        .as_ref()
        .map_or(place.extent, |f| covering(place.extent, &f.trace));
    let best = best_view(basis, &placement);
    let status = length_status(&group, &measured, fused.as_ref(), &placement);
    let per_frame = best_score_per_frame(observations, &group);
    let mut scores: Vec<f64> = per_frame.values().copied().collect();
    scores.sort_by(|a, b| b.total_cmp(a));
    let off_surface: Vec<f64> = group
        .iter()
        .map(|i| (placement(*i).centre - place.position).dot(&place.normal))
        .collect();
    DefectCandidate {
        id: String::new(),
        position: place.position,
        position_uncertainty_m: place.uncertainty_m,
        normal: place.normal,
        extent,
        voxel: placement(best).hit.voxel,
        face: FaceSide::nearest(&place.normal),
        length_m: fused.as_ref().map(|f| f.length_m),
        length_views: fused.as_ref().map_or(0, |f| f.views),
        trace: fused.map(|f| f.trace).unwrap_or_default(),
        frames: per_frame.len() as u32,
        confidence: confidence(&scores, &off_surface),
        max_score: scores[0],
        best,
        evidence: evidence(placement(best), status),
        width: width(group.iter().filter_map(|i| placement(*i).width)),
        observations: group,
    }
}

/// Where a candidate is, from the views that place it.
struct Place {
    /// Component-wise medians: one view with a bad pose does not move it.
    position: Point3<f64>,
    uncertainty_m: Option<f64>,
    normal: Vector3<f64>,
    extent: [Point3<f64>; 2],
}

impl Place {
    fn of(views: &[&Placement]) -> Self {
        let position = Point3::from(Vector3::from_fn(|a, _| {
            median(views.iter().map(|p| p.centre[a]).collect()).expect("a member")
        }));
        Self {
            position,
            uncertainty_m: position_uncertainty(views.iter().copied(), &position),
            normal: views
                .iter()
                .map(|p| p.hit.normal)
                .sum::<Vector3<f64>>()
                .normalize(),
            extent: views.iter().fold(views[0].extent, |[lo, hi], p| {
                [lo.inf(&p.extent[0]), hi.sup(&p.extent[1])]
            }),
        }
    }
}

/// The views a candidate's length is measured from. Every view shows at
/// most the whole crack (faint or hidden stretches and the image border
/// only shorten it), so the longest near view, complete or cut, is the
/// estimate; complete views from farther count only when no near view
/// measured it.
fn length_views<'a>(
    group: &[usize],
    complete: &[usize],
    length_range_m: f64,
    placement: &dyn Fn(usize) -> &'a Placement,
) -> Vec<usize> {
    let measuring = |views: &[usize], max_range: f64| -> Vec<usize> {
        views
            .iter()
            .copied()
            .filter(|i| placement(*i).hit.range <= max_range && placement(*i).length_m.is_some())
            .collect()
    };
    let measured = measuring(group, length_range_m);
    if !measured.iter().any(|i| complete.contains(i)) {
        let far = measuring(complete, f64::INFINITY);
        if !far.is_empty() {
            return far;
        }
    }
    measured
}

/// The view to show and judge a candidate by: the fewest View model rules
/// broken, then the finest GSD.
fn best_view<'a>(basis: &[usize], placement: &dyn Fn(usize) -> &'a Placement) -> usize {
    *basis
        .iter()
        .min_by(|a, b| {
            let (pa, pb) = (placement(**a), placement(**b));
            pa.view_faults
                .len()
                .cmp(&pb.view_faults.len())
                .then(pa.oblique_gsd_mm.total_cmp(&pb.oblique_gsd_mm))
        })
        .expect("a member")
}

/// The best detection score in each frame that saw the candidate.
fn best_score_per_frame(observations: &[Observation], group: &[usize]) -> BTreeMap<u32, f64> {
    let mut per_frame: BTreeMap<u32, f64> = BTreeMap::new();
    for i in group {
        let d = &observations[*i].detection;
        let s = per_frame.entry(d.frame).or_default();
        *s = s.max(f64::from(d.detection.score));
    }
    per_frame
}

/// How far off a candidate at `position` may be (one standard deviation)
/// from the views it is the median of: their scatter about it over the
/// square root of their number, and their cameras' accuracy (the median)
/// in full, as RTK errors run from photo to photo; `None` from one view of
/// a camera of unknown accuracy.
fn position_uncertainty<'a>(
    views: impl ExactSizeIterator<Item = &'a Placement>,
    position: &Point3<f64>,
) -> Option<f64> {
    let n = views.len() as f64;
    let (squares, cameras): (Vec<f64>, Vec<Option<f64>>) = views
        .map(|p| ((p.centre - position).norm_squared(), p.camera_std_m))
        .unzip();
    let scatter = (n >= 2.0).then(|| squares.iter().sum::<f64>() / (n - 1.0) / n);
    let camera = median(cameras.into_iter().flatten().collect()).map(|s| s * s);
    match (scatter, camera) {
        (None, None) => None,
        (s, c) => Some((s.unwrap_or(0.0) + c.unwrap_or(0.0)).sqrt()),
    }
}

/// The box `extent` grown to cover every point of `trace`.
fn covering(extent: [Point3<f64>; 2], trace: &Trace) -> [Point3<f64>; 2] {
    trace
        .0
        .iter()
        .flatten()
        .map(|p| Point3::from(*p))
        .fold(extent, |[lo, hi], p| [lo.inf(&p), hi.sup(&p)])
}

/// Two lines of a view within this many pixels' footprint are one stretch.
const NEAR_PX: f64 = 3.0;

/// A candidate's width from its views' measures, by resolution: of the
/// views that measured it with about the fewest millimetres per pixel
/// across the crack (within [`AS_FINE`]), the widest, since views of one
/// frame (or of frames alike) each show a stretch of the crack and the
/// crack is as wide as its widest; with none measuring it, the finest
/// view's "narrower than".
fn width(views: impl Iterator<Item = WidthRecord>) -> Option<WidthRecord> {
    let views: Vec<WidthRecord> = views.collect();
    let finest = |v: &&WidthRecord, w: &&WidthRecord| v.mm_per_px.total_cmp(&w.mm_per_px);
    let measured: Vec<&WidthRecord> = views.iter().filter(|v| v.max_mm.is_some()).collect();
    let Some(scale) = measured.iter().copied().min_by(finest).map(|v| v.mm_per_px) else {
        return views.iter().min_by(finest).copied();
    };
    measured
        .into_iter()
        .filter(|v| v.mm_per_px <= AS_FINE * scale)
        .max_by(|v, w| v.max_mm.unwrap_or(0.0).total_cmp(&w.max_mm.unwrap_or(0.0)))
        .copied()
}

/// Views whose millimetres per pixel are within this factor of the finest
/// measure as finely.
const AS_FINE: f64 = 1.25;

/// Whether the views `measured` (the ones the length came from) make a
/// measured length (every end of their `fused` line seen inside a view) or
/// a lower bound, or why no view measured it.
fn length_status<'a>(
    group: &[usize],
    measured: &[usize],
    fused: Option<&FusedLine>,
    placement: &dyn Fn(usize) -> &'a Placement,
) -> LengthStatus {
    if fused.is_some_and(|f| f.complete) {
        LengthStatus::Measured
    } else if !measured.is_empty() {
        LengthStatus::Partial
    } else if group
        .iter()
        .all(|i| !measures_length(placement(*i).hit.incidence))
    {
        LengthStatus::TooOblique
    } else if group.iter().all(|i| {
        let p = placement(*i);
        !measures_length(p.hit.incidence) || p.view_faults.contains(&Miss::Blurred)
    }) {
        LengthStatus::Blurred
    } else if group.iter().all(|i| placement(*i).length_m.is_none()) {
        LengthStatus::NotTraced
    } else {
        LengthStatus::FarAndCut
    }
}

/// Views that agree on the crack's surface to this, metres, count fully;
/// farther apart they count less (the simulator's pose noise puts views of
/// one crack about 2 cm off its surface).
const AGREEMENT_M: f64 = 0.1;
/// Frames at which the views' support reaches 1 - 1/e.
const SUPPORT_FRAMES: f64 = 2.0;

/// Confidence from the best score of each frame (`scores`, best first) and
/// each view's offset from the fused surface (`off_surface`, metres): the
/// mean of the three best scores, times the support of the number of
/// frames (1 - exp(-frames / 2): one frame 0.39, three 0.78, six 0.95),
/// times the geometric agreement (exp(-(rms offset / 0.1 m)^2)). A single
/// confident view, or views that disagree on where the surface is, no
/// longer read as certainty.
pub fn confidence(scores: &[f64], off_surface: &[f64]) -> f64 {
    let top = &scores[..scores.len().min(3)];
    let score = top.iter().sum::<f64>() / top.len().max(1) as f64;
    let support = 1.0 - (-(scores.len() as f64) / SUPPORT_FRAMES).exp();
    let rms =
        (off_surface.iter().map(|d| d * d).sum::<f64>() / off_surface.len().max(1) as f64).sqrt();
    let agreement = (-(rms / AGREEMENT_M).powi(2)).exp();
    score * support * agreement
}

/// Ids from the voxel and face, numbered in position order within one.
fn name(candidates: &mut [DefectCandidate]) {
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    let key = |c: &DefectCandidate| (c.voxel.0, c.face.name());
    order.sort_by(|a, b| {
        let (ca, cb) = (&candidates[*a], &candidates[*b]);
        key(ca).cmp(&key(cb)).then(
            ca.position
                .coords
                .as_slice()
                .partial_cmp(cb.position.coords.as_slice())
                .unwrap_or(std::cmp::Ordering::Equal),
        )
    });
    let mut previous: Option<(([i32; 3], &str), u32)> = None;
    for i in order {
        let c = &mut candidates[i];
        let n = match previous {
            Some((k, n)) if k == key(c) => n + 1,
            _ => 1,
        };
        let [x, y, z] = c.voxel.0;
        c.id = if n == 1 {
            format!("{x}_{y}_{z}{}", c.face)
        } else {
            format!("{x}_{y}_{z}{}.{n}", c.face)
        };
        previous = Some((key(c), n));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::{Placement, Sight};
    use crate::surface::SurfaceHit;
    use postflight_core::defect_kind::DefectKind;
    use postflight_core::detection::FrameDetection;
    use postflight_core::detection::{BoxXyxy, Detection};

    fn observation(frame: u32, centre: [f64; 3], normal: [f64; 3], radius: f64) -> Observation {
        let centre = Point3::from(centre);
        let normal = Vector3::from(normal).normalize();
        let r = Vector3::repeat(radius);
        // Its line runs across the surface, horizontally where it can.
        let along = (Vector3::y() - normal * normal.y)
            .try_normalize(1e-6)
            .unwrap_or_else(Vector3::x);
        Observation {
            detection: FrameDetection {
                frame,
                time_ns: i64::from(frame),
                detection: Detection {
                    bbox: BoxXyxy {
                        x0: 10.0,
                        y0: 10.0,
                        x1: 50.0,
                        y1: 50.0,
                    },
                    score: 0.5,
                    class: 0,
                    kind: DefectKind::Crack,
                    tile: -1,
                    mask: None,
                },
            },
            outcome: Outcome::Placed,
            placement: Some(Placement {
                sight: Default::default(),
                hit: SurfaceHit {
                    point: centre,
                    normal,
                    voxel: VoxelIndex([0, 0, 0]),
                    range: 4.0 + f64::from(frame),
                    incidence: 0.0,
                },
                centre,
                extent: [centre - r, centre + r],
                radius,
                length_m: Some(2.0 * radius),
                oblique_gsd_mm: 4.0 + f64::from(frame),
                view_gsd_mm: 4.0,
                blur_px: None,
                view_faults: Vec::new(),
                width: None,
                crossed: None,
                camera_std_m: None,
                trace: Trace(vec![vec![
                    (centre - along * radius).coords.into(),
                    (centre + along * radius).coords.into(),
                ]]),
                cut: Vec::new(),
                line: None,
            }),
            traced_px: 30,
            clipped: false,
        }
    }

    /// The image border cut `o`'s line at its start, its end, or both.
    fn cut(o: &mut Observation, ends: &[usize]) {
        o.clipped = true;
        let p = o.placement.as_mut().unwrap();
        p.cut = ends
            .iter()
            .map(|e| Point3::from(p.trace.0[0][*e]))
            .collect();
    }

    #[test]
    fn views_of_one_crack_fuse_and_neighbours_stay_apart() {
        let obs = vec![
            // One crack seen three times, a few centimetres apart (pose noise).
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(1, [3.0, 1.05, 2.03], [-1.0, 0.05, 0.0], 0.28),
            observation(2, [3.01, 0.97, 1.98], [-1.0, 0.0, 0.02], 0.31),
            // Another crack 0.8 m along the same wall.
            observation(1, [3.0, 1.0, 3.5], [-1.0, 0.0, 0.0], 0.2),
            // Same place, the other side of a 0.3 m thick web: another surface.
            observation(2, [3.3, 1.0, 2.0], [1.0, 0.0, 0.0], 0.3),
        ];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c.len(), 3);
        let big = c.iter().find(|c| c.frames == 3).unwrap();
        assert_eq!(big.observations, vec![0, 1, 2]);
        assert!((big.position - Point3::new(3.0, 1.0, 2.0)).norm() < 0.01);
        assert_eq!(big.best, 0);
        // Three frames at 0.5 agreeing on the surface: 0.5 x 0.78 x 1.
        assert!((0.38..0.39).contains(&big.confidence), "{}", big.confidence);
        // Views from beyond 5 m (frame 2) do not count towards length; the
        // longest view saw both its ends.
        assert_eq!(big.length_views, 1);
        assert!((big.length_m.unwrap() - 0.6).abs() < 1e-12);
        // Stable names from voxel and face, numbered within one.
        let mut ids: Vec<&str> = c.iter().map(|c| c.id.as_str()).collect();
        ids.sort();
        assert_eq!(ids, ["0_0_0+x", "0_0_0-x", "0_0_0-x.2"]);
    }

    #[test]
    fn the_uncertainty_is_the_views_scatter_and_their_cameras_accuracy() {
        let mut obs = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(1, [3.0, 1.06, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(2, [3.0, 0.94, 2.0], [-1.0, 0.0, 0.0], 0.3),
        ];
        let uncertainty = |obs: &[Observation]| {
            let c = fuse(obs, &LocaliseConfig::default());
            assert_eq!(c.len(), 1);
            c[0].position_uncertainty_m
        };
        // Scatter alone: sample variance 0.0036 m^2 over three views.
        let scatter = (0.0072_f64 / 2.0 / 3.0).sqrt();
        assert!((uncertainty(&obs).unwrap() - scatter).abs() < 1e-9);
        // RTK cameras of 2, 3 and 4 cm: their median counts in full.
        for (o, std) in obs.iter_mut().zip([0.02, 0.03, 0.04]) {
            o.placement.as_mut().unwrap().camera_std_m = Some(std);
        }
        let both = (scatter * scatter + 0.03 * 0.03).sqrt();
        assert!((uncertainty(&obs).unwrap() - both).abs() < 1e-9);
        // One view: its camera's accuracy, or nothing known.
        assert_eq!(uncertainty(&obs[..1]), Some(0.02));
        obs[0].placement.as_mut().unwrap().camera_std_m = None;
        assert_eq!(uncertainty(&obs[..1]), None);
    }

    #[test]
    fn a_lone_view_placed_on_an_edge_in_front_of_a_crack_it_shows_joins_it() {
        // A crack on a wall (x = 3) seen twice; a third view's rays graze an
        // edge 1.1 m in front of it and land there, on a face at 45 degrees.
        let mut obs = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(1, [3.0, 1.05, 2.03], [-1.0, 0.0, 0.0], 0.3),
            observation(2, [1.9, 1.0, 2.0], [-1.0, 0.0, -1.0], 0.2),
        ];
        // Its camera at x = 0, its box a narrow cone about the line to the
        // crack.
        let sight = |toward: Point3<f64>| Sight {
            origin: Point3::origin(),
            corners: [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
                .map(|[u, v]| toward.coords.normalize() + Vector3::new(0.0, u * 0.02, v * 0.02)),
        };
        let lone = obs[2].placement.as_mut().unwrap();
        lone.sight = sight(Point3::new(3.0, 1.0, 2.0));
        lone.hit.range = 1.9;
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(
            c.len(),
            1,
            "{:?}",
            c.iter().map(|c| &c.id).collect::<Vec<_>>()
        );
        assert_eq!(c[0].frames, 3);
        // A box that looks elsewhere keeps its own candidate.
        obs[2].placement.as_mut().unwrap().sight = sight(Point3::new(3.0, -1.0, 2.0));
        assert_eq!(fuse(&obs, &LocaliseConfig::default()).len(), 2);
    }

    #[test]
    fn the_extent_covers_the_trace_views_cut_by_the_border_carried_on() {
        // Frame 0 holds its box whole but its line runs out of the image at
        // y = 1.2; frame 1's box is clipped, its line going on to 1.75.
        let mut whole = observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.2);
        let p = whole.placement.as_mut().unwrap();
        p.cut = vec![Point3::from(p.trace.0[0][1])];
        let mut clipped = observation(1, [3.0, 1.45, 2.0], [-1.0, 0.0, 0.0], 0.3);
        cut(&mut clipped, &[0]);
        let c = fuse(&[whole, clipped], &LocaliseConfig::default());
        assert_eq!(c.len(), 1);
        assert!(
            (c[0].length_m.unwrap() - 0.95).abs() < 1e-9,
            "{:?}",
            c[0].length_m
        );
        assert!((c[0].extent[0].y - 0.8).abs() < 1e-9, "{:?}", c[0].extent);
        assert!((c[0].extent[1].y - 1.75).abs() < 1e-9, "{:?}", c[0].extent);
    }

    #[test]
    fn pieces_of_one_crack_in_one_frame_add_up_to_its_length() {
        // Frame 0 shows the crack in two pieces (a faint stretch between),
        // 0.4 and 0.3 m; frame 1 shows 0.5 m of it in one.
        let obs = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.2),
            observation(0, [3.0, 1.4, 2.0], [-1.0, 0.0, 0.0], 0.15),
            observation(1, [3.0, 1.2, 2.0], [-1.0, 0.0, 0.0], 0.25),
        ];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c.len(), 1);
        assert!(
            (c[0].length_m.unwrap() - 0.7).abs() < 1e-12,
            "{:?}",
            c[0].length_m
        );
    }

    #[test]
    fn confidence_grows_with_frames_and_falls_with_disagreement() {
        let one = confidence(&[0.9], &[0.0]);
        let five = confidence(&[0.9; 5], &[0.0; 5]);
        let scattered = confidence(&[0.9; 5], &[0.1, -0.1, 0.1, -0.1, 0.1]);
        assert!(one < 0.4 && five > 0.8, "{one} {five}");
        assert!(scattered < 0.4 * five, "{scattered}");
    }

    #[test]
    fn the_best_view_meets_the_view_model_when_one_does_and_a_missing_length_says_why() {
        let mut obs = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(1, [3.0, 1.02, 2.0], [-1.0, 0.0, 0.0], 0.3),
        ];
        // Frame 0 is finer but too close; frame 1 meets the rules.
        obs[0].placement.as_mut().unwrap().view_faults = vec![Miss::TooClose];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c[0].best, 1);
        assert!(!c[0].evidence.reshoot);
        // Seen only at 75 degrees: no length, because too oblique; re-shoot.
        for o in &mut obs {
            let p = o.placement.as_mut().unwrap();
            p.hit.incidence = 75f64.to_radians();
            p.length_m = None;
        }
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c[0].length_m, None);
        assert_eq!(c[0].evidence.length, LengthStatus::TooOblique);
        assert!(c[0].evidence.reshoot);
        // One of them face-on but blurred: no length, because blurred.
        let p = obs[1].placement.as_mut().unwrap();
        p.hit.incidence = 10f64.to_radians();
        p.view_faults = vec![Miss::Blurred];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c[0].evidence.length, LengthStatus::Blurred);
        assert!(c[0].evidence.reshoot);
    }

    #[test]
    fn a_crack_at_an_edge_placed_on_both_faces_is_one_candidate() {
        let obs = vec![
            // Seen on the top face and on the side face of a slab edge.
            observation(0, [3.0, 1.0, 2.0], [0.0, 0.0, 1.0], 0.3),
            observation(1, [3.05, 1.1, 1.85], [1.0, 0.0, 0.0], 0.3),
            // A crack round the edge but clear of the first one's extent.
            observation(2, [3.05, 2.0, 1.2], [1.0, 0.0, 0.0], 0.2),
        ];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c.len(), 2);
        assert!(c.iter().any(|c| c.observations == [0, 1]));
        // Parallel faces a step apart are not an edge, however close.
        let step = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.3),
            observation(1, [3.3, 1.1, 2.0], [-1.0, 0.0, 0.0], 0.3),
        ];
        assert_eq!(fuse(&step, &LocaliseConfig::default()).len(), 2);
    }

    #[test]
    fn a_long_crack_seen_in_parts_becomes_one_candidate() {
        // Three overlapping stretches of a 2 m crack, then a gap of 0.5 m.
        let obs = vec![
            observation(0, [3.0, 0.0, 2.0], [-1.0, 0.0, 0.0], 0.4),
            observation(1, [3.0, 0.7, 2.0], [-1.0, 0.0, 0.0], 0.4),
            observation(2, [3.0, 1.4, 2.0], [-1.0, 0.0, 0.0], 0.4),
            observation(3, [3.0, 2.7, 2.0], [-1.0, 0.0, 0.0], 0.4),
        ];
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c.len(), 2);
        assert!(c.iter().any(|c| c.observations == [0, 1, 2]));
        assert!(
            c.iter()
                .all(|c| c.evidence.length == LengthStatus::Measured)
        );
    }

    #[test]
    fn views_cut_by_the_image_border_give_a_lower_bound_until_a_view_sees_the_end() {
        // Frame 1 shows 0.8..1.4 m along the wall, frame 0 0.8..1.2 m, both
        // cut at both ends.
        let mut obs = vec![
            observation(0, [3.0, 1.0, 2.0], [-1.0, 0.0, 0.0], 0.2),
            observation(1, [3.0, 1.1, 2.0], [-1.0, 0.0, 0.0], 0.3),
        ];
        for o in &mut obs {
            cut(o, &[0, 1]);
        }
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].evidence.length, LengthStatus::Partial);
        assert!((c[0].length_m.unwrap() - 0.6).abs() < 1e-12);
        // Frame 0 saw the crack end at 0.8 m, and frame 2 sees it go on to
        // 1.5 m and end: measured, 0.7 m, from three views.
        cut(&mut obs[0], &[1]);
        obs.push(observation(2, [3.0, 1.35, 2.0], [-1.0, 0.0, 0.0], 0.15));
        obs[2].placement.as_mut().unwrap().hit.range = 4.0;
        let c = fuse(&obs, &LocaliseConfig::default());
        assert_eq!(c[0].evidence.length, LengthStatus::Measured);
        assert!(
            (c[0].length_m.unwrap() - 0.7).abs() < 1e-9,
            "{:?}",
            c[0].length_m
        );
        assert_eq!(c[0].length_views, 3);
    }
}

//! What changed between two flights of one structure: the earlier flight's
//! defect candidates, moved into the later flight's frame, matched with
//! the later ones (a face that agrees, the same element, extents within the
//! link distance), and each classified: new, first seen, grown, widened,
//! unchanged, not seen again, or not re-inspected.

use std::collections::HashMap;

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::outputs::changes::{ChangeKind, ChangeRecord};
use postflight_core::outputs::coverage::{CoverageSummary, VoxelRecord};
use postflight_core::outputs::localise::{DefectRecord, LengthStatus, WidthRecord};
use postflight_core::structure::ElementMap;
use postflight_core::trace::Trace;

use crate::sight::FramesInView;

/// How candidates are matched.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchOptions {
    /// Largest gap between two candidates' extents, metres.
    pub link_distance_m: f64,
    /// Largest angle between their surfaces' normals, degrees (a face).
    pub max_normal_angle_deg: f64,
    /// How far a length measurement spreads: this share of the length.
    pub length_spread: f64,
    /// How far apart two flights may see one crack's end without it
    /// having grown, metres, beyond their traces' tolerance.
    pub end_spread_m: f64,
}

impl MatchOptions {
    /// Candidates as far apart as `link_distance_m` may match (each run's
    /// localise fused its own views that far apart).
    pub fn with_link_distance(link_distance_m: f64) -> Self {
        Self {
            link_distance_m,
            // Wider than one flight's fusion allows: a normal fitted in each
            // flight, at a surface's edge, can differ by more.
            max_normal_angle_deg: 45.0,
            // Lengths measured from 5 m or closer come within about 10% of
            // the truth (docs/evaluation.md).
            length_spread: 0.1,
            // Where a hairline tip fades differs between views by a few
            // centimetres.
            end_spread_m: 0.03,
        }
    }
}

/// A run's coverage: how it saw each target voxel, and their elements.
pub struct Inspected {
    grid: VoxelGrid,
    looks: HashMap<VoxelIndex, Look>,
    elements: ElementMap,
}

/// How a run saw a target voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Look {
    pub inspected: bool,
    /// Its finest view, millimetres per pixel (the View model's GSD).
    pub mm_per_px: Option<f64>,
}

impl Inspected {
    pub fn new(summary: &CoverageSummary, records: &[VoxelRecord]) -> Self {
        let look = |r: &VoxelRecord| Look {
            inspected: r.inspected,
            mm_per_px: r.best.map(|b| b.gsd_mm),
        };
        Self {
            grid: VoxelGrid::new(summary.figures.resolution_m, summary.grid_origin.into()),
            looks: records.iter().map(|r| (r.voxel, look(r))).collect(),
            elements: postflight_core::outputs::coverage::element_map(summary, records),
        }
    }

    /// Whether the run inspected the target voxel under a surface point
    /// (see [`Inspected::look`]).
    pub fn at(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Option<bool> {
        self.look(point, normal).map(|l| l.inspected)
    }

    /// How the run saw the target voxel under a surface point: its own,
    /// or, when the point sits on a voxel's edge, the nearest target voxel
    /// around it; `None` when no target voxel is there.
    pub fn look(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Option<Look> {
        let inside = self.inside(point, normal);
        let v = self.grid.voxel_of(&inside);
        if let Some(&look) = self.looks.get(&v) {
            return Some(look);
        }
        // The nearest, not any: any of 26 neighbours inspected called
        // surface inspected that the flight never saw.
        neighbours(v)
            .filter_map(|n| Some(((self.grid.center(n) - inside).norm(), *self.looks.get(&n)?)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, look)| look)
    }

    /// The element at a surface point, by name: that of the target voxel
    /// nearest just inside the surface (on a deck above a pier, the deck).
    pub fn element(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Option<String> {
        self.elements
            .element_at(&self.inside(point, normal))
            .map(|e| self.elements.structure.elements[e].name.clone())
    }

    /// Just inside the surface at a point: the structure's voxel, not the
    /// air's.
    fn inside(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Point3<f64> {
        point - normal * (0.25 * self.grid.resolution)
    }
}

fn neighbours(v: VoxelIndex) -> impl Iterator<Item = VoxelIndex> {
    let [x, y, z] = v.0;
    (-1..=1).flat_map(move |dx| {
        (-1..=1).flat_map(move |dy| (-1..=1).map(move |dz| VoxelIndex([x + dx, y + dy, z + dz])))
    })
}

/// A candidate in the later flight's frame.
#[derive(Debug, Clone)]
struct Placed<'a> {
    defect: &'a DefectRecord,
    position: Point3<f64>,
    normal: Vector3<f64>,
    min: Point3<f64>,
    max: Point3<f64>,
    element: Option<String>,
    trace: Trace,
}

impl<'a> Placed<'a> {
    fn new(defect: &'a DefectRecord, to_after: &Isometry3<f64>, after: &Inspected) -> Self {
        let corners = (0..8).map(|k| {
            let pick = |axis: usize| {
                if k >> axis & 1 == 0 {
                    defect.extent_min[axis]
                } else {
                    defect.extent_max[axis]
                }
            };
            to_after * Point3::new(pick(0), pick(1), pick(2))
        });
        let (mut min, mut max) = (
            Point3::from([f64::INFINITY; 3]),
            Point3::from([f64::NEG_INFINITY; 3]),
        );
        for c in corners {
            min = min.inf(&c);
            max = max.sup(&c);
        }
        let position = to_after * Point3::from(defect.position);
        let normal = to_after * Vector3::from(defect.normal);
        Self {
            defect,
            position,
            normal,
            min,
            max,
            element: after.element(&position, &normal),
            trace: defect.trace.transformed(to_after),
        }
    }

    /// The gap between the two extents, metres (0 when they overlap).
    fn gap(&self, other: &Placed) -> f64 {
        let d = (self.min - other.max)
            .sup(&(other.min - self.max))
            .sup(&Vector3::zeros());
        d.norm()
    }

    /// On one face of one element, within the link distance.
    fn matches(&self, other: &Placed, options: &MatchOptions) -> bool {
        let same_element = match (&self.element, &other.element) {
            (Some(a), Some(b)) => a == b,
            _ => true,
        };
        let angle = self.normal.angle(&other.normal).to_degrees();
        same_element
            && angle <= options.max_normal_angle_deg
            && self.gap(other) <= options.link_distance_m
    }
}

/// Every change between `before` (the earlier candidates, `to_after` moving
/// them into this frame) and `after`, those that stand out first.
pub fn changes(
    before: &[DefectRecord],
    after: &[DefectRecord],
    to_after: &Isometry3<f64>,
    inspected_after: &Inspected,
    seen_before: &Earlier,
    options: &MatchOptions,
) -> Vec<ChangeRecord> {
    let identity = Isometry3::identity();
    let earlier: Vec<Placed> = before
        .iter()
        .map(|d| Placed::new(d, to_after, inspected_after))
        .collect();
    let later: Vec<Placed> = after
        .iter()
        .map(|d| Placed::new(d, &identity, inspected_after))
        .collect();
    let pairs = match_pairs(&earlier, &later, options);
    let back = to_after.inverse();
    let mut records = Vec::new();
    let mut matched_before = vec![false; earlier.len()];
    for (b, now) in later.iter().enumerate() {
        let record = match pairs.get(&b) {
            Some(&a) => {
                matched_before[a] = true;
                let earlier_saw = |p: &Point3<f64>| {
                    seen_before.saw(&(back * p), &(back * now.normal), now.defect)
                };
                seen_again(&earlier[a], now, &earlier_saw, options)
            }
            None => {
                let look = seen_before
                    .inspected
                    .and_then(|i| i.look(&(back * now.position), &(back * now.normal)));
                // New only where the earlier flight looked, finely enough to
                // see it, and found nothing.
                let kind = if sees(look, now.defect) {
                    ChangeKind::New
                } else {
                    ChangeKind::FirstSeen
                };
                ChangeRecord {
                    earlier_inspected: look.map(|l| l.inspected),
                    earlier_mm_per_px: look.and_then(|l| l.mm_per_px),
                    ..record(kind, None, Some(now))
                }
            }
        };
        records.push(record);
    }
    for (was, _) in earlier.iter().zip(&matched_before).filter(|(_, m)| !**m) {
        let kind = match inspected_after.at(&was.position, &was.normal) {
            Some(true) => ChangeKind::NotSeenAgain,
            _ => ChangeKind::NotReinspected,
        };
        records.push(record(kind, Some(was), None));
    }
    records.sort_by_key(|r| r.change);
    records
}

/// Narrowest crack a view sees, in its pixels: narrower, the crack darkens
/// a pixel by less than half its own darkness, near the sensor's noise and
/// the compression's artefacts (a width measured that thin is a darkness
/// integral near the noise, so its change is not judged either).
const MIN_SEEN_PX: f64 = 0.5;

/// Whether a candidate's widest (or, below resolution now, the bound on
/// it) is under [`MIN_SEEN_PX`] of a view `mm_per_px` fine; not where
/// either is unknown (a box model measures no width).
fn too_narrow_for(width: Option<&WidthRecord>, mm_per_px: Option<f64>) -> bool {
    let widest = width.and_then(|w| w.max_mm.or(w.narrower_than_mm));
    matches!((widest, mm_per_px), (Some(w), Some(px)) if w < MIN_SEEN_PX * px)
}

/// What the earlier flight saw, to tell where it would have found a crack.
pub struct Earlier<'a> {
    /// Its coverage; `None` where it computed none (then it is taken to
    /// have seen everywhere).
    pub inspected: Option<&'a Inspected>,
    /// Its frames, beyond what coverage counts as inspected.
    pub frames: Option<&'a FramesInView>,
}

impl Earlier<'_> {
    /// Whether it would have seen `crack` at a surface point (earlier
    /// frame): it inspected the surface finely enough for the crack's
    /// width, or a usable frame had the point in view that finely (at an
    /// image's edge, outside the View model's cone).
    fn saw(&self, point: &Point3<f64>, normal: &Vector3<f64>, crack: &DefectRecord) -> bool {
        let Some(inspected) = self.inspected else {
            return true;
        };
        sees(inspected.look(point, normal), crack)
            || self.frames.is_some_and(|f| {
                f.finest_gsd_mm(point, normal)
                    .is_some_and(|gsd| !too_narrow_for(crack.width.as_ref(), Some(gsd)))
            })
    }
}

/// Whether a run's `look` at a surface would have seen `crack` there: it
/// inspected it, finely enough for its width.
fn sees(look: Option<Look>, crack: &DefectRecord) -> bool {
    look.is_some_and(|l| l.inspected && !too_narrow_for(crack.width.as_ref(), l.mm_per_px))
}

/// Matches, later candidate to earlier: closest pairs first, each
/// candidate in one pair at most.
fn match_pairs(
    earlier: &[Placed],
    later: &[Placed],
    options: &MatchOptions,
) -> HashMap<usize, usize> {
    let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
    for (b, now) in later.iter().enumerate() {
        for (a, was) in earlier.iter().enumerate() {
            if was.matches(now, options) {
                candidates.push(((was.position - now.position).norm(), a, b));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (mut taken, mut pairs) = (vec![false; earlier.len()], HashMap::new());
    for (_, a, b) in candidates {
        if !taken[a] && !pairs.contains_key(&b) {
            taken[a] = true;
            pairs.insert(b, a);
        }
    }
    pairs
}

/// Least widening judged real, as a share of the earlier width.
const WIDENING_SHARE: f64 = 0.2;

/// A candidate seen in both flights, classified by [`classify`];
/// `earlier_saw` tells where the earlier flight would have seen it.
fn seen_again(
    was: &Placed,
    now: &Placed,
    earlier_saw: &dyn Fn(&Point3<f64>) -> bool,
    options: &MatchOptions,
) -> ChangeRecord {
    let base = record(ChangeKind::Unchanged, Some(was), Some(now));
    let growth = stronger(
        growth(was.defect, now.defect, options),
        extension(&was.trace, &now.trace, earlier_saw, options),
    );
    let widening = widening(was.defect.width.as_ref(), now.defect.width.as_ref());
    ChangeRecord {
        change: classify(growth, widening),
        growth_m: growth.map(|g| g.0),
        spread_m: growth.map(|g| g.1),
        widening_mm: widening.map(|w| w.0),
        width_spread_mm: widening.map(|w| w.1),
        ..base
    }
}

/// A crack seen in both flights from its growth and its widening (each
/// the change and the spread it is judged against, `None` where it cannot
/// be judged): grown when its length grew by more than the spread, else
/// widened when its widest did, else unchanged where either could be
/// judged, and not measured where neither could.
fn classify(growth: Option<(f64, f64)>, widening: Option<(f64, f64)>) -> ChangeKind {
    let beyond = |change: Option<(f64, f64)>| change.is_some_and(|(by, spread)| by > spread);
    if beyond(growth) {
        ChangeKind::Grown
    } else if beyond(widening) {
        ChangeKind::Widened
    } else if growth.is_none() && widening.is_none() {
        ChangeKind::NotMeasured
    } else {
        ChangeKind::Unchanged
    }
}

/// Of two judgements of one change (each the change and its spread), the
/// one that shows it more.
fn stronger(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    let margin = |c: &(f64, f64)| c.0 - c.1;
    match (a, b) {
        (Some(a), Some(b)) => Some(if margin(&b) > margin(&a) { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// How far its trace now runs on beyond the earlier one, and the spread
/// that is judged against, metres; none where either has no trace. Only
/// its stretches more than the link distance from the earlier trace (the
/// two flights' pose errors) count, on surface where the earlier flight
/// would have seen it; a line running on leaves that band a link distance
/// past the earlier end, so that is added back to both. It judges growth
/// where a length cannot: a crack longer than a frame, cut by the image
/// border in every view, still shows where it runs on.
fn extension(
    was: &Trace,
    now: &Trace,
    earlier_saw: &dyn Fn(&Point3<f64>) -> bool,
    options: &MatchOptions,
) -> Option<(f64, f64)> {
    if was.is_empty() || now.is_empty() {
        return None;
    }
    let band = options.link_distance_m;
    let beyond = now.length_beyond(was, band, earlier_saw);
    let by = if beyond > 0.0 { beyond + band } else { 0.0 };
    Some((by, options.end_spread_m + band))
}

/// How much longer it is now and the spread that is judged against,
/// metres; none where either length is unknown, or the earlier one is a
/// lower bound (its views cut by the image border), which cannot show
/// growth.
fn growth(was: &DefectRecord, now: &DefectRecord, options: &MatchOptions) -> Option<(f64, f64)> {
    let (before, after) = (was.length_m?, now.length_m?);
    if was.evidence.length == LengthStatus::Partial {
        return None;
    }
    Some((after - before, options.length_spread * (before + after)))
}

/// How much wider its widest is now, and the spread that is judged
/// against, millimetres: both flights' uncertainties combined (root of the
/// sum of squares: two views' errors are independent), and at least a
/// fifth of the earlier width (thin cracks measure within about 20%,
/// docs/evaluation.md; the uncertainties do not cover two views' different
/// resolutions). Where it was below resolution before, the growth beyond
/// that bound, against the later uncertainty alone. Not judged where
/// either width is under half a pixel of its view.
fn widening(was: Option<&WidthRecord>, now: Option<&WidthRecord>) -> Option<(f64, f64)> {
    let (was, now) = (was?, now?);
    let after = now.max_mm.filter(|mm| mm / now.mm_per_px >= MIN_SEEN_PX)?;
    let uncertainty = |w: &WidthRecord| w.uncertainty_mm.unwrap_or(0.0);
    match (was.max_mm, was.narrower_than_mm) {
        (Some(before), _) if before / was.mm_per_px >= MIN_SEEN_PX => Some((
            after - before,
            uncertainty(was)
                .hypot(uncertainty(now))
                .max(WIDENING_SHARE * before),
        )),
        (None, Some(bound)) => Some((after - bound, uncertainty(now))),
        _ => None,
    }
}

fn record(kind: ChangeKind, was: Option<&Placed>, now: Option<&Placed>) -> ChangeRecord {
    let at = now.or(was).expect("a change has a candidate");
    ChangeRecord {
        change: kind,
        after: now.map(|p| p.defect.id.clone()),
        before: was.map(|p| p.defect.id.clone()),
        position: at.position.into(),
        element: at.element.clone(),
        length_before_m: was.and_then(|p| p.defect.length_m),
        length_after_m: now.and_then(|p| p.defect.length_m),
        growth_m: None,
        spread_m: None,
        width_before_mm: was.and_then(|p| p.defect.width?.max_mm),
        width_after_mm: now.and_then(|p| p.defect.width?.max_mm),
        widening_mm: None,
        width_spread_mm: None,
        earlier_inspected: None,
        earlier_mm_per_px: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn width(
        max_mm: Option<f64>,
        uncertainty_mm: f64,
        narrower_than_mm: Option<f64>,
    ) -> WidthRecord {
        WidthRecord {
            max_mm,
            median_mm: max_mm,
            uncertainty_mm: max_mm.map(|_| uncertainty_mm),
            narrower_than_mm,
            mm_per_px: 0.5,
            ..WidthRecord::default()
        }
    }

    #[test]
    fn a_crack_under_half_a_pixel_of_the_earlier_view_could_not_have_been_seen() {
        let at = |mm: f64| too_narrow_for(Some(&width(Some(mm), 0.1, None)), Some(1.2));
        assert!(at(0.5) && !at(0.7), "half of 1.2 mm/px is 0.6 mm");
        // Below resolution now: its bound tells.
        let below = width(None, 0.0, Some(0.4));
        assert!(too_narrow_for(Some(&below), Some(1.2)));
        // Without a width (a box model) or the earlier view, not known.
        assert!(!too_narrow_for(None, Some(1.2)));
        assert!(!too_narrow_for(Some(&width(Some(0.1), 0.1, None)), None));
    }

    #[test]
    fn a_crack_seen_again_is_unchanged_only_where_something_was_compared() {
        let (longer, same) = (Some((0.3, 0.1)), Some((0.02, 0.1)));
        assert_eq!(classify(longer, same), ChangeKind::Grown);
        assert_eq!(classify(same, longer), ChangeKind::Widened);
        assert_eq!(classify(None, longer), ChangeKind::Widened);
        assert_eq!(classify(same, None), ChangeKind::Unchanged);
        assert_eq!(classify(None, same), ChangeKind::Unchanged);
        // Every view of one flight blurred or too oblique: nothing to compare.
        assert_eq!(classify(None, None), ChangeKind::NotMeasured);
    }

    #[test]
    fn growth_is_where_the_trace_runs_on_beyond_the_earlier_one_on_surface_it_saw() {
        let options = MatchOptions::with_link_distance(0.1);
        // Each flight's line of a crack cut by the image border: 0.8 m of it
        // before, now 4 cm off (pose error) and on 0.4 m further.
        let was = Trace(vec![vec![[0.0, 0.0, 0.0], [0.8, 0.0, 0.0]]]);
        let now = Trace(vec![vec![[0.1, 0.04, 0.0], [1.2, 0.04, 0.0]]]);
        let everywhere = |_: &Point3<f64>| true;
        let (by, spread) = extension(&was, &now, &everywhere, &options).unwrap();
        assert!(
            (by - (0.4 - 0.0917 + 0.1)).abs() < 0.011 && by > spread,
            "{by}"
        );
        // Where the earlier flight never looked, its running on is not growth.
        let up_to_1_m = |p: &Point3<f64>| p.x < 1.0;
        let (by, spread) = extension(&was, &now, &up_to_1_m, &options).unwrap();
        assert!(by < 0.11 + 0.1 && by > spread, "{by}");
        let up_to_0_9_m = |p: &Point3<f64>| p.x < 0.9;
        let (by, spread) = extension(&was, &now, &up_to_0_9_m, &options).unwrap();
        assert!(by < spread, "{by}");
        // Not judged without a trace; the stronger judgement shows a change.
        assert_eq!(
            extension(&Trace::default(), &now, &everywhere, &options),
            None
        );
        let (short, long) = (Some((0.05, 0.1)), Some((0.4, 0.03)));
        assert_eq!(stronger(short, long), long);
        assert_eq!(stronger(short, None), short);
    }

    #[test]
    fn widening_is_judged_against_both_flights_uncertainty() {
        let before = width(Some(0.6), 0.1, None);
        let (by, spread) = widening(Some(&before), Some(&width(Some(1.0), 0.15, None))).unwrap();
        assert!((by - 0.4).abs() < 1e-12 && (spread - 0.1f64.hypot(0.15)).abs() < 1e-12);
        let (by, spread) = widening(Some(&before), Some(&width(Some(0.75), 0.15, None))).unwrap();
        assert!(
            by < spread,
            "0.15 mm wider is within 0.18 mm of uncertainty"
        );
        // Below resolution before: its bound, against the later uncertainty.
        let below = width(None, 0.0, Some(0.3));
        let (by, spread) = widening(Some(&below), Some(&width(Some(0.9), 0.2, None))).unwrap();
        assert!((by - 0.6).abs() < 1e-12 && (spread - 0.2).abs() < 1e-12);
        // A wide crack's spread is a fifth of its width at least.
        let wide = width(Some(4.0), 0.1, None);
        let (by, spread) = widening(Some(&wide), Some(&width(Some(4.6), 0.1, None))).unwrap();
        assert!((spread - 0.8).abs() < 1e-12 && by < spread);
        // Under half a pixel in either view: not judged.
        let faint = WidthRecord {
            mm_per_px: 2.0,
            ..width(Some(0.9), 0.1, None)
        };
        assert_eq!(
            widening(Some(&faint), Some(&width(Some(3.0), 0.1, None))),
            None
        );
        // Unknown now, or from a box-only model: nothing to judge.
        assert_eq!(widening(Some(&before), Some(&below)), None);
        assert_eq!(widening(None, Some(&before)), None);
    }
}

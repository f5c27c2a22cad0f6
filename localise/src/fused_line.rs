//! A candidate's centre line from its views, for cracks no frame holds
//! whole. The frame that shows the most of the crack is the base (its
//! pieces summed, each stretch once); where its line runs out of the image,
//! the other views that pass that end carry it on beyond the line (a view
//! that runs back along it adds nothing), each measured along its own line
//! from the point nearest the end (pose error moves, tilts and scales a
//! view's line on the surface by centimetres, so lines are never laid over
//! each other): the median of the views that saw the crack end, or, while
//! every view there runs out of the image too, the longest, carried on
//! again.

use std::collections::BTreeMap;

use nalgebra::Point3;
use postflight_core::trace::{Trace, closest_on_segment};

use crate::centre_line::{self, points};

/// One view's centre line on the surface.
#[derive(Debug, Clone, Copy)]
pub struct ViewLine<'a> {
    pub trace: &'a Trace,
    /// Where its line runs out of the image: the crack may go on there.
    pub cut: &'a [Point3<f64>],
    /// Its frame: the pieces of a crack one frame shows add up.
    pub frame: u32,
    /// A few pixels' footprint of the view, metres: two of its lines this
    /// close are one stretch.
    pub near: f64,
}

impl ViewLine<'_> {
    fn lines(&self) -> Vec<Vec<Point3<f64>>> {
        self.trace.0.iter().map(|l| points(l)).collect()
    }

    /// Whether its line runs out of the image at `p`.
    fn is_cut(&self, p: &Point3<f64>) -> bool {
        self.cut.iter().any(|c| (c - p).norm() <= self.near)
    }
}

/// The fused centre line.
#[derive(Debug, Clone, PartialEq)]
pub struct FusedLine {
    pub trace: Trace,
    /// Length along it, metres.
    pub length_m: f64,
    /// Every end of the line was seen inside a view (the crack ends or
    /// fades there): the length is measured, not a lower bound.
    pub complete: bool,
    /// Views that went into it.
    pub views: u32,
}

/// Fuse `views`; `apart` is how far pose error can move a view's line (the
/// link distance): a view passes an end when its line comes that close.
/// `None` when no view has a line.
pub fn fuse(views: &[ViewLine], apart: f64) -> Option<FusedLine> {
    let mut frames: BTreeMap<u32, Vec<&ViewLine>> = BTreeMap::new();
    for v in views.iter().filter(|v| !v.trace.is_empty()) {
        frames.entry(v.frame).or_default().push(v);
    }
    let (base_frame, base) = frames
        .iter()
        .map(|(f, pieces)| (*f, frame_line(pieces)))
        .max_by(|a, b| a.1.length_m.total_cmp(&b.1.length_m))?;
    let pieces = &frames[&base_frame];
    let mut fused = FusedLine {
        trace: Trace(base.lines.iter().flat_map(|p| p.trace.0.clone()).collect()),
        length_m: base.length_m,
        complete: true,
        views: pieces.len() as u32,
    };
    let others: Vec<&ViewLine> = views
        .iter()
        .filter(|v| v.frame != base_frame && !v.trace.is_empty())
        .collect();
    let mut used = vec![false; others.len()];
    let mut kept: Vec<Vec<Point3<f64>>> = pieces.iter().flat_map(|p| p.lines()).collect();
    for cut in cut_ends(pieces) {
        let carried = carry_on(cut, &others, &mut used, &mut kept, apart);
        fused.length_m += carried.length_m;
        fused.trace.0.extend(carried.lines);
        fused.complete &= carried.seen_end;
    }
    fused.views += used.iter().filter(|u| **u).count() as u32;
    Some(fused)
}

/// What one frame shows of a crack.
struct FrameLine<'a> {
    length_m: f64,
    /// The pieces that show something the longer ones do not.
    lines: Vec<&'a ViewLine<'a>>,
}

/// A frame's line of a crack from its pieces: the longest, then each
/// other for the share of its line the longer ones do not already show
/// (two detections of one stretch count it once, and draw it once).
fn frame_line<'a>(pieces: &[&'a ViewLine<'a>]) -> FrameLine<'a> {
    let mut by_length: Vec<&ViewLine> = pieces.to_vec();
    by_length.sort_by(|a, b| b.trace.length_m().total_cmp(&a.trace.length_m()));
    let mut line = FrameLine {
        length_m: 0.0,
        lines: Vec::new(),
    };
    for (k, piece) in by_length.iter().enumerate() {
        let longer: Vec<&Trace> = by_length[..k].iter().map(|p| p.trace).collect();
        let shown = centre_line::share_near(piece.trace, &longer, piece.near.max(PLACED_APART));
        line.length_m += piece.trace.length_m() * (1.0 - shown);
        if shown < SHOWN_ALREADY {
            line.lines.push(piece);
        }
    }
    line
}

/// How far apart one frame's detections of one stretch can be placed,
/// metres: each on its own fit of the surface (9 mm seen on a bridge deck).
const PLACED_APART: f64 = 0.02;

/// A piece of a frame's line the longer ones show this much of adds
/// nothing to draw.
const SHOWN_ALREADY: f64 = 0.9;

/// The ends of a frame's lines that no other of its lines goes on from and
/// the image border cut (the others are where the crack ends or fades).
fn cut_ends(pieces: &[&ViewLine]) -> Vec<Point3<f64>> {
    let lines: Vec<(usize, Vec<Point3<f64>>)> = pieces
        .iter()
        .enumerate()
        .flat_map(|(k, p)| p.lines().into_iter().map(move |l| (k, l)))
        .filter(|(_, l)| l.len() >= 2)
        .collect();
    let mut ends = Vec::new();
    for (i, (k, line)) in lines.iter().enumerate() {
        let view = pieces[*k];
        for p in [line[0], line[line.len() - 1]] {
            let joins = lines
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .any(|(_, (_, other))| {
                    centre_line::distance(&p, std::slice::from_ref(other)) <= view.near
                });
            if !joins && view.is_cut(&p) {
                ends.push(p);
            }
        }
    }
    ends
}

/// What the other views add beyond a cut end.
struct Carried {
    length_m: f64,
    lines: Vec<Vec<[f64; 3]>>,
    /// Some view saw the crack end beyond it.
    seen_end: bool,
}

/// How a view goes on beyond an end: its line from the point nearest the
/// end to its far end, that stretch's length, and whether the image border
/// cut its far end.
struct Beyond {
    view: usize,
    line: Vec<Point3<f64>>,
    length_m: f64,
    far_end: Point3<f64>,
    cut: bool,
}

/// Carries the line on from `end`, where the image border cut it, with the
/// views not yet `used` that pass it: the median of those that saw the
/// crack end; while all are cut, the longest, and on from its far end.
/// `kept` holds the lines so far (what a view goes on from them is new).
fn carry_on(
    end: Point3<f64>,
    views: &[&ViewLine],
    used: &mut [bool],
    kept: &mut Vec<Vec<Point3<f64>>>,
    apart: f64,
) -> Carried {
    let mut carried = Carried {
        length_m: 0.0,
        lines: Vec::new(),
        seen_end: false,
    };
    let mut end = end;
    loop {
        let beyond: Vec<Beyond> = (0..views.len())
            .filter(|v| !used[*v])
            .filter_map(|v| beyond(v, views[v], &end, kept, apart))
            .collect();
        if beyond.is_empty() {
            return carried;
        }
        let mut seen: Vec<&Beyond> = beyond.iter().filter(|b| !b.cut).collect();
        let chosen = if seen.is_empty() {
            beyond
                .iter()
                .max_by(|a, b| a.length_m.total_cmp(&b.length_m))
                .expect("some view")
        } else {
            seen.sort_by(|a, b| a.length_m.total_cmp(&b.length_m));
            seen[(seen.len() - 1) / 2]
        };
        for b in &beyond {
            used[b.view] = true;
        }
        carried.length_m += chosen.length_m;
        if chosen.line.len() >= 2 {
            carried
                .lines
                .push(chosen.line.iter().map(|p| p.coords.into()).collect());
            kept.push(chosen.line.clone());
        }
        if !chosen.cut {
            carried.seen_end = true;
            return carried;
        }
        end = chosen.far_end;
    }
}

/// How `view` goes on beyond `end`: its line passing within `apart` of
/// `end`, from its nearest point that way whose far end leaves the `kept`
/// lines (the other way runs back along them), when it leaves them by
/// more than the view's `near`; nothing beyond when its line ends there
/// uncut (it saw the crack end there); `None` when it does not pass.
fn beyond(
    index: usize,
    view: &ViewLine,
    end: &Point3<f64>,
    kept: &[Vec<Point3<f64>>],
    apart: f64,
) -> Option<Beyond> {
    let (line, at) = view
        .lines()
        .into_iter()
        .filter(|l| l.len() >= 2)
        .filter_map(|l| {
            let at = nearest_on(&l, end);
            (at.distance <= apart).then_some((l, at))
        })
        .min_by(|a, b| a.1.distance.total_cmp(&b.1.distance))?;
    let off_kept = |p: &Point3<f64>| centre_line::distance(p, kept);
    let forward: Vec<Point3<f64>> = std::iter::once(at.point)
        .chain(line[at.segment + 1..].iter().copied())
        .collect();
    let backward: Vec<Point3<f64>> = std::iter::once(at.point)
        .chain(line[..=at.segment].iter().rev().copied())
        .collect();
    let (way, off) = [forward, backward]
        .into_iter()
        .map(|way| {
            let off = off_kept(&way[way.len() - 1]);
            (way, off)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("two ways");
    if off <= along_kept(view, &at, &way) {
        // It does not go on: where its line ends at the end, uncut, it saw
        // the crack end there.
        let ends = [line[0], line[line.len() - 1]];
        let ends_here = ends.iter().any(|e| (e - at.point).norm() < 1e-9);
        return (ends_here && !view.is_cut(&at.point)).then(|| Beyond {
            view: index,
            line: vec![at.point],
            length_m: 0.0,
            far_end: at.point,
            cut: false,
        });
    }
    let far_end = way[way.len() - 1];
    Some(Beyond {
        view: index,
        length_m: polyline_length(&way),
        cut: view.is_cut(&far_end),
        far_end,
        line: way,
    })
}

/// How far off the `kept` lines a view's `way` from the end may end and
/// still run back along them: its few pixels, twice how far its line passes
/// the end (pose error moves a view's whole line by about that) and
/// [`POSE_TILT`] of the way's reach (and turns it).
fn along_kept(view: &ViewLine, at: &OnLine, way: &[Point3<f64>]) -> f64 {
    let reach = (way[way.len() - 1] - at.point).norm();
    view.near + 2.0 * at.distance + POSE_TILT * reach
}

/// How far a view's line may turn from another's under pose error, metres
/// per metre (about 2 degrees; the simulator's attitude noise is 0.5).
const POSE_TILT: f64 = 0.035;

/// The point of a polyline nearest `p`: where, how far, on which segment.
struct OnLine {
    point: Point3<f64>,
    distance: f64,
    segment: usize,
}

fn nearest_on(line: &[Point3<f64>], p: &Point3<f64>) -> OnLine {
    line.windows(2)
        .enumerate()
        .map(|(segment, w)| {
            let point = closest_on_segment(p, &w[0], &w[1]);
            OnLine {
                point,
                distance: (p - point).norm(),
                segment,
            }
        })
        .min_by(|a, b| a.distance.total_cmp(&b.distance))
        .expect("a segment")
}

fn polyline_length(line: &[Point3<f64>]) -> f64 {
    line.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(from: [f64; 3], to: [f64; 3]) -> Trace {
        Trace(vec![vec![from, to]])
    }

    fn view<'a>(trace: &'a Trace, cut: &'a [Point3<f64>], frame: u32) -> ViewLine<'a> {
        ViewLine {
            trace,
            cut,
            frame,
            near: 0.005,
        }
    }

    #[test]
    fn views_each_cut_by_the_border_make_the_whole_crack() {
        // A 1.4 m crack no frame holds whole: four views, each a few
        // centimetres off and 2% scaled (pose error), each cut where it
        // leaves the image; the middle one is longest.
        let a = line([0.0, 0.0, 0.0], [0.4, 0.0, 0.0]);
        let b = line([0.3, 0.02, 0.0], [0.9, 0.02, 0.0]);
        let c = line([0.8, -0.02, 0.01], [1.22, -0.02, 0.01]);
        let d = line([1.1, 0.0, 0.0], [1.4, 0.0, 0.0]);
        let cut_a = [Point3::new(0.4, 0.0, 0.0)];
        let cut_b = [Point3::new(0.3, 0.02, 0.0), Point3::new(0.9, 0.02, 0.0)];
        let cut_c = [
            Point3::new(0.8, -0.02, 0.01),
            Point3::new(1.22, -0.02, 0.01),
        ];
        let cut_d = [Point3::new(1.1, 0.0, 0.0)];
        let views = [
            view(&a, &cut_a, 1),
            view(&b, &cut_b, 2),
            view(&c, &cut_c, 3),
            view(&d, &cut_d, 4),
        ];
        let fused = fuse(&views, 0.1).unwrap();
        // 0.6 (b) + 0.3 (a beyond b's start) + 0.32 (c beyond b's end) +
        // 0.18 (d beyond c's end).
        assert!((fused.length_m - 1.4).abs() < 0.03, "{fused:?}");
        assert!(fused.complete, "both ends were seen inside a view");
        assert_eq!(fused.views, 4);
        // Without the views that saw its ends, it is a lower bound.
        let fused = fuse(&views[1..3], 0.1).unwrap();
        assert!(
            (fused.length_m - 0.92).abs() < 0.01 && !fused.complete,
            "{fused:?}"
        );
    }

    #[test]
    fn a_cut_end_goes_on_to_where_the_median_view_saw_it_end() {
        // The base view, cut at 0.5 m; three views go on to 0.8, 0.85 and
        // 0.95 m: the median, 0.85.
        let base = line([0.0, 0.0, 0.0], [0.5, 0.0, 0.0]);
        let cut = [Point3::new(0.5, 0.0, 0.0)];
        let traces: Vec<Trace> = [0.8, 0.85, 0.95]
            .iter()
            .map(|e| line([0.45, 0.01, 0.0], [*e, 0.01, 0.0]))
            .collect();
        let mut views = vec![view(&base, &cut, 0)];
        views.extend(
            traces
                .iter()
                .enumerate()
                .map(|(k, t)| view(t, &[], k as u32 + 1)),
        );
        // Each of the others is shorter than the base: 0.35 m..0.5 m.
        let fused = fuse(&views, 0.1).unwrap();
        assert!((fused.length_m - 0.85).abs() < 0.005, "{fused:?}");
        assert!(fused.complete);
    }

    #[test]
    fn an_end_the_crack_ends_at_is_not_carried_on() {
        // The base saw both its ends; a longer-reaching view (its pose
        // error along the crack) adds nothing.
        let base = line([0.0, 0.0, 0.0], [0.5, 0.0, 0.0]);
        let other = line([0.03, 0.0, 0.0], [0.53, 0.0, 0.0]);
        let fused = fuse(&[view(&base, &[], 0), view(&other, &[], 1)], 0.1).unwrap();
        assert!((fused.length_m - 0.5).abs() < 1e-9 && fused.complete);
    }

    #[test]
    fn a_view_along_the_line_off_by_its_pose_error_adds_nothing() {
        // The base, cut at 0.78 m; another frame shows the same stretch 2 cm
        // off and turned a degree (pose error): it runs back along the base,
        // not on beyond its end.
        let base = line([0.0, 0.0, 0.0], [0.78, 0.0, 0.0]);
        let cut = [Point3::new(0.78, 0.0, 0.0)];
        let other = line([0.77, 0.02, 0.0], [0.01, 0.02 + 0.76 * 0.0175, 0.0]);
        let other_cut = [Point3::new(0.77, 0.02, 0.0)];
        let fused = fuse(&[view(&base, &cut, 0), view(&other, &other_cut, 1)], 0.1).unwrap();
        assert!((fused.length_m - 0.78).abs() < 1e-9, "{fused:?}");
    }

    #[test]
    fn pieces_of_one_frame_add_up() {
        let a = line([0.0, 0.0, 0.0], [0.3, 0.0, 0.0]);
        let b = line([0.35, 0.0, 0.0], [0.6, 0.0, 0.0]);
        let c = line([0.0, 0.5, 0.0], [0.4, 0.5, 0.0]);
        // A second detection of `a`'s stretch, placed on its own fit of the
        // surface, counts and draws once.
        let again = line([0.0, 0.0, 0.009], [0.3, 0.0, 0.009]);
        let views = [a, b, again].map(|t| (t, 1)).into_iter().chain([(c, 2)]);
        let traces: Vec<(Trace, u32)> = views.collect();
        let views: Vec<ViewLine> = traces.iter().map(|(t, f)| view(t, &[], *f)).collect();
        let fused = fuse(&views, 0.1).unwrap();
        assert!((fused.length_m - 0.55).abs() < 1e-9, "{fused:?}");
        assert_eq!(fused.trace.0.len(), 2, "{fused:?}");
    }
}

//! Cracks in a pattern, by their spacing. The manual puts moderate
//! pattern (map) cracking in state 2 and heavy in state 3 by how far apart
//! the cracks run: 1.0 to 3.0 ft (0.3 to 0.9 m) is moderate, under 1.0 ft
//! (0.3 m) heavy.
//!
//! A crack runs in a pattern where another crack runs alongside it:
//! within 30 degrees of parallel and across from it (not off past its
//! end), along at least half its length. Its
//! spacing is the median distance between them there. Lines of one
//! candidate count as two cracks unless they touch (a branch is part of
//! its crack, not its neighbour). The surface between two cracks of a
//! pattern is the pattern's too: each point's span to its neighbour is
//! laid into the cells.

use nalgebra::{Point3, Vector3};
use postflight_core::condition::ConditionState;

/// Closer than this, cracks are heavy pattern cracking (1.0 ft).
pub const HEAVY_BELOW_M: f64 = 0.3048;
/// Closer than this, moderate (3.0 ft).
pub const MODERATE_BELOW_M: f64 = 0.9144;
/// Two cracks run alongside where their directions are this close.
const ALONGSIDE_DEG: f64 = 30.0;
/// Lines of one candidate this close touch: a branch, not a neighbour.
const TOUCH_M: f64 = 0.02;

/// A crack's centre line, sampled.
#[derive(Debug, Clone)]
pub struct Line {
    /// The crack (its index among the element's cracks) it is a line of.
    pub crack: usize,
    pub points: Vec<Point3<f64>>,
}

/// A stretch of surface between two cracks: a point on one and the
/// nearest on the other.
pub type Span = (Point3<f64>, Point3<f64>);

/// What the pattern rule says of one crack.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InPattern {
    /// Its spacing to the nearest crack alongside, metres.
    pub spacing_m: Option<f64>,
    /// The state its pattern puts it in.
    pub state: Option<ConditionState>,
    /// Each stretch of surface between it and its neighbour, as pairs of
    /// points, for the cells between them.
    pub spans: Vec<Span>,
}

/// The state a spacing puts a pattern in; `None` for cracks further apart.
pub fn pattern_state(spacing_m: f64) -> Option<ConditionState> {
    if spacing_m < HEAVY_BELOW_M {
        Some(ConditionState::Poor)
    } else if spacing_m < MODERATE_BELOW_M {
        Some(ConditionState::Fair)
    } else {
        None
    }
}

/// Lines sampled at most `step` apart.
pub fn sample(crack: usize, line: &[[f64; 3]], step: f64) -> Line {
    let mut points = Vec::new();
    for pair in line.windows(2) {
        let (a, b) = (Point3::from(pair[0]), Point3::from(pair[1]));
        let n = ((b - a).norm() / step).ceil().max(1.0) as usize;
        points.extend((0..n).map(|i| a + (b - a) * (i as f64 / n as f64)));
    }
    if let Some(last) = line.last() {
        points.push(Point3::from(*last));
    }
    Line { crack, points }
}

/// Each of `cracks` cracks' pattern, from `lines` (every line of every
/// crack on one element).
pub fn patterns(cracks: usize, lines: &[Line]) -> Vec<InPattern> {
    let mut out = vec![InPattern::default(); cracks];
    for (i, a) in lines.iter().enumerate() {
        let mut nearest: Option<(f64, Vec<Span>)> = None;
        for (j, b) in lines.iter().enumerate() {
            if i == j || (a.crack == b.crack && touch(a, b)) {
                continue;
            }
            if let Some((spacing, spans)) = alongside(a, b)
                && nearest.as_ref().is_none_or(|(s, _)| spacing < *s)
            {
                nearest = Some((spacing, spans));
            }
        }
        let Some((spacing, spans)) = nearest else {
            continue;
        };
        let p = &mut out[a.crack];
        if p.spacing_m.is_none_or(|s| spacing < s) {
            p.spacing_m = Some(spacing);
            p.state = pattern_state(spacing);
        }
        if pattern_state(spacing).is_some() {
            p.spans.extend(spans);
        }
    }
    out
}

/// Whether two lines come within [`TOUCH_M`] of each other.
fn touch(a: &Line, b: &Line) -> bool {
    a.points
        .iter()
        .any(|p| nearest_on(p, &b.points).is_some_and(|(q, _)| (q - p).norm() < TOUCH_M))
}

/// `a`'s spacing to `b` where `b` runs alongside it along at least half of
/// `a`, and the spans between them there.
fn alongside(a: &Line, b: &Line) -> Option<(f64, Vec<Span>)> {
    if a.points.len() < 2 {
        return None;
    }
    let cos_limit = ALONGSIDE_DEG.to_radians().cos();
    let mut distances = Vec::new();
    let mut spans = Vec::new();
    for (k, p) in a.points.iter().enumerate() {
        let dir = direction(&a.points, k);
        let Some((q, b_dir)) = nearest_on(p, &b.points) else {
            continue;
        };
        // Alongside: parallel, and across from it (not off past its end).
        let across = (q - p)
            .try_normalize(1e-9)
            .is_none_or(|to| to.dot(&dir).abs() <= 0.5);
        if dir.dot(&b_dir).abs() >= cos_limit && across {
            distances.push((q - p).norm());
            spans.push((*p, q));
        }
    }
    if 2 * distances.len() < a.points.len() {
        return None;
    }
    distances.sort_by(f64::total_cmp);
    Some((distances[distances.len() / 2], spans))
}

/// The line's direction at its `k`th point (unit).
fn direction(points: &[Point3<f64>], k: usize) -> Vector3<f64> {
    let (a, b) = (k.saturating_sub(1), (k + 1).min(points.len() - 1));
    (points[b] - points[a])
        .try_normalize(1e-12)
        .unwrap_or_else(Vector3::x)
}

/// The nearest point of the polyline `points` to `p`, and the direction of
/// the segment it is on; `None` for a line of fewer than two points.
fn nearest_on(p: &Point3<f64>, points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    let mut best: Option<(f64, Point3<f64>, Vector3<f64>)> = None;
    for pair in points.windows(2) {
        let q = postflight_core::trace::closest_on_segment(p, &pair[0], &pair[1]);
        let d = (q - p).norm();
        if best.is_none_or(|(bd, _, _)| d < bd)
            && let Some(dir) = (pair[1] - pair[0]).try_normalize(1e-12)
        {
            best = Some((d, q, dir));
        }
    }
    best.map(|(_, q, dir)| (q, dir))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(crack: usize, y: f64, x0: f64, x1: f64) -> Line {
        sample(crack, &[[x0, y, 0.0], [x1, y, 0.0]], 0.05)
    }

    #[test]
    fn parallel_cracks_are_a_pattern_by_their_spacing() {
        // Three cracks 0.5 m apart: moderate; two 0.2 m apart: heavy.
        let lines = [
            straight(0, 0.0, 0.0, 2.0),
            straight(1, 0.5, 0.0, 2.0),
            straight(2, 1.0, 0.0, 2.0),
        ];
        let p = patterns(3, &lines);
        for c in &p {
            assert!((c.spacing_m.unwrap() - 0.5).abs() < 1e-9);
            assert_eq!(c.state, Some(ConditionState::Fair));
            assert!(!c.spans.is_empty());
        }
        let close = patterns(2, &[straight(0, 0.0, 0.0, 2.0), straight(1, 0.2, 0.0, 2.0)]);
        assert_eq!(close[0].state, Some(ConditionState::Poor));
        let far = patterns(2, &[straight(0, 0.0, 0.0, 2.0), straight(1, 1.2, 0.0, 2.0)]);
        assert_eq!(far[0].state, None);
        assert!(far[0].spans.is_empty());
    }

    #[test]
    fn crossing_cracks_and_a_branch_are_no_pattern() {
        let across = sample(1, &[[1.0, -1.0, 0.0], [1.0, 1.0, 0.0]], 0.05);
        let p = patterns(2, &[straight(0, 0.0, 0.0, 2.0), across]);
        assert_eq!(p[0].spacing_m, None);
        assert_eq!(p[1].spacing_m, None);
        // A branch leaving its crack at 20 degrees touches it: its own crack.
        let branch = sample(0, &[[1.0, 0.0, 0.0], [2.0, 0.364, 0.0]], 0.05);
        let p = patterns(1, &[straight(0, 0.0, 0.0, 2.0), branch]);
        assert_eq!(p[0].spacing_m, None);
    }

    #[test]
    fn a_short_crack_beside_a_long_one_is_in_its_pattern_but_not_the_long_one() {
        let p = patterns(
            2,
            &[straight(0, 0.0, 0.0, 4.0), straight(1, 0.25, 1.0, 1.5)],
        );
        assert_eq!(p[1].state, Some(ConditionState::Poor));
        assert_eq!(
            p[0].state, None,
            "the short one runs beside an eighth of it"
        );
    }
}

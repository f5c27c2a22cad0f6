//! A view's centre line on the structure: its traced pixels put on the
//! surface and simplified (a candidate's, from its views', is
//! [`crate::fused_line`]'s).

use nalgebra::Point3;
use postflight_core::trace::{Trace, closest_on_segment, distance_to_lines};

use crate::trace::CrackTrace;

/// A view's centre line: the chains of `trace` with pixel `i` at `at[i]`
/// (split where a pixel has no place), each simplified to within
/// `tolerance` metres.
pub fn on_surface(trace: &CrackTrace, at: &[Option<Point3<f64>>], tolerance: f64) -> Trace {
    let mut lines = Vec::new();
    for chain in trace.chains() {
        let mut run: Vec<Point3<f64>> = Vec::new();
        for p in chain.iter().map(|&i| at[i as usize]) {
            match p {
                Some(p) => run.push(p),
                None => lines.extend(finished(std::mem::take(&mut run), tolerance)),
            }
        }
        lines.extend(finished(run, tolerance));
    }
    Trace(lines)
}

/// A run of points as a polyline, simplified; `None` for a lone point.
fn finished(run: Vec<Point3<f64>>, tolerance: f64) -> Option<Vec<[f64; 3]>> {
    (run.len() >= 2).then(|| {
        simplify(&run, tolerance)
            .iter()
            .map(|p| p.coords.into())
            .collect()
    })
}

/// Ramer–Douglas–Peucker: the fewest of `line`'s points that keep every
/// point within `tolerance` of the polyline through them.
fn simplify(line: &[Point3<f64>], tolerance: f64) -> Vec<Point3<f64>> {
    let mut keep = vec![false; line.len()];
    keep[0] = true;
    keep[line.len() - 1] = true;
    let mut stack = vec![(0, line.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        let far = (a + 1..b)
            .map(|i| (i, to_segment(&line[i], &line[a], &line[b])))
            .max_by(|x, y| x.1.total_cmp(&y.1));
        if let Some((i, _)) = far.filter(|(_, d)| *d > tolerance) {
            keep[i] = true;
            stack.push((a, i));
            stack.push((i, b));
        }
    }
    line.iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

/// The share of `trace`'s length within `near` metres of any of `others`
/// (0 when it is empty).
pub fn share_near(trace: &Trace, others: &[&Trace], near: f64) -> f64 {
    let length = trace.length_m();
    if length <= 0.0 || others.iter().all(|t| t.is_empty()) {
        return 0.0;
    }
    let others = Trace(others.iter().flat_map(|t| t.0.iter().cloned()).collect());
    1.0 - trace.length_beyond(&others, near, |_| true) / length
}

pub(crate) fn points(line: &[[f64; 3]]) -> Vec<Point3<f64>> {
    line.iter().map(|p| Point3::from(*p)).collect()
}

/// Distance from `p` to the nearest of `lines`.
pub(crate) fn distance(p: &Point3<f64>, lines: &[Vec<Point3<f64>>]) -> f64 {
    distance_to_lines(p, lines.iter().map(|l| l.iter().copied()))
}

/// Distance from `p` to the segment `a`–`b`.
fn to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    (p - closest_on_segment(p, a, b)).norm()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn a_chain_of_pixels_becomes_a_simplified_polyline_split_where_unplaced() {
        // An L of pixels, one of them without a place on the surface.
        let pixels: Vec<Point2<f64>> = (0..10)
            .map(|i| Point2::new(f64::from(i), 0.0))
            .chain((1..6).map(|j| Point2::new(9.0, f64::from(j))))
            .collect();
        let edges: Vec<(u32, u32)> = (0..pixels.len() as u32 - 1).map(|i| (i, i + 1)).collect();
        let trace = CrackTrace {
            pixels: pixels.clone(),
            edges,
            bridges: Vec::new(),
        };
        let mut at: Vec<Option<Point3<f64>>> = pixels
            .iter()
            .map(|p| Some(Point3::new(p.x / 1000.0, p.y / 1000.0, 2.0)))
            .collect();
        let whole = on_surface(&trace, &at, 0.0001);
        assert_eq!(
            whole.0,
            vec![vec![
                [0.0, 0.0, 2.0],
                [0.009, 0.0, 2.0],
                [0.009, 0.005, 2.0]
            ]]
        );
        assert!((whole.length_m() - 0.014).abs() < 1e-12);
        at[4] = None;
        let split = on_surface(&trace, &at, 0.0001);
        assert_eq!(split.0.len(), 2);
        assert!((split.length_m() - 0.012).abs() < 1e-12);
    }
}

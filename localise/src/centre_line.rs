//! A crack's centre line on the structure: a view's, its traced pixels put
//! on the surface and simplified, and a candidate's, its views' merged.

use nalgebra::Point3;
use postflight_core::trace::Trace;

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

/// Several views' centre lines as one: the first whole, then from each of
/// the others the stretches farther than `apart` metres from what is kept
/// already (where the earlier views were cut by the image border, or the
/// crack faded or was hidden in them), each joined to the point it leaves
/// from, simplified to within `tolerance`. A stretch must reach twice
/// `apart` away: one that stays near is the same crack seen with another
/// pose error, running beside it.
pub fn merge(views: &[&Trace], apart: f64, tolerance: f64) -> Trace {
    let Some((first, rest)) = views.split_first() else {
        return Trace::default();
    };
    let mut kept: Vec<Vec<Point3<f64>>> = first.0.iter().map(|l| points(l)).collect();
    for view in rest {
        for line in &view.0 {
            let dense = densify(&points(line), apart / 2.0);
            let off: Vec<f64> = dense.iter().map(|p| distance(p, &kept)).collect();
            // Each stretch off the kept lines, with how far off it reaches.
            let mut runs: Vec<(Vec<Point3<f64>>, f64)> = Vec::new();
            let mut run: Vec<Point3<f64>> = Vec::new();
            let mut reach: f64 = 0.0;
            for (i, p) in dense.iter().enumerate() {
                if off[i] > apart {
                    // Joined to the kept point it leaves from.
                    if run.is_empty() && i > 0 {
                        run.push(dense[i - 1]);
                    }
                    run.push(*p);
                    reach = reach.max(off[i]);
                } else if !run.is_empty() {
                    run.push(*p);
                    runs.push((std::mem::take(&mut run), reach));
                    reach = 0.0;
                }
            }
            runs.push((run, reach));
            runs.retain(|(run, reach)| run.len() >= 2 && *reach > 2.0 * apart);
            kept.extend(runs.iter().map(|(r, _)| simplify(r, tolerance)));
        }
    }
    Trace(
        kept.iter()
            .map(|l| l.iter().map(|p| p.coords.into()).collect())
            .collect(),
    )
}

/// The share of `trace`'s length within `near` metres of any of `others`
/// (0 when it is empty).
pub fn share_near(trace: &Trace, others: &[&Trace], near: f64) -> f64 {
    let kept: Vec<Vec<Point3<f64>>> = others
        .iter()
        .flat_map(|t| t.0.iter().map(|l| points(l)))
        .collect();
    let dense: Vec<Point3<f64>> = trace
        .0
        .iter()
        .flat_map(|l| densify(&points(l), near / 2.0))
        .collect();
    if dense.is_empty() || kept.is_empty() {
        return 0.0;
    }
    dense.iter().filter(|p| distance(p, &kept) <= near).count() as f64 / dense.len() as f64
}

fn points(line: &[[f64; 3]]) -> Vec<Point3<f64>> {
    line.iter().map(|p| Point3::from(*p)).collect()
}

/// `line` with points added so that none is more than `step` from the next.
fn densify(line: &[Point3<f64>], step: f64) -> Vec<Point3<f64>> {
    let mut out = Vec::new();
    for w in line.windows(2) {
        let n = ((w[1] - w[0]).norm() / step).ceil().max(1.0) as usize;
        out.extend((0..n).map(|k| w[0] + (w[1] - w[0]) * (k as f64 / n as f64)));
    }
    out.extend(line.last());
    out
}

/// Distance from `p` to the nearest of `lines`.
fn distance(p: &Point3<f64>, lines: &[Vec<Point3<f64>>]) -> f64 {
    lines
        .iter()
        .flat_map(|l| {
            let single = (l.len() == 1).then(|| (p - l[0]).norm());
            l.windows(2)
                .map(|w| to_segment(p, &w[0], &w[1]))
                .chain(single)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to the segment `a`–`b`.
fn to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
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

    #[test]
    fn merging_keeps_what_only_later_views_show() {
        // One view shows the crack's first 40 cm, another (2 cm off, as
        // pose noise puts it) its last 40 cm.
        let left = Trace(vec![vec![[0.0, 0.0, 0.0], [0.4, 0.0, 0.0]]]);
        let right = Trace(vec![vec![[0.2, 0.02, 0.0], [0.6, 0.02, 0.0]]]);
        let merged = merge(&[&left, &right], 0.03, 0.001);
        assert!((merged.length_m() - 0.6).abs() < 0.03, "{merged:?}");
        // A view showing nothing new adds nothing, nor one running beside
        // it (a larger pose error).
        assert_eq!(merge(&[&left, &left], 0.03, 0.001), left);
        let beside = Trace(vec![vec![[0.0, 0.05, 0.0], [0.4, 0.04, 0.0]]]);
        assert_eq!(merge(&[&left, &beside], 0.03, 0.001), left);
    }
}

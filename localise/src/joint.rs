//! Formwork joints, which a crack detector finds too: thin, dark grooves
//! where concrete panels or lifts met, running straight across a face,
//! level or plumb. A candidate whose views see a line do that is set aside
//! as a joint, not proposed as a crack; cracks wander (a crack as straight as a
//! joint over 15 cm and more is rare, and one also level or plumb rarer).

use nalgebra::{Matrix3, Point3, Vector3};

use crate::fusion::DefectCandidate;
use crate::observation::Observation;

/// A joint's points stray from their straight line by at most this (pose noise and
/// the pixel footprint), metres, plus [`STRAY_SHARE`] of its length.
const STRAY_M: f64 = 0.006;
const STRAY_SHARE: f64 = 0.005;
/// Shorter lines say too little about their straightness, metres.
const MIN_LENGTH_M: f64 = 0.15;
/// How far from level or from the face's fall line a joint may run, degrees.
const MAX_TILT_DEG: f64 = 5.0;

/// The straight line a view's centre-line points lie along.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Unit direction.
    pub direction: Vector3<f64>,
    /// From one end of the points to the other, along it, metres.
    pub length_m: f64,
    /// Farthest point from it, metres.
    pub stray_m: f64,
}

impl Line {
    /// The line fitted through `points` (the principal axis of their
    /// spread); `None` with fewer than two distinct points.
    pub fn fit(points: &[Point3<f64>]) -> Option<Self> {
        let points: Vec<Vector3<f64>> = points.iter().map(|p| p.coords).collect();
        if points.len() < 2 {
            return None;
        }
        let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        let spread: Matrix3<f64> = points
            .iter()
            .map(|p| (p - mean) * (p - mean).transpose())
            .sum();
        let eigen = spread.symmetric_eigen();
        let axis = eigen.eigenvalues.imax();
        let direction = eigen.eigenvectors.column(axis).normalize();
        if !direction.iter().all(|v| v.is_finite()) {
            return None;
        }
        let along: Vec<f64> = points.iter().map(|p| (p - mean).dot(&direction)).collect();
        let (lo, hi) = along
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
                (lo.min(*s), hi.max(*s))
            });
        let stray_m = points
            .iter()
            .zip(&along)
            .map(|(p, s)| ((p - mean) - direction * *s).norm())
            .fold(0.0, f64::max);
        (hi > lo).then_some(Self {
            direction,
            length_m: hi - lo,
            stray_m,
        })
    }

    /// Whether it runs as a formwork joint does on a face with outward
    /// `normal`: straight over 15 cm or more, level or plumb.
    pub fn runs_like_a_joint(&self, normal: &Vector3<f64>) -> bool {
        self.is_straight() && self.is_level_or_plumb(normal)
    }

    /// Straight enough for a joint: long, and close to its line throughout.
    fn is_straight(&self) -> bool {
        self.length_m >= MIN_LENGTH_M && self.stray_m <= STRAY_M + STRAY_SHARE * self.length_m
    }

    /// Level, or down the fall line of the face with outward `normal`.
    fn is_level_or_plumb(&self, normal: &Vector3<f64>) -> bool {
        let tilt = MAX_TILT_DEG.to_radians();
        let level = self.direction.z.abs() <= tilt.sin();
        let fall = -Vector3::z() + normal * normal.z;
        let plumb = fall.norm() > 0.3 && self.direction.dot(&fall.normalize()).abs() >= tilt.cos();
        level || plumb
    }
}

/// Whether candidate `c` is a formwork joint: half or more of its views
/// (those whose centre line is long enough to judge) see it run like one.
/// View by view, each on its own surface plane, not its fused trace: a
/// long joint's candidate gathers views along many metres, where a stray
/// crossing crack or pose drift would bend the whole; and a joint seen
/// only obliquely has no fused trace.
pub fn is_joint(c: &DefectCandidate, observations: &[Observation]) -> bool {
    let lines: Vec<&Line> = c
        .observations
        .iter()
        .filter_map(|i| observations[*i].placement.as_ref()?.line.as_ref())
        .filter(|l| l.length_m >= MIN_LENGTH_M)
        .collect();
    let joints = lines
        .iter()
        .filter(|l| l.runs_like_a_joint(&c.normal))
        .count();
    joints > 0 && 2 * joints >= lines.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall() -> Vector3<f64> {
        Vector3::x()
    }

    /// Points on the wall x = 0 from the origin in steps of (dy, dz), each
    /// pushed sideways by `wobble(k)`.
    fn line(steps: usize, d: (f64, f64), wobble: impl Fn(usize) -> f64) -> Vec<Point3<f64>> {
        let (dy, dz) = d;
        let side = Vector3::new(0.0, -dz, dy).normalize();
        (0..=steps)
            .map(|k| Point3::new(0.0, dy * k as f64, dz * k as f64) + side * wobble(k))
            .collect()
    }

    fn runs_like_a_joint(points: &[Point3<f64>], normal: &Vector3<f64>) -> bool {
        Line::fit(points).is_some_and(|l| l.runs_like_a_joint(normal))
    }

    #[test]
    fn a_straight_level_or_plumb_groove_is_a_joint() {
        // 1 m level and plumb, 2 mm of noise.
        let noise = |k: usize| 0.002 * ((k * 7919) % 5) as f64 / 4.0;
        assert!(runs_like_a_joint(&line(50, (0.02, 0.0), noise), &wall()));
        assert!(runs_like_a_joint(&line(50, (0.0, 0.02), noise), &wall()));
    }

    #[test]
    fn cracks_that_wander_slant_or_are_short_are_not() {
        // Wandering 3 cm either way over 1 m, level.
        let wander = |k: usize| 0.03 * (k as f64 / 8.0).sin();
        assert!(!runs_like_a_joint(&line(50, (0.02, 0.0), wander), &wall()));
        // Straight but at 20 degrees.
        let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
        assert!(!runs_like_a_joint(
            &line(50, (0.02 * c, 0.02 * s), |_| 0.0),
            &wall()
        ));
        // Straight and level but 10 cm.
        assert!(!runs_like_a_joint(&line(5, (0.02, 0.0), |_| 0.0), &wall()));
        assert!(!runs_like_a_joint(&[], &wall()));
    }

    #[test]
    fn on_a_sloping_face_plumb_means_down_its_fall_line() {
        // A face tilted 30 degrees back from vertical; its fall line.
        let normal = Vector3::new(30f64.to_radians().cos(), 0.0, 30f64.to_radians().sin());
        let fall = (-Vector3::z() + normal * normal.z).normalize();
        let down: Vec<Point3<f64>> = (0..=40)
            .map(|k| Point3::from(fall * (0.025 * k as f64)))
            .collect();
        assert!(runs_like_a_joint(&down, &normal));
    }
}

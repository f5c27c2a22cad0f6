//! A similarity transform (scale, rotation, translation): how a
//! reconstruction's frame, whose scale is its own, sits in the map frame;
//! found by least squares from point pairs (Umeyama's method), or from a
//! reference frame's place on the Earth.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::geo::{GeoOrigin, Geodetic};

/// `p -> scale * rotation * p + translation`: how a reconstruction's frame
/// sits in the run's map frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Similarity {
    pub scale: f64,
    #[serde(with = "crate::serde_pose")]
    pub rigid: Isometry3<f64>,
}

impl Similarity {
    /// Fewer pairs leave a fit to chance.
    pub const MIN_PAIRS: usize = 3;

    pub fn identity() -> Self {
        Self {
            scale: 1.0,
            rigid: Isometry3::identity(),
        }
    }

    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        self.rigid * Point3::from(p.coords * self.scale)
    }

    /// A camera pose moved by it (the rotation turns, the centre moves).
    pub fn pose(&self, pose: &Isometry3<f64>) -> Isometry3<f64> {
        let centre = self.apply(&Point3::from(pose.translation.vector));
        Isometry3::from_parts(
            Translation3::from(centre.coords),
            self.rigid.rotation * pose.rotation,
        )
    }

    /// The similarity from the reference frame `at` (east-north-up there)
    /// into the map frame at `origin`: through the Earth-centred frame.
    pub fn from_reference(at: &Geodetic, origin: &GeoOrigin) -> Self {
        // Three points of the reference frame on the Earth fix its axes.
        let reference = GeoOrigin {
            position: *at,
            yaw_deg: 0.0,
        };
        let local = |p: Vector3<f64>| origin.to_local(&reference.to_geodetic(&Point3::from(p)));
        let o = local(Vector3::zeros());
        let axes = Matrix3::from_columns(&[
            local(Vector3::x() * 100.0) - o,
            local(Vector3::y() * 100.0) - o,
            local(Vector3::z() * 100.0) - o,
        ]) / 100.0;
        let rotation = rotation(&axes);
        Self {
            scale: 1.0,
            rigid: Isometry3::from_parts(Translation3::from(o.coords), rotation),
        }
    }

    /// The least-squares similarity putting `from` on `to` (pairs; Umeyama's
    /// method), and its RMS residual, metres.
    pub fn fit(from: &[Point3<f64>], to: &[Point3<f64>]) -> Result<(Self, f64), String> {
        let n = from.len();
        if n < Self::MIN_PAIRS || n != to.len() {
            return Err(format!(
                "{n} point pairs; a similarity needs {} or more",
                Self::MIN_PAIRS
            ));
        }
        let finite = |ps: &[Point3<f64>]| ps.iter().all(|p| p.coords.iter().all(|v| v.is_finite()));
        if !(finite(from) && finite(to)) {
            return Err("a point is not a place (its coordinates are not finite)".into());
        }
        let mean =
            |ps: &[Point3<f64>]| ps.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n as f64;
        let (mf, mt) = (mean(from), mean(to));
        let mut cov = Matrix3::zeros();
        let mut spread = 0.0;
        for (a, b) in from.iter().zip(to) {
            let (a, b) = (a.coords - mf, b.coords - mt);
            cov += b * a.transpose();
            spread += a.norm_squared();
        }
        cov /= n as f64;
        spread /= n as f64;
        if spread < 1e-12 {
            return Err("the points are all at one place".into());
        }
        let svd = cov.svd(true, true);
        let (u, v_t) = (svd.u.ok_or("no SVD")?, svd.v_t.ok_or("no SVD")?);
        let mut d = Matrix3::identity();
        if (u * v_t).determinant() < 0.0 {
            d[(2, 2)] = -1.0;
        }
        let r = u * d * v_t;
        let scale = (svd.singular_values.component_mul(&d.diagonal())).sum() / spread;
        let rotation = rotation(&r);
        let translation = mt - rotation * (mf * scale);
        let fit = Self {
            scale,
            rigid: Isometry3::from_parts(Translation3::from(translation), rotation),
        };
        let rms = (from
            .iter()
            .zip(to)
            .map(|(a, b)| (fit.apply(a) - b).norm_squared())
            .sum::<f64>()
            / n as f64)
            .sqrt();
        Ok((fit, rms))
    }
}

/// The rotation nearest `m`, found in a bounded number of steps: nalgebra's
/// `from_matrix` iterates until it converges, which a matrix holding NaN
/// never does. A rotation matrix converges in a few.
fn rotation(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_matrix_eps(m, f64::EPSILON, 100, UnitQuaternion::identity())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn a_similarity_is_found_again_from_its_points() {
        let truth = Similarity {
            scale: 7.3,
            rigid: Isometry3::new(Vector3::new(12.0, -4.0, 30.0), Vector3::new(0.3, -0.2, 1.1)),
        };
        let from: Vec<Point3<f64>> = (0..12)
            .map(|i| {
                let t = f64::from(i);
                Point3::new(t.sin(), (0.7 * t).cos(), 0.1 * t)
            })
            .collect();
        let to: Vec<Point3<f64>> = from.iter().map(|p| truth.apply(p)).collect();
        let (fit, rms) = Similarity::fit(&from, &to).unwrap();
        assert!(rms < 1e-9, "{rms}");
        assert!((fit.scale - 7.3).abs() < 1e-9);
        assert!((fit.rigid.translation.vector - truth.rigid.translation.vector).norm() < 1e-9);
        assert!(fit.rigid.rotation.angle_to(&truth.rigid.rotation) < 1e-9);
        // A camera pose moves with it: its axis turns, its centre moves.
        let pose = Isometry3::new(Vector3::new(0.5, 0.2, 0.1), Vector3::new(0.0, 0.4, 0.0));
        let moved = fit.pose(&pose);
        let axis = |p: &Isometry3<f64>| p.rotation * Vector3::z();
        assert!((axis(&moved) - truth.rigid.rotation * axis(&pose)).norm() < 1e-9);
        assert!(Similarity::fit(&from[..2], &to[..2]).is_err());
    }

    #[test]
    fn a_reference_frame_nearby_is_a_shift_and_a_slight_turn() {
        let origin = GeoOrigin::parse("47.3977,8.5456,488").unwrap();
        let at = origin.to_geodetic(&Point3::new(120.0, -40.0, 5.0));
        let s = Similarity::from_reference(&at, &origin);
        assert!((s.apply(&Point3::origin()) - Point3::new(120.0, -40.0, 5.0)).norm() < 1e-6);
        // A point 10 m east of the reference, on the Earth, where the
        // origin's frame puts it.
        let reference = GeoOrigin {
            position: at,
            yaw_deg: 0.0,
        };
        let p = Point3::new(10.0, 3.0, 2.0);
        let expected = origin.to_local(&reference.to_geodetic(&p));
        assert!(
            (s.apply(&p) - expected).norm() < 1e-6,
            "{}",
            s.apply(&p) - expected
        );
    }
}

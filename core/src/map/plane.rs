//! Planes through map points: a surface's position and normal.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// The least-squares plane through `points`: their centroid and its unit
/// normal (its sign arbitrary); `None` for fewer than three points or
/// points on a line.
pub fn fit_plane(points: &[Point3<f64>]) -> Option<(Point3<f64>, Vector3<f64>)> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let c = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        cov += d * d.transpose();
    }
    let eig = SymmetricEigen::new(cov / n);
    let (k, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    // A line of points (or one point) has no plane.
    let mut sorted = [eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]];
    sorted.sort_by(f64::total_cmp);
    if sorted[1] < 1e-6 {
        return None;
    }
    Some((Point3::from(c), eig.eigenvectors.column(k).normalize()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_through_points_of_a_tilted_square_has_its_normal() {
        let normal = Vector3::new(1.0, 2.0, 3.0).normalize();
        let u = normal.cross(&Vector3::z()).normalize();
        let v = normal.cross(&u);
        let points: Vec<Point3<f64>> = (0..25)
            .map(|i| Point3::new(1.0, -2.0, 0.5) + u * f64::from(i % 5) + v * f64::from(i / 5))
            .collect();
        let (c, n) = fit_plane(&points).unwrap();
        assert!(n.dot(&normal).abs() > 1.0 - 1e-12);
        assert!(((c - points[0]).dot(&normal)).abs() < 1e-12);
        assert!(fit_plane(&points[..5]).is_none(), "points on a line");
    }
}

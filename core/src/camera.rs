//! Camera models: pinhole intrinsics with the ROS distortion models, and the
//! camera's mounting on the body (extrinsics).

use nalgebra::{Isometry3, Point2, Vector3};
use serde::{Deserialize, Serialize};

use crate::shown::Shown;

/// Lens distortion, as named by ROS's `distortion_model`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", content = "coefficients", rename_all = "snake_case")]
pub enum Distortion {
    /// No distortion (an empty `D`, or all zeros).
    None,
    /// OpenCV radial-tangential: `[k1, k2, p1, p2, k3]`.
    PlumbBob([f64; 5]),
    /// OpenCV rational: `[k1, k2, p1, p2, k3, k4, k5, k6]`.
    RationalPolynomial([f64; 8]),
    /// OpenCV fisheye (Kannala-Brandt): `[k1, k2, k3, k4]`.
    Equidistant([f64; 4]),
}

impl Distortion {
    /// No lens's coefficient is this large: OpenCV's calibrations give
    /// single figures, a rational model's denominators some tens.
    pub const MAX_COEFFICIENT: f64 = 1000.0;

    /// Parse a ROS model name and coefficient list.
    pub fn from_ros(model: &str, d: &[f64]) -> Result<Self, String> {
        if let Some(bad) = d
            .iter()
            .find(|v| !(-Self::MAX_COEFFICIENT..=Self::MAX_COEFFICIENT).contains(*v))
        {
            return Err(format!(
                "distortion coefficient {} is not a lens's (each must be finite and within ±{})",
                Shown(*bad),
                Self::MAX_COEFFICIENT
            ));
        }
        if d.iter().all(|v| *v == 0.0) {
            return Ok(Self::None);
        }
        let take = |n: usize| -> Result<Vec<f64>, String> {
            if d.len() < n {
                return Err(format!(
                    "distortion model {model:?} needs {n} coefficients, got {}",
                    d.len()
                ));
            }
            Ok(d[..n].to_vec())
        };
        Ok(match model {
            "plumb_bob" if d.len() >= 8 => {
                Self::RationalPolynomial(take(8)?.try_into().expect("8 coefficients"))
            }
            "plumb_bob" | "" => {
                let mut c = [0.0; 5];
                c[..d.len().min(5)].copy_from_slice(&d[..d.len().min(5)]);
                Self::PlumbBob(c)
            }
            "rational_polynomial" => {
                Self::RationalPolynomial(take(8)?.try_into().expect("8 coefficients"))
            }
            "equidistant" | "fisheye" => {
                Self::Equidistant(take(4)?.try_into().expect("4 coefficients"))
            }
            other => {
                return Err(format!(
                    "unsupported distortion model {other:?} (supported: plumb_bob, rational_polynomial, equidistant)"
                ));
            }
        })
    }

    /// Map normalised undistorted coordinates to distorted ones.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        match *self {
            Self::None => (x, y),
            Self::PlumbBob([k1, k2, p1, p2, k3]) => {
                radial_tangential(x, y, [k1, k2, p1, p2, k3, 0.0, 0.0, 0.0])
            }
            Self::RationalPolynomial(c) => radial_tangential(x, y, c),
            Self::Equidistant([k1, k2, k3, k4]) => {
                let r = (x * x + y * y).sqrt();
                if r < 1e-12 {
                    return (x, y);
                }
                let theta = r.atan();
                let t2 = theta * theta;
                let theta_d = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
                (x * theta_d / r, y * theta_d / r)
            }
        }
    }

    /// Invert [`Self::distort`] by fixed-point iteration (as OpenCV's
    /// `undistortPoints`), refined with Newton steps on the residual.
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        if matches!(self, Self::None) {
            return (xd, yd);
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-14 && ey.abs() < 1e-14 {
                break;
            }
            // Numerical Jacobian; the maps are smooth near the image.
            let h = 1e-7;
            let (ax, ay) = self.distort(x + h, y);
            let (bx, by) = self.distort(x, y + h);
            let (j11, j21, j12, j22) = ((ax - fx) / h, (ay - fy) / h, (bx - fx) / h, (by - fy) / h);
            let det = j11 * j22 - j12 * j21;
            if det.abs() < 1e-12 {
                x -= ex;
                y -= ey;
            } else {
                x -= (j22 * ex - j12 * ey) / det;
                y -= (-j21 * ex + j11 * ey) / det;
            }
        }
        (x, y)
    }
}

fn radial_tangential(x: f64, y: f64, [k1, k2, p1, p2, k3, k4, k5, k6]: [f64; 8]) -> (f64, f64) {
    let r2 = x * x + y * y;
    let radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)));
    (
        x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
        y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
    )
}

/// Pinhole intrinsics of an image stream, in the ROS optical convention
/// (x right, y down, z forward).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub distortion: Distortion,
}

impl Intrinsics {
    /// An ideal pinhole: `width` x `height` pixels, focal length `f` pixels,
    /// the principal point at the image centre, no distortion.
    pub fn pinhole(width: u32, height: u32, f: f64) -> Self {
        Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: f64::from(width) / 2.0,
            cy: f64::from(height) / 2.0,
            distortion: Distortion::None,
        }
    }

    /// From the fields ROS calibrations carry: image size, the row-major
    /// camera matrix `K` and the distortion model and coefficients.
    pub fn from_ros(
        width: u32,
        height: u32,
        k: &[f64],
        model: &str,
        d: &[f64],
    ) -> Result<Self, String> {
        let [fx, _, cx, _, fy, cy, ..] = k else {
            return Err(format!(
                "camera matrix K has {} values, expected 9",
                k.len()
            ));
        };
        if *fx == 0.0 && *fy == 0.0 {
            return Err("camera matrix K is unset (fx, fy must be positive)".into());
        }
        let lens = Self {
            width,
            height,
            fx: *fx,
            fy: *fy,
            cx: *cx,
            cy: *cy,
            distortion: Distortion::from_ros(model, d)?,
        };
        lens.check()?;
        Ok(lens)
    }

    /// A longer focal length than this, in pixels, is no camera's (a 20 MP
    /// frame behind a 1200 mm lens has some 300,000).
    pub const MAX_FOCAL_PX: f64 = 1e6;

    /// Whether these are a camera's: a positive size, focal lengths
    /// positive up to [`Self::MAX_FOCAL_PX`], the principal point within a
    /// frame's size of the frame. Every lens read from a file or a tag
    /// passes this where it enters, so nothing later meets NaN.
    pub fn check(&self) -> Result<(), String> {
        let Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            ..
        } = *self;
        if width == 0 || height == 0 {
            return Err(format!(
                "an image {width} x {height} pixels (width and height must be positive)"
            ));
        }
        let focal = |f: f64| f > 0.0 && f <= Self::MAX_FOCAL_PX;
        if !(focal(fx) && focal(fy)) {
            return Err(format!(
                "focal length {} x {} px (each must be positive and at most {})",
                Shown(fx),
                Shown(fy),
                Self::MAX_FOCAL_PX
            ));
        }
        let (w, h) = (f64::from(width), f64::from(height));
        if !((-w..=2.0 * w).contains(&cx) && (-h..=2.0 * h).contains(&cy)) {
            return Err(format!(
                "principal point {}, {} px is not near a {width} x {height} frame",
                Shown(cx),
                Shown(cy)
            ));
        }
        Ok(())
    }

    /// Pixel of a point in the camera's optical frame; `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<Point2<f64>> {
        if p.z <= 1e-9 {
            return None;
        }
        let (x, y) = self.distortion.distort(p.x / p.z, p.y / p.z);
        Some(Point2::new(self.fx * x + self.cx, self.fy * y + self.cy))
    }

    /// Unit ray in the optical frame through a pixel, distortion undone.
    pub fn ray(&self, pixel: &Point2<f64>) -> Vector3<f64> {
        let xd = (pixel.x - self.cx) / self.fx;
        let yd = (pixel.y - self.cy) / self.fy;
        let (x, y) = self.distortion.undistort(xd, yd);
        Vector3::new(x, y, 1.0).normalize()
    }

    /// Whether a pixel lies inside the image.
    pub fn contains(&self, pixel: &Point2<f64>) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x < f64::from(self.width)
            && pixel.y < f64::from(self.height)
    }
}

/// One camera of the flight: its image stream, intrinsics and mounting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// The recording whose images it took (its place in `ingest.json`'s
    /// `recordings`): each drone of a team, or each sortie, has its own.
    #[serde(default)]
    pub recording: u16,
    /// Image topic.
    pub topic: String,
    /// Optical frame of the images (`header.frame_id`).
    pub frame_id: String,
    pub intrinsics: Option<Intrinsics>,
    /// Where the intrinsics came from: a CameraInfo topic or a calibration file.
    pub intrinsics_source: Option<String>,
    /// Pose of the camera's optical frame in the body frame (`T_body_camera`).
    #[serde(with = "crate::serde_pose::option")]
    pub extrinsic: Option<Isometry3<f64>>,
    /// Body frame the extrinsic is expressed in.
    pub body_frame: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intrinsics(distortion: Distortion) -> Intrinsics {
        Intrinsics {
            width: 1280,
            height: 960,
            fx: 900.0,
            fy: 905.0,
            cx: 640.5,
            cy: 480.5,
            distortion,
        }
    }

    #[test]
    fn project_then_ray_round_trips_for_every_model() {
        for d in [
            Distortion::None,
            Distortion::PlumbBob([-0.28, 0.07, 0.001, -0.0005, 0.0]),
            Distortion::RationalPolynomial([0.1, -0.05, 0.001, 0.002, 0.01, 0.05, -0.01, 0.002]),
            Distortion::Equidistant([-0.01, 0.02, -0.005, 0.001]),
        ] {
            let cam = intrinsics(d.clone());
            for p in [
                Vector3::new(0.0, 0.0, 5.0),
                Vector3::new(1.5, -1.0, 4.0),
                Vector3::new(-2.0, 1.4, 3.0),
            ] {
                let px = cam.project(&p).unwrap();
                let r = cam.ray(&px);
                assert!(
                    (r - p.normalize()).norm() < 1e-9,
                    "{d:?}: {r} vs {}",
                    p.normalize()
                );
            }
        }
    }

    #[test]
    fn parses_ros_distortion_names() {
        assert_eq!(
            Distortion::from_ros("plumb_bob", &[0.0; 5]).unwrap(),
            Distortion::None
        );
        assert!(matches!(
            Distortion::from_ros("equidistant", &[0.1, 0.2, 0.3, 0.4]).unwrap(),
            Distortion::Equidistant(_)
        ));
        assert!(Distortion::from_ros("equidistant", &[0.1]).is_err());
        assert!(Distortion::from_ros("mystery", &[0.1]).is_err());
    }
}

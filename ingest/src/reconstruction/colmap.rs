//! COLMAP sparse models, as COLMAP and pycolmap write them: `cameras`,
//! `images` and `points3D`, each `.bin` or `.txt` (the binary where both
//! are). An image's pose is `cam_from_world` (a point `X` of the model is
//! at `R X + t` in the camera, axes as OpenCV's); pixel centres are at
//! half-integers, where ROS and OpenCV put them at integers.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use postflight_core::{Distortion, Intrinsics};

use super::{Format, Reconstruction, RegisteredImage, file_name};

/// A camera model by COLMAP's name, its id in binary models, and its
/// parameter count.
const MODELS: [(&str, i32, usize); 12] = [
    ("SIMPLE_PINHOLE", 0, 3),
    ("PINHOLE", 1, 4),
    ("SIMPLE_RADIAL", 2, 4),
    ("RADIAL", 3, 5),
    ("OPENCV", 4, 8),
    ("OPENCV_FISHEYE", 5, 8),
    ("FULL_OPENCV", 6, 12),
    ("FOV", 7, 5),
    ("SIMPLE_RADIAL_FISHEYE", 8, 4),
    ("RADIAL_FISHEYE", 9, 5),
    ("THIN_PRISM_FISHEYE", 10, 12),
    ("RAD_TAN_THIN_PRISM_FISHEYE", 11, 16),
];

pub(super) fn read(dir: &Path) -> Result<Reconstruction, String> {
    let binary = dir.join("images.bin").is_file();
    let file = |stem: &str| {
        let path = dir.join(format!("{stem}.{}", if binary { "bin" } else { "txt" }));
        postflight_core::user_file::read(&path).map_err(|e| {
            format!(
                "it is not a COLMAP model: {} ({e}); give the folder holding cameras, images and points3D (.bin or .txt)",
                path.display()
            )
        })
    };
    let (cameras, images, points) = (file("cameras")?, file("images")?, file("points3D")?);
    let (cameras, images, points) = match binary {
        true => (
            binary::cameras(&cameras)?,
            binary::images(&images)?,
            binary::points(&points)?,
        ),
        false => (
            text::cameras(&text("cameras.txt", &cameras)?)?,
            text::images(&text("images.txt", &images)?)?,
            text::points(&text("points3D.txt", &points)?)?,
        ),
    };
    let mut registered = BTreeMap::new();
    for (name, camera_id, pose) in images {
        let lens = cameras
            .get(&camera_id)
            .ok_or_else(|| {
                format!("image {name} names camera {camera_id}, which it does not list")
            })?
            .clone();
        registered.insert(file_name(&name), RegisteredImage { lens, pose });
    }
    Ok(Reconstruction {
        path: dir.to_owned(),
        format: Format::Colmap,
        images: registered,
        points,
        reference: None,
    })
}

fn text(name: &str, bytes: &[u8]) -> Result<String, String> {
    String::from_utf8(bytes.to_vec()).map_err(|e| format!("its {name} is not UTF-8 text ({e})"))
}

/// A camera as postflight models it: OpenCV's distortion models, the
/// principal point moved half a pixel to ROS's pixel centres.
fn intrinsics(model: &str, width: u64, height: u64, p: &[f64]) -> Result<Intrinsics, String> {
    if let Some((_, _, count)) = MODELS.iter().find(|m| m.0 == model)
        && *count != p.len()
    {
        return Err(format!(
            "its camera model {model} has {} parameters; COLMAP's {model} has {count}",
            p.len()
        ));
    }
    let size = |v: u64| u32::try_from(v).map_err(|_| format!("a camera {width} x {height} pixels"));
    let (width, height) = (size(width)?, size(height)?);
    let pinhole = |fx: f64, fy: f64, cx: f64, cy: f64, distortion| Intrinsics {
        width,
        height,
        fx,
        fy,
        cx: cx - 0.5,
        cy: cy - 0.5,
        distortion,
    };
    let radial = |k: [f64; 5]| Distortion::from_ros("plumb_bob", &k);
    let lens = match (model, p) {
        ("SIMPLE_PINHOLE", [f, cx, cy]) => pinhole(*f, *f, *cx, *cy, Distortion::None),
        ("PINHOLE", [fx, fy, cx, cy]) => pinhole(*fx, *fy, *cx, *cy, Distortion::None),
        ("SIMPLE_RADIAL", [f, cx, cy, k]) => {
            pinhole(*f, *f, *cx, *cy, radial([*k, 0.0, 0.0, 0.0, 0.0])?)
        }
        ("RADIAL", [f, cx, cy, k1, k2]) => {
            pinhole(*f, *f, *cx, *cy, radial([*k1, *k2, 0.0, 0.0, 0.0])?)
        }
        ("OPENCV", [fx, fy, cx, cy, k1, k2, p1, p2]) => {
            pinhole(*fx, *fy, *cx, *cy, radial([*k1, *k2, *p1, *p2, 0.0])?)
        }
        ("FULL_OPENCV", [fx, fy, cx, cy, d @ ..]) => pinhole(
            *fx,
            *fy,
            *cx,
            *cy,
            Distortion::from_ros("rational_polynomial", d)?,
        ),
        ("OPENCV_FISHEYE", [fx, fy, cx, cy, d @ ..]) => {
            pinhole(*fx, *fy, *cx, *cy, Distortion::from_ros("equidistant", d)?)
        }
        (other, _) => {
            return Err(format!(
                "its camera model {other} is not one postflight projects with (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE); refine with one of those"
            ));
        }
    };
    lens.check()
        .map_err(|e| format!("a camera's lens is not one: {e}"))?;
    Ok(lens)
}

/// `T_model_camera` from COLMAP's `cam_from_world`.
fn pose(q: [f64; 4], t: [f64; 3]) -> Result<Isometry3<f64>, String> {
    let [w, x, y, z] = q;
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if !(norm.is_finite() && norm > 0.5) || t.iter().any(|v| !v.is_finite()) {
        return Err("an image's pose is not a rotation and translation".into());
    }
    let cam_from_world = Isometry3::from_parts(
        Translation3::from(Vector3::from(t)),
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
    );
    Ok(cam_from_world.inverse())
}

mod text {
    use super::*;

    /// The lines that hold data (not comments, not empty).
    fn lines(text: &str) -> impl Iterator<Item = &str> {
        text.lines()
            .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
    }

    fn numbers(fields: &[&str]) -> Result<Vec<f64>, String> {
        fields
            .iter()
            .map(|f| {
                f.parse::<f64>()
                    .map_err(|_| format!("{f:?} is not a number"))
            })
            .collect()
    }

    pub(super) fn cameras(text: &str) -> Result<HashMap<u64, Intrinsics>, String> {
        lines(text)
            .map(|line| {
                let f: Vec<&str> = line.split_whitespace().collect();
                let [id, model, width, height, params @ ..] = &f[..] else {
                    return Err(format!("cameras.txt line {line:?} is short"));
                };
                let parse = |v: &str| {
                    v.parse::<u64>()
                        .map_err(|_| format!("cameras.txt: {v:?} is not a number"))
                };
                let k = intrinsics(model, parse(width)?, parse(height)?, &numbers(params)?)?;
                Ok((parse(id)?, k))
            })
            .collect()
    }

    pub(super) fn images(text: &str) -> Result<Vec<(String, u64, Isometry3<f64>)>, String> {
        // Two lines per image; the second (its 2-D points) may be empty.
        let data: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        let mut images = Vec::new();
        for line in data.iter().step_by(2).filter(|l| !l.trim().is_empty()) {
            let f: Vec<&str> = line.split_whitespace().collect();
            let [_, qw, qx, qy, qz, tx, ty, tz, camera, name @ ..] = &f[..] else {
                return Err(format!("images.txt line {line:?} is short"));
            };
            let v = numbers(&[qw, qx, qy, qz, tx, ty, tz])?;
            let camera = camera
                .parse()
                .map_err(|_| format!("images.txt: camera {camera:?} is not a number"))?;
            let pose = pose([v[0], v[1], v[2], v[3]], [v[4], v[5], v[6]])?;
            images.push((name.join(" "), camera, pose));
        }
        Ok(images)
    }

    pub(super) fn points(text: &str) -> Result<Vec<Point3<f64>>, String> {
        lines(text)
            .map(|line| {
                let f: Vec<&str> = line.split_whitespace().collect();
                let v = numbers(f.get(1..4).ok_or("points3D.txt line is short")?)?;
                Ok(Point3::new(v[0], v[1], v[2]))
            })
            .collect()
    }
}

mod binary {
    use super::*;

    /// A little-endian reader over a model file.
    struct Bytes<'a> {
        bytes: &'a [u8],
        at: usize,
        file: &'static str,
    }

    impl<'a> Bytes<'a> {
        fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
            let out = self
                .bytes
                .get(self.at..self.at + n)
                .ok_or_else(|| format!("{} ends early, at byte {}", self.file, self.at))?;
            self.at += n;
            Ok(out)
        }
        fn u64(&mut self) -> Result<u64, String> {
            Ok(u64::from_le_bytes(
                self.take(8)?.try_into().expect("8 bytes"),
            ))
        }
        fn u32(&mut self) -> Result<u32, String> {
            Ok(u32::from_le_bytes(
                self.take(4)?.try_into().expect("4 bytes"),
            ))
        }
        fn f64(&mut self) -> Result<f64, String> {
            Ok(f64::from_le_bytes(
                self.take(8)?.try_into().expect("8 bytes"),
            ))
        }
        /// A count of things at least `size` bytes each, checked against
        /// what is left (a damaged count would ask for terabytes).
        fn count(&mut self, size: usize) -> Result<usize, String> {
            let n = self.u64()? as usize;
            if n.saturating_mul(size) > self.bytes.len() - self.at {
                return Err(format!("{} is damaged: it counts {n} entries", self.file));
            }
            Ok(n)
        }
    }

    pub(super) fn cameras(bytes: &[u8]) -> Result<HashMap<u64, Intrinsics>, String> {
        let mut b = Bytes {
            bytes,
            at: 0,
            file: "cameras.bin",
        };
        let n = b.count(24)?;
        (0..n)
            .map(|_| {
                let id = u64::from(b.u32()?);
                let model_id = b.u32()? as i32;
                let (width, height) = (b.u64()?, b.u64()?);
                let (name, _, count) = MODELS
                    .iter()
                    .find(|m| m.1 == model_id)
                    .ok_or_else(|| format!("cameras.bin: unknown camera model {model_id}"))?;
                let params = (0..*count)
                    .map(|_| b.f64())
                    .collect::<Result<Vec<_>, _>>()?;
                Ok((id, intrinsics(name, width, height, &params)?))
            })
            .collect()
    }

    pub(super) fn images(bytes: &[u8]) -> Result<Vec<(String, u64, Isometry3<f64>)>, String> {
        let mut b = Bytes {
            bytes,
            at: 0,
            file: "images.bin",
        };
        let n = b.count(64)?;
        (0..n)
            .map(|_| {
                let _id = b.u32()?;
                let q = [b.f64()?, b.f64()?, b.f64()?, b.f64()?];
                let t = [b.f64()?, b.f64()?, b.f64()?];
                let camera = u64::from(b.u32()?);
                let end = b.bytes[b.at..]
                    .iter()
                    .position(|c| *c == 0)
                    .ok_or("images.bin ends inside an image's name")?;
                let name = String::from_utf8_lossy(b.take(end)?).into_owned();
                b.take(1)?;
                let points = b.count(24)?;
                b.take(points * 24)?;
                Ok((name, camera, pose(q, t)?))
            })
            .collect()
    }

    pub(super) fn points(bytes: &[u8]) -> Result<Vec<Point3<f64>>, String> {
        let mut b = Bytes {
            bytes,
            at: 0,
            file: "points3D.bin",
        };
        let n = b.count(43)?;
        (0..n)
            .map(|_| {
                b.u64()?;
                let p = Point3::new(b.f64()?, b.f64()?, b.f64()?);
                b.take(3)?;
                b.f64()?;
                let track = b.count(8)?;
                b.take(track * 8)?;
                Ok(p)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_file_that_is_not_text_is_named() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("cameras.txt"),
            "1 PINHOLE 640 480 500 500 320 240\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("images.txt"),
            b"1 1 0 0 0 0 0 0 1 \xff\xfe.jpg\n\n",
        )
        .unwrap();
        std::fs::write(dir.path().join("points3D.txt"), "").unwrap();
        let err = read(dir.path()).err().unwrap();
        assert!(err.contains("its images.txt is not UTF-8 text"), "{err}");
    }
}

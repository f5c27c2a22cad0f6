//! OpenSfM's `reconstruction.json`, as OpenDroneMap and WebODM leave it in
//! `opensfm/`: a list of reconstructions, each with its cameras
//! (normalised by the image's larger side), its shots (`rotation` as an
//! axis-angle vector and `translation`: a point `X` is at `R X + t` in the
//! camera, axes as OpenCV's), its points, and `reference_lla`, the
//! east-north-up frame its coordinates are in (else in
//! `reference_lla.json` beside it).

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use postflight_core::geo::Geodetic;
use postflight_core::{Distortion, Intrinsics};
use serde::Deserialize;

use super::{Format, Reconstruction, RegisteredImage, file_name};

#[derive(Deserialize)]
struct Part {
    #[serde(default)]
    cameras: BTreeMap<String, Camera>,
    #[serde(default)]
    shots: BTreeMap<String, Shot>,
    #[serde(default)]
    points: BTreeMap<String, PointRecord>,
    reference_lla: Option<Lla>,
}

#[derive(Deserialize)]
struct Camera {
    projection_type: String,
    width: f64,
    height: f64,
    focal: Option<f64>,
    focal_x: Option<f64>,
    focal_y: Option<f64>,
    #[serde(default)]
    c_x: f64,
    #[serde(default)]
    c_y: f64,
    #[serde(default)]
    k1: f64,
    #[serde(default)]
    k2: f64,
    #[serde(default)]
    k3: f64,
    #[serde(default)]
    p1: f64,
    #[serde(default)]
    p2: f64,
}

#[derive(Deserialize)]
struct Shot {
    rotation: [f64; 3],
    translation: [f64; 3],
    camera: String,
}

#[derive(Deserialize)]
struct PointRecord {
    coordinates: [f64; 3],
}

#[derive(Deserialize, Clone, Copy)]
struct Lla {
    latitude: f64,
    longitude: f64,
    altitude: f64,
}

pub(super) fn read(path: &Path) -> Result<Reconstruction, String> {
    let text = postflight_core::user_file::read_to_string(path)
        .map_err(|e| format!("{e}; check the path"))?;
    let parts: Vec<Part> = serde_json::from_str(&text)
        .map_err(|e| format!("it is not an OpenSfM reconstruction.json ({e})"))?;
    let beside = path.with_file_name("reference_lla.json");
    let reference_file: Option<Lla> = std::fs::read_to_string(&beside)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    // Parts in one reference frame are one reconstruction; parts in frames
    // of their own cannot be put together: the largest is taken.
    let georeferenced = reference_file.is_some() || parts.iter().all(|p| p.reference_lla.is_some());
    let mut parts = parts;
    if !georeferenced {
        parts.sort_by_key(|p| std::cmp::Reverse(p.shots.len()));
        parts.truncate(1);
    }
    let reference = parts
        .first()
        .and_then(|p| p.reference_lla)
        .or(reference_file)
        .filter(|_| georeferenced)
        .map(|r| Geodetic {
            latitude_deg: r.latitude,
            longitude_deg: r.longitude,
            altitude_m: r.altitude,
        });
    if let Some(at) = &reference {
        at.check()
            .map_err(|e| format!("its reference_lla is not a place on the Earth: {e}"))?;
    }
    let mut images = BTreeMap::new();
    let mut points = Vec::new();
    for part in &parts {
        for (name, shot) in &part.shots {
            let camera = part.cameras.get(&shot.camera).ok_or_else(|| {
                format!(
                    "shot {name} names camera {:?}, which it does not list",
                    shot.camera
                )
            })?;
            let lens = intrinsics(camera)?;
            if !shot
                .translation
                .iter()
                .chain(&shot.rotation)
                .all(|v| v.is_finite())
            {
                return Err(format!(
                    "shot {name}'s pose is not a rotation and translation"
                ));
            }
            let cam_from_world = Isometry3::from_parts(
                Translation3::from(Vector3::from(shot.translation)),
                UnitQuaternion::from_scaled_axis(Vector3::from(shot.rotation)),
            );
            let pose = cam_from_world.inverse();
            images.insert(file_name(name), RegisteredImage { lens, pose });
        }
        points.extend(part.points.values().map(|p| Point3::from(p.coordinates)));
    }
    Ok(Reconstruction {
        path: path.to_owned(),
        format: Format::OpenSfm,
        images,
        points,
        reference,
    })
}

/// OpenSfM's normalised camera in pixels, ROS's pixel centres.
fn intrinsics(c: &Camera) -> Result<Intrinsics, String> {
    let size = c.width.max(c.height);
    let focal = c
        .focal
        .or(c.focal_x)
        .ok_or("a camera has no focal length")?;
    let (fx, fy) = (focal * size, c.focal_y.unwrap_or(focal) * size);
    let distortion = match c.projection_type.as_str() {
        "perspective" => Distortion::from_ros("plumb_bob", &[c.k1, c.k2, 0.0, 0.0, 0.0])?,
        "brown" => Distortion::from_ros("plumb_bob", &[c.k1, c.k2, c.p1, c.p2, c.k3])?,
        "fisheye" => Distortion::from_ros("equidistant", &[c.k1, c.k2, 0.0, 0.0])?,
        other => {
            return Err(format!(
                "its camera projection {other:?} is not one postflight projects with (perspective, brown, fisheye)"
            ));
        }
    };
    let pixels = |v: f64| {
        (v >= 1.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0)
            .then_some(v as u32)
            .ok_or_else(|| format!("a camera {} x {} pixels", c.width, c.height))
    };
    let lens = Intrinsics {
        width: pixels(c.width)?,
        height: pixels(c.height)?,
        fx,
        fy,
        cx: c.c_x * size + c.width / 2.0 - 0.5,
        cy: c.c_y * size + c.height / 2.0 - 0.5,
        distortion,
    };
    lens.check()
        .map_err(|e| format!("a camera's lens is not one: {e}"))?;
    Ok(lens)
}

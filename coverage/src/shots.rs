//! The shots coverage judges: the flight's frames with a pose (each with
//! its motion blur), or a plan's viewpoints as shots of the flight's first
//! camera; and where a viewpoint puts that camera, which replan shares.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use postflight_core::map::SlamMap;
use postflight_core::motion::frame_blur_px;
use postflight_core::{Flight, FlownPlan, Intrinsics, Viewpoint};

use crate::cover::Shot;
use crate::error::CoverageError;
use crate::settings::keys;

/// How far down the camera mounted by `extrinsic` looks, radians.
pub fn mount_pitch(extrinsic: &Isometry3<f64>) -> f64 {
    let axis = extrinsic.rotation * Vector3::z();
    (-axis.z).clamp(-1.0, 1.0).asin()
}

/// Camera pose for a plan viewpoint: the body at the viewpoint, the camera
/// mounted by `extrinsic` turned where it is mounted, about the body's y
/// axis, to the viewpoint's gimbal pitch.
pub fn viewpoint_camera(v: &Viewpoint, extrinsic: &Isometry3<f64>) -> Isometry3<f64> {
    let body = Isometry3::from_parts(
        Translation3::from(Vector3::from(v.position)),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), v.yaw),
    );
    let tilt = UnitQuaternion::from_axis_angle(
        &Vector3::y_axis(),
        v.gimbal_pitch - mount_pitch(extrinsic),
    );
    body * Isometry3::from_parts(extrinsic.translation, tilt * extrinsic.rotation)
}

/// How the flight's first camera is mounted on the body (plan viewpoints
/// are shots of it). Without a recorded mounting, a camera at the body
/// origin looking forward (optical z along body x, y down).
pub fn camera_mount(flight: &Flight) -> Isometry3<f64> {
    flight
        .cameras
        .first()
        .and_then(|c| c.extrinsic)
        .unwrap_or_else(|| {
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, 0.5, -0.5)),
            )
        })
}

/// The flight's lenses, one per camera (in cameras.json's order).
pub fn lenses(flight: &Flight) -> Result<Vec<Intrinsics>, CoverageError> {
    if flight.cameras.is_empty() {
        return Err(CoverageError::NoCamera);
    }
    flight
        .cameras
        .iter()
        .map(|c| c.intrinsics.clone())
        .collect::<Option<Vec<_>>>()
        .ok_or(CoverageError::NoIntrinsics)
}

/// A plan's viewpoints as shots of the flight's first camera (sharp: a
/// plan is flown hovering).
pub(crate) fn viewpoint_shots(plan: &FlownPlan, extrinsic: &Isometry3<f64>) -> Vec<Shot> {
    plan.viewpoints(mount_pitch(extrinsic))
        .iter()
        .enumerate()
        .map(|(i, v)| Shot {
            id: i as u32,
            camera: viewpoint_camera(v, extrinsic),
            lens: 0,
            blur_px: Some(0.0),
        })
        .collect()
}

/// The flight's frames as shots, and the frames that could not be.
pub struct FlightShots {
    pub shots: Vec<Shot>,
    /// Frames without a camera pose (or of a camera not in cameras.json).
    pub without_pose: usize,
    /// Frames whose blur cannot be judged: no exposure time recorded or given.
    pub without_exposure: usize,
}

impl FlightShots {
    /// What the summary warns of frames that count for less.
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        if self.without_pose > 0 {
            warnings.push(format!(
                "{} frames have no pose and count for nothing (ingest.json says why)",
                self.without_pose
            ));
        }
        if self.without_exposure > 0 {
            warnings.push(format!(
                "{} frames recorded no exposure time, so their blur was not judged; pass {} SECONDS",
                self.without_exposure,
                keys::exposure_s
            ));
        }
        warnings
    }
}

/// Every frame with a pose, with its motion blur (`exposure_s` for frames
/// that recorded none); their lenses are [`lenses`]'s.
pub fn flight_shots(
    flight: &Flight,
    lenses: &[Intrinsics],
    map: &SlamMap,
    exposure_s: Option<f64>,
) -> FlightShots {
    let mut out = FlightShots {
        shots: Vec::new(),
        without_pose: 0,
        without_exposure: 0,
    };
    for frame in &flight.frames {
        let (Some(camera), Some(lens)) = (
            frame.camera_pose,
            flight
                .cameras
                .iter()
                .position(|c| c.recording == frame.recording && c.topic == frame.topic),
        ) else {
            out.without_pose += 1;
            continue;
        };
        let exposure = frame.exposure_s.or(exposure_s);
        if exposure.is_none() {
            out.without_exposure += 1;
        }
        let blur =
            exposure.and_then(|e| frame_blur_px(flight, frame, &lenses[lens], e, &map.voxels));
        out.shots.push(Shot {
            id: frame.index,
            camera,
            lens,
            blur_px: blur,
        });
    }
    out
}

//! `flight.rrd`: the run as a Rerun recording, for the 3D viewer (`rerun
//! flight.rrd`). World frame z up, metres. Static: the map points, the target
//! voxels by coverage status, the trajectory, the defect candidates and the
//! follow-up flight. On the `time` timeline (and `frame`), each camera's pose,
//! pinhole and image with the detector's boxes.

use std::collections::BTreeMap;
use std::path::Path;

use ingest::map::PointCloud;
use nalgebra::Isometry3;

use crate::error::ReportError;
use crate::results::{RunResults, VoxelStatus};
use crate::views::colour;

/// Most map points logged; larger maps are thinned evenly.
const MAX_MAP_POINTS: usize = 2_000_000;

/// Write the recording of `results` to `path`; `progress(done, total)` over frames.
pub fn write_recording(
    results: &RunResults,
    path: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(), ReportError> {
    let rerun_error = |e: &dyn std::fmt::Display| ReportError::Recording {
        path: path.to_owned(),
        why: e.to_string(),
    };
    let flight = &results.flight;
    let rec = rerun::RecordingStreamBuilder::new("postflight")
        .save(path)
        .map_err(|e| rerun_error(&e))?;
    let log = |entity: &str, what: &dyn rerun::AsComponents| {
        rec.log_static(entity, what).map_err(|e| rerun_error(&e))
    };
    log("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;

    if let Some(cloud) = map_cloud(results, flight)? {
        let step = cloud.points.len().div_ceil(MAX_MAP_POINTS).max(1);
        let points: Vec<[f32; 3]> = cloud
            .points
            .iter()
            .step_by(step)
            .map(|p| f32x3(p.coords.into()))
            .collect();
        log(
            "world/map",
            &rerun::Points3D::new(points)
                .with_colors([rerun::Color::from_rgb(150, 150, 150)])
                .with_radii([rerun::Radius::new_ui_points(1.0)]),
        )?;
    }

    let resolution = results.coverage.as_ref().map_or(0.5, |c| c.resolution_m);
    for status in VoxelStatus::ALL {
        let centres: Vec<[f32; 3]> = results
            .voxels
            .iter()
            .filter(|v| v.status == status)
            .map(|v| f32x3(v.centre))
            .collect();
        if centres.is_empty() {
            continue;
        }
        let half = (resolution / 2.0 * 0.95) as f32;
        log(
            &format!("world/coverage/{}", status.key()),
            &rerun::Boxes3D::from_centers_and_half_sizes(
                centres.clone(),
                vec![[half; 3]; centres.len()],
            )
            .with_colors([rgb(colour(status))])
            .with_fill_mode(rerun::FillMode::Solid),
        )?;
    }

    let trajectory: Vec<[f32; 3]> = flight
        .trajectory
        .poses()
        .iter()
        .map(|p| f32x3(p.pose.translation.vector.into()))
        .collect();
    if trajectory.len() > 1 {
        log(
            "world/trajectory",
            &rerun::LineStrips3D::new([trajectory])
                .with_colors([rerun::Color::from_rgb(240, 240, 240)]),
        )?;
    }

    let review = results.defects_for_review();
    if !review.is_empty() {
        log(
            "world/defects",
            &rerun::Points3D::new(review.iter().map(|d| f32x3(d.position)))
                .with_radii([0.12])
                .with_colors([rerun::Color::from_rgb(17, 24, 39)])
                .with_labels(review.iter().enumerate().map(|(i, d)| {
                    let length = d.length_m.map_or(String::new(), |l| format!(", {l:.2} m"));
                    format!("#{} {}{length}", i + 1, d.id)
                })),
        )?;
    }

    if let Some(plan) = &results.replan {
        let strips: Vec<Vec<[f32; 3]>> = plan
            .sorties
            .iter()
            .map(|s| s.path.iter().map(|p| f32x3(*p)).collect())
            .collect();
        let waypoints: Vec<[f32; 3]> = plan
            .sorties
            .iter()
            .flat_map(|s| s.waypoints.iter().map(|w| f32x3([w.x, w.y, w.z])))
            .collect();
        if !strips.is_empty() {
            log(
                "world/replan/path",
                &rerun::LineStrips3D::new(strips).with_colors([rgb("#1f4fd1")]),
            )?;
            log(
                "world/replan/waypoints",
                &rerun::Points3D::new(waypoints)
                    .with_colors([rgb("#1f4fd1")])
                    .with_radii([0.08]),
            )?;
            log(
                "world/replan/home",
                &rerun::Points3D::new([f32x3(plan.home)])
                    .with_radii([0.25])
                    .with_labels(["home"]),
            )?;
        }
    }

    // Detections by frame index.
    let mut boxes: BTreeMap<u32, Vec<detect::FrameDetection>> = BTreeMap::new();
    if results.detect.is_some() {
        for d in detect::read_detections(results.dir().path()).map_err(|e| rerun_error(&e))? {
            boxes.entry(d.frame).or_default().push(d);
        }
    }
    let classes = results
        .detect
        .as_ref()
        .map(|d| d.classes.clone())
        .unwrap_or_default();
    let total = flight.frames.len() as u64;
    for (done, frame) in flight.frames.iter().enumerate() {
        progress(done as u64, total);
        let (Some(pose), Some(camera)) = (frame.camera_pose, flight.camera(frame)) else {
            continue;
        };
        let entity = format!("world/cameras/{}", entity_name(&camera.topic));
        let image_entity = format!("{entity}/image");
        rec.set_timestamp_nanos_since_epoch("time", frame.time_ns);
        rec.set_time_sequence("frame", i64::from(frame.index));
        let timed = |path: &str, what: &dyn rerun::AsComponents| {
            rec.log(path, what).map_err(|e| rerun_error(&e))
        };
        timed(&entity, &transform(&pose))?;
        if let Some(k) = &camera.intrinsics {
            timed(
                &image_entity,
                &rerun::Pinhole::from_focal_length_and_resolution(
                    [k.fx as f32, k.fy as f32],
                    [k.width as f32, k.height as f32],
                )
                .with_principal_point([k.cx as f32, k.cy as f32])
                .with_image_plane_distance(1.0),
            )?;
        }
        match flight.compressed_image(frame) {
            Ok(Some(bytes)) => {
                let media = if frame.encoding == "png" {
                    rerun::MediaType::png()
                } else {
                    rerun::MediaType::jpeg()
                };
                timed(
                    &image_entity,
                    &rerun::EncodedImage::new(bytes).with_media_type(media),
                )?;
            }
            Ok(None) => {
                if let Ok(image) = flight.image(frame) {
                    let rgb = image.to_rgb8();
                    let (w, h) = rgb.dimensions();
                    timed(
                        &image_entity,
                        &rerun::Image::from_rgb24(rgb.into_raw(), [w, h]),
                    )?;
                }
            }
            // An unreadable image is already reported by ingest and detect.
            Err(_) => {}
        }
        let found = boxes
            .get(&frame.index)
            .map(Vec::as_slice)
            .unwrap_or_default();
        timed(
            &format!("{image_entity}/detections"),
            &rerun::Boxes2D::from_mins_and_sizes(
                found
                    .iter()
                    .map(|d| [d.detection.bbox.x0, d.detection.bbox.y0]),
                found.iter().map(|d| {
                    [
                        d.detection.bbox.x1 - d.detection.bbox.x0,
                        d.detection.bbox.y1 - d.detection.bbox.y0,
                    ]
                }),
            )
            .with_labels(found.iter().map(|d| {
                let class = classes
                    .get(d.detection.class as usize)
                    .map_or("crack", String::as_str);
                format!("{class} {:.2}", d.detection.score)
            }))
            .with_colors([rgb("#d7301f")]),
        )?;
    }
    progress(total, total);
    rec.flush_blocking().map_err(|e| rerun_error(&e))?;
    drop(rec);
    Ok(())
}

/// The map coverage judged against: its file, else the one in the flight.
fn map_cloud(
    results: &RunResults,
    flight: &ingest::Flight,
) -> Result<Option<PointCloud>, ReportError> {
    if let Some(path) = results.coverage.as_ref().and_then(|c| c.map.as_ref()) {
        return Ok(Some(PointCloud::load(path)?));
    }
    Ok(flight.recorded_map()?)
}

fn transform(pose: &Isometry3<f64>) -> rerun::Transform3D {
    let t = pose.translation.vector;
    let q = pose.rotation.into_inner().coords; // [x, y, z, w]
    rerun::Transform3D::from_translation_rotation(
        [t.x as f32, t.y as f32, t.z as f32],
        rerun::Quaternion::from_xyzw([q.x as f32, q.y as f32, q.z as f32, q.w as f32]),
    )
}

fn f32x3(p: [f64; 3]) -> [f32; 3] {
    p.map(|c| c as f32)
}

/// `#rrggbb` as a Rerun colour.
fn rgb(hex: &str) -> rerun::Color {
    let v = u32::from_str_radix(hex.trim_start_matches('#'), 16).unwrap_or(0);
    rerun::Color::from_rgb((v >> 16) as u8, (v >> 8) as u8, v as u8)
}

/// A topic as an entity path part: `/camera/image_raw` -> `camera_image_raw`.
fn entity_name(topic: &str) -> String {
    let name: String = topic
        .trim_start_matches('/')
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if name.is_empty() {
        "camera".into()
    } else {
        name
    }
}

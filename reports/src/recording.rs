//! `flight.rrd`: the run as a Rerun recording, for the 3D viewer (`rerun
//! flight.rrd`). World frame z up, metres. Static: the map points, the target
//! voxels by coverage status, the trajectory, the defect candidates with
//! their traces (coloured by condition state) and the follow-up flight. On
//! the `time` timeline (and `frame`), each camera's pose, pinhole and image
//! with the detector's boxes and, from a segmenting model, its crack pixels.

use std::collections::BTreeMap;
use std::path::Path;

use ingest::Recordings;
use nalgebra::Isometry3;
use page::state_text;
use postflight_core::detection::FrameDetection;
use postflight_core::frame::{Compression, ImageEncoding};
use postflight_core::mask::Mask;
use postflight_core::outputs::detect::read_detections;
use postflight_core::{Camera, Flight, Frame};

use crate::error::ReportError;
use crate::results::{RunResults, VoxelStatus};
use crate::views::{colour, state_colour};

/// The class of crack pixels in the frames' segmentation images.
const CRACK_CLASS: u16 = 1;
/// Most map points logged; larger maps are thinned evenly.
const MAX_MAP_POINTS: usize = 2_000_000;

/// Write the recording of `results` to `path`; `progress(done, total)` over frames.
pub fn write_recording(
    results: &RunResults,
    path: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(), ReportError> {
    let rec = rerun::RecordingStreamBuilder::new("postflight")
        .save(path)
        .map_err(|e| rerun_error(path, &e))?;
    let out = Out { rec: &rec, path };
    out.log("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())?;
    out.log(
        "world",
        &rerun::AnnotationContext::new([(
            CRACK_CLASS,
            "crack",
            rerun::Rgba32::from_rgb(215, 48, 31),
        )]),
    )?;
    log_map(&out, results)?;
    log_coverage(&out, results)?;
    log_trajectory(&out, results)?;
    log_defects(&out, results)?;
    log_follow_up(&out, results)?;
    log_frames(&out, results, progress)?;
    rec.flush_blocking().map_err(|e| rerun_error(path, &e))?;
    drop(rec);
    Ok(())
}

/// The recording being written, and where (for errors).
struct Out<'a> {
    rec: &'a rerun::RecordingStream,
    path: &'a Path,
}

impl Out<'_> {
    /// Log for the whole recording.
    fn log(&self, entity: &str, what: &dyn rerun::AsComponents) -> Result<(), ReportError> {
        self.rec
            .log_static(entity, what)
            .map_err(|e| rerun_error(self.path, &e))
    }

    /// Log at the current time.
    fn log_now(&self, entity: &str, what: &dyn rerun::AsComponents) -> Result<(), ReportError> {
        self.rec
            .log(entity, what)
            .map_err(|e| rerun_error(self.path, &e))
    }
}

fn rerun_error(path: &Path, e: &dyn std::fmt::Display) -> ReportError {
    ReportError::Recording {
        path: path.to_owned(),
        why: e.to_string(),
    }
}

/// The map coverage judged against (its file, else the one in the flight),
/// thinned to [`MAX_MAP_POINTS`].
fn log_map(out: &Out, results: &RunResults) -> Result<(), ReportError> {
    let given = results.coverage.as_ref().and_then(|c| c.map.as_deref());
    let Some((cloud, _)) = ingest::map_cloud(&results.flight, given)? else {
        return Ok(());
    };
    let step = cloud.points.len().div_ceil(MAX_MAP_POINTS).max(1);
    let points: Vec<[f32; 3]> = cloud
        .points
        .iter()
        .step_by(step)
        .map(|p| f32x3(p.coords.into()))
        .collect();
    out.log(
        "world/map",
        &rerun::Points3D::new(points)
            .with_colors([rerun::Color::from_rgb(150, 150, 150)])
            .with_radii([rerun::Radius::new_ui_points(1.0)]),
    )
}

/// The target voxels, one entity per coverage status.
fn log_coverage(out: &Out, results: &RunResults) -> Result<(), ReportError> {
    let resolution = results
        .coverage
        .as_ref()
        .map_or(0.5, |c| c.figures.resolution_m);
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
        out.log(
            &format!("world/coverage/{}", status.key()),
            &rerun::Boxes3D::from_centers_and_half_sizes(
                centres.clone(),
                vec![[half; 3]; centres.len()],
            )
            .with_colors([rgb(colour(status))])
            .with_fill_mode(rerun::FillMode::Solid),
        )?;
    }
    Ok(())
}

fn log_trajectory(out: &Out, results: &RunResults) -> Result<(), ReportError> {
    // One strip per recording: no line jumps from one sortie or drone to the next.
    let strips: Vec<Vec<[f32; 3]>> = results
        .flight
        .trajectories
        .iter()
        .map(|t| {
            let poses = t.poses().iter();
            poses
                .map(|p| f32x3(p.pose.translation.vector.into()))
                .collect::<Vec<_>>()
        })
        .filter(|strip| strip.len() >= 2)
        .collect();
    if strips.is_empty() {
        return Ok(());
    }
    out.log(
        "world/trajectory",
        &rerun::LineStrips3D::new(strips).with_colors([rerun::Color::from_rgb(240, 240, 240)]),
    )
}

/// The defect candidates, labelled in review order, and their traces
/// coloured by condition state.
fn log_defects(out: &Out, results: &RunResults) -> Result<(), ReportError> {
    let review = results.defects_for_review();
    if review.is_empty() {
        return Ok(());
    }
    out.log(
        "world/defects",
        &rerun::Points3D::new(review.iter().map(|d| f32x3(d.position)))
            .with_radii([0.12])
            .with_colors([rerun::Color::from_rgb(17, 24, 39)])
            .with_labels(review.iter().enumerate().map(|(i, d)| {
                let length = d.length_m.map_or(String::new(), |l| format!(", {l:.2} m"));
                let state = d.condition.map_or(String::new(), |s| {
                    format!(", state {}", state_text(Some(s)))
                });
                format!("#{} {}{length}{state}", i + 1, d.id)
            })),
    )?;
    let lines: Vec<(Vec<[f32; 3]>, rerun::Color)> = review
        .iter()
        .flat_map(|d| {
            let colour = rgb(state_colour(d.state()));
            d.trace
                .0
                .iter()
                .map(move |l| (l.iter().map(|p| f32x3(*p)).collect(), colour))
        })
        .collect();
    if lines.is_empty() {
        return Ok(());
    }
    out.log(
        "world/defects/traces",
        &rerun::LineStrips3D::new(lines.iter().map(|(l, _)| l.clone()))
            .with_colors(lines.iter().map(|(_, c)| *c))
            .with_radii([0.004]),
    )
}

/// The follow-up flight: its paths, waypoints and home.
fn log_follow_up(out: &Out, results: &RunResults) -> Result<(), ReportError> {
    let Some(plan) = &results.replan else {
        return Ok(());
    };
    let strips: Vec<Vec<[f32; 3]>> = plan
        .sorties
        .iter()
        .map(|s| s.path.iter().map(|p| f32x3(*p)).collect())
        .collect();
    if strips.is_empty() {
        return Ok(());
    }
    let waypoints: Vec<[f32; 3]> = plan
        .sorties
        .iter()
        .flat_map(|s| s.waypoints.iter().map(|w| f32x3([w.x, w.y, w.z])))
        .collect();
    out.log(
        "world/replan/path",
        &rerun::LineStrips3D::new(strips).with_colors([rgb("#1f4fd1")]),
    )?;
    out.log(
        "world/replan/waypoints",
        &rerun::Points3D::new(waypoints)
            .with_colors([rgb("#1f4fd1")])
            .with_radii([0.08]),
    )?;
    out.log(
        "world/replan/home",
        &rerun::Points3D::new([f32x3(plan.home)])
            .with_radii([0.25])
            .with_labels(["home"]),
    )
}

/// Every posed frame on the `time` and `frame` timelines: its camera's
/// pose and pinhole, its image, and the detector's boxes.
fn log_frames(
    out: &Out,
    results: &RunResults,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(), ReportError> {
    let flight = &results.flight;
    let mut boxes: BTreeMap<u32, Vec<FrameDetection>> = BTreeMap::new();
    if results.detect.is_some() {
        for d in read_detections(results.dir())? {
            boxes.entry(d.frame).or_default().push(d);
        }
    }
    let classes = results
        .detect
        .as_ref()
        .map(|d| d.classes.clone())
        .unwrap_or_default();
    let recording = Recordings::reopen(flight)?;
    let total = flight.frames.len() as u64;
    for (done, frame) in flight.frames.iter().enumerate() {
        progress(done as u64, total);
        let (Some(pose), Some(camera)) = (frame.camera_pose, flight.camera(frame)) else {
            continue;
        };
        out.rec
            .set_timestamp_nanos_since_epoch("time", frame.time_ns);
        out.rec.set_time_sequence("frame", i64::from(frame.index));
        let entity = camera_entity(flight, camera);
        out.log_now(&entity, &transform(&pose))?;
        let image_entity = format!("{entity}/image");
        log_image(out, &recording, frame, camera, &image_entity)?;
        let found = boxes
            .get(&frame.index)
            .map(Vec::as_slice)
            .unwrap_or_default();
        log_boxes(out, found, &classes, &format!("{image_entity}/detections"))?;
        if let Some(k) = &camera.intrinsics {
            log_masks(
                out,
                found,
                [k.width, k.height],
                &format!("{image_entity}/masks"),
            )?;
        }
    }
    progress(total, total);
    Ok(())
}

/// A frame's pinhole and image (passed on compressed when it was recorded so).
fn log_image(
    out: &Out,
    recording: &Recordings,
    frame: &Frame,
    camera: &Camera,
    entity: &str,
) -> Result<(), ReportError> {
    if let Some(k) = &camera.intrinsics {
        out.log_now(
            entity,
            &rerun::Pinhole::from_focal_length_and_resolution(
                [k.fx as f32, k.fy as f32],
                [k.width as f32, k.height as f32],
            )
            .with_principal_point([k.cx as f32, k.cy as f32])
            .with_image_plane_distance(1.0),
        )?;
    }
    match recording.compressed_image(frame) {
        Ok(Some(bytes)) => {
            let media = if frame.encoding == ImageEncoding::Compressed(Compression::Png) {
                rerun::MediaType::png()
            } else {
                rerun::MediaType::jpeg()
            };
            out.log_now(
                entity,
                &rerun::EncodedImage::new(bytes).with_media_type(media),
            )
        }
        Ok(None) => match recording.image(frame) {
            Ok(image) => {
                let rgb = image.to_rgb8();
                let (w, h) = rgb.dimensions();
                out.log_now(entity, &rerun::Image::from_rgb24(rgb.into_raw(), [w, h]))
            }
            Err(_) => Ok(()),
        },
        // An unreadable image is already reported by ingest and detect.
        Err(_) => Ok(()),
    }
}

/// The crack pixels of a frame's detections (a segmenting model's), as a
/// segmentation image over the frame: class 1, crack.
fn log_masks(
    out: &Out,
    found: &[FrameDetection],
    [width, height]: [u32; 2],
    entity: &str,
) -> Result<(), ReportError> {
    let masks: Vec<&Mask> = found
        .iter()
        .filter_map(|d| d.detection.mask.as_ref())
        .collect();
    if masks.is_empty() {
        return Ok(());
    }
    let mut classes = vec![0u8; width as usize * height as usize];
    for (x, y) in masks.iter().flat_map(|m| m.pixels()) {
        if x < width && y < height {
            classes[y as usize * width as usize + x as usize] = CRACK_CLASS as u8;
        }
    }
    out.log_now(
        entity,
        &rerun::SegmentationImage::new(
            classes,
            rerun::datatypes::ImageFormat::segmentation(
                [width, height],
                rerun::datatypes::ChannelDatatype::U8,
            ),
        )
        .with_opacity(0.5),
    )
}

/// A frame's detections, labelled with class and score.
fn log_boxes(
    out: &Out,
    found: &[FrameDetection],
    classes: &[String],
    entity: &str,
) -> Result<(), ReportError> {
    out.log_now(
        entity,
        &rerun::Boxes2D::from_mins_and_sizes(
            found
                .iter()
                .map(|d| [d.detection.bbox.x0, d.detection.bbox.y0]),
            found
                .iter()
                .map(|d| [d.detection.bbox.width(), d.detection.bbox.height()]),
        )
        .with_labels(found.iter().map(|d| {
            let class = classes
                .get(d.detection.class as usize)
                .map_or("crack", String::as_str);
            format!("{class} {:.2}", d.detection.score)
        }))
        .with_colors([rgb("#d7301f")]),
    )
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

/// A camera's entity: by its topic, under its recording's name when the
/// flight has several (two drones may use the same topic).
fn camera_entity(flight: &Flight, camera: &Camera) -> String {
    let topic = entity_name(&camera.topic);
    match flight.summary.recordings.as_slice() {
        [_] => format!("world/cameras/{topic}"),
        all => {
            let recording = all.get(usize::from(camera.recording));
            let name = recording.map(|r| r.name()).unwrap_or_default();
            format!("world/cameras/{}/{topic}", entity_name(&name))
        }
    }
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

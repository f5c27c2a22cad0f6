//! The pictures a reviewer judges by: each supporting view's whole frame
//! with the detection box drawn, and the candidate's place on the structure
//! seen from above and from the side.

use std::io::Cursor;

use image::DynamicImage;
use ingest::Recordings;
use postflight_core::Flight;
use postflight_core::outputs::localise::{DefectRecord, ViewRecord};

use reports::results::TargetVoxel;
use reports::views::{Marker, Overlay, Side, nearest_per_cell, view};

/// Frames wider than this are scaled down before sending.
const MAX_WIDTH: u32 = 1280;

/// The frame of a supporting view as JPEG, its detection box drawn unless
/// `draw_box` is false (scaled down to at most [`MAX_WIDTH`] pixels wide).
pub fn view_jpeg(
    flight: &Flight,
    recording: &Recordings,
    v: &ViewRecord,
    draw_box: bool,
) -> Result<Vec<u8>, String> {
    let frame = flight
        .frame(v.frame)
        .ok_or_else(|| format!("frame {} is not in this run's flight", v.frame))?;
    let mut img = recording
        .image(frame)
        .map_err(|e| format!("frame {}: {e}", v.frame))?
        .to_rgb8();
    if draw_box {
        let thickness = (img.width() / 320).max(2);
        ingest::image::draw_box(&mut img, v.bbox, thickness);
    }
    let mut img = DynamicImage::ImageRgb8(img);
    if img.width() > MAX_WIDTH {
        img = img.resize(MAX_WIDTH, u32::MAX, image::imageops::FilterType::Triangle);
    }
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Jpeg)
        .map_err(|e| format!("frame {}: {e}", v.frame))?;
    Ok(out.into_inner())
}

/// Where a candidate is: the structure's target voxels (grey) in plan
/// (from above, or from below for a spot on an underside) and from the side
/// its surface faces, with the spot marked; each with its title. `backdrop`
/// holds per side only the voxels a view draws (see [`backdrop`]). Empty
/// when the run has no coverage voxels.
pub fn position_svgs(
    backdrop: &[(Side, Vec<TargetVoxel>)],
    resolution: f64,
    defect: &DefectRecord,
) -> Vec<(String, String)> {
    let plan = if defect.normal[2] < -0.5 {
        Side::Bottom
    } else {
        Side::Top
    };
    let elevation = match Side::facing(defect.normal) {
        Side::Top | Side::Bottom => Side::South,
        side => side,
    };
    [plan, elevation]
        .into_iter()
        .filter_map(|side| {
            let (_, voxels) = backdrop.iter().find(|(s, _)| *s == side)?;
            // In plan the spot is marked where it lies even on a wall the
            // plan does not see: it answers "where along the structure".
            let normal = if side == plan {
                side.toward_viewer()
            } else {
                defect.normal
            };
            let overlay = Overlay {
                markers: vec![Marker {
                    label: String::new(),
                    position: defect.position,
                    normal,
                    trace: &defect.trace,
                    condition: defect.state(),
                }],
                grey: true,
                ..Overlay::default()
            };
            let title = if side == plan {
                format!("In plan, {}", side.title())
            } else {
                format!("Elevation {}", side.title())
            };
            Some((title, view(voxels, resolution, side, &overlay, 440.0)))
        })
        .collect()
}

/// For each side a candidate can be seen from, the voxels nearest the
/// viewer per picture cell: computed once per server, so a candidate page
/// draws hundreds of squares, not the whole structure.
pub fn backdrop(voxels: &[TargetVoxel], resolution: f64) -> Vec<(Side, Vec<TargetVoxel>)> {
    Side::ALL
        .into_iter()
        .map(|side| {
            let front = nearest_per_cell(voxels, resolution, side);
            (side, front.into_iter().map(|i| voxels[i]).collect())
        })
        .collect()
}

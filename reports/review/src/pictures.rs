//! The pictures a reviewer judges by: each supporting view's whole frame
//! with the detection box drawn, and the candidate's place on the structure
//! seen from above and from the side.

use std::io::Cursor;

use image::DynamicImage;
use ingest::Recording;
use postflight_core::Flight;
use postflight_core::outputs::localise::{DefectRecord, ViewRecord};

use reports::results::TargetVoxel;
use reports::views::{Overlay, Side, nearest_per_cell, view};

/// Frames wider than this are scaled down before sending.
const MAX_WIDTH: u32 = 1280;

/// The frame of a supporting view as JPEG, its detection box drawn (scaled
/// down to at most [`MAX_WIDTH`] pixels wide).
pub fn view_jpeg(
    flight: &Flight,
    recording: &Recording,
    v: &ViewRecord,
) -> Result<Vec<u8>, String> {
    let frame = flight
        .frame(v.frame)
        .ok_or_else(|| format!("frame {} is not in this run's flight", v.frame))?;
    let mut img = recording
        .image(frame)
        .map_err(|e| format!("frame {}: {e}", v.frame))?
        .to_rgb8();
    let thickness = (img.width() / 320).max(2);
    localise::crop::draw_box(&mut img, v.bbox, thickness);
    let mut img = DynamicImage::ImageRgb8(img);
    if img.width() > MAX_WIDTH {
        img = img.resize(MAX_WIDTH, u32::MAX, image::imageops::FilterType::Triangle);
    }
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Jpeg)
        .map_err(|e| format!("frame {}: {e}", v.frame))?;
    Ok(out.into_inner())
}

/// Where a candidate is: the structure's target voxels (grey) seen from
/// above and from the side facing the candidate, with the candidate marked.
/// `backdrop` holds per side only the voxels a view draws (see
/// [`backdrop`]). Empty when the run has no coverage voxels.
pub fn position_svgs(
    backdrop: &[(Side, Vec<TargetVoxel>)],
    resolution: f64,
    defect: &DefectRecord,
) -> Vec<String> {
    let facing = if defect.normal[1] > 0.0 {
        Side::North
    } else {
        Side::South
    };
    backdrop
        .iter()
        .filter(|(side, _)| *side == Side::Top || *side == facing)
        .map(|(side, voxels)| {
            let overlay = Overlay {
                markers: vec![(String::new(), defect.position)],
                grey: true,
                ..Overlay::default()
            };
            view(voxels, resolution, *side, &overlay, 260.0)
        })
        .collect()
}

/// For each side a candidate can be seen from, the voxels nearest the
/// viewer per picture cell: computed once per server, so a candidate page
/// draws hundreds of squares, not the whole structure.
pub fn backdrop(voxels: &[TargetVoxel], resolution: f64) -> Vec<(Side, Vec<TargetVoxel>)> {
    [Side::Top, Side::South, Side::North]
        .into_iter()
        .map(|side| {
            let front = nearest_per_cell(voxels, resolution, side);
            (side, front.into_iter().map(|i| voxels[i]).collect())
        })
        .collect()
}

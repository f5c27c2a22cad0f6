//! The crop of a candidate's best view, its box drawn, for reviewers.

use std::path::Path;

use image::{DynamicImage, RgbImage};
use ingest::Recordings;
use ingest::image::draw_box;
use postflight_core::Frame;

use crate::observation::Observation;

/// The least a crop spans each way, pixels (where the frame has as many):
/// a small box's crop shows the surface round it, not a blur of its pixels.
const MIN_CROP_PX: f32 = 160.0;

/// Crop of the best view around its box (with the box drawn), for
/// reviewers; `false` when the frame's image cannot be decoded (its
/// detections were then placed by their boxes, and the summary says so).
/// The frame is decoded again: keeping every frame's image until fusion
/// picks the best views would hold the whole flight in memory.
pub(crate) fn write_crop(
    recording: &Recordings,
    frame: &Frame,
    best: &Observation,
    path: &Path,
) -> Result<bool, postflight_core::Error> {
    let Ok(img) = recording.image(frame) else {
        return Ok(false);
    };
    let img = img.to_rgb8();
    let b = best.detection.detection.bbox;
    let margin = 0.5 * (b.x1 - b.x0).max(b.y1 - b.y0);
    // Each way, the box and its margin, or MIN_CROP_PX round its centre.
    let span = |lo: f32, hi: f32, size: f32| {
        let half = (0.5 * (hi - lo) + margin).max(0.5 * MIN_CROP_PX);
        let mid = 0.5 * (lo + hi);
        let start = (mid - half).clamp(0.0, size - 1.0);
        (start as u32, (mid + half).clamp(start + 1.0, size) as u32)
    };
    let (x0, x1) = span(b.x0, b.x1, img.width() as f32);
    let (y0, y1) = span(b.y0, b.y1, img.height() as f32);
    let mut crop: RgbImage = image::imageops::crop_imm(&img, x0, y0, x1 - x0, y1 - y0).to_image();
    let (dx, dy) = (x0 as f32, y0 as f32);
    draw_box(&mut crop, [b.x0 - dx, b.y0 - dy, b.x1 - dx, b.y1 - dy], 1);
    let tmp = path.with_extension("jpg.tmp");
    let write_error = |cause| postflight_core::Error::Write {
        path: path.to_owned(),
        cause,
    };
    DynamicImage::ImageRgb8(crop)
        .save_with_format(&tmp, image::ImageFormat::Jpeg)
        .map_err(|e| write_error(std::io::Error::other(e)))?;
    std::fs::rename(&tmp, path).map_err(write_error)?;
    Ok(true)
}

//! Pictures of a detection for reviewers: its box drawn on a frame, and
//! the crop of a candidate's best view.

use std::path::Path;

use image::{DynamicImage, Rgb, RgbImage};
use ingest::Recordings;
use postflight_core::Frame;

use crate::observation::Observation;

/// Draw a detection box (`[x0, y0, x1, y1]`, pixels) on an image in red,
/// `thickness` pixels wide inwards, clipped to the image.
pub fn draw_box(img: &mut RgbImage, bbox: [f32; 4], thickness: u32) {
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return;
    }
    let red = Rgb([230, 40, 40]);
    let clamp = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1);
    let (x0, y0) = (clamp(bbox[0], w), clamp(bbox[1], h));
    let (x1, y1) = (clamp(bbox[2], w).max(x0), clamp(bbox[3], h).max(y0));
    for t in 0..thickness {
        let (ax0, ay0) = ((x0 + t).min(x1), (y0 + t).min(y1));
        let (ax1, ay1) = (x1.saturating_sub(t).max(ax0), y1.saturating_sub(t).max(ay0));
        for x in ax0..=ax1 {
            img.put_pixel(x, ay0, red);
            img.put_pixel(x, ay1, red);
        }
        for y in ay0..=ay1 {
            img.put_pixel(ax0, y, red);
            img.put_pixel(ax1, y, red);
        }
    }
}

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

//! `detections.coco.json`: the detections as COCO detection results, with
//! their images and categories, crack pixels as COCO RLE.

use postflight_core::Frame;
use postflight_core::detection::FrameDetection;
use postflight_core::outputs::detect::DetectionRow;

/// COCO detection results with their images and categories (ids from 1):
/// the detections `found`, with `rows` their table rows (masks encoded).
pub(crate) fn results(
    frames: &[Frame],
    found: &[FrameDetection],
    rows: &[DetectionRow],
    classes: &[String],
) -> serde_json::Value {
    let images: Vec<serde_json::Value> = frames
        .iter()
        .map(|f| {
            serde_json::json!({
                "id": f.index + 1,
                "file_name": format!("frame_{:06}.jpg", f.index),
                "width": f.width,
                "height": f.height,
                "time_ns": f.time_ns,
            })
        })
        .collect();
    let annotations: Vec<serde_json::Value> = rows
        .iter()
        .zip(found)
        .enumerate()
        .map(|(i, (row, d))| {
            let b = row.detection.bbox;
            let mut annotation = serde_json::json!({
                "id": i + 1,
                "image_id": row.detection.frame + 1,
                "category_id": row.class + 1,
                "bbox": [b.x0, b.y0, b.width(), b.height()],
                "area": b.area(),
                "score": row.detection.score,
                "iscrowd": 0,
            });
            // Crack pixels as COCO RLE over the frame; the area is theirs.
            if let Some((counts, mask)) = row.mask.as_ref().zip(d.detection.mask.as_ref()) {
                annotation["segmentation"] = serde_json::json!({
                    "size": [row.frame_height, row.frame_width],
                    "counts": counts,
                });
                annotation["area"] = mask.area().into();
            }
            annotation
        })
        .collect();
    let categories: Vec<serde_json::Value> = classes
        .iter()
        .enumerate()
        .map(|(i, c)| serde_json::json!({"id": i + 1, "name": c, "supercategory": "defect"}))
        .collect();
    serde_json::json!({
        "info": {"description": "postflight detections", "version": env!("CARGO_PKG_VERSION")},
        "images": images,
        "annotations": annotations,
        "categories": categories,
    })
}

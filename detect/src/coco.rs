//! `detections.coco.json`: the detections as COCO detection results, with
//! their images and categories (one per defect kind, named as the kind),
//! their pixels as COCO RLE.

use postflight_core::Frame;
use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::FrameDetection;
use postflight_core::kind::Named;
use postflight_core::outputs::detect::DetectionRow;

/// COCO detection results with their images and categories: the
/// detections `found`, with `rows` their table rows (masks encoded). A
/// category is a defect kind, its id the kind's place among them from 1,
/// the same in every run.
pub(crate) fn results(
    frames: &[Frame],
    found: &[FrameDetection],
    rows: &[DetectionRow],
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
                "category_id": category(row.kind),
                "bbox": [b.x0, b.y0, b.width(), b.height()],
                "area": b.area(),
                "score": row.detection.score,
                "iscrowd": 0,
            });
            // Its pixels as COCO RLE over the frame; the area is theirs.
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
    let categories: Vec<serde_json::Value> = DefectKind::ALL
        .iter()
        .map(|k| serde_json::json!({"id": category(*k), "name": k.name(), "supercategory": "defect"}))
        .collect();
    serde_json::json!({
        "info": {"description": "postflight detections", "version": env!("CARGO_PKG_VERSION")},
        "images": images,
        "annotations": annotations,
        "categories": categories,
    })
}

/// A kind's COCO category id.
fn category(kind: DefectKind) -> usize {
    kind.index() + 1
}

//! Class-aware non-maximum suppression of detections, and merging of
//! boxes a crack was reported in piecewise.

use postflight_core::detection::{BoxXyxy, Detection};

/// Class-aware non-maximum suppression: keep the best-scoring boxes, dropping
/// any that overlap a kept box of the same class by more than `iou`.
/// Returns the kept detections, best first.
pub fn nms(detections: Vec<Detection>, iou: f32) -> Vec<Detection> {
    let tagged = detections.into_iter().map(|d| (d, ())).collect();
    nms_with(tagged, iou).into_iter().map(|(d, ())| d).collect()
}

/// [`nms`] of detections that each carry something along (mask coefficients).
pub fn nms_with<T>(mut detections: Vec<(Detection, T)>, iou: f32) -> Vec<(Detection, T)> {
    // Ties broken by position so the result does not depend on input order.
    detections.sort_by(|(a, _), (b, _)| {
        b.score
            .total_cmp(&a.score)
            .then(a.bbox.x0.total_cmp(&b.bbox.x0))
            .then(a.bbox.y0.total_cmp(&b.bbox.y0))
    });
    let mut kept: Vec<(Detection, T)> = Vec::new();
    for (d, t) in detections {
        if kept
            .iter()
            .all(|(k, _)| k.class != d.class || k.bbox.iou(&d.bbox) <= iou)
        {
            kept.push((d, t));
        }
    }
    kept
}

/// A box merges into a neighbour only when its score is at least this share
/// of the neighbour's. A faint response beside a confident crack box (as at
/// GATSBI's confidence of 0.008) is noise or another finding, and merging it
/// would stretch the crack's box over it.
pub const MERGE_SCORE_RATIO: f32 = 0.5;

/// Merge same-class boxes of comparable score (see [`MERGE_SCORE_RATIO`])
/// that overlap or lie within `gap` pixels of each other into their union,
/// keeping the best score and the union of their crack pixels: a long crack
/// reported piecewise (by grid cells or by tiles) becomes one finding.
pub fn merge_touching(mut detections: Vec<Detection>, gap: f32) -> Vec<Detection> {
    let near = |a: &BoxXyxy, b: &BoxXyxy| {
        a.x0 <= b.x1 + gap && b.x0 <= a.x1 + gap && a.y0 <= b.y1 + gap && b.y0 <= a.y1 + gap
    };
    let comparable = |a: &Detection, b: &Detection| {
        a.score.min(b.score) >= MERGE_SCORE_RATIO * a.score.max(b.score)
    };
    let mut merged = true;
    while merged {
        merged = false;
        'search: for i in 0..detections.len() {
            for j in i + 1..detections.len() {
                let (a, b) = (&detections[i], &detections[j]);
                if a.class == b.class && near(&a.bbox, &b.bbox) && comparable(a, b) {
                    let mask = match (&a.mask, &b.mask) {
                        (Some(m), Some(n)) => Some(m.union(n)),
                        (m, n) => m.clone().or_else(|| n.clone()),
                    };
                    detections[i] = Detection {
                        bbox: BoxXyxy {
                            x0: a.bbox.x0.min(b.bbox.x0),
                            y0: a.bbox.y0.min(b.bbox.y0),
                            x1: a.bbox.x1.max(b.bbox.x1),
                            y1: a.bbox.y1.max(b.bbox.y1),
                        },
                        score: a.score.max(b.score),
                        class: a.class,
                        kind: a.kind,
                        tile: if a.score >= b.score { a.tile } else { b.tile },
                        mask,
                    };
                    detections.swap_remove(j);
                    merged = true;
                    break 'search;
                }
            }
        }
    }
    detections.sort_by(|a, b| b.score.total_cmp(&a.score));
    detections
}

#[cfg(test)]
mod tests {
    use super::*;
    use postflight_core::defect_kind::DefectKind;

    fn det(x0: f32, score: f32, class: u32) -> Detection {
        Detection {
            bbox: BoxXyxy {
                x0,
                y0: 0.0,
                x1: x0 + 10.0,
                y1: 10.0,
            },
            score,
            class,
            kind: DefectKind::Crack,
            tile: -1,
            mask: None,
        }
    }

    #[test]
    fn iou_of_known_overlaps() {
        let a = det(0.0, 1.0, 0).bbox;
        assert_eq!(a.iou(&a), 1.0);
        assert!((a.iou(&det(5.0, 1.0, 0).bbox) - 50.0 / 150.0).abs() < 1e-6);
        assert_eq!(a.iou(&det(20.0, 1.0, 0).bbox), 0.0);
        let c = BoxXyxy::from_cxcywh(5.0, 5.0, 10.0, 10.0);
        assert_eq!(c, a);
    }

    #[test]
    fn touching_boxes_of_a_class_merge() {
        // 0-10 and 12-22 are 2 px apart: merged with gap 4; 40-50 stays; class 1 stays.
        let out = merge_touching(
            vec![
                det(0.0, 0.5, 0),
                det(12.0, 0.9, 0),
                det(40.0, 0.3, 0),
                det(5.0, 0.8, 1),
            ],
            4.0,
        );
        let summary: Vec<(f32, f32, f32, u32)> = out
            .iter()
            .map(|d| (d.bbox.x0, d.bbox.x1, d.score, d.class))
            .collect();
        assert_eq!(
            summary,
            vec![
                (0.0, 22.0, 0.9, 0),
                (5.0, 15.0, 0.8, 1),
                (40.0, 50.0, 0.3, 0)
            ]
        );
    }

    #[test]
    fn a_box_scored_far_below_its_neighbour_is_not_merged_into_it() {
        // 2 px apart, but 0.01 is under half of 0.9: two findings, not one wide box.
        let out = merge_touching(vec![det(0.0, 0.9, 0), det(12.0, 0.01, 0)], 4.0);
        let summary: Vec<(f32, f32)> = out.iter().map(|d| (d.bbox.x0, d.bbox.x1)).collect();
        assert_eq!(summary, vec![(0.0, 10.0), (12.0, 22.0)]);
    }

    #[test]
    fn nms_suppresses_within_a_class_only() {
        let kept = nms(
            vec![
                det(0.0, 0.5, 0),
                det(2.0, 0.9, 0),
                det(1.0, 0.8, 1),
                det(30.0, 0.1, 0),
            ],
            0.5,
        );
        let summary: Vec<(f32, u32)> = kept.iter().map(|d| (d.score, d.class)).collect();
        assert_eq!(summary, vec![(0.9, 0), (0.8, 1), (0.1, 0)]);
    }
}

//! Decoding YOLO output `[batch, 4 + nc (+ k), anchors]` (centre, size, then
//! class scores, in model input pixels, then a segmenting model's `k` mask
//! coefficients) into detections.

use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::{BoxXyxy, Detection};

/// Detections of image `b` of a `[batch, 4 + classes + extra, anchors]`
/// output laid out row-major in `data`, keeping each anchor's best class
/// when its score is at least `confidence`, each with its `extra` values
/// (mask coefficients).
pub fn decode(
    data: &[f32],
    classes: usize,
    extra: usize,
    anchors: usize,
    b: usize,
    confidence: f32,
) -> Vec<(Detection, Vec<f32>)> {
    let rows = 4 + classes + extra;
    let image = &data[b * rows * anchors..(b + 1) * rows * anchors];
    let row = |r: usize| &image[r * anchors..(r + 1) * anchors];
    let (cx, cy, w, h) = (row(0), row(1), row(2), row(3));
    let mut out = Vec::new();
    for a in 0..anchors {
        let (class, score) =
            (0..classes)
                .map(|c| (c, row(4 + c)[a]))
                .fold(
                    (0, f32::NEG_INFINITY),
                    |best, s| if s.1 > best.1 { s } else { best },
                );
        if score >= confidence {
            let detection = Detection {
                bbox: BoxXyxy::from_cxcywh(cx[a], cy[a], w[a], h[a]),
                score,
                class: class as u32,
                kind: DefectKind::Crack,
                tile: -1,
                mask: None,
            };
            let coefficients = (0..extra).map(|k| row(4 + classes + k)[a]).collect();
            out.push((detection, coefficients));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_class_per_anchor_above_threshold() {
        // batch 2, 2 classes, 3 anchors; image 1 only.
        let image0 = vec![0.0; 6 * 3];
        #[rustfmt::skip]
        let image1 = vec![
            10.0, 50.0, 90.0, // cx
            10.0, 50.0, 90.0, // cy
            4.0, 8.0, 2.0,    // w
            2.0, 8.0, 2.0,    // h
            0.9, 0.1, 0.3,    // class 0
            0.2, 0.6, 0.01,   // class 1
        ];
        let data = [image0, image1].concat();
        let d: Vec<Detection> = decode(&data, 2, 0, 3, 1, 0.25)
            .into_iter()
            .map(|(d, _)| d)
            .collect();
        assert_eq!(d.len(), 3);
        assert_eq!((d[0].class, d[0].score), (0, 0.9));
        assert_eq!(
            d[0].bbox,
            BoxXyxy {
                x0: 8.0,
                y0: 9.0,
                x1: 12.0,
                y1: 11.0
            }
        );
        assert_eq!((d[1].class, d[1].score), (1, 0.6));
        assert_eq!((d[2].class, d[2].score), (0, 0.3));
        assert!(decode(&data, 2, 0, 3, 0, 0.25).is_empty());
        // The last rows are coefficients, not classes.
        let with_coefficients = decode(&data, 1, 1, 3, 1, 0.25);
        assert_eq!(with_coefficients.len(), 2);
        assert_eq!(with_coefficients[0].1, vec![0.2]);
    }
}

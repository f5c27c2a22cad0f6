//! Crack pixels from a segmenting model's outputs, in frame pixels: from a
//! crack probability map (a semantic segmentation network's output, or the
//! reference detector's), or from instance prototypes and a detection's
//! coefficients (Ultralytics `-seg` models).

use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::{BoxXyxy, Detection};
use postflight_core::mask::Mask;

use crate::letterbox::Placement;
use crate::tiles::Window;

/// Where a view's model input lies in its frame.
#[derive(Debug, Clone, Copy)]
pub struct ViewPlace {
    pub window: Window,
    pub placement: Placement,
}

impl ViewPlace {
    /// The model-input coordinates (pixel-centre convention) of the centre
    /// of frame pixel `(x, y)`; `None` outside the view's window.
    fn input_at(&self, x: u32, y: u32) -> Option<(f32, f32)> {
        let w = &self.window;
        if x < w.x || y < w.y || x >= w.x + w.width || y >= w.y + w.height {
            return None;
        }
        let p = &self.placement;
        Some((
            ((x - w.x) as f32 + 0.5) * p.scale + p.pad_x - 0.5,
            ((y - w.y) as f32 + 0.5) * p.scale + p.pad_y - 0.5,
        ))
    }
}

/// A plane of values over a view's model input (or a fraction of it, as
/// Ultralytics' prototypes are a quarter of the input's size).
#[derive(Debug, Clone)]
pub struct Plane {
    pub width: usize,
    pub height: usize,
    /// Model input pixels per plane pixel (1: the plane is the input's size).
    pub stride: f32,
    /// Row-major values.
    pub values: Vec<f32>,
}

impl Plane {
    /// The plane coordinates of model-input coordinates `(u, v)` (both
    /// pixel-centre convention).
    fn of_input(&self, (u, v): (f32, f32)) -> (f32, f32) {
        let s = self.stride;
        ((u + 0.5) / s - 0.5, (v + 0.5) / s - 0.5)
    }

    /// Bilinear sample at `(u, v)` (pixel-centre convention), clamped at
    /// the border.
    fn sample(&self, u: f32, v: f32) -> f32 {
        let (w, h) = (self.width as f32, self.height as f32);
        let (u, v) = (u.clamp(0.0, w - 1.0), v.clamp(0.0, h - 1.0));
        let (x0, y0) = (u.floor() as usize, v.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let at = |x: usize, y: usize| self.values[y * self.width + x];
        let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
        let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// One view's probability map of a class (`None`: of every class the
/// model's boxes score, as the reference detectors' crack map), over its
/// model input.
#[derive(Debug, Clone)]
pub struct ProbabilityMap {
    pub place: ViewPlace,
    pub class: Option<u32>,
    pub probability: Plane,
}

/// Order maps finest first, as [`from_maps`] takes them: tiles see more
/// detail than the whole frame scaled down.
pub fn finest_first(maps: &mut [ProbabilityMap]) {
    maps.sort_by(|a, b| b.place.placement.scale.total_cmp(&a.place.placement.scale));
}

/// Frame pixels of `bbox` whose crack probability is above `threshold`,
/// each read from the first of `maps` (ordered by [`finest_first`])
/// covering it; `None` when there are none.
pub fn from_maps(maps: &[&ProbabilityMap], bbox: &BoxXyxy, threshold: f32) -> Option<Mask> {
    let x0 = bbox.x0.max(0.0).floor() as u32;
    let y0 = bbox.y0.max(0.0).floor() as u32;
    let (x1, y1) = (
        bbox.x1.ceil().max(0.0) as u32,
        bbox.y1.ceil().max(0.0) as u32,
    );
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    let mut mask = Mask::empty(x0, y0, x1 - x0, y1 - y0);
    for y in y0..y1 {
        for x in x0..x1 {
            let p = maps.iter().find_map(|m| {
                let (u, v) = m.probability.of_input(m.place.input_at(x, y)?);
                Some(m.probability.sample(u, v))
            });
            if p.is_some_and(|p| p > threshold) {
                mask.on[((y - y0) * mask.width + x - x0) as usize] = true;
            }
        }
    }
    mask.trimmed()
}

/// Ultralytics' mask prototypes of one view: `[k, h, w]` at a fraction of
/// the model input.
#[derive(Debug, Clone)]
pub struct Prototypes {
    pub place: ViewPlace,
    /// One plane per coefficient, each of the same size and stride (4 for
    /// YOLO's P3 prototypes).
    pub planes: Vec<Plane>,
}

impl Prototypes {
    /// The instance mask of a detection with mask `coefficients` and box
    /// `bbox` (frame pixels), as Ultralytics decodes it with
    /// `retina_masks=True`: the coefficients times the prototypes, scaled
    /// to the frame (bilinear), cropped to the box, above logit 0 (a
    /// sigmoid above 0.5).
    pub fn instance(&self, coefficients: &[f32], bbox: &BoxXyxy) -> Option<Mask> {
        let first = self.planes.first()?;
        let x0 = bbox.x0.max(0.0).round() as u32;
        let y0 = bbox.y0.max(0.0).round() as u32;
        let (x1, y1) = (
            bbox.x1.max(0.0).round() as u32,
            bbox.y1.max(0.0).round() as u32,
        );
        if x1 <= x0 || y1 <= y0 {
            return None;
        }
        // Prototype pixels under the box (one more each side for the
        // bilinear taps): the logits are needed there only.
        let to_proto = |x: u32, y: u32| Some(first.of_input(self.place.input_at(x, y)?));
        let (a, b) = (to_proto(x0, y0)?, to_proto(x1 - 1, y1 - 1)?);
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n - 1);
        let (px0, py0) = (
            clamp(a.0.floor() - 1.0, first.width),
            clamp(a.1.floor() - 1.0, first.height),
        );
        let (px1, py1) = (
            clamp(b.0.ceil() + 1.0, first.width),
            clamp(b.1.ceil() + 1.0, first.height),
        );
        let (w, h) = (px1 - px0 + 1, py1 - py0 + 1);
        let mut values = vec![0.0f32; w * h];
        for (plane, c) in self.planes.iter().zip(coefficients) {
            for y in 0..h {
                let row = &plane.values[(py0 + y) * plane.width + px0..][..w];
                for (out, v) in values[y * w..(y + 1) * w].iter_mut().zip(row) {
                    *out += v * c;
                }
            }
        }
        let logits = Plane {
            width: w,
            height: h,
            stride: first.stride,
            values,
        };
        let mut mask = Mask::empty(x0, y0, x1 - x0, y1 - y0);
        for y in y0..y1 {
            for x in x0..x1 {
                let Some((u, v)) = to_proto(x, y) else {
                    continue;
                };
                // Clamped at the prototypes' own border, as a whole-plane
                // sample would be.
                let u = u.clamp(0.0, (first.width - 1) as f32) - px0 as f32;
                let v = v.clamp(0.0, (first.height - 1) as f32) - py0 as f32;
                if logits.sample(u, v) > 0.0 {
                    mask.on[((y - y0) * mask.width + x - x0) as usize] = true;
                }
            }
        }
        mask.trimmed()
    }
}

/// Connected regions (8-neighbours) of a probability plane above
/// `threshold`, at least `min_pixels` large: each one's box (plane pixels,
/// exclusive edges) and its mean probability, how sure the map is over the
/// whole region (a map clipped at 1 gives most regions a brightest pixel
/// of 1, which would rank nothing).
pub fn components(plane: &Plane, threshold: f32, min_pixels: usize) -> Vec<(BoxXyxy, f32)> {
    let (w, h) = (plane.width, plane.height);
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if seen[start] || plane.values[start] <= threshold {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        let (mut count, mut sum) = (0usize, 0.0f64);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
            count += 1;
            sum += f64::from(plane.values[i]);
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if !seen[j] && plane.values[j] > threshold {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if count >= min_pixels {
            let b = BoxXyxy {
                x0: x0 as f32,
                y0: y0 as f32,
                x1: x1 as f32,
                y1: y1 as f32,
            };
            out.push((b, (sum / count as f64) as f32));
        }
    }
    out
}

/// Model pixels whose crack probability is above this are crack (Ultralytics'
/// mask threshold, a sigmoid of 0.5).
pub(crate) const MASK_THRESHOLD: f32 = 0.5;
/// Connected crack pixels of a semantic map fewer than this are noise, not
/// a finding (model pixels).
const MIN_COMPONENT_PX: usize = 8;

/// A semantic map's connected regions of `class` (which finds `kind`)
/// scoring at least `confidence`, as detections in model input pixels.
pub(crate) fn regions(
    probability: &Plane,
    confidence: f32,
    class: u32,
    kind: DefectKind,
) -> Vec<(Detection, Vec<f32>)> {
    let s = probability.stride;
    components(probability, MASK_THRESHOLD, MIN_COMPONENT_PX)
        .into_iter()
        .filter(|(_, score)| *score >= confidence)
        .map(|(b, score)| {
            let detection = Detection {
                bbox: BoxXyxy {
                    x0: b.x0 * s,
                    y0: b.y0 * s,
                    x1: b.x1 * s,
                    y1: b.y1 * s,
                },
                score,
                class,
                kind,
                tile: -1,
                mask: None,
            };
            (detection, Vec::new())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn whole(width: u32, height: u32, scale: f32) -> ViewPlace {
        ViewPlace {
            window: Window {
                x: 0,
                y: 0,
                width,
                height,
                tile: -1,
            },
            placement: Placement {
                scale,
                pad_x: 0.0,
                pad_y: 0.0,
            },
        }
    }

    /// A plane with a vertical line of probability 0.9 at column `x`.
    fn line(width: usize, height: usize, x: usize) -> Plane {
        let mut values = vec![0.05; width * height];
        for y in 2..height - 2 {
            values[y * width + x] = 0.9;
        }
        Plane {
            width,
            height,
            stride: 1.0,
            values,
        }
    }

    #[test]
    fn a_map_gives_the_box_pixels_above_threshold_from_the_finest_view() {
        let fine = ProbabilityMap {
            place: whole(40, 30, 1.0),
            class: None,
            probability: line(40, 30, 10),
        };
        let b = BoxXyxy {
            x0: 0.0,
            y0: 0.0,
            x1: 40.0,
            y1: 30.0,
        };
        let m = from_maps(&[&fine], &b, 0.5).unwrap();
        assert_eq!((m.x0, m.width, m.area()), (10, 1, 26));
        // A coarse whole-frame view (half scale) of another line does not
        // override the fine one where both cover.
        let coarse = ProbabilityMap {
            place: whole(40, 30, 0.5),
            class: None,
            probability: line(20, 15, 15),
        };
        let mut maps = vec![coarse, fine];
        finest_first(&mut maps);
        let m = from_maps(&maps.iter().collect::<Vec<_>>(), &b, 0.5).unwrap();
        assert_eq!((m.x0, m.width), (10, 1));
    }

    #[test]
    fn components_are_the_connected_regions_with_their_mean_score() {
        let mut p = line(20, 20, 3);
        p.values[10 * 20 + 12] = 0.7;
        p.values[11 * 20 + 13] = 0.6;
        let found = components(&p, 0.5, 2);
        assert_eq!(found.len(), 2);
        assert_eq!(
            (found[0].0.x0, found[0].0.y0, found[0].0.y1),
            (3.0, 2.0, 18.0)
        );
        assert_eq!(
            (found[1].0.x0, found[1].0.x1, found[1].1),
            (12.0, 14.0, 0.65)
        );
        assert_eq!(components(&p, 0.5, 3).len(), 1);
    }

    #[test]
    fn instance_masks_are_prototypes_weighted_by_coefficients_cropped_to_the_box() {
        // Two 10x10 prototypes (a 40x40 input at stride 4): one positive on
        // the left half, one on the top half.
        let left = Plane {
            width: 10,
            height: 10,
            stride: 4.0,
            values: (0..100)
                .map(|i| if i % 10 < 5 { 1.0 } else { -1.0 })
                .collect(),
        };
        let top = Plane {
            width: 10,
            height: 10,
            stride: 4.0,
            values: (0..100)
                .map(|i| if i / 10 < 5 { 1.0 } else { -1.0 })
                .collect(),
        };
        let protos = Prototypes {
            place: whole(40, 40, 1.0),
            planes: vec![left, top],
        };
        let b = BoxXyxy {
            x0: 0.0,
            y0: 0.0,
            x1: 40.0,
            y1: 40.0,
        };
        let m = protos.instance(&[1.0, 0.0], &b).unwrap();
        assert_eq!(
            (m.x0, m.y0, m.width, m.height, m.area()),
            (0, 0, 20, 40, 800)
        );
        let m = protos.instance(&[0.0, -2.0], &b).unwrap();
        assert_eq!(
            (m.x0, m.y0, m.width, m.height, m.area()),
            (0, 20, 40, 20, 800)
        );
        // Cropped to a box.
        let small = BoxXyxy {
            x0: 5.0,
            y0: 5.0,
            x1: 10.0,
            y1: 40.0,
        };
        assert_eq!(protos.instance(&[1.0, 0.0], &small).unwrap().area(), 5 * 35);
    }
}

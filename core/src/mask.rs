//! A detection's pixels: the part of a frame a segmentation model marked as
//! crack, kept as the window around them, and written as COCO's run-length
//! encoding (what CVAT, FiftyOne, Label Studio and pycocotools read).

use hotcoco::mask as coco;
use hotcoco::types::Rle;

/// Crack pixels of one detection, in a window of the frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mask {
    /// The window's top-left pixel in the frame.
    pub x0: u32,
    pub y0: u32,
    pub width: u32,
    pub height: u32,
    /// Row-major, `width * height`: whether each pixel is crack.
    pub on: Vec<bool>,
}

impl Mask {
    /// An empty mask over the window `x0, y0, width, height`.
    pub fn empty(x0: u32, y0: u32, width: u32, height: u32) -> Self {
        Self {
            x0,
            y0,
            width,
            height,
            on: vec![false; (width * height) as usize],
        }
    }

    /// Whether frame pixel `(x, y)` is crack.
    pub fn at(&self, x: u32, y: u32) -> bool {
        x >= self.x0
            && y >= self.y0
            && x < self.x0 + self.width
            && y < self.y0 + self.height
            && self.on[((y - self.y0) * self.width + x - self.x0) as usize]
    }

    /// Crack pixels.
    pub fn area(&self) -> usize {
        self.on.iter().filter(|v| **v).count()
    }

    /// Frame pixels `(x, y)` marked as crack, row by row.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + Clone + '_ {
        self.on
            .iter()
            .enumerate()
            .filter(|(_, on)| **on)
            .map(|(i, _)| {
                let i = i as u32;
                (self.x0 + i % self.width, self.y0 + i / self.width)
            })
    }

    /// The mask of frame pixels `pixels` over the tightest window around
    /// them; `None` when there are none.
    pub fn from_pixels(pixels: impl Iterator<Item = (u32, u32)> + Clone) -> Option<Self> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for (x, y) in pixels.clone() {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
        }
        if x0 >= x1 {
            return None;
        }
        let mut out = Self::empty(x0, y0, x1 - x0, y1 - y0);
        for (x, y) in pixels {
            out.on[((y - y0) * out.width + x - x0) as usize] = true;
        }
        Some(out)
    }

    /// The tightest window around its crack pixels; `None` when it has none.
    pub fn trimmed(&self) -> Option<Self> {
        Self::from_pixels(self.pixels())
    }

    /// The union of two masks' crack pixels.
    pub fn union(&self, other: &Self) -> Self {
        Self::from_pixels(self.pixels().chain(other.pixels()))
            .unwrap_or_else(|| Self::empty(self.x0, self.y0, 0, 0))
    }

    /// Intersection over union of the crack pixels; 0 when both are empty.
    pub fn iou(&self, other: &Self) -> f64 {
        let inter = self.pixels().filter(|(x, y)| other.at(*x, *y)).count();
        let union = self.area() + other.area() - inter;
        if union == 0 {
            0.0
        } else {
            inter as f64 / union as f64
        }
    }

    /// COCO's compressed RLE `counts` of the mask over a whole frame
    /// `frame_width` x `frame_height`: runs down the columns, background
    /// first, in pycocotools' LEB128-like string.
    pub fn to_coco(&self, frame_width: u32, frame_height: u32) -> String {
        let h = frame_height;
        // Column-major index of each crack pixel, in order.
        let on = (self.x0..self.x0 + self.width)
            .filter(|x| *x < frame_width)
            .flat_map(|x| {
                (self.y0..(self.y0 + self.height).min(h))
                    .filter(move |y| self.at(x, *y))
                    .map(move |y| x * h + y)
            });
        let mut counts = Vec::new();
        let (mut next, mut run_start) = (0u32, None::<u32>);
        for i in on {
            match run_start {
                Some(_) if i == next => {}
                Some(start) => {
                    counts.push(next - start);
                    counts.push(i - next);
                    run_start = Some(i);
                }
                None => {
                    counts.push(i);
                    run_start = Some(i);
                }
            }
            next = i + 1;
        }
        if let Some(start) = run_start {
            counts.push(next - start);
        }
        let rest = frame_width * h - counts.iter().sum::<u32>();
        if rest > 0 || counts.is_empty() {
            counts.push(rest);
        }
        coco::rle_to_string(&Rle {
            h: frame_height,
            w: frame_width,
            counts,
        })
    }

    /// The mask of COCO compressed RLE `counts` over a frame `frame_width` x
    /// `frame_height`, trimmed to its pixels (`None`: it has none).
    pub fn from_coco(
        counts: &str,
        frame_width: u32,
        frame_height: u32,
    ) -> Result<Option<Self>, String> {
        let rle = coco::rle_from_string(counts, frame_height, frame_width)
            .and_then(|rle| {
                coco::check_counts(&rle.counts, frame_height, frame_width).map(|()| rle)
            })
            .map_err(|e| format!("not COCO RLE of a {frame_width}x{frame_height} frame: {e}"))?;
        // The runs' crack pixels (every other run), as frame pixels.
        let mut runs = Vec::new();
        let mut at = 0u32;
        for (k, n) in rle.counts.iter().enumerate() {
            if k % 2 == 1 {
                runs.push(at..at + n);
            }
            at += n;
        }
        let h = frame_height;
        let pixels = runs
            .iter()
            .flat_map(|r| r.clone().map(move |i| (i / h, i % h)));
        Ok(Self::from_pixels(pixels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diagonal() -> Mask {
        let mut m = Mask::empty(10, 20, 8, 6);
        for k in 0..6 {
            m.on[(k * 8 + k + 1) as usize] = true;
        }
        m
    }

    #[test]
    fn coco_rle_round_trips_over_the_frame() {
        let m = diagonal();
        let counts = m.to_coco(40, 30);
        let back = Mask::from_coco(&counts, 40, 30).unwrap().unwrap();
        assert_eq!(back.area(), 6);
        assert_eq!((back.x0, back.y0, back.width, back.height), (11, 20, 6, 6));
        assert_eq!(back.iou(&m), 1.0);
        // Garbage, and runs longer than the frame, are refused.
        assert!(Mask::from_coco("!!", 40, 30).is_err());
        assert!(Mask::from_coco(&counts, 40, 20).is_err());
    }

    #[test]
    fn runs_are_those_pycocotools_encodes_from_the_whole_frame() {
        // pycocotools' encoder (hotcoco's port) over a frame-sized buffer.
        let reference = |m: &Mask, w: u32, h: u32| {
            let mut column_major = vec![0u8; (w * h) as usize];
            for (x, y) in m.pixels() {
                column_major[(y + h * x) as usize] = 1;
            }
            coco::rle_to_string(&coco::encode(&column_major, h, w).unwrap())
        };
        let mut corners = Mask::empty(0, 0, 40, 30);
        for i in [0, 39, 29 * 40, 29 * 40 + 39, 15 * 40 + 20, 16 * 40 + 20] {
            corners.on[i] = true;
        }
        let full = Mask {
            on: vec![true; 6],
            ..Mask::empty(38, 27, 2, 3)
        };
        for m in [diagonal(), corners, full, Mask::empty(3, 3, 2, 2)] {
            assert_eq!(m.to_coco(40, 30), reference(&m, 40, 30), "{m:?}");
        }
    }

    #[test]
    fn union_and_iou_count_shared_pixels() {
        let a = diagonal();
        let mut b = Mask::empty(0, 0, 30, 30);
        b.on[20 * 30 + 11] = true;
        b.on[0] = true;
        let u = a.union(&b);
        assert_eq!(u.area(), 7);
        assert!((a.iou(&b) - 1.0 / 7.0).abs() < 1e-12);
        assert!(u.at(0, 0) && u.at(11, 20) && !u.at(10, 20));
    }
}

//! A detection's pixels: the part of a frame a segmentation model marked as
//! crack, kept as the window around them, and written as COCO's run-length
//! encoding (what CVAT, FiftyOne, Label Studio and pycocotools read).

use hotcoco::mask as coco;

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
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.on
            .iter()
            .enumerate()
            .filter(|(_, on)| **on)
            .map(|(i, _)| {
                let i = i as u32;
                (self.x0 + i % self.width, self.y0 + i / self.width)
            })
    }

    /// The tightest window around its crack pixels; `None` when it has none.
    pub fn trimmed(&self) -> Option<Self> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for (x, y) in self.pixels() {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
        }
        if x0 >= x1 {
            return None;
        }
        let mut out = Self::empty(x0, y0, x1 - x0, y1 - y0);
        for (x, y) in self.pixels() {
            out.on[((y - y0) * out.width + x - x0) as usize] = true;
        }
        Some(out)
    }

    /// The union of two masks, over a window holding both.
    pub fn union(&self, other: &Self) -> Self {
        let x0 = self.x0.min(other.x0);
        let y0 = self.y0.min(other.y0);
        let x1 = (self.x0 + self.width).max(other.x0 + other.width);
        let y1 = (self.y0 + self.height).max(other.y0 + other.height);
        let mut out = Self::empty(x0, y0, x1 - x0, y1 - y0);
        for (x, y) in self.pixels().chain(other.pixels()) {
            out.on[((y - y0) * out.width + x - x0) as usize] = true;
        }
        out
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
    /// `frame_width` x `frame_height` (column-major runs, LEB128-like string).
    pub fn to_coco(&self, frame_width: u32, frame_height: u32) -> String {
        let (w, h) = (frame_width as usize, frame_height as usize);
        let mut column_major = vec![0u8; w * h];
        for (x, y) in self.pixels() {
            if (x as usize) < w && (y as usize) < h {
                column_major[y as usize + h * x as usize] = 1;
            }
        }
        let rle = coco::encode(&column_major, frame_height, frame_width)
            .expect("the buffer is frame-sized");
        coco::rle_to_string(&rle)
    }

    /// The mask of COCO compressed RLE `counts` over a frame `frame_width` x
    /// `frame_height`, trimmed to its pixels (`None`: it has none).
    pub fn from_coco(
        counts: &str,
        frame_width: u32,
        frame_height: u32,
    ) -> Result<Option<Self>, String> {
        let rle = coco::rle_from_string(counts, frame_height, frame_width)
            .map_err(|e| format!("not COCO RLE of a {frame_width}x{frame_height} frame: {e}"))?;
        let column_major = coco::decode(&rle);
        let h = frame_height as usize;
        let mut full = Self::empty(0, 0, frame_width, frame_height);
        for (i, v) in column_major.iter().enumerate() {
            if *v != 0 {
                let (x, y) = (i / h, i % h);
                full.on[y * frame_width as usize + x] = true;
            }
        }
        Ok(full.trimmed())
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
        assert!(
            Mask::from_coco("!!", 40, 30).is_err()
                || Mask::from_coco("!!", 40, 30).unwrap().is_none()
        );
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

//! Letterboxing as Ultralytics does it: scale the image to fit the model
//! input keeping its aspect ratio (bilinear, with OpenCV's `INTER_LINEAR`
//! pixel-centre alignment, rounded back to 8 bits), centre it on gray (114)
//! padding, and map boxes back to the original pixels afterwards. A model
//! with a dynamic input gets the smallest such rectangle, as Ultralytics
//! predicts with one (`LetterBox(auto=True)`): a 640x480 frame runs as
//! 640x480, not padded to 640x640.
//!
//! The arithmetic is spelled out (f32, horizontal then vertical) so that a
//! NumPy reimplementation gives bit-identical inputs: see
//! `detect/python/pipeline.py`.

use image::RgbImage;

use postflight_core::detection::BoxXyxy;

/// Gray of the padding, as Ultralytics pads.
pub const PAD: u8 = 114;

/// How an image was placed in the model input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Model input pixels per image pixel.
    pub scale: f32,
    /// Padding left and top, model input pixels.
    pub pad_x: f32,
    pub pad_y: f32,
}

/// The model input's size, for an image of a given size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputSize {
    /// The model's fixed input, `(width, height)`.
    Fixed(u32, u32),
    /// A dynamic input: the image scaled to fit a `size` square, padded only
    /// up to a multiple of the model's `stride`.
    Rect { size: u32, stride: u32 },
}

impl InputSize {
    /// The input `(width, height)` for a `width` x `height` image, and where
    /// the image goes in it.
    pub fn place(self, width: u32, height: u32) -> ((u32, u32), Placement) {
        let (fit_w, fit_h) = match self {
            Self::Fixed(w, h) => (w, h),
            Self::Rect { size, .. } => (size, size),
        };
        let scale = (fit_w as f32 / width as f32).min(fit_h as f32 / height as f32);
        let (new_w, new_h) = scaled(width, height, scale);
        let (size_w, size_h) = match self {
            Self::Fixed(w, h) => (w, h),
            Self::Rect { size, stride } => (
                new_w + size.saturating_sub(new_w) % stride,
                new_h + size.saturating_sub(new_h) % stride,
            ),
        };
        let placement = Placement {
            scale,
            // Ultralytics splits odd padding with the extra pixel right/bottom.
            pad_x: (size_w.saturating_sub(new_w) / 2) as f32,
            pad_y: (size_h.saturating_sub(new_h) / 2) as f32,
        };
        ((size_w, size_h), placement)
    }
}

impl Placement {
    /// A box in model input pixels, back in image pixels.
    pub fn to_image(&self, b: &BoxXyxy) -> BoxXyxy {
        BoxXyxy {
            x0: (b.x0 - self.pad_x) / self.scale,
            y0: (b.y0 - self.pad_y) / self.scale,
            x1: (b.x1 - self.pad_x) / self.scale,
            y1: (b.y1 - self.pad_y) / self.scale,
        }
    }
}

fn scaled(width: u32, height: u32, scale: f32) -> (u32, u32) {
    (
        ((width as f32 * scale).round() as u32).max(1),
        ((height as f32 * scale).round() as u32).max(1),
    )
}

/// Letterbox `img` into the model input `size` gives it, written as planar
/// float32 0..1 (`[3, height, width]`) into `out`; returns the input's
/// `(width, height)` and the image's placement in it.
pub fn letterbox(img: &RgbImage, size: InputSize, out: &mut Vec<f32>) -> ((u32, u32), Placement) {
    let ((size_w, size_h), placement) = size.place(img.width(), img.height());
    let (new_w, new_h) = scaled(img.width(), img.height(), placement.scale);
    out.clear();
    out.resize(3 * (size_w * size_h) as usize, f32::from(PAD) / 255.0);
    let plane = (size_w * size_h) as usize;
    let (px, py) = (placement.pad_x as usize, placement.pad_y as usize);
    let mut put = |x: usize, y: usize, rgb: [u8; 3]| {
        let i = (y + py) * size_w as usize + x + px;
        for (c, v) in rgb.into_iter().enumerate() {
            out[c * plane + i] = f32::from(v) / 255.0;
        }
    };
    if (new_w, new_h) == img.dimensions() {
        for (x, y, p) in img.enumerate_pixels() {
            put(x as usize, y as usize, p.0);
        }
    } else {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let columns = taps(w, new_w as usize);
        let rows = taps(h, new_h as usize);
        let src = img.as_raw();
        // One source row resized horizontally, as f32 RGB.
        let horizontal = |y: usize, row: &mut [f32]| {
            let line = &src[y * w * 3..(y + 1) * w * 3];
            for (x, &(x0, x1, f)) in columns.iter().enumerate() {
                for c in 0..3 {
                    let (a, b) = (f32::from(line[x0 * 3 + c]), f32::from(line[x1 * 3 + c]));
                    row[x * 3 + c] = a * (1.0 - f) + b * f;
                }
            }
        };
        let mut top = vec![0.0f32; new_w as usize * 3];
        let mut bottom = top.clone();
        for (y, &(y0, y1, f)) in rows.iter().enumerate() {
            horizontal(y0, &mut top);
            horizontal(y1, &mut bottom);
            for x in 0..new_w as usize {
                let v = |c: usize| {
                    let v = top[x * 3 + c] * (1.0 - f) + bottom[x * 3 + c] * f;
                    (v + 0.5).floor().clamp(0.0, 255.0) as u8
                };
                put(x, y, [v(0), v(1), v(2)]);
            }
        }
    }
    ((size_w, size_h), placement)
}

/// Bilinear taps resizing `from` pixels to `to`: for each output pixel, the
/// two source pixels and the weight of the second. Pixel centres align as in
/// OpenCV's `INTER_LINEAR`: `src = (dst + 0.5) * from / to - 0.5`, clamped
/// to the image.
fn taps(from: usize, to: usize) -> Vec<(usize, usize, f32)> {
    let scale = from as f32 / to as f32;
    let last = (from - 1) as f32;
    (0..to)
        .map(|d| {
            let s = ((d as f32 + 0.5) * scale - 0.5).clamp(0.0, last);
            let i = s.floor();
            let i0 = i as usize;
            (i0, (i0 + 1).min(from - 1), s - i)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_image_is_padded_top_and_bottom_and_boxes_map_back() {
        let img = RgbImage::from_pixel(640, 480, image::Rgb([255, 0, 0]));
        let mut input = Vec::new();
        let (_, p) = letterbox(&img, InputSize::Fixed(640, 640), &mut input);
        assert_eq!(
            p,
            Placement {
                scale: 1.0,
                pad_x: 0.0,
                pad_y: 80.0
            }
        );
        let plane = 640 * 640;
        assert_eq!(input[0], 114.0 / 255.0); // padding, top row
        assert_eq!(input[80 * 640], 1.0); // red, first image row
        assert_eq!(input[plane + 80 * 640], 0.0); // green plane
        let b = p.to_image(&BoxXyxy {
            x0: 10.0,
            y0: 90.0,
            x1: 20.0,
            y1: 100.0,
        });
        assert_eq!(
            b,
            BoxXyxy {
                x0: 10.0,
                y0: 10.0,
                x1: 20.0,
                y1: 20.0
            }
        );
    }

    #[test]
    fn resizing_interpolates_between_pixel_centres() {
        // Two columns, 0 and 200, stretched to four: OpenCV gives 0, 50, 150, 200.
        let img = RgbImage::from_fn(2, 1, |x, _| image::Rgb([(x * 200) as u8; 3]));
        let mut input = Vec::new();
        let (_, p) = letterbox(&img, InputSize::Fixed(4, 4), &mut input);
        assert_eq!((p.scale, p.pad_y), (2.0, 1.0));
        let row: Vec<f32> = input[4..8].iter().map(|v| v * 255.0).collect();
        for (got, want) in row.iter().zip([0.0, 50.0, 150.0, 200.0]) {
            assert!((got - want).abs() < 1e-3, "{row:?}");
        }
        // Halving averages neighbours: 10 and 30 give 20.
        let img = RgbImage::from_fn(4, 2, |x, _| image::Rgb([[10, 30, 50, 70][x as usize]; 3]));
        let mut input = Vec::new();
        letterbox(&img, InputSize::Fixed(2, 2), &mut input);
        let row: Vec<f32> = input[0..2].iter().map(|v| (v * 255.0).round()).collect();
        assert_eq!(row, [20.0, 60.0]);
    }

    #[test]
    fn large_image_is_scaled_down() {
        let img = RgbImage::new(1920, 1080);
        let (_, p) = InputSize::Fixed(640, 640).place(img.width(), img.height());
        assert!((p.scale - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!((p.pad_x, p.pad_y), (0.0, 140.0));
        let b = p.to_image(&BoxXyxy {
            x0: 0.0,
            y0: 140.0,
            x1: 640.0,
            y1: 500.0,
        });
        assert!((b.x1 - 1920.0).abs() < 1e-3 && (b.y1 - 1080.0).abs() < 1e-3);
    }

    #[test]
    fn a_dynamic_input_is_the_smallest_stride_multiple_rectangle() {
        let rect = InputSize::Rect {
            size: 640,
            stride: 32,
        };
        // A VGA frame runs as it is: no padding rows.
        let (size, p) = rect.place(640, 480);
        assert_eq!(
            (size, p.scale, p.pad_x, p.pad_y),
            ((640, 480), 1.0, 0.0, 0.0)
        );
        // Full HD shrinks to 640x360, padded to 384 rows (12 above, 12 below),
        // as Ultralytics' LetterBox(auto=True) gives.
        let (size, p) = rect.place(1920, 1080);
        assert_eq!((size, p.pad_x, p.pad_y), ((640, 384), 0.0, 12.0));
        // A fixed input is filled whatever the image.
        let (size, p) = InputSize::Fixed(640, 640).place(640, 480);
        assert_eq!((size, p.pad_y), ((640, 640), 80.0));
    }
}

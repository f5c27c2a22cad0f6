//! Letterboxing as Ultralytics does it: scale the image to fit the model
//! input keeping its aspect ratio, centre it on gray (114) padding, and map
//! boxes back to the original pixels afterwards.

use image::RgbImage;
use image::imageops::FilterType;

use crate::boxes::BoxXyxy;

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

impl Placement {
    /// The placement of a `width` x `height` image in a `size_w` x `size_h` input.
    pub fn fit(width: u32, height: u32, size_w: u32, size_h: u32) -> Self {
        let scale = (size_w as f32 / width as f32).min(size_h as f32 / height as f32);
        let (new_w, new_h) = scaled(width, height, scale);
        Self {
            scale,
            // Ultralytics splits odd padding with the extra pixel right/bottom.
            pad_x: ((size_w - new_w) / 2) as f32,
            pad_y: ((size_h - new_h) / 2) as f32,
        }
    }

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

/// Letterbox `img` into a `size_w` x `size_h` RGB input, written as planar
/// float32 0..1 (`[3, size_h, size_w]`) into `out`.
pub fn letterbox(img: &RgbImage, size_w: u32, size_h: u32, out: &mut [f32]) -> Placement {
    assert_eq!(
        out.len(),
        3 * (size_w * size_h) as usize,
        "input buffer size"
    );
    let placement = Placement::fit(img.width(), img.height(), size_w, size_h);
    let (new_w, new_h) = scaled(img.width(), img.height(), placement.scale);
    let resized;
    let src = if (new_w, new_h) == img.dimensions() {
        img
    } else {
        resized = image::imageops::resize(img, new_w, new_h, FilterType::Triangle);
        &resized
    };
    out.fill(f32::from(PAD) / 255.0);
    let plane = (size_w * size_h) as usize;
    let (px, py) = (placement.pad_x as u32, placement.pad_y as u32);
    for (x, y, p) in src.enumerate_pixels() {
        let i = ((y + py) * size_w + (x + px)) as usize;
        for c in 0..3 {
            out[c * plane + i] = f32::from(p.0[c]) / 255.0;
        }
    }
    placement
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_image_is_padded_top_and_bottom_and_boxes_map_back() {
        let img = RgbImage::from_pixel(640, 480, image::Rgb([255, 0, 0]));
        let mut input = vec![0.0; 3 * 640 * 640];
        let p = letterbox(&img, 640, 640, &mut input);
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
    fn large_image_is_scaled_down() {
        let img = RgbImage::new(1920, 1080);
        let p = Placement::fit(img.width(), img.height(), 640, 640);
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
}

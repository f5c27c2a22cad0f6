//! Camera images as recorded: reading their size from the first bytes
//! (metadata ingest), decoding them to pixels (later stages) and marking a
//! detection's box on one for reviewers (localise's crops, the review
//! queue's frames).

use image::{DynamicImage, GrayImage, ImageBuffer, Luma, Rgb, RgbImage};

pub use postflight_core::frame::Compression;

/// Width and height of a JPEG or PNG from its headers, reading only the
/// bytes before the pixel data.
pub fn compressed_size(data: &[u8]) -> Option<(u32, u32)> {
    match Compression::sniff(data)? {
        Compression::Png => {
            // Signature, IHDR length and type, then width and height.
            let ihdr = data.get(12..24)?;
            if &ihdr[..4] != b"IHDR" {
                return None;
            }
            let w = u32::from_be_bytes(ihdr[4..8].try_into().ok()?);
            let h = u32::from_be_bytes(ihdr[8..12].try_into().ok()?);
            Some((w, h))
        }
        Compression::Jpeg => jpeg_size(data),
    }
}

fn jpeg_size(data: &[u8]) -> Option<(u32, u32)> {
    let mut pos = 2;
    loop {
        // Skip fill bytes before a marker.
        while *data.get(pos)? == 0xff && *data.get(pos + 1)? == 0xff {
            pos += 1;
        }
        if *data.get(pos)? != 0xff {
            return None;
        }
        let marker = *data.get(pos + 1)?;
        pos += 2;
        if (0xd0..=0xd9).contains(&marker) || marker == 0x01 {
            continue; // markers without a length
        }
        let len = usize::from(u16::from_be_bytes([*data.get(pos)?, *data.get(pos + 1)?]));
        // SOF0..SOF15 except DHT (c4), JPG (c8) and DAC (cc).
        if (0xc0..=0xcf).contains(&marker) && ![0xc4, 0xc8, 0xcc].contains(&marker) {
            let h = u16::from_be_bytes([*data.get(pos + 3)?, *data.get(pos + 4)?]);
            let w = u16::from_be_bytes([*data.get(pos + 5)?, *data.get(pos + 6)?]);
            return Some((u32::from(w), u32::from(h)));
        }
        pos += len;
    }
}

/// Raw `sensor_msgs/msg/Image` encodings postflight decodes.
pub const RAW_ENCODINGS: &[&str] = &[
    "rgb8", "bgr8", "rgba8", "bgra8", "mono8", "mono16", "8UC1", "16UC1",
];

/// Decode a `sensor_msgs/msg/Image` payload.
pub fn decode_raw(
    encoding: &str,
    width: u32,
    height: u32,
    step: u32,
    big_endian: bool,
    data: &[u8],
) -> Result<DynamicImage, String> {
    let channels: usize = match encoding {
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        "mono8" | "8UC1" => 1,
        "mono16" | "16UC1" => 2,
        other => {
            return Err(format!(
                "unsupported image encoding {other:?} (supported: {})",
                RAW_ENCODINGS.join(", ")
            ));
        }
    };
    let (w, h, step) = (width as usize, height as usize, step as usize);
    let row = w * channels;
    if step < row || data.len() < step * h.saturating_sub(1) + row {
        return Err(format!(
            "{encoding} image {width}x{height} with step {step} needs more than the {} bytes recorded",
            data.len()
        ));
    }
    let rows = (0..h).map(|y| &data[y * step..y * step + row]);
    Ok(match encoding {
        "rgb8" | "bgr8" | "rgba8" | "bgra8" => {
            let bgr = encoding.starts_with("bgr");
            let mut out = Vec::with_capacity(w * h * 3);
            for r in rows {
                for px in r.chunks_exact(channels) {
                    if bgr {
                        out.extend_from_slice(&[px[2], px[1], px[0]]);
                    } else {
                        out.extend_from_slice(&px[..3]);
                    }
                }
            }
            DynamicImage::ImageRgb8(RgbImage::from_raw(width, height, out).ok_or("bad size")?)
        }
        "mono8" | "8UC1" => {
            let out: Vec<u8> = rows.flatten().copied().collect();
            DynamicImage::ImageLuma8(GrayImage::from_raw(width, height, out).ok_or("bad size")?)
        }
        _ => {
            let out: Vec<u16> = rows
                .flat_map(|r| r.chunks_exact(2))
                .map(|b| {
                    if big_endian {
                        u16::from_be_bytes([b[0], b[1]])
                    } else {
                        u16::from_le_bytes([b[0], b[1]])
                    }
                })
                .collect();
            DynamicImage::ImageLuma16(
                ImageBuffer::<Luma<u16>, _>::from_raw(width, height, out).ok_or("bad size")?,
            )
        }
    })
}

/// Decode a `sensor_msgs/msg/CompressedImage` payload (JPEG or PNG).
pub fn decode_compressed(data: &[u8]) -> Result<DynamicImage, String> {
    let format = match Compression::sniff(data) {
        Some(Compression::Jpeg) => image::ImageFormat::Jpeg,
        Some(Compression::Png) => image::ImageFormat::Png,
        None => return Err("compressed image is neither JPEG nor PNG".into()),
    };
    // The JPEG decoder fills a cut-off scan with gray rather than failing; a
    // frame that lost its pixels must not pass for a blank surface.
    if format == image::ImageFormat::Jpeg && !ends_with_eoi(data) {
        return Err("JPEG is cut off (no end-of-image marker)".into());
    }
    image::load_from_memory_with_format(data, format).map_err(one_line)
}

/// A decoder's message on one line: some of them run over lines, or end
/// in a line break, which would split the log's line.
pub(crate) fn one_line(error: image::ImageError) -> String {
    let text = error.to_string();
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .collect::<Vec<_>>()
        .join("; ")
}

/// Whether a JPEG ends with its end-of-image marker (`FF D9`), allowing the
/// few padding bytes some encoders append.
pub(crate) fn ends_with_eoi(data: &[u8]) -> bool {
    let tail = &data[data.len().saturating_sub(16)..];
    tail.windows(2).any(|w| w == [0xff, 0xd9])
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn encoded(format: image::ImageFormat) -> Vec<u8> {
        let img = RgbImage::from_fn(37, 21, |x, y| image::Rgb([x as u8 * 6, y as u8 * 12, 90]));
        let mut out = Cursor::new(Vec::new());
        img.write_to(&mut out, format).unwrap();
        out.into_inner()
    }

    #[test]
    fn a_decoders_message_is_one_line() {
        // An APP0 segment claiming 65 kB: the JPEG decoder's message ends
        // in a line break, which would split the log's line.
        let mut data = encoded(image::ImageFormat::Jpeg);
        data[4] = 0xff;
        let err = decode_compressed(&data).unwrap_err();
        assert!(
            err.contains("Not enough bytes") && !err.contains('\n'),
            "{err:?}"
        );
    }

    #[test]
    fn a_cut_off_jpeg_is_an_error_not_a_gray_image() {
        let data = encoded(image::ImageFormat::Jpeg);
        assert!(decode_compressed(&data).is_ok());
        let err = decode_compressed(&data[..data.len() - 40]).unwrap_err();
        assert!(err.contains("cut off"), "{err}");
    }

    #[test]
    fn reads_size_from_headers_only() {
        for format in [image::ImageFormat::Jpeg, image::ImageFormat::Png] {
            let data = encoded(format);
            assert_eq!(compressed_size(&data), Some((37, 21)), "{format:?}");
            let img = decode_compressed(&data).unwrap();
            assert_eq!((img.width(), img.height()), (37, 21));
        }
        assert_eq!(compressed_size(b"GIF89a"), None);
    }

    #[test]
    fn decodes_bgr_with_row_padding() {
        // 2x2 bgr8 with a step of 8 (2 bytes of padding per row).
        let data = [1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0];
        let img = decode_raw("bgr8", 2, 2, 8, false, &data).unwrap().to_rgb8();
        assert_eq!(img.get_pixel(0, 0).0, [3, 2, 1]);
        assert_eq!(img.get_pixel(1, 1).0, [12, 11, 10]);
        assert!(decode_raw("bgr8", 2, 2, 8, false, &data[..10]).is_err());
        let m16 = decode_raw("mono16", 1, 1, 2, true, &[1, 2]).unwrap();
        assert_eq!(m16.as_luma16().unwrap().get_pixel(0, 0).0, [258]);
    }
}

//! Tiled inference: thin cracks vanish when a large frame is shrunk to the
//! model input, so the detector also sees overlapping full-resolution tiles.

/// A part of a frame the detector sees on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
    /// Tile number, or -1 for the whole frame.
    pub tile: i32,
}

/// Starts of `size`-long tiles overlapping by `overlap` (0..1) covering `len`.
fn starts(len: u32, size: u32, overlap: f32) -> Vec<u32> {
    if len <= size {
        return vec![0];
    }
    let step = ((size as f32 * (1.0 - overlap)).floor() as u32).max(1);
    let mut out: Vec<u32> = (0..)
        .map(|k| k * step)
        .take_while(|s| s + size < len)
        .collect();
    out.push(len - size); // the last tile ends at the edge
    out
}

/// The whole frame, then (with `tile`) square tiles of that size overlapping
/// by `overlap`, row by row.
pub fn windows(width: u32, height: u32, tile: Option<u32>, overlap: f32) -> Vec<Window> {
    let mut out = vec![Window {
        x: 0,
        y: 0,
        width,
        height,
        tile: -1,
    }];
    if let Some(size) = tile.filter(|s| *s < width.max(height)) {
        for y in starts(height, size, overlap) {
            for x in starts(width, size, overlap) {
                out.push(Window {
                    x,
                    y,
                    width: size.min(width),
                    height: size.min(height),
                    tile: out.len() as i32 - 1,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_frame_with_overlap() {
        let w = windows(4000, 3000, Some(640), 0.2);
        assert_eq!(w[0].tile, -1);
        let tiles = &w[1..];
        // Every pixel is in some tile, and neighbours overlap by at least 20%.
        for (px, py) in [(0, 0), (3999, 2999), (1234, 2345), (639, 640)] {
            assert!(
                tiles
                    .iter()
                    .any(|t| px >= t.x && px < t.x + t.width && py >= t.y && py < t.y + t.height)
            );
        }
        let xs: Vec<u32> = tiles.iter().filter(|t| t.y == 0).map(|t| t.x).collect();
        assert!(xs.windows(2).all(|p| p[1] - p[0] <= 512));
        assert_eq!(*xs.last().unwrap(), 4000 - 640);
        assert_eq!(
            tiles.iter().map(|t| t.tile).collect::<Vec<_>>(),
            (0..tiles.len() as i32).collect::<Vec<_>>()
        );
        // A frame no larger than a tile needs no tiles.
        assert_eq!(windows(640, 480, Some(640), 0.2).len(), 1);
        assert_eq!(windows(640, 480, None, 0.2).len(), 1);
    }
}

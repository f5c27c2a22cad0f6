//! A crack's width at each point of its centre line in one image, in
//! pixels, read from its crossing there ([`crate::crossing`]) two ways:
//!
//! - **across its walls**, where it is wider than the camera's blur: its
//!   width at a quarter of its depth, less what the blur alone spreads a
//!   wall there ([`crate::blur`]), and never less than its width at half
//!   depth. A blurred wall's half depth lies on the wall, so a crack with
//!   upright walls reads its opening either way; a V or U section's walls
//!   slope from its opening, and the quarter depth takes in three quarters
//!   of a V's and all of a U's. (The detector's mask only says where a
//!   crack is: a trained model's mask reproduces how the people who drew
//!   its training masks drew, wider than the opening a gauge reads;
//!   docs/evaluation.md.)
//! - **from its darkness**: the light it takes away, summed across it, over
//!   the contrast between the surface and a crack's interior. A line
//!   thinner than the blur never reaches its interior's darkness, and its
//!   half-depth width is the blur's; the sum keeps its width. The contrast
//!   is read where cracks resolve ([`crate::contrast`]), or is the blurred
//!   profile's own depth where that is darker.
//!
//! The two meet without a step: the walls' share grows with the width they
//! read, from none at [`RESOLVED_PX`] to all of it at [`WALLS_ALONE_PX`],
//! and with how near the crossing's depth comes to the interior's (a line
//! thinner than the blur reaches a fraction of it, however wide a
//! defocused camera spreads it). Below what the image's noise lets the sum
//! tell from the surface, the width is only known to be narrower than that
//! limit.

use nalgebra::{Point2, Vector2};

use crate::blur::Blur;
use crate::contrast::Contrast;
use crate::crossing::{Crossing, RESOLVED_PX, WALLS_APART_PX};

/// Width across the walls from which it alone is the width, pixels.
pub const WALLS_ALONE_PX: f64 = 2.0 * RESOLVED_PX;
/// A crossing's depth, as a share of the interior's darkness, from which
/// its walls count (none below, all from [`FULL_DEPTH`]).
const WALLS_FROM_DEPTH: f64 = 0.5;
const FULL_DEPTH: f64 = 1.0;

/// A crack's width at one centre-line pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointWidth {
    /// The centre-line pixel.
    pub at: Point2<f64>,
    /// Unit normal of the centre line there, image pixels.
    pub across: Vector2<f64>,
    pub width: Width,
}

/// What a crossing tells of the crack's width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Width {
    /// Measured, pixels.
    Read(Read),
    /// Fainter than the noise: narrower than this many pixels.
    Below { px: f64 },
}

/// A width read across a crack's walls, from its darkness, or both.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Read {
    /// The width, pixels.
    pub px: f64,
    /// The walls' share of it (0: its darkness alone, 1: its walls alone).
    pub resolved: f64,
    /// How uncertain the walls' slope leaves their width, pixels: half the
    /// difference between their width at a quarter and at half depth
    /// (times the walls' share).
    pub spread: f64,
    /// The share of the width its darkness gave over the interior's
    /// contrast (not the profile's own depth), which the contrast's
    /// uncertainty scales.
    pub by_contrast: f64,
}

impl Width {
    /// The width, or the bound it is below, in pixels.
    pub fn px(self) -> f64 {
        match self {
            Self::Read(r) => r.px,
            Self::Below { px } => px,
        }
    }

    /// The reading, where measured.
    pub fn read(self) -> Option<Read> {
        match self {
            Self::Read(r) => Some(r),
            Self::Below { .. } => None,
        }
    }
}

/// The width at each crossing of a crack (`None` where it has none), its
/// darkness over `contrast`, its walls as the camera's `blur` (where
/// known) spreads them.
pub fn widths(
    crossings: &[Option<Crossing>],
    contrast: Contrast,
    blur: Option<Blur>,
) -> Vec<Option<PointWidth>> {
    let widening = Blur::quarter_widening_px(blur);
    crossings
        .iter()
        .map(|c| {
            let c = c.as_ref()?;
            Some(PointWidth {
                at: c.at,
                across: c.across,
                width: width(c, &contrast, widening),
            })
        })
        .collect()
}

/// One crossing's width (see the module's doc), the blur widening its
/// walls by `widening` pixels at a quarter depth.
fn width(c: &Crossing, contrast: &Contrast, widening: f64) -> Width {
    let interior = contrast.share * c.surface;
    // How far the walls' slope leaves the opening uncertain: half the
    // difference between the two depths.
    let walls = c.walls.filter(|w| w.half >= WALLS_APART_PX).map(|w| {
        let px = (w.quarter - widening).max(w.half);
        (px, (w.quarter - w.half) / 2.0)
    });
    let resolved = walls.map_or(0.0, |(px, _)| {
        ramp(px, RESOLVED_PX, WALLS_ALONE_PX)
            * ramp(c.depth / interior.max(1e-9), WALLS_FROM_DEPTH, FULL_DEPTH)
    });
    if resolved == 0.0 && (c.darkness <= c.noise_limit || interior <= 0.0) {
        return Width::Below {
            px: c.noise_limit / interior.max(1.0),
        };
    }
    // The interior's darkness, or the profile's own where it is darker.
    let dark_px = c.darkness.max(0.0) / c.depth.max(interior);
    let (walls_px, spread) = walls.unwrap_or((0.0, 0.0));
    Width::Read(Read {
        px: resolved * walls_px + (1.0 - resolved) * dark_px,
        resolved,
        spread: resolved * spread,
        by_contrast: if c.depth < interior {
            1.0 - resolved
        } else {
            0.0
        },
    })
}

/// 0 at or below `from`, 1 at or above `to`, linear between.
fn ramp(v: f64, from: f64, to: f64) -> f64 {
    ((v - from) / (to - from)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crossing::{adjacency, crossings};
    use image::GrayImage;
    use postflight_core::mask::Mask;

    /// A straight crack `w` pixels wide at `angle` through the middle of a
    /// 64x64 image of brightness 150 with noise, drawn by the share of each
    /// pixel it covers (16x16 supersampling), its interior 85% darker, then
    /// blurred by a Gaussian lens of `blur` pixels (standard deviation; 0
    /// none).
    fn crack_image(
        w: f64,
        angle: f64,
        seed: u32,
        blur: f64,
    ) -> (GrayImage, Vec<Point2<f64>>, Vec<(u32, u32)>) {
        section_image(w, 0.0, angle, seed, blur)
    }

    /// [`crack_image`] with a section from a flat-bottomed slot (`vee` 0)
    /// to a V (1): the interior ramps to its full darkness over that share
    /// of the half width from each edge.
    fn section_image(
        w: f64,
        vee: f64,
        angle: f64,
        seed: u32,
        blur: f64,
    ) -> (GrayImage, Vec<Point2<f64>>, Vec<(u32, u32)>) {
        let (dx, dy) = (angle.cos(), angle.sin());
        let mut lit = vec![0.0; 64 * 64];
        for y in 0..64u32 {
            for x in 0..64u32 {
                let mut covered = 0.0;
                for sy in 0..16 {
                    for sx in 0..16 {
                        let (px, py) = (
                            f64::from(x) + (f64::from(sx) + 0.5) / 16.0 - 32.0,
                            f64::from(y) + (f64::from(sy) + 0.5) / 16.0 - 32.0,
                        );
                        let inside = w / 2.0 - (px * dy - py * dx).abs();
                        if inside >= 0.0 {
                            let ramp = vee * w / 2.0;
                            covered += (inside / ramp).min(1.0) / 256.0;
                        }
                    }
                }
                lit[(y * 64 + x) as usize] = 150.0 * (1.0 - 0.85 * covered);
            }
        }
        let lit = gaussian(&lit, 64, blur);
        let mut state = seed.wrapping_mul(2_654_435_761).max(1);
        let img = GrayImage::from_fn(64, 64, |x, y| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = f64::from(state % 7) - 3.0;
            image::Luma([(lit[(y * 64 + x) as usize] + noise)
                .round()
                .clamp(0.0, 255.0) as u8])
        });
        let centre: Vec<Point2<f64>> = (-20..=20)
            .map(|k| Point2::new(32.0 + f64::from(k) * dx, 32.0 + f64::from(k) * dy))
            .collect();
        let edges = (0..40).map(|k| (k, k + 1)).collect();
        (img, centre, edges)
    }

    /// A square image blurred by a Gaussian of `sigma` pixels, separably.
    fn gaussian(values: &[f64], n: usize, sigma: f64) -> Vec<f64> {
        if sigma <= 0.0 {
            return values.to_vec();
        }
        let r = (3.0 * sigma).ceil() as isize;
        let k: Vec<f64> = (-r..=r)
            .map(|i| (-(i as f64).powi(2) / (2.0 * sigma * sigma)).exp())
            .collect();
        let total: f64 = k.iter().sum();
        let pass = |v: &[f64], dx: isize, dy: isize| -> Vec<f64> {
            (0..n * n)
                .map(|i| {
                    let (x, y) = ((i % n) as isize, (i / n) as isize);
                    (-r..=r)
                        .map(|j| {
                            let (sx, sy) = (
                                (x + j * dx).clamp(0, n as isize - 1),
                                (y + j * dy).clamp(0, n as isize - 1),
                            );
                            v[sy as usize * n + sx as usize] * k[(j + r) as usize]
                        })
                        .sum::<f64>()
                        / total
                })
                .collect()
        };
        pass(&pass(values, 1, 0), 0, 1)
    }

    /// The blur a flight through a lens of `lens` pixels shows: its thin
    /// cracks' crossings.
    fn flight_blur(lens: f64) -> Option<Blur> {
        let thin: Vec<Crossing> = [(0.3, 0.3, 1), (0.2, 1.0, 2)]
            .into_iter()
            .flat_map(|(w, angle, seed)| {
                let (img, centre, edges) = crack_image(w, angle, seed, lens);
                crossings(&img, None, &centre, &adjacency(centre.len(), &edges))
            })
            .flatten()
            .collect();
        Blur::of(thin.iter(), 0.85)
    }

    fn measured(
        img: &GrayImage,
        mask: Option<&Mask>,
        centre: &[Point2<f64>],
        edges: &[(u32, u32)],
        lens: f64,
    ) -> Vec<Width> {
        let neighbours = adjacency(centre.len(), edges);
        let crossings = crossings(img, mask, centre, &neighbours);
        widths(&crossings, Contrast::given(0.85), flight_blur(lens))
            .into_iter()
            .flatten()
            .map(|p| p.width)
            .collect()
    }

    fn median_width(w: f64, angle: f64, blur: f64) -> (f64, Width) {
        let (img, centre, edges) = crack_image(w, angle, 7, blur);
        let found = measured(&img, None, &centre, &edges, blur);
        let mut px: Vec<f64> = found.iter().map(|p| p.px()).collect();
        px.sort_by(f64::total_cmp);
        (px[px.len() / 2], found[found.len() / 2])
    }

    #[test]
    fn widths_from_a_tenth_of_a_pixel_to_several_pixels_are_measured() {
        for (w, angle) in [
            (0.3, 0.2),
            (0.6, 1.0),
            (1.0, 0.0),
            (1.8, 0.7),
            (3.5, 0.3),
            (6.0, 1.2),
        ] {
            let (measured, kind) = median_width(w, angle, 0.0);
            let error = (measured - w).abs() / w;
            assert!(
                error < 0.15,
                "{w} px at {angle} rad measured {measured} ({kind:?})"
            );
        }
    }

    #[test]
    fn a_line_thinner_than_the_blur_is_read_from_its_darkness_not_its_blur() {
        // A lens of 0.85 px (the gauge readings' photos: 2 px at half
        // depth) spreads every line under 2 px to about 2 px at half depth.
        for (w, angle) in [(0.4, 0.3), (0.8, 1.0), (1.3, 0.0), (2.0, 0.6), (3.0, 0.2)] {
            let (measured, kind) = median_width(w, angle, 0.85);
            let error = (measured - w).abs();
            assert!(
                error < 0.15 * w.max(1.0),
                "{w} px at {angle} rad measured {measured} ({kind:?})"
            );
        }
        // Wide enough, its edges measure it.
        let (measured, kind) = median_width(7.0, 0.4, 0.85);
        assert!((measured - 7.0).abs() < 0.7, "{measured} ({kind:?})");
        assert!(
            matches!(kind, Width::Read(r) if r.resolved == 1.0),
            "{kind:?}"
        );
    }

    #[test]
    fn darkness_and_edges_meet_without_a_step() {
        // Widths from 2 to 7 px a quarter pixel apart: each measured wider
        // than the last by about the quarter pixel, however the reading
        // moves from darkness to edges.
        let mut last = None;
        let mut w = 2.0;
        while w <= 7.0 {
            let (measured, _) = median_width(w, 0.3, 0.85);
            if let Some(previous) = last {
                let step: f64 = measured - previous;
                assert!(
                    step > 0.0 && step < 0.6,
                    "{w} px: {previous} then {measured}"
                );
            }
            last = Some(measured);
            w += 0.25;
        }
    }

    #[test]
    fn a_v_section_reads_between_its_middle_and_its_opening() {
        // A V's walls slope from its opening: its half depth reads its
        // middle half, its quarter depth (less the blur's spread, which a
        // sloping wall barely has) more; its walls' slope is in the spread.
        for (w, angle) in [(8.0, 1.1), (11.0, 0.0)] {
            let (img, centre, edges) = section_image(w, 1.0, angle, 11, 0.6);
            let found = measured(&img, None, &centre, &edges, 0.6);
            let mid = found[found.len() / 2];
            let Width::Read(r) = mid else {
                panic!("{w} px V: {mid:?}");
            };
            assert!(r.px > 0.5 * w && r.px < w, "{w} px V: {mid:?}");
            assert!(r.resolved > 0.0 && r.spread > 0.3, "{w} px V: {mid:?}");
        }
    }

    /// The mask of a straight crack `w` pixels wide through the middle of a
    /// 64x64 frame at `angle`: the pixels whose centres it covers.
    fn crack_mask(w: f64, angle: f64) -> Mask {
        let (dx, dy) = (angle.cos(), angle.sin());
        let pixels = (0..64u32).flat_map(|y| (0..64u32).map(move |x| (x, y)));
        Mask::from_pixels(pixels.filter(|&(x, y)| {
            let (px, py) = (f64::from(x) + 0.5 - 32.0, f64::from(y) + 0.5 - 32.0);
            (px * dy - py * dx).abs() <= w / 2.0
        }))
        .unwrap()
    }

    #[test]
    fn the_detectors_mask_says_where_the_crack_is_not_how_wide() {
        // A model's mask two pixels outside each wall (its map blurred over
        // its receptive field), on cracks thinner and wider than the blur:
        // their own widths.
        for (w, angle) in [(1.0, 0.4), (2.5, 0.5), (3.5, 0.5), (9.0, 1.1), (14.0, 0.0)] {
            let (img, centre, edges) = crack_image(w, angle, 3, 0.85);
            let found = measured(
                &img,
                Some(&crack_mask(w + 4.0, angle)),
                &centre,
                &edges,
                0.85,
            );
            let mid = found[found.len() / 2];
            assert!(
                (mid.px() - w).abs() < 0.15 * w.max(1.0),
                "{w} px at {angle} rad measured {mid:?}"
            );
        }
        // A mask where the grey levels show no crack: not the mask's extent.
        let (img, centre, edges) = crack_image(0.0, 0.5, 9, 0.0);
        let found = measured(&img, Some(&crack_mask(7.0, 0.5)), &centre, &edges, 0.0);
        assert!(found.iter().all(|w| w.px() < 1.0), "{found:?}");
    }

    #[test]
    fn a_crack_fainter_than_the_noise_is_below_a_limit() {
        let (_, kind) = median_width(0.03, 0.4, 0.0);
        let Width::Below { px } = kind else {
            panic!("measured {kind:?}");
        };
        assert!(px > 0.03 && px < 1.0, "{px}");
    }
}

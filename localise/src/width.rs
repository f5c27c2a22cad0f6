//! A crack's width at each point of its centre line in one image, in
//! pixels, read from its crossing there ([`crate::crossing`]) against the
//! model of a slot blurred by the camera ([`crate::slot`]), two ways:
//!
//! - **across its walls**, where its opening is several blurs wide: the
//!   opening of the slot its walls' width at half depth means, the blur
//!   taken off. A blurred upright wall's half depth lies on the wall,
//!   whatever the crack's inside looks like (filled, stained, lit); the
//!   walls are found from outside in, within the detector's mask where it
//!   segments. (The mask only says where a crack is: a trained model's
//!   mask reproduces how the people who drew its training masks drew,
//!   wider than the opening a gauge reads; docs/evaluation.md.)
//! - **from its darkness**: the light it takes away, summed across it, over
//!   the contrast between the surface and a crack's interior. A line
//!   thinner than the blur never reaches its interior's darkness, and its
//!   half-depth width is the blur's; the sum keeps its width. The contrast
//!   is read where cracks resolve ([`crate::contrast`]), or is the
//!   crossing's own where that is darker.
//!
//! The two meet without a step: the walls' share grows with the opening
//! they read, in blurs, from none at [`RESOLVED_BLURS`] to all of it at
//! [`WALLS_ALONE_BLURS`] (and with how near its depth comes to the
//! interior's, where the crossing does not show its interior). Where the crossing is not a blurred slot (walls
//! that slope or darkened shoulders beside them, the walls and the
//! darkness reading apart beyond their uncertainties) it says so, and its
//! uncertainty covers both. Below what the image's noise lets the sum tell
//! from the surface, the width is only known to be narrower than that
//! limit.

use nalgebra::{Point2, Vector2};
use postflight_core::outputs::localise::WidthFit;

use crate::blur::Blur;
use crate::contrast::Contrast;
use crate::crossing::{Crossing, Walls};
use crate::slot;

/// Opening, in blurs, from which the walls count.
pub const RESOLVED_BLURS: f64 = 2.5;
/// Opening, in blurs, from which the walls alone are the width.
pub const WALLS_ALONE_BLURS: f64 = 5.0;
/// And in pixels at least, from which the walls count (all of it from
/// twice that): narrower, the pixel grid shapes a sharp camera's profile
/// more than its blur does, and the darkness, which the grid keeps, reads
/// it better.
const RESOLVED_MIN_PX: f64 = 2.0;
/// A crossing's depth, as a share of the interior's darkness, from which
/// its walls count where it does not show its interior (none below, all
/// at the interior's).
const WALLS_FROM_DEPTH: f64 = 0.5;
/// A blurred step's rise from a quarter to three quarters of its height,
/// in blurs: twice the normal quantile of 0.75.
const RISE_BLURS: f64 = 2.0 * QUARTER_OUT_BLURS;
/// The most a photo's blur may exceed the flight's and still be taken for
/// blur, as a share of it.
const MAX_BLUR_SHARE: f64 = 1.5;
/// How far out a blurred upright wall's quarter depth lies from its half
/// depth, in blurs: the normal quantile of 0.75.
const QUARTER_OUT_BLURS: f64 = 0.674_489_75;
/// Standard deviations apart beyond which the walls and the darkness
/// disagree.
const DISAGREE_SIGMAS: f64 = 2.0;
/// How far a point's reading is off for the pixel grid and the noise
/// alone, pixels (one standard deviation): the gauge readings' profiles
/// read to a quarter or a third of a pixel.
const POINT_PX: f64 = 0.3;

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
    /// How uncertain the crossing's shape leaves its width, pixels (one
    /// standard deviation): the walls' slope beyond the blur's, the blur's
    /// own uncertainty, and where the walls and the darkness disagree, half
    /// their difference.
    pub spread: f64,
    /// The share of the width its darkness gave over the interior's
    /// contrast (not the crossing's own depth), which the contrast's
    /// uncertainty scales.
    pub by_contrast: f64,
    /// How well the crossing fits a blurred slot.
    pub fit: WidthFit,
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
/// darkness over `contrast`, its walls as the camera's `blur` spreads them.
pub fn widths(
    crossings: &[Option<Crossing>],
    contrast: Contrast,
    blur: &Blur,
) -> Vec<Option<PointWidth>> {
    crossings
        .iter()
        .map(|c| {
            let c = c.as_ref()?;
            Some(PointWidth {
                at: c.at,
                across: c.across,
                width: width(c, &contrast, blur),
            })
        })
        .collect()
}

/// What a crossing's walls say: the slot's opening, its share of the
/// width, and how uncertain its shape and the blur leave it, pixels.
struct Walled {
    opening: f64,
    resolved: f64,
    spread: f64,
    sloping: bool,
}

/// The walls' reading of crossing `c` through `blur`, where they stand
/// apart (their half-depth width is more than the blur alone spreads a
/// line): the opening of the slot that half-depth width means. Their
/// share grows with that opening, in blurs, and, where the crossing does
/// not show its interior (a line in a broader shade, or one thinner than
/// the blur), with how near its depth comes to the interior's.
fn walled(c: &Crossing, interior: f64, blur: &Blur) -> Option<Walled> {
    let w = c.walls?;
    let sigma = own_blur(&w, blur);
    let opening = slot::opening(w.half, sigma)?;
    let from = (RESOLVED_BLURS * sigma).max(RESOLVED_MIN_PX);
    let to = (WALLS_ALONE_BLURS * sigma).max(2.0 * RESOLVED_MIN_PX);
    let by_width = ramp(opening, from, to);
    // However light its inside, a crossing that shows it is its walls'
    // once it is several blurs wide (a faint line's noise can make its
    // blur look like an interior, so not before its walls count half).
    let shown = if w.show_interior() {
        ramp(by_width, 0.5, 1.0)
    } else {
        0.0
    };
    let by_depth = ramp(c.depth / interior.max(1e-9), WALLS_FROM_DEPTH, 1.0).max(shown);
    let resolved = by_width * by_depth;
    // A quarter depth further out than the flight's blur puts it: sloping
    // walls, darkened shoulders or a blurrier photo, the opening uncertain
    // by the excess (a V's walls at half depth are half its opening, at a
    // quarter three quarters), however it is read.
    let flight = blur.sigma_px;
    let excess = (w.quarter - w.half - 2.0 * QUARTER_OUT_BLURS * flight).max(0.0);
    let by_blur = resolved * slot::opening_per_blur(w.half, sigma).abs() * blur.uncertainty_px;
    Some(Walled {
        opening,
        resolved,
        spread: excess.hypot(by_blur),
        sloping: excess > POINT_PX.max(flight / 2.0),
    })
}

/// The blur crossing walls `w` show: their rise (a blurred step's is 1.35
/// blurs), from the flight's `blur` (a line thinner than the blur rises
/// less) to [`MAX_BLUR_SHARE`] of it. A photo out of focus, or taken on
/// the move, is blurrier than the flight's median: a thin crack there
/// spreads into a broad, shallow band whose walls rise slowly; a broader
/// band than any such blur spreads is a crack that wide.
fn own_blur(w: &Walls, blur: &Blur) -> f64 {
    let sigma = blur.sigma_px;
    (w.rise / RISE_BLURS).clamp(sigma, MAX_BLUR_SHARE * sigma)
}

/// One crossing's width (see the module's doc).
fn width(c: &Crossing, contrast: &Contrast, blur: &Blur) -> Width {
    let interior = contrast.share * c.surface;
    let walls = walled(c, interior, blur);
    let resolved = walls.as_ref().map_or(0.0, |w| w.resolved);
    if resolved == 0.0 && (c.darkness <= c.noise_limit || interior <= 0.0) {
        return Width::Below {
            px: c.noise_limit / interior.max(1.0),
        };
    }
    // The interior's darkness, or the crossing's own where it is darker.
    let dark_px = c.darkness.max(0.0) / c.depth.max(interior).max(1e-9);
    let by_contrast = if c.depth < interior {
        1.0 - resolved
    } else {
        0.0
    };
    let Some(walls) = walls else {
        return Width::Read(Read {
            px: dark_px,
            resolved: 0.0,
            spread: 0.0,
            by_contrast,
            fit: WidthFit::Slot,
        });
    };
    // Where both say something, do they agree within their uncertainties?
    let apart = (walls.opening - dark_px).abs();
    let allowed = DISAGREE_SIGMAS
        * (POINT_PX.hypot(walls.spread)).hypot(contrast.spread * dark_px * by_contrast);
    let disagree = resolved > 0.0 && resolved < 1.0 && apart > allowed;
    let fit = if disagree {
        WidthFit::WallsAndDarknessDisagree
    } else if walls.sloping {
        WidthFit::SlopingWalls
    } else {
        WidthFit::Slot
    };
    let spread = if disagree {
        walls.spread.max(apart / 2.0)
    } else {
        walls.spread
    };
    Width::Read(Read {
        px: resolved * walls.opening + (1.0 - resolved) * dark_px,
        resolved,
        spread,
        by_contrast,
        fit,
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
    use crate::stats::median;
    use image::GrayImage;
    use postflight_core::mask::Mask;

    /// A straight crack through the middle of an `n` x `n` image of
    /// brightness 150 at `angle`, its cross-section `section` (the share of
    /// the surface's brightness it lacks at each offset across its line and
    /// each point along it, pixels), drawn by the share of each pixel each
    /// darkness covers (8 x 8 supersampling), blurred by a Gaussian lens of
    /// `lens` pixels (standard deviation; 0 none), with noise of up to 3
    /// grey levels either way; and its centre line.
    struct Drawn {
        img: GrayImage,
        centre: Vec<Point2<f64>>,
        edges: Vec<(u32, u32)>,
    }

    fn drawn(n: u32, angle: f64, lens: f64, seed: u32, section: impl Fn(f64, f64) -> f64) -> Drawn {
        let (dx, dy) = (angle.cos(), angle.sin());
        let mid = f64::from(n) / 2.0;
        let mut lit = vec![0.0; (n * n) as usize];
        for y in 0..n {
            for x in 0..n {
                let mut dark = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let px = f64::from(x) + (f64::from(sx) + 0.5) / 8.0 - mid;
                        let py = f64::from(y) + (f64::from(sy) + 0.5) / 8.0 - mid;
                        dark += section(px * dy - py * dx, px * dx + py * dy) / 64.0;
                    }
                }
                lit[(y * n + x) as usize] = 150.0 * (1.0 - dark);
            }
        }
        let lit = gaussian(&lit, n as usize, lens);
        let mut state = seed.wrapping_mul(2_654_435_761).max(1);
        let img = GrayImage::from_fn(n, n, |x, y| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = f64::from(state % 7) - 3.0;
            image::Luma([(lit[(y * n + x) as usize] + noise)
                .round()
                .clamp(0.0, 255.0) as u8])
        });
        let half = (n / 2 - n / 5) as i32;
        let centre: Vec<Point2<f64>> = (-half..=half)
            .map(|k| Point2::new(mid + f64::from(k) * dx, mid + f64::from(k) * dy))
            .collect();
        let edges = (0..centre.len() as u32 - 1).map(|k| (k, k + 1)).collect();
        Drawn { img, centre, edges }
    }

    /// A flat-bottomed slot `w` pixels wide, its interior 85% darker.
    fn slot(w: f64) -> impl Fn(f64, f64) -> f64 {
        move |s, _| if s.abs() <= w / 2.0 { 0.85 } else { 0.0 }
    }

    /// A straight crack `w` pixels wide through a 64 x 64 image, 85% dark.
    fn crack_image(w: f64, angle: f64, seed: u32, lens: f64) -> Drawn {
        drawn(64, angle, lens, seed, slot(w))
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

    fn crossed(d: &Drawn, mask: Option<&Mask>) -> Vec<Option<Crossing>> {
        crossings(
            &d.img,
            mask,
            &d.centre,
            &adjacency(d.centre.len(), &d.edges),
        )
    }

    /// The blur a flight through a lens of `lens` pixels shows: its thin
    /// cracks' crossings (or, where the lens spreads them into the noise,
    /// its wide cracks' walls).
    fn flight_blur(lens: f64) -> Blur {
        let mut seen: Vec<Crossing> = Vec::new();
        for (w, angle, seed) in [(0.3, 0.3, 1), (0.2, 1.0, 2)] {
            seen.extend(
                crossed(&crack_image(w, angle, seed, lens), None)
                    .into_iter()
                    .flatten(),
            );
        }
        for (w, angle, seed) in [(12.0, 0.2, 4), (14.0, 1.3, 5)] {
            let wide = drawn(160, angle, lens, seed, slot(w));
            seen.extend(crossed(&wide, None).into_iter().flatten());
        }
        Blur::of(seen.iter(), 0.85, None)
    }

    /// Its widths through the flight's blur, the flight's cracks 85% dark.
    fn measured(d: &Drawn, mask: Option<&Mask>, lens: f64) -> Vec<Width> {
        measured_through(d, mask, &flight_blur(lens))
    }

    fn measured_through(d: &Drawn, mask: Option<&Mask>, blur: &Blur) -> Vec<Width> {
        widths(&crossed(d, mask), Contrast::given(0.85), blur)
            .into_iter()
            .flatten()
            .map(|p| p.width)
            .collect()
    }

    /// The median width read, and the middle point's reading.
    fn median_of(found: &[Width]) -> (f64, Width) {
        let px = median(found.iter().map(|p| p.px()).collect()).unwrap();
        (px, found[found.len() / 2])
    }

    fn median_width(w: f64, angle: f64, lens: f64) -> (f64, Width) {
        median_of(&measured(&crack_image(w, angle, 7, lens), None, lens))
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
        // Wide enough, its walls measure it.
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

    /// The openings, lenses and angles the shapes below are drawn at: the
    /// blur from half a pixel to two, each opening six blurs or more (its
    /// walls resolved).
    const SHAPES: [(f64, f64, f64); 6] = [
        (5.0, 0.5, 0.3),
        (8.0, 0.5, 1.1),
        (9.0, 1.0, 0.0),
        (12.0, 1.0, 0.7),
        (14.0, 2.0, 0.4),
        (18.0, 2.0, 1.3),
    ];

    /// The lens [`SHAPES`] draws opening `w` through.
    fn lens_of(w: f64) -> f64 {
        SHAPES
            .iter()
            .find(|(o, _, _)| *o == w)
            .map_or(1.0, |(_, l, _)| *l)
    }

    /// Reads `section` (drawn for each of [`SHAPES`]'s openings) within a
    /// tenth of the opening, its median over the crack's crossings.
    fn reads_its_opening(what: &str, section: impl Fn(f64) -> Box<dyn Fn(f64, f64) -> f64>) {
        let blurs: Vec<(f64, Blur)> = [0.5, 1.0, 2.0].map(|l| (l, flight_blur(l))).into();
        for (seed, (w, lens, angle)) in SHAPES.into_iter().enumerate() {
            let blur = &blurs
                .iter()
                .find(|(l, _)| *l == lens)
                .expect("a lens of SHAPES")
                .1;
            let d = drawn(160, angle, lens, seed as u32 + 20, section(w));
            let (px, mid) = median_of(&measured_through(&d, None, blur));
            assert!(
                (px - w).abs() <= 0.1 * w,
                "{what}, {w} px through a {lens} px lens: {px:.2} px ({mid:?})"
            );
        }
    }

    #[test]
    fn broad_darkened_shoulders_and_chipped_edges_read_the_opening() {
        // Shoulders a quarter as dark as the crack, fading out over its own
        // width (8 px at most) either side: damp, dirt, a chamfer in shade.
        reads_its_opening("shoulders", |w| {
            Box::new(move |s, _| {
                let out = s.abs() - w / 2.0;
                if out <= 0.0 {
                    0.85
                } else {
                    (0.85 * 0.25 * (1.0 - out / w.min(8.0))).max(0.0)
                }
            })
        });
        // Chips out of either edge: every 9 to 20 px along it a bite up to
        // a third of the opening deep and twice that long, their floors
        // 40% as dark as the crack.
        reads_its_opening("chipped edges", |w| {
            Box::new(move |s, along| {
                if s.abs() <= w / 2.0 {
                    return 0.85;
                }
                let spacing = 9.0 + 11.0 * (0.5 + 0.5 * (0.37 * along.floor()).sin()).fract();
                let phase = (along / spacing).fract() - 0.5;
                let bite = (w / 3.0) * (1.0 - (2.0 * phase).powi(2)).max(0.0).sqrt();
                let side = if (along / spacing).floor() as i64 % 2 == 0 {
                    1.0
                } else {
                    -1.0
                };
                let chipped = s * side > 0.0 && s.abs() - w / 2.0 <= bite;
                if chipped { 0.85 * 0.4 } else { 0.0 }
            })
        });
    }

    #[test]
    fn a_crack_whose_inside_is_not_dark_reads_its_walls() {
        // Filled with lighter debris: dark only in the walls' shadow (as
        // wide as the blur spreads a step, and a pixel and a half more:
        // walls the photo shows), the fill between a third as dark,
        // mottled.
        reads_its_opening("filled", |w| {
            Box::new(move |s, along| {
                let inside = w / 2.0 - s.abs();
                let shadow = 1.5 + 1.5 * lens_of(w);
                if inside < 0.0 {
                    0.0
                } else if inside <= shadow {
                    0.85
                } else {
                    0.3 + 0.1 * (1.7 * s + 0.9 * along).sin()
                }
            })
        });
        // Stained light (efflorescence, rust run into it): the whole
        // interior only 40% dark, against a flight whose cracks are 85%.
        reads_its_opening("stained", |w| {
            Box::new(move |s, _| if s.abs() <= w / 2.0 { 0.4 } else { 0.0 })
        });
        // Lit from the side: dark in the shadow of one wall, lit towards
        // the other, where it is 40% as dark.
        reads_its_opening("lit from the side", |w| {
            Box::new(move |s, _| {
                if s.abs() > w / 2.0 {
                    0.0
                } else {
                    0.85 * (1.0 - 0.6 * (s / w + 0.5))
                }
            })
        });
    }

    #[test]
    fn a_v_section_reads_within_its_opening_and_says_its_walls_slope() {
        // A V's walls slope from its opening: every point of them rises as
        // steeply, its half depth is its middle half, and its quarter step
        // further out than the blur puts it says the opening may be wider.
        for (w, angle) in [(8.0, 1.1), (11.0, 0.0)] {
            let vee = move |s: f64, _| (0.85 * (1.0 - 2.0 * s.abs() / w)).max(0.0);
            let found = measured(&drawn(64, angle, 0.6, 11, vee), None, 0.6);
            let (px, mid) = median_of(&found);
            let Width::Read(r) = mid else {
                panic!("{w} px V: {mid:?}");
            };
            assert!(px > 0.45 * w && px < w, "{w} px V: {px} ({mid:?})");
            assert!(r.spread > 0.05 * w, "{w} px V: {mid:?}");
            assert_eq!(r.fit, WidthFit::SlopingWalls, "{w} px V: {mid:?}");
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
            let d = crack_image(w, angle, 3, 0.85);
            let found = measured(&d, Some(&crack_mask(w + 4.0, angle)), 0.85);
            let mid = found[found.len() / 2];
            assert!(
                (mid.px() - w).abs() < 0.15 * w.max(1.0),
                "{w} px at {angle} rad measured {mid:?}"
            );
        }
        // A mask where the grey levels show no crack: not the mask's extent.
        let d = crack_image(0.0, 0.5, 9, 0.0);
        let found = measured(&d, Some(&crack_mask(7.0, 0.5)), 0.0);
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

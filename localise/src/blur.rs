//! The camera's blur, as the flight's thinnest cracks show it. A line
//! much thinner than the blur is spread into the blur's own profile (the
//! lens's line-spread function, with the pixel's area and the profile's
//! sampling), so its width at half depth is the blur's, whatever its
//! opening: the median over the crossings that reach less than
//! [`THIN_DEPTH`] of the interior's darkness. Its walls read wider at a
//! quarter of their depth than at half by what the blur alone spreads
//! them, which a wider crack's quarter depth (a V or U section's opening,
//! [`crate::crossing::Walls`]) must not count as crack.

use crate::crossing::Crossing;
use crate::stats::median;

/// A crossing this shallow, as a share of the interior's darkness, is a
/// line thinner than the blur: one a third of the blur's width at half
/// depth reaches about a third.
const THIN_DEPTH: f64 = 0.35;
/// Fewest thin crossings that say a flight's blur.
const MIN_THIN: usize = 50;
/// A Gaussian's width at half its height over its standard deviation.
const FWHM_PER_SIGMA: f64 = 2.354_820_045;
/// How far out of a blurred step's edge its darkness falls to a quarter,
/// in standard deviations of the blur: the normal quantile of 0.75.
const QUARTER_OUT_SIGMAS: f64 = 0.674_489_75;

/// The camera's blur: a Gaussian of `sigma_px`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blur {
    pub sigma_px: f64,
}

impl Blur {
    /// The blur the thin crossings among `crossings` show, their darkness
    /// judged against an interior lacking `share` of the surface's
    /// brightness; `None` with too few.
    pub fn of<'a>(crossings: impl Iterator<Item = &'a Crossing>, share: f64) -> Option<Self> {
        let widths: Vec<f64> = crossings
            .filter(|c| c.depth < THIN_DEPTH * share * c.surface)
            .filter_map(|c| c.half)
            .collect();
        if widths.len() < MIN_THIN {
            return None;
        }
        Some(Self {
            sigma_px: median(widths)? / FWHM_PER_SIGMA,
        })
    }

    /// How much wider a crack's walls read at a quarter of its depth than
    /// at half for the blur alone, pixels: both walls, each spread a
    /// [`QUARTER_OUT_SIGMAS`] further out.
    pub fn quarter_widening_px(blur: Option<Self>) -> f64 {
        blur.map_or(0.0, |b| 2.0 * QUARTER_OUT_SIGMAS * b.sigma_px)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point2, Vector2};

    fn crossing(depth: f64, half: f64) -> Crossing {
        Crossing {
            at: Point2::origin(),
            across: Vector2::y(),
            surface: 150.0,
            depth,
            darkness: 0.0,
            noise_limit: 5.0,
            walls: Some(crate::crossing::Walls {
                half,
                quarter: 1.4 * half,
            }),
            half: Some(half),
            flat: false,
        }
    }

    #[test]
    fn thin_crossings_say_the_blur_and_wide_ones_do_not() {
        // 60 thin lines 2 px wide at half depth, 40 wide cracks 6 px wide.
        let mut crossings: Vec<Crossing> = (0..60).map(|_| crossing(30.0, 2.0)).collect();
        crossings.extend((0..40).map(|_| crossing(120.0, 6.0)));
        let blur = Blur::of(crossings.iter(), 0.85).unwrap();
        assert!((blur.sigma_px - 2.0 / FWHM_PER_SIGMA).abs() < 1e-9);
        assert!((Blur::quarter_widening_px(Some(blur)) - 1.1457).abs() < 1e-3);
        // Too few thin ones: unknown, and nothing is taken off.
        assert_eq!(Blur::of(crossings[40..].iter(), 0.85), None);
        assert_eq!(Blur::quarter_widening_px(None), 0.0);
    }
}

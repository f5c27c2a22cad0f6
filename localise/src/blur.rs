//! The camera's blur, as the flight's own photos show it, a Gaussian's
//! standard deviation in pixels (the lens, the sensor's pixels, focus and
//! the profile's sampling together), and where it came from:
//!
//! - **thin lines**: a line much thinner than the blur is spread into the
//!   blur's own profile (its line-spread function), so its width at half
//!   depth is the blur's, whatever its opening: the median over the
//!   crossings that reach less than [`THIN_DEPTH`] of the interior's
//!   darkness;
//! - **crack walls**: a resolved crack's walls are steps, spread by the
//!   blur into its edge-spread function (as the slanted-edge method of
//!   ISO 12233 reads a lens): each wall rises from a quarter to three
//!   quarters of the crack's depth over 1.35 of the blur's sigma; the
//!   median over flat-bottomed crossings wide enough for the two walls to
//!   be apart;
//! - **the setting** (`[localise] camera_blur_px`), the camera's blur as
//!   declared (from its lens and sensor, or a test chart);
//! - **unknown**: none of these, so a middling blur, uncertain by half of
//!   it, which the widths of cracks about as wide as the blur carry in
//!   their uncertainty.

use postflight_core::outputs::localise::BlurSource;

use crate::crossing::Crossing;
use crate::slot::THIN_FWHM_SIGMAS;
use crate::stats::{median, robust_sigma};

/// A crossing this shallow, as a share of the interior's darkness, is a
/// line thinner than the blur: one a third of the blur's width at half
/// depth reaches about a third.
const THIN_DEPTH: f64 = 0.35;
/// Fewest crossings that say a flight's blur.
const MIN_SAMPLES: usize = 50;
/// A Gaussian edge's rise from a quarter to three quarters of its step,
/// in standard deviations: twice the normal quantile of 0.75.
const RISE_SIGMAS: f64 = 1.348_979_5;
/// Walls this many of their own blurs apart or more each show their own
/// edge (the other's blur adds under a hundredth there).
const WALLS_APART_BLURS: f64 = 5.0;
/// How far off a measured blur may be besides its samples' scatter, as a
/// share of it: a thin line's own opening widens it (by 4% for a line half
/// the blur wide), a wall's slope widens its rise.
const THIN_SYSTEMATIC: f64 = 0.05;
const WALLS_SYSTEMATIC: f64 = 0.15;
/// A declared blur's uncertainty, as a share of it.
const SETTING_SHARE: f64 = 0.1;
/// The blur taken where nothing says it, pixels, and how far off it may
/// be: cameras flown for inspection blur by half a pixel to two.
const UNKNOWN_SIGMA_PX: f64 = 1.0;
const UNKNOWN_UNCERTAINTY_PX: f64 = 0.5;

/// The camera's blur: a Gaussian of `sigma_px`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blur {
    pub sigma_px: f64,
    /// How far off `sigma_px` may be, pixels (one standard deviation).
    pub uncertainty_px: f64,
    pub from: BlurSource,
    /// Crossings it was read from (0 for the setting or unknown).
    pub samples: usize,
}

impl Blur {
    /// The blur `crossings` show, their darkness judged against an
    /// interior lacking `share` of the surface's brightness: their thin
    /// lines' or their crack walls' (the more of them), else `given`, else
    /// unknown.
    pub fn of<'a>(
        crossings: impl Iterator<Item = &'a Crossing> + Clone,
        share: f64,
        given: Option<f64>,
    ) -> Self {
        // Where both say it, the one more crossings say: a few shallow
        // stretches of a flight of resolved cracks are not its thin lines.
        let thin = Self::of_thin_lines(crossings.clone(), share);
        let walls = Self::of_walls(crossings);
        [thin, walls]
            .into_iter()
            .flatten()
            .max_by_key(|b| b.samples)
            .or_else(|| given.map(Self::declared))
            .unwrap_or(Self::UNKNOWN)
    }

    /// Where nothing says the blur.
    pub const UNKNOWN: Self = Self {
        sigma_px: UNKNOWN_SIGMA_PX,
        uncertainty_px: UNKNOWN_UNCERTAINTY_PX,
        from: BlurSource::Unknown,
        samples: 0,
    };

    /// A blur the camera is declared to have, pixels.
    pub fn declared(sigma_px: f64) -> Self {
        Self {
            sigma_px,
            uncertainty_px: SETTING_SHARE * sigma_px,
            from: BlurSource::Setting,
            samples: 0,
        }
    }

    /// Known exactly (a test's lens).
    pub fn exact(sigma_px: f64) -> Self {
        Self {
            uncertainty_px: 0.0,
            ..Self::declared(sigma_px)
        }
    }

    fn of_thin_lines<'a>(
        crossings: impl Iterator<Item = &'a Crossing>,
        share: f64,
    ) -> Option<Self> {
        let sigmas: Vec<f64> = crossings
            .filter(|c| c.sure && c.depth < THIN_DEPTH * share * c.surface)
            .filter_map(|c| Some(c.half? / THIN_FWHM_SIGMAS))
            .collect();
        Self::measured(sigmas, BlurSource::ThinLines, THIN_SYSTEMATIC)
    }

    fn of_walls<'a>(crossings: impl Iterator<Item = &'a Crossing>) -> Option<Self> {
        let sigmas: Vec<f64> = crossings
            .filter(|c| c.flat)
            .filter_map(|c| c.walls)
            .filter(|w| w.rise > 0.0)
            .map(|w| (w.rise / RISE_SIGMAS, w.half))
            .filter(|(sigma, half)| *half >= WALLS_APART_BLURS * sigma)
            .map(|(sigma, _)| sigma)
            .collect();
        Self::measured(sigmas, BlurSource::CrackWalls, WALLS_SYSTEMATIC)
    }

    /// The median of `sigmas`, with the standard error of that median and
    /// a `systematic` share of it; `None` with too few.
    fn measured(sigmas: Vec<f64>, from: BlurSource, systematic: f64) -> Option<Self> {
        if sigmas.len() < MIN_SAMPLES {
            return None;
        }
        let samples = sigmas.len();
        let sigma_px = median(sigmas.clone())?;
        let scatter = robust_sigma(sigmas.iter().map(|s| (s - sigma_px).abs()).collect())?;
        let statistical = 1.25 * scatter / (samples as f64).sqrt();
        Some(Self {
            sigma_px,
            uncertainty_px: statistical.hypot(systematic * sigma_px),
            from,
            samples,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crossing::Walls;
    use nalgebra::{Point2, Vector2};

    fn crossing(depth: f64, half: f64, rise: f64, flat: bool) -> Crossing {
        Crossing {
            at: Point2::origin(),
            across: Vector2::y(),
            surface: 150.0,
            noise: 2.0,
            depth,
            darkness: 0.0,
            noise_limit: 5.0,
            walls: Some(Walls {
                half,
                quarter: 1.4 * half,
                three_quarters: 0.9 * half,
                rise,
            }),
            half: Some(half),
            sure: true,
            flat,
        }
    }

    #[test]
    fn thin_lines_say_the_blur_else_crack_walls_else_the_setting() {
        // 70 thin lines 2 px wide at half depth, 60 wide cracks 8 px wide
        // whose walls rise over 1.1 px: the thin lines, the more.
        let mut crossings: Vec<Crossing> =
            (0..70).map(|_| crossing(30.0, 2.0, 0.9, false)).collect();
        crossings.extend((0..60).map(|_| crossing(120.0, 8.0, 1.1, true)));
        let blur = Blur::of(crossings.iter(), 0.85, None);
        assert_eq!(blur.from, BlurSource::ThinLines);
        assert!((blur.sigma_px - 2.0 / THIN_FWHM_SIGMAS).abs() < 1e-9);
        // Without the thin ones: their walls'.
        let walls = Blur::of(crossings[70..].iter(), 0.85, Some(0.7));
        assert_eq!((walls.from, walls.samples), (BlurSource::CrackWalls, 60));
        assert!((walls.sigma_px - 1.1 / RISE_SIGMAS).abs() < 1e-9);
        // Walls too close to show their own edges say nothing.
        let close: Vec<Crossing> = (0..60).map(|_| crossing(120.0, 3.0, 1.1, true)).collect();
        let given = Blur::of(close.iter(), 0.85, Some(0.7));
        assert_eq!((given.from, given.sigma_px), (BlurSource::Setting, 0.7));
        let unknown = Blur::of(close[..10].iter(), 0.85, None);
        assert_eq!(unknown, Blur::UNKNOWN);
        assert!(unknown.uncertainty_px >= 0.5 * unknown.sigma_px);
    }
}

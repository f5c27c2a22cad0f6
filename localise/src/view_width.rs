//! A crack's width as one view measures it, from its points' widths each
//! with its footing on the surface: its median, and its widest stretch,
//! the width its condition state follows, read as an inspector would put a
//! gauge on it: the median of a few consecutive points ([`STRETCH_STEPS`]
//! either side), not one point's outlier. A stretch counts as wider than
//! the crack only where it is surely so (by more than [`SURELY`] of its
//! own standard errors above the crack's median); a crack with none is as
//! wide along its length, and its widest is its median. A stretch by a
//! fork is not the crack's widest: there two lines run within a blur of
//! each other and their darkness adds up.

use nalgebra::Point3;
use postflight_core::kind::Counts;
use postflight_core::outputs::localise::{WidestStretch, WidthFit, WidthMethod, WidthRecord};

use crate::contrast::Contrast;
use crate::crossing::within;
use crate::stats::{median, robust_sigma};
use crate::width::{PointWidth, Read, Width};

/// Centre-line points either side of a point that make its stretch.
const STRETCH_STEPS: usize = 4;
/// Fewest measured points of a stretch.
const MIN_STRETCH: usize = 5;
/// Standard errors by which a stretch must pass the crack's median to be
/// wider: with 50 or so independent stretches along a crack of one width,
/// the widest of them passes 2 in two flights of three, 3 in one of fifteen.
const SURELY: f64 = 3.0;
/// Steps along the line from a fork (a point with three neighbours or
/// more) within which no stretch is the widest: a stretch's own length
/// either side, so none reaches within [`STRETCH_STEPS`] of it. On the
/// simulated tower at 4 mm a pixel, the widest of 1 px cracks read 2 px
/// at 7 steps from a fork, the branch still unresolved beside the stem.
const FORK_STEPS: usize = 2 * STRETCH_STEPS;
/// How far a view's width is off for the pixel grid alone, pixels (one
/// standard deviation): on the gauge readings (docs/evaluation.md) widths
/// read from the profiles are off by a quarter to a third of a pixel.
const PIXEL_UNCERTAINTY_PX: f64 = 1.0 / 3.0;
/// The walls' share from which a stretch is read across its walls, and
/// below which (one less it) from its darkness.
const MOSTLY: f64 = 0.9;

/// Where a point of the crack lies on the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footing {
    /// Millimetres on the surface per image pixel across the crack there.
    pub mm_per_px: f64,
    /// The point on the surface, world frame.
    pub at: Point3<f64>,
}

/// The view's width from `points` (a crack's widths along its centre line,
/// `None` where unmeasured) and their `footing` (`None` where off the
/// surface), neighbours along the line `neighbours`, its darkness read
/// over `contrast`; `None` with no point on the surface.
pub fn view_width(
    points: &[Option<PointWidth>],
    footing: &[Option<Footing>],
    neighbours: &[Vec<usize>],
    contrast: &Contrast,
) -> Option<WidthRecord> {
    let on: Vec<(usize, Width, Footing)> = points
        .iter()
        .zip(footing)
        .enumerate()
        .filter_map(|(i, (p, f))| Some((i, p.as_ref()?.width, (*f)?)))
        .collect();
    let mm_per_px = median(on.iter().map(|(_, _, f)| f.mm_per_px).collect())?;
    let mm: Vec<Option<f64>> = {
        let mut mm = vec![None; points.len()];
        for (i, w, f) in &on {
            if let Width::Read(r) = w {
                mm[*i] = Some(r.px * f.mm_per_px);
            }
        }
        mm
    };
    let measured: Vec<f64> = mm.iter().flatten().copied().collect();
    let Some(median_mm) = median(measured.clone()) else {
        let limits = on.iter().filter_map(|(_, w, f)| match w {
            Width::Below { px } => Some(px * f.mm_per_px),
            Width::Read(_) => None,
        });
        return Some(WidthRecord {
            narrower_than_mm: median(limits.collect()),
            mm_per_px,
            ..WidthRecord::default()
        });
    };
    // A point is good to a third of a pixel at best: steadier neighbours
    // are the same pixels read again.
    let noise = point_noise(&mm, neighbours).max(PIXEL_UNCERTAINTY_PX * mm_per_px);
    let widest =
        widest_stretch(&mm, neighbours, noise).filter(|s| s.mm - s.sigma * SURELY > median_mm);
    // The points the widest is read from: its stretch, or the whole crack.
    let (width_mm, sigma_mm, read): (f64, f64, Vec<usize>) = match &widest {
        Some(s) => (s.mm, s.sigma, s.points.clone()),
        None => (
            median_mm,
            median_error(noise, measured.len()),
            (0..mm.len()).filter(|i| mm[*i].is_some()).collect(),
        ),
    };
    let reads: Vec<(Read, f64)> = read
        .iter()
        .filter_map(|i| Some((points[*i]?.width.read()?, footing[*i]?.mm_per_px)))
        .collect();
    let mean = |f: &dyn Fn(&(Read, f64)) -> f64| {
        reads.iter().map(f).sum::<f64>() / reads.len().max(1) as f64
    };
    let resolved = mean(&|(r, _)| r.resolved);
    let by_contrast = mean(&|(r, _)| r.by_contrast);
    // The pixel grid's share, the walls' slope (quarter against half
    // depth), the contrast its darkness was divided by, and the stretch's
    // noise.
    let pixel = PIXEL_UNCERTAINTY_PX * mm_per_px;
    let slope = mean(&|(r, scale)| r.spread * scale);
    let from_contrast = by_contrast * width_mm * contrast.spread;
    let uncertainty_mm = [pixel, slope, from_contrast, sigma_mm]
        .iter()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt();
    let method = if resolved >= MOSTLY {
        WidthMethod::Walls
    } else if resolved <= 1.0 - MOSTLY {
        WidthMethod::Darkness
    } else {
        WidthMethod::WallsAndDarkness
    };
    let darkness = method != WidthMethod::Walls;
    let fit = fit_of(reads.iter().map(|(r, _)| r.fit));
    Some(WidthRecord {
        max_mm: Some(width_mm),
        median_mm: Some(median_mm),
        uncertainty_mm: Some(uncertainty_mm),
        narrower_than_mm: None,
        mm_per_px,
        method: Some(method),
        contrast_from: darkness.then_some(contrast.from),
        interior_darkness: darkness.then_some(contrast.share),
        fit: Some(fit),
        widest: widest.and_then(|s| {
            Some(WidestStretch {
                at: footing[s.middle]?.at.coords.into(),
                along_m: None,
            })
        }),
    })
}

/// How a stretch's points fit a blurred slot: the misfit half of them or
/// more show (the commoner of the two where both do), else a slot.
fn fit_of(fits: impl Iterator<Item = WidthFit>) -> WidthFit {
    let counts: Counts<WidthFit> = fits.collect();
    let total = counts.total();
    [WidthFit::WallsAndDarknessDisagree, WidthFit::SlopingWalls]
        .into_iter()
        .filter(|f| 2 * counts.get(*f) >= total && counts.get(*f) > 0)
        .max_by_key(|f| counts.get(*f))
        .unwrap_or(WidthFit::Slot)
}

/// A stretch of the crack: its points, the middle one, its median width
/// and that median's standard error, millimetres.
struct Stretch {
    points: Vec<usize>,
    middle: usize,
    mm: f64,
    sigma: f64,
}

/// The stretch whose median is widest, of those away from forks.
fn widest_stretch(mm: &[Option<f64>], neighbours: &[Vec<usize>], noise: f64) -> Option<Stretch> {
    let mut by_fork = vec![false; mm.len()];
    for fork in (0..mm.len()).filter(|i| neighbours[*i].len() >= 3) {
        for j in within(neighbours, fork, FORK_STEPS) {
            by_fork[j] = true;
        }
    }
    (0..mm.len())
        .filter(|i| mm[*i].is_some() && !by_fork[*i])
        .filter_map(|i| {
            let points: Vec<usize> = within(neighbours, i, STRETCH_STEPS)
                .into_iter()
                .filter(|j| mm[*j].is_some())
                .collect();
            if points.len() < MIN_STRETCH {
                return None;
            }
            let width = median(points.iter().filter_map(|j| mm[*j]).collect())?;
            Some(Stretch {
                sigma: median_error(noise, points.len()),
                points,
                middle: i,
                mm: width,
            })
        })
        .max_by(|a, b| a.mm.total_cmp(&b.mm))
}

/// The standard error of the median of `n` points each off by `noise`
/// (one standard deviation): 1.25 of the mean's.
fn median_error(noise: f64, n: usize) -> f64 {
    1.25 * noise / (n as f64).sqrt()
}

/// How far one point's width scatters about its neighbours', millimetres
/// (one standard deviation): the robust spread of the differences between
/// neighbours over the root of 2, so a crack that widens along its length
/// is not taken for noise.
fn point_noise(mm: &[Option<f64>], neighbours: &[Vec<usize>]) -> f64 {
    let differences: Vec<f64> = (0..mm.len())
        .flat_map(|i| neighbours[i].iter().map(move |j| (i, *j)))
        .filter(|(i, j)| i < j)
        .filter_map(|(i, j)| Some((mm[i]? - mm[j]?).abs()))
        .collect();
    robust_sigma(differences).map_or(0.0, |d| d / std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point2, Vector2};

    /// A crack's points: their widths, footing and neighbours.
    type Line = (
        Vec<Option<PointWidth>>,
        Vec<Option<Footing>>,
        Vec<Vec<usize>>,
    );

    /// A straight centre line of `widths` (px, `None` unmeasured), 1 mm per
    /// pixel, each point a millimetre further along x.
    fn line(widths: &[Option<f64>]) -> Line {
        let points = widths
            .iter()
            .enumerate()
            .map(|(i, w)| {
                Some(PointWidth {
                    at: Point2::new(i as f64, 0.0),
                    across: Vector2::y(),
                    width: match w {
                        Some(px) => Width::Read(Read {
                            px: *px,
                            resolved: 0.0,
                            spread: 0.0,
                            by_contrast: 1.0,
                            fit: WidthFit::Slot,
                        }),
                        None => Width::Below { px: 0.5 },
                    },
                })
            })
            .collect();
        let footing = (0..widths.len())
            .map(|i| {
                Some(Footing {
                    mm_per_px: 1.0,
                    at: Point3::new(i as f64 / 1000.0, 0.0, 0.0),
                })
            })
            .collect();
        let n = widths.len();
        let neighbours = (0..n)
            .map(|i| {
                [i.checked_sub(1), (i + 1 < n).then_some(i + 1)]
                    .into_iter()
                    .flatten()
                    .collect()
            })
            .collect();
        (points, footing, neighbours)
    }

    fn noisy(n: usize, width: impl Fn(usize) -> f64) -> Vec<Option<f64>> {
        // Independent noise, uniform within 0.15 px either side.
        let mut state: u32 = 2_463_534_242;
        (0..n)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                Some(width(i) + 0.3 * (f64::from(state) / f64::from(u32::MAX) - 0.5))
            })
            .collect()
    }

    #[test]
    fn a_crack_of_one_width_is_as_wide_as_its_median_and_one_outlier_is_not_its_widest() {
        let mut widths = noisy(200, |_| 1.0);
        widths[120] = Some(3.0);
        let (points, footing, neighbours) = line(&widths);
        let w = view_width(&points, &footing, &neighbours, &Contrast::given(0.85)).unwrap();
        assert!((w.max_mm.unwrap() - 1.0).abs() < 0.05, "{w:?}");
        assert_eq!(w.max_mm, w.median_mm);
        assert!(w.widest.is_none());
        assert_eq!(w.method, Some(WidthMethod::Darkness));
        assert_eq!(
            w.contrast_from,
            Some(postflight_core::outputs::localise::ContrastSource::Setting)
        );
    }

    #[test]
    fn a_wider_stretch_is_the_widest_and_says_where_it_is() {
        // 1 mm wide, 1.6 mm over points 140 to 160.
        let widths = noisy(200, |i| if (140..=160).contains(&i) { 1.6 } else { 1.0 });
        let (points, footing, neighbours) = line(&widths);
        let w = view_width(&points, &footing, &neighbours, &Contrast::given(0.85)).unwrap();
        assert!((w.max_mm.unwrap() - 1.6).abs() < 0.1, "{w:?}");
        assert!((w.median_mm.unwrap() - 1.0).abs() < 0.05, "{w:?}");
        let at = w.widest.unwrap().at;
        assert!((140.0..=160.0).contains(&(at[0] * 1000.0)), "{at:?}");
        // Its uncertainty: a third of a pixel, and the darkness's share of
        // the contrast's 8% of 1.6 mm, and the stretch's own.
        let u = w.uncertainty_mm.unwrap();
        assert!(u > (1.0f64 / 9.0 + 0.128 * 0.128).sqrt() && u < 0.5, "{u}");
    }

    #[test]
    fn a_stretch_by_a_fork_is_not_the_widest() {
        // 1 mm wide, with a branch leaving point 100 and read twice as
        // wide (two lines unresolved) from 94 to 100.
        let widths = noisy(200, |i| if (94..=100).contains(&i) { 2.0 } else { 1.0 });
        let (points, footing, mut neighbours) = line(&widths[..180]);
        let (more, more_footing, _) = line(&widths[180..]);
        let (points, footing) = ([points, more].concat(), [footing, more_footing].concat());
        neighbours.extend((180..200).map(|i| {
            let before = if i == 180 { 100 } else { i - 1 };
            [Some(before), (i < 199).then_some(i + 1)]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
        }));
        neighbours[100].push(180);
        let w = view_width(&points, &footing, &neighbours, &Contrast::given(0.85)).unwrap();
        assert!(w.widest.is_none(), "{w:?}");
        assert!((w.max_mm.unwrap() - 1.0).abs() < 0.05, "{w:?}");
    }

    #[test]
    fn a_crack_below_resolution_is_narrower_than_its_limit() {
        let (points, footing, neighbours) = line(&[None; 20]);
        let w = view_width(&points, &footing, &neighbours, &Contrast::given(0.85)).unwrap();
        assert_eq!((w.max_mm, w.narrower_than_mm), (None, Some(0.5)));
    }
}

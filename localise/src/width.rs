//! A crack's width in one image, across its centre line, in pixels.
//!
//! Along the centre line, each point is measured across the crack (on the
//! normal of the line's local direction, at sub-pixel steps). The grey
//! levels are sampled across it, out to a reach that grows with the crack
//! (its mask, or its own dark extent) so the surface is read outside it.
//!
//! - Where the detector segments the crack, its mask spans several pixels
//!   there and the profile shows a dark line with its edges apart: a blend of
//!   the mask's extent across the line and the profile's width at half
//!   depth, the mask's share growing with the crack. A trained model marks
//!   a wide crack's full width (ragged and spalled edges, V and U sections,
//!   debris in it) as the people who drew its training masks did, which
//!   the half depth misses; round a crack a few pixels wide its mask is a
//!   pixel too wide each side, and the half depth reads it.
//!
//! Elsewhere (the mask alone, with no dark line in the grey levels, marks
//! a stain or the surface's texture) the profile alone measures:
//!
//! - where the crack spans several pixels with a flat bottom, its full
//!   width at half its depth (the edges found to a fraction of a pixel by
//!   interpolation), as a mask of the crack's pixels would give it;
//! - where it is wider than the blur without one (a V or U section, in a
//!   stretch of such points), its full width at a quarter of its depth;
//! - where it is thinner, its *darkness integral*: a crack `w` pixels wide
//!   whose interior lacks `C` grey levels of the surface's brightness darkens
//!   the profile by `w * C` summed across it, however the lens, the sensor
//!   and motion blur spread it, so `w` = integral / `C`. `C` is read from the
//!   crack's own resolved stretches where it has any, else given.
//!
//! Below what the image's noise lets the integral tell from the surface,
//! the width is only known to be narrower than that limit.

use image::GrayImage;
use nalgebra::{Point2, Vector2};
use postflight_core::mask::Mask;

use crate::stats::median;

/// Samples per pixel across the crack.
const STEP: f64 = 0.25;
/// Centre-line pixels on either side that give the line's local direction.
const DIRECTION_REACH: usize = 3;
/// A point is resolved (measured at half depth) this many pixels wide or more.
pub const RESOLVED_PX: f64 = 3.0;
/// A crack has resolved stretches when this share of its points (and five
/// at least) are resolved.
const MIN_RESOLVED_SHARE: f64 = 0.1;

/// A crack's width at one centre-line pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointWidth {
    /// The centre-line pixel.
    pub at: Point2<f64>,
    /// Unit normal of the centre line there, image pixels.
    pub across: Vector2<f64>,
    pub width: Width,
}

/// What the profile across the crack tells of its width.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Width {
    /// The detector's mask spans the crack and the profile confirms it:
    /// their blend (see [`MASK_FROM_PX`]), pixels, and half the difference
    /// between the two.
    Masked { px: f64, spread: f64 },
    /// Wide enough to see both edges, with a flat bottom: full width at
    /// half depth, pixels.
    Resolved { px: f64, depth: f64 },
    /// Wider than the blur with sloping flanks and no mask spanning it:
    /// full width at a quarter of its depth (see [`sloped`]), pixels, and
    /// half the difference from its width at half depth (how far its
    /// flanks leave the opening uncertain).
    Sloped { px: f64, spread: f64 },
    /// Thinner: the darkness integral over the crack's depth, pixels.
    Integrated { px: f64 },
    /// Fainter than the noise: narrower than this many pixels.
    Below { px: f64 },
}

impl Width {
    /// The width, or the bound it is below, in pixels.
    pub fn px(self) -> f64 {
        match self {
            Self::Masked { px, .. }
            | Self::Resolved { px, .. }
            | Self::Sloped { px, .. }
            | Self::Integrated { px }
            | Self::Below { px } => px,
        }
    }

    /// How uncertain the crack's shape leaves this width, pixels: where a
    /// mask and the profile, or a sloped profile's levels, disagree.
    pub fn spread(self) -> Option<f64> {
        match self {
            Self::Masked { spread, .. } | Self::Sloped { spread, .. } => Some(spread),
            _ => None,
        }
    }

    /// Whether it spans the crack (both edges seen), not a sum or a bound.
    pub fn spans(self) -> bool {
        !matches!(self, Self::Integrated { .. } | Self::Below { .. })
    }
}

/// The profile across the crack at one centre-line pixel.
struct Profile {
    /// Offsets across the line, pixels, `STEP` apart, centred on 0.
    t: Vec<f64>,
    /// Darkness below the surface at each offset, grey levels.
    dark: Vec<f64>,
    /// The surface's brightness and noise (robust sigma), grey levels.
    surface: f64,
    noise: f64,
}

/// The width at each of `centre` (a traced centre line, frame pixels, with
/// `edges` joining neighbours), measured in `mask` (the detector's crack
/// pixels, where it segments) and `gray`. `interior` is the share of the
/// surface's brightness a crack's interior lacks, used where the crack has
/// no resolved stretch to read it from.
pub fn widths(
    gray: &GrayImage,
    mask: Option<&Mask>,
    centre: &[Point2<f64>],
    edges: &[(u32, u32)],
    interior: f64,
) -> Vec<PointWidth> {
    let neighbours = adjacency(centre.len(), edges);
    let inside = mask.map(Inside::of);
    let profiles: Vec<Option<(Vector2<f64>, Across)>> = (0..centre.len())
        .map(|i| {
            let across = normal(centre, &neighbours, i)?;
            let masked = inside.as_ref().and_then(|m| m.width(centre[i], across));
            // The profile reaches well past the crack: past its mask's
            // extent, or (without one) past its own dark extent.
            let reach = masked.map_or(REACH, |px| REACH.max(1.5 * px + 4.0));
            let profile = reached(gray, centre[i], across, reach)?;
            let sloped = sloped(&profile);
            Some((
                across,
                Across {
                    masked,
                    profile,
                    sloped,
                },
            ))
        })
        .collect();
    // The crack's interior darkness: from its resolved stretches, if it
    // has some; a few scattered points that look resolved are something
    // else (a bend the profile runs along, a crossing), and would scale
    // every thin point's width by a wrong darkness. Sloped points likewise
    // count only in a crack with stretches of them: a few scattered ones
    // would make a thin crack's widest. The stretches are counted off any
    // mask (a thin mask's points count for neither; counting them too made
    // the repeat inspection call two unchanged cracks widened).
    let depths: Vec<f64> = profiles
        .iter()
        .flatten()
        .filter_map(|(_, a)| resolved(&a.profile).map(|(_, depth)| depth / a.profile.surface))
        .collect();
    let measured = profiles.iter().flatten().count();
    let stretches = |n: usize| n as f64 >= (MIN_RESOLVED_SHARE * measured as f64).max(5.0);
    let has_stretches = stretches(depths.len());
    let slopes = stretches(
        profiles
            .iter()
            .flatten()
            .filter(|(_, a)| a.masked.is_none() && a.sloped.is_some())
            .count(),
    );
    let whole = Whole {
        share: if has_stretches {
            median(depths).unwrap_or(interior)
        } else {
            interior
        },
        has_stretches,
        slopes,
    };
    let points: Vec<Option<PointWidth>> = profiles
        .into_iter()
        .zip(centre)
        .map(|(p, at)| {
            let (across, a) = p?;
            Some(PointWidth {
                at: *at,
                across,
                width: a.measure(&whole),
            })
        })
        .collect();
    along_the_line(points, &neighbours)
}

/// Each point measured across both edges by the mask or sloping flanks,
/// its width the median of those so measured within [`SMOOTH_STEPS`]
/// centre-line pixels of it: a crack's width is a stretch's, and one
/// crossing of a real crack is noisy (a speck of aggregate, a ragged edge,
/// a bend the normal misjudges), which its widest point would otherwise
/// pick out. Points with a flat bottom or a darkness integral keep their
/// own (the one is already steady, the other a sum across the crack).
fn along_the_line(points: Vec<Option<PointWidth>>, neighbours: &[Vec<usize>]) -> Vec<PointWidth> {
    let smoothed = |w: Width| matches!(w, Width::Masked { .. } | Width::Sloped { .. });
    (0..points.len())
        .filter_map(|i| {
            let mut point = points[i]?;
            if smoothed(point.width) {
                let kind = std::mem::discriminant(&point.width);
                let near = within(neighbours, i, SMOOTH_STEPS);
                let px = median(
                    near.iter()
                        .filter_map(|j| points[*j])
                        .filter(|p| std::mem::discriminant(&p.width) == kind)
                        .map(|p| p.width.px())
                        .collect(),
                )
                .unwrap_or(point.width.px());
                point.width = match point.width {
                    Width::Masked { spread, .. } => Width::Masked { px, spread },
                    Width::Sloped { spread, .. } => Width::Sloped { px, spread },
                    other => other,
                };
            }
            Some(point)
        })
        .collect()
}

/// Centre-line pixels a width is the median over, each side.
const SMOOTH_STEPS: usize = 4;

/// What is measured across the line at one point: the mask's extent
/// (pixels; `None` off the mask), the grey levels and, where they show
/// sloping flanks, their width (see [`sloped`]).
struct Across {
    masked: Option<f64>,
    profile: Profile,
    sloped: Option<Width>,
}

impl Across {
    /// The mask's extent where it spans the crack ([`RESOLVED_PX`] or more).
    fn spanned(&self) -> Option<f64> {
        self.masked.filter(|px| *px >= RESOLVED_PX)
    }

    /// The width: where the mask spans the crack and the grey levels
    /// confirm a dark line there with its edges apart ([`EDGES_APART_PX`]),
    /// the profile's full width at half depth for a crack a few pixels
    /// wide, the mask's extent for a wide one, and a blend between (see
    /// [`MASK_FROM_PX`]); elsewhere (off the mask, where the mask spans
    /// less than [`RESOLVED_PX`], where the profile shows the crack
    /// thinner, or where it shows no dark line at all, so the mask there
    /// marks a stain or the surface's texture), the profile's alone.
    fn measure(&self, whole: &Whole) -> Width {
        let masked = self.spanned();
        let confirmed = masked.and_then(|mask_px| {
            let (profile_px, _) = half_depth(&self.profile, mask_px / 2.0)?;
            Some((mask_px, profile_px)).filter(|_| profile_px >= EDGES_APART_PX)
        });
        match confirmed {
            Some((mask_px, profile_px)) => {
                let mask_share =
                    ((profile_px - RESOLVED_PX) / (MASK_FROM_PX - RESOLVED_PX)).clamp(0.0, 1.0);
                Width::Masked {
                    px: mask_share * mask_px + (1.0 - mask_share) * profile_px,
                    spread: (profile_px - mask_px).abs() / 2.0,
                }
            }
            None => measure(&self.profile, self.sloped, whole, masked.is_some()),
        }
    }
}

/// How wide (at half depth) a crack is where its width is the mask's
/// alone, pixels; from [`RESOLVED_PX`] to this the mask's share grows from
/// none. A model's mask edges lie about a pixel outside a thin crack's
/// (its map is blurred over its receptive field): on Crack500's test
/// photos, at the centre line's points where the annotators' masks say 2
/// to 4 px, the model's masks came out 39 to 74% wider, the half depth 7
/// to 34%. The half depth misses a wide crack's V or U shoulders: where
/// they say over 6 px, it came out 19 to 25% narrower, the mask 3 to 14%.
const MASK_FROM_PX: f64 = 2.0 * RESOLVED_PX;
/// Noise sigmas a crack's depth must pass for its half-depth width to
/// count where the mask already says a crack is there.
const CONFIRM_SIGMAS: f64 = 3.0;
/// Noise sigmas a crack's depth must pass where nothing else says a crack
/// is there.
const FOUND_SIGMAS: f64 = 6.0;

/// Half the profile's span across the line, pixels, unless the crack
/// reaches further.
const REACH: f64 = 8.0;
/// The farthest a profile reaches, pixels.
const MAX_REACH: f64 = 64.0;

/// How deep inside the detector's mask each of its pixels is: the distance
/// from its centre to the nearest pixel off the mask, pixels.
struct Inside {
    mask: Mask,
    distance: image::ImageBuffer<image::Luma<f64>, Vec<f64>>,
}

impl Inside {
    fn of(mask: &Mask) -> Self {
        // A pixel of background round the window: the crack ends there.
        let (w, h) = (mask.width + 2, mask.height + 2);
        let off = image::GrayImage::from_fn(w, h, |x, y| {
            let on = x > 0 && y > 0 && mask.at(mask.x0 + x - 1, mask.y0 + y - 1);
            image::Luma([if on { 0 } else { 255 }])
        });
        Self {
            mask: mask.clone(),
            distance: imageproc::distance_transform::euclidean_squared_distance_transform(&off),
        }
    }

    /// The distance at frame pixel `(x, y)`; 0 off the mask.
    fn at(&self, x: u32, y: u32) -> f64 {
        if !self.mask.at(x, y) {
            return 0.0;
        }
        let (u, v) = (x - self.mask.x0 + 1, y - self.mask.y0 + 1);
        self.distance.get_pixel(u, v).0[0].sqrt()
    }

    /// The crack's width where the line through `at` along `across` crosses
    /// the mask (`None` when no crack pixel lies within a pixel and a half
    /// of `at` on it): the widest disc inside the mask on that crossing, as
    /// `2 r - 1` pixels for `r` the distance between pixel centres (a line
    /// one pixel wide is 1), the measure people's masks are scored by.
    fn width(&self, at: Point2<f64>, across: Vector2<f64>) -> Option<f64> {
        let depth = |t: f64| {
            let p = at + across * t;
            if p.x < 0.0 || p.y < 0.0 {
                0.0
            } else {
                self.at(p.x as u32, p.y as u32)
            }
        };
        let start = [0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5]
            .into_iter()
            .find(|t| depth(*t) > 0.0)?;
        let deepest = |step: f64| {
            let (mut t, mut most) = (start, depth(start));
            while (t - start).abs() < MAX_REACH && depth(t + step) > 0.0 {
                t += step;
                most = most.max(depth(t));
            }
            most
        };
        Some(2.0 * deepest(STEP).max(deepest(-STEP)) - 1.0)
    }
}

/// The profile at `at` out to `reach` pixels each side, reaching further
/// (up to [`MAX_REACH`]) while the crack's darkness runs past half of it,
/// so the surface is read outside the crack.
fn reached(gray: &GrayImage, at: Point2<f64>, across: Vector2<f64>, reach: f64) -> Option<Profile> {
    let mut reach = reach.min(MAX_REACH);
    loop {
        let p = profile(gray, at, across, reach)?;
        if reach >= MAX_REACH || dark_extent(&p) < 0.5 * reach {
            return Some(p);
        }
        reach = (2.0 * reach).min(MAX_REACH);
    }
}

/// How far from the line the crack's darkness runs, pixels: the farther of
/// the two sides where the profile, walking out from the line, first comes
/// back within three noise sigmas of the surface.
fn dark_extent(p: &Profile) -> f64 {
    let Some(centre) = p.t.iter().position(|t| t.abs() < STEP / 2.0) else {
        return 0.0;
    };
    let floor = 3.0 * p.noise;
    if p.dark[centre] <= floor {
        return 0.0;
    }
    let side = |step: isize| {
        let mut i = centre as isize;
        while i + step >= 0 && ((i + step) as usize) < p.dark.len() && p.dark[i as usize] > floor {
            i += step;
        }
        p.t[i as usize].abs()
    };
    side(1).max(side(-1))
}

/// What a crack as a whole tells the measure of each of its points.
struct Whole {
    /// The share of the surface's brightness its interior lacks.
    share: f64,
    /// Whether it has resolved (flat-bottomed) stretches.
    has_stretches: bool,
    /// Whether it has sloped stretches (see [`sloped`]).
    slopes: bool,
}

/// The width from one profile: at half depth where the crack has resolved
/// stretches and this point is one; at a quarter depth where it slopes
/// (`sloped`, see [`sloped`]) and no mask spans it (`spanned`: one that does but
/// shows no dark line marks a stain or texture, not a wide crack); else
/// the darkness integral over the interior's darkness.
fn measure(p: &Profile, sloped: Option<Width>, whole: &Whole, spanned: bool) -> Width {
    if let Some((px, depth)) = resolved(p).filter(|_| whole.has_stretches) {
        return Width::Resolved { px, depth };
    }
    if let Some(width) = sloped.filter(|_| whole.slopes && !spanned) {
        return width;
    }
    let depth = whole.share * p.surface;
    // The crack's darkness near the line, not a neighbour's further out.
    let core: f64 =
        p.t.iter()
            .zip(&p.dark)
            .filter(|(t, _)| t.abs() <= 2.5)
            .map(|(_, d)| d * STEP)
            .sum();
    // What noise alone sums to over that window: 3 sigma of the mean of
    // 5 independent pixels, times their span.
    let limit = 3.0 * p.noise * 5.0 / 5f64.sqrt();
    if core <= limit || depth <= 0.0 {
        return Width::Below {
            px: limit / depth.max(1.0),
        };
    }
    Width::Integrated { px: core / depth }
}

/// The width of a crack wider than the image's blur ([`EDGES_APART_PX`]
/// at half depth or more) with no flat bottom, at a quarter of its depth.
/// A V or U section's flanks slope from its edges, so its half depth
/// reads only part of its opening (half of a V's) and its darkness summed
/// across it less than an interior of the assumed darkness would give
/// (real cracks 3 px and wider sum to 0.39 to 0.59 of their width,
/// docs/evaluation.md); a quarter depth reads three quarters of a V's and
/// all of a U's, and the blur widens it by little. How far the two levels
/// differ says how far the flanks leave the opening uncertain.
fn sloped(p: &Profile) -> Option<Width> {
    let Found {
        centre,
        depth,
        width: half,
    } = found(p)?;
    if half < EDGES_APART_PX {
        return None;
    }
    // The edges at half of half the depth.
    let quarter = edges_at_half(p, centre, depth / 2.0, 0.0)?;
    Some(Width::Sloped {
        px: quarter,
        spread: (quarter - half) / 2.0,
    })
}

/// Half-depth width from which a profile shows a crack's two edges apart
/// (its flanks), not a thinner line's blur, pixels.
const EDGES_APART_PX: f64 = 2.0;

/// Full width at half depth where the profile shows a flat-bottomed crack
/// at least [`RESOLVED_PX`] wide: (width px, depth grey levels).
fn resolved(p: &Profile) -> Option<(f64, f64)> {
    let Found { depth, width, .. } = found(p)?;
    // A flat bottom: the middle two thirds of the crack are nearly as dark
    // as its deepest (a V's darkness falls to two thirds there).
    let flat =
        p.t.iter()
            .zip(&p.dark)
            .filter(|(t, _)| t.abs() <= width / 3.0)
            .all(|(_, d)| *d >= 0.8 * depth);
    (width >= RESOLVED_PX && flat).then_some((width, depth))
}

/// A crack the profile shows on the line, where nothing else says one is
/// there: deeper than [`FOUND_SIGMAS`] noise sigmas.
struct Found {
    /// The sample on the line.
    centre: usize,
    /// The darkest within two samples of it, grey levels.
    depth: f64,
    /// Full width at half that depth, pixels.
    width: f64,
}

fn found(p: &Profile) -> Option<Found> {
    let centre = p.t.iter().position(|t| t.abs() < STEP / 2.0)?;
    let depth = p.dark[centre.saturating_sub(2)..=(centre + 2).min(p.dark.len() - 1)]
        .iter()
        .copied()
        .fold(0.0, f64::max);
    let width = edges_at_half(p, centre, depth, FOUND_SIGMAS)?;
    Some(Found {
        centre,
        depth,
        width,
    })
}

/// The distance between the two places, walking out from sample `from`,
/// where the profile's darkness falls below half of `depth`, found
/// between samples by interpolation; `None` where the crack is no darker
/// than `sigmas` noise sigmas or runs past the profile.
fn edges_at_half(p: &Profile, from: usize, depth: f64, sigmas: f64) -> Option<f64> {
    if depth < sigmas * p.noise.max(1.0) {
        return None;
    }
    let half = depth / 2.0;
    let edge = |step: isize| -> Option<f64> {
        let mut i = from as isize;
        loop {
            let next = i + step;
            if next < 0 || next as usize >= p.dark.len() {
                return None;
            }
            let (a, b) = (p.dark[i as usize], p.dark[next as usize]);
            if b < half {
                let f = ((a - half) / (a - b)).clamp(0.0, 1.0);
                return Some(p.t[i as usize] + f * (p.t[next as usize] - p.t[i as usize]));
            }
            i = next;
        }
    };
    Some(edge(1)? - edge(-1)?)
}

/// Full width at half depth around the darkest point within `search`
/// pixels of the line (its depth the mean over half a pixel each side of
/// it): (width px, depth grey levels); `None` where the crack is no darker
/// than [`CONFIRM_SIGMAS`] noise sigmas or runs past the profile.
fn half_depth(p: &Profile, search: f64) -> Option<(f64, f64)> {
    let deepest = (0..p.t.len())
        .filter(|i| p.t[*i].abs() <= search.max(STEP))
        .max_by(|a, b| p.dark[*a].total_cmp(&p.dark[*b]))?;
    let near = deepest.saturating_sub(2)..=(deepest + 2).min(p.dark.len() - 1);
    let depth = p.dark[near.clone()].iter().sum::<f64>() / near.count() as f64;
    Some((edges_at_half(p, deepest, depth, CONFIRM_SIGMAS)?, depth))
}

/// The grey levels across the crack at `at` along `across`, out to `reach`
/// pixels each side, the surface read from the outer two fifths.
fn profile(gray: &GrayImage, at: Point2<f64>, across: Vector2<f64>, reach: f64) -> Option<Profile> {
    let n = (reach / STEP) as i64;
    let t: Vec<f64> = (-n..=n).map(|k| k as f64 * STEP).collect();
    let values: Vec<f64> = t
        .iter()
        .map(|t| sample(gray, at + across * *t))
        .collect::<Option<_>>()?;
    let outer: Vec<f64> = t
        .iter()
        .zip(&values)
        .filter(|(t, _)| t.abs() >= reach * 0.6)
        .map(|(_, v)| *v)
        .collect();
    let deviations = |surface: f64| outer.iter().map(|v| (v - surface).abs()).collect();
    let surface = median(outer.clone())?;
    let noise = 1.4826 * median(deviations(surface))?;
    let dark = values.iter().map(|v| (surface - v).max(0.0)).collect();
    Some(Profile {
        t,
        dark,
        surface,
        noise: noise.max(0.5),
    })
}

/// Bilinear grey level at `p` (pixel-centre coordinates: pixel `(x, y)`
/// spans `x..x+1`); `None` outside the image.
fn sample(gray: &GrayImage, p: Point2<f64>) -> Option<f64> {
    let (u, v) = (p.x - 0.5, p.y - 0.5);
    let (w, h) = (f64::from(gray.width()), f64::from(gray.height()));
    if u < 0.0 || v < 0.0 || u > w - 1.0 || v > h - 1.0 {
        return None;
    }
    let (x0, y0) = (u.floor() as u32, v.floor() as u32);
    let (x1, y1) = (
        (x0 + 1).min(gray.width() - 1),
        (y0 + 1).min(gray.height() - 1),
    );
    let (fx, fy) = (u - f64::from(x0), v - f64::from(y0));
    let at = |x: u32, y: u32| f64::from(gray.get_pixel(x, y).0[0]);
    let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
    let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

fn adjacency(n: usize, edges: &[(u32, u32)]) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); n];
    for &(a, b) in edges {
        out[a as usize].push(b as usize);
        out[b as usize].push(a as usize);
    }
    out
}

/// Centre-line pixels within `steps` steps of pixel `i` along the line,
/// `i` among them.
fn within(neighbours: &[Vec<usize>], i: usize, steps: usize) -> Vec<usize> {
    let mut near = vec![i];
    let mut frontier = vec![i];
    for _ in 0..steps {
        let mut next: Vec<usize> = frontier
            .iter()
            .flat_map(|j| neighbours[*j].iter().copied())
            .filter(|j| !near.contains(j))
            .collect();
        next.sort_unstable();
        next.dedup();
        near.extend(&next);
        frontier = next;
    }
    near
}

/// Unit normal of the centre line at pixel `i`: across the main direction
/// of the pixels within `DIRECTION_REACH` steps along the line.
fn normal(centre: &[Point2<f64>], neighbours: &[Vec<usize>], i: usize) -> Option<Vector2<f64>> {
    let near = within(neighbours, i, DIRECTION_REACH);
    if near.len() < 3 {
        return None;
    }
    let mean = near.iter().map(|j| centre[*j].coords).sum::<Vector2<f64>>() / near.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for j in &near {
        let d = centre[*j].coords - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some(Vector2::new(-angle.sin(), angle.cos()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight crack `w` pixels wide at `angle` through the middle of a
    /// 64x64 image of brightness 150 with noise, drawn by the share of each
    /// pixel it covers (16x16 supersampling), its interior 85% darker.
    fn crack_image(
        w: f64,
        angle: f64,
        seed: u32,
    ) -> (GrayImage, Vec<Point2<f64>>, Vec<(u32, u32)>) {
        section_image(w, 0.0, angle, seed)
    }

    /// [`crack_image`] with a section from a flat-bottomed slot (`vee` 0)
    /// to a V (1): the interior ramps to its full darkness over that share
    /// of the half width from each edge.
    fn section_image(
        w: f64,
        vee: f64,
        angle: f64,
        seed: u32,
    ) -> (GrayImage, Vec<Point2<f64>>, Vec<(u32, u32)>) {
        let (dx, dy) = (angle.cos(), angle.sin());
        let mut img = GrayImage::new(64, 64);
        let mut state = seed.wrapping_mul(2_654_435_761).max(1);
        for (x, y, p) in img.enumerate_pixels_mut() {
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
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = f64::from(state % 7) - 3.0;
            p.0[0] = (150.0 * (1.0 - 0.85 * covered) + noise)
                .round()
                .clamp(0.0, 255.0) as u8;
        }
        let centre: Vec<Point2<f64>> = (-20..=20)
            .map(|k| Point2::new(32.0 + f64::from(k) * dx, 32.0 + f64::from(k) * dy))
            .collect();
        let edges = (0..40).map(|k| (k, k + 1)).collect();
        (img, centre, edges)
    }

    fn median_width(w: f64, angle: f64) -> (f64, Width) {
        let (img, centre, edges) = crack_image(w, angle, 7);
        let found = widths(&img, None, &centre, &edges, 0.85);
        let mut px: Vec<f64> = found.iter().map(|p| p.width.px()).collect();
        px.sort_by(f64::total_cmp);
        (px[px.len() / 2], found[found.len() / 2].width)
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
            let (measured, kind) = median_width(w, angle);
            let error = (measured - w).abs() / w;
            assert!(
                error < 0.15,
                "{w} px at {angle} rad measured {measured} ({kind:?})"
            );
            if w >= 3.5 {
                assert!(matches!(kind, Width::Resolved { .. }), "{w}: {kind:?}");
            }
        }
    }

    #[test]
    fn a_v_section_without_a_mask_is_read_at_a_quarter_of_its_depth() {
        for (w, vee, angle) in [(5.0, 1.0, 0.3), (8.0, 1.0, 1.1), (11.0, 1.0, 0.0)] {
            let (img, centre, edges) = section_image(w, vee, angle, 11);
            let found = widths(&img, None, &centre, &edges, 0.85);
            let mid = found[found.len() / 2].width;
            let Width::Sloped { px, spread } = mid else {
                panic!("{w} px, vee {vee}: {mid:?}");
            };
            // Half depth reads a V's middle half; a quarter depth, all but
            // its last eighths, which the uncertainty says.
            assert!((px - w).abs() < 0.25 * w, "{w} px, vee {vee}: {mid:?}");
            assert!((px - w).abs() < 2.5 * spread, "{w} px, vee {vee}: {mid:?}");
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
    fn a_mask_that_spans_the_crack_measures_it_with_the_profile() {
        for (w, angle) in [(5.0, 0.3), (9.0, 1.1), (14.0, 0.0)] {
            let (img, centre, edges) = crack_image(w, angle, 3);
            let mask = crack_mask(w, angle);
            let found = widths(&img, Some(&mask), &centre, &edges, 0.85);
            let mid = found[found.len() / 2].width;
            assert!(matches!(mid, Width::Masked { .. }), "{w}: {mid:?}");
            let error = (mid.px() - w).abs() / w;
            assert!(error < 0.15, "{w} px at {angle} rad measured {mid:?}");
        }
        // A mask wider than a thin crack (a model's blur): the profile's
        // measure, not the mask's.
        let (img, centre, edges) = crack_image(1.0, 0.4, 5);
        let found = widths(&img, Some(&crack_mask(7.0, 0.4)), &centre, &edges, 0.85);
        let mid = found[found.len() / 2].width;
        assert!(
            matches!(mid, Width::Integrated { .. }) && (mid.px() - 1.0).abs() < 0.2,
            "{mid:?}"
        );
    }

    #[test]
    fn a_mask_a_pixel_too_wide_or_over_bare_surface_does_not_widen_the_crack() {
        // A model's mask a pixel outside each edge of a crack a few pixels
        // wide: the half depth, not the mean of the two.
        for w in [2.5, 3.5] {
            let (img, centre, edges) = crack_image(w, 0.5, 9);
            let found = widths(&img, Some(&crack_mask(w + 2.0, 0.5)), &centre, &edges, 0.85);
            // From where its edges are apart, the crack is on the mask's
            // stretch (smoothed with it), at its half depth.
            let mid = found[found.len() / 2].width;
            assert!(matches!(mid, Width::Masked { .. }), "{w}: {mid:?}");
            assert!((mid.px() - w).abs() < 0.15 * w, "{w}: {mid:?}");
        }
        // A mask where the grey levels show no crack: not the mask's extent.
        let (img, centre, edges) = crack_image(0.0, 0.5, 9);
        let found = widths(&img, Some(&crack_mask(7.0, 0.5)), &centre, &edges, 0.85);
        assert!(
            found
                .iter()
                .all(|p| !matches!(p.width, Width::Masked { .. })),
            "{found:?}"
        );
    }

    #[test]
    fn a_crack_fainter_than_the_noise_is_below_a_limit() {
        let (_, kind) = median_width(0.03, 0.4);
        let Width::Below { px } = kind else {
            panic!("measured {kind:?}");
        };
        assert!(px > 0.03 && px < 1.0, "{px}");
    }
}

//! One crossing of a crack: the grey levels across its centre line at one
//! point in the numbers a width is read from. The profile is sampled on the
//! line's normal at sub-pixel steps, out to a reach that grows with the
//! crack (the detector's mask, where it segments, or the crack's own dark
//! extent) so the surface is read outside it.
//!
//! A camera spreads a line thinner than its blur over a couple of pixels:
//! such a crack's profile never reaches its interior's darkness, and its
//! width at half depth is the blur's. What the blur keeps is the light the
//! crack takes away, summed across it ([`Crossing::darkness`]); its walls
//! ([`Crossing::walls`]) say its width only where it is wider than the
//! blur. Each wall is where its own step is half up: a crack whose inside
//! is not dark (filled, stained, lit from one side) or that has a darkened
//! shoulder beside it still shows where its walls stand.
//! [`crate::width`] weighs the two.

use std::collections::HashMap;

use image::GrayImage;
use nalgebra::{Point2, Vector2};
use postflight_core::mask::Mask;

use crate::stats::{median, robust_sigma};

/// Samples per pixel across the crack.
const STEP: f64 = 0.25;
/// A crossing is flat-bottomed and resolved this many pixels wide or more
/// at half depth.
pub const RESOLVED_PX: f64 = 3.0;
/// Half-depth width from which a profile shows a crack's two walls apart,
/// not a thinner line's blur, pixels.
pub const WALLS_APART_PX: f64 = 2.0;
/// Noise sigmas a crack's depth must pass for its half depth to be read
/// where the detector's mask spans it (the mask already says a crack is
/// there).
const CONFIRM_SIGMAS: f64 = 3.0;
/// How much wider than the detector's mask walls fainter than
/// [`FOUND_SIGMAS`] may stand and still be the mask's crack, pixels.
const MASK_MARGIN_PX: f64 = 1.0;
/// Noise sigmas a crack's depth must pass where nothing else says one is
/// there.
const FOUND_SIGMAS: f64 = 6.0;
/// Half the profile's span across the line, pixels, unless the crack
/// reaches further.
const REACH: f64 = 8.0;
/// The farthest a profile reaches, pixels.
const MAX_REACH: f64 = 64.0;
/// How far either side of a wall its step's foot and top are looked for,
/// pixels: a blurred step of up to 1.5 px (one sigma) is all but up by
/// then.
const WALL_STEP_PX: f64 = 3.0;
/// A crossing shows its interior when its width at three quarters of its
/// depth is at least this share of its width at half: a blurred slot's
/// nearly is, a soft band's two thirds, a V's half; a line in a broader
/// shade shows only the line at three quarters.
const SHOWS_INTERIOR: f64 = 0.5;
/// The darkness is summed this far either side of the line at least,
/// pixels: a thin line's blur (on the gauge readings' photos about 2 px
/// at half depth, a Gaussian of 0.85 px) lies within it.
const DARKNESS_REACH_PX: f64 = 2.5;
/// And this far beyond a wider crack's walls at half depth, pixels: a
/// blurred wall's darkness falls to a fiftieth there.
const DARKNESS_MARGIN_PX: f64 = 1.5;

/// What the profile across a crack at one centre-line point shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The centre-line pixel.
    pub at: Point2<f64>,
    /// Unit normal of the centre line there, image pixels.
    pub across: Vector2<f64>,
    /// The surface's brightness beside the crack, grey levels.
    pub surface: f64,
    /// The surface's noise there (a robust standard deviation), grey
    /// levels.
    pub noise: f64,
    /// The crack's darkness below the surface at the line (the deepest
    /// within half a pixel), grey levels.
    pub depth: f64,
    /// The darkness summed across the crack: the light it takes away,
    /// grey levels times pixels. A crack `w` pixels wide whose interior
    /// lacks `C` grey levels of the surface's sums to `w C`, however the
    /// lens, the sensor and motion blur spread it.
    pub darkness: f64,
    /// What the image's noise alone may sum to over that span (3 sigma),
    /// grey levels times pixels.
    pub noise_limit: f64,
    /// Where the profile shows the crack's walls on the line (deeper than
    /// [`FOUND_SIGMAS`] noise sigmas, or [`CONFIRM_SIGMAS`] where the
    /// detector's mask spans it).
    pub walls: Option<Walls>,
    /// Its width at half depth: its walls', else, where the detector's mask
    /// spans it, around its darkest line within the mask (deeper than
    /// [`CONFIRM_SIGMAS`]), pixels.
    pub half: Option<f64>,
    /// Whether its walls pass [`FOUND_SIGMAS`] noise sigmas, as a crack
    /// that says the flight's blur and contrast must: fainter ones within
    /// the detector's mask are measured, but in a textured photo are as
    /// often the texture.
    pub sure: bool,
    /// Whether it is sure, flat-bottomed and at least [`RESOLVED_PX`] wide
    /// at half depth: its depth is its interior's darkness.
    pub flat: bool,
}

/// Where a crack's walls are: its widths between them at half, a quarter
/// and three quarters of its depth, pixels, walking out from the line,
/// each wall at half depth where its own step is half up. A blurred wall's
/// half depth lies on the wall; its quarter depth further out by what the
/// blur spreads it. A V or U section's walls slope from its opening, so
/// its half depth reads only part of it (half of a V's), its quarter depth
/// three quarters of a V's and all of a U's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Walls {
    pub half: f64,
    pub quarter: f64,
    pub three_quarters: f64,
    /// How far each wall rises, from a quarter to three quarters of the
    /// depth, the two walls' mean, pixels: a blurred upright wall's rise is
    /// 1.35 of the blur's sigma.
    pub rise: f64,
}

impl Walls {
    /// Whether the crossing shows its interior ([`SHOWS_INTERIOR`]): its
    /// depth is then the interior's, however dark that is.
    pub fn show_interior(&self) -> bool {
        self.three_quarters >= SHOWS_INTERIOR * self.half
    }
}

impl Crossing {
    /// The share of the surface's brightness its interior lacks, where it
    /// shows its interior (flat-bottomed and resolved).
    pub fn interior(&self) -> Option<f64> {
        (self.flat && self.surface > 0.0).then(|| self.depth / self.surface)
    }
}

/// The crack's crossings at each of `centre` (a traced centre line, frame
/// pixels, with `neighbours` along it), measured in `gray` and `mask` (the
/// detector's crack pixels, where it segments); `None` where no profile
/// fits in the image, the line has no direction, or the crossing takes in
/// another stretch of the crack ([`Apart`]).
pub fn crossings(
    gray: &GrayImage,
    mask: Option<&Mask>,
    centre: &[Point2<f64>],
    neighbours: &[Vec<usize>],
) -> Vec<Option<Crossing>> {
    let inside = mask.map(Inside::of);
    let apart = Apart::of(centre, neighbours);
    (0..centre.len())
        .map(|i| {
            let across = normal(centre, neighbours, i)?;
            let mask_px = inside.as_ref().and_then(|m| m.width(centre[i], across));
            // The profile reaches well past the crack: past its mask's
            // extent, or (without one) past its own dark extent.
            let reach = mask_px.map_or(REACH, |px| REACH.max(1.5 * px + 4.0));
            let profile = reached(gray, centre[i], across, reach)?;
            let crossing = profile.crossing(centre[i], across, mask_px);
            // A crack is longer than it is wide: a crossing needs as much
            // traced line either side as half its width, or it is a line's
            // end hooking across the crack (or a blob), whose profile runs
            // along the crack.
            let long = crossing
                .walls
                .is_none_or(|w| runs_on(neighbours, i, (w.half / 2.0).ceil() as usize));
            (long && apart.alone(i, &crossing)).then_some(crossing)
        })
        .collect()
}

/// Whether the centre line runs on `steps` steps either side of pixel `i`
/// (one short at most).
fn runs_on(neighbours: &[Vec<usize>], i: usize, steps: usize) -> bool {
    within(neighbours, i, steps).len() >= 2 * steps
}

/// Centre-line steps beyond a crossing's summed reach within which a fork
/// still bends its normal.
const FORK_MARGIN: usize = DIRECTION_REACH;

/// Which crossings take in only their own stretch of the crack. Near a
/// fork the line's direction bends into the branch, and across a bend, a
/// branch or a parallel piece the crossing's sum takes in that stretch's
/// darkness too: a branched crack would read twice its width where its
/// branches meet, and that would be its widest.
struct Apart<'a> {
    neighbours: &'a [Vec<usize>],
    /// The centre-line pixel at each frame pixel.
    at: HashMap<(i64, i64), usize>,
}

impl<'a> Apart<'a> {
    fn of(centre: &'a [Point2<f64>], neighbours: &'a [Vec<usize>]) -> Self {
        let at = centre
            .iter()
            .enumerate()
            .map(|(i, p)| ((p.x.floor() as i64, p.y.floor() as i64), i))
            .collect();
        Self { neighbours, at }
    }

    /// Whether `crossing`, at centre-line pixel `i`, is clear of every fork
    /// and every other stretch of the line over the span it sums.
    fn alone(&self, i: usize, crossing: &Crossing) -> bool {
        let reach = darkness_reach(crossing.half);
        let own = within(self.neighbours, i, reach.ceil() as usize + FORK_MARGIN);
        if own.iter().any(|j| self.neighbours[*j].len() >= 3) {
            return false;
        }
        let steps = (2.0 * reach / STEP).ceil() as usize;
        (0..=steps).all(|k| {
            let p = crossing.at + crossing.across * (k as f64 * STEP - reach);
            let (x, y) = (p.x.floor() as i64, p.y.floor() as i64);
            [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .filter_map(|(dx, dy)| self.at.get(&(x + dx, y + dy)))
                .all(|j| own.contains(j))
        })
    }
}

/// How far either side of the line a crossing's darkness is summed, its
/// width at half depth `half` where known, pixels.
fn darkness_reach(half: Option<f64>) -> f64 {
    half.map_or(DARKNESS_REACH_PX, |h| {
        (h / 2.0 + DARKNESS_MARGIN_PX).max(DARKNESS_REACH_PX)
    })
}

/// The profile across the crack at one centre-line pixel.
struct Profile {
    /// Offsets across the line, pixels, `STEP` apart, centred on 0.
    t: Vec<f64>,
    /// Darkness below the surface at each offset, grey levels (negative
    /// where brighter).
    dark: Vec<f64>,
    /// The surface's brightness and noise (robust sigma), grey levels.
    surface: f64,
    noise: f64,
}

impl Profile {
    /// What it shows; `mask_px` the detector's mask's width across it,
    /// where it segments.
    fn crossing(&self, at: Point2<f64>, across: Vector2<f64>, mask_px: Option<f64>) -> Crossing {
        // Where the detector's mask spans it, the mask already says a crack
        // is there: its walls are read at a fainter depth.
        let sigmas = if mask_px.is_some_and(|px| px >= RESOLVED_PX) {
            CONFIRM_SIGMAS
        } else {
            FOUND_SIGMAS
        };
        let found = found(self, sigmas);
        let sure = found
            .as_ref()
            .is_some_and(|f| f.depth >= FOUND_SIGMAS * self.noise.max(1.0));
        let centre = self.t.iter().position(|t| t.abs() < STEP / 2.0);
        let depth = centre.map_or(0.0, |c| self.deepest_near(c, 2));
        // Fainter walls count where the mask confirms them: within it. A
        // faint line's noise spreads its half depth past its mask, which
        // would read a hairline wide.
        let walls = found
            .as_ref()
            .and_then(|f| self.walls(f))
            .filter(|w| sure || mask_px.is_some_and(|px| w.half <= px + MASK_MARGIN_PX));
        // Where the mask spans the crack, its darkest line may lie off the
        // traced one: its half depth there.
        let half = found.as_ref().map(|f| f.width).or_else(|| {
            mask_px
                .filter(|px| *px >= RESOLVED_PX)
                .and_then(|px| half_depth(self, px / 2.0))
        });
        // The darkness summed over the crack's half-depth width and its
        // blur each side, signed (the noise sums to nothing).
        let reach = darkness_reach(half);
        let darkness: f64 = self
            .t
            .iter()
            .zip(&self.dark)
            .filter(|(t, _)| t.abs() <= reach)
            .map(|(_, d)| d * STEP)
            .sum();
        // What noise alone sums to over that span: 3 sigma of the sum of
        // its independent pixels.
        let noise_limit = 3.0 * self.noise * (2.0 * reach).sqrt();
        Crossing {
            at,
            across,
            surface: self.surface,
            noise: self.noise,
            depth,
            darkness,
            noise_limit,
            walls,
            half,
            sure,
            flat: sure && found.as_ref().is_some_and(|f| self.flat(f)),
        }
    }

    /// The walls of crack `f`: walking out from the line, where its
    /// darkness falls below a half, a quarter and three quarters of its
    /// depth, each wall at half depth moved to where its own step is half
    /// up ([`wall`]); `None` where a level runs past the profile.
    fn walls(&self, f: &Found) -> Option<Walls> {
        let level = |share: f64| edges(self, f.centre, share * f.depth, 0.0);
        let (lo, hi) = level(0.5)?;
        let (qlo, qhi) = level(0.25)?;
        let (tlo, thi) = level(0.75)?;
        let (lo, hi) = (self.wall(lo, f.centre), self.wall(hi, f.centre));
        Some(Walls {
            half: hi - lo,
            quarter: qhi - qlo,
            three_quarters: thi - tlo,
            rise: 0.5 * ((tlo - qlo) + (qhi - thi)),
        })
    }

    /// A wall found at offset `edge` walking out from sample `centre`, moved
    /// to where its own step is half up: from the least darkness within
    /// [`WALL_STEP_PX`] outside it to the most within as far inside (up to
    /// the line). A crack whose inside is filled or lit along one wall
    /// shows a lower step there than its depth at the line; a darkened
    /// shoulder beside it lifts the foot of the step.
    fn wall(&self, edge: f64, centre: usize) -> f64 {
        let i = self.index(edge);
        let out: isize = if edge >= 0.0 { 1 } else { -1 };
        let reach = (WALL_STEP_PX / STEP) as isize;
        let at = |k: isize| {
            self.smooth_at((i as isize + out * k).clamp(0, self.t.len() as isize - 1) as usize)
        };
        let foot = (0..=reach).map(at).fold(f64::INFINITY, f64::min);
        let inside = (i.abs_diff(centre) as isize).min(reach);
        let top = (-inside..=0).map(at).fold(f64::NEG_INFINITY, f64::max);
        let half = (foot.max(0.0) + top) / 2.0;
        // Walking out from the inside of the step to where it falls below
        // half, found between samples.
        let mut k = -inside;
        while k < reach && at(k + 1) >= half {
            k += 1;
        }
        let (a, b) = (at(k), at(k + 1));
        let f = if a > b {
            ((a - half) / (a - b)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let t =
            |k: isize| self.t[(i as isize + out * k).clamp(0, self.t.len() as isize - 1) as usize];
        t(k) + f * (t(k + 1) - t(k))
    }

    /// The profile's darkness averaged over half a pixel about sample `i`.
    fn smooth_at(&self, i: usize) -> f64 {
        let near = &self.dark[i.saturating_sub(2)..=(i + 2).min(self.dark.len() - 1)];
        near.iter().sum::<f64>() / near.len() as f64
    }

    /// The sample nearest offset `t`, within the profile.
    fn index(&self, t: f64) -> usize {
        let i = ((t - self.t[0]) / STEP).round();
        i.clamp(0.0, (self.t.len() - 1) as f64) as usize
    }

    /// The darkest sample within `samples` of sample `i`.
    fn deepest_near(&self, i: usize, samples: usize) -> f64 {
        self.dark[i.saturating_sub(samples)..=(i + samples).min(self.dark.len() - 1)]
            .iter()
            .copied()
            .fold(0.0, f64::max)
    }

    /// A flat bottom at least [`RESOLVED_PX`] wide: the middle two thirds
    /// of the crack nearly as dark as its deepest (a V's darkness falls to
    /// two thirds there).
    fn flat(&self, f: &Found) -> bool {
        f.width >= RESOLVED_PX
            && self
                .t
                .iter()
                .zip(&self.dark)
                .filter(|(t, _)| t.abs() <= f.width / 3.0)
                .all(|(_, d)| *d >= 0.8 * f.depth)
    }
}

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
/// or the image beyond the profile is brighter than the surface it read (a
/// crack wider than the reach, its inside taken for the surface), so the
/// surface is read outside the crack.
fn reached(gray: &GrayImage, at: Point2<f64>, across: Vector2<f64>, reach: f64) -> Option<Profile> {
    let mut reach = reach.min(MAX_REACH);
    loop {
        let p = profile(gray, at, across, reach)?;
        let inside = dark_extent(&p) >= 0.5 * reach || brighter_beyond(gray, at, across, reach, &p);
        if reach >= MAX_REACH || !inside {
            return Some(p);
        }
        reach = (2.0 * reach).min(MAX_REACH);
    }
}

/// Whether the image from `reach` to twice it either side of `at` along
/// `across` (where inside it) is brighter than profile `p`'s surface by
/// more than its own noise allows.
fn brighter_beyond(
    gray: &GrayImage,
    at: Point2<f64>,
    across: Vector2<f64>,
    reach: f64,
    p: &Profile,
) -> bool {
    let beyond: Vec<f64> = (0..=8)
        .map(|k| reach * (1.0 + f64::from(k) / 8.0))
        .flat_map(|t| [t, -t])
        .filter_map(|t| sample(gray, at + across * t))
        .collect();
    let Some(b) = median(beyond.clone()) else {
        return false;
    };
    // Beyond's own noise: the profile's is its outer samples', which take
    // in the crack's walls where it is wider.
    let noise = robust_sigma(beyond.iter().map(|v| (v - b).abs()).collect()).unwrap_or(0.0);
    b - p.surface > (3.0 * noise).max(2.0)
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

/// A crack the profile shows on the line, deeper than so many noise
/// sigmas.
struct Found {
    /// The sample on the line.
    centre: usize,
    /// The darkest within two samples of it, grey levels.
    depth: f64,
    /// Full width at half that depth, pixels.
    width: f64,
}

fn found(p: &Profile, sigmas: f64) -> Option<Found> {
    let centre = p.t.iter().position(|t| t.abs() < STEP / 2.0)?;
    let depth = p.deepest_near(centre, 2);
    let width = edges_at_half(p, centre, depth, sigmas)?;
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
    let (lo, hi) = edges(p, from, depth / 2.0, sigmas.max(0.0) / 2.0)?;
    Some(hi - lo)
}

/// The two places, walking out from sample `from`, where the profile's
/// darkness falls below `level`, offsets from the line, found between
/// samples by interpolation; `None` where `level` is no more than `sigmas`
/// noise sigmas or the crack runs past the profile.
fn edges(p: &Profile, from: usize, level: f64, sigmas: f64) -> Option<(f64, f64)> {
    if level < sigmas * p.noise.max(1.0) {
        return None;
    }
    let half = level;
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
    Some((edge(-1)?, edge(1)?))
}

/// Full width at half depth around the darkest point within `search`
/// pixels of the line (its depth the mean over half a pixel each side of
/// it); `None` where the crack is no darker than [`CONFIRM_SIGMAS`] noise
/// sigmas or runs past the profile.
fn half_depth(p: &Profile, search: f64) -> Option<f64> {
    let deepest = (0..p.t.len())
        .filter(|i| p.t[*i].abs() <= search.max(STEP))
        .max_by(|a, b| p.dark[*a].total_cmp(&p.dark[*b]))?;
    let near = deepest.saturating_sub(2)..=(deepest + 2).min(p.dark.len() - 1);
    let depth = p.dark[near.clone()].iter().sum::<f64>() / near.count() as f64;
    edges_at_half(p, deepest, depth, CONFIRM_SIGMAS)
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
    let noise = robust_sigma(deviations(surface))?;
    let dark = values.iter().map(|v| surface - v).collect();
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

/// Centre-line pixels on either side that give the line's local direction.
const DIRECTION_REACH: usize = 3;

/// Each centre-line pixel's neighbours along the line, from its `edges`.
pub fn adjacency(n: usize, edges: &[(u32, u32)]) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); n];
    for &(a, b) in edges {
        out[a as usize].push(b as usize);
        out[b as usize].push(a as usize);
    }
    out
}

/// Centre-line pixels within `steps` steps of pixel `i` along the line,
/// `i` among them.
pub fn within(neighbours: &[Vec<usize>], i: usize, steps: usize) -> Vec<usize> {
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

    /// A crack 3 px wide down column 32 of a 64 x 64 image, and a branch of
    /// it from (32, 32) up and to the right; the traced line follows both,
    /// the fork at (32, 32).
    fn branched() -> (GrayImage, Vec<Point2<f64>>, Vec<(u32, u32)>) {
        let on_line = |x: f64, y: f64, (ax, ay): (f64, f64), (bx, by): (f64, f64)| {
            let (dx, dy) = (bx - ax, by - ay);
            let t = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            (x - ax - t * dx).hypot(y - ay - t * dy) <= 1.0
        };
        let main = ((32.5, 2.0), (32.5, 62.0));
        let branch = ((32.5, 32.5), (56.5, 8.5));
        let img = GrayImage::from_fn(64, 64, |x, y| {
            let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            let dark = on_line(px, py, main.0, main.1) || on_line(px, py, branch.0, branch.1);
            image::Luma([if dark { 30 } else { 150 }])
        });
        let mut centre: Vec<Point2<f64>> = (4..60)
            .map(|y| Point2::new(32.5, f64::from(y) + 0.5))
            .collect();
        let mut edges: Vec<(u32, u32)> = (0..55).map(|k| (k, k + 1)).collect();
        let fork = 28; // (32.5, 32.5)
        for k in 1..=22 {
            centre.push(Point2::new(32.5 + f64::from(k), 32.5 - f64::from(k)));
            let i = centre.len() as u32 - 1;
            edges.push((if k == 1 { fork } else { i - 1 }, i));
        }
        (img, centre, edges)
    }

    #[test]
    fn a_crossing_where_branches_meet_is_not_read() {
        let (img, centre, edges) = branched();
        let neighbours = adjacency(centre.len(), &edges);
        let found = crossings(&img, None, &centre, &neighbours);
        // Near the fork the sum takes in the branch: no crossing there.
        for (i, p) in centre.iter().enumerate().take(56) {
            let from_fork = (p.y - 32.5).abs();
            if from_fork <= 3.0 {
                assert!(found[i].is_none(), "{p} is {from_fork} px from the fork");
            }
            if from_fork >= 12.0 && (8.0..=56.0).contains(&p.y) {
                assert!(found[i].is_some(), "{p} is clear of the fork");
            }
        }
        // Every crossing of the main line read sums one crack 3 px wide, 120
        // grey levels deep.
        let sums: Vec<f64> = found[..56].iter().flatten().map(|c| c.darkness).collect();
        assert!(sums.len() >= 40, "{}", sums.len());
        for s in sums {
            assert!((s / 120.0 - 3.0).abs() < 0.4, "{s}");
        }
    }
}

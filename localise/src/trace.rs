//! The crack inside a detection box, traced in the image (or in the crack
//! pixels a segmenting model marked): pixels clearly
//! darker than the surface around them, thinned to a one-pixel centre line,
//! joined into a minimum spanning forest, and its pieces bridged where a
//! hairline crack faded for a few pixels. A box says only roughly where
//! a crack is; the trace gives its shape, so a long diagonal, curved or
//! branching crack is measured along its length and placed at its centre,
//! not at the centre of its box.

use image::GrayImage;
use nalgebra::{Point2, SVector};
use postflight_core::mask::Mask;

use crate::union_find::UnionFind;

/// A crack's centre line in one image.
#[derive(Debug, Clone, PartialEq)]
pub struct CrackTrace {
    /// Centre-line pixels, as pixel-centre coordinates of the whole frame.
    pub pixels: Vec<Point2<f64>>,
    /// Edges between neighbouring pixels (indices into `pixels`) that join
    /// them into a spanning forest: summed, they are the crack's length.
    pub edges: Vec<(u32, u32)>,
    /// Straight joins across gaps where the crack faded (ends of two pieces).
    pub bridges: Vec<(u32, u32)>,
}

impl CrackTrace {
    /// Length of the centre line with its pixels placed at `at` (pixel `i`
    /// at `at[i]`, `None` where it has no place): in pixels for the pixels
    /// themselves, in metres for their places on a surface.
    pub fn length<const D: usize>(&self, at: &[Option<SVector<f64, D>>]) -> f64 {
        let sum = |edges: &[(u32, u32)]| {
            edges
                .iter()
                .filter_map(|&(a, b)| Some((at[a as usize]? - at[b as usize]?).norm()))
                .sum::<f64>()
        };
        CHAIN_CORRECTION * sum(&self.edges) + sum(&self.bridges)
    }

    /// The centre line as chains of pixels (indices into `pixels`), along
    /// its edges and bridges: each runs between ends and forks, through
    /// pixels with two neighbours.
    pub fn chains(&self) -> Vec<Vec<u32>> {
        let n = self.pixels.len();
        let mut next: Vec<Vec<(u32, usize)>> = vec![Vec::new(); n];
        let joins: Vec<(u32, u32)> = self.edges.iter().chain(&self.bridges).copied().collect();
        for (e, &(a, b)) in joins.iter().enumerate() {
            next[a as usize].push((b, e));
            next[b as usize].push((a, e));
        }
        let mut used = vec![false; joins.len()];
        let mut chains = Vec::new();
        // From ends and forks first, then round any loop left.
        let starts = (0..n as u32)
            .filter(|&p| next[p as usize].len() != 2)
            .chain(0..n as u32);
        for start in starts {
            while let Some(&(to, e)) = next[start as usize].iter().find(|(_, e)| !used[*e]) {
                used[e] = true;
                let mut chain = vec![start, to];
                let mut at = to;
                while next[at as usize].len() == 2 {
                    let Some(&(to, e)) = next[at as usize].iter().find(|(_, e)| !used[*e]) else {
                        break;
                    };
                    used[e] = true;
                    chain.push(to);
                    at = to;
                }
                chains.push(chain);
            }
        }
        chains
    }
}

/// Steps of 1 and sqrt 2 between pixel centres overstate a line's length by
/// up to 8% depending on its direction; this factor (Kulpa 1977) makes the
/// sum unbiased over directions.
pub const CHAIN_CORRECTION: f64 = 0.9481;

/// Pixels around the box searched too, since boxes are drawn tight.
const MARGIN: u32 = 3;
/// Least darkening that counts as a crack, as a share of the surface's
/// brightness (a crack in shade is dark by fewer grey levels), and in grey
/// levels (below that, JPEG noise).
const MIN_CONTRAST: f64 = 0.06;
const MIN_CONTRAST_LEVELS: f64 = 3.0;
/// Darkening, in robust standard deviations of the surface, that counts.
const NOISE_SIGMAS: f64 = 4.0;
/// Share of the darkening above that a pixel joined to clearly dark ones
/// needs to count.
const WEAK_SHARE: f64 = 0.8;
/// Dark blobs smaller than this are texture, not crack, pixels.
const MIN_COMPONENT: usize = 6;
/// Dark areas holding a full square of `2r + 1` pixels a side, r at least
/// this, are shade or another surface, not a crack (a thin line).
const MIN_SHADE_RADIUS: usize = 3;
/// A centre line longer than this many times the box's width plus height
/// is a web of texture, not a crack: in deep shade the surface's grain and
/// the compression's blocks darken by as few grey levels as a crack does.
const MAX_LINE_PER_BOX: f64 = 3.0;

/// Times the window around the box may double while the crack runs on
/// out of it: a detector often boxes only a crack's darkest stretch, and
/// its faint tails go on for several boxes' lengths.
const MAX_DOUBLINGS: u32 = 5;

/// Trace the crack in the box `[x0, y0, x1, y1]` (frame pixels) of `gray`,
/// following it past the box's edges (a detector often boxes only part of a
/// crack) for as long as it runs on; `None` when nothing in the box stands
/// out from the surface, or too much does (a web, not a line: see
/// [`MAX_LINE_PER_BOX`]).
pub fn trace(gray: &GrayImage, bbox: [f32; 4]) -> Option<CrackTrace> {
    let mut reach = first_reach(bbox);
    let mut line = None;
    for _ in 0..=MAX_DOUBLINGS {
        // Nothing, or a web in the wider window: the last line stands.
        let Some((t, runs_on)) = trace_within(gray, bbox, reach) else {
            break;
        };
        line = Some(t);
        if !runs_on {
            break;
        }
        reach *= 2;
    }
    line
}

/// How far past the box the first window reaches, pixels: half its longer
/// side, 8 at least.
fn first_reach(bbox: [f32; 4]) -> u32 {
    (0.5 * (bbox[2] - bbox[0]).max(bbox[3] - bbox[1])).max(8.0) as u32
}

/// [`trace`] in the window `reach` pixels around the box, and whether the
/// line runs on out of that window (it meets a side that is not the
/// image's border).
fn trace_within(gray: &GrayImage, bbox: [f32; 4], reach: u32) -> Option<(CrackTrace, bool)> {
    let (w, h) = gray.dimensions();
    let clip = |v: f32, max: u32| (v.max(0.0) as u32).min(max);
    let inner = [
        clip(bbox[0].floor(), w).saturating_sub(MARGIN),
        clip(bbox[1].floor(), h).saturating_sub(MARGIN),
        (clip(bbox[2].ceil(), w) + MARGIN).min(w),
        (clip(bbox[3].ceil(), h) + MARGIN).min(h),
    ];
    if inner[2] <= inner[0] + 2 || inner[3] <= inner[1] + 2 {
        return None;
    }
    let (x0, y0) = (
        inner[0].saturating_sub(reach),
        inner[1].saturating_sub(reach),
    );
    let (x1, y1) = ((inner[2] + reach).min(w), (inner[3] + reach).min(h));
    let (cw, ch) = (x1 - x0, y1 - y0);
    let values: Vec<u8> = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| gray.get_pixel(x, y).0[0]))
        .collect();
    let in_box = |i: usize| {
        let (x, y) = (x0 + (i % cw as usize) as u32, y0 + (i / cw as usize) as u32);
        (inner[0]..inner[2]).contains(&x) && (inner[1]..inner[3]).contains(&y)
    };
    // The surface is most of the box; a crack is a thin minority of dark pixels.
    let boxed: Vec<u8> = (0..values.len())
        .filter(|i| in_box(*i))
        .map(|i| values[i])
        .collect();
    let median = f64::from(percentile(&boxed, 0.5));
    let deviations: Vec<u8> = boxed
        .iter()
        .map(|v| (f64::from(*v) - median).abs().min(255.0) as u8)
        .collect();
    let sigma = 1.4826 * f64::from(percentile(&deviations, 0.5));
    // Hysteresis, as in Canny: clearly dark pixels find the crack, and
    // faintly dark ones joined to them follow its fading ends.
    let threshold = |share: f64| {
        median
            - share
                * (NOISE_SIGMAS * sigma)
                    .max(MIN_CONTRAST * median)
                    .max(MIN_CONTRAST_LEVELS)
    };
    let (strong, weak) = (threshold(1.0), threshold(WEAK_SHARE));
    let mut mask: Vec<bool> = values.iter().map(|v| f64::from(*v) < weak).collect();
    let shortest_side = (bbox[2] - bbox[0]).min(bbox[3] - bbox[1]).max(0.0) as usize;
    drop_shade(
        &mut mask,
        cw as usize,
        ch as usize,
        (shortest_side / 16).max(MIN_SHADE_RADIUS),
    );
    keep_components(&mut mask, cw as usize, ch as usize, |i| {
        in_box(i) && f64::from(values[i]) < strong
    });
    // The window's growth past the first counts towards the span: a crack
    // followed out of its box is longer than the box.
    let box_span = f64::from((bbox[2] - bbox[0]) + (bbox[3] - bbox[1]))
        + 4.0 * f64::from(reach.saturating_sub(first_reach(bbox)));
    let line = centre_line(mask, [x0, y0, cw, ch])
        .filter(|t| (t.pixels.len() as f64) <= MAX_LINE_PER_BOX * box_span.max(1.0))?;
    let at_side = |p: &Point2<f64>| {
        let (x, y) = (p.x as u32, p.y as u32);
        (x < x0 + 2 && x0 > 0)
            || (y < y0 + 2 && y0 > 0)
            || (x + 2 >= x1 && x1 < w)
            || (y + 2 >= y1 && y1 < h)
    };
    let runs_on = line.pixels.iter().any(at_side);
    Some((line, runs_on))
}

/// Trace the crack a segmenting model marked: the centre line of its
/// pixels (`None` when they are too few to be a crack).
pub fn trace_mask(mask: &Mask) -> Option<CrackTrace> {
    // An empty pixel around (inside the frame), so the thinning sees the
    // mask's edges.
    let (left, top) = (mask.x0.min(1), mask.y0.min(1));
    let (w, h) = (mask.width + left + 1, mask.height + top + 1);
    let mut on = vec![false; (w * h) as usize];
    for (x, y) in mask.pixels() {
        on[((y - mask.y0 + top) * w + x - mask.x0 + left) as usize] = true;
    }
    centre_line(on, [mask.x0 - left, mask.y0 - top, w, h])
}

/// The centre line of the crack pixels `mask` of the window `[x0, y0,
/// width, height]` (frame pixels): holes filled, thinned to one pixel,
/// joined into a spanning forest, faded stretches bridged.
fn centre_line(mut mask: Vec<bool>, [x0, y0, cw, ch]: [u32; 4]) -> Option<CrackTrace> {
    fill_holes(&mut mask, cw as usize, ch as usize);
    thin(&mut mask, cw as usize, ch as usize);
    drop_corners(&mut mask, cw as usize, ch as usize);
    let index: Vec<Option<u32>> = {
        let mut next = 0u32;
        mask.iter()
            .map(|m| {
                m.then(|| {
                    next += 1;
                    next - 1
                })
            })
            .collect()
    };
    let pixels: Vec<Point2<f64>> = (0..mask.len())
        .filter(|i| mask[*i])
        .map(|i| {
            Point2::new(
                f64::from(x0) + (i % cw as usize) as f64 + 0.5,
                f64::from(y0) + (i / cw as usize) as f64 + 0.5,
            )
        })
        .collect();
    if pixels.len() < MIN_COMPONENT {
        return None;
    }
    let edges = spanning_forest(&index, cw as usize, ch as usize, pixels.len());
    let bridges = bridge_gaps(&pixels, &edges);
    Some(CrackTrace {
        pixels,
        edges,
        bridges,
    })
}

fn percentile(values: &[u8], q: f64) -> u8 {
    let mut histogram = [0usize; 256];
    for v in values {
        histogram[*v as usize] += 1;
    }
    let rank = ((values.len() - 1) as f64 * q).round() as usize;
    let mut seen = 0;
    for (v, n) in histogram.iter().enumerate() {
        seen += n;
        if seen > rank {
            return v as u8;
        }
    }
    255
}

const NEIGHBOURS: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Clear the dark areas too wide to be a crack: every pixel within `r + 1`
/// of a fully dark square of `2r + 1` pixels a side. A shaded face or a
/// shadow in the box would otherwise thin to a long line of its own, and
/// a crack running into it would be measured along the shade's edge.
fn drop_shade(mask: &mut [bool], w: usize, h: usize, r: usize) {
    // Summed-area table of `on`, with a zero row and column in front.
    let table = |on: &dyn Fn(usize) -> bool| {
        let mut t = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            for x in 0..w {
                t[(y + 1) * (w + 1) + x + 1] =
                    u32::from(on(y * w + x)) + t[y * (w + 1) + x + 1] + t[(y + 1) * (w + 1) + x]
                        - t[y * (w + 1) + x];
            }
        }
        t
    };
    // Count in the square of radius `r` around pixel `i`, clipped to the image.
    let count = |t: &[u32], i: usize, r: usize| {
        let (x, y) = (i % w, i / w);
        let (x0, y0, x1, y1) = (
            x.saturating_sub(r),
            y.saturating_sub(r),
            (x + r + 1).min(w),
            (y + r + 1).min(h),
        );
        (
            t[y1 * (w + 1) + x1] + t[y0 * (w + 1) + x0]
                - t[y0 * (w + 1) + x1]
                - t[y1 * (w + 1) + x0],
            (x1 - x0) * (y1 - y0),
        )
    };
    let dark = table(&|i| mask[i]);
    let core = table(&|i| {
        let (n, area) = count(&dark, i, r);
        area == (2 * r + 1).pow(2) && n as usize == area
    });
    for (i, pixel) in mask.iter_mut().enumerate() {
        if *pixel && count(&core, i, r + 1).0 > 0 {
            *pixel = false;
        }
    }
}

/// Keep the 8-connected groups of at least [`MIN_COMPONENT`] pixels that
/// have a seed pixel (`seed`: clearly dark, inside the box).
fn keep_components(mask: &mut [bool], w: usize, h: usize, seed: impl Fn(usize) -> bool) {
    let mut seen = vec![false; mask.len()];
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || seen[start] {
            continue;
        }
        let mut group = vec![start];
        seen[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = ((i % w) as i32, (i / w) as i32);
            for (dx, dy) in NEIGHBOURS {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if mask[j] && !seen[j] {
                    seen[j] = true;
                    group.push(j);
                    stack.push(j);
                }
            }
        }
        if group.len() < MIN_COMPONENT || !group.iter().any(|i| seed(*i)) {
            for i in group {
                mask[i] = false;
            }
        }
    }
}

/// Largest hole in the dark pixels filled before thinning, pixels: specks
/// of surface inside a wide crack would thin into loops, measured twice.
const MAX_HOLE: usize = 12;

/// Fill the small enclosed holes of `mask` (4-connected runs of surface
/// pixels that do not reach the window's edge).
fn fill_holes(mask: &mut [bool], w: usize, h: usize) {
    let mut seen = vec![false; mask.len()];
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if mask[start] || seen[start] {
            continue;
        }
        let (mut hole, mut enclosed) = (vec![start], true);
        seen[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                enclosed = false;
            }
            let next = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            for j in next.into_iter().flatten() {
                if !mask[j] && !seen[j] {
                    seen[j] = true;
                    hole.push(j);
                    stack.push(j);
                }
            }
        }
        if enclosed && hole.len() <= MAX_HOLE {
            for i in hole {
                mask[i] = true;
            }
        }
    }
}

/// Zhang-Suen thinning: peel boundary pixels until a one-pixel line remains.
fn thin(mask: &mut [bool], w: usize, h: usize) {
    let at = |m: &[bool], x: i32, y: i32| {
        x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h && m[y as usize * w + x as usize]
    };
    loop {
        let mut changed = false;
        for pass in 0..2 {
            let mut clear = Vec::new();
            for i in 0..mask.len() {
                if !mask[i] {
                    continue;
                }
                let (x, y) = ((i % w) as i32, (i / w) as i32);
                // P2..P9 clockwise from north.
                let p = [
                    at(mask, x, y - 1),
                    at(mask, x + 1, y - 1),
                    at(mask, x + 1, y),
                    at(mask, x + 1, y + 1),
                    at(mask, x, y + 1),
                    at(mask, x - 1, y + 1),
                    at(mask, x - 1, y),
                    at(mask, x - 1, y - 1),
                ];
                let b = p.iter().filter(|v| **v).count();
                let a = (0..8).filter(|k| !p[*k] && p[(k + 1) % 8]).count();
                let (c, d) = if pass == 0 {
                    (p[0] && p[2] && p[4], p[2] && p[4] && p[6])
                } else {
                    (p[0] && p[2] && p[6], p[0] && p[4] && p[6])
                };
                if (2..=6).contains(&b) && a == 1 && !c && !d {
                    clear.push(i);
                }
            }
            changed |= !clear.is_empty();
            for i in clear {
                mask[i] = false;
            }
        }
        if !changed {
            return;
        }
    }
}

/// Clear the pixels thinning leaves at the inner corners of staircases:
/// a pixel (not a line end) whose neighbours stay connected without it.
fn drop_corners(mask: &mut [bool], w: usize, h: usize) {
    // Ring of the 8 neighbours, clockwise from north; even entries are the
    // 4-neighbours, which also touch the 4-neighbour two steps on.
    const RING: [(i32, i32); 8] = [
        (0, -1),
        (1, -1),
        (1, 0),
        (1, 1),
        (0, 1),
        (-1, 1),
        (-1, 0),
        (-1, -1),
    ];
    for i in 0..mask.len() {
        if !mask[i] {
            continue;
        }
        let (x, y) = ((i % w) as i32, (i / w) as i32);
        let set: Vec<bool> = RING
            .iter()
            .map(|(dx, dy)| {
                let (nx, ny) = (x + dx, y + dy);
                nx >= 0
                    && ny >= 0
                    && (nx as usize) < w
                    && (ny as usize) < h
                    && mask[ny as usize * w + nx as usize]
            })
            .collect();
        let count = set.iter().filter(|s| **s).count();
        if count < 2 {
            continue;
        }
        // Flood the set neighbours from one of them.
        let mut reached = [false; 8];
        let first = set.iter().position(|s| *s).expect("a neighbour");
        let mut stack = vec![first];
        reached[first] = true;
        while let Some(k) = stack.pop() {
            let mut next = vec![(k + 1) % 8, (k + 7) % 8];
            if k % 2 == 0 {
                next.extend([(k + 2) % 8, (k + 6) % 8]);
            }
            for n in next {
                if set[n] && !reached[n] {
                    reached[n] = true;
                    stack.push(n);
                }
            }
        }
        if reached.iter().filter(|r| **r).count() == count {
            mask[i] = false;
        }
    }
}

/// Longest gap bridged between pieces of one crack, pixels.
const MAX_GAP_PX: f64 = 20.0;
/// Largest angle between a piece's direction at its end and the gap.
const MAX_GAP_TURN_DEG: f64 = 45.0;
/// Pixels back along a piece its direction at an end is taken over.
const END_DIRECTION_PX: usize = 6;

/// Join the pieces of a crack that faded below the threshold in places (a
/// hairline crack's darkening comes and goes along it): an end of one piece
/// is joined to an end of another when the gap is short and continues both
/// pieces' directions, so the gap counts towards the length while texture
/// beside the crack, or a parallel crack, stays apart. Shortest gaps first,
/// never closing a loop.
fn bridge_gaps(pixels: &[Point2<f64>], edges: &[(u32, u32)]) -> Vec<(u32, u32)> {
    let n = pixels.len();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for &(a, b) in edges {
        neighbours[a as usize].push(b);
        neighbours[b as usize].push(a);
    }
    let mut pieces = UnionFind::new(n);
    for &(a, b) in edges {
        pieces.join(a as usize, b as usize);
    }
    // Each end with the direction its piece runs out of it.
    let ends: Vec<(u32, nalgebra::Vector2<f64>)> = (0..n)
        .filter(|&i| neighbours[i].len() == 1)
        .filter_map(|i| {
            let (mut previous, mut at) = (i, i);
            for _ in 0..END_DIRECTION_PX {
                let Some(&next) = neighbours[at].iter().find(|&&k| k as usize != previous) else {
                    break;
                };
                (previous, at) = (at, next as usize);
            }
            let out = pixels[i] - pixels[at];
            (out.norm() >= 2.0).then(|| (i as u32, out.normalize()))
        })
        .collect();
    let cos_turn = MAX_GAP_TURN_DEG.to_radians().cos();
    let mut gaps: Vec<(f64, u32, u32)> = Vec::new();
    for (k, (a, out_a)) in ends.iter().enumerate() {
        for (b, out_b) in &ends[k + 1..] {
            let gap = pixels[*b as usize] - pixels[*a as usize];
            let length = gap.norm();
            if length <= MAX_GAP_PX
                && out_a.dot(&gap) >= cos_turn * length
                && out_b.dot(&-gap) >= cos_turn * length
            {
                gaps.push((length, *a, *b));
            }
        }
    }
    gaps.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut used = vec![false; n];
    let mut bridges = Vec::new();
    for (_, a, b) in gaps {
        if !used[a as usize] && !used[b as usize] && pieces.join(a as usize, b as usize) {
            used[a as usize] = true;
            used[b as usize] = true;
            bridges.push((a, b));
        }
    }
    bridges
}

/// Kruskal over the 8-neighbour grid graph: straight steps (length 1)
/// before diagonal ones (length sqrt 2), so a staircase is not counted twice.
fn spanning_forest(index: &[Option<u32>], w: usize, h: usize, n: usize) -> Vec<(u32, u32)> {
    let mut pieces = UnionFind::new(n);
    let mut edges = Vec::new();
    for steps in [[(1, 0), (0, 1)], [(1, 1), (-1, 1)]] {
        for y in 0..h {
            for x in 0..w {
                let Some(a) = index[y * w + x] else { continue };
                for (dx, dy) in steps {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let Some(b) = index[ny as usize * w + nx as usize] else {
                        continue;
                    };
                    if pieces.join(a as usize, b as usize) {
                        edges.push((a, b));
                    }
                }
            }
        }
    }
    edges
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    /// A grey, slightly noisy surface with a dark line drawn from `a` to `b`,
    /// `width` pixels wide.
    fn line_image(a: (f64, f64), b: (f64, f64), width: f64) -> GrayImage {
        let mut k = 7u32;
        GrayImage::from_fn(200, 150, |x, y| {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let noise = (k >> 16) % 5;
            let p = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            let d = (b.0 - a.0, b.1 - a.1);
            let s =
                (((p.0 - a.0) * d.0 + (p.1 - a.1) * d.1) / (d.0 * d.0 + d.1 * d.1)).clamp(0.0, 1.0);
            let off = ((p.0 - a.0 - s * d.0).powi(2) + (p.1 - a.1 - s * d.1).powi(2)).sqrt();
            Luma([if off <= width / 2.0 {
                50
            } else {
                120 + noise as u8
            }])
        })
    }

    #[test]
    fn a_thick_diagonal_line_traces_to_its_length() {
        for (a, b, width) in [
            ((30.0, 20.0), (170.0, 130.0), 3.0),
            ((40.0, 75.0), (160.0, 75.0), 1.2),
            ((100.0, 10.0), (110.0, 140.0), 2.0),
        ] {
            let img = line_image(a, b, width);
            let t = trace(&img, [20.0, 5.0, 180.0, 145.0]).unwrap();
            let truth = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
            let at: Vec<_> = t.pixels.iter().map(|p| Some(p.coords)).collect();
            let len = t.length(&at);
            assert!(
                (len - truth).abs() / truth < 0.1,
                "traced {len:.1} px of a {truth:.1} px line"
            );
            // One connected line: a spanning tree has one edge fewer than pixels.
            assert_eq!(t.edges.len(), t.pixels.len() - 1);
            // Every traced pixel lies on the line.
            assert!(t.pixels.iter().all(|p| {
                let d = (b.0 - a.0, b.1 - a.1);
                let cross = ((p.x - a.0) * d.1 - (p.y - a.1) * d.0).abs() / truth;
                cross <= width / 2.0 + 1.0
            }));
        }
    }

    #[test]
    fn shade_in_the_box_is_not_measured_as_crack() {
        // A crack that ends at a shaded face, which fills a corner of the box.
        let (a, b) = ((30.0, 20.0), (148.0, 72.0));
        let mut img = line_image(a, b, 2.0);
        for y in 70..150 {
            for x in 150..175 {
                img.put_pixel(x, y, Luma([60]));
            }
        }
        let t = trace(&img, [20.0, 5.0, 180.0, 145.0]).unwrap();
        let at: Vec<_> = t.pixels.iter().map(|p| Some(p.coords)).collect();
        let truth = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        let len = t.length(&at);
        assert!(
            (len - truth).abs() / truth < 0.1,
            "traced {len:.1} px of a {truth:.1} px crack beside shade"
        );
        assert!(t.pixels.iter().all(|p| p.x < 150.0));
    }

    #[test]
    fn a_crack_fading_out_is_followed_to_its_end() {
        // On a flat 120 surface the clear threshold is 6% darker (112.8)
        // and the faint one 80% of that (114.2): the last 40% of this crack
        // is only faintly dark, and is traced because it joins the rest.
        let (a, b) = ((30.0, 75.0), (170.0, 75.0));
        let img = GrayImage::from_fn(200, 150, |x, y| {
            let on = (f64::from(y) + 0.5 - a.1).abs() <= 1.0 && (30..170).contains(&x);
            Luma([match (on, x < 114) {
                (false, _) => 120,
                (true, true) => 90,
                (true, false) => 113,
            }])
        });
        let t = trace(&img, [20.0, 5.0, 180.0, 145.0]).unwrap();
        let at: Vec<_> = t.pixels.iter().map(|p| Some(p.coords)).collect();
        let (len, truth) = (t.length(&at), b.0 - a.0);
        assert!(
            (len - truth).abs() / truth < 0.1,
            "traced {len:.1} px of a {truth:.1} px fading crack"
        );
        // A surface that dark all over is not a crack at all.
        let faint = GrayImage::from_fn(200, 150, |x, y| {
            let on = (f64::from(y) + 0.5 - a.1).abs() <= 1.0 && (30..170).contains(&x);
            Luma([if on { 113 } else { 120 }])
        });
        assert!(trace(&faint, [20.0, 5.0, 180.0, 145.0]).is_none());
    }

    #[test]
    fn a_crack_boxed_at_its_darkest_is_followed_far_out_of_the_box() {
        // Dark only where the detector boxed it (x 280 to 320), faintly dark
        // for 260 pixels either side: the window doubles until the line
        // ends inside it.
        let img = GrayImage::from_fn(600, 100, |x, y| {
            let on = (f64::from(y) + 0.5 - 50.0).abs() <= 1.0 && (20..580).contains(&x);
            Luma([match (on, (280..320).contains(&x)) {
                (false, _) => 120,
                (true, true) => 60,
                (true, false) => 113,
            }])
        });
        let t = trace(&img, [276.0, 44.0, 324.0, 56.0]).unwrap();
        let at: Vec<_> = t.pixels.iter().map(|p| Some(p.coords)).collect();
        let len = t.length(&at);
        assert!(
            (len - 560.0).abs() / 560.0 < 0.1,
            "traced {len:.1} px of 560"
        );
    }

    /// `line_image` with the line broken: every `period` pixels along it,
    /// `gap` pixels of plain surface.
    fn broken_line(a: (f64, f64), b: (f64, f64), period: f64, gap: f64) -> GrayImage {
        let mut img = line_image(a, b, 1.5);
        let plain = line_image((0.0, 0.0), (0.0, 0.0), 0.0);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = (dx * dx + dy * dy).sqrt();
        for (x, y, p) in img.enumerate_pixels_mut() {
            let s = ((f64::from(x) + 0.5 - a.0) * dx + (f64::from(y) + 0.5 - a.1) * dy) / len;
            if s > 0.0 && s < len && s % period >= period - gap {
                *p = *plain.get_pixel(x, y);
            }
        }
        img
    }

    fn traced_length(img: &GrayImage, bbox: [f32; 4]) -> f64 {
        let t = trace(img, bbox).expect("a trace");
        let at: Vec<Option<nalgebra::Vector2<f64>>> =
            t.pixels.iter().map(|p| Some(p.coords)).collect();
        t.length(&at)
    }

    #[test]
    fn a_crack_that_fades_in_places_is_measured_across_its_gaps() {
        // 100 px long, broken for 6 px in every 20.
        let img = broken_line((40.0, 40.0), (120.0, 100.0), 20.0, 6.0);
        // Drawn: from 0 to 94 px along the line (the last 6 px are a gap).
        let length = traced_length(&img, [38.0, 38.0, 122.0, 102.0]);
        assert!((length - 94.0).abs() <= 6.0, "length {length}");
        // Unbridged, the pieces would add up to about 50 px.
        let t = trace(&img, [38.0, 38.0, 122.0, 102.0]).unwrap();
        assert_eq!(t.bridges.len(), 4);
    }

    #[test]
    fn parallel_cracks_are_not_joined_sideways() {
        // Two 60 px lines 8 px apart, side by side: two pieces, no bridge.
        let mut img = line_image((40.0, 40.0), (100.0, 40.0), 1.5);
        let other = line_image((40.0, 48.0), (100.0, 48.0), 1.5);
        for (x, y, p) in img.enumerate_pixels_mut() {
            p.0[0] = p.0[0].min(other.get_pixel(x, y).0[0]);
        }
        let t = trace(&img, [38.0, 36.0, 102.0, 52.0]).unwrap();
        assert!(t.bridges.is_empty(), "{:?}", t.bridges);
        let length = traced_length(&img, [38.0, 36.0, 102.0, 52.0]);
        assert!((length - 120.0).abs() <= 10.0, "length {length}");
    }

    #[test]
    fn grain_in_deep_shade_is_a_web_not_a_crack() {
        // Dark concrete whose grain darkens a third of the pixels by as
        // many grey levels as a crack.
        let mut k = 11u32;
        let img = GrayImage::from_fn(200, 150, |_, _| {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12345);
            Luma([if (k >> 16).is_multiple_of(3) { 30 } else { 40 }])
        });
        assert!(trace(&img, [60.0, 40.0, 140.0, 110.0]).is_none());
    }

    #[test]
    fn a_plain_surface_has_no_trace() {
        let img = line_image((-50.0, -50.0), (-40.0, -40.0), 1.0);
        assert!(trace(&img, [10.0, 10.0, 100.0, 100.0]).is_none());
        // A box off the image or empty.
        assert!(trace(&img, [300.0, 10.0, 400.0, 100.0]).is_none());
        assert!(trace(&img, [10.0, 10.0, 10.0, 10.0]).is_none());
    }
}

//! Cracks: thin, dark, branching polylines drawn on the structure's surfaces
//! at seeded random places, millimetres wide: of one even width (the default
//! flights), or opening and closing along their length (flights made to
//! measure width).

use nalgebra::{Point3, Vector3};

use crate::rng::Rng;
use crate::scene::{FacePicker, Scene};
use crate::section::Section;

/// One crack on one planar face of the structure.
#[derive(Debug, Clone)]
pub struct Crack {
    pub id: u32,
    /// The main line, then its branches; each a polyline on the surface.
    pub lines: Vec<Vec<Point3<f64>>>,
    /// Width of the opening, metres: its widest.
    pub width: f64,
    /// How the opening varies along the crack.
    pub opening: Opening,
    /// Outward unit normal of the face it lies on.
    pub normal: Vector3<f64>,
    /// The pattern it is one crack of, if any.
    pub pattern: Option<Pattern>,
    /// A triangle of the face it starts on.
    pub triangle: u32,
    pub(crate) center: Point3<f64>,
    pub(crate) radius: f64,
    /// Arc length at each point of each line, metres.
    arc: Vec<Vec<f64>>,
    /// Width where each branch leaves the main line, metres (the main line's own: `width`).
    roots: Vec<f64>,
}

/// The widths cracks open to, millimetres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WidthRange {
    pub min_mm: f64,
    pub max_mm: f64,
}

impl WidthRange {
    /// `MIN,MAX` millimetres.
    pub fn parse(s: &str) -> Result<Self, String> {
        match postflight_core::setting::comma_numbers(s).as_deref() {
            Some(&[min_mm, max_mm]) if 0.0 < min_mm && min_mm <= max_mm && max_mm < 100.0 => {
                Ok(Self { min_mm, max_mm })
            }
            _ => Err(format!(
                "expected two widths MIN,MAX in millimetres, 0 < MIN <= MAX < 100, not '{s}'"
            )),
        }
    }
}

/// How a crack's opening varies along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Opening {
    /// One width everywhere, drawn where a pixel centre falls on the crack
    /// (as the default flights always have been).
    Even,
    /// Widest mid-way along the main line, closing to `tip` metres at its
    /// ends; a branch leaves at the main line's width there and closes to
    /// `tip`. Its opening ragged, its cross-section `section` (a V to a U,
    /// spalled edges, dirt); drawn by the darkness each pixel's footprint
    /// across it holds, so its width can be measured below a pixel.
    Tapered { tip: f64, section: Section },
}

/// The nearest point of a crack's centre line to a query point.
#[derive(Debug, Clone, Copy)]
pub struct Nearest {
    pub distance: f64,
    /// The crack's width there, metres.
    pub width: f64,
    /// The line it is on, and the arc length along it, metres.
    pub line: usize,
    pub arc: f64,
    /// Unit direction of the centre line there.
    pub along: Vector3<f64>,
}

impl Crack {
    /// The crack's width at arc length `s` along line `line`, metres.
    pub fn width_at(&self, line: usize, s: f64) -> f64 {
        match self.opening {
            Opening::Even => self.width,
            Opening::Tapered { tip, section } => {
                let length = self.arc[line].last().copied().unwrap_or(0.0).max(1e-9);
                let t = (s / length).clamp(0.0, 1.0);
                let (root, shape) = if line == 0 {
                    (self.width, (std::f64::consts::PI * t).sin())
                } else {
                    (
                        self.roots[line - 1],
                        (std::f64::consts::FRAC_PI_2 * t).cos(),
                    )
                };
                tip + (root - tip).max(0.0) * shape.max(0.0).sqrt() * section.opening(line, s)
            }
        }
    }

    /// The width at every point of every line, metres.
    pub fn widths(&self) -> Vec<Vec<f64>> {
        self.arc
            .iter()
            .enumerate()
            .map(|(l, arc)| arc.iter().map(|s| self.width_at(l, *s)).collect())
            .collect()
    }

    /// The nearest point of the centre line to `p`.
    pub fn nearest(&self, p: &Point3<f64>) -> Nearest {
        let mut best = Nearest {
            distance: f64::INFINITY,
            width: self.width,
            line: 0,
            arc: 0.0,
            along: Vector3::x(),
        };
        for (l, line) in self.lines.iter().enumerate() {
            for (k, w) in line.windows(2).enumerate() {
                let ab = w[1] - w[0];
                let len2 = ab.norm_squared().max(1e-18);
                let s = ((p - w[0]).dot(&ab) / len2).clamp(0.0, 1.0);
                let d = (p - (w[0] + ab * s)).norm();
                if d < best.distance {
                    let arc = self.arc[l][k] + s * len2.sqrt();
                    best = Nearest {
                        distance: d,
                        width: self.width_at(l, arc),
                        line: l,
                        arc,
                        along: ab / len2.sqrt(),
                    };
                }
            }
        }
        best
    }

    pub fn segments(&self) -> impl Iterator<Item = (Point3<f64>, Point3<f64>)> + '_ {
        self.lines
            .iter()
            .flat_map(|l| l.windows(2).map(|w| (w[0], w[1])))
    }

    /// Total length of all its lines, metres.
    pub fn length(&self) -> f64 {
        self.segments().map(|(a, b)| (b - a).norm()).sum()
    }

    /// Points along the crack about `step` metres apart, with its width
    /// at each.
    pub fn samples(&self, step: f64) -> Vec<(Point3<f64>, f64)> {
        let mut out = Vec::new();
        for (l, line) in self.lines.iter().enumerate() {
            for (i, w) in line.windows(2).enumerate() {
                let (a, b) = (w[0], w[1]);
                let len = (b - a).norm();
                let n = (len / step).ceil().max(1.0) as usize;
                out.extend((0..n).map(|k| {
                    let t = k as f64 / n as f64;
                    (a + (b - a) * t, self.width_at(l, self.arc[l][i] + t * len))
                }));
            }
        }
        out
    }

    pub fn centroid(&self) -> Point3<f64> {
        self.center
    }
}

/// How far a crack's heading wanders a step, radians (one standard
/// deviation).
const WANDER: f64 = 0.35;
/// A pattern of cracks side by side: its number (from 0) and how far apart
/// its cracks were drawn.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Pattern {
    pub number: u32,
    pub spacing_m: f64,
}

/// How far a pattern's crack strays aside a step, metres (one standard
/// deviation, smoothed along it): it keeps its spacing to its neighbours.
const PATTERN_STRAY_M: f64 = 0.002;

/// Share of the light the interior of a crack of one even width lacks.
const EVEN_DEPTH: f64 = 0.85;

/// All the cracks of a scene, with the query the renderer needs.
pub struct Cracks(pub Vec<Crack>);

impl Cracks {
    /// Draw `count` cracks on the structure's surfaces.
    pub fn generate(scene: &Scene, count: usize, rng: &mut Rng) -> Self {
        let mut cracks = Self(Vec::new());
        cracks.add(scene, count, rng);
        cracks
    }

    /// Draw `count` more cracks, clear of those there are, numbered on from
    /// them; how many it drew (fewer when the structure runs out of room).
    pub fn add(&mut self, scene: &Scene, count: usize, rng: &mut Rng) -> usize {
        let faces = FacePicker::new(scene, 0.05);
        let cracks = &mut self.0;
        let (before, mut attempts) = (cracks.len(), 0);
        while cracks.len() < before + count && attempts < count * 50 {
            attempts += 1;
            let Some(face) = faces.pick(rng) else {
                break;
            };
            if let Some(c) = grow(scene, face, cracks.len() as u32, rng)
                && cracks
                    .iter()
                    .all(|o: &Crack| (o.center - c.center).norm() > o.radius + c.radius + 0.3)
            {
                cracks.push(c);
            }
        }
        cracks.len() - before
    }

    /// Draw `groups` patterns of cracks: each three to five cracks side by
    /// side on one face (an element's map or transverse cracking, which
    /// the manual judges by the spacing), half of them heavy (0.10 to
    /// 0.25 m apart), half moderate (0.35 to 0.8 m), each crack opening
    /// within `widths`, clear of the cracks there are; how many patterns it
    /// drew.
    pub fn add_patterns(
        &mut self,
        scene: &Scene,
        groups: usize,
        widths: WidthRange,
        rng: &mut Rng,
    ) -> usize {
        let faces = FacePicker::new(scene, 0.05);
        let (mut drawn, mut attempts) = (0, 0);
        while drawn < groups && attempts < groups * 50 {
            attempts += 1;
            let Some(face) = faces.pick(rng) else {
                break;
            };
            let number = drawn as u32;
            let Some(mut group) = pattern(scene, face, self.0.len() as u32, number, rng) else {
                continue;
            };
            let clear = group.iter().all(|c| {
                self.0
                    .iter()
                    .all(|o| (o.center - c.center).norm() > o.radius + c.radius + 0.3)
            });
            if clear {
                for c in &mut group {
                    c.taper(widths, rng);
                }
                self.0.extend(group);
                drawn += 1;
            }
        }
        drawn
    }

    /// Open every crack along its length within `range`: widest mid-way
    /// (log-uniform between the range's ends), closing to its narrowest at
    /// the tips. The lines stay as they were drawn.
    pub fn taper(&mut self, range: WidthRange, rng: &mut Rng) {
        // A pattern's cracks open within the pattern's own widths.
        for c in self.0.iter_mut().filter(|c| c.pattern.is_none()) {
            c.taper(range, rng);
        }
    }

    /// The share of a pixel's light a crack takes (0 to 1) where the pixel
    /// is centred at the surface point `p`, for a ray along `dir` whose
    /// pixel spans `footprint` metres on the surface where it is most
    /// stretched; `pixel` is the pixel's footprint across the ray, metres.
    pub fn darkness(&self, p: &Point3<f64>, dir: &Vector3<f64>, footprint: f64, pixel: f64) -> f64 {
        let mut best: f64 = 0.0;
        for c in &self.0 {
            // Off the crack's plane first: it rules out most cracks, and
            // without a square root.
            let off = p - c.center;
            if off.dot(&c.normal).abs() > 0.02 || off.norm() > c.radius + footprint {
                continue;
            }
            let near = c.nearest(p);
            let share = match c.opening {
                Opening::Even => {
                    // Area fraction of a crack of width w in a footprint of
                    // width f, its interior 85% dark.
                    let reach = footprint.max(c.width) / 2.0;
                    if near.distance < reach {
                        EVEN_DEPTH * (c.width / footprint).min(1.0)
                    } else {
                        0.0
                    }
                }
                Opening::Tapered { section, .. } => {
                    // The pixel's extent on the surface across the crack,
                    // and the darkness the section holds over it.
                    let across = c.normal.cross(&near.along);
                    let f = pixel / (1.0 - across.dot(dir).powi(2)).max(1e-6).sqrt();
                    let reach = section.reach(near.width);
                    let (lo, hi) = (
                        (near.distance - f / 2.0).max(-reach),
                        (near.distance + f / 2.0).min(reach),
                    );
                    if hi <= lo {
                        0.0
                    } else {
                        (section.across(near.line, near.arc, lo, hi, near.width) / f).min(1.0)
                    }
                }
            };
            best = best.max(share);
        }
        best
    }
}

/// Random walks in the plane of one face of the structure.
pub(crate) struct FaceWalk<'a> {
    scene: &'a Scene,
    pub normal: Vector3<f64>,
    /// Axes in the face's plane.
    pub u: Vector3<f64>,
    pub v: Vector3<f64>,
}

impl<'a> FaceWalk<'a> {
    pub fn new(scene: &'a Scene, triangle: u32) -> Self {
        let [a, b, _] = scene.triangles[triangle as usize];
        let normal = scene.normal(triangle);
        let u = (b - a).normalize();
        Self {
            scene,
            normal,
            u,
            v: normal.cross(&u),
        }
    }

    pub fn on_face(&self, p: &Point3<f64>) -> bool {
        self.scene
            .cast(&(p + self.normal * 0.05), &-self.normal, 0.1)
            .is_some_and(|h| {
                (h.distance - 0.05).abs() < 1e-3
                    && self.scene.normal(h.triangle).dot(&self.normal) > 0.999
            })
    }

    /// A wandering line from `from` at `heading` (radians from `u`): up to
    /// `steps` steps, or until it has `length` metres, or leaves the face.
    fn walk(
        &self,
        from: Point3<f64>,
        heading: f64,
        steps: usize,
        length: f64,
        rng: &mut Rng,
    ) -> Vec<Point3<f64>> {
        let mut line = vec![from];
        let (mut h, mut walked) = (heading, 0.0);
        for _ in 0..steps {
            if walked >= length {
                break;
            }
            h += rng.normal() * WANDER;
            let step = rng.range(0.025, 0.05);
            let next = line[line.len() - 1] + (self.u * h.cos() + self.v * h.sin()) * step;
            if !self.on_face(&next) {
                break;
            }
            line.push(next);
            walked += step;
        }
        line
    }

    /// A nearly straight line from `from` at `heading`, `length` metres or
    /// until it leaves the face: a pattern's crack, which keeps its spacing
    /// to its neighbours; it strays from the straight line a few
    /// millimetres, smoothly.
    fn straight(
        &self,
        from: Point3<f64>,
        heading: f64,
        length: f64,
        rng: &mut Rng,
    ) -> Vec<Point3<f64>> {
        let along = self.u * heading.cos() + self.v * heading.sin();
        let aside = self.normal.cross(&along);
        let (mut line, mut walked, mut off) = (vec![from], 0.0, 0.0);
        while walked < length {
            walked += rng.range(0.025, 0.05);
            off = 0.8 * off + rng.normal() * PATTERN_STRAY_M;
            let next = from + along * walked + aside * off;
            if !self.on_face(&next) {
                break;
            }
            line.push(next);
        }
        line
    }

    /// The heading of the step from `a` to `b`.
    fn heading(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let d = b - a;
        d.dot(&self.v).atan2(d.dot(&self.u))
    }
}

/// Where a crack starts on `triangle`, uniformly over it, and the way it
/// heads (radians from the face's first axis).
fn start_on(scene: &Scene, triangle: u32, rng: &mut Rng) -> (Point3<f64>, f64) {
    let [a, b, c] = scene.triangles[triangle as usize];
    let (mut s, mut t) = (rng.uniform(), rng.uniform());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    let start = a + (b - a) * s + (c - a) * t;
    (start, rng.range(0.0, std::f64::consts::TAU))
}

/// Grow one crack on the face of `triangle` by a random walk in its plane.
fn grow(scene: &Scene, triangle: u32, id: u32, rng: &mut Rng) -> Option<Crack> {
    let face = FaceWalk::new(scene, triangle);
    let (start, heading) = start_on(scene, triangle, rng);
    let main = face.walk(
        start,
        heading,
        14 + (rng.uniform() * 10.0) as usize,
        f64::INFINITY,
        rng,
    );
    let mut lines = vec![main];
    for _ in 0..(rng.uniform() * 3.0) as usize {
        let at = lines[0][(rng.uniform() * lines[0].len() as f64) as usize];
        let side = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
        let branch = face.walk(
            at,
            heading + side * rng.range(0.5, 1.2),
            4 + (rng.uniform() * 6.0) as usize,
            f64::INFINITY,
            rng,
        );
        if branch.len() > 2 {
            lines.push(branch);
        }
    }
    let crack = Crack::even(id, lines, rng.range(0.001, 0.005), &face, triangle, None);
    (crack.length() >= 0.3).then_some(crack)
}

/// Pattern `number`: cracks side by side on the face of `triangle`,
/// numbered from `first_id`; `None` where one would not fit on the face.
fn pattern(
    scene: &Scene,
    triangle: u32,
    first_id: u32,
    number: u32,
    rng: &mut Rng,
) -> Option<Vec<Crack>> {
    let face = FaceWalk::new(scene, triangle);
    let (start, heading) = start_on(scene, triangle, rng);
    let count = 3 + (rng.uniform() * 3.0) as usize;
    // Heavy or moderate, clear of the limit between them (0.3 m).
    let spacing = if rng.uniform() < 0.5 {
        rng.range(0.10, 0.25)
    } else {
        rng.range(0.35, 0.8)
    };
    let length = rng.range(0.5, 1.2);
    // Along the heading drawn, else across it (a narrow face has room one
    // way only).
    [heading, heading + std::f64::consts::FRAC_PI_2]
        .into_iter()
        .find_map(|heading| {
            let side = heading + std::f64::consts::FRAC_PI_2;
            let across = face.u * side.cos() + face.v * side.sin();
            (0..count)
                .map(|k| {
                    let from = start + across * (spacing * k as f64);
                    if !face.on_face(&from) {
                        return None;
                    }
                    let line = face.straight(from, heading, length, rng);
                    let pattern = Pattern {
                        number,
                        spacing_m: spacing,
                    };
                    let id = first_id + k as u32;
                    let width = rng.range(0.001, 0.005);
                    let crack = Crack::even(id, vec![line], width, &face, triangle, Some(pattern));
                    (crack.length() >= 0.6 * length).then_some(crack)
                })
                .collect()
        })
}

impl Crack {
    /// A crack `width` metres wide along `lines` on `face` (the face of
    /// `triangle`).
    fn even(
        id: u32,
        lines: Vec<Vec<Point3<f64>>>,
        width: f64,
        face: &FaceWalk,
        triangle: u32,
        pattern: Option<Pattern>,
    ) -> Self {
        Self {
            id,
            lines,
            width,
            opening: Opening::Even,
            normal: face.normal,
            pattern,
            triangle,
            center: Point3::origin(),
            radius: 0.0,
            arc: Vec::new(),
            roots: Vec::new(),
        }
        .with_bounds()
    }

    /// With its centre, radius, arc lengths and branch roots recomputed
    /// from its lines.
    fn with_bounds(mut self) -> Self {
        self.arc = self
            .lines
            .iter()
            .map(|l| {
                let mut s = 0.0;
                std::iter::once(0.0)
                    .chain(l.windows(2).map(|w| {
                        s += (w[1] - w[0]).norm();
                        s
                    }))
                    .collect()
            })
            .collect();
        self.roots = self.lines[1..]
            .iter()
            .map(|branch| {
                let main = &self.lines[0];
                let k = (0..main.len())
                    .min_by(|a, b| {
                        (main[*a] - branch[0])
                            .norm()
                            .total_cmp(&(main[*b] - branch[0]).norm())
                    })
                    .unwrap_or(0);
                self.width_at(0, self.arc[0][k])
            })
            .collect();
        let points: Vec<Point3<f64>> = self.lines.iter().flatten().copied().collect();
        self.center = Point3::from(
            points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64,
        );
        self.radius = points
            .iter()
            .map(|p| (p - self.center).norm())
            .fold(0.0, f64::max);
        self
    }

    /// The crack grown along its main line by about `by` metres, from the
    /// end with more room on the face (a crack grows at its tips); the
    /// metres it grew.
    pub fn extend(&mut self, scene: &Scene, by: f64, rng: &mut Rng) -> f64 {
        let face = FaceWalk::new(scene, self.triangle);
        let main = &self.lines[0];
        let n = main.len();
        // A crack the face's edge stopped at its first point has no tip
        // direction to grow along.
        if n < 2 {
            return 0.0;
        }
        let tips = [(main[n - 1], main[n - 2]), (main[0], main[1])];
        let steps = (by / 0.025).ceil() as usize + 1;
        let walks: Vec<Vec<Point3<f64>>> = tips
            .iter()
            .map(|(tip, before)| face.walk(*tip, face.heading(before, tip), steps, by, rng))
            .collect();
        let length = |l: &[Point3<f64>]| l.windows(2).map(|w| (w[1] - w[0]).norm()).sum::<f64>();
        let (longer, at_end) = if length(&walks[0]) >= length(&walks[1]) {
            (&walks[0], true)
        } else {
            (&walks[1], false)
        };
        let grown = length(longer);
        let main = &mut self.lines[0];
        if at_end {
            main.extend(longer.iter().skip(1));
        } else {
            let mut line: Vec<Point3<f64>> = longer.iter().skip(1).rev().copied().collect();
            line.append(main);
            *main = line;
        }
        *self = self.clone().with_bounds();
        grown
    }

    /// Open the crack along its length within `range` (see [`Cracks::taper`]).
    pub fn taper(&mut self, range: WidthRange, rng: &mut Rng) {
        let (lo, hi) = (range.min_mm / 1000.0, range.max_mm / 1000.0);
        self.width = lo * (hi / lo).powf(rng.uniform());
        self.opening = Opening::Tapered {
            tip: lo,
            section: Section::of(self.id),
        };
        *self = self.clone().with_bounds();
    }

    /// The crack opened `factor` times wider along its whole length (its
    /// tips stay hairline).
    pub fn widen(&mut self, factor: f64) {
        self.width *= factor;
        *self = self.clone().with_bounds();
    }

    /// The crack in another frame.
    pub fn transformed(&self, iso: &nalgebra::Isometry3<f64>) -> Self {
        Self {
            lines: self
                .lines
                .iter()
                .map(|l| l.iter().map(|p| iso * p).collect())
                .collect(),
            normal: iso * self.normal,
            center: iso * self.center,
            ..self.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point of `c` lies on the structure's surface.
    fn assert_on_surface(scene: &Scene, c: &Crack) {
        for (p, _) in c.samples(0.05) {
            let hit = scene.cast(&(p + c.normal * 0.2), &-c.normal, 1.0).unwrap();
            assert!(
                (hit.distance - 0.2).abs() < 1e-3,
                "crack {} leaves its surface",
                c.id
            );
        }
    }

    #[test]
    fn patterns_are_cracks_side_by_side_on_one_face() {
        let scene = Scene::girder_bridge();
        let mut cracks = Cracks::generate(&scene, 5, &mut Rng::new(7));
        let fine = WidthRange::parse("0.4,1.0").unwrap();
        assert_eq!(cracks.add_patterns(&scene, 3, fine, &mut Rng::new(8)), 3);
        let added = &cracks.0[5..];
        assert!((9..=15).contains(&added.len()), "{}", added.len());
        // Each crack runs beside the next of its pattern, a steady spacing
        // apart on the same face.
        for pair in added.windows(2).filter(|p| p[0].triangle == p[1].triangle) {
            let (a, b) = (&pair[0], &pair[1]);
            assert!(a.normal.dot(&b.normal) > 0.999);
            let gaps: Vec<f64> = a.lines[0].iter().map(|p| b.nearest(p).distance).collect();
            let (lo, hi) = gaps
                .iter()
                .fold((f64::MAX, 0.0f64), |(l, h), g| (l.min(*g), h.max(*g)));
            assert!(lo > 0.05 && hi < 1.2, "{lo} {hi}");
        }
        for c in added {
            assert!(c.pattern.is_some() && (0.0004..=0.001).contains(&c.width));
            assert_on_surface(&scene, c);
        }
    }

    #[test]
    fn cracks_lie_on_the_structure_and_are_seeded() {
        let scene = Scene::girder_bridge();
        let cracks = Cracks::generate(&scene, 12, &mut Rng::new(7));
        assert_eq!(cracks.0.len(), 12);
        for c in &cracks.0 {
            assert!(c.length() >= 0.3 && c.width < 0.0051);
            assert_on_surface(&scene, c);
        }
        let again = Cracks::generate(&scene, 12, &mut Rng::new(7));
        assert_eq!(again.0[5].lines, cracks.0[5].lines);
        // A point on a crack is covered; one a metre away is not.
        let c = &cracks.0[0];
        let p = c.lines[0][1];
        let dir = -c.normal;
        assert!(cracks.darkness(&p, &dir, 0.004, 0.004) > 0.05);
        assert_eq!(
            cracks.darkness(&(p + c.normal * 1.5), &dir, 0.004, 0.004),
            0.0
        );
    }

    #[test]
    fn tapered_cracks_are_widest_mid_way_and_darken_a_pixel_by_their_section() {
        let scene = Scene::girder_bridge();
        let mut cracks = Cracks::generate(&scene, 6, &mut Rng::new(7));
        let lines: Vec<_> = cracks.0.iter().map(|c| c.lines.clone()).collect();
        let range = WidthRange {
            min_mm: 0.1,
            max_mm: 5.0,
        };
        cracks.taper(range, &mut Rng::new(8));
        for (c, lines) in cracks.0.iter().zip(&lines) {
            assert_eq!(&c.lines, lines, "tapering moves no line");
            assert!((0.0001..=0.005).contains(&c.width));
            let widths = c.widths();
            let main = &widths[0];
            assert!(
                (main[0] - 0.0001).abs() < 1e-9 && (main[main.len() - 1] - 0.0001).abs() < 1e-9
            );
            let widest = main.iter().copied().fold(0.0, f64::max);
            assert!(widest <= c.width + 1e-12 && widest > 0.7 * c.width);
            for (b, branch) in widths.iter().enumerate().skip(1) {
                assert!(
                    branch[0] <= c.width + 1e-12,
                    "branch {b} starts wider than the crack"
                );
            }
        }
        // Seen face on through a pixel 4 mm across, the pixel lacks the
        // light its section takes summed across it, over 4 mm.
        let c = &cracks.0[0];
        let k = c.lines[0].len() / 2;
        let p = c.lines[0][k];
        let near = c.nearest(&p);
        let Opening::Tapered { section, .. } = c.opening else {
            panic!("tapered");
        };
        let reach = section.reach(near.width);
        let n = 100_000;
        let summed: f64 = (0..n)
            .map(|i| {
                let x = -reach + (f64::from(i) + 0.5) * 2.0 * reach / f64::from(n);
                section.darkness(near.line, near.arc, x, near.width) * 2.0 * reach / f64::from(n)
            })
            .sum();
        let dark = cracks.darkness(&p, &-c.normal, 0.004, 0.004);
        assert!(
            (dark - (summed / 0.004).min(1.0)).abs() < 0.01 * dark.max(1e-3),
            "{dark} for {summed} m of darkness"
        );
    }
}

//! Cracks: thin, dark, branching polylines drawn on the structure's surfaces
//! at seeded random places, millimetres wide.

use nalgebra::{Point3, Vector3};

use crate::rng::Rng;
use crate::scene::{Scene, area};

/// One crack on one planar face of the structure.
#[derive(Debug, Clone)]
pub struct Crack {
    pub id: u32,
    /// The main line, then its branches; each a polyline on the surface.
    pub lines: Vec<Vec<Point3<f64>>>,
    /// Width of the opening, metres.
    pub width: f64,
    /// Outward unit normal of the face it lies on.
    pub normal: Vector3<f64>,
    /// A triangle of the face it starts on.
    pub triangle: u32,
    center: Point3<f64>,
    radius: f64,
}

impl Crack {
    pub fn segments(&self) -> impl Iterator<Item = (Point3<f64>, Point3<f64>)> + '_ {
        self.lines
            .iter()
            .flat_map(|l| l.windows(2).map(|w| (w[0], w[1])))
    }

    /// Total length of all its lines, metres.
    pub fn length(&self) -> f64 {
        self.segments().map(|(a, b)| (b - a).norm()).sum()
    }

    /// Points along the crack about `step` metres apart.
    pub fn samples(&self, step: f64) -> Vec<Point3<f64>> {
        let mut out = Vec::new();
        for (a, b) in self.segments() {
            let n = ((b - a).norm() / step).ceil().max(1.0) as usize;
            out.extend((0..n).map(|k| a + (b - a) * (k as f64 / n as f64)));
        }
        out
    }

    pub fn centroid(&self) -> Point3<f64> {
        self.center
    }

    /// Distance from `p` to the crack's centre line.
    fn distance(&self, p: &Point3<f64>) -> f64 {
        self.segments()
            .map(|(a, b)| {
                let ab = b - a;
                let s = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                (p - (a + ab * s)).norm()
            })
            .fold(f64::INFINITY, f64::min)
    }
}

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
        let faces: Vec<u32> = scene
            .infrastructure()
            .filter(|t| area(&scene.triangles[*t as usize]) > 0.05)
            .collect();
        let weights: Vec<f64> = faces
            .iter()
            .map(|t| area(&scene.triangles[*t as usize]))
            .collect();
        let total: f64 = weights.iter().sum();
        let cracks = &mut self.0;
        let (before, mut attempts) = (cracks.len(), 0);
        while cracks.len() < before + count && attempts < count * 50 {
            attempts += 1;
            let mut pick = rng.uniform() * total;
            let k = weights
                .iter()
                .position(|w| {
                    pick -= w;
                    pick <= 0.0
                })
                .unwrap_or(faces.len() - 1);
            if let Some(c) = grow(scene, faces[k], cracks.len() as u32, rng)
                && cracks
                    .iter()
                    .all(|o: &Crack| (o.center - c.center).norm() > o.radius + c.radius + 0.3)
            {
                cracks.push(c);
            }
        }
        cracks.len() - before
    }

    /// How much of a pixel footprint `footprint` metres wide, centred at the
    /// surface point `p`, is covered by a crack (0 to 1).
    pub fn coverage(&self, p: &Point3<f64>, footprint: f64) -> f64 {
        let mut best: f64 = 0.0;
        for c in &self.0 {
            // Off the crack's plane first: it rules out most cracks, and
            // without a square root.
            let off = p - c.center;
            if off.dot(&c.normal).abs() > 0.02 || off.norm() > c.radius + footprint {
                continue;
            }
            let reach = footprint.max(c.width) / 2.0;
            let d = c.distance(p);
            if d < reach {
                // Area fraction of a crack of width w in a footprint of width f.
                best = best.max((c.width / footprint).min(1.0));
            }
        }
        best
    }
}

/// Random walks in the plane of one face of the structure.
struct FaceWalk<'a> {
    scene: &'a Scene,
    normal: Vector3<f64>,
    /// Axes in the face's plane.
    u: Vector3<f64>,
    v: Vector3<f64>,
}

impl<'a> FaceWalk<'a> {
    fn new(scene: &'a Scene, triangle: u32) -> Self {
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

    fn on_face(&self, p: &Point3<f64>) -> bool {
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
            h += rng.normal() * 0.35;
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

    /// The heading of the step from `a` to `b`.
    fn heading(&self, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let d = b - a;
        d.dot(&self.v).atan2(d.dot(&self.u))
    }
}

/// Grow one crack on the face of `triangle` by a random walk in its plane.
fn grow(scene: &Scene, triangle: u32, id: u32, rng: &mut Rng) -> Option<Crack> {
    let [a, b, c] = scene.triangles[triangle as usize];
    let face = FaceWalk::new(scene, triangle);
    let (mut s, mut t) = (rng.uniform(), rng.uniform());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    let start = a + (b - a) * s + (c - a) * t;
    let heading = rng.range(0.0, std::f64::consts::TAU);
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
    let crack = Crack {
        id,
        lines,
        width: rng.range(0.001, 0.005),
        normal: face.normal,
        triangle,
        center: Point3::origin(),
        radius: 0.0,
    }
    .with_bounds();
    (crack.length() >= 0.3).then_some(crack)
}

impl Crack {
    /// With its centre and radius recomputed from its lines.
    fn with_bounds(mut self) -> Self {
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

    #[test]
    fn cracks_lie_on_the_structure_and_are_seeded() {
        let scene = Scene::girder_bridge();
        let cracks = Cracks::generate(&scene, 12, &mut Rng::new(7));
        assert_eq!(cracks.0.len(), 12);
        for c in &cracks.0 {
            assert!(c.length() >= 0.3 && c.width < 0.0051);
            for p in c.samples(0.05) {
                let hit = scene.cast(&(p + c.normal * 0.2), &-c.normal, 1.0).unwrap();
                assert!(
                    (hit.distance - 0.2).abs() < 1e-3,
                    "crack {} leaves its surface",
                    c.id
                );
            }
        }
        let again = Cracks::generate(&scene, 12, &mut Rng::new(7));
        assert_eq!(again.0[5].lines, cracks.0[5].lines);
        // A point on a crack is covered; one a metre away is not.
        let c = &cracks.0[0];
        let p = c.lines[0][1];
        assert!(cracks.coverage(&p, 0.004) > 0.1);
        assert_eq!(cracks.coverage(&(p + c.normal * 1.5), 0.004), 0.0);
    }
}

//! Spalls: concrete broken out of a face of the structure, each a
//! depression below the face with sloping walls and a rough floor, some
//! with reinforcing bars showing in it. The renderer finds where a ray
//! meets the broken surface, the map's points lie on it, and truth.json
//! gives each spall's outline, area and depth (and its bars' as exposed
//! reinforcement).

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::Intrinsics;
use postflight_core::defect_kind::DefectKind;
use serde::Serialize;

use crate::crack::{Crack, FaceWalk};
use crate::rng::Rng;
use crate::scene::{FacePicker, Scene};

/// Share of a spall's radius, from its outline in, over which its wall
/// slopes down to the floor.
const WALL: f64 = 0.3;
/// Harmonics that make an outline irregular (2, 3 and 4 lobes).
const HARMONICS: usize = 3;
/// Points an outline is written with in truth.json.
const OUTLINE_POINTS: usize = 64;
/// Diameter of a bar showing, metres (a No. 5 bar, 16 mm).
pub const BAR_DIAMETER_M: f64 = 0.016;

/// One spall on a face of the structure.
#[derive(Debug, Clone)]
pub struct Spall {
    pub id: u32,
    /// A triangle of the face it is on.
    pub triangle: u32,
    /// Its centre on the face, the face's outward normal and the face's
    /// axes.
    pub center: Point3<f64>,
    pub normal: Vector3<f64>,
    pub u: Vector3<f64>,
    pub v: Vector3<f64>,
    /// Semi-axes of the ellipse its outline wobbles about, along `u` and
    /// `v`, metres.
    pub radii: (f64, f64),
    /// Each harmonic's amplitude (share of the radius) and phase.
    wobble: [(f64, f64); HARMONICS],
    /// Depth of its floor below the face, metres.
    pub depth_m: f64,
    /// Bars showing in its floor: each a centre line across it on the
    /// face's plane (from, to), lying in the floor.
    pub bars: Vec<(Point3<f64>, Point3<f64>)>,
}

/// Where a ray meets a spall's broken surface.
#[derive(Debug, Clone, Copy)]
pub struct SpallHit {
    pub point: Point3<f64>,
    /// The broken surface's normal there.
    pub normal: Vector3<f64>,
    /// On a bar showing in the floor.
    pub on_bar: bool,
}

impl Spall {
    /// The outline's distance from the centre at angle `theta` from `u`.
    fn radius_at(&self, theta: f64) -> f64 {
        let (a, b) = self.radii;
        let ellipse = a * b / ((b * theta.cos()).powi(2) + (a * theta.sin()).powi(2)).sqrt();
        let wobble: f64 = self
            .wobble
            .iter()
            .enumerate()
            .map(|(k, (amp, phase))| amp * ((k + 2) as f64 * theta + phase).cos())
            .sum();
        ellipse * (1.0 + wobble)
    }

    /// The largest distance of its outline from its centre.
    fn reach(&self) -> f64 {
        self.radii.0.max(self.radii.1) * (1.0 + self.wobble.iter().map(|w| w.0).sum::<f64>())
    }

    /// `p`'s place on the face's plane: (u, v) from the centre.
    fn plane(&self, p: &Point3<f64>) -> (f64, f64) {
        let d = p - self.center;
        (d.dot(&self.u), d.dot(&self.v))
    }

    /// How deep the broken surface lies below the face at the plane point
    /// `(x, y)`: the floor's depth inside its wall, sloping up to 0 at the
    /// outline, 0 outside.
    pub fn depth_at(&self, (x, y): (f64, f64)) -> f64 {
        let rho = x.hypot(y) / self.radius_at(y.atan2(x));
        if rho >= 1.0 {
            return 0.0;
        }
        let t = ((1.0 - rho) / WALL).min(1.0);
        self.depth_m * t * t * (3.0 - 2.0 * t)
    }

    /// Whether the plane point `(x, y)` lies on a bar showing.
    fn on_bar(&self, (x, y): (f64, f64)) -> bool {
        let q = self.center + self.u * x + self.v * y;
        self.bars.iter().any(|(a, b)| {
            let ab = b - a;
            let t = ((q - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
            (q - (a + ab * t)).norm() < BAR_DIAMETER_M / 2.0
        })
    }

    /// Where a ray along `dir` that meets the face at `p` meets the broken
    /// surface, if `p` is over the spall: marched down into the depression
    /// until below the surface, then bisected.
    pub fn hit(&self, p: &Point3<f64>, dir: &Vector3<f64>) -> Option<SpallHit> {
        let off = p - self.center;
        let down = dir.dot(&self.normal);
        if off.dot(&self.normal).abs() > 0.01 || down >= -1e-3 || off.norm() > self.reach() {
            return None;
        }
        let height = |t: f64| (p + dir * t - self.center).dot(&self.normal);
        let below = |t: f64| height(t) <= -self.depth_at(self.plane(&(p + dir * t)));
        if self.depth_at(self.plane(p)) <= 0.0 {
            return None;
        }
        let far = self.depth_m / -down * 1.01;
        let steps = 48;
        let step = far / steps as f64;
        let mut hi = (1..=steps)
            .map(|k| k as f64 * step)
            .find(|t| below(*t))
            .unwrap_or(far);
        let mut lo = (hi - step).max(0.0);
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if below(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let point = p + dir * hi;
        let at = self.plane(&point);
        Some(SpallHit {
            point,
            normal: self.surface_normal(at),
            on_bar: self.on_bar(at),
        })
    }

    /// The broken surface's normal at the plane point `(x, y)`, from its
    /// depth's slope.
    fn surface_normal(&self, (x, y): (f64, f64)) -> Vector3<f64> {
        let e = 1e-3;
        let dx = (self.depth_at((x + e, y)) - self.depth_at((x - e, y))) / (2.0 * e);
        let dy = (self.depth_at((x, y + e)) - self.depth_at((x, y - e))) / (2.0 * e);
        (self.normal + self.u * dx + self.v * dy).normalize()
    }

    /// Its outline on the face, `OUTLINE_POINTS` points.
    pub fn outline(&self) -> Vec<Point3<f64>> {
        (0..OUTLINE_POINTS)
            .map(|k| {
                let theta = std::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
                let r = self.radius_at(theta);
                self.center + (self.u * theta.cos() + self.v * theta.sin()) * r
            })
            .collect()
    }

    /// Its area on the face and the centroid of that area: the integral of
    /// r(θ)²/2 around it, finely.
    pub fn area_and_centroid(&self) -> (f64, Point3<f64>) {
        let n = 4096;
        let dtheta = std::f64::consts::TAU / n as f64;
        let (mut area, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for k in 0..n {
            let theta = (k as f64 + 0.5) * dtheta;
            let r = self.radius_at(theta);
            area += 0.5 * r * r * dtheta;
            cx += r.powi(3) / 3.0 * theta.cos() * dtheta;
            cy += r.powi(3) / 3.0 * theta.sin() * dtheta;
        }
        (
            area,
            self.center + self.u * (cx / area) + self.v * (cy / area),
        )
    }

    /// The bars' area showing (each its length within the floor times its
    /// diameter), their centroid and a rectangle around each, on the face.
    pub fn bars_shown(&self) -> Option<BarsShown> {
        let mut area = 0.0;
        let mut centroid = Vector3::zeros();
        let mut outlines = Vec::new();
        for (a, b) in &self.bars {
            let along = (b - a).normalize();
            let across = self.normal.cross(&along) * (BAR_DIAMETER_M / 2.0);
            let length = (b - a).norm();
            area += length * BAR_DIAMETER_M;
            centroid += ((a.coords + b.coords) / 2.0) * length * BAR_DIAMETER_M;
            outlines.push(vec![a + across, b + across, b - across, a - across]);
        }
        (area > 0.0).then(|| BarsShown {
            area_m2: area,
            centroid: Point3::from(centroid / area),
            outlines,
        })
    }
}

/// The bars showing in a spall: their area, its centroid and each bar's
/// rectangle on the face.
#[derive(Debug, Clone)]
pub struct BarsShown {
    pub area_m2: f64,
    pub centroid: Point3<f64>,
    pub outlines: Vec<Vec<Point3<f64>>>,
}

/// An area defect as truth.json gives it: a spall, or the bars showing in
/// one (exposed reinforcement), on the structure.
#[derive(Debug, Clone, Serialize)]
pub struct AreaDefectTruth {
    /// `S<n>` for spall n, `S<n>-rebar` for its bars.
    pub id: String,
    pub kind: DefectKind,
    pub part: String,
    /// The centroid of its area on the face, world metres.
    pub centroid: [f64; 3],
    pub area_m2: f64,
    /// A spall's floor below the face (its bars': the same spall's).
    pub depth_m: f64,
    /// The largest distance across its outline, metres.
    pub largest_dimension_m: f64,
    /// Its outline on the face (a spall's; the bars' each a rectangle).
    pub outlines: Vec<Vec<[f64; 3]>>,
    /// The face's outward normal.
    pub normal: [f64; 3],
    /// The spall its bars show in (exposed reinforcement only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub in_spall: Option<String>,
}

impl Spall {
    /// Its truth, then its bars' when they show.
    pub fn truths(&self, part: &str) -> Vec<AreaDefectTruth> {
        let xyz = |p: &Point3<f64>| [p.x, p.y, p.z];
        let normal = [self.normal.x, self.normal.y, self.normal.z];
        let outline = self.outline();
        let (area_m2, centroid) = self.area_and_centroid();
        let id = format!("S{}", self.id);
        let mut out = vec![AreaDefectTruth {
            id: id.clone(),
            kind: DefectKind::Spall,
            part: part.to_string(),
            centroid: xyz(&centroid),
            area_m2,
            depth_m: self.depth_m,
            largest_dimension_m: largest_dimension(&outline),
            outlines: vec![outline.iter().map(xyz).collect()],
            normal,
            in_spall: None,
        }];
        if let Some(BarsShown {
            area_m2,
            centroid,
            outlines: bars,
        }) = self.bars_shown()
        {
            let corners: Vec<Point3<f64>> = bars.iter().flatten().copied().collect();
            out.push(AreaDefectTruth {
                id: format!("{id}-rebar"),
                kind: DefectKind::ExposedRebar,
                part: part.to_string(),
                centroid: xyz(&centroid),
                area_m2,
                depth_m: self.depth_m,
                largest_dimension_m: largest_dimension(&corners),
                outlines: bars.iter().map(|b| b.iter().map(xyz).collect()).collect(),
                normal,
                in_spall: Some(id),
            });
        }
        out
    }

    /// Whether a camera at `camera` (optical frame in the world) sees it:
    /// its centroid in the image, facing the camera, unblocked.
    pub fn seen_by(&self, scene: &Scene, k: &Intrinsics, camera: &Isometry3<f64>) -> bool {
        let (_, centroid) = self.area_and_centroid();
        let origin = Point3::from(camera.translation.vector);
        let to_camera = origin - centroid;
        let range = to_camera.norm();
        if self.normal.dot(&to_camera) <= 0.0 || range > 60.0 {
            return false;
        }
        let Some(px) = k.project(&(camera.inverse() * centroid).coords) else {
            return false;
        };
        let inside =
            px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(k.width) && px.y < f64::from(k.height);
        inside
            && scene
                .cast(&origin, &(-to_camera / range), range + 0.05)
                .is_none_or(|h| h.distance > range - 0.01)
    }
}

/// The largest distance between two of `points`.
fn largest_dimension(points: &[Point3<f64>]) -> f64 {
    points
        .iter()
        .flat_map(|a| points.iter().map(move |b| (a - b).norm()))
        .fold(0.0, f64::max)
}

/// The spalls of a scene.
#[derive(Debug, Clone, Default)]
pub struct Spalls(pub Vec<Spall>);

impl Spalls {
    /// Each spall's truth and its bars'.
    pub fn truths(&self, scene: &Scene) -> Vec<AreaDefectTruth> {
        self.0
            .iter()
            .flat_map(|s| s.truths(scene.part_name(s.triangle)))
            .collect()
    }

    /// The ids of the area defects a camera at `camera` sees.
    pub fn seen_by(&self, scene: &Scene, k: &Intrinsics, camera: &Isometry3<f64>) -> Vec<String> {
        let mut ids = Vec::new();
        for s in self.0.iter().filter(|s| s.seen_by(scene, k, camera)) {
            ids.push(format!("S{}", s.id));
            if !s.bars.is_empty() {
                ids.push(format!("S{}-rebar", s.id));
            }
        }
        ids
    }

    /// Draw `count` spalls on the structure's faces, clear of its `cracks`
    /// and of each other; fewer where the structure runs out of room.
    pub fn generate(scene: &Scene, count: usize, cracks: &[Crack], rng: &mut Rng) -> Self {
        let faces = FacePicker::new(scene, 0.3);
        let mut spalls: Vec<Spall> = Vec::new();
        let mut attempts = 0;
        while spalls.len() < count && attempts < count * 80 {
            attempts += 1;
            let Some(triangle) = faces.pick(rng) else {
                break;
            };
            let Some(s) = draw(scene, triangle, spalls.len() as u32, rng) else {
                continue;
            };
            let clear_of_cracks = cracks
                .iter()
                .all(|c| (c.center - s.center).norm() > c.radius + s.reach() + 0.1);
            let clear_of_spalls = spalls
                .iter()
                .all(|o| (o.center - s.center).norm() > o.reach() + s.reach() + 0.1);
            if clear_of_cracks && clear_of_spalls {
                spalls.push(s);
            }
        }
        Self(spalls)
    }

    /// Where a ray along `dir` meeting the structure at `p` meets a spall's
    /// broken surface, if it falls in one.
    pub fn hit(&self, p: &Point3<f64>, dir: &Vector3<f64>) -> Option<SpallHit> {
        self.0.iter().find_map(|s| s.hit(p, dir))
    }

    /// A map point sampled on the face at `p`, on the broken surface where
    /// a spall took the face away.
    pub fn sunk(&self, p: Point3<f64>) -> Point3<f64> {
        for s in &self.0 {
            let off = p - s.center;
            if off.dot(&s.normal).abs() < 0.01 && off.norm() < s.reach() {
                let d = s.depth_at(s.plane(&p));
                if d > 0.0 {
                    return p - s.normal * d;
                }
            }
        }
        p
    }
}

/// One spall on the face of `triangle`, numbered `id`: 8 to 45 cm across,
/// 8 to 45 mm deep (both sides of the manual's 150 mm and 25 mm), an
/// irregular outline; a deep one shows bars in two of five. `None` where it
/// would not fit on the face.
fn draw(scene: &Scene, triangle: u32, id: u32, rng: &mut Rng) -> Option<Spall> {
    let face = FaceWalk::new(scene, triangle);
    let [a, b, c] = scene.triangles[triangle as usize];
    let (mut s, mut t) = (rng.uniform(), rng.uniform());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    let center = a + (b - a) * s + (c - a) * t;
    let across = rng.range(0.08, 0.45);
    let radii = (across / 2.0, across / 2.0 * rng.range(0.6, 1.0));
    let wobble =
        [0; HARMONICS].map(|_| (rng.range(0.0, 0.08), rng.range(0.0, std::f64::consts::TAU)));
    let depth_m = rng.range(0.008, 0.045);
    let mut spall = Spall {
        id,
        triangle,
        center,
        normal: face.normal,
        u: face.u,
        v: face.v,
        radii,
        wobble,
        depth_m,
        bars: Vec::new(),
    };
    // The outline and a little beyond must lie on the face.
    let fits = spall
        .outline()
        .iter()
        .step_by(4)
        .all(|p| face.on_face(&(p + (p - center) * 0.15)));
    if !fits {
        return None;
    }
    if depth_m > 0.02 && rng.uniform() < 0.4 {
        spall.bars = bars(&spall, rng);
    }
    Some(spall)
}

/// One or two bars across the floor of `spall`, 15 cm apart along the
/// face's `u` or `v`, each as long as the floor is across it.
fn bars(spall: &Spall, rng: &mut Rng) -> Vec<(Point3<f64>, Point3<f64>)> {
    let (along, across) = if rng.uniform() < 0.5 {
        (spall.u, spall.v)
    } else {
        (spall.v, spall.u)
    };
    let count = if rng.uniform() < 0.5 { 1 } else { 2 };
    let first = -0.075 * (count - 1) as f64 + rng.range(-0.03, 0.03);
    (0..count)
        .filter_map(|k| {
            let offset = first + 0.15 * k as f64;
            let at = |t: f64| spall.center + across * offset + along * t;
            // The bar shows where the floor is at its full depth.
            let floor = |t: f64| spall.depth_at(spall.plane(&at(t))) >= spall.depth_m * 0.99;
            let ts: Vec<f64> = (-200..=200)
                .map(|i| f64::from(i) * spall.reach() / 200.0)
                .filter(|t| floor(*t))
                .collect();
            let (lo, hi) = (*ts.first()?, *ts.last()?);
            (hi - lo > 0.03).then(|| (at(lo), at(hi)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(depth_m: f64) -> Spall {
        Spall {
            id: 0,
            triangle: 0,
            center: Point3::new(0.0, 0.0, 0.0),
            normal: Vector3::z(),
            u: Vector3::x(),
            v: Vector3::y(),
            radii: (0.2, 0.1),
            wobble: [(0.05, 0.3), (0.03, 1.0), (0.02, 2.0)],
            depth_m,
            bars: vec![(Point3::new(-0.1, 0.0, 0.0), Point3::new(0.1, 0.0, 0.0))],
        }
    }

    /// The shoelace area and centroid of a polygon in the x-y plane.
    fn shoelace(points: &[Point3<f64>]) -> (f64, f64, f64) {
        let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for (p, q) in points.iter().zip(points.iter().cycle().skip(1)) {
            let cross = p.x * q.y - q.x * p.y;
            a += cross / 2.0;
            cx += (p.x + q.x) * cross / 6.0;
            cy += (p.y + q.y) * cross / 6.0;
        }
        (a, cx / a, cy / a)
    }

    #[test]
    fn its_area_and_centroid_are_its_outlines() {
        let s = flat(0.03);
        let (area, centroid) = s.area_and_centroid();
        // A finer outline than truth.json's, by the shoelace formula.
        let fine: Vec<Point3<f64>> = (0..20_000)
            .map(|k| {
                let theta = std::f64::consts::TAU * f64::from(k) / 20_000.0;
                s.center + (s.u * theta.cos() + s.v * theta.sin()) * s.radius_at(theta)
            })
            .collect();
        let (a, cx, cy) = shoelace(&fine);
        assert!((area - a).abs() / a < 1e-4, "{area} vs {a}");
        assert!((centroid.x - cx).abs() < 1e-5 && (centroid.y - cy).abs() < 1e-5);
        // Near the ellipse's area: the wobble averages out to second order.
        let ellipse = std::f64::consts::PI * 0.2 * 0.1;
        assert!(
            (area - ellipse).abs() / ellipse < 0.05,
            "{area} vs {ellipse}"
        );
    }

    #[test]
    fn a_ray_falls_to_the_floor_and_a_slanted_one_meets_the_wall() {
        let s = flat(0.03);
        let down = -Vector3::z();
        let hit = s.hit(&Point3::new(0.0, 0.02, 0.0), &down).unwrap();
        assert!((hit.point.z + 0.03).abs() < 1e-4, "{:?}", hit.point);
        assert!(!hit.on_bar && hit.normal.z > 0.999);
        let bar = s.hit(&Point3::new(0.02, 0.0, 0.0), &down).unwrap();
        assert!(bar.on_bar);
        // Steeply slanted near the rim: it meets the wall above the floor.
        let slant = Vector3::new(0.95, 0.0, -0.3).normalize();
        let wall = s.hit(&Point3::new(0.15, 0.0, 0.0), &slant).unwrap();
        assert!(
            wall.point.z > -0.03 && wall.point.z < 0.0,
            "{:?}",
            wall.point
        );
        assert!(s.hit(&Point3::new(0.5, 0.0, 0.0), &down).is_none());
        // The map's points sink to the broken surface.
        let spalls = Spalls(vec![s]);
        assert!((spalls.sunk(Point3::new(0.0, 0.0, 0.0)).z + 0.03).abs() < 1e-9);
        assert_eq!(spalls.sunk(Point3::new(0.5, 0.0, 0.0)).z, 0.0);
    }

    #[test]
    fn bars_show_across_the_floor() {
        let s = flat(0.03);
        let shown = s.bars_shown().unwrap();
        assert!((shown.area_m2 - 0.2 * BAR_DIAMETER_M).abs() < 1e-12);
        assert!(shown.centroid.coords.norm() < 1e-12 && shown.outlines.len() == 1);
    }
}

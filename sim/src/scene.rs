//! The simulated world: triangle meshes of the structure, obstacles and
//! ground, with a BVH ray caster (parry3d) over all of them.

use std::path::Path;

use nalgebra::{Point3, Vector3};
use parry3d::math::Vector as PVector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::TriMesh;

/// What a part of the scene is, as GATSBI classes voxels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// The structure under inspection.
    Infrastructure,
    /// Anything else in the air: trees, poles.
    Obstacle,
    Ground,
}

#[derive(Debug, Clone, serde::Serialize)]
pub struct Part {
    pub name: String,
    pub class: Class,
}

/// A ray's first hit.
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    pub distance: f64,
    pub point: Point3<f64>,
    /// Unit normal of the hit triangle, facing the ray's origin.
    pub normal: Vector3<f64>,
    pub triangle: u32,
}

pub struct Scene {
    pub name: String,
    pub triangles: Vec<[Point3<f64>; 3]>,
    /// Part index of each triangle.
    pub part_of: Vec<u16>,
    pub parts: Vec<Part>,
    mesh: TriMesh,
}

/// Triangles being gathered for a scene.
#[derive(Default)]
struct Builder {
    triangles: Vec<[Point3<f64>; 3]>,
    part_of: Vec<u16>,
    parts: Vec<Part>,
}

impl Builder {
    fn part(&mut self, name: &str, class: Class) -> u16 {
        self.parts.push(Part {
            name: name.into(),
            class,
        });
        (self.parts.len() - 1) as u16
    }

    fn triangle(&mut self, part: u16, a: Point3<f64>, b: Point3<f64>, c: Point3<f64>) {
        self.triangles.push([a, b, c]);
        self.part_of.push(part);
    }

    /// A quad `a b c d`, counter-clockwise seen from its front.
    fn quad(&mut self, part: u16, a: Point3<f64>, b: Point3<f64>, c: Point3<f64>, d: Point3<f64>) {
        self.triangle(part, a, b, c);
        self.triangle(part, a, c, d);
    }

    /// An axis-aligned box with outward-facing triangles.
    fn cuboid(&mut self, name: &str, class: Class, lo: [f64; 3], hi: [f64; 3]) {
        let part = self.part(name, class);
        let p = |x: usize, y: usize, z: usize| {
            Point3::new([lo[0], hi[0]][x], [lo[1], hi[1]][y], [lo[2], hi[2]][z])
        };
        self.quad(part, p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)); // -z
        self.quad(part, p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)); // +z
        self.quad(part, p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)); // -y
        self.quad(part, p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0)); // +y
        self.quad(part, p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)); // -x
        self.quad(part, p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)); // +x
    }

    /// A vertical closed cylinder.
    fn cylinder(
        &mut self,
        name: &str,
        class: Class,
        base: [f64; 3],
        radius: f64,
        height: f64,
        segments: usize,
    ) {
        let part = self.part(name, class);
        let at = |k: usize, z: f64| {
            let a = std::f64::consts::TAU * k as f64 / segments as f64;
            Point3::new(
                base[0] + radius * a.cos(),
                base[1] + radius * a.sin(),
                base[2] + z,
            )
        };
        let bottom = Point3::new(base[0], base[1], base[2]);
        let top = Point3::new(base[0], base[1], base[2] + height);
        for k in 0..segments {
            let (a0, a1, b0, b1) = (at(k, 0.0), at(k + 1, 0.0), at(k, height), at(k + 1, height));
            self.quad(part, a0, a1, b1, b0);
            self.triangle(part, top, b0, b1);
            self.triangle(part, bottom, a1, a0);
        }
    }

    /// Flat ground at height `z` covering `lo..hi` in x and y.
    fn ground(&mut self, lo: [f64; 2], hi: [f64; 2], z: f64) {
        let part = self.part("ground", Class::Ground);
        self.quad(
            part,
            Point3::new(lo[0], lo[1], z),
            Point3::new(hi[0], lo[1], z),
            Point3::new(hi[0], hi[1], z),
            Point3::new(lo[0], hi[1], z),
        );
    }

    fn build(self, name: &str) -> Result<Scene, String> {
        let vertices: Vec<PVector> = self
            .triangles
            .iter()
            .flatten()
            .map(|p| PVector::new(p.x as f32, p.y as f32, p.z as f32))
            .collect();
        let indices: Vec<[u32; 3]> = (0..self.triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let mesh = TriMesh::new(vertices, indices).map_err(|e| format!("bad mesh: {e:?}"))?;
        Ok(Scene {
            name: name.into(),
            triangles: self.triangles,
            part_of: self.part_of,
            parts: self.parts,
            mesh,
        })
    }
}

impl Scene {
    /// A steel-girder bridge: deck on three girders on two piers, with a tree
    /// and a lamp pole nearby.
    pub fn girder_bridge() -> Self {
        let mut b = Builder::default();
        b.ground([-40.0, -30.0], [40.0, 30.0], 0.0);
        for (name, x) in [("pier west", -8.0), ("pier east", 8.0)] {
            b.cuboid(
                name,
                Class::Infrastructure,
                [x - 0.6, -2.5, 0.0],
                [x + 0.6, 2.5, 5.0],
            );
        }
        for (name, y) in [
            ("girder south", -2.0),
            ("girder middle", 0.0),
            ("girder north", 2.0),
        ] {
            b.cuboid(
                name,
                Class::Infrastructure,
                [-15.0, y - 0.25, 5.0],
                [15.0, y + 0.25, 6.0],
            );
        }
        b.cuboid(
            "deck",
            Class::Infrastructure,
            [-15.0, -3.5, 6.0],
            [15.0, 3.5, 6.5],
        );
        b.cylinder(
            "tree trunk",
            Class::Obstacle,
            [4.0, 10.0, 0.0],
            0.25,
            3.0,
            12,
        );
        b.cuboid(
            "tree crown",
            Class::Obstacle,
            [2.8, 8.8, 3.0],
            [5.2, 11.2, 6.0],
        );
        b.cylinder(
            "lamp pole",
            Class::Obstacle,
            [-6.0, -9.0, 0.0],
            0.12,
            7.0,
            10,
        );
        b.build("girder-bridge")
            .expect("the built-in scene is a valid mesh")
    }

    /// A concrete silo tower with a pole beside it.
    pub fn tower() -> Self {
        let mut b = Builder::default();
        b.ground([-30.0, -30.0], [30.0, 30.0], 0.0);
        b.cylinder(
            "tower",
            Class::Infrastructure,
            [0.0, 0.0, 0.0],
            3.0,
            18.0,
            48,
        );
        b.cylinder(
            "antenna pole",
            Class::Obstacle,
            [7.5, 2.0, 0.0],
            0.15,
            10.0,
            10,
        );
        b.build("tower")
            .expect("the built-in scene is a valid mesh")
    }

    /// A structure from a Wavefront OBJ file (z up, metres), standing on ground.
    pub fn from_obj(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{e}; check the path given to --mesh"))?;
        let postflight_core::map::mesh::Mesh {
            vertices,
            triangles: faces,
        } = postflight_core::map::mesh::parse_obj(&text)?;
        let mut b = Builder::default();
        let part = b.part("structure", Class::Infrastructure);
        for f in &faces {
            b.triangle(part, vertices[f[0]], vertices[f[1]], vertices[f[2]]);
        }
        let (lo, hi) = bounds(vertices.iter());
        b.ground(
            [lo.x - 30.0, lo.y - 30.0],
            [hi.x + 30.0, hi.y + 30.0],
            lo.z - 0.01,
        );
        let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("mesh");
        b.build(name)
    }

    /// The scene in another frame: each point `p` at `iso * p`.
    pub fn transformed(&self, iso: &nalgebra::Isometry3<f64>) -> Self {
        Builder {
            triangles: self.triangles.iter().map(|t| t.map(|p| iso * p)).collect(),
            part_of: self.part_of.clone(),
            parts: self.parts.clone(),
        }
        .build(&self.name)
        .expect("a rigid motion of a valid mesh is valid")
    }

    /// First hit of the ray `origin + t * dir` (unit `dir`) with `t <= max`.
    pub fn cast(&self, origin: &Point3<f64>, dir: &Vector3<f64>, max: f64) -> Option<Hit> {
        let ray = Ray::new(
            PVector::new(origin.x as f32, origin.y as f32, origin.z as f32),
            PVector::new(dir.x as f32, dir.y as f32, dir.z as f32),
        );
        let hit = self
            .mesh
            .cast_local_ray_and_get_normal(&ray, max as f32, true)?;
        let triangle = hit.subshape;
        let distance = f64::from(hit.time_of_impact);
        let mut normal = self.normal(triangle);
        if normal.dot(dir) > 0.0 {
            normal = -normal;
        }
        Some(Hit {
            distance,
            point: origin + dir * distance,
            normal,
            triangle,
        })
    }

    /// Outward unit normal of a triangle.
    pub fn normal(&self, triangle: u32) -> Vector3<f64> {
        let [a, b, c] = self.triangles[triangle as usize];
        (b - a).cross(&(c - a)).normalize()
    }

    pub fn class(&self, triangle: u32) -> Class {
        self.parts[usize::from(self.part_of[triangle as usize])].class
    }

    pub fn part_name(&self, triangle: u32) -> &str {
        &self.parts[usize::from(self.part_of[triangle as usize])].name
    }

    /// Triangles of the structure under inspection.
    pub fn infrastructure(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.triangles.len() as u32).filter(|t| self.class(*t) == Class::Infrastructure)
    }

    /// Bounds of the infrastructure.
    pub fn infrastructure_bounds(&self) -> (Point3<f64>, Point3<f64>) {
        bounds(
            self.infrastructure()
                .flat_map(|t| self.triangles[t as usize].iter()),
        )
    }
}

/// The structure's faces larger than some area, picked at random in
/// proportion to their area.
pub struct FacePicker {
    faces: Vec<u32>,
    weights: Vec<f64>,
    total: f64,
}

impl FacePicker {
    /// The structure's triangles of `scene` larger than `min_area`, m².
    pub fn new(scene: &Scene, min_area: f64) -> Self {
        let faces: Vec<u32> = scene
            .infrastructure()
            .filter(|t| area(&scene.triangles[*t as usize]) > min_area)
            .collect();
        let weights: Vec<f64> = faces
            .iter()
            .map(|t| area(&scene.triangles[*t as usize]))
            .collect();
        let total = weights.iter().sum();
        Self {
            faces,
            weights,
            total,
        }
    }

    /// A face, more likely the larger it is; `None` when there are none.
    pub fn pick(&self, rng: &mut crate::rng::Rng) -> Option<u32> {
        let last = self.faces.len().checked_sub(1)?;
        let mut pick = rng.uniform() * self.total;
        let k = self
            .weights
            .iter()
            .position(|w| {
                pick -= w;
                pick <= 0.0
            })
            .unwrap_or(last);
        Some(self.faces[k])
    }
}

pub fn area(t: &[Point3<f64>; 3]) -> f64 {
    0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm()
}

fn bounds<'a>(points: impl Iterator<Item = &'a Point3<f64>>) -> (Point3<f64>, Point3<f64>) {
    points.fold(
        (
            Point3::from([f64::INFINITY; 3]),
            Point3::from([f64::NEG_INFINITY; 3]),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_hit_the_right_parts_with_outward_normals() {
        let scene = Scene::girder_bridge();
        // Straight down onto the deck.
        let hit = scene
            .cast(&Point3::new(0.0, 0.0, 20.0), &-Vector3::z(), 100.0)
            .unwrap();
        assert!((hit.distance - 13.5).abs() < 1e-4);
        assert_eq!(scene.part_name(hit.triangle), "deck");
        assert!((hit.normal - Vector3::z()).norm() < 1e-9);
        // Horizontally into the west pier's west face.
        let hit = scene
            .cast(&Point3::new(-20.0, 0.0, 2.0), &Vector3::x(), 100.0)
            .unwrap();
        assert_eq!(scene.part_name(hit.triangle), "pier west");
        assert!((hit.point.x - -8.6).abs() < 1e-4);
        assert!((scene.normal(hit.triangle) + Vector3::x()).norm() < 1e-9);
        // Up into the sky.
        assert!(
            scene
                .cast(&Point3::new(0.0, 20.0, 2.0), &Vector3::z(), 100.0)
                .is_none()
        );
    }
}

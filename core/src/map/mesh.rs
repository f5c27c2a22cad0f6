//! Meshes as maps: an OBJ or PLY mesh (a photogrammetry model, a BIM
//! export) whose triangles are sampled into points closer together than
//! the map's voxels and a crack's placement needs, so it serves as a
//! point cloud does.

use nalgebra::Point3;

/// Points are sampled this far apart on a mesh's surface, metres.
pub const SAMPLE_SPACING_M: f64 = 0.02;

/// The most points a mesh's surface is sampled into (half a gigabyte): a
/// larger surface is sampled farther apart, and the map says so.
pub const MAX_SURFACE_POINTS: usize = 20_000_000;

/// Vertices and the triangles between them (indices into `vertices`).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<Point3<f64>>,
    pub triangles: Vec<[usize; 3]>,
}

impl Mesh {
    /// The spacing its surface is sampled at: [`SAMPLE_SPACING_M`], or as
    /// much farther apart as keeps it within [`MAX_SURFACE_POINTS`]; an
    /// error for a vertex that is not a place, or more triangles than
    /// that many points can sample at all.
    pub fn spacing(&self) -> Result<f64, String> {
        if let Some((i, v)) = self
            .vertices
            .iter()
            .enumerate()
            .find(|(_, v)| !v.coords.iter().all(|x| x.is_finite()))
        {
            return Err(format!(
                "vertex {} ({}, {}, {}) is not a place: its coordinates must be finite",
                i + 1,
                v.x,
                v.y,
                v.z
            ));
        }
        // Each triangle's grid of rows: at most (n + 1) rows of m / 2 + 2.
        let bound = |spacing: f64| -> f64 {
            self.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| self.vertices[i]);
                    let n = ((b - a).norm() / spacing).ceil().max(1.0);
                    let m = ((c - a).norm() / spacing).ceil().max(1.0);
                    (n + 1.0) * (m / 2.0 + 2.0)
                })
                .sum()
        };
        let budget = MAX_SURFACE_POINTS as f64;
        let mut spacing = SAMPLE_SPACING_M;
        for _ in 0..200 {
            if bound(spacing) <= budget {
                return Ok(spacing);
            }
            spacing *= 1.25;
        }
        Err(format!(
            "its {} triangles are more than {MAX_SURFACE_POINTS} points can sample; simplify the mesh",
            self.triangles.len()
        ))
    }

    /// Points on every triangle, on a grid `spacing` apart along two of
    /// its sides (its corners and edges included), so no point of the
    /// surface is farther than `spacing` from one.
    pub fn surface_points(&self, spacing: f64) -> Vec<Point3<f64>> {
        let mut points = Vec::new();
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.vertices[i]);
            let steps = |p: Point3<f64>, q: Point3<f64>| {
                ((q - p).norm() / spacing).ceil().max(1.0) as usize
            };
            let (n, m) = (steps(a, b), steps(a, c));
            for i in 0..=n {
                let u = i as f64 / n as f64;
                // The row across the triangle shortens toward b.
                let across = ((1.0 - u) * m as f64).ceil() as usize;
                for j in 0..=across {
                    let v = (j as f64 / m as f64).min(1.0 - u);
                    points.push(a + (b - a) * u + (c - a) * v);
                }
            }
        }
        points
    }
}

/// Wavefront OBJ's vertices (`v`) and faces (`f`, any polygon,
/// fan-triangulated).
pub fn parse_obj(text: &str) -> Result<Mesh, String> {
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f64> = words
                    .take(3)
                    .map(|w| w.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("line {}: bad vertex {line:?}", n + 1))?;
                if c.len() != 3 {
                    return Err(format!("line {}: a vertex needs x y z", n + 1));
                }
                vertices.push(Point3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let idx: Vec<usize> = words
                    .map(|w| {
                        // "v", "v/vt", "v//vn" or "v/vt/vn"; negative indices count back.
                        let v: i64 = w.split('/').next().unwrap_or("").parse().map_err(|_| ())?;
                        let i = if v < 0 {
                            vertices.len() as i64 + v
                        } else {
                            v - 1
                        };
                        usize::try_from(i)
                            .ok()
                            .filter(|i| *i < vertices.len())
                            .ok_or(())
                    })
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        format!("line {}: face refers to a missing vertex: {line:?}", n + 1)
                    })?;
                if idx.len() < 3 {
                    return Err(format!("line {}: a face needs 3 vertices", n + 1));
                }
                for k in 1..idx.len() - 1 {
                    faces.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if faces.is_empty() {
        return Err("the OBJ file has no faces".into());
    }
    Ok(Mesh {
        vertices,
        triangles: faces,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sampled_triangle_covers_its_surface() {
        let mesh = Mesh {
            vertices: vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(2.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let points = mesh.surface_points(0.05);
        // Every point on the triangle, none off it.
        assert!(
            points
                .iter()
                .all(|p| p.z == 0.0 && p.x >= 0.0 && p.y >= 0.0 && p.x / 2.0 + p.y <= 1.0 + 1e-9)
        );
        for (x, y) in [
            (0.0, 0.0),
            (1.99, 0.0),
            (0.0, 0.99),
            (0.5, 0.5),
            (1.0, 0.49),
        ] {
            let nearest = points
                .iter()
                .map(|p| (p - Point3::new(x, y, 0.0)).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest <= 0.05, "({x}, {y}) is {nearest} from a point");
        }
    }

    #[test]
    fn parses_polygons_and_index_forms() {
        let mesh = parse_obj("# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2/2/2 3//3 -1\n")
            .unwrap();
        assert_eq!(mesh.vertices.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(parse_obj("v 0 0 0\nf 1 2 3\n").is_err());
        assert!(parse_obj("v 0 0\n").is_err());
    }

    #[test]
    fn a_vast_mesh_is_sampled_within_its_budget_and_a_map_holds_only_places() {
        // One triangle with 1 km sides, 36 bytes: 1.25e9 points every 2 cm.
        let obj = b"v 0 0 0\nv 1000 0 0\nv 0 1000 0\nf 1 2 3\n";
        let cloud = crate::map::PointCloud::parse(obj, "obj").unwrap();
        assert!(
            cloud.points.len() <= MAX_SURFACE_POINTS,
            "{}",
            cloud.points.len()
        );
        assert!(
            cloud.points.len() > MAX_SURFACE_POINTS / 4,
            "{}",
            cloud.points.len()
        );
        let warning = cloud.coarsened().unwrap();
        let spacing = cloud.mesh_spacing_m.unwrap();
        assert!((0.1..0.4).contains(&spacing), "{spacing}");
        assert!(
            warning.contains(&format!("sampled every {spacing:.2} m")),
            "{warning}"
        );
        // A small one is sampled as always, with nothing to say.
        let small =
            crate::map::PointCloud::parse(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "obj").unwrap();
        assert_eq!(small.mesh_spacing_m, Some(SAMPLE_SPACING_M));
        assert!(small.coarsened().is_none());
        // A vertex that is not a place is named.
        let err = crate::map::PointCloud::parse(b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "obj")
            .unwrap_err();
        assert!(err.contains("vertex 2 (NaN, 0, 0) is not a place"), "{err}");
        // A cloud's NaN points are no returns (PCL's organised clouds):
        // dropped; a cloud of nothing else has no points.
        let pcd = |rows: &str| {
            format!(
                "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n{rows}"
            )
        };
        let cloud =
            crate::map::PointCloud::parse(pcd("nan nan nan\n1 2 3\n").as_bytes(), "pcd").unwrap();
        assert_eq!(cloud.points, [Point3::new(1.0, 2.0, 3.0)]);
        let err =
            crate::map::PointCloud::parse(pcd("nan 0 0\n0 nan 0\n").as_bytes(), "pcd").unwrap_err();
        assert!(err.contains("no points"), "{err}");
    }
}

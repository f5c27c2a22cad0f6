//! Wavefront OBJ: vertices (`v`) and faces (`f`, any polygon, fan-triangulated).

use nalgebra::Point3;

type Faces = Vec<[usize; 3]>;

pub fn parse(text: &str) -> Result<(Vec<Point3<f64>>, Faces), String> {
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
    Ok((vertices, faces))
}

#[cfg(test)]
mod tests {
    #[test]
    fn parses_polygons_and_index_forms() {
        let (v, f) =
            super::parse("# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2/2/2 3//3 -1\n")
                .unwrap();
        assert_eq!(v.len(), 4);
        assert_eq!(f, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(super::parse("v 0 0 0\nf 1 2 3\n").is_err());
        assert!(super::parse("v 0 0\n").is_err());
    }
}

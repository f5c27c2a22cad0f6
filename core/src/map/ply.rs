//! PLY point clouds and meshes (ascii, binary little and big endian): the
//! vertex element's `x`, `y`, `z`, and the face element's
//! `vertex_indices` (or `vertex_index`), fan-triangulated; other elements
//! and properties are skipped.

use nalgebra::Point3;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Result<Self, String> {
        Ok(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            other => return Err(format!("unknown PLY property type {other:?}")),
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty) => {{
                let a = b[..std::mem::size_of::<$t>()].try_into().unwrap();
                f64::from(if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                })
            }};
        }
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => num!(i16),
            Self::U16 => num!(u16),
            Self::I32 => num!(i32),
            Self::U32 => num!(u32),
            Self::F32 => num!(f32),
            Self::F64 => num!(f64),
        }
    }
}

enum Property {
    Scalar(String, Scalar),
    List(String, Scalar, Scalar),
}

struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

#[derive(PartialEq)]
enum Format {
    Ascii,
    Binary { big: bool },
}

/// A PLY file's vertices and its faces as triangles (none for a cloud).
pub struct Ply {
    pub points: Vec<Point3<f64>>,
    pub triangles: Vec<[usize; 3]>,
}

/// Which element and property a value belongs to, as the parsers read.
struct Layout {
    vertex: usize,
    xyz: [usize; 3],
    /// The face element and its list of vertex indices.
    faces: Option<(usize, usize)>,
}

impl Layout {
    /// The last element the parsers need to read to.
    fn last(&self) -> usize {
        self.faces.map_or(self.vertex, |(f, _)| f.max(self.vertex))
    }

    /// An empty mesh for a body of `body_len` bytes, room made for its
    /// vertices (the header's count is a claim; no more than the body can
    /// hold).
    fn empty(&self, elements: &[Element], body_len: usize) -> Ply {
        Ply {
            points: Vec::with_capacity(elements[self.vertex].count.min(body_len)),
            triangles: Vec::new(),
        }
    }
}

pub fn parse(bytes: &[u8]) -> Result<Ply, String> {
    let end = find(bytes, b"end_header\n").ok_or("not a PLY file: no end_header line")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| "PLY header is not text")?;
    let body = &bytes[end + b"end_header\n".len()..];
    let mut lines = header.lines().map(str::trim);
    if lines.next() != Some("ply") {
        return Err("not a PLY file: it does not start with \"ply\"".into());
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "ascii", _] => format = Some(Format::Ascii),
            ["format", "binary_little_endian", _] => format = Some(Format::Binary { big: false }),
            ["format", "binary_big_endian", _] => format = Some(Format::Binary { big: true }),
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| format!("bad element count in {line:?}"))?,
                properties: Vec::new(),
            }),
            ["property", "list", count, item, name] => elements
                .last_mut()
                .ok_or("PLY property before any element")?
                .properties
                .push(Property::List(
                    name.to_string(),
                    Scalar::parse(count)?,
                    Scalar::parse(item)?,
                )),
            ["property", ty, name] => elements
                .last_mut()
                .ok_or("PLY property before any element")?
                .properties
                .push(Property::Scalar(name.to_string(), Scalar::parse(ty)?)),
            _ => {} // comment, obj_info
        }
    }
    let format = format.ok_or("PLY header has no format line")?;
    let vertex = elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or("PLY file has no vertex element")?;
    let axis = |n: &str| {
        elements[vertex]
            .properties
            .iter()
            .position(|p| matches!(p, Property::Scalar(name, _) if name == n))
            .ok_or(format!("PLY vertex element has no {n} property"))
    };
    let xyz = [axis("x")?, axis("y")?, axis("z")?];
    let faces = elements.iter().position(|e| e.name == "face").and_then(|f| {
        let list = elements[f].properties.iter().position(|p| {
            matches!(p, Property::List(name, ..) if name == "vertex_indices" || name == "vertex_index")
        })?;
        Some((f, list))
    });
    let layout = Layout { vertex, xyz, faces };
    let mut ply = match format {
        Format::Ascii => parse_ascii(body, &elements, &layout)?,
        Format::Binary { big } => parse_binary(body, &elements, &layout, big)?,
    };
    let n = ply.points.len();
    if ply.triangles.iter().flatten().any(|i| *i >= n) {
        return Err(format!("a PLY face names a vertex beyond its {n}"));
    }
    ply.triangles.shrink_to_fit();
    Ok(ply)
}

fn parse_ascii(body: &[u8], elements: &[Element], layout: &Layout) -> Result<Ply, String> {
    let text = std::str::from_utf8(body).map_err(|_| "PLY ascii body is not text")?;
    // One line per element instance, elements in header order.
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let mut ply = layout.empty(elements, body.len());
    for (e, element) in elements.iter().enumerate().take(layout.last() + 1) {
        for i in 0..element.count {
            let line = lines.next().ok_or(format!(
                "PLY file ends at {} {i} of {}",
                element.name, element.count
            ))?;
            let values: Vec<&str> = line.split_whitespace().collect();
            let get = |k: usize| -> Result<f64, String> {
                values
                    .get(k)
                    .and_then(|v| v.parse().ok())
                    .ok_or(format!("bad PLY {} line {line:?}", element.name))
            };
            if e == layout.vertex {
                let [x, y, z] = layout.xyz;
                ply.points.push(Point3::new(get(x)?, get(y)?, get(z)?));
            } else if layout.faces.is_some_and(|(f, _)| f == e) {
                // Faces hold only their index list where postflight reads them.
                let n = get(0)? as usize;
                let polygon: Vec<usize> = (1..=n)
                    .map(|k| get(k).and_then(index))
                    .collect::<Result<_, _>>()?;
                fan(&polygon, &mut ply.triangles);
            }
        }
    }
    Ok(ply)
}

/// A face's vertex index as read: a whole number, 0 or more.
fn index(v: f64) -> Result<usize, String> {
    if v >= 0.0 && v.fract() == 0.0 && v < usize::MAX as f64 {
        Ok(v as usize)
    } else {
        Err(format!(
            "a PLY face names vertex {v}, which is not an index (a whole number, 0 or more)"
        ))
    }
}

/// A polygon's triangles, fanned from its first corner.
fn fan(polygon: &[usize], triangles: &mut Vec<[usize; 3]>) {
    for k in 1..polygon.len().saturating_sub(1) {
        triangles.push([polygon[0], polygon[k], polygon[k + 1]]);
    }
}

fn parse_binary(
    body: &[u8],
    elements: &[Element],
    layout: &Layout,
    big: bool,
) -> Result<Ply, String> {
    let short = || "PLY file is shorter than its header says".to_string();
    let mut pos = 0usize;
    let mut ply = layout.empty(elements, body.len());
    let mut polygon = Vec::new();
    for (e, element) in elements.iter().enumerate().take(layout.last() + 1) {
        for _ in 0..element.count {
            let mut values = [0.0f64; 3];
            for (k, property) in element.properties.iter().enumerate() {
                match property {
                    Property::Scalar(_, ty) => {
                        let b = body.get(pos..pos + ty.size()).ok_or_else(short)?;
                        if e == layout.vertex
                            && let Some(axis) = layout.xyz.iter().position(|&a| a == k)
                        {
                            values[axis] = ty.read(b, big);
                        }
                        pos += ty.size();
                    }
                    Property::List(_, count_ty, item_ty) => {
                        let b = body.get(pos..pos + count_ty.size()).ok_or_else(short)?;
                        let n = count_ty.read(b, big) as usize;
                        pos += count_ty.size();
                        let items = body.get(pos..pos + n * item_ty.size()).ok_or_else(short)?;
                        if layout.faces == Some((e, k)) {
                            polygon.clear();
                            for b in items.chunks_exact(item_ty.size()) {
                                polygon.push(index(item_ty.read(b, big))?);
                            }
                            fan(&polygon, &mut ply.triangles);
                        }
                        pos += n * item_ty.size();
                    }
                }
            }
            if e == layout.vertex {
                ply.points.push(Point3::from(values));
            }
        }
    }
    Ok(ply)
}

pub(crate) fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_with_faces_before_vertices() {
        let ply = b"ply\nformat ascii 1.0\ncomment made by hand\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 2\nproperty float y\nproperty float x\nproperty float z\nproperty uchar red\nend_header\n3 0 1 1\n1.5 2.5 3.5 255\n-1 -2 -3 0\n";
        let ply = parse(ply).unwrap();
        assert_eq!(
            ply.points,
            vec![Point3::new(2.5, 1.5, 3.5), Point3::new(-2.0, -1.0, -3.0)]
        );
        assert_eq!(ply.triangles, vec![[0, 1, 1]]);
    }

    #[test]
    fn binary_little_and_big_endian() {
        for big in [false, true] {
            let mut b = format!(
                "ply\nformat {} 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar intensity\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
                if big { "binary_big_endian" } else { "binary_little_endian" }
            )
            .into_bytes();
            for v in [[1.0f64, 2.0, 3.0], [4.0, 5.0, 6.25]] {
                for c in v {
                    b.extend_from_slice(&if big {
                        c.to_be_bytes()
                    } else {
                        c.to_le_bytes()
                    });
                }
                b.push(7);
            }
            // A quad: two triangles.
            b.push(4);
            for i in [0i32, 1, 1, 0] {
                b.extend_from_slice(&if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
            let ply = parse(&b).unwrap();
            assert_eq!(ply.points[1], Point3::new(4.0, 5.0, 6.25));
            assert_eq!(ply.triangles, vec![[0, 1, 1], [0, 1, 0]]);
            assert!(parse(&b[..b.len() - 10]).is_err());
        }
    }

    #[test]
    fn rejects_non_ply() {
        assert!(parse(b"hello").is_err());
        assert!(
            parse(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
                .is_err()
        );
    }

    #[test]
    fn a_negative_face_index_is_refused() {
        let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n";
        let err = parse(ply).err().unwrap();
        assert!(err.contains("names vertex -1"), "{err}");
        let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        binary.extend([0u8; 36]);
        binary.push(3);
        for i in [0i32, -7, 2] {
            binary.extend(i.to_le_bytes());
        }
        let err = parse(&binary).err().unwrap();
        assert!(err.contains("names vertex -7"), "{err}");
    }
}

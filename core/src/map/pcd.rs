//! PCD point clouds (the Point Cloud Library's format): `DATA ascii`,
//! `binary` and `binary_compressed` (LZF, fields stored column by column).

use nalgebra::Point3;

struct Field {
    name: String,
    size: usize,
    kind: char,
    count: usize,
}

impl Field {
    fn bytes(&self) -> usize {
        self.size * self.count
    }

    fn read(&self, b: &[u8]) -> Option<f64> {
        Some(match (self.kind, self.size) {
            ('F', 4) => f64::from(f32::from_le_bytes(b.get(..4)?.try_into().ok()?)),
            ('F', 8) => f64::from_le_bytes(b.get(..8)?.try_into().ok()?),
            ('I', 1) => f64::from(*b.first()? as i8),
            ('U', 1) => f64::from(*b.first()?),
            ('I', 2) => f64::from(i16::from_le_bytes(b.get(..2)?.try_into().ok()?)),
            ('U', 2) => f64::from(u16::from_le_bytes(b.get(..2)?.try_into().ok()?)),
            ('I', 4) => f64::from(i32::from_le_bytes(b.get(..4)?.try_into().ok()?)),
            ('U', 4) => f64::from(u32::from_le_bytes(b.get(..4)?.try_into().ok()?)),
            _ => return None,
        })
    }
}

pub fn parse(bytes: &[u8]) -> Result<Vec<Point3<f64>>, String> {
    let (header, body) = split_header(bytes)?;
    let header = Header::parse(header)?;
    let layout = Layout::of(&header.fields)?;
    let n = header.points;
    layout.total(n)?;
    let mut points = match header.data.as_str() {
        "ascii" => read_ascii(body, &layout, n)?,
        "binary" => read_binary(body, &header.fields, &layout, n)?,
        "binary_compressed" => read_compressed(body, &header.fields, &layout, n)?,
        other => return Err(format!("unknown PCD DATA kind {other:?}")),
    };
    // PCL marks missing points as NaN in organised clouds.
    points.retain(|p| p.iter().all(|v| v.is_finite()));
    Ok(points)
}

/// The header's text (through the `DATA` line) and the body after it.
fn split_header(bytes: &[u8]) -> Result<(&str, &[u8]), String> {
    let data_line = super::ply::find(bytes, b"\nDATA ").ok_or("not a PCD file: no DATA line")?;
    let eol = bytes[data_line + 1..]
        .iter()
        .position(|&b| b == b'\n')
        .map(|p| data_line + 1 + p)
        .ok_or("PCD header has no end")?;
    let header = std::str::from_utf8(&bytes[..eol]).map_err(|_| "PCD header is not text")?;
    Ok((header, &bytes[eol + 1..]))
}

/// What a PCD header says: its fields, its point count and how the data
/// is stored.
struct Header {
    fields: Vec<Field>,
    points: usize,
    data: String,
}

impl Header {
    fn parse(header: &str) -> Result<Self, String> {
        let mut names = Vec::new();
        let mut sizes = Vec::new();
        let mut kinds = Vec::new();
        let mut counts = Vec::new();
        let mut points = None;
        let mut data = "";
        for line in header
            .lines()
            .map(str::trim)
            .filter(|l| !l.starts_with('#'))
        {
            let mut words = line.split_whitespace();
            let key = words.next().unwrap_or_default();
            let rest: Vec<&str> = words.collect();
            match key {
                "FIELDS" => names = rest.iter().map(|s| s.to_string()).collect(),
                "SIZE" => sizes = parse_all(&rest, line)?,
                "TYPE" => {
                    kinds = rest
                        .iter()
                        .map(|s| s.chars().next().unwrap_or('?'))
                        .collect()
                }
                "COUNT" => counts = parse_all(&rest, line)?,
                "POINTS" => {
                    points = Some(
                        parse_all::<usize>(&rest, line)?
                            .first()
                            .copied()
                            .unwrap_or(0),
                    )
                }
                "DATA" => data = rest.first().copied().unwrap_or_default(),
                _ => {}
            }
        }
        if counts.is_empty() {
            counts = vec![1; names.len()];
        }
        if sizes.len() != names.len() || kinds.len() != names.len() || counts.len() != names.len() {
            return Err("PCD header's FIELDS, SIZE, TYPE and COUNT disagree in length".into());
        }
        let fields = (0..names.len())
            .map(|i| Field {
                name: names[i].clone(),
                size: sizes[i],
                kind: kinds[i],
                count: counts[i],
            })
            .collect();
        Ok(Self {
            fields,
            points: points.ok_or("PCD header has no POINTS line")?,
            data: data.to_string(),
        })
    }
}

/// Where x, y and z are in a point: their fields, each field's byte offset
/// and value column, and a point's bytes.
struct Layout {
    xyz: [usize; 3],
    offsets: Vec<usize>,
    columns: Vec<usize>,
    point_size: usize,
}

impl Layout {
    fn of(fields: &[Field]) -> Result<Self, String> {
        let axis = |a: &str| {
            fields
                .iter()
                .position(|f| f.name == a)
                .ok_or(format!("PCD file has no {a} field"))
        };
        let xyz = [axis("x")?, axis("y")?, axis("z")?];
        // A point's bytes and values, checked: a SIZE or COUNT no file holds
        // would wrap them.
        let values = fields
            .iter()
            .try_fold(0usize, |sum, f| sum.checked_add(f.count));
        let point_size = fields
            .iter()
            .try_fold(0usize, |sum, f| {
                sum.checked_add(f.size.checked_mul(f.count)?)
            })
            .filter(|_| values.is_some())
            .ok_or("PCD header's SIZE and COUNT give a point more bytes than any file holds")?;
        if point_size == 0 {
            return Err("PCD header gives its fields no size (SIZE or COUNT 0)".into());
        }
        let running = |each: fn(&Field) -> usize| {
            fields
                .iter()
                .scan(0, |sum, f| {
                    let at = *sum;
                    *sum += each(f);
                    Some(at)
                })
                .collect()
        };
        Ok(Self {
            xyz,
            offsets: running(Field::bytes),
            columns: running(|f| f.count),
            point_size,
        })
    }

    /// The points' bytes, checked before anything is read or allocated by
    /// them.
    fn total(&self, n: usize) -> Result<usize, String> {
        n.checked_mul(self.point_size)
            .ok_or_else(|| format!("PCD header claims {n} points, more than any file holds"))
    }
}

fn short() -> String {
    "PCD file is shorter than its header says".to_string()
}

/// `DATA ascii`: a line per point, each field giving COUNT values.
fn read_ascii(body: &[u8], layout: &Layout, n: usize) -> Result<Vec<Point3<f64>>, String> {
    let text = std::str::from_utf8(body).map_err(|_| "PCD ascii data is not text")?;
    // The header's count is a claim; reserve no more than the body can hold.
    let mut points = Vec::with_capacity(n.min(body.len()));
    for line in text.lines().filter(|l| !l.trim().is_empty()).take(n) {
        let values: Vec<&str> = line.split_whitespace().collect();
        let get = |a: usize| -> Result<f64, String> {
            values
                .get(layout.columns[layout.xyz[a]])
                .and_then(|v| v.parse().ok())
                .ok_or(format!("bad PCD line {line:?}"))
        };
        points.push(Point3::new(get(0)?, get(1)?, get(2)?));
    }
    if points.len() < n {
        return Err(short());
    }
    Ok(points)
}

/// `DATA binary`: the points one after the other.
fn read_binary(
    body: &[u8],
    fields: &[Field],
    layout: &Layout,
    n: usize,
) -> Result<Vec<Point3<f64>>, String> {
    if layout.total(n)? > body.len() {
        return Err(short());
    }
    let size = layout.point_size;
    (0..n)
        .map(|i| {
            let p = body.get(i * size..(i + 1) * size).ok_or_else(short)?;
            let get = |a: usize| {
                let field = layout.xyz[a];
                fields[field]
                    .read(&p[layout.offsets[field]..])
                    .ok_or("unsupported PCD field type")
            };
            Ok(Point3::new(get(0)?, get(1)?, get(2)?))
        })
        .collect()
}

/// `DATA binary_compressed`: LZF of the points stored field by field (all
/// points' first field, then the second, ...).
fn read_compressed(
    body: &[u8],
    fields: &[Field],
    layout: &Layout,
    n: usize,
) -> Result<Vec<Point3<f64>>, String> {
    let total = layout.total(n)?;
    let word = |at: usize| -> Result<usize, String> {
        Ok(
            u32::from_le_bytes(body.get(at..at + 4).ok_or_else(short)?.try_into().unwrap())
                as usize,
        )
    };
    let (compressed, raw) = (word(0)?, word(4)?);
    if raw != total {
        return Err("PCD compressed data has the wrong size".into());
    }
    let src = body.get(8..8 + compressed).ok_or_else(short)?;
    let soa = lzf_decompress(src, raw)?;
    if soa.len() != total {
        return Err("PCD compressed data has the wrong size".into());
    }
    let column = |a: usize, i: usize| {
        let field = layout.xyz[a];
        let f = &fields[field];
        let start = layout.offsets[field] * n + i * f.bytes();
        f.read(&soa[start..]).ok_or("unsupported PCD field type")
    };
    (0..n)
        .map(|i| Ok(Point3::new(column(0, i)?, column(1, i)?, column(2, i)?)))
        .collect()
}

fn parse_all<T: std::str::FromStr>(words: &[&str], line: &str) -> Result<Vec<T>, String> {
    words
        .iter()
        .map(|w| {
            w.parse()
                .map_err(|_| format!("bad PCD header line {line:?}"))
        })
        .collect()
}

/// Decompress LZF (liblzf's format, as PCL writes it).
fn lzf_decompress(src: &[u8], expected: usize) -> Result<Vec<u8>, String> {
    let bad = || "corrupt LZF data in PCD file".to_string();
    // The expected size is the header's claim: LZF expands at most ~100x.
    let mut out = Vec::with_capacity(expected.min(src.len().saturating_mul(100)));
    let mut i = 0;
    while i < src.len() {
        let ctrl = usize::from(src[i]);
        i += 1;
        if ctrl < 32 {
            let run = src.get(i..i + ctrl + 1).ok_or_else(bad)?;
            out.extend_from_slice(run);
            i += ctrl + 1;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += usize::from(*src.get(i).ok_or_else(bad)?);
                i += 1;
            }
            let back = ((ctrl & 0x1f) << 8) + usize::from(*src.get(i).ok_or_else(bad)?) + 1;
            i += 1;
            let start = out.len().checked_sub(back).ok_or_else(bad)?;
            // Overlapping copies repeat bytes, so copy one at a time.
            for k in 0..len + 2 {
                let b = out[start + k];
                out.push(b);
            }
        }
        if out.len() > expected {
            return Err(bad());
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 8 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n";

    fn points() -> [[f64; 3]; 2] {
        [[1.0, 2.0, 3.0], [-4.5, 0.25, 1e3]]
    }

    fn binary_points() -> Vec<u8> {
        let mut b = Vec::new();
        for p in points() {
            b.extend_from_slice(&(p[0] as f32).to_le_bytes());
            b.extend_from_slice(&(p[1] as f32).to_le_bytes());
            b.extend_from_slice(&p[2].to_le_bytes());
            b.extend_from_slice(&7u32.to_le_bytes());
        }
        b
    }

    fn expected() -> Vec<Point3<f64>> {
        points().iter().map(|p| Point3::from(*p)).collect()
    }

    #[test]
    fn ascii_and_binary() {
        let ascii = format!("{HEADER}DATA ascii\n1 2 3 7\n-4.5 0.25 1000 7\n");
        assert_eq!(parse(ascii.as_bytes()).unwrap(), expected());
        let mut bin = format!("{HEADER}DATA binary\n").into_bytes();
        bin.extend_from_slice(&binary_points());
        assert_eq!(parse(&bin).unwrap(), expected());
        assert!(parse(&bin[..bin.len() - 1]).is_err());
    }

    #[test]
    fn binary_compressed_is_field_major_lzf() {
        let aos = binary_points();
        // Reorder to field-major, then "compress" as LZF literal runs plus one
        // back-reference, which is what liblzf emits for repeated bytes.
        let mut soa = Vec::new();
        for (off, size) in [(0, 4), (4, 4), (8, 8), (16, 4)] {
            for i in 0..2 {
                soa.extend_from_slice(&aos[i * 20 + off..i * 20 + off + size]);
            }
        }
        let (head, tail) = soa.split_at(32);
        assert_eq!(tail, [7, 0, 0, 0, 7, 0, 0, 0]);
        let mut lzf = vec![31u8];
        lzf.extend_from_slice(head);
        lzf.extend_from_slice(&[3, 7, 0, 0, 0]); // literal "7 0 0 0"
        lzf.extend_from_slice(&[(2 << 5) as u8, 3]); // copy 4 bytes from 4 back
        let mut file = format!("{HEADER}DATA binary_compressed\n").into_bytes();
        file.extend_from_slice(&(lzf.len() as u32).to_le_bytes());
        file.extend_from_slice(&(soa.len() as u32).to_le_bytes());
        file.extend_from_slice(&lzf);
        assert_eq!(parse(&file).unwrap(), expected());
    }

    #[test]
    fn a_count_no_file_holds_is_refused_before_anything_is_read() {
        // POINTS times the point size wraps a 64-bit size; and a count
        // the body is far too short for, in each DATA kind.
        for points in ["1537228672809129302", "4000000000"] {
            let header = HEADER.replace("POINTS 2", &format!("POINTS {points}"));
            for data in ["binary", "binary_compressed"] {
                let mut file = format!(
                    "{header}DATA {data}
"
                )
                .into_bytes();
                file.extend_from_slice(&[8, 0, 0, 0, 40, 0, 0, 0]);
                file.extend_from_slice(&binary_points());
                let err = parse(&file).unwrap_err();
                assert!(err.contains("PCD"), "{points} {data}: {err}");
            }
        }
        // Found by the `pcd` fuzz target: a COUNT whose bytes wrap a
        // 64-bit size (a panic in debug builds).
        let counted = HEADER.replace("COUNT 1 1 1 1", "COUNT 7039476560217360156 1 1 1");
        let err = parse(format!("{counted}DATA binary\n").as_bytes()).unwrap_err();
        assert!(err.contains("more bytes than any file holds"), "{err}");
        let sizeless = HEADER.replace("SIZE 4 4 8 4", "SIZE 0 0 0 0");
        let err = parse(
            format!(
                "{sizeless}DATA binary
"
            )
            .as_bytes(),
        )
        .unwrap_err();
        assert!(err.contains("no size"), "{err}");
    }
}

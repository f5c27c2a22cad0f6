//! Text prompts for open-vocabulary models: prompt names to text embeddings,
//! assembled into the `[1, nc, dim]` input. Two file forms:
//! - JSON, `{"crack": [0.01, ...], ...}`;
//! - NumPy `.npy`, a `[n, dim]` float32/float64 array (CLIP text features
//!   saved with `np.save`), with the `n` prompt names one per line in a
//!   `.txt` file of the same stem beside it.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::DetectError;

/// Embeddings of named prompts, each L2-normalised.
pub struct Embeddings(BTreeMap<String, Vec<f32>>);

impl Embeddings {
    /// Read embeddings from JSON or `.npy` (with its `.txt` of names).
    pub fn load(path: &Path) -> Result<Self, DetectError> {
        let bad = |why: String| DetectError::Embeddings {
            path: path.to_owned(),
            why,
        };
        let bytes = postflight_core::user_file::read(path).map_err(|e| {
            bad(format!(
                "{e}; check the path given to {}",
                crate::settings::keys::embeddings
            ))
        })?;
        let map = if path.extension().is_some_and(|e| e == "npy") {
            named_rows(path, &bytes).map_err(bad)?
        } else {
            serde_json::from_slice::<BTreeMap<String, Vec<f32>>>(&bytes).map_err(|e| {
                bad(format!(
                    "expected JSON {{\"prompt\": [numbers, ...]}} or a .npy array: {e}"
                ))
            })?
        };
        let mut out = BTreeMap::new();
        for (name, v) in map {
            let norm = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                return Err(bad(format!(
                    "the embedding of {name:?} is zero or not finite"
                )));
            }
            out.insert(name, v.iter().map(|x| x / norm).collect());
        }
        Ok(Self(out))
    }

    /// The `[1, classes, dim]` text input for `prompts`: padded with zero
    /// rows (which score nothing) or refused when the model's `classes` is
    /// fixed and smaller.
    pub fn input(
        &self,
        prompts: &[String],
        classes: Option<usize>,
        dim: usize,
    ) -> Result<(Vec<f32>, usize), String> {
        let mut rows = Vec::new();
        for p in prompts {
            let v = self.0.get(p).ok_or_else(|| {
                format!(
                    "no embedding for prompt {p:?}; the embeddings file has {}",
                    self.0.keys().cloned().collect::<Vec<_>>().join(", ")
                )
            })?;
            if v.len() != dim {
                return Err(format!(
                    "the embedding of {p:?} has {} values, the model takes {dim}",
                    v.len()
                ));
            }
            rows.extend_from_slice(v);
        }
        let n = classes.unwrap_or(prompts.len());
        if prompts.len() > n {
            return Err(format!(
                "{} prompts given, the model scores at most {n}",
                prompts.len()
            ));
        }
        rows.resize(n * dim, 0.0);
        Ok((rows, n))
    }
}

/// The rows of a `.npy` array named by the lines of the `.txt` beside it.
fn named_rows(path: &Path, bytes: &[u8]) -> Result<BTreeMap<String, Vec<f32>>, String> {
    let names_path = path.with_extension("txt");
    let names = postflight_core::user_file::read_to_string(&names_path).map_err(|e| {
        format!(
            "cannot read the prompt names {} ({e}); write one name per line, in the order of the array's rows",
            names_path.display()
        )
    })?;
    let names: Vec<&str> = names
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let (rows, dim, values) = read_npy(bytes)?;
    if rows != names.len() || dim == 0 {
        return Err(format!(
            "{rows} embeddings of {dim} values but {} names in {}",
            names.len(),
            names_path.display()
        ));
    }
    Ok(names
        .iter()
        .zip(values.chunks(dim))
        .map(|(n, v)| (n.to_string(), v.to_vec()))
        .collect())
}

/// A 2-D little-endian float array from `.npy` bytes: `(rows, columns, values)`.
fn read_npy(bytes: &[u8]) -> Result<(usize, usize, Vec<f32>), String> {
    let bad = || {
        "not a NumPy .npy file (expected the \\x93NUMPY magic); save it with np.save".to_string()
    };
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad());
    }
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(bad()),
    };
    let header = bytes
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(bad)?;
    let field = |key: &str| -> Option<&str> {
        let at = header.find(&format!("'{key}':"))? + key.len() + 3;
        Some(header[at..].trim_start())
    };
    let descr = field("descr").ok_or_else(bad)?;
    let width = if descr.starts_with("'<f4'") {
        4
    } else if descr.starts_with("'<f8'") {
        8
    } else {
        return Err(format!(
            "the array holds {}, expected float32 or float64 ('<f4' or '<f8')",
            descr.split(',').next().unwrap_or(descr)
        ));
    };
    if field("fortran_order").is_some_and(|v| v.starts_with("True")) {
        return Err("the array is in Fortran order; save np.ascontiguousarray(a)".into());
    }
    let shape = field("shape").ok_or_else(bad)?;
    let dims: Vec<usize> = shape[1..shape.find(')').ok_or_else(bad)?]
        .split(',')
        .map(str::trim)
        .filter(|d| !d.is_empty())
        .map(|d| d.parse().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let [rows, columns] = dims[..] else {
        return Err(format!(
            "the array has shape {dims:?}, expected [prompts, dim]"
        ));
    };
    let data = &bytes[start + header_len..];
    if data.len() != rows * columns * width {
        return Err(format!(
            "the array's data is {} bytes, its shape [{rows}, {columns}] needs {}",
            data.len(),
            rows * columns * width
        ));
    }
    let values = if width == 4 {
        data.chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    } else {
        data.chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
            .collect()
    };
    Ok((rows, columns, values))
}

//! Text prompts for open-vocabulary models: prompt names to text embeddings
//! (`{"crack": [0.01, ...], ...}`), assembled into the `[1, nc, dim]` input.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::DetectError;

/// Embeddings of named prompts, each L2-normalised.
pub struct Embeddings(BTreeMap<String, Vec<f32>>);

impl Embeddings {
    /// Read a JSON object of prompt name to embedding vector.
    pub fn load(path: &Path) -> Result<Self, DetectError> {
        let bad = |why: String| DetectError::Embeddings {
            path: path.to_owned(),
            why,
        };
        let text = std::fs::read_to_string(path)
            .map_err(|e| bad(format!("{e}; check the path given to --embeddings")))?;
        let map: BTreeMap<String, Vec<f32>> = serde_json::from_str(&text)
            .map_err(|e| bad(format!("expected {{\"prompt\": [numbers, ...]}}: {e}")))?;
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

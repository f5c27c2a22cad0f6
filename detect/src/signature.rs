//! What a detector model expects and returns, read from its inputs and
//! outputs: YOLO-World's two export interfaces (prompts baked in, or text
//! embeddings as an input), and what its outputs hold: boxes, boxes with a
//! crack probability map, Ultralytics instance segmentation, or a semantic
//! segmentation map alone.

use std::fmt::Write;

/// A tensor of the model: its name and shape (`-1` for a dynamic dimension).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorSpec {
    pub name: String,
    pub shape: Vec<i64>,
}

/// How prompts reach the model.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Vocabulary {
    /// Class names are baked into the export (Ultralytics `set_classes` then `export`).
    Baked,
    /// Text embeddings `[1, nc, dim]` are a second input (CLIP text features).
    Embeddings { input: String, dim: usize },
}

/// The interface of a detector export.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signature {
    /// Image input `[batch, 3, height, width]`.
    pub images: String,
    /// Fixed batch size, or `None` when dynamic.
    pub batch: Option<usize>,
    /// Fixed input `(height, width)`, or `None` when dynamic.
    pub input_size: Option<(u32, u32)>,
    pub vocabulary: Vocabulary,
    /// Number of classes the output scores (`nc`), when fixed.
    pub classes: Option<usize>,
    pub head: Head,
}

/// What a model's outputs hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Head {
    /// `[batch, 4 + classes, anchors]`: boxes and class scores (YOLO detect).
    Boxes { output: String },
    /// Boxes as [`Head::Boxes`], and a crack probability map `[batch, 1,
    /// height, width]` over the input (postflight's reference detector).
    BoxesAndMap { output: String, map: String },
    /// Ultralytics instance segmentation (`-seg` models): `[batch, 4 +
    /// classes + k, anchors]`, each anchor's mask coefficients last, and
    /// `k` prototypes `[batch, k, height / 4, width / 4]`.
    Instances {
        output: String,
        prototypes: String,
        coefficients: usize,
    },
    /// Semantic segmentation: one map `[batch, 1, height, width]` of crack
    /// probability (logits where values leave 0..1), or `[batch, channels,
    /// height, width]` logits of each class (background and crack, or the
    /// classes the model's names list). The channel count is read
    /// from each result: PyTorch's exporter often leaves every dimension of
    /// such an output unnamed.
    Semantic { output: String },
}

impl Head {
    /// Rows of the boxes output besides the box and class scores.
    pub fn extra_rows(&self) -> usize {
        match self {
            Self::Instances { coefficients, .. } => *coefficients,
            _ => 0,
        }
    }
}

fn fixed(d: i64) -> Option<usize> {
    usize::try_from(d).ok().filter(|d| *d > 0)
}

fn describe(specs: &[TensorSpec]) -> String {
    let mut s = String::new();
    for (i, t) in specs.iter().enumerate() {
        let dims: Vec<String> = t
            .shape
            .iter()
            .map(|d| if *d < 0 { "?".into() } else { d.to_string() })
            .collect();
        let _ = write!(
            s,
            "{}{} [{}]",
            if i > 0 { ", " } else { "" },
            t.name,
            dims.join(", ")
        );
    }
    s
}

impl Signature {
    /// Recognise the interface of an opened model.
    pub fn of_session(session: &ort::session::Session) -> Result<Self, String> {
        let specs = |outlets: &[ort::value::Outlet]| -> Vec<TensorSpec> {
            outlets
                .iter()
                .map(|o| TensorSpec {
                    name: o.name().to_string(),
                    shape: o
                        .dtype()
                        .tensor_shape()
                        .map(|s| s.to_vec())
                        .unwrap_or_default(),
                })
                .collect()
        };
        Self::of(&specs(session.inputs()), &specs(session.outputs()))
    }

    /// Recognise the interface from the model's inputs and outputs.
    pub fn of(inputs: &[TensorSpec], outputs: &[TensorSpec]) -> Result<Self, String> {
        let mismatch = || {
            format!(
                "inputs {} and outputs {} match no detector interface: expected images [batch, 3, height, width] (optionally with text embeddings [1, classes, dim]), and boxes [batch, 4 + classes, anchors] (with a probability map [batch, 1, height, width] or Ultralytics mask prototypes [batch, k, h, w]), or a segmentation map [batch, classes, height, width] alone",
                describe(inputs),
                describe(outputs)
            )
        };
        let is_image = |t: &&TensorSpec| t.shape.len() == 4 && (t.shape[1] == 3 || t.shape[1] < 0);
        let images: Vec<&TensorSpec> = inputs.iter().filter(is_image).collect();
        let images = match images.as_slice() {
            [one] => *one,
            many => *many
                .iter()
                .find(|t| t.name == "images")
                .ok_or_else(mismatch)?,
        };
        let others: Vec<&TensorSpec> = inputs.iter().filter(|t| t.name != images.name).collect();
        let (vocabulary, text_classes) = match others.as_slice() {
            [] => (Vocabulary::Baked, None),
            [text] if text.shape.len() == 3 => {
                let dim = fixed(text.shape[2]).ok_or_else(mismatch)?;
                (
                    Vocabulary::Embeddings {
                        input: text.name.clone(),
                        dim,
                    },
                    fixed(text.shape[1]),
                )
            }
            _ => return Err(mismatch()),
        };
        let (rank3, rank4): (Vec<&TensorSpec>, Vec<&TensorSpec>) =
            outputs.iter().partition(|t| t.shape.len() == 3);
        let (head, box_rows) = match (rank3.as_slice(), rank4.as_slice()) {
            ([boxes], []) if outputs.len() == 1 => (
                Head::Boxes {
                    output: boxes.name.clone(),
                },
                fixed(boxes.shape[1]),
            ),
            ([boxes], [planes]) if planes.shape.len() == 4 => match fixed(planes.shape[1]) {
                Some(1) => (
                    Head::BoxesAndMap {
                        output: boxes.name.clone(),
                        map: planes.name.clone(),
                    },
                    fixed(boxes.shape[1]),
                ),
                Some(k) if k > 2 => (
                    Head::Instances {
                        output: boxes.name.clone(),
                        prototypes: planes.name.clone(),
                        coefficients: k,
                    },
                    fixed(boxes.shape[1]).and_then(|rows| rows.checked_sub(k)),
                ),
                _ => return Err(mismatch()),
            },
            ([], [map]) if outputs.len() == 1 && map.shape.len() == 4 => {
                // Its classes are its channels', named by the model.
                (
                    Head::Semantic {
                        output: map.name.clone(),
                    },
                    None,
                )
            }
            _ => return Err(mismatch()),
        };
        let classes = match (box_rows, text_classes) {
            (Some(rows), _) if rows > 4 => Some(rows - 4),
            (Some(_), _) => return Err(mismatch()),
            (None, c) => c,
        };
        if let (Some(c), Some(t)) = (classes, text_classes)
            && c != t
        {
            return Err(mismatch());
        }
        let input_size = match (fixed(images.shape[2]), fixed(images.shape[3])) {
            (Some(h), Some(w)) => Some((h as u32, w as u32)),
            _ => None,
        };
        Ok(Self {
            images: images.name.clone(),
            batch: fixed(images.shape[0]),
            input_size,
            vocabulary,
            classes,
            head,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(name: &str, shape: &[i64]) -> TensorSpec {
        TensorSpec {
            name: name.into(),
            shape: shape.to_vec(),
        }
    }

    #[test]
    fn recognises_both_interfaces() {
        let baked = Signature::of(
            &[t("images", &[1, 3, 640, 640])],
            &[t("output0", &[1, 5, 8400])],
        )
        .unwrap();
        assert_eq!(baked.vocabulary, Vocabulary::Baked);
        assert_eq!(
            (baked.classes, baked.input_size, baked.batch),
            (Some(1), Some((640, 640)), Some(1))
        );

        let open = Signature::of(
            &[t("images", &[-1, 3, -1, -1]), t("txt_feats", &[1, 80, 512])],
            &[t("output0", &[-1, 84, -1])],
        )
        .unwrap();
        assert_eq!(
            open.vocabulary,
            Vocabulary::Embeddings {
                input: "txt_feats".into(),
                dim: 512
            }
        );
        assert_eq!(
            (open.classes, open.input_size, open.batch),
            (Some(80), None, None)
        );
    }

    #[test]
    fn names_the_shapes_when_nothing_matches() {
        let err = Signature::of(&[t("input", &[1, 224, 224, 3])], &[t("logits", &[1, 1000])])
            .unwrap_err();
        assert!(
            err.contains("input [1, 224, 224, 3]") && err.contains("logits [1, 1000]"),
            "{err}"
        );
        let err = Signature::of(
            &[t("images", &[1, 3, 640, 640]), t("txt", &[1, 8, 512])],
            &[t("output0", &[1, 84, 8400])],
        )
        .unwrap_err();
        assert!(err.contains("match no detector interface"), "{err}");
    }

    #[test]
    fn recognises_what_the_outputs_hold() {
        let images = [t("images", &[1, 3, 640, 640])];
        let seg = Signature::of(
            &images,
            &[
                t("output0", &[1, 37, 8400]),
                t("output1", &[1, 32, 160, 160]),
            ],
        )
        .unwrap();
        assert_eq!(
            seg.head,
            Head::Instances {
                output: "output0".into(),
                prototypes: "output1".into(),
                coefficients: 32
            }
        );
        assert_eq!(seg.classes, Some(1));
        let reference = Signature::of(
            &images,
            &[t("output0", &[1, 5, -1]), t("mask", &[1, 1, -1, -1])],
        )
        .unwrap();
        assert!(matches!(reference.head, Head::BoxesAndMap { .. }));
        let semantic = Signature::of(&images, &[t("logits", &[1, 2, 640, 640])]).unwrap();
        let logits = Head::Semantic {
            output: "logits".into(),
        };
        assert_eq!((&semantic.head, semantic.classes), (&logits, None));
        // As torch.onnx.export leaves a DeepLabV3's output: nothing named.
        let exported = Signature::of(&images, &[t("logits", &[-1, -1, -1, -1])]).unwrap();
        assert_eq!(exported.head, logits);
        let classes = Signature::of(&images, &[t("seg", &[1, 7, 640, 640])]).unwrap();
        assert!(matches!(classes.head, Head::Semantic { .. }));
        let two_maps = [t("a", &[1, 2, 64, 64]), t("b", &[1, 2, 64, 64])];
        assert!(Signature::of(&images, &two_maps).is_err());
    }
}

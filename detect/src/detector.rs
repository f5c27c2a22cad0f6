//! A model ready to run: its session, its interface, its input size and
//! pixel convention, and for open-vocabulary models the text input, built
//! once; frames run in batches of views of one input size.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::time::Instant;

use ort::session::SessionInputValue;
use ort::value::{Tensor, TensorRef};
use postflight_core::detection::{Detection, FrameDetection};

use crate::classes::Classes;
use crate::convention::{self, Declared};
use crate::error::DetectError;
use crate::letterbox::{InputSize, PAD};
use crate::metadata::{baked_names, metadata, model_stride, train_px};
use crate::prompts::Embeddings;
use crate::read::{FrameFound, Reader};
use crate::settings::keys;
use crate::signature::{Signature, Vocabulary};
use crate::stage::DetectOptions;
use crate::views::{Feed, Prepared, View};

/// A model ready to run: its session, its interface, and for
/// open-vocabulary models the text input, built once.
pub(crate) struct Detector {
    pub(crate) session: ort::session::Session,
    pub(crate) signature: Signature,
    /// How large an input each view gets, and its pixels' convention.
    pub(crate) feed: Feed,
    /// Classes a boxes output scores.
    pub(crate) box_classes: usize,
    /// The model's classes and the kinds they find.
    pub(crate) classes: Classes,
    /// Views per `run`.
    pub(crate) batch: usize,
    /// Text embeddings input: its name and value.
    pub(crate) text: Option<(String, Tensor<f32>)>,
    /// Wall time spent inside `run`, seconds.
    pub(crate) run_seconds: f64,
}

impl Detector {
    /// Recognise the model `path`'s interface and prepare its inputs.
    /// With `own_scale`, a model of dynamic input runs at the scale its
    /// metadata says it was trained at (an area model), not `imgsz`.
    pub(crate) fn new(
        session: ort::session::Session,
        path: &std::path::Path,
        options: &DetectOptions,
        own_scale: bool,
    ) -> Result<Self, DetectError> {
        let model_error = |why: String| DetectError::Model {
            path: path.to_owned(),
            why,
        };
        let signature = Signature::of_session(&session).map_err(model_error)?;
        // Read once: the stride, the class names and the input convention.
        let metadata = metadata(&session);
        let size = match signature.input_size {
            Some((h, w)) => InputSize::Fixed(w, h),
            None => InputSize::Rect {
                size: train_px(&metadata)
                    .filter(|_| own_scale)
                    .unwrap_or(options.settings.image_size),
                stride: model_stride(&metadata).unwrap_or(DetectOptions::DEFAULT_STRIDE),
            },
        };
        let declared = Declared::of(&metadata).map_err(model_error)?;
        let feed = Feed {
            size,
            convention: convention::resolve(&options.settings, &declared),
        };
        let (text, names) = match &signature.vocabulary {
            Vocabulary::Baked => (
                None,
                baked_names(&metadata).unwrap_or_else(|| options.settings.prompts.clone()),
            ),
            Vocabulary::Embeddings { input, dim } => {
                let path = options.settings.embeddings.as_deref().ok_or_else(|| {
                    model_error(format!(
                        "takes text embeddings; give them (prompts.json) as {}",
                        keys::embeddings
                    ))
                })?;
                let (rows, n) = Embeddings::load(path)?
                    .input(&options.settings.prompts, signature.classes, *dim)
                    .map_err(|why| DetectError::Embeddings {
                        path: path.to_owned(),
                        why,
                    })?;
                let tensor = Tensor::from_array((vec![1i64, n as i64, *dim as i64], rows))
                    .map_err(|e| model_error(e.to_string()))?;
                (
                    Some((input.clone(), n, tensor)),
                    options.settings.prompts.clone(),
                )
            }
        };
        let box_classes = signature
            .classes
            .or(text.as_ref().map(|t| t.1))
            .unwrap_or(names.len());
        let classes = Classes::of(names, &options.settings.class_kinds).map_err(model_error)?;
        Ok(Self {
            session,
            feed,
            box_classes,
            classes,
            batch: signature.batch.unwrap_or(options.settings.batch),
            text: text.map(|(name, _, tensor)| (name, tensor)),
            run_seconds: 0.0,
            signature,
        })
    }

    /// Run the `pending` frames, moving their detections into `found`;
    /// returns how many frames ran.
    pub(crate) fn run_frames(
        &mut self,
        pending: &mut Vec<Prepared>,
        options: &DetectOptions,
        found: &mut Vec<FrameDetection>,
    ) -> Result<u64, DetectError> {
        let per_frame = self.frames(pending, options)?;
        let ran = pending.len() as u64;
        for (p, dets) in pending.drain(..).zip(per_frame) {
            found.extend(dets.into_iter().map(|detection| FrameDetection {
                frame: p.frame,
                time_ns: p.time_ns,
                detection,
            }));
        }
        Ok(ran)
    }

    /// Detections of each of `frames`: every view run (in batches), mapped
    /// to frame pixels, then NMS'd and merged per frame, with their crack
    /// pixels where the model segments.
    pub(crate) fn frames(
        &mut self,
        frames: &[Prepared],
        options: &DetectOptions,
    ) -> Result<Vec<Vec<Detection>>, DetectError> {
        // Views of one input size run together: a frame and its tiles can differ.
        let mut by_size: BTreeMap<(u32, u32), Vec<(usize, &View)>> = BTreeMap::new();
        for (i, p) in frames.iter().enumerate() {
            for v in &p.views {
                by_size.entry(v.size).or_default().push((i, v));
            }
        }
        let mut found: Vec<FrameFound> = frames.iter().map(FrameFound::new).collect();
        let mut stacked = Vec::new();
        let batch = self.batch;
        let chunks = by_size
            .iter()
            .flat_map(|(&size, views)| views.chunks(batch).map(move |c| (size, c)));
        for ((w, h), chunk) in chunks {
            let failed = |why: String| DetectError::Inference {
                frame: frames[chunk[0].0].frame,
                why,
            };
            let images = self.signature.batch.unwrap_or(chunk.len());
            let inputs = Inputs {
                images: &self.signature.images,
                text: self.text.as_ref(),
                padding: convention::padding(&self.feed.convention, PAD),
            };
            let started = Instant::now();
            let outputs = run_chunk(
                &mut self.session,
                inputs,
                chunk,
                images,
                (w, h),
                &mut stacked,
            )
            .map_err(failed)?;
            self.run_seconds += started.elapsed().as_secs_f64();
            let reader = Reader {
                head: &self.signature.head,
                box_classes: self.box_classes,
                classes: &self.classes,
                images,
            };
            for (b, &(i, view)) in chunk.iter().enumerate() {
                reader
                    .read_view(&outputs, b, view, options, &mut found[i])
                    .map_err(failed)?;
            }
        }
        Ok(found.into_iter().map(|f| f.finish(options)).collect())
    }
}

/// The model's inputs besides the images' values.
#[derive(Clone, Copy)]
pub(crate) struct Inputs<'a> {
    pub(crate) images: &'a str,
    pub(crate) text: Option<&'a (String, Tensor<f32>)>,
    /// Each channel's value of a padding pixel, as the model is fed.
    pub(crate) padding: [f32; 3],
}

/// Run one batch of views of size `(w, h)` as `images` images (a fixed
/// batch size is filled up with padding images).
pub(crate) fn run_chunk<'s>(
    session: &'s mut ort::session::Session,
    inputs: Inputs<'_>,
    chunk: &[(usize, &View)],
    images: usize,
    (w, h): (u32, u32),
    stacked: &mut Vec<f32>,
) -> Result<ort::session::SessionOutputs<'s>, String> {
    let input = if images == 1 {
        chunk[0].1.input.as_slice()
    } else {
        stacked.clear();
        let channel = (w * h) as usize;
        for k in 0..images {
            match chunk.get(k) {
                Some((_, view)) => stacked.extend_from_slice(&view.input),
                // A fixed batch is filled up with padding images.
                None => {
                    for value in inputs.padding {
                        stacked.extend(std::iter::repeat_n(value, channel));
                    }
                }
            }
        }
        stacked.as_slice()
    };
    let shape = vec![images as i64, 3, i64::from(h), i64::from(w)];
    let image = TensorRef::from_array_view((shape, input)).map_err(|e| e.to_string())?;
    let mut values: Vec<(Cow<str>, SessionInputValue)> = vec![(inputs.images.into(), image.into())];
    if let Some((name, tensor)) = inputs.text {
        values.push((name.as_str().into(), tensor.into()));
    }
    session.run(values).map_err(|e| e.to_string())
}

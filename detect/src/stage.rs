//! The detect stage: every frame of an ingested flight through the detector,
//! decoding and letterboxing on worker threads while ONNX Runtime infers,
//! into `detections.parquet`, `detections.coco.json` and `detect.json`.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use ingest::Recordings;
use ort::session::SessionInputValue;
use ort::value::{Tensor, TensorRef};
use postflight_core::detection::{BoxXyxy, Detection, FrameDetection};
use postflight_core::outputs::detect::{
    DetectSummary, DetectionRow, FailedFrame, InputConvention, files,
};
use postflight_core::run_log::sha256_file;
use postflight_core::{Flight, Frame, ImageStatus, InvalidSetting, Key, RunDir};
use rayon::prelude::*;

use crate::boxes::{merge_touching, nms, nms_with};
use crate::coco;
use crate::convention::{self, Declared};
use crate::decode::decode;
use crate::error::DetectError;
use crate::letterbox::{InputSize, PAD, Placement, letterbox};
use crate::masks::{
    MASK_THRESHOLD, Plane, ProbabilityMap, Prototypes, ViewPlace, finest_first, from_maps, regions,
};
use crate::prompts::Embeddings;
use crate::runtime::{Runtime, locate};
use crate::settings::{DetectConfig, Tile, keys};
use crate::signature::{Head, Signature, Vocabulary};
use crate::tiles::{Window, windows};

/// What detect runs and how. Serialised, it is what the stage's result
/// depends on besides its input files (`postflight run`'s fingerprint): the
/// settings, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct DetectOptions {
    #[serde(skip)]
    pub run: PathBuf,
    #[serde(skip)]
    pub model: PathBuf,
    /// ONNX Runtime library (default: found by [`locate`]).
    #[serde(skip)]
    pub onnxruntime: Option<PathBuf>,
    pub settings: DetectConfig,
}

impl DetectOptions {
    /// The stride a dynamic input is padded to when the model's metadata
    /// does not give one (YOLO's largest).
    pub const DEFAULT_STRIDE: u32 = 32;

    /// `model` over the frames of `run` with the default settings.
    pub fn new(run: PathBuf, model: PathBuf) -> Self {
        Self {
            run,
            model,
            onnxruntime: None,
            settings: DetectConfig::default(),
        }
    }

    /// Refuse settings that cannot work.
    fn check(&self) -> Result<(), InvalidSetting> {
        let share = |key: Key, v: f32| {
            InvalidSetting::check((0.0..=1.0).contains(&v), key, v, "between 0 and 1")
        };
        InvalidSetting::check(
            (0.0..0.9).contains(&self.settings.tile_overlap),
            keys::tile_overlap,
            self.settings.tile_overlap,
            "at least 0 and below 0.9",
        )?;
        if let Tile::Pixels(tile) = self.settings.tile {
            InvalidSetting::check(
                tile >= 32,
                keys::tile,
                tile,
                "at least 32 pixels, auto or off",
            )?;
        }
        if let Some(mean) = self.settings.mean {
            InvalidSetting::check(
                mean.iter().all(|c| c.is_finite() && c.abs() <= 1e3),
                keys::mean,
                format!("{},{},{}", mean[0], mean[1], mean[2]),
                "three numbers (on 0..1, as 0.485,0.456,0.406)",
            )?;
        }
        if let Some(std) = self.settings.std {
            InvalidSetting::check(
                std.iter().all(|c| c.is_finite() && *c > 0.0 && *c <= 1e3),
                keys::std,
                format!("{},{},{}", std[0], std[1], std[2]),
                "three numbers above 0 (on 0..1, as 0.229,0.224,0.225)",
            )?;
        }
        if let Some(scale) = self.settings.pixel_scale {
            InvalidSetting::check(
                scale.is_finite() && scale > 0.0 && scale <= 65_535.0,
                keys::pixel_scale,
                scale,
                "above 0 (1 for values 0..1, 255 for raw 0..255)",
            )?;
        }
        share(keys::confidence, self.settings.confidence)?;
        share(keys::iou, self.settings.iou)?;
        InvalidSetting::check(
            self.settings.image_size >= 32 && self.settings.image_size.is_multiple_of(32),
            keys::image_size,
            self.settings.image_size,
            "a multiple of 32",
        )?;
        if let Some(gap) = self.settings.merge_gap.pixels() {
            InvalidSetting::check(
                (0.0..=10_000.0).contains(&gap),
                keys::merge_gap,
                gap,
                "0 or more pixels, or off",
            )?;
        }
        InvalidSetting::check(
            (1..=256).contains(&self.settings.batch),
            keys::batch,
            self.settings.batch,
            "between 1 and 256",
        )
    }
}

/// A frame ready for the model.
struct Prepared {
    frame: u32,
    time_ns: i64,
    /// One model input per window (the whole frame, then tiles).
    views: Vec<View>,
    width: u32,
    height: u32,
}

/// A window of a frame, letterboxed for the model.
struct View {
    window: Window,
    /// Model input, `[3, height, width]`.
    input: Vec<f32>,
    /// The input's `(width, height)`.
    size: (u32, u32),
    placement: Placement,
}

fn prepare(
    recording: &Recordings,
    frame: &Frame,
    feed: Feed,
    options: &DetectOptions,
) -> Result<Prepared, FailedFrame> {
    let img = recording
        .image(frame)
        .map_err(|e| FailedFrame {
            frame: frame.index,
            why: e.to_string(),
        })?
        .to_rgb8();
    let views = windows(
        img.width(),
        img.height(),
        feed.tile(options, img.width(), img.height()),
        options.settings.tile_overlap,
    )
    .into_iter()
    .map(|window| {
        let mut input = Vec::new();
        let (size, placement) = if window.tile < 0 {
            letterbox(&img, feed.size, &mut input)
        } else {
            let crop =
                image::imageops::crop_imm(&img, window.x, window.y, window.width, window.height)
                    .to_image();
            letterbox(&crop, feed.size, &mut input)
        };
        convention::apply(&feed.convention, &mut input);
        View {
            window,
            input,
            size,
            placement,
        }
    })
    .collect();
    Ok(Prepared {
        frame: frame.index,
        time_ns: frame.time_ns,
        views,
        width: img.width(),
        height: img.height(),
    })
}

/// How each view is fed to the model: its input size and pixel convention.
#[derive(Debug, Clone, Copy)]
struct Feed {
    size: InputSize,
    convention: InputConvention,
}

impl Feed {
    /// The tile size a `width` x `height` frame runs with: the setting's,
    /// or with `auto` a fixed-size model's input when the frame is larger.
    fn tile(&self, options: &DetectOptions, width: u32, height: u32) -> Option<u32> {
        let fixed = match self.size {
            InputSize::Fixed(w, h) => Some((w, h)),
            InputSize::Rect { .. } => None,
        };
        options.settings.tile.size(fixed, width, height)
    }
}

/// The model's custom metadata, keys as written.
fn metadata(session: &ort::session::Session) -> HashMap<String, String> {
    let Ok(meta) = session.metadata() else {
        return HashMap::new();
    };
    meta.custom_keys()
        .unwrap_or_default()
        .into_iter()
        .filter_map(|k| Some((k.clone(), meta.custom(&k)?)))
        .collect()
}

/// The model's stride from its metadata (Ultralytics writes `stride`).
fn model_stride(metadata: &HashMap<String, String>) -> Option<u32> {
    let stride = metadata.get("stride")?;
    stride.trim().parse().ok().filter(|s| *s > 0)
}

/// Class names of a model with a baked vocabulary, from its `names` metadata
/// (Ultralytics writes `{0: 'crack', 1: 'spalling'}`).
fn baked_names(metadata: &HashMap<String, String>) -> Option<Vec<String>> {
    let names = metadata.get("names")?;
    let mut out = Vec::new();
    for entry in names
        .trim()
        .trim_start_matches('{')
        .trim_end_matches('}')
        .split(',')
    {
        let (_, name) = entry.split_once(':')?;
        out.push(
            name.trim()
                .trim_matches(|c| c == '\'' || c == '"')
                .to_string(),
        );
    }
    Some(out)
}

/// Run the detector over every frame of the run's flight.
pub fn detect(
    options: &DetectOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<DetectSummary, DetectError> {
    options.check()?;
    let start = Instant::now();
    let flight = Flight::load(&options.run)?;
    let recording = Recordings::reopen(&flight)?;
    let library = locate(options.onnxruntime.as_deref())?;
    let runtime = Runtime::start(library)?;
    let session = runtime.session(&options.model, options.settings.device)?;
    let mut warnings: Vec<String> = session.warning.iter().cloned().collect();
    let device = session.device;
    let (mut detector, classes) = Detector::new(session.session, options)?;

    let total = flight.frames.len() as u64;
    let (runnable, unreadable): (Vec<&Frame>, Vec<&Frame>) = flight
        .frames
        .iter()
        .partition(|f| f.image_status == ImageStatus::Ok);
    let mut failed: Vec<FailedFrame> = unreadable
        .iter()
        .map(|f| FailedFrame {
            frame: f.index,
            why: format!("image {}", f.image_status.as_str()),
        })
        .collect();
    let (found, ran) = infer_all(
        &mut detector,
        &recording,
        &runnable,
        options,
        &mut failed,
        total,
        progress,
    )?;
    failed.sort_by_key(|f| f.frame);
    // What the whole frame ran as (tiles run at the tile size).
    let first = runnable.iter().find_map(|f| Some((f.width?, f.height?)));
    let (w, h) = first
        .map(|(fw, fh)| detector.feed.size.place(fw, fh).0)
        .unwrap_or((options.settings.image_size, options.settings.image_size));
    let tile = first.and_then(|(fw, fh)| detector.feed.tile(options, fw, fh));
    if let (None, InputSize::Fixed(mw, mh), Some((fw, fh))) = (tile, detector.feed.size, first) {
        let shrink = (fw as f32 / mw as f32).max(fh as f32 / mh as f32);
        if shrink > 1.5 {
            warnings.push(format!(
                "frames of {fw}x{fh} were shrunk {shrink:.1} times to the model's fixed {mw}x{mh} input; thin cracks vanish: tile them ([detect] tile = \"auto\" or --tile {})",
                mw.min(mh)
            ));
        }
    }
    if ran == 0
        && let Some(first) = failed.first()
    {
        return Err(DetectError::NoFrames {
            frames: total,
            first: first.frame,
            why: first.why.clone(),
        });
    }
    let seconds = start.elapsed().as_secs_f64();
    let summary = DetectSummary {
        model: std::path::absolute(&options.model).unwrap_or_else(|_| options.model.clone()),
        model_bytes: std::fs::metadata(&options.model)
            .map(|m| m.len())
            .unwrap_or(0),
        model_sha256: sha256_file(&options.model)?,
        onnxruntime: runtime.library.path.clone(),
        onnxruntime_version: runtime.version(),
        vocabulary: match detector.signature.vocabulary {
            Vocabulary::Baked => "baked".into(),
            Vocabulary::Embeddings { .. } => "embeddings".into(),
        },
        classes: classes.clone(),
        input_size: [w, h],
        input: detector.feed.convention,
        tile,
        confidence: options.settings.confidence,
        iou: options.settings.iou,
        merge_gap: options.settings.merge_gap.pixels(),
        frames: total,
        frames_run: ran,
        detections: found.len() as u64,
        failed_frames: failed,
        seconds,
        frames_per_s: ran as f64 / seconds.max(1e-9),
        inference_share: detector.run_seconds / seconds.max(1e-9),
        device,
        batch: detector.batch,
        warnings,
    };
    write_outputs(&flight.run, &flight.frames, &found, &classes, &summary)?;
    Ok(summary)
}

/// Run the detector over `runnable`, decoding ahead on worker threads;
/// frames that cannot be prepared join `failed`. Returns what was found and
/// how many frames ran.
fn infer_all(
    detector: &mut Detector,
    recording: &Recordings,
    runnable: &[&Frame],
    options: &DetectOptions,
    failed: &mut Vec<FailedFrame>,
    total: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(Vec<FrameDetection>, u64), DetectError> {
    let feed = detector.feed;
    let mut found: Vec<FrameDetection> = Vec::new();
    let mut ran = 0u64;
    let mut run_error = None;
    std::thread::scope(|scope| {
        // Workers decode and letterbox the next frames while the runtime infers.
        let (tx, rx) = sync_channel::<Result<Prepared, FailedFrame>>(8);
        scope.spawn(move || {
            for chunk in runnable.chunks(8) {
                let prepared: Vec<_> = chunk
                    .par_iter()
                    .map(|f| prepare(recording, f, feed, options))
                    .collect();
                for p in prepared {
                    if tx.send(p).is_err() {
                        return;
                    }
                }
            }
        });
        // Frames wait until their views fill a batch.
        let mut pending: Vec<Prepared> = Vec::new();
        let mut pending_views = 0;
        for prepared in rx {
            match prepared {
                Ok(p) => {
                    pending_views += p.views.len();
                    pending.push(p);
                }
                Err(f) => failed.push(f),
            }
            if pending_views >= detector.batch {
                match detector.run_frames(&mut pending, options, &mut found) {
                    Ok(n) => ran += n,
                    Err(e) => {
                        run_error = Some(e);
                        return;
                    }
                }
                pending_views = 0;
            }
            progress(ran + failed.len() as u64, total);
        }
        match detector.run_frames(&mut pending, options, &mut found) {
            Ok(n) => ran += n,
            Err(e) => run_error = Some(e),
        }
        progress(ran + failed.len() as u64, total);
    });
    match run_error {
        Some(e) => Err(e),
        None => Ok((found, ran)),
    }
}

/// A model ready to run: its session, its interface, and for
/// open-vocabulary models the text input, built once.
struct Detector {
    session: ort::session::Session,
    signature: Signature,
    /// How large an input each view gets, and its pixels' convention.
    feed: Feed,
    /// Classes the output scores.
    classes: usize,
    /// Views per `run`.
    batch: usize,
    /// Text embeddings input: its name and value.
    text: Option<(String, Tensor<f32>)>,
    /// Wall time spent inside `run`, seconds.
    run_seconds: f64,
}

impl Detector {
    /// Recognise the model's interface and prepare its inputs; also returns
    /// the class names.
    fn new(
        session: ort::session::Session,
        options: &DetectOptions,
    ) -> Result<(Self, Vec<String>), DetectError> {
        let model_error = |why: String| DetectError::Model {
            path: options.model.clone(),
            why,
        };
        let signature = Signature::of_session(&session).map_err(model_error)?;
        // Read once: the stride, the class names and the input convention.
        let metadata = metadata(&session);
        let size = match signature.input_size {
            Some((h, w)) => InputSize::Fixed(w, h),
            None => InputSize::Rect {
                size: options.settings.image_size,
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
        let classes = signature
            .classes
            .or(text.as_ref().map(|t| t.1))
            .unwrap_or(names.len());
        let detector = Self {
            session,
            feed,
            classes,
            batch: signature.batch.unwrap_or(options.settings.batch),
            text: text.map(|(name, _, tensor)| (name, tensor)),
            run_seconds: 0.0,
            signature,
        };
        Ok((detector, names))
    }

    /// Run the `pending` frames, moving their detections into `found`;
    /// returns how many frames ran.
    fn run_frames(
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
    fn frames(
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
                classes: self.classes,
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
struct Inputs<'a> {
    images: &'a str,
    text: Option<&'a (String, Tensor<f32>)>,
    /// Each channel's value of a padding pixel, as the model is fed.
    padding: [f32; 3],
}

/// Run one batch of views of size `(w, h)` as `images` images (a fixed
/// batch size is filled up with padding images).
fn run_chunk<'s>(
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

/// Reads a run's outputs for what each view found.
struct Reader<'a> {
    head: &'a Head,
    /// Classes the boxes output scores.
    classes: usize,
    /// Images in the run.
    images: usize,
}

impl Reader<'_> {
    /// What image `b` of a run's `outputs` found in `view`: its detections
    /// in frame pixels (with their crack pixels for instance masks), and
    /// its probability map, into the frame's `found`.
    fn read_view(
        &self,
        outputs: &ort::session::SessionOutputs<'_>,
        b: usize,
        view: &View,
        options: &DetectOptions,
        found: &mut FrameFound,
    ) -> Result<(), String> {
        let output = Output {
            outputs,
            image: b,
            images: self.images,
            input_width: view.size.0,
        };
        let place = ViewPlace {
            window: view.window,
            placement: view.placement,
        };
        let confidence = options.settings.confidence;
        let mut detections = match &self.head {
            Head::Boxes { output: name }
            | Head::BoxesAndMap { output: name, .. }
            | Head::Instances { output: name, .. } => self.boxes(&output, name, confidence)?,
            Head::Semantic { output: name } => {
                let probability = crack_probability(&output, name)?;
                let regions = regions(&probability, confidence);
                found.maps.push(ProbabilityMap { place, probability });
                regions
            }
        };
        if let Head::BoxesAndMap { map, .. } = &self.head {
            let probability = output.plane(map, 0)?;
            found.maps.push(ProbabilityMap { place, probability });
        }
        // Into frame pixels; boxes are clipped to the frame after NMS, as
        // Ultralytics does.
        let Window { x, y, tile, .. } = view.window;
        for (d, _) in &mut detections {
            let b = view.placement.to_image(&d.bbox);
            d.bbox = BoxXyxy {
                x0: b.x0 + x as f32,
                y0: b.y0 + y as f32,
                x1: b.x1 + x as f32,
                y1: b.y1 + y as f32,
            };
            d.tile = tile;
        }
        match &self.head {
            Head::Instances {
                prototypes,
                coefficients,
                ..
            } => {
                let protos = Prototypes {
                    place,
                    planes: (0..*coefficients)
                        .map(|k| output.plane(prototypes, k))
                        .collect::<Result<_, _>>()?,
                };
                found.add_instances(detections, &protos, options.settings.iou);
            }
            _ => found
                .detections
                .extend(detections.into_iter().map(|(d, _)| d)),
        }
        Ok(())
    }

    /// The detections of a boxes output `name` scoring at least
    /// `confidence`, in model input pixels, each with its mask
    /// coefficients (none for a model of boxes only).
    fn boxes(
        &self,
        output: &Output<'_, '_>,
        name: &str,
        confidence: f32,
    ) -> Result<Vec<(Detection, Vec<f32>)>, String> {
        let (shape, data) = output.tensor(name)?;
        let extra = self.head.extra_rows();
        if shape.len() != 3 || shape[1] != 4 + self.classes + extra {
            let coefficients = if extra > 0 {
                format!(" + {extra} mask coefficients")
            } else {
                String::new()
            };
            return Err(format!(
                "output shape {shape:?}, expected [batch, 4 + {} classes{coefficients}, anchors]",
                self.classes
            ));
        }
        Ok(decode(
            data,
            self.classes,
            extra,
            shape[2],
            output.image,
            confidence,
        ))
    }
}

/// One image's outputs of a run.
struct Output<'a, 's> {
    outputs: &'a ort::session::SessionOutputs<'s>,
    /// The image in the batch, and the batch's size.
    image: usize,
    images: usize,
    /// The model input's width, pixels.
    input_width: u32,
}

impl Output<'_, '_> {
    /// The output `name`: its shape and values, for the whole batch.
    fn tensor(&self, name: &str) -> Result<(Vec<usize>, &[f32]), String> {
        let (shape, data) = self.outputs[name]
            .try_extract_tensor::<f32>()
            .map_err(|e| e.to_string())?;
        let shape = shape
            .iter()
            .map(|d| usize::try_from(*d).unwrap_or(0))
            .collect();
        Ok((shape, data))
    }

    /// Channel `channel` of this image in a `[batch, channels, height,
    /// width]` output `name`.
    fn plane(&self, name: &str, channel: usize) -> Result<Plane, String> {
        let (shape, data) = self.tensor(name)?;
        if shape.len() != 4 || shape[0] < self.images || channel >= shape[1] {
            return Err(format!(
                "output {name} has shape {shape:?}, expected [batch, channels, height, width]"
            ));
        }
        let (c, h, w) = (shape[1], shape[2], shape[3]);
        let at = (self.image * c + channel) * h * w;
        Ok(Plane {
            width: w,
            height: h,
            stride: self.input_width as f32 / w as f32,
            values: data[at..at + h * w].to_vec(),
        })
    }
}

/// A semantic map's crack probability: the softmax of background and crack
/// logits (two channels), or the one channel: the sigmoid of its logits
/// where its values leave 0..1, else the channel itself.
fn crack_probability(output: &Output<'_, '_>, name: &str) -> Result<Plane, String> {
    let sigmoid = |v: f32| 1.0 / (1.0 + (-v).exp());
    let channels = output.tensor(name)?.0.get(1).copied().unwrap_or(0);
    if !(1..=2).contains(&channels) {
        return Err(format!(
            "output {name} has {channels} channels; a semantic crack map has 1 (crack probability or logit) or 2 (background and crack logits): export the model with one of those"
        ));
    }
    let mut p = output.plane(name, 0)?;
    if channels == 2 {
        let crack = output.plane(name, 1)?;
        for (b, c) in p.values.iter_mut().zip(&crack.values) {
            *b = sigmoid(c - *b);
        }
    } else if p.values.iter().any(|v| !(0.0..=1.0).contains(v)) {
        p.values.iter_mut().for_each(|v| *v = sigmoid(*v));
    }
    Ok(p)
}

/// What a frame's views found, until the frame is finished.
struct FrameFound {
    detections: Vec<Detection>,
    /// Each view's crack probability map (models that give one).
    maps: Vec<ProbabilityMap>,
    /// The frame's (width, height), pixels.
    size: (f32, f32),
}

impl FrameFound {
    fn new(frame: &Prepared) -> Self {
        Self {
            detections: Vec::new(),
            maps: Vec::new(),
            size: (frame.width as f32, frame.height as f32),
        }
    }

    /// Instances of one view: as Ultralytics does, suppressed first, then
    /// the survivors' masks decoded within their boxes clipped to the
    /// frame, and those left empty dropped.
    fn add_instances(
        &mut self,
        detections: Vec<(Detection, Vec<f32>)>,
        protos: &Prototypes,
        iou: f32,
    ) {
        let (w, h) = self.size;
        let kept = nms_with(detections, iou);
        self.detections
            .extend(kept.into_iter().filter_map(|(mut d, coefficients)| {
                d.mask = Some(protos.instance(&coefficients, &d.bbox.clip(w, h))?);
                Some(d)
            }));
    }

    /// The frame's findings: NMS'd and merged, each with its crack pixels
    /// from the probability maps where the model gives maps.
    fn finish(self, options: &DetectOptions) -> Vec<Detection> {
        let (w, h) = self.size;
        let mut detections = self.detections;
        detections.retain(|d| d.bbox.clip(w, h).area() > 0.0);
        // Grid cells and tiles report a long crack piecewise: join the pieces.
        let kept = nms(detections, options.settings.iou);
        let mut merged = match options.settings.merge_gap.pixels() {
            Some(gap) => merge_touching(kept, gap),
            None => kept,
        };
        for d in &mut merged {
            d.bbox = d.bbox.clip(w, h);
        }
        if !self.maps.is_empty() {
            let mut maps = self.maps;
            finest_first(&mut maps);
            for d in &mut merged {
                d.mask = from_maps(&maps, &d.bbox, MASK_THRESHOLD);
            }
        }
        merged
    }
}

fn write_outputs(
    run: &RunDir,
    frames: &[Frame],
    found: &[FrameDetection],
    classes: &[String],
    summary: &DetectSummary,
) -> Result<(), DetectError> {
    run.remove(files::SUMMARY)?;
    let sizes: BTreeMap<u32, (u32, u32)> = frames
        .iter()
        .map(|f| (f.index, (f.width.unwrap_or(0), f.height.unwrap_or(0))))
        .collect();
    // Each mask is run-length encoded once, for the table and the COCO file.
    let rows: Vec<DetectionRow> = found
        .iter()
        .map(|d| DetectionRow::of(d, classes, sizes.get(&d.frame).copied().unwrap_or((0, 0))))
        .collect();
    run.write_rows(files::DETECTIONS, &rows)?;
    run.write_json(files::COCO, &coco::results(frames, found, &rows, classes))?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}

//! The detect stage: every frame of an ingested flight through the detector,
//! decoding and letterboxing on worker threads while ONNX Runtime infers,
//! into `detections.parquet`, `detections.coco.json` and `detect.json`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use ingest::Recordings;
use postflight_core::detection::FrameDetection;
use postflight_core::outputs::detect::{DetectSummary, DetectionRow, FailedFrame, files};
use postflight_core::run_log::sha256_file;
use postflight_core::{Flight, Frame, ImageStatus, InvalidSetting, Key, RunDir};
use rayon::prelude::*;

use crate::coco;
use crate::detector::Detector;
use crate::error::DetectError;
use crate::letterbox::InputSize;
use crate::runtime::{Runtime, locate};
use crate::settings::{DetectConfig, Tile, keys};
use crate::signature::Vocabulary;
use crate::views::{Prepared, prepare};

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

//! One model's pass over a flight: the chosen tiles of its frames decoded
//! and letterboxed on worker threads while ONNX Runtime infers, with its
//! pace told as it goes; what it found and what it cost.

use std::sync::mpsc::sync_channel;
use std::time::Instant;

use ingest::Recordings;
use postflight_core::Frame;
use postflight_core::best_views::TileSkip;
use postflight_core::detection::{Device, FrameDetection};
use postflight_core::kind::Counts;
use postflight_core::outputs::detect::{
    AreaModelRun, DetectSummary, FailedFrame, Shard, TileChoice,
};
use postflight_core::run_log::sha256_file;
use rayon::prelude::*;

use crate::choose::{FrameWork, TilesToRun, choose};
use crate::detector::Detector;
use crate::error::DetectError;
use crate::runtime::Runtime;
use crate::settings::{Off, Tile};
use crate::signature::Vocabulary;
use crate::stage::{DetectOptions, Estimate, Told};
use crate::views::{Prepared, prepare};

/// The flight a detect runs over: its frames, and which of their tiles.
pub(crate) struct Flown<'a> {
    pub(crate) runtime: &'a Runtime,
    pub(crate) recording: &'a Recordings,
    pub(crate) runnable: &'a [&'a Frame],
    pub(crate) unreadable: &'a [&'a Frame],
    pub(crate) tiles: TilesToRun<'a>,
}

/// One model's pass over the flight: what it found and what it cost.
pub(crate) struct Pass {
    detector: Detector,
    pub(crate) found: Vec<FrameDetection>,
    frames: u64,
    ran: u64,
    tiles_run: u64,
    skipped: Counts<TileSkip>,
    failed: Vec<FailedFrame>,
    pub(crate) warnings: Vec<String>,
    device: Device,
    estimate_s: Option<f64>,
    input: ([u32; 2], Option<u32>),
    seconds: f64,
}

impl Flown<'_> {
    /// `model` over the chosen tiles, as `options` and `own_scale` say
    /// (see [`Detector::new`]).
    pub(crate) fn pass(
        &self,
        options: &DetectOptions,
        model: &std::path::Path,
        own_scale: bool,
        start: Instant,
        told: &mut dyn FnMut(Told<'_>),
    ) -> Result<Pass, DetectError> {
        let session = self.runtime.session(model, options.settings.device)?;
        let mut warnings: Vec<String> = session.warning.iter().cloned().collect();
        warnings.extend(no_map_warning(self.tiles.choice));
        let device = session.device;
        let mut detector = Detector::new(session.session, model, options, own_scale)?;
        warnings.extend(detector.classes.warning.clone());
        let chosen = choose(self.runnable, detector.feed, options, self.tiles);
        let mut failed = unreadable_in(self.unreadable, self.tiles.shard);
        let frames = chosen.frames + failed.len() as u64;
        let mut pace = Pace {
            start,
            tiles: chosen.tiles() + chosen.skipped.total(),
            tiles_run: chosen.tiles(),
            choice: self.tiles.words(),
            device,
            warm: None,
            estimate_s: None,
        };
        let (found, ran, tiles_run) = infer_all(
            &mut detector,
            self.recording,
            &chosen.work,
            options,
            &mut failed,
            &mut pace,
            told,
        )?;
        failed.sort_by_key(|f| f.frame);
        let input = detector
            .feed
            .input_shape(self.runnable, options, &mut warnings);
        // Frames failed and none ran, though some were to (a share may hold
        // only frames the choice skips, or none that decode).
        let meant_to_run =
            !chosen.work.is_empty() || (chosen.frames == 0 && self.tiles.shard.is_none());
        if ran == 0
            && meant_to_run
            && let Some(first) = failed.first()
        {
            return Err(DetectError::NoFrames {
                frames: frames.max(1),
                first: first.frame,
                why: first.why.clone(),
            });
        }
        Ok(Pass {
            detector,
            found,
            frames,
            ran,
            tiles_run,
            skipped: chosen.skipped,
            failed,
            warnings,
            device,
            estimate_s: pace.estimate_s,
            input,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The area model at `path` over the whole of each frame the crack
    /// model chose from, at its own scale; its progress told after the
    /// crack model's.
    pub(crate) fn area_pass(
        &self,
        options: &DetectOptions,
        path: &std::path::Path,
        crack: &Pass,
        told: &mut dyn FnMut(Told<'_>),
    ) -> Result<Pass, DetectError> {
        let mut whole = options.clone();
        whole.settings.tile = Tile::Off(Off::Off);
        let before = crack.tiles_run;
        let mut after = |t: Told<'_>| {
            if let Told::Progress { done, total } = t {
                told(Told::Progress {
                    done: before + done,
                    total: before + total,
                });
            }
        };
        self.pass(&whole, path, true, Instant::now(), &mut after)
    }
}

impl Pass {
    /// `detect.json` of a run whose first (crack) pass this is.
    pub(crate) fn summary(
        &self,
        options: &DetectOptions,
        runtime: &Runtime,
        tiles: TilesToRun<'_>,
        seconds: f64,
    ) -> Result<DetectSummary, DetectError> {
        let detector = &self.detector;
        let ([w, h], tile) = self.input;
        Ok(DetectSummary {
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
            classes: detector.classes.names.clone(),
            kinds: detector.classes.finds(),
            area_model: None,
            input_size: [w, h],
            input: detector.feed.convention,
            tile,
            confidence: options.settings.confidence,
            iou: options.settings.iou,
            merge_gap: options.settings.merge_gap.pixels(),
            frames: self.frames,
            frames_run: self.ran,
            tile_choice: tiles.choice,
            views_per_patch: options.settings.views_per_patch,
            tiles_run: self.tiles_run,
            tiles_skipped: self.skipped.clone(),
            estimate_s: self.estimate_s,
            shard: tiles.shard,
            detections: self.found.len() as u64,
            failed_frames: self.failed.clone(),
            seconds,
            frames_per_s: self.ran as f64 / seconds.max(1e-9),
            inference_share: detector.run_seconds / seconds.max(1e-9),
            device: self.device,
            batch: detector.batch,
            warnings: self.warnings.clone(),
        })
    }

    /// What an area pass (of the model at `path`) ran and cost.
    pub(crate) fn area_summary(&self, path: &std::path::Path) -> Result<AreaModelRun, DetectError> {
        Ok(AreaModelRun {
            model: std::path::absolute(path).unwrap_or_else(|_| path.to_owned()),
            model_bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
            model_sha256: sha256_file(path)?,
            classes: self.detector.classes.names.clone(),
            kinds: self.detector.classes.finds(),
            input_size: self.input.0,
            input: self.detector.feed.convention,
            frames_run: self.ran,
            detections: self.found.len() as u64,
            seconds: self.seconds,
            inference_share: self.detector.run_seconds / self.seconds.max(1e-9),
        })
    }

    /// An area pass's detections after this pass's, its class ids after
    /// this one's classes.
    pub(crate) fn add(&mut self, area: Pass) {
        let offset = self.detector.classes.names.len() as u32;
        self.found.extend(area.found.into_iter().map(|mut d| {
            d.detection.class += offset;
            d
        }));
    }
}

/// What a run without a map to choose views by says: every tile ran.
pub(crate) fn no_map_warning(choice: TileChoice) -> Option<String> {
    (choice == TileChoice::NoMap).then(|| {
        "every tile ran: the flight has no map to choose the best views of each patch by; give --map to run fewer".into()
    })
}

/// The frames of `shard` (all without one) whose images did not decode,
/// as failed frames.
pub(crate) fn unreadable_in(unreadable: &[&Frame], shard: Option<Shard>) -> Vec<FailedFrame> {
    unreadable
        .iter()
        .filter(|f| shard.is_none_or(|s| f.index % s.count + 1 == s.index))
        .map(|f| FailedFrame {
            frame: f.index,
            why: format!("image {}", f.image_status.as_str()),
        })
        .collect()
}

/// The run's pace: what its first batches say of the whole. ONNX Runtime's
/// first run sets it up, and the frames decoded meanwhile wait ready; the
/// pace is that of the tiles run after them, decoding and inference
/// sharing the machine as they will to the end, once they add up to a
/// second or 64 tiles (or, with frames of hundreds of tiles, 5 seconds).
struct Pace {
    start: Instant,
    tiles: u64,
    tiles_run: u64,
    choice: String,
    device: Device,
    /// From the end of the first batch: when, and the tiles and frames
    /// run by then.
    warm: Option<(Instant, u64, u64)>,
    estimate_s: Option<f64>,
}

impl Pace {
    /// Frames decoded ahead of inference: the channel's and a chunk's.
    const AHEAD: u64 = 2 * PREPARE_AHEAD as u64;

    /// After a batch: `done` tiles and `frames` frames have run. The
    /// estimate once the pace is known, the first time only.
    fn after_batch(&mut self, done: u64, frames: u64) -> Option<Estimate> {
        let Some((since, tiles_then, frames_then)) = self.warm else {
            self.warm = Some((Instant::now(), done, frames));
            return None;
        };
        let (tiles, seconds) = (done - tiles_then, since.elapsed().as_secs_f64());
        let drained = frames - frames_then > Self::AHEAD;
        let enough = (seconds >= 1.0 || tiles >= 64) && drained || seconds >= 5.0;
        if self.estimate_s.is_some() || !enough || done >= self.tiles_run || tiles == 0 {
            return None;
        }
        let rest = seconds / tiles as f64 * (self.tiles_run - done) as f64;
        let seconds = self.start.elapsed().as_secs_f64() + rest;
        self.estimate_s = Some(seconds);
        Some(Estimate {
            tiles_run: self.tiles_run,
            tiles: self.tiles,
            choice: self.choice.clone(),
            seconds,
            device: self.device,
        })
    }
}

/// Frames decoded at once, and waiting decoded, ahead of inference.
const PREPARE_AHEAD: usize = 8;

/// Run the detector over the chosen windows of `work`'s frames, decoding
/// ahead on worker threads; frames that cannot be prepared join `failed`.
/// Returns what was found, how many frames ran and how many tiles.
fn infer_all(
    detector: &mut Detector,
    recording: &Recordings,
    work: &[FrameWork<'_>],
    options: &DetectOptions,
    failed: &mut Vec<FailedFrame>,
    pace: &mut Pace,
    told: &mut dyn FnMut(Told<'_>),
) -> Result<(Vec<FrameDetection>, u64, u64), DetectError> {
    let feed = detector.feed;
    let mut found: Vec<FrameDetection> = Vec::new();
    let mut ran = 0u64;
    let mut done = 0u64;
    let total = pace.tiles_run;
    let mut run_error = None;
    std::thread::scope(|scope| {
        // Workers decode and letterbox the next frames while the runtime infers.
        let (tx, rx) = sync_channel::<Result<Prepared, FailedFrame>>(PREPARE_AHEAD);
        scope.spawn(move || {
            for chunk in work.chunks(PREPARE_AHEAD) {
                let ready: Vec<_> = chunk
                    .par_iter()
                    .map(|w| prepare(recording, w, feed, options))
                    .collect();
                for p in ready {
                    if tx.send(p).is_err() {
                        return;
                    }
                }
            }
        });
        // Frames wait until their views fill a batch.
        let mut pending: Vec<Prepared> = Vec::new();
        let mut pending_views = 0;
        let batch = detector.batch;
        let mut frames_run = 0u64;
        let mut run = |pending: &mut Vec<Prepared>,
                       views: u64,
                       done: &mut u64,
                       told: &mut dyn FnMut(Told<'_>)| {
            frames_run += pending.len() as u64;
            let n = detector.run_frames(pending, options, &mut found)?;
            *done += views;
            if let Some(estimate) = pace.after_batch(*done, frames_run) {
                told(Told::Estimate(&estimate));
            }
            Ok::<u64, DetectError>(n)
        };
        for ready in rx {
            match ready {
                Ok(p) => {
                    pending_views += p.views.len();
                    pending.push(p);
                }
                Err(f) => failed.push(f),
            }
            if pending_views >= batch {
                match run(&mut pending, pending_views as u64, &mut done, told) {
                    Ok(n) => ran += n,
                    Err(e) => {
                        run_error = Some(e);
                        return;
                    }
                }
                pending_views = 0;
            }
            told(Told::Progress { done, total });
        }
        match run(&mut pending, pending_views as u64, &mut done, told) {
            Ok(n) => ran += n,
            Err(e) => run_error = Some(e),
        }
        told(Told::Progress { done, total });
    });
    match run_error {
        Some(e) => Err(e),
        None => Ok((found, ran, done)),
    }
}

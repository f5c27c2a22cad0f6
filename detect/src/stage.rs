//! The detect stage: every frame of an ingested flight through the detector,
//! decoding and letterboxing on worker threads while ONNX Runtime infers,
//! into `detections.parquet`, `detections.coco.json` and `detect.json`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use ingest::Recordings;
use postflight_core::detection::FrameDetection;
use postflight_core::outputs::detect::{DetectSummary, DetectionRow, Shard, files};
use postflight_core::{Flight, Frame, ImageStatus, InvalidSetting, Key, RunDir};

use crate::choose::TilesToRun;
use crate::coco;
use crate::error::DetectError;
use crate::pass::Flown;
use crate::runtime::{Runtime, locate};
use crate::settings::{DetectConfig, Tile, keys};

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

/// What detect tells as it works.
#[derive(Debug, Clone, Copy)]
pub enum Told<'a> {
    /// Tiles run so far, of those it will run.
    Progress { done: u64, total: u64 },
    /// After its first batches: how long the whole run will take.
    Estimate(&'a Estimate),
}

/// How long a detect will take, from the pace of its first batches after
/// ONNX Runtime's warm-up (see [`Pace`]).
#[derive(Debug, Clone)]
pub struct Estimate {
    /// Tiles it will run, and the flight's (or the share's) tiles in all.
    pub tiles_run: u64,
    pub tiles: u64,
    /// The choice, in words ("the best 2 views of each patch of the map").
    pub choice: String,
    /// The whole run, seconds from the start of the stage.
    pub seconds: f64,
    pub device: postflight_core::detection::Device,
}

/// Run the detector over the flight's frames: the tiles `tiles` chooses,
/// of every frame or of a share of them; then the area model, if one is
/// given, over the whole of the same frames.
pub fn detect(
    options: &DetectOptions,
    tiles: TilesToRun<'_>,
    told: &mut dyn FnMut(Told<'_>),
) -> Result<DetectSummary, DetectError> {
    options.check()?;
    let start = Instant::now();
    let flight = Flight::load(&options.run)?;
    let recording = Recordings::reopen(&flight)?;
    let library = locate(options.onnxruntime.as_deref())?;
    let runtime = Runtime::start(library)?;
    let (runnable, unreadable): (Vec<&Frame>, Vec<&Frame>) = flight
        .frames
        .iter()
        .partition(|f| f.image_status == ImageStatus::Ok);
    let on = Flown {
        runtime,
        recording: &recording,
        runnable: &runnable,
        unreadable: &unreadable,
        tiles,
    };
    let mut crack = on.pass(options, &options.model, false, start, told)?;
    let area = match &options.settings.area_model {
        Some(path) => Some(on.area_pass(options, path, &crack, told)?),
        None => None,
    };
    let seconds = start.elapsed().as_secs_f64();
    let mut summary = crack.summary(options, runtime, tiles, seconds)?;
    if let (Some(area), Some(path)) = (area, &options.settings.area_model) {
        let run = area.area_summary(path)?;
        summary.classes.extend(run.classes.iter().cloned());
        summary.kinds.extend(&run.kinds);
        summary.kinds.sort();
        summary.kinds.dedup();
        let said = area.warnings.iter().map(|w| format!("area model: {w}"));
        summary.warnings.extend(said);
        summary.area_model = Some(run);
        crack.add(area);
    }
    summary.detections = crack.found.len() as u64;
    write(
        &flight,
        tiles.shard,
        &crack.found,
        &summary.classes,
        &summary,
    )?;
    Ok(summary)
}

/// The detections and summary written: the flight's files for a whole
/// run (replacing any split's), a share's for `shard`.
fn write(
    flight: &Flight,
    shard: Option<Shard>,
    found: &[FrameDetection],
    classes: &[String],
    summary: &DetectSummary,
) -> Result<(), DetectError> {
    match shard {
        None => {
            remove_shares(&flight.run, None)?;
            write_outputs(&flight.run, &flight.frames, found, classes, summary)
        }
        Some(shard) => write_share(&flight.run, shard, &flight.frames, found, classes, summary),
    }
}

/// `detections.parquet`, `detections.coco.json` and, last, `detect.json`.
pub(crate) fn write_outputs(
    run: &RunDir,
    frames: &[Frame],
    found: &[FrameDetection],
    classes: &[String],
    summary: &DetectSummary,
) -> Result<(), DetectError> {
    run.remove(files::SUMMARY)?;
    let rows = rows(frames, found, classes);
    run.write_rows(files::DETECTIONS, &rows)?;
    run.write_json(files::COCO, &coco::results(frames, found, &rows))?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}

/// A share's detections and, last, its summary, beside the others'.
fn write_share(
    run: &RunDir,
    shard: Shard,
    frames: &[Frame],
    found: &[FrameDetection],
    classes: &[String],
    summary: &DetectSummary,
) -> Result<(), DetectError> {
    // The flight's detections are being remade; another split's shares
    // are stale.
    for name in [files::SUMMARY, files::DETECTIONS, files::COCO] {
        run.remove(name)?;
    }
    remove_shares(run, Some(shard.count))?;
    run.remove(&shard.summary())?;
    run.write_rows(&shard.detections(), &rows(frames, found, classes))?;
    run.write_json(&shard.summary(), summary)?;
    Ok(())
}

/// Remove the shares' files of every split but one of `keep` shares.
fn remove_shares(run: &RunDir, keep: Option<u32>) -> Result<(), DetectError> {
    let Ok(entries) = std::fs::read_dir(run.path()) else {
        return Ok(());
    };
    for entry in entries.filter_map(|e| e.ok()) {
        let name = entry.file_name().to_string_lossy().into_owned();
        if Shard::of_file(&name).is_some_and(|s| Some(s.count) != keep) {
            run.remove(&name)?;
        }
    }
    Ok(())
}

/// Each detection as its row; each mask is run-length encoded once, for
/// the table and the COCO file.
fn rows(frames: &[Frame], found: &[FrameDetection], classes: &[String]) -> Vec<DetectionRow> {
    let sizes: BTreeMap<u32, (u32, u32)> = frames
        .iter()
        .map(|f| (f.index, (f.width.unwrap_or(0), f.height.unwrap_or(0))))
        .collect();
    found
        .iter()
        .map(|d| DetectionRow::of(d, classes, sizes.get(&d.frame).copied().unwrap_or((0, 0))))
        .collect()
}

//! What the detect stage writes: `detections.parquet` (one row per
//! detection, in the frame's pixels, laid out for polars, pandas and DuckDB:
//! flat columns, class name beside id), `detections.coco.json` and its
//! summary `detect.json`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::best_views::TileSkip;
use crate::defect_kind::DefectKind;
use crate::detection::{BoxXyxy, Detection, Device, FrameDetection};
use crate::error::Error;
use crate::kind::Counts;
use crate::mask::Mask;
use crate::run_dir::RunDir;

/// Files of the detect stage.
pub mod files {
    pub const DETECTIONS: &str = "detections.parquet";
    pub const COCO: &str = "detections.coco.json";
    pub const SUMMARY: &str = "detect.json";
}

/// One share of a flight's frames, run by its own process
/// (`postflight detect --shard K/N`): the `index`th of `count`, from 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// The file it writes its detections to, beside `detections.parquet`.
    pub fn detections(self) -> String {
        format!("{}.parquet", self.stem())
    }

    /// The file it writes its summary to (last, so that with it the share
    /// is whole).
    pub fn summary(self) -> String {
        format!("{}.json", self.stem())
    }

    fn stem(self) -> String {
        format!("detect-shard-{}-of-{}", self.index, self.count)
    }

    /// The share a file of the run directory belongs to, if it is one's.
    pub fn of_file(name: &str) -> Option<Shard> {
        let stem = name
            .strip_suffix(".parquet")
            .or_else(|| name.strip_suffix(".json"))?;
        let (index, count) = stem.strip_prefix("detect-shard-")?.split_once("-of-")?;
        let shard = Shard {
            index: index.parse().ok()?,
            count: count.parse().ok()?,
        };
        (shard.index >= 1 && shard.index <= shard.count && shard.stem() == stem).then_some(shard)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let parsed = s.split_once('/').and_then(|(k, n)| {
            Some((k.trim().parse::<u32>().ok()?, n.trim().parse::<u32>().ok()?))
        });
        match parsed {
            Some((index, count)) if (1..=count).contains(&index) && count <= 10_000 => {
                Ok(Shard { index, count })
            }
            _ => Err(format!(
                "'{s}' is not a share K/N of a flight (1 <= K <= N <= 10000, as 2/4)"
            )),
        }
    }
}

crate::kind! {
    /// How detect chose the tiles it ran.
    pub enum TileChoice("tile choice") {
        /// The tiles that show a patch of the map among its best views
        /// (`[detect] views_per_patch`).
        BestViews = "best_views",
        /// Every tile: `[detect] views_per_patch = 0`.
        Every = "every",
        /// Every tile: the flight has no map (or no camera model) to
        /// choose by.
        NoMap = "no_map",
    }
}

/// A frame that could not be run, and why.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FailedFrame {
    pub frame: u32,
    pub why: String,
}

/// The order of a model input's colour channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum ChannelOrder {
    /// Red, green, blue (PyTorch and Ultralytics models).
    Rgb,
    /// Blue, green, red (models trained on OpenCV's images).
    Bgr,
}

/// Where a model's input convention came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// Nothing said: RGB on 0..1.
    Default,
    /// The model's metadata.
    Metadata,
    /// `[detect]` settings.
    Settings,
}

/// How pixels were fed to the model: each channel's value is
/// `pixel_scale * (v - mean) / std` for `v` on 0..1, the means and
/// deviations listed red, green, blue, in `channel_order`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InputConvention {
    pub channel_order: ChannelOrder,
    pub pixel_scale: f32,
    pub mean: [f32; 3],
    pub std: [f32; 3],
    pub source: Source,
}

impl Default for InputConvention {
    fn default() -> Self {
        Self {
            channel_order: ChannelOrder::Rgb,
            pixel_scale: 1.0,
            mean: [0.0; 3],
            std: [1.0; 3],
            source: Source::Default,
        }
    }
}

impl InputConvention {
    /// RGB on 0..1 as letterboxing writes it, untouched.
    pub fn is_identity(&self) -> bool {
        self.channel_order == ChannelOrder::Rgb
            && self.pixel_scale == 1.0
            && self.mean == [0.0; 3]
            && self.std == [1.0; 3]
    }
}

/// `detect.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DetectSummary {
    pub model: PathBuf,
    pub model_bytes: u64,
    /// SHA-256 of the model file, as `sha256sum` prints it.
    #[serde(default)]
    pub model_sha256: String,
    pub onnxruntime: PathBuf,
    /// ONNX Runtime's version (`1.31.1`).
    #[serde(default)]
    pub onnxruntime_version: String,
    /// Device inference ran on (`cpu` when a GPU was asked for but unavailable).
    pub device: Device,
    /// Views per inference call.
    pub batch: usize,
    /// `baked` or `embeddings`.
    pub vocabulary: String,
    /// Class names, the crack model's then the area model's: a
    /// detection's `class` indexes them.
    pub classes: Vec<String>,
    /// The kinds of defect the run looked for (its models' classes');
    /// without an area kind, area defects were not looked for.
    #[serde(default = "crack_only")]
    pub kinds: Vec<DefectKind>,
    /// The area model's pass, when one ran (`[detect] area_model`).
    #[serde(default)]
    pub area_model: Option<AreaModelRun>,
    pub input_size: [u32; 2],
    /// How pixels were fed to the model.
    #[serde(default)]
    pub input: InputConvention,
    /// Tile size, when tiles were run besides the whole frame.
    pub tile: Option<u32>,
    pub confidence: f32,
    pub iou: f32,
    /// Pixels; `None` when merging was off.
    pub merge_gap: Option<f32>,
    pub frames: u64,
    pub frames_run: u64,
    /// How the tiles run were chosen (a frame not tiled is one tile; a
    /// tiled frame's tiles and the whole frame are each one).
    #[serde(default = "TileChoice::every")]
    pub tile_choice: TileChoice,
    /// `[detect] views_per_patch` (0: every tile).
    #[serde(default)]
    pub views_per_patch: u32,
    /// Tiles the model ran on.
    #[serde(default)]
    pub tiles_run: u64,
    /// Tiles not run, by why.
    #[serde(default)]
    pub tiles_skipped: Counts<TileSkip>,
    /// What detect said the whole run would take, seconds, after its
    /// first batches (ONNX Runtime's warm-up, then a second's or 64 tiles'
    /// worth); none when those were all.
    #[serde(default)]
    pub estimate_s: Option<f64>,
    /// The share of the flight this run was, when it was one.
    #[serde(default)]
    pub shard: Option<Shard>,
    pub detections: u64,
    pub failed_frames: Vec<FailedFrame>,
    pub seconds: f64,
    pub frames_per_s: f64,
    /// Share of `seconds` spent inside ONNX Runtime's `run`.
    pub inference_share: f64,
    pub warnings: Vec<String>,
}

fn crack_only() -> Vec<DefectKind> {
    vec![DefectKind::Crack]
}

/// What the area model's pass over the flight ran and cost (`detect.json`
/// `area_model`): the whole of each frame chosen, at the model's own scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AreaModelRun {
    pub model: PathBuf,
    pub model_bytes: u64,
    /// SHA-256 of the model file, as `sha256sum` prints it.
    pub model_sha256: String,
    /// Its classes, as the model names them, and the kinds they find.
    pub classes: Vec<String>,
    pub kinds: Vec<DefectKind>,
    /// The input a frame ran at (width, height), pixels.
    pub input_size: [u32; 2],
    pub input: InputConvention,
    pub frames_run: u64,
    pub detections: u64,
    /// The pass, seconds, and the share of it inside ONNX Runtime's `run`.
    pub seconds: f64,
    pub inference_share: f64,
}

impl TileChoice {
    fn every() -> Self {
        Self::Every
    }
}

crate::table! {
    /// A detection's columns in every table of detections: its frame, its
    /// box (frame pixels) and its score.
    pub struct DetectionCells {
        frame: u32,
        time_ns: i64,
        bbox: BoxXyxy,
        score: f32,
    }
}

impl DetectionCells {
    pub fn of(frame: u32, time_ns: i64, bbox: BoxXyxy, score: f32) -> Self {
        Self {
            frame,
            time_ns,
            bbox,
            score,
        }
    }
}

crate::table! {
    /// One row of `detections.parquet`: a detection, in its frame's pixels.
    pub struct DetectionRow {
        detection: DetectionCells,
        /// The class id (of the model that found it), and its name
        /// (`prompt`).
        class: u32,
        /// What the class means: `crack`, or an area defect (`spall`,
        /// `exposed_rebar`, ...).
        kind: DefectKind,
        /// The tile it was found in; -1 for the whole frame.
        tile: i32,
        prompt: String,
        /// The frame's size, pixels.
        frame_width: u32,
        frame_height: u32,
        /// Its pixels (a crack's, or an area defect's outline filled) as COCO's compressed RLE `counts` over the
        /// frame (pycocotools' `mask.decode({"size": [frame_height,
        /// frame_width], "counts": mask})`); null for a model of boxes only.
        mask: Option<String>,
    }
}

impl DetectionRow {
    /// A detection in a frame `frame_size` (width, height) pixels as its
    /// row; `classes` names the class ids.
    pub fn of(d: &FrameDetection, classes: &[String], frame_size: (u32, u32)) -> Self {
        let class = d.detection.class;
        let (frame_width, frame_height) = frame_size;
        Self {
            detection: DetectionCells::of(d.frame, d.time_ns, d.detection.bbox, d.detection.score),
            class,
            kind: d.detection.kind,
            tile: d.detection.tile,
            prompt: classes
                .get(class as usize)
                .cloned()
                .unwrap_or_else(|| format!("class{class}")),
            frame_width,
            frame_height,
            mask: d
                .detection
                .mask
                .as_ref()
                .map(|m| m.to_coco(frame_width, frame_height)),
        }
    }

    /// The detection the row holds.
    pub fn detection(&self) -> Result<FrameDetection, String> {
        let cells = &self.detection;
        let mask = match &self.mask {
            Some(counts) => {
                Mask::from_coco(counts, self.frame_width, self.frame_height).map_err(|why| {
                    format!("the mask of the detection in frame {}: {why}", cells.frame)
                })?
            }
            None => None,
        };
        Ok(FrameDetection {
            frame: cells.frame,
            time_ns: cells.time_ns,
            detection: Detection {
                bbox: cells.bbox,
                score: cells.score,
                class: self.class,
                kind: self.kind,
                tile: self.tile,
                mask,
            },
        })
    }
}

/// Read `detections.parquet`.
pub fn read_detections(run: &RunDir) -> Result<Vec<FrameDetection>, Error> {
    let rows: Vec<DetectionRow> = run.read_rows(files::DETECTIONS)?;
    rows.iter()
        .map(|r| {
            r.detection().map_err(|why| Error::Table {
                path: run.file(files::DETECTIONS),
                cause: polars::prelude::polars_err!(ComputeError: "{why}"),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::Row;

    #[test]
    fn a_share_is_named_as_given_and_its_files_are_known_as_its_own() {
        let s: Shard = "2/4".parse().unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        assert_eq!(s.to_string(), "2/4");
        assert_eq!(
            (s.detections(), s.summary()),
            (
                "detect-shard-2-of-4.parquet".into(),
                "detect-shard-2-of-4.json".into()
            )
        );
        for name in [s.detections(), s.summary()] {
            assert_eq!(Shard::of_file(&name), Some(s));
        }
        for bad in ["0/4", "5/4", "2", "2/0", "a/b", "-1/4", "2/4/6"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        for other in [
            "detect-shard-5-of-4.json",
            "detect-shard-02-of-4.json",
            "detect-shard-2-of-4.csv",
            "detections.parquet",
        ] {
            assert_eq!(Shard::of_file(other), None, "{other}");
        }
    }

    #[test]
    fn table_round_trips() {
        let found: Vec<FrameDetection> = (0..3)
            .map(|i| FrameDetection {
                frame: i,
                time_ns: 1_000 + i64::from(i),
                detection: Detection {
                    bbox: BoxXyxy {
                        x0: 1.5,
                        y0: 2.0,
                        x1: 30.25 + i as f32,
                        y1: 40.0,
                    },
                    score: 0.5,
                    class: i % 2,
                    kind: if i == 2 {
                        DefectKind::Spall
                    } else {
                        DefectKind::Crack
                    },
                    tile: -1 + i as i32,
                    mask: (i == 1).then(|| {
                        let mut m = Mask::empty(2, 3, 4, 4);
                        m.on[5] = true;
                        m.on[10] = true;
                        m
                    }),
                },
            })
            .collect();
        let rows: Vec<DetectionRow> = found
            .iter()
            .map(|d| DetectionRow::of(d, &["crack".into()], (64, 48)))
            .collect();
        let df = DetectionRow::frame(&rows).unwrap();
        assert_eq!(
            df.column("prompt").unwrap().str().unwrap().get(1),
            Some("class1")
        );
        let back = DetectionRow::rows(&df).unwrap();
        let back: Vec<FrameDetection> = back.iter().map(|r| r.detection().unwrap()).collect();
        assert_eq!(back[0], found[0]);
        assert_eq!(back[2], found[2]);
        // A mask reads back trimmed to its pixels.
        let (mask, was) = (
            back[1].detection.mask.as_ref().unwrap(),
            found[1].detection.mask.as_ref().unwrap(),
        );
        assert_eq!((mask.area(), mask.iou(was)), (2, 1.0));
    }
}

//! What the detect stage writes: `detections.parquet` (one row per
//! detection, in the frame's pixels, laid out for polars, pandas and DuckDB:
//! flat columns, class name beside id), `detections.coco.json` and its
//! summary `detect.json`.

use std::path::PathBuf;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::required;
use crate::detection::{BoxXyxy, Detection, FrameDetection};
use crate::error::Error;
use crate::run_dir::RunDir;

/// Files of the detect stage.
pub mod files {
    pub const DETECTIONS: &str = "detections.parquet";
    pub const COCO: &str = "detections.coco.json";
    pub const SUMMARY: &str = "detect.json";
}

/// A frame that could not be run, and why.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FailedFrame {
    pub frame: u32,
    pub why: String,
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
    pub device: String,
    /// Views per inference call.
    pub batch: usize,
    /// `baked` or `embeddings`.
    pub vocabulary: String,
    pub classes: Vec<String>,
    pub input_size: [u32; 2],
    /// Tile size, when tiles were run besides the whole frame.
    pub tile: Option<u32>,
    pub confidence: f32,
    pub iou: f32,
    /// Pixels; `None` when merging was off.
    pub merge_gap: Option<f32>,
    pub frames: u64,
    pub frames_run: u64,
    pub detections: u64,
    pub failed_frames: Vec<FailedFrame>,
    pub seconds: f64,
    pub frames_per_s: f64,
    /// Share of `seconds` spent inside ONNX Runtime's `run`.
    pub inference_share: f64,
    pub warnings: Vec<String>,
}

/// Write `detections.parquet`; `classes` names the class ids.
pub fn write_detections(
    run: &RunDir,
    found: &[FrameDetection],
    classes: &[String],
) -> Result<(), Error> {
    run.write_table(files::DETECTIONS, detections_table(found, classes))
}

/// Read `detections.parquet`.
pub fn read_detections(run: &RunDir) -> Result<Vec<FrameDetection>, Error> {
    run.read_table(files::DETECTIONS, detections_from)
}

fn detections_table(found: &[FrameDetection], classes: &[String]) -> PolarsResult<DataFrame> {
    let class_name = |c: u32| {
        classes
            .get(c as usize)
            .cloned()
            .unwrap_or_else(|| format!("class{c}"))
    };
    let col_f32 = |f: &dyn Fn(&FrameDetection) -> f32| found.iter().map(f).collect::<Vec<f32>>();
    DataFrame::new(
        found.len(),
        vec![
            Column::new(
                "frame".into(),
                found.iter().map(|d| d.frame).collect::<Vec<u32>>(),
            ),
            Column::new(
                "time_ns".into(),
                found.iter().map(|d| d.time_ns).collect::<Vec<i64>>(),
            ),
            Column::new("x0".into(), col_f32(&|d| d.detection.bbox.x0)),
            Column::new("y0".into(), col_f32(&|d| d.detection.bbox.y0)),
            Column::new("x1".into(), col_f32(&|d| d.detection.bbox.x1)),
            Column::new("y1".into(), col_f32(&|d| d.detection.bbox.y1)),
            Column::new("score".into(), col_f32(&|d| d.detection.score)),
            Column::new(
                "class".into(),
                found
                    .iter()
                    .map(|d| d.detection.class)
                    .collect::<Vec<u32>>(),
            ),
            Column::new(
                "tile".into(),
                found.iter().map(|d| d.detection.tile).collect::<Vec<i32>>(),
            ),
            Column::new(
                "prompt".into(),
                found
                    .iter()
                    .map(|d| class_name(d.detection.class))
                    .collect::<Vec<String>>(),
            ),
        ],
    )
}

fn detections_from(df: &DataFrame) -> PolarsResult<Vec<FrameDetection>> {
    let frame = df.column("frame")?.u32()?;
    let time = df.column("time_ns")?.i64()?;
    let f32s: Vec<&Float32Chunked> = ["x0", "y0", "x1", "y1", "score"]
        .iter()
        .map(|n| df.column(n).and_then(|c| c.f32()))
        .collect::<PolarsResult<_>>()?;
    let class = df.column("class")?.u32()?;
    let tile = df.column("tile")?.i32()?;
    (0..df.height())
        .map(|i| {
            let v = |k: usize| required(f32s[k], i);
            Ok(FrameDetection {
                frame: required(frame, i)?,
                time_ns: required(time, i)?,
                detection: Detection {
                    bbox: BoxXyxy {
                        x0: v(0)?,
                        y0: v(1)?,
                        x1: v(2)?,
                        y1: v(3)?,
                    },
                    score: v(4)?,
                    class: required(class, i)?,
                    tile: required(tile, i)?,
                },
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

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
                    tile: -1 + i as i32,
                },
            })
            .collect();
        let df = detections_table(&found, &["crack".into()]).unwrap();
        assert_eq!(
            df.column("prompt").unwrap().str().unwrap().get(1),
            Some("class1")
        );
        assert_eq!(detections_from(&df).unwrap(), found);
    }
}

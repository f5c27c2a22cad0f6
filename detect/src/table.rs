//! `detections.parquet`: one row per detection, in the frame's pixels, laid
//! out for polars, pandas and DuckDB (flat columns, class name beside id).

use ingest::RunDir;
use polars::prelude::*;

use crate::boxes::{BoxXyxy, Detection};
use crate::error::DetectError;
use crate::stage::files;

/// One detection of one frame, in the frame's pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameDetection {
    pub frame: u32,
    pub time_ns: i64,
    pub detection: Detection,
}

pub fn detections_to_table(
    found: &[FrameDetection],
    classes: &[String],
) -> PolarsResult<DataFrame> {
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

pub fn detections_from_table(df: &DataFrame) -> PolarsResult<Vec<FrameDetection>> {
    let frame = df.column("frame")?.u32()?;
    let time = df.column("time_ns")?.i64()?;
    let f32s: Vec<&Float32Chunked> = ["x0", "y0", "x1", "y1", "score"]
        .iter()
        .map(|n| df.column(n).and_then(|c| c.f32()))
        .collect::<PolarsResult<_>>()?;
    let class = df.column("class")?.u32()?;
    let tile = df.column("tile")?.i32()?;
    let missing = || PolarsError::ComputeError("a detection has a null value".into());
    (0..df.height())
        .map(|i| {
            let v = |k: usize| f32s[k].get(i).ok_or_else(missing);
            Ok(FrameDetection {
                frame: frame.get(i).ok_or_else(missing)?,
                time_ns: time.get(i).ok_or_else(missing)?,
                detection: Detection {
                    bbox: BoxXyxy {
                        x0: v(0)?,
                        y0: v(1)?,
                        x1: v(2)?,
                        y1: v(3)?,
                    },
                    score: v(4)?,
                    class: class.get(i).ok_or_else(missing)?,
                    tile: tile.get(i).ok_or_else(missing)?,
                },
            })
        })
        .collect()
}

/// The detections of a run's completed detect stage.
pub fn read_detections(run: &std::path::Path) -> Result<Vec<FrameDetection>, DetectError> {
    let run = RunDir::open(run, files::SUMMARY, "detect")?;
    detections_from_table(&run.read_table(files::DETECTIONS)?).map_err(|e| DetectError::Table {
        path: run.file(files::DETECTIONS),
        why: e.to_string(),
    })
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
        let df = detections_to_table(&found, &["crack".into()]).unwrap();
        assert_eq!(
            df.column("prompt").unwrap().str().unwrap().get(1),
            Some("class1")
        );
        assert_eq!(detections_from_table(&df).unwrap(), found);
    }
}

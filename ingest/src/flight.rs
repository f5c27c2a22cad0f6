//! A flight as later stages see it: the outputs of a completed ingest,
//! with the recording opened for lazy image access.

use std::path::Path;

use image::DynamicImage;

use crate::camera::Camera;
use crate::error::IngestError;
use crate::frame::Frame;
use crate::image::{decode_compressed, decode_raw};
use crate::map::{PointCloud, pointcloud2};
use crate::recording::Recording;
use crate::ros::{cdr, msg};
use crate::run_dir::{RunDir, files};
use crate::stage::IngestSummary;
use crate::tables;
use crate::trajectory::Trajectory;

pub struct Flight {
    pub run: RunDir,
    pub summary: IngestSummary,
    pub frames: Vec<Frame>,
    pub cameras: Vec<Camera>,
    pub trajectory: Trajectory,
    recording: Recording,
}

impl Flight {
    /// Load the ingest outputs of `run_dir` and reopen its recording.
    pub fn load(run_dir: &Path) -> Result<Self, IngestError> {
        let run = RunDir::open(run_dir, files::INGEST, "ingest")?;
        let summary: IngestSummary = run.read_json(files::INGEST)?;
        let table = |name: &str| {
            let path = run.file(name);
            move |source| IngestError::Table { path, source }
        };
        let frames = tables::frames_from_table(&run.read_table(files::FRAMES)?)
            .map_err(table(files::FRAMES))?;
        let trajectory = tables::trajectory_from_table(&run.read_table(files::TRAJECTORY)?)
            .map_err(table(files::TRAJECTORY))?;
        let cameras: Vec<Camera> = run.read_json(files::CAMERAS)?;
        let recording = Recording::open(&summary.flight.path)?;
        if recording.len() != summary.flight.size_bytes {
            return Err(IngestError::RunDir {
                path: run_dir.to_owned(),
                why: format!(
                    "the recording {} changed size since ingest ({} bytes, was {}); rerun `postflight ingest`",
                    summary.flight.path.display(),
                    recording.len(),
                    summary.flight.size_bytes
                ),
            });
        }
        Ok(Self {
            run,
            summary,
            frames,
            cameras,
            trajectory,
            recording,
        })
    }

    /// The frame with this index (its place in time order).
    pub fn frame(&self, index: u32) -> Option<&Frame> {
        self.frames
            .binary_search_by_key(&index, |f| f.index)
            .ok()
            .map(|i| &self.frames[i])
    }

    /// The camera that took a frame.
    pub fn camera(&self, frame: &Frame) -> Option<&Camera> {
        self.cameras.iter().find(|c| c.topic == frame.topic)
    }

    /// Decode a frame's image from the recording.
    pub fn image(&self, frame: &Frame) -> Result<DynamicImage, IngestError> {
        let payload = self.recording.read_message(frame.location)?;
        let bad = |why: String| IngestError::BadLocation {
            path: self.recording.path().to_owned(),
            location: frame.location,
            why,
        };
        if matches!(frame.encoding.as_str(), "jpeg" | "png") {
            decode_compressed(compressed_bytes(&payload).map_err(&bad)?).map_err(bad)
        } else {
            let (head, mut tail) =
                cdr::decode_head::<msg::ImageHead>(&payload).map_err(|e| bad(e.to_string()))?;
            let data = tail.byte_sequence().map_err(|e| bad(e.to_string()))?;
            decode_raw(
                &head.encoding,
                head.width,
                head.height,
                head.step,
                head.is_bigendian != 0,
                data,
            )
            .map_err(bad)
        }
    }

    /// A frame's image as recorded, still compressed (JPEG or PNG bytes), for
    /// passing on without decoding; `None` for raw images.
    pub fn compressed_image(&self, frame: &Frame) -> Result<Option<Vec<u8>>, IngestError> {
        if !matches!(frame.encoding.as_str(), "jpeg" | "png") {
            return Ok(None);
        }
        let payload = self.recording.read_message(frame.location)?;
        let bad = |why: String| IngestError::BadLocation {
            path: self.recording.path().to_owned(),
            location: frame.location,
            why,
        };
        Ok(Some(compressed_bytes(&payload).map_err(bad)?.to_vec()))
    }

    /// The SLAM map recorded in the flight, if it had one.
    pub fn recorded_map(&self) -> Result<Option<PointCloud>, IngestError> {
        let Some(map) = &self.summary.map else {
            return Ok(None);
        };
        let payload = self.recording.read_message(map.location)?;
        let bad = |why: String| IngestError::Map {
            path: self.recording.path().to_owned(),
            why: format!("topic {}: {why}", map.topic),
        };
        let msg: msg::PointCloud2 = cdr::decode(&payload).map_err(|e| bad(e.to_string()))?;
        pointcloud2::decode(&msg).map(Some).map_err(bad)
    }
}

/// The data of a CompressedImage message.
fn compressed_bytes(payload: &[u8]) -> Result<&[u8], String> {
    let (_, mut tail) =
        cdr::decode_head::<msg::CompressedImageHead>(payload).map_err(|e| e.to_string())?;
    tail.byte_sequence().map_err(|e| e.to_string())
}
